//! Harmonic amplitude fit: the labels' voices as sums of harmonics of their F0s, fitted jointly
//! to the reference microphone's low bins.
//!
//! Each harmonic h of a label's F0 is a column of the window's transform centred on bin
//! h F0 / (Hz per bin); the columns' complex amplitudes are the regularised least-squares fit
//! of all labels' columns to the bins, each column's regularisation inversely proportional to
//! its label's claim on that harmonic (its evidence in the contest for it). Each label's fitted
//! power per bin then says how much of the bin is its voice, and the residual how much is
//! nobody's harmonic (noise, reverberation of earlier pitches, unvoiced sounds). Where the
//! array cannot tell labels apart this divides a bin by the power each voice has there, not
//! by which comb is strongest overall, so two voices sharing a bin each keep their part.

use crate::dsp::Complex;
use crate::separate::cholesky;

/// Bins on either side of a harmonic's centre that its column covers: the periodic Hann
/// window's main lobe is 2 bins wide each way and its side lobes are 31 dB down and falling.
const HALF_WIDTH: usize = 3;
/// Columns below this claim are left out (their regularisation would hold them near zero).
const MIN_PRIOR: f64 = 1e-3;
/// At most this many columns, the best claimed kept: the solve grows with their cube, and
/// three voices at the lowest F0 need 42 (about 40 us), so a room of many voiced labels stays
/// within a hop's budget.
const MAX_COLUMNS: usize = 64;

/// One harmonic's column.
#[derive(Debug, Clone, Copy)]
struct Column {
    label: usize,
    lo: usize,
    taps: [Complex; 2 * HALF_WIDTH + 1],
    len: usize,
    prior: f64,
}

impl Column {
    fn hi(&self) -> usize {
        self.lo + self.len
    }
}

/// The fit's constants and scratch.
#[derive(Debug, Clone, Default)]
pub struct HarmonicFit {
    frame: usize,
    hz_per_bin: f64,
    top: usize,
    loading: f64,
    columns: Vec<Column>,
    gram: Vec<Complex>,
    amplitudes: Vec<Complex>,
    model: Vec<Complex>,
}

impl HarmonicFit {
    /// A fit of bins 1..`top` of a `frame`-sample STFT at `hz_per_bin`, with `loading` the
    /// regularisation of a fully claimed column relative to the mean column energy.
    pub fn new(frame: usize, hz_per_bin: f64, top: usize, loading: f64) -> Self {
        Self {
            frame,
            hz_per_bin,
            top: top.min(frame / 2),
            loading,
            ..Self::default()
        }
    }

    /// The bins fitted are below this one.
    pub fn top(&self) -> usize {
        self.top
    }

    /// Fits the harmonics of `f0s` (Hz, one per label; 0 for none) to `x` (the reference
    /// microphone's bins from 0, at least `top` of them). `prior(label, bin)` is the label's
    /// claim on its harmonic at (fractional) `bin`, in [0, 1]. On return `power[label * top + k]`
    /// is the label's fitted power in bin k and `residual[k]` what no harmonic explains; false
    /// (and both zero) when no column was claimed or the system could not be solved.
    pub fn fit(
        &mut self,
        x: &[Complex],
        f0s: &[f64],
        prior: impl Fn(usize, f64) -> f64,
        power: &mut Vec<f64>,
        residual: &mut Vec<f64>,
    ) -> bool {
        let top = self.top.min(x.len());
        power.clear();
        power.resize(f0s.len() * top, 0.0);
        residual.clear();
        residual.resize(top, 0.0);
        self.columns.clear();
        for (label, &f0) in f0s.iter().enumerate() {
            let step = f0 / self.hz_per_bin;
            if !(step.is_finite() && step > 0.0) {
                continue;
            }
            let mut centre = step;
            while centre < top as f64 {
                let p = prior(label, centre);
                if p >= MIN_PRIOR
                    && let Some(c) = self.column(label, centre, p.min(1.0), top)
                {
                    self.columns.push(c);
                }
                centre += step;
            }
        }
        if self.columns.len() > MAX_COLUMNS {
            self.columns
                .sort_unstable_by(|a, b| b.prior.total_cmp(&a.prior));
            self.columns.truncate(MAX_COLUMNS);
        }
        let n = self.columns.len();
        if n == 0 || !self.solve(x) {
            return false;
        }
        self.model.clear();
        self.model.resize(f0s.len() * top, Complex::new(0.0, 0.0));
        for (c, a) in self.columns.iter().zip(&self.amplitudes) {
            let m = &mut self.model[c.label * top..(c.label + 1) * top];
            for (k, t) in (c.lo..c.hi()).zip(&c.taps) {
                m[k] += a * t;
            }
        }
        for (k, (r, xk)) in residual.iter_mut().zip(x).enumerate() {
            let mut explained = Complex::new(0.0, 0.0);
            for label in 0..f0s.len() {
                let m = self.model[label * top + k];
                power[label * top + k] = m.norm_sqr();
                explained += m;
            }
            *r = (xk - explained).norm_sqr();
        }
        true
    }

    /// The column of a harmonic centred on fractional bin `centre`, clipped to bins 1..top.
    fn column(&self, label: usize, centre: f64, prior: f64, top: usize) -> Option<Column> {
        let lo = (centre - HALF_WIDTH as f64).ceil().max(1.0) as usize;
        let hi = ((centre + HALF_WIDTH as f64).floor() as usize + 1).min(top);
        if lo >= hi {
            return None;
        }
        let mut taps = [Complex::new(0.0, 0.0); 2 * HALF_WIDTH + 1];
        for (t, k) in taps.iter_mut().zip(lo..hi) {
            *t = hann_transform(k as f64 - centre, self.frame);
        }
        Some(Column {
            label,
            lo,
            taps,
            len: hi - lo,
            prior,
        })
    }

    /// The columns' amplitudes: (A^H A + diag(loading x mean energy / prior)) a = A^H x.
    fn solve(&mut self, x: &[Complex]) -> bool {
        let n = self.columns.len();
        self.gram.clear();
        self.gram.resize(n * n, Complex::new(0.0, 0.0));
        self.amplitudes.clear();
        self.amplitudes.resize(n, Complex::new(0.0, 0.0));
        let cols = &self.columns;
        let mut energy = 0.0;
        for (i, a) in cols.iter().enumerate() {
            self.amplitudes[i] = (a.lo..a.hi())
                .zip(&a.taps)
                .map(|(k, t)| t.conj() * x[k])
                .sum();
            for (j, b) in cols.iter().enumerate().skip(i) {
                let (lo, hi) = (a.lo.max(b.lo), a.hi().min(b.hi()));
                let g: Complex = (lo..hi)
                    .map(|k| a.taps[k - a.lo].conj() * b.taps[k - b.lo])
                    .sum();
                self.gram[i * n + j] = g;
                self.gram[j * n + i] = g.conj();
            }
            energy += self.gram[i * n + i].re;
        }
        let scale = self.loading * energy / n as f64;
        for (i, c) in cols.iter().enumerate() {
            self.gram[i * n + i] += Complex::new(scale / c.prior, 0.0);
        }
        if !cholesky::factor(&mut self.gram, n) {
            return false;
        }
        cholesky::solve(&self.gram, n, &mut self.amplitudes);
        self.amplitudes
            .iter()
            .all(|a| a.re.is_finite() && a.im.is_finite())
    }
}

/// The transform of an `n`-sample periodic Hann window at `d` bins from a complex tone's
/// frequency: bin k of the STFT of e^{j 2 pi nu t / n} is `hann_transform(k - nu, n)`.
pub fn hann_transform(d: f64, n: usize) -> Complex {
    0.5 * dirichlet(d, n) - 0.25 * dirichlet(d - 1.0, n) - 0.25 * dirichlet(d + 1.0, n)
}

/// sum_{t<n} e^{-j 2 pi d t / n}.
fn dirichlet(d: f64, n: usize) -> Complex {
    let nf = n as f64;
    let s = (std::f64::consts::PI * d / nf).sin();
    let magnitude = if s.abs() < 1e-12 {
        nf
    } else {
        (std::f64::consts::PI * d).sin() / s
    };
    Complex::from_polar(magnitude, -std::f64::consts::PI * d * (nf - 1.0) / nf)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::dsp::Stft;

    /// Frame length and sample rate of the test signals.
    pub const N: usize = 1024;
    pub const FS: f64 = 16_000.0;

    /// The STFT bins of one `N`-sample frame.
    pub fn spectrum(x: &[f64]) -> Vec<Complex> {
        let mut out = vec![Complex::new(0.0, 0.0); N / 2 + 1];
        Stft::new(N).forward(x, &mut out);
        out
    }

    /// One frame of a steady voice on `f0` with harmonic h + 1 of amplitude `amps[h]` and
    /// phase `phase` (h + 1).
    pub fn voice(f0: f64, amps: &[f64], phase: f64) -> Vec<f64> {
        (0..N)
            .map(|t| {
                amps.iter()
                    .enumerate()
                    .map(|(h, a)| {
                        let w = 2.0 * std::f64::consts::PI * f0 * (h + 1) as f64 / FS;
                        a * (w * t as f64 + phase * (h + 1) as f64).cos()
                    })
                    .sum()
            })
            .collect()
    }

    #[test]
    fn the_window_transform_is_what_the_stft_gives_a_tone() {
        let nu = 40.3;
        let x: Vec<f64> = (0..N)
            .map(|t| (2.0 * std::f64::consts::PI * nu * t as f64 / N as f64 + 0.7).cos())
            .collect();
        let s = spectrum(&x);
        for (k, sk) in s.iter().enumerate().take(45).skip(36) {
            let model = 0.5 * Complex::from_polar(1.0, 0.7) * hann_transform(k as f64 - nu, N)
                + 0.5 * Complex::from_polar(1.0, -0.7) * hann_transform(k as f64 + nu, N);
            assert!((sk - model).norm() < 1e-6 * N as f64, "bin {k}");
        }
    }

    #[test]
    fn two_voices_sharing_bins_each_get_their_own_power() {
        // 125 Hz and 200 Hz: their 8th and 5th harmonics meet at 1 kHz, others interleave.
        let (a_amps, b_amps) = ([1.0, 0.8, 0.6, 0.5, 0.4, 0.3], [0.2, 0.3, 0.25, 0.2]);
        let a = voice(125.0, &a_amps, 0.3);
        let b = voice(200.0, &b_amps, 1.1);
        let mix: Vec<f64> = a.iter().zip(&b).map(|(p, q)| p + q).collect();
        let (sa, sb, sx) = (spectrum(&a), spectrum(&b), spectrum(&mix));
        let hz = FS / N as f64;
        let top = (1000.0 / hz) as usize;
        let mut fit = HarmonicFit::new(N, hz, top, 1e-6);
        let (mut power, mut residual) = (Vec::new(), Vec::new());
        assert!(fit.fit(&sx, &[125.0, 200.0], |_, _| 1.0, &mut power, &mut residual));
        // In every bin with voice in it, each label's fitted power is its voice's.
        let total: f64 = sx[1..top].iter().map(|v| v.norm_sqr()).sum();
        let (mut err, mut left) = (0.0, 0.0);
        for k in 1..top {
            err += (power[k] - sa[k].norm_sqr()).abs() + (power[top + k] - sb[k].norm_sqr()).abs();
            left += residual[k];
        }
        assert!(err < 0.02 * total, "power error {:.4}", err / total);
        assert!(left < 1e-3 * total, "residual {:.5}", left / total);
    }

    #[test]
    fn an_unclaimed_voice_is_not_fitted() {
        let a = voice(150.0, &[1.0, 0.5, 0.3], 0.0);
        let sx = spectrum(&a);
        let hz = FS / N as f64;
        let top = (1000.0 / hz) as usize;
        let mut fit = HarmonicFit::new(N, hz, top, 1e-3);
        let (mut power, mut residual) = (Vec::new(), Vec::new());
        // Label 1 claims the same F0 with a claim below the cut: it is left out.
        let claims = |label: usize, _| if label == 0 { 0.0 } else { 1e-4 };
        assert!(!fit.fit(&sx, &[150.0, 150.0], claims, &mut power, &mut residual));
        assert!(power.iter().all(|&p| p == 0.0));
    }

    #[test]
    fn of_two_labels_reading_one_f0_the_stronger_claim_takes_most() {
        let a = voice(180.0, &[1.0, 0.7, 0.5, 0.4], 0.2);
        let sx = spectrum(&a);
        let hz = FS / N as f64;
        let top = (1000.0 / hz) as usize;
        let mut fit = HarmonicFit::new(N, hz, top, 1e-2);
        let (mut power, mut residual) = (Vec::new(), Vec::new());
        let claims = |label: usize, _| if label == 0 { 1.0 } else { 0.05 };
        assert!(fit.fit(&sx, &[180.0, 180.0], claims, &mut power, &mut residual));
        let (p0, p1): (f64, f64) = (power[..top].iter().sum(), power[top..].iter().sum());
        assert!(p0 > 50.0 * p1, "{p0} against {p1}");
    }

    #[test]
    fn many_voiced_labels_are_fitted_within_the_column_cap() {
        let hz = FS / N as f64;
        let top = (1000.0 / hz) as usize;
        let f0s: Vec<f64> = (0..8).map(|i| 70.0 + 3.0 * f64::from(i)).collect();
        let mut x = vec![Complex::new(0.0, 0.0); top];
        x[10] = Complex::new(1.0, 0.0);
        let mut fit = HarmonicFit::new(N, hz, top, 1e-3);
        let (mut power, mut residual) = (Vec::new(), Vec::new());
        // Label 0's claim is the strongest: its columns are all kept.
        let claims = |label: usize, _| if label == 0 { 1.0 } else { 0.5 };
        assert!(fit.fit(&x, &f0s, claims, &mut power, &mut residual));
        assert_eq!(fit.columns.len(), MAX_COLUMNS);
        let kept = fit.columns.iter().filter(|c| c.label == 0).count();
        assert_eq!(kept, (1000.0 / 70.0) as usize);
        assert!(power.iter().chain(&residual).all(|v| v.is_finite()));
    }
}
