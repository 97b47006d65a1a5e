//! Small dense Hermitian (or real symmetric) positive-definite systems (at most a few dozen
//! unknowns), solved by Cholesky factorisation in place on row-major slices, without allocation.

use nalgebra::ComplexField;

#[cfg(test)]
use crate::dsp::Complex;

/// Factors the Hermitian positive-definite `n x n` matrix `a` (row-major, both triangles set) in
/// place into its lower Cholesky factor L with A = L L^H (the upper triangle is left stale).
/// Returns false when a pivot is not positive and finite (not positive definite). Complex
/// (beamformers) or real (the direct-path power fit's normal equations).
#[inline]
pub fn factor<T: ComplexField<RealField = f64> + Copy>(a: &mut [T], n: usize) -> bool {
    for j in 0..n {
        let mut diag = a[j * n + j].real();
        for p in 0..j {
            diag -= a[j * n + p].modulus_squared();
        }
        if !(diag > 0.0 && diag.is_finite()) {
            return false;
        }
        let ljj = diag.sqrt();
        a[j * n + j] = T::from_real(ljj);
        let inv = 1.0 / ljj;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for p in 0..j {
                s -= a[i * n + p] * a[j * n + p].conjugate();
            }
            a[i * n + j] = s.scale(inv);
        }
    }
    true
}

/// Solves L L^H x = b in place (`b` becomes x) with the factor from [`factor`].
#[inline]
pub fn solve<T: ComplexField<RealField = f64> + Copy>(l: &[T], n: usize, b: &mut [T]) {
    // Forward: L z = b.
    for i in 0..n {
        let mut s = b[i];
        for p in 0..i {
            s -= l[i * n + p] * b[p];
        }
        b[i] = s.unscale(l[i * n + i].real());
    }
    // Backward: L^H x = z.
    for i in (0..n).rev() {
        let mut s = b[i];
        for p in i + 1..n {
            s -= l[p * n + i].conjugate() * b[p];
        }
        b[i] = s.unscale(l[i * n + i].real());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_hermitian_system() {
        let n = 3;
        // A = B B^H + I for a fixed complex B.
        let b = [
            Complex::new(1.0, 0.5),
            Complex::new(-0.3, 0.2),
            Complex::new(0.0, 1.0),
            Complex::new(0.7, -0.1),
            Complex::new(2.0, 0.0),
            Complex::new(0.1, 0.1),
            Complex::new(-1.0, 0.4),
            Complex::new(0.3, 0.3),
            Complex::new(0.5, -0.8),
        ];
        let mut a = vec![Complex::new(0.0, 0.0); 9];
        for i in 0..n {
            for j in 0..n {
                let mut s = if i == j {
                    Complex::new(1.0, 0.0)
                } else {
                    Complex::new(0.0, 0.0)
                };
                for p in 0..n {
                    s += b[i * n + p] * b[j * n + p].conj();
                }
                a[i * n + j] = s;
            }
        }
        let orig = a.clone();
        assert!(factor(&mut a, n));
        let rhs = [
            Complex::new(1.0, 0.0),
            Complex::new(0.0, -2.0),
            Complex::new(0.5, 0.5),
        ];
        let mut x = rhs;
        solve(&a, n, &mut x);
        for i in 0..n {
            let mut s = Complex::new(0.0, 0.0);
            for j in 0..n {
                s += orig[i * n + j] * x[j];
            }
            assert!((s - rhs[i]).norm() < 1e-12);
        }
    }

    #[test]
    fn refuses_indefinite_matrices() {
        let mut a = vec![
            Complex::new(1.0, 0.0),
            Complex::new(2.0, 0.0),
            Complex::new(2.0, 0.0),
            Complex::new(1.0, 0.0),
        ];
        assert!(!factor(&mut a, 2));
        let mut nan = vec![Complex::new(f64::NAN, 0.0)];
        assert!(!factor(&mut nan, 1));
    }
}
