//! Non-negative least squares for a few unknowns, on the normal equations: the direct-path
//! power fit of the activity gate and the post-filter's demixing of the beamformers' powers.

use super::cholesky;

/// Ridge on the normal matrix's diagonal, relative to it, so two collinear unknowns split their
/// value instead of making the system singular.
const RIDGE: f64 = 1e-6;

/// Non-negative least squares on the normal equations (Lawson-Hanson active set) for a few
/// unknowns: minimises x^T K x - 2 b^T x over x >= 0 for a symmetric positive semi-definite K.
#[derive(Debug, Clone, Default)]
pub struct Nnls {
    x: Vec<f64>,
    z: Vec<f64>,
    passive: Vec<bool>,
    sub: Vec<f64>,
    idx: Vec<usize>,
    rhs: Vec<f64>,
}

impl Nnls {
    /// The solution for the `n x n` matrix `k` (row-major) and right-hand side `b`, starting
    /// from the `support` (bit j: x_j > 0; used for n <= 32) of a similar problem, which
    /// it is set to on return.
    pub fn solve(&mut self, k: &[f64], b: &[f64], n: usize, support: &mut u32) -> &[f64] {
        self.x.clear();
        self.x.resize(n, 0.0);
        self.z.clear();
        self.z.resize(n, 0.0);
        self.passive.clear();
        self.passive.resize(n, false);
        let scale = (0..n).map(|i| k[i * n + i]).fold(0.0, f64::max);
        if !(scale > 0.0 && scale.is_finite()) {
            return &self.x;
        }
        let tol = 1e-12 * b.iter().fold(0.0f64, |a, v| a.max(v.abs())).max(1e-300);
        self.warm_start(k, b, n, *support);
        'grow: for _ in 0..3 * n {
            // The most negative gradient among the variables held at zero enters.
            let mut best = None;
            for j in (0..n).filter(|&j| !self.passive[j]) {
                let g = b[j] - (0..n).map(|i| k[j * n + i] * self.x[i]).sum::<f64>();
                if g > tol && best.is_none_or(|(_, v)| g > v) {
                    best = Some((j, g));
                }
            }
            let Some((enter, _)) = best else {
                break;
            };
            self.passive[enter] = true;
            // Each pass either accepts z or drops at least one variable, so n passes suffice.
            for _ in 0..=n {
                if !self.solve_passive(k, b, n) {
                    self.passive[enter] = false;
                    break 'grow;
                }
                if (0..n).all(|j| !self.passive[j] || self.z[j] > 0.0) {
                    self.x.copy_from_slice(&self.z);
                    break;
                }
                // Step from x toward z until the first passive variable reaches zero; that one
                // (and any other at zero) leaves the passive set, set to exactly zero so that
                // rounding cannot keep it in.
                let mut step = (1.0f64, None);
                for j in (0..n).filter(|&j| self.passive[j] && self.z[j] <= 0.0) {
                    let d = self.x[j] - self.z[j];
                    let a = if d > 0.0 { self.x[j] / d } else { 0.0 };
                    if a < step.0 || step.1.is_none() {
                        step = (a.min(step.0), Some(j));
                    }
                }
                let (alpha, blocking) = step;
                for j in 0..n {
                    self.x[j] += alpha * (self.z[j] - self.x[j]);
                    if self.passive[j] && (Some(j) == blocking || self.x[j] <= 0.0) {
                        self.passive[j] = false;
                        self.x[j] = 0.0;
                    }
                }
                if !self.passive.iter().any(|&p| p) {
                    break;
                }
            }
        }
        *support = (0..n.min(32))
            .filter(|&j| self.x[j] > 0.0)
            .fold(0, |m, j| m | (1 << j));
        &self.x
    }

    /// Starts from the solution on `support`, shrunk until it is positive (any feasible point
    /// with its support passive is a valid start of the active-set iteration).
    fn warm_start(&mut self, k: &[f64], b: &[f64], n: usize, support: u32) {
        for (j, p) in self.passive.iter_mut().enumerate() {
            *p = j < 32 && support & (1 << j) != 0;
        }
        while self.passive.iter().any(|&p| p) {
            if !self.solve_passive(k, b, n) {
                self.passive.fill(false);
                return;
            }
            if (0..n).all(|j| !self.passive[j] || self.z[j] > 0.0) {
                self.x.copy_from_slice(&self.z);
                return;
            }
            for (p, z) in self.passive.iter_mut().zip(&self.z) {
                *p &= *z > 0.0;
            }
        }
    }

    /// z = the unconstrained solution on the passive set (zero elsewhere), by Cholesky with a
    /// small ridge; false when the system is not positive definite or the solution not finite.
    fn solve_passive(&mut self, k: &[f64], b: &[f64], n: usize) -> bool {
        self.idx.clear();
        self.idx.extend((0..n).filter(|&j| self.passive[j]));
        let p = self.idx.len();
        self.sub.clear();
        self.rhs.clear();
        for &i in &self.idx {
            for &j in &self.idx {
                let ridge = if i == j { RIDGE * k[i * n + i] } else { 0.0 };
                self.sub.push(k[i * n + j] + ridge);
            }
            self.rhs.push(b[i]);
        }
        if !cholesky::factor(&mut self.sub, p) {
            return false;
        }
        cholesky::solve(&self.sub, p, &mut self.rhs);
        self.z.fill(0.0);
        for (&j, v) in self.idx.iter().zip(&self.rhs) {
            self.z[j] = *v;
        }
        self.z.iter().all(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};
    use rand_distr::StandardNormal;

    /// The least-squares objective x^T K x - 2 b^T x.
    fn objective(k: &[f64], b: &[f64], x: &[f64], n: usize) -> f64 {
        let mut v = 0.0;
        for i in 0..n {
            for j in 0..n {
                v += x[i] * k[i * n + j] * x[j];
            }
            v -= 2.0 * b[i] * x[i];
        }
        v
    }

    /// The best feasible point over every support (solving the normal equations on it).
    fn brute_force(k: &[f64], b: &[f64], n: usize) -> Vec<f64> {
        let mut best = (vec![0.0; n], 0.0);
        let mut solver = Nnls::default();
        for mask in 1..(1u32 << n) {
            solver.passive = (0..n).map(|j| mask & (1 << j) != 0).collect();
            solver.z = vec![0.0; n];
            if !solver.solve_passive(k, b, n) || solver.z.iter().any(|&v| v < 0.0) {
                continue;
            }
            let f = objective(k, b, &solver.z, n);
            if f < best.1 {
                best = (solver.z.clone(), f);
            }
        }
        best.0
    }

    #[test]
    fn nnls_finds_the_best_non_negative_point() {
        let mut rng = StdRng::seed_from_u64(7);
        let mut solver = Nnls::default();
        for n in 1..=6 {
            for _ in 0..300 {
                // K = A^T A for a random tall A, b = A^T r for a random r: some unknowns end at 0.
                let rows = n + 3;
                let mut a: Vec<f64> = (0..rows * n).map(|_| rng.sample(StandardNormal)).collect();
                // Half the problems have two nearly collinear columns (two labels the array can
                // hardly tell apart), where rounding once kept the active set cycling.
                if n >= 2 && rng.random_bool(0.5) {
                    for q in 0..rows {
                        let e: f64 = rng.sample(StandardNormal);
                        a[q * n + 1] = a[q * n] * (1.0 + 1e-9 * e);
                    }
                }
                let r: Vec<f64> = (0..rows).map(|_| rng.sample(StandardNormal)).collect();
                let mut k = vec![0.0; n * n];
                let mut b = vec![0.0; n];
                for i in 0..n {
                    for j in 0..n {
                        k[i * n + j] = (0..rows).map(|q| a[q * n + i] * a[q * n + j]).sum();
                    }
                    b[i] = (0..rows).map(|q| a[q * n + i] * r[q]).sum();
                }
                // Cold and warm starts (from a random support) reach the same optimum.
                let x = solver.solve(&k, &b, n, &mut 0).to_vec();
                let mut support = rng.random_range(0..(1u32 << n));
                let warm = solver.solve(&k, &b, n, &mut support).to_vec();
                let fwarm = objective(&k, &b, &warm, n);
                let want = brute_force(&k, &b, n);
                assert!(x.iter().all(|&v| v >= 0.0), "{x:?}");
                let (fx, fw) = (objective(&k, &b, &x, n), objective(&k, &b, &want, n));
                // Both solve with the ridge, which moves the optimum by about its size (1e-6).
                assert!(
                    fx <= fw + 1e-6 * fw.abs().max(1.0),
                    "n {n}: {fx} against {fw}"
                );
                assert!(
                    fwarm <= fw + 1e-6 * fw.abs().max(1.0),
                    "n {n}: {fwarm} against {fw}"
                );
                assert!(warm.iter().all(|&v| v >= 0.0), "{warm:?}");
            }
        }
    }
}
