//! The GSC's fixed branch: unit response toward one label and nulls toward the others
//! (spec 003 eq. 27, the minimum-norm solution of D^H W = e_i), diagonally loaded:
//! W_i = D (D^H D + eps I)^{-1} e_i / c_i with eps = loading * trace(D^H D) / N.
//!
//! The loading keeps two labels at nearly the same angle, and the low-frequency bins where every
//! steering vector looks alike, from blowing up the white-noise gain: the nulls there become
//! shallow instead of the output exploding. The scale c_i = a_i^H D (D^H D + eps I)^{-1} e_i (real,
//! in (0, 1]) restores an exact unit response toward the label; for two identical columns the
//! result degrades gracefully to delay-and-sum.

use super::cholesky;
use crate::dsp::{Complex, inner};

/// Solver of the loaded null-steering problem for one constraint matrix, reused across bins.
///
/// With G + eps I = L L^H it keeps L^{-1}, so X = (G + eps I)^{-1} = L^{-H} L^{-1} is applied as two
/// triangular products and diag(X) (for the unit-response scale) is a sum of squares.
#[derive(Debug, Clone, Default)]
pub struct NullSteering {
    n: usize,
    gram: Vec<Complex>,
    linv: Vec<Complex>,
    z: Vec<Complex>,
    t: Vec<Complex>,
    scale: Vec<f64>,
    eps: f64,
    /// The first column's weights, kept by [`NullSteering::prepare_first`].
    first: Vec<Complex>,
}

impl NullSteering {
    /// Prepares the weights for the constraint matrix `d` (`n` steering columns of `m` entries,
    /// column after column).
    pub fn prepare(&mut self, d: &[Complex], n: usize, m: usize, loading: f64) {
        // Small label counts get copies with constant loop bounds (unrolled).
        match (n, m) {
            (1, 8) => self.prepare_sized(d, 1, 8, loading),
            (2, 8) => self.prepare_sized(d, 2, 8, loading),
            (3, 8) => self.prepare_sized(d, 3, 8, loading),
            (4, 8) => self.prepare_sized(d, 4, 8, loading),
            (1, _) => self.prepare_sized(d, 1, m, loading),
            (2, _) => self.prepare_sized(d, 2, m, loading),
            (3, _) => self.prepare_sized(d, 3, m, loading),
            (4, _) => self.prepare_sized(d, 4, m, loading),
            _ => self.prepare_sized(d, n, m, loading),
        }
    }

    /// Prepares the weights for `d` as [`NullSteering::prepare`] does and keeps the first
    /// column's, for a label whose constraint set is its own (itself first): its output is then
    /// m products per frame instead of the whole system's n m + n^2.
    pub fn prepare_first(&mut self, d: &[Complex], n: usize, m: usize, loading: f64) {
        self.prepare(d, n, m, loading);
        let mut w = std::mem::take(&mut self.first);
        w.resize(m, Complex::new(0.0, 0.0));
        self.weights(d, m, 0, &mut w);
        self.first = w;
    }

    /// W_0^H y with the weights kept by [`NullSteering::prepare_first`].
    pub fn first_output(&self, y: &[Complex]) -> Complex {
        inner(&self.first, y)
    }

    /// The weights kept by [`NullSteering::prepare_first`].
    pub fn first_weights(&self) -> &[Complex] {
        &self.first
    }

    #[inline(always)]
    fn prepare_sized(&mut self, d: &[Complex], n: usize, m: usize, loading: f64) {
        self.n = n;
        let zero = Complex::new(0.0, 0.0);
        self.gram.resize(n * n, zero);
        self.linv.resize(n * n, zero);
        self.z.resize(n, zero);
        self.t.resize(n, zero);
        self.scale.resize(n, 1.0);
        let mut trace = 0.0;
        for i in 0..n {
            let ci = &d[i * m..(i + 1) * m];
            for j in i..n {
                let cj = &d[j * m..(j + 1) * m];
                let (mut re, mut im) = (0.0, 0.0);
                for k in 0..m {
                    re += ci[k].re * cj[k].re + ci[k].im * cj[k].im;
                    im += ci[k].re * cj[k].im - ci[k].im * cj[k].re;
                }
                self.gram[i * n + j] = Complex::new(re, im);
                self.gram[j * n + i] = Complex::new(re, -im);
            }
            trace += self.gram[i * n + i].re;
        }
        let eps = (loading * trace / n.max(1) as f64).max(1e-300);
        self.eps = eps;
        for i in 0..n {
            // Keep the unloaded diagonal for the fallback below.
            self.scale[i] = self.gram[i * n + i].re;
            self.gram[i * n + i].re += eps;
        }
        for x in self.linv[..n * n].iter_mut() {
            *x = zero;
        }
        if cholesky::factor(&mut self.gram[..n * n], n) {
            let (l, li) = (&self.gram, &mut self.linv);
            for j in 0..n {
                li[j * n + j] = Complex::new(1.0 / l[j * n + j].re, 0.0);
                for i in j + 1..n {
                    let mut s = zero;
                    for p in j..i {
                        s += l[i * n + p] * li[p * n + j];
                    }
                    li[i * n + j] = -s / l[i * n + i].re;
                }
            }
        } else {
            // Not positive definite (non-finite steering): fall back to delay-and-sum per column.
            for i in 0..n {
                let g = if self.scale[i].is_finite() {
                    self.scale[i]
                } else {
                    0.0
                };
                self.linv[i * n + i] = Complex::new(1.0 / (g + eps).sqrt(), 0.0);
            }
        }
        for i in 0..n {
            // X_ii = sum_k |Linv_ki|^2; (G X)_ii = 1 - eps X_ii is real and in (0, 1].
            let xii: f64 = (i..n).map(|k| self.linv[k * n + i].norm_sqr()).sum();
            let c = 1.0 - eps * xii;
            self.scale[i] = if c > 1e-12 && c.is_finite() {
                1.0 / c
            } else {
                0.0
            };
        }
    }

    /// Outputs W_i^H y of every column's beamformer at once.
    pub fn outputs(&mut self, d: &[Complex], m: usize, y: &[Complex], out: &mut [Complex]) {
        match (self.n, m) {
            (2, 8) => self.outputs_sized(d, 2, 8, y, out),
            (3, 8) => self.outputs_sized(d, 3, 8, y, out),
            (4, 8) => self.outputs_sized(d, 4, 8, y, out),
            (n, _) => self.outputs_sized(d, n, m, y, out),
        }
    }

    #[inline(always)]
    fn outputs_sized(
        &mut self,
        d: &[Complex],
        n: usize,
        m: usize,
        y: &[Complex],
        out: &mut [Complex],
    ) {
        let y = &y[..m];
        for i in 0..n {
            let a = &d[i * m..(i + 1) * m];
            let (mut re, mut im) = (0.0, 0.0);
            for k in 0..m {
                re += a[k].re * y[k].re + a[k].im * y[k].im;
                im += a[k].re * y[k].im - a[k].im * y[k].re;
            }
            self.z[i] = Complex::new(re, im);
        }
        // W_i^H y = e_i^T X D^H y / c_i (X Hermitian), X = Linv^H Linv.
        for k in 0..n {
            let mut s = Complex::new(0.0, 0.0);
            for p in 0..=k {
                s += self.linv[k * n + p] * self.z[p];
            }
            self.t[k] = s;
        }
        for (i, o) in out.iter_mut().enumerate().take(n) {
            let mut s = Complex::new(0.0, 0.0);
            for k in i..n {
                s += self.linv[k * n + i].conj() * self.t[k];
            }
            *o = s * self.scale[i];
        }
    }

    /// Column `i`'s beamformer's power response toward every column, |W_i^H d_j|^2, written to
    /// `out` (length n). With G the unloaded Gram matrix, X G = I - eps X, so the responses come
    /// from X alone: W_i^H d_j = c_i^-1 (delta_ij - eps X_ij), no beamformer applied.
    pub fn cross_powers(&self, i: usize, out: &mut [f64]) {
        for (j, o) in out.iter_mut().enumerate().take(self.n) {
            let delta = if i == j { 1.0 } else { 0.0 };
            *o = ((Complex::new(delta, 0.0) - self.inverse_at(i, j) * self.eps) * self.scale[i])
                .norm_sqr();
        }
    }

    /// X_ij of X = (G + eps I)^{-1} = Linv^H Linv: sum_k conj(Linv_ki) Linv_kj.
    fn inverse_at(&self, i: usize, j: usize) -> Complex {
        let n = self.n;
        let mut x = Complex::new(0.0, 0.0);
        for k in i.max(j)..n {
            x += self.linv[k * n + i].conj() * self.linv[k * n + j];
        }
        x
    }

    /// The weights W_i (length `m`) of column `i`'s beamformer.
    pub fn weights(&self, d: &[Complex], m: usize, i: usize, out: &mut [Complex]) {
        let n = self.n;
        out[..m].fill(Complex::new(0.0, 0.0));
        for j in 0..n {
            // x_j = (X e_i)_j.
            let x = self.inverse_at(j, i) * self.scale[i];
            for (o, a) in out.iter_mut().zip(&d[j * m..(j + 1) * m]) {
                *o += a * x;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use crate::separate::steering::Steering;

    fn uca(n: usize, r: f64) -> Vec<Vec3> {
        (0..n)
            .map(|i| {
                let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                Vec3::new(r * a.cos(), r * a.sin(), 1.0)
            })
            .collect()
    }

    #[test]
    fn unit_response_toward_label_and_deep_nulls_elsewhere() {
        let mics = uca(8, 0.05);
        let srcs = [
            Vec3::new(1.5, 0.3, 1.5),
            Vec3::new(-0.8, 1.2, 1.6),
            Vec3::new(-0.5, -1.5, 1.4),
        ];
        for f in [500.0, 1000.0, 2000.0, 4000.0, 7000.0] {
            let omega = 2.0 * std::f64::consts::PI * f;
            let mut d = vec![Complex::new(0.0, 0.0); 3 * 8];
            for (i, s) in srcs.iter().enumerate() {
                Steering::near_field(&mics, &mics[0], s, 343.0).at(omega, &mut d[i * 8..]);
            }
            let mut ns = NullSteering::default();
            ns.prepare(&d, 3, 8, 1e-2);
            let mut w = vec![Complex::new(0.0, 0.0); 8];
            for i in 0..3 {
                ns.weights(&d, 8, i, &mut w);
                for j in 0..3 {
                    let r = inner(&w, &d[j * 8..(j + 1) * 8]);
                    if i == j {
                        assert!((r - Complex::new(1.0, 0.0)).norm() < 1e-9, "{f} Hz: {r}");
                    } else {
                        let db = 20.0 * r.norm().log10();
                        // Normalised correlation of the two steering vectors: near 1 the labels
                        // look alike to the array (low frequency, or spatial aliasing at 7 kHz
                        // for this 10 cm array) and the loading trades null depth for noise gain.
                        let rho =
                            inner(&d[i * 8..(i + 1) * 8], &d[j * 8..(j + 1) * 8]).norm() / 8.0;
                        let need = if rho < 0.85 { -30.0 } else { -20.0 };
                        assert!(
                            db < need,
                            "{f} Hz: null {i}->{j} only {db:.1} dB (rho {rho:.2})"
                        );
                    }
                }
                // Bounded white-noise gain: at most 10 dB above delay-and-sum's 1/M.
                let wn: f64 = w.iter().map(|x| x.norm_sqr()).sum();
                assert!(wn < 10.0 / 8.0, "{f} Hz: |w|^2 = {wn}");
                // The closed-form power cross-responses agree with the weights'.
                let mut cross = [0.0; 3];
                ns.cross_powers(i, &mut cross);
                for j in 0..3 {
                    let r = inner(&w, &d[j * 8..(j + 1) * 8]).norm_sqr();
                    assert!((cross[j] - r).abs() < 1e-9 * r.max(1.0), "{f} Hz");
                }
                // outputs() agrees with the explicit weights.
                let y: Vec<Complex> = (0..8).map(|k| Complex::new(k as f64, -1.0)).collect();
                let mut out = vec![Complex::new(0.0, 0.0); 3];
                ns.outputs(&d, 8, &y, &mut out);
                assert!((out[i] - inner(&w, &y)).norm() < 1e-9);
                // So do the kept first-column weights, with the label's column first.
                let mut own = d[i * 8..(i + 1) * 8].to_vec();
                own.extend(
                    (0..3)
                        .filter(|&j| j != i)
                        .flat_map(|j| d[j * 8..(j + 1) * 8].to_vec()),
                );
                let mut first = NullSteering::default();
                first.prepare_first(&own, 3, 8, 1e-2);
                assert!((first.first_output(&y) - out[i]).norm() < 1e-9);
            }
        }
    }

    #[test]
    fn coincident_labels_degrade_to_delay_and_sum() {
        let mics = uca(4, 0.05);
        let s = Steering::near_field(&mics, &mics[0], &Vec3::new(1.0, 1.0, 1.0), 343.0);
        let mut d = vec![Complex::new(0.0, 0.0); 8];
        s.at(3000.0, &mut d[..4]);
        s.at(3000.0, &mut d[4..]);
        let mut ns = NullSteering::default();
        ns.prepare(&d, 2, 4, 1e-2);
        let mut w = vec![Complex::new(0.0, 0.0); 4];
        ns.weights(&d, 4, 0, &mut w);
        let r = inner(&w, &d[..4]);
        assert!((r - Complex::new(1.0, 0.0)).norm() < 1e-9);
        let wn: f64 = w.iter().map(|x| x.norm_sqr()).sum();
        let an: f64 = d[..4].iter().map(|x| x.norm_sqr()).sum();
        assert!(
            (wn - 1.0 / an).abs() < 1e-6 / an,
            "white-noise gain blew up: {wn}"
        );
    }
}
