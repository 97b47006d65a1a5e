//! MVDR beamformer per bin: w = R^{-1} a / (a^H R^{-1} a) with the noise-plus-interference
//! covariance R learned recursively while the target is quiet and diagonally loaded against
//! ill-conditioning (thesis eq. 2.9-2.10).

use super::cholesky;
use crate::dsp::Complex;

/// Resets one bin's covariance to an isotropic field of the given power.
pub fn reset(r: &mut [Complex], m: usize, power: f64) {
    r.fill(Complex::new(0.0, 0.0));
    for i in 0..m {
        r[i * m + i] = Complex::new(power.max(super::rls::POWER_FLOOR), 0.0);
    }
}

/// Weighted recursive covariance update R <- lambda R + (1 - lambda) y y^H with
/// 1 - lambda = (1 - forgetting) * beta.
pub fn update(r: &mut [Complex], m: usize, y: &[Complex], beta: f64, forgetting: f64) {
    if beta <= 0.0 {
        return;
    }
    let a = (1.0 - forgetting) * beta;
    let lam = 1.0 - a;
    for i in 0..m {
        let yi = y[i] * a;
        r[i * m + i] = Complex::new(lam * r[i * m + i].re + (yi * y[i].conj()).re, 0.0);
        for j in i + 1..m {
            let x = r[i * m + j] * lam + yi * y[j].conj();
            r[i * m + j] = x;
            r[j * m + i] = x.conj();
        }
    }
}

/// MVDR weights toward `a` from covariance `r` loaded by `loading` times its mean diagonal.
/// `work` is scratch of length m * m. Falls back to delay-and-sum when R is unusable.
pub fn weights(
    r: &[Complex],
    m: usize,
    a: &[Complex],
    loading: f64,
    work: &mut [Complex],
    w: &mut [Complex],
) {
    let tr: f64 = (0..m).map(|i| r[i * m + i].re).sum();
    let eps = (loading * tr / m as f64).max(super::rls::POWER_FLOOR);
    work[..m * m].copy_from_slice(&r[..m * m]);
    for i in 0..m {
        work[i * m + i].re += eps;
    }
    w[..m].copy_from_slice(&a[..m]);
    let ok = cholesky::factor(&mut work[..m * m], m);
    if ok {
        cholesky::solve(&work[..m * m], m, &mut w[..m]);
    }
    let mut aw = Complex::new(0.0, 0.0);
    for (a, w) in a.iter().zip(w.iter()) {
        aw += a.conj() * w;
    }
    // a^H R^{-1} a is real and positive for a positive-definite R.
    if ok && aw.re > 1e-300 && aw.re.is_finite() {
        let s = 1.0 / aw.re;
        for x in w[..m].iter_mut() {
            *x *= s;
        }
    } else {
        let an: f64 = a.iter().map(|x| x.norm_sqr()).sum();
        for (x, a) in w[..m].iter_mut().zip(a) {
            *x = a / an.max(1e-300);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dsp::inner;

    #[test]
    fn distortionless_and_rejects_a_learnt_interferer() {
        let m = 4;
        let a: Vec<Complex> = (0..m)
            .map(|i| Complex::from_polar(1.0, -0.4 * i as f64))
            .collect();
        let b: Vec<Complex> = (0..m)
            .map(|i| Complex::from_polar(1.0, 0.9 * i as f64))
            .collect();
        let mut r = vec![Complex::new(0.0, 0.0); m * m];
        reset(&mut r, m, 1e-3);
        for n in 0..500 {
            let s = Complex::from_polar(1.0, n as f64 * 1.7);
            let y: Vec<Complex> = b.iter().map(|x| x * s).collect();
            update(&mut r, m, &y, 1.0, 0.98);
        }
        let mut work = vec![Complex::new(0.0, 0.0); m * m];
        let mut w = vec![Complex::new(0.0, 0.0); m];
        weights(&r, m, &a, 1e-3, &mut work, &mut w);
        let resp = |v: &[Complex]| -> Complex { inner(&w, v) };
        assert!((resp(&a) - Complex::new(1.0, 0.0)).norm() < 1e-9);
        assert!(resp(&b).norm() < 0.03, "{}", resp(&b).norm());
    }
}
