//! Blocking matrix of the GSC: an orthonormal basis of the complement of the target's steering
//! vector, held as a Householder reflector.
//!
//! The reflector H = I - s v v^H (s = 2 / v^H v) maps the phase-normalised steering vector x onto
//! -|x| e_0, so columns 1..M of the (Hermitian, unitary) H are an orthonormal basis B of the
//! complement of the target (M x (M-1), spec 003 section 6.2): B^H a = 0 exactly, whatever the other
//! labels do, so the target cannot leak into the canceller through the fixed beamformer's shape
//! (spec 000 section 4.2, "blocking matrix remark"). Applying it costs O(M) instead of O(M^2), and
//! because x_0 is made real and positive the basis moves smoothly with the target, so the
//! canceller's weights keep their meaning as positions change.

use crate::dsp::Complex;

/// A Householder blocking matrix for one steering vector.
#[derive(Debug, Clone, Default)]
pub struct Blocking {
    v: Vec<Complex>,
    scale: f64,
}

impl Blocking {
    /// An empty blocking matrix for `m` microphones.
    pub fn new(m: usize) -> Self {
        Self {
            v: vec![Complex::new(0.0, 0.0); m],
            scale: 0.0,
        }
    }

    /// Number of microphones.
    pub fn mics(&self) -> usize {
        self.v.len()
    }

    /// Builds the reflector that blocks steering vector `a` (length M).
    pub fn set(&mut self, a: &[Complex]) {
        let a0 = a[0].norm();
        // Rotating x so that x_0 >= 0 spans the same line and keeps the basis continuous.
        let rot = if a0 > 1e-300 {
            a[0].conj() / a0
        } else {
            Complex::new(1.0, 0.0)
        };
        let mut norm2 = 0.0;
        for (v, x) in self.v.iter_mut().zip(a) {
            *v = x * rot;
            norm2 += v.norm_sqr();
        }
        let norm = norm2.sqrt();
        self.v[0].re += norm;
        let vv = 2.0 * norm * (norm + a0);
        self.scale = if vv > 1e-300 && vv.is_finite() {
            2.0 / vv
        } else {
            0.0
        };
    }

    /// The blocked signals u = B^H y (length M - 1).
    pub fn apply(&self, y: &[Complex], u: &mut [Complex]) {
        let mut vy = Complex::new(0.0, 0.0);
        for (v, y) in self.v.iter().zip(y) {
            vy += v.conj() * y;
        }
        let c = vy * self.scale;
        for ((u, v), y) in u.iter_mut().zip(&self.v[1..]).zip(&y[1..]) {
            *u = y - v * c;
        }
    }

    /// The combination B q of the basis columns (length M), e.g. the canceller's share of the
    /// beamformer weights.
    pub fn combine(&self, q: &[Complex], out: &mut [Complex]) {
        // H [0; q] = [0; q] - s v (v^H [0; q]).
        let mut vq = Complex::new(0.0, 0.0);
        for (v, q) in self.v[1..].iter().zip(q) {
            vq += v.conj() * q;
        }
        let c = vq * self.scale;
        out[0] = -self.v[0] * c;
        for ((o, v), q) in out[1..].iter_mut().zip(&self.v[1..]).zip(q) {
            *o = q - v * c;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vecs() -> Vec<Vec<Complex>> {
        vec![
            vec![
                Complex::new(1.0, 0.0),
                Complex::from_polar(0.9, 1.0),
                Complex::from_polar(1.1, -2.5),
                Complex::from_polar(0.95, 0.3),
            ],
            vec![
                Complex::from_polar(0.5, 2.0),
                Complex::new(-1.0, 0.2),
                Complex::new(0.0, 0.0),
                Complex::new(0.3, -0.7),
            ],
        ]
    }

    #[test]
    fn blocks_the_target_and_is_orthonormal() {
        for a in vecs() {
            let m = a.len();
            let mut b = Blocking::new(m);
            b.set(&a);
            let mut u = vec![Complex::new(0.0, 0.0); m - 1];
            b.apply(&a, &mut u);
            let an: f64 = a.iter().map(|x| x.norm_sqr()).sum::<f64>().sqrt();
            assert!(u.iter().all(|x| x.norm() < 1e-12 * an), "{u:?}");
            // Columns of B: B e_j for unit q.
            let cols: Vec<Vec<Complex>> = (0..m - 1)
                .map(|j| {
                    let mut q = vec![Complex::new(0.0, 0.0); m - 1];
                    q[j] = Complex::new(1.0, 0.0);
                    let mut c = vec![Complex::new(0.0, 0.0); m];
                    b.combine(&q, &mut c);
                    c
                })
                .collect();
            for i in 0..m - 1 {
                for j in 0..m - 1 {
                    let ip: Complex = cols[i]
                        .iter()
                        .zip(&cols[j])
                        .map(|(x, y)| x.conj() * y)
                        .sum();
                    let e = if i == j { 1.0 } else { 0.0 };
                    assert!((ip - Complex::new(e, 0.0)).norm() < 1e-12);
                }
                // apply() is B^H: its j-th output is column j's inner product with y.
                let y = &a;
                let mut u = vec![Complex::new(0.0, 0.0); m - 1];
                let y2: Vec<Complex> = y
                    .iter()
                    .enumerate()
                    .map(|(k, v)| v + Complex::new(k as f64, 1.0))
                    .collect();
                b.apply(&y2, &mut u);
                let ip: Complex = cols[i].iter().zip(&y2).map(|(x, y)| x.conj() * y).sum();
                assert!((ip - u[i]).norm() < 1e-12);
            }
        }
    }
}
