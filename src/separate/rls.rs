//! The GSC's adaptive interference canceller: complex recursive least squares per bin
//! (spec 003 eq. 31, section 6.2), minimising sum_t lambda^{n-t} |d_t - V^H u_t|^2 over the
//! blocked signals u = B^H y and the fixed-beamformer output d.
//!
//! Three additions make it safe to run unattended:
//! * a weighted step: sample weight beta in [0, 1] (adaptation control) with the forgetting slowed
//!   to lambda = 1 - (1 - gamma) beta, so a frame where the target talks neither teaches the
//!   canceller nor makes it forget;
//! * leakage: a ridge term kept in the correlation estimate by one rank-one update per step on a
//!   cycling coordinate (steady state ~ leakage * power * I), so directions that the input never
//!   excites do not let P grow like lambda^{-n};
//! * a norm bound on V (a white-noise-gain constraint), scaled back when exceeded.

use crate::dsp::Complex;

/// Smallest per-bin power used to scale the regularisation (input units squared); keeps the
/// inverse correlation bounded on digital silence.
pub const POWER_FLOOR: f64 = 1e-14;

/// Per-step constants of the canceller.
#[derive(Debug, Clone, Copy)]
pub struct RlsStep {
    /// Forgetting factor at full adaptation.
    pub forgetting: f64,
    /// Leakage relative to the input power.
    pub leakage: f64,
    /// Upper bound on |V|^2 (absolute).
    pub max_norm2: f64,
}

/// Resets one bin's canceller: V = 0, P = I / (delta * power).
pub fn reset(v: &mut [Complex], p: &mut [Complex], l: usize, delta: f64, power: f64) {
    v.fill(Complex::new(0.0, 0.0));
    p.fill(Complex::new(0.0, 0.0));
    let p0 = 1.0 / (delta * power.max(POWER_FLOOR));
    for i in 0..l {
        p[i * l + i] = Complex::new(p0, 0.0);
    }
}

/// A-priori output e = d - V^H u (the canceller's output with the weights before this step).
pub fn output(v: &[Complex], u: &[Complex], d: Complex) -> Complex {
    let mut s = d;
    for (v, u) in v.iter().zip(u) {
        s -= v.conj() * u;
    }
    s
}

/// One weighted RLS step with leakage on coordinate `leak_index`. `e` is the a-priori output,
/// `power` the bin's input power, `pi` scratch of length `l`. Returns false (state untouched
/// beyond repair) when the recursion produced something non-finite; the caller then resets.
#[allow(clippy::too_many_arguments)]
pub fn adapt(
    v: &mut [Complex],
    p: &mut [Complex],
    l: usize,
    u: &[Complex],
    e: Complex,
    beta: f64,
    power: f64,
    leak_index: usize,
    step: &RlsStep,
    pi: &mut [Complex],
) -> bool {
    if beta <= 0.0 || l == 0 {
        return true;
    }
    let lam = 1.0 - (1.0 - step.forgetting) * beta;
    // pi = P u and the conversion term u^H P u (real for Hermitian P).
    let mut upu = 0.0;
    for i in 0..l {
        let row = &p[i * l..(i + 1) * l];
        let mut s = Complex::new(0.0, 0.0);
        for (x, y) in row.iter().zip(u) {
            s += x * y;
        }
        pi[i] = s;
        upu += (u[i].conj() * s).re;
    }
    let den = lam + beta * upu;
    if !(den > 0.0 && den.is_finite()) {
        return false;
    }
    let g = beta / den;
    let ec = e.conj();
    for (vi, pii) in v.iter_mut().zip(pi.iter()) {
        *vi += pii * (g * ec);
    }
    let inv_lam = 1.0 / lam;
    // P <- (P - g pi pi^H) / lambda, upper triangle mirrored so P stays exactly Hermitian.
    for i in 0..l {
        let gi = pi[i] * g;
        let d = (p[i * l + i].re - (gi * pi[i].conj()).re) * inv_lam;
        p[i * l + i] = Complex::new(d, 0.0);
        for j in i + 1..l {
            let x = (p[i * l + j] - gi * pi[j].conj()) * inv_lam;
            p[i * l + j] = x;
            p[j * l + i] = x.conj();
        }
    }
    // Leakage: R += c e_j e_j^H, i.e. P -= c q q^H / (1 + c q_j) with q = P e_j, and the weights
    // move to the regularised solution V -= c q V_j / (1 + c q_j).
    let c = step.leakage * power.max(POWER_FLOOR) * l as f64 * beta;
    if c > 0.0 {
        let j = leak_index % l;
        for (i, q) in pi.iter_mut().enumerate() {
            *q = p[i * l + j];
        }
        let pjj = pi[j].re;
        let s = c / (1.0 + c * pjj);
        let vj = v[j];
        for (vi, q) in v.iter_mut().zip(pi.iter()) {
            *vi -= q * (s * vj);
        }
        for i in 0..l {
            let si = pi[i] * s;
            p[i * l + i].re -= (si * pi[i].conj()).re;
            for jj in i + 1..l {
                let x = p[i * l + jj] - si * pi[jj].conj();
                p[i * l + jj] = x;
                p[jj * l + i] = x.conj();
            }
        }
    }
    let n2: f64 = v.iter().map(|x| x.norm_sqr()).sum();
    if n2 > step.max_norm2 {
        let s = (step.max_norm2 / n2).sqrt();
        for x in v.iter_mut() {
            *x *= s;
        }
    }
    n2.is_finite() && (0..l).all(|i| p[i * l + i].re > 0.0 && p[i * l + i].re.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn cn(rng: &mut ChaCha8Rng) -> Complex {
        Complex::new(
            rng.random::<f64>() * 2.0 - 1.0,
            rng.random::<f64>() * 2.0 - 1.0,
        )
    }

    #[test]
    fn converges_to_the_wiener_solution() {
        let l = 3;
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let truth = [
            Complex::new(0.5, -0.2),
            Complex::new(-0.1, 0.3),
            Complex::new(0.0, 0.7),
        ];
        let mut v = vec![Complex::new(0.0, 0.0); l];
        let mut p = vec![Complex::new(0.0, 0.0); l * l];
        let mut pi = vec![Complex::new(0.0, 0.0); l];
        reset(&mut v, &mut p, l, 1e-2, 0.66);
        let step = RlsStep {
            forgetting: 0.99,
            leakage: 1e-4,
            max_norm2: 1e6,
        };
        for n in 0..2000 {
            let u: Vec<Complex> = (0..l).map(|_| cn(&mut rng)).collect();
            let d: Complex = truth.iter().zip(&u).map(|(w, u)| w.conj() * u).sum();
            let e = output(&v, &u, d);
            assert!(adapt(
                &mut v, &mut p, l, &u, e, 1.0, 0.66, n, &step, &mut pi
            ));
        }
        for (a, b) in v.iter().zip(&truth) {
            assert!((a - b).norm() < 1e-2, "{v:?}");
        }
    }

    #[test]
    fn stays_bounded_when_one_direction_is_never_excited() {
        let l = 4;
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut v = vec![Complex::new(0.0, 0.0); l];
        let mut p = vec![Complex::new(0.0, 0.0); l * l];
        let mut pi = vec![Complex::new(0.0, 0.0); l];
        reset(&mut v, &mut p, l, 1e-2, 1.0);
        let step = RlsStep {
            forgetting: 0.95,
            leakage: 1e-3,
            max_norm2: 100.0,
        };
        // Rank-one input for 100k frames: plain RLS would grow P like 0.95^-n and overflow.
        let dir = [
            Complex::new(1.0, 0.0),
            Complex::new(0.0, 1.0),
            Complex::new(0.5, 0.0),
            Complex::new(0.0, 0.0),
        ];
        for n in 0..100_000 {
            let s = cn(&mut rng);
            let u: Vec<Complex> = dir.iter().map(|x| x * s).collect();
            let d = s * 0.3;
            let e = output(&v, &u, d);
            assert!(adapt(&mut v, &mut p, l, &u, e, 1.0, 1.0, n, &step, &mut pi));
        }
        let tr: f64 = (0..l).map(|i| p[i * l + i].re).sum();
        assert!(tr.is_finite() && tr < 1e6, "P grew to trace {tr}");
        // Still cancels the excited direction.
        let s = Complex::new(0.7, -0.2);
        let u: Vec<Complex> = dir.iter().map(|x| x * s).collect();
        assert!(output(&v, &u, s * 0.3).norm() < 0.02 * (s * 0.3).norm());
    }

    #[test]
    fn zero_weight_freezes_the_state() {
        let l = 2;
        let mut v = vec![Complex::new(0.1, 0.0); l];
        let mut p = vec![Complex::new(0.0, 0.0); l * l];
        reset(&mut vec![Complex::new(0.0, 0.0); l], &mut p, l, 1.0, 1.0);
        let (v0, p0) = (v.clone(), p.clone());
        let step = RlsStep {
            forgetting: 0.9,
            leakage: 1e-3,
            max_norm2: 1e6,
        };
        let u = [Complex::new(1.0, 2.0), Complex::new(-1.0, 0.5)];
        let mut pi = vec![Complex::new(0.0, 0.0); l];
        assert!(adapt(
            &mut v,
            &mut p,
            l,
            &u,
            Complex::new(3.0, 0.0),
            0.0,
            1.0,
            0,
            &step,
            &mut pi
        ));
        assert_eq!(v, v0);
        assert_eq!(p, p0);
    }
}
