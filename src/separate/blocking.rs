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
        self.v.resize(a.len(), Complex::new(0.0, 0.0));
        self.scale = reflector(a, &mut self.v);
    }

    /// The blocked signals u = B^H y (length M - 1).
    pub fn apply(&self, y: &[Complex], u: &mut [Complex]) {
        let c = projection(&self.v, self.scale, y);
        let m = self.v.len();
        let (v, y, u) = (&self.v[1..m], &y[1..m], &mut u[..m - 1]);
        for i in 0..m - 1 {
            u[i] = y[i] - v[i] * c;
        }
    }

    /// The blocked signals u = B^H y with real and imaginary parts apart (first M - 1 entries),
    /// in the canceller's precision.
    pub fn apply_split(&self, y: &[Complex], ur: &mut [f32], ui: &mut [f32]) {
        apply_split(&self.v, self.scale, y, ur, ui);
    }

    /// The combination B q of the basis columns (length M), e.g. the canceller's share of the
    /// beamformer weights.
    pub fn combine(&self, q: &[Complex], out: &mut [Complex]) {
        combine(&self.v, self.scale, q, out);
    }
}

/// One label's blocking matrices for every bin, stored bin after bin in one block, so the
/// per-frame sweep over the bins reads memory in order instead of chasing a pointer per bin.
#[derive(Debug, Clone, Default)]
pub struct BlockingBank {
    m: usize,
    v: Vec<Complex>,
    scale: Vec<f64>,
}

impl BlockingBank {
    /// Empty matrices for `m` microphones and `bins` bins.
    pub fn new(m: usize, bins: usize) -> Self {
        Self {
            m,
            v: vec![Complex::new(0.0, 0.0); m * bins],
            scale: vec![0.0; bins],
        }
    }

    /// Number of microphones.
    pub fn mics(&self) -> usize {
        self.m
    }

    /// Number of bins.
    pub fn bins(&self) -> usize {
        self.scale.len()
    }

    /// Builds bin `k`'s reflector for steering vector `a` (length M).
    pub fn set(&mut self, k: usize, a: &[Complex]) {
        let m = self.m;
        self.scale[k] = reflector(&a[..m], &mut self.v[k * m..(k + 1) * m]);
    }

    /// Bin `k`'s blocked signals, as [`Blocking::apply_split`].
    pub fn apply_split(&self, k: usize, y: &[Complex], ur: &mut [f32], ui: &mut [f32]) {
        let m = self.m;
        apply_split(&self.v[k * m..(k + 1) * m], self.scale[k], y, ur, ui);
    }

    /// Bin `k`'s combination of basis columns, as [`Blocking::combine`].
    pub fn combine(&self, k: usize, q: &[Complex], out: &mut [Complex]) {
        let m = self.m;
        combine(&self.v[k * m..(k + 1) * m], self.scale[k], q, out);
    }
}

/// Writes the reflector vector v for steering `a` (same length); returns its scale s.
fn reflector(a: &[Complex], v: &mut [Complex]) -> f64 {
    let m = a.len();
    let a0 = a[0].norm_sqr().sqrt();
    // Rotating x so that x_0 >= 0 spans the same line and keeps the basis continuous.
    let rot = if a0 > 1e-300 {
        a[0].conj() / a0
    } else {
        Complex::new(1.0, 0.0)
    };
    let v = &mut v[..m];
    let mut norm2 = 0.0;
    for i in 0..m {
        v[i] = a[i] * rot;
        norm2 += v[i].norm_sqr();
    }
    let norm = norm2.sqrt();
    v[0].re += norm;
    let vv = 2.0 * norm * (norm + a0);
    if vv > 1e-300 && vv.is_finite() {
        2.0 / vv
    } else {
        0.0
    }
}

/// s v^H y, the component removed by the reflection.
fn projection(v: &[Complex], scale: f64, y: &[Complex]) -> Complex {
    let m = v.len();
    let y = &y[..m];
    let (mut re, mut im) = (0.0, 0.0);
    for i in 0..m {
        re += v[i].re * y[i].re + v[i].im * y[i].im;
        im += v[i].re * y[i].im - v[i].im * y[i].re;
    }
    Complex::new(re * scale, im * scale)
}

fn apply_split(v: &[Complex], scale: f64, y: &[Complex], ur: &mut [f32], ui: &mut [f32]) {
    let c = projection(v, scale, y);
    let m = v.len();
    let (v, y, ur, ui) = (&v[1..m], &y[1..m], &mut ur[..m - 1], &mut ui[..m - 1]);
    for i in 0..m - 1 {
        ur[i] = (y[i].re - (v[i].re * c.re - v[i].im * c.im)) as f32;
        ui[i] = (y[i].im - (v[i].re * c.im + v[i].im * c.re)) as f32;
    }
}

fn combine(v: &[Complex], scale: f64, q: &[Complex], out: &mut [Complex]) {
    // H [0; q] = [0; q] - s v (v^H [0; q]).
    let mut vq = Complex::new(0.0, 0.0);
    for (v, q) in v[1..].iter().zip(q) {
        vq += v.conj() * q;
    }
    let c = vq * scale;
    out[0] = -v[0] * c;
    for ((o, v), q) in out[1..].iter_mut().zip(&v[1..]).zip(q) {
        *o = q - v * c;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dsp::inner;

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
                let ip: Complex = inner(&cols[i], &y2);
                assert!((ip - u[i]).norm() < 1e-12);
            }
        }
    }

    #[test]
    fn bank_matches_one_matrix_per_bin() {
        let vs = vecs();
        let m = vs[0].len();
        let mut bank = BlockingBank::new(m, vs.len());
        for (k, a) in vs.iter().enumerate() {
            bank.set(k, a);
        }
        let y: Vec<Complex> = (0..m)
            .map(|i| Complex::new(i as f64, 1.0 - i as f64))
            .collect();
        for (k, a) in vs.iter().enumerate() {
            let mut one = Blocking::new(m);
            one.set(a);
            let (mut r1, mut i1) = (vec![0.0f32; m - 1], vec![0.0f32; m - 1]);
            let (mut r2, mut i2) = (vec![0.0f32; m - 1], vec![0.0f32; m - 1]);
            one.apply_split(&y, &mut r1, &mut i1);
            bank.apply_split(k, &y, &mut r2, &mut i2);
            assert_eq!((r1, i1), (r2, i2));
            let q: Vec<Complex> = y[..m - 1].to_vec();
            let (mut c1, mut c2) = (
                vec![Complex::new(0.0, 0.0); m],
                vec![Complex::new(0.0, 0.0); m],
            );
            one.combine(&q, &mut c1);
            bank.combine(k, &q, &mut c2);
            assert_eq!(c1, c2);
        }
    }
}
