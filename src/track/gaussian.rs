//! Gaussian bookkeeping: keeping covariances symmetric positive definite, log-sum-exp and the
//! chi-square quantile used for gating.

use nalgebra::{DMatrix, SMatrix, SVector};

/// A Gaussian density N(mean, cov) over the state.
#[derive(Debug, Clone, PartialEq)]
pub struct Gaussian<const N: usize> {
    /// Mean.
    pub mean: SVector<f64, N>,
    /// Covariance (symmetric positive definite).
    pub cov: SMatrix<f64, N, N>,
}

/// Smallest eigenvalue a covariance may have, relative to its largest diagonal entry.
const EIGEN_FLOOR_REL: f64 = 1e-10;
/// Absolute eigenvalue floor.
const EIGEN_FLOOR_ABS: f64 = 1e-12;

/// Symmetrises `p` and, when it is not positive definite, floors its eigenvalues. Returns false
/// (leaving `p` untouched) when it holds non-finite numbers.
pub fn condition<const N: usize>(p: &mut SMatrix<f64, N, N>) -> bool {
    if p.iter().any(|v| !v.is_finite()) {
        return false;
    }
    let sym = (*p + p.transpose()) * 0.5;
    *p = sym;
    let scale = (0..N).map(|i| p[(i, i)].abs()).fold(0.0, f64::max);
    let floor = (scale * EIGEN_FLOOR_REL).max(EIGEN_FLOOR_ABS);
    if cholesky_pivots_above(p, floor) {
        return true;
    }
    // Eigen-decomposition needs dynamic dimensions for generic N; this path is rare.
    let d = DMatrix::from_column_slice(N, N, p.as_slice());
    let eig = d.symmetric_eigen();
    let mut fixed = SMatrix::<f64, N, N>::zeros();
    for k in 0..N {
        let lambda = eig.eigenvalues[k].max(floor);
        let v = eig.eigenvectors.column(k);
        for i in 0..N {
            for j in 0..N {
                fixed[(i, j)] += lambda * v[i] * v[j];
            }
        }
    }
    let sym = (fixed + fixed.transpose()) * 0.5;
    if sym.iter().all(|v| v.is_finite()) {
        *p = sym;
        true
    } else {
        false
    }
}

/// Whether every Cholesky pivot of symmetric `p` exceeds `floor` (then p is positive definite
/// and not nearly singular). Written out because nalgebra's generic decomposition is several
/// times slower for these small matrices, and this check runs for every covariance.
fn cholesky_pivots_above<const N: usize>(p: &SMatrix<f64, N, N>, floor: f64) -> bool {
    let a = p.as_slice();
    let mut l = [[0.0f64; N]; N];
    for j in 0..N {
        let d = a[j * N + j] - l[j][..j].iter().map(|v| v * v).sum::<f64>();
        if d.is_nan() || d <= floor {
            return false;
        }
        let ljj = d.sqrt();
        l[j][j] = ljj;
        for i in j + 1..N {
            let dot: f64 = l[i][..j].iter().zip(&l[j][..j]).map(|(x, y)| x * y).sum();
            l[i][j] = (a[j * N + i] - dot) / ljj;
        }
    }
    true
}

/// The moment-matched Gaussian of the mixture sum_i w_i N(g_i) of `parts` (w_i, g_i), the
/// weights summing to 1. Its covariance is returned as summed: callers symmetrise or
/// [`condition`] it as their use needs.
pub fn mixture_moments<'a, const N: usize>(
    parts: impl Iterator<Item = (f64, &'a Gaussian<N>)> + Clone,
) -> Gaussian<N> {
    let mut mean = SVector::<f64, N>::zeros();
    for (w, g) in parts.clone() {
        mean += g.mean * w;
    }
    let mut cov = SMatrix::<f64, N, N>::zeros();
    for (w, g) in parts {
        let d = g.mean - mean;
        cov += (g.cov + d * d.transpose()) * w;
    }
    Gaussian { mean, cov }
}

/// log(sum(exp(x))) computed without overflow; -inf for an empty or all -inf input.
pub fn log_sum_exp(xs: impl Iterator<Item = f64> + Clone) -> f64 {
    let m = xs.clone().fold(f64::NEG_INFINITY, f64::max);
    if !m.is_finite() {
        return m;
    }
    m + xs.map(|x| (x - m).exp()).sum::<f64>().ln()
}

/// log(exp(a) + exp(b)).
pub fn log_add(a: f64, b: f64) -> f64 {
    let (hi, lo) = if a > b { (a, b) } else { (b, a) };
    if hi == f64::NEG_INFINITY {
        return hi;
    }
    hi + (lo - hi).exp().ln_1p()
}

/// Regularised lower incomplete gamma function P(a, x) (series / continued fraction).
fn gamma_p(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let ln_front = a * x.ln() - x - ln_gamma(a);
    if x < a + 1.0 {
        let (mut sum, mut term, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..500 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        (sum.ln() + ln_front).exp()
    } else {
        // Lentz's continued fraction for Q(a, x).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..500 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let delta = d * c;
            h *= delta;
            if (delta - 1.0).abs() < 1e-15 {
                break;
            }
        }
        1.0 - (h.ln() + ln_front).exp()
    }
}

/// The standard normal distribution function Phi(x) (complementary error function of Numerical
/// Recipes' `erfcc`, relative error below 1.2e-7).
pub fn normal_cdf(x: f64) -> f64 {
    let z = x.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let erfc = t * poly.exp();
    if x >= 0.0 {
        1.0 - 0.5 * erfc
    } else {
        0.5 * erfc
    }
}

/// ln Gamma(x) for x > 0 (Lanczos, g = 7).
fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The chi-square quantile: the squared Mahalanobis radius holding probability `p` of a
/// `dof`-dimensional Gaussian. `p >= 1` gives infinity (no gate).
pub fn chi_square_quantile(p: f64, dof: usize) -> f64 {
    if p >= 1.0 {
        return f64::INFINITY;
    }
    if p <= 0.0 || dof == 0 {
        return 0.0;
    }
    let a = dof as f64 / 2.0;
    let (mut lo, mut hi) = (0.0, 1.0);
    while gamma_p(a, hi / 2.0) < p && hi < 1e6 {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if gamma_p(a, mid / 2.0) < p {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-12 * hi.max(1.0) {
            break;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    #[test]
    fn a_mixtures_moments_are_its_mean_and_its_spread_about_it() {
        let g = |m: f64, v: f64| Gaussian::<1> {
            mean: SVector::from([m]),
            cov: SMatrix::from([[v]]),
        };
        let (a, b) = (g(0.0, 1.0), g(4.0, 2.0));
        let m = mixture_moments([(0.25, &a), (0.75, &b)].into_iter());
        assert!((m.mean[0] - 3.0).abs() < 1e-12);
        // Within: 0.25 * 1 + 0.75 * 2; between: 0.25 * 9 + 0.75 * 1.
        assert!((m.cov[(0, 0)] - (1.75 + 3.0)).abs() < 1e-12);
        // One component is itself.
        assert_eq!(mixture_moments([(1.0, &b)].into_iter()), b);
    }

    #[test]
    fn chi_square_quantiles_match_tables() {
        // Standard tables: 95% -> 3.841 (1 dof), 5.991 (2), 7.815 (3); 99.99% (2 dof) -> 18.42.
        assert!((chi_square_quantile(0.95, 1) - 3.841_458_8).abs() < 1e-5);
        assert!((chi_square_quantile(0.95, 2) - 5.991_464_5).abs() < 1e-5);
        assert!((chi_square_quantile(0.95, 3) - 7.814_727_9).abs() < 1e-5);
        assert!((chi_square_quantile(0.9999, 2) - (-2.0 * 1e-4f64.ln())).abs() < 1e-6);
        assert_eq!(chi_square_quantile(1.0, 2), f64::INFINITY);
    }

    #[test]
    fn normal_cdf_matches_tables() {
        assert!((normal_cdf(0.0) - 0.5).abs() < 1e-7);
        assert!((normal_cdf(1.0) - 0.841_344_75).abs() < 1e-6);
        assert!((normal_cdf(-1.959_964) - 0.025).abs() < 1e-6);
        assert!(normal_cdf(-40.0) >= 0.0 && normal_cdf(40.0) <= 1.0);
    }

    #[test]
    fn conditioning_repairs_indefinite_and_rejects_nan() {
        let mut p = Matrix3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        assert!(condition(&mut p));
        assert!(p.cholesky().is_some());
        let mut p = Matrix3::new(1.0, 1e-3, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        assert!(condition(&mut p));
        assert_eq!(p, p.transpose());
        let mut z = Matrix3::<f64>::zeros();
        assert!(condition(&mut z));
        assert!(z.cholesky().is_some());
        let mut bad = Matrix3::new(f64::NAN, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        assert!(!condition(&mut bad));
    }

    #[test]
    fn log_sum_exp_is_stable() {
        let v = [1000.0, 1000.0];
        assert!((log_sum_exp(v.iter().copied()) - (1000.0 + 2f64.ln())).abs() < 1e-12);
        assert_eq!(
            log_sum_exp([f64::NEG_INFINITY].iter().copied()),
            f64::NEG_INFINITY
        );
        assert!((log_add(-1000.0, -1000.0) - (-1000.0 + 2f64.ln())).abs() < 1e-12);
    }
}
