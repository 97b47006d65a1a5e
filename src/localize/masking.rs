//! Removal of found sources in the time-frequency domain: which sub-bands a found source
//! dominates, and the bin weights that take them out before the next search.
//!
//! The band is cut into sub-bands of a few adjacent bins. Each sub-band's spatial covariance
//! (the smoothed, whitened cross-spectra summed over its bins) has a principal eigenvector: the
//! array response of whatever dominates the sub-band. Summing adjacent bins keeps the direct
//! path, whose phases barely turn across a sub-band, and averages out the reverberation and the
//! coherent reflections, whose relative phases do. A found source dominates a sub-band as much
//! as its steering vector `a` lines up with that eigenvector `v`: |a^H v|^2 / (M |v|^2), near 1
//! where it dominates and the array's beam-pattern leakage where another source does. Unlike
//! the sub-band's SRP at the source (its share of a reverberant sub-band's power, often well
//! under one half), this measure does not shrink with reverberation, so its mask
//! prod_i (1 - dominance_i)^exponent removes the found sources' sub-bands (with their
//! reflections) and keeps those a quieter talker dominates: W-disjoint orthogonality of speech
//! leaves such a talker dominant in some sub-bands even where it is 10 dB below the other.

use std::f64::consts::PI;

use crate::dsp::{Complex, inner};

use super::gcc::GccBank;

/// Sub-band covariances of one frame, their principal eigenvectors and the dominance of every
/// source found so far.
pub(crate) struct SubbandMask {
    /// Bins per sub-band.
    width: usize,
    /// Power iterations towards each sub-band's principal eigenvector.
    iterations: usize,
    /// Mask weight of a bin is prod_i (1 - dominance_i)^exponent.
    exponent: f64,
    /// Microphones of every pair.
    pairs: Vec<(usize, usize)>,
    mics: usize,
    /// Per sub-band and pair: the summed smoothed cross-spectrum.
    sub: Vec<Complex>,
    /// Per sub-band: the diagonal of its covariance (the mean over pairs of the bin norms).
    diag: Vec<f64>,
    /// Centre angular frequency of the first sub-band and the step between sub-bands (rad/s).
    omega0: f64,
    omega_step: f64,
    /// Per sub-band and microphone: the principal eigenvector (unit norm), once computed.
    principal: Vec<Complex>,
    has_principal: bool,
    /// Per found source and sub-band: its dominance.
    dominance: Vec<Vec<f64>>,
    /// Per sub-band: the weight left once the sources (but one) are removed.
    mask: Vec<f64>,
    steer: Vec<Complex>,
    step: Vec<Complex>,
    next: Vec<Complex>,
}

impl SubbandMask {
    /// The sub-bands of `bank`.
    pub fn new(bank: &GccBank, iterations: usize, exponent: f64, fs: f64) -> Self {
        let (width, count) = (bank.subband_width(), bank.subband_count());
        let mics = bank
            .pairs
            .iter()
            .map(|p| p.a.max(p.b) + 1)
            .max()
            .unwrap_or(0);
        let bin = 2.0 * PI * fs / bank.frame as f64;
        Self {
            width,
            iterations,
            exponent,
            pairs: bank.pairs.iter().map(|p| (p.a, p.b)).collect(),
            mics,
            sub: vec![Complex::new(0.0, 0.0); count * bank.pairs.len()],
            diag: vec![0.0; count],
            omega0: bin * (bank.band.0 as f64 + 0.5 * (width as f64 - 1.0)),
            omega_step: bin * width as f64,
            principal: vec![Complex::new(0.0, 0.0); count * mics],
            has_principal: false,
            dominance: Vec::new(),
            mask: vec![1.0; count],
            steer: vec![Complex::new(0.0, 0.0); mics],
            step: vec![Complex::new(0.0, 0.0); mics],
            next: vec![Complex::new(0.0, 0.0); mics],
        }
    }

    /// Starts a frame: sums the bank's smoothed cross-spectra into the sub-bands and forgets the
    /// sources of the previous search.
    pub fn start(&mut self, bank: &GccBank) {
        let nb = bank.band.1 + 1 - bank.band.0;
        let np = self.pairs.len();
        for q in 0..np {
            let s = &bank.smoothed[q * nb..(q + 1) * nb];
            for (b, chunk) in s.chunks(self.width).enumerate() {
                self.sub[b * np + q] = chunk.iter().sum();
            }
        }
        for (d, chunk) in self.diag.iter_mut().zip(bank.bin_norm.chunks(self.width)) {
            *d = chunk.iter().sum::<f64>() / np.max(1) as f64;
        }
        self.has_principal = false;
        self.dominance.clear();
    }

    /// Forgets the sources added so far but keeps the frame's sub-band covariances and their
    /// principal eigenvectors, to mask another set of sources in the same frame.
    pub fn clear_sources(&mut self) {
        self.dominance.clear();
    }

    /// Adds a found source whose wave reaches the microphones at `delays` (seconds).
    pub fn add(&mut self, delays: &[f64]) {
        if !self.has_principal {
            // The first source dominates most sub-bands, so its steering vector is the start
            // nearest to most eigenvectors.
            self.find_principal(delays);
        }
        let mut dom = vec![0.0; self.diag.len()];
        self.dominance_of(delays, &mut dom);
        self.dominance.push(dom);
    }

    /// Replaces source `i` by one at `delays` (after it was re-estimated).
    pub fn set(&mut self, i: usize, delays: &[f64]) {
        let mut dom = std::mem::take(&mut self.dominance[i]);
        self.dominance_of(delays, &mut dom);
        self.dominance[i] = dom;
    }

    /// Recomputes the bank's tables with every source added so far removed, except `keep`.
    pub fn apply(&mut self, bank: &mut GccBank, keep: Option<usize>) {
        self.weights(keep);
        bank.tabulate_subbands(Some(&self.mask));
    }

    /// The per-sub-band weights with every source added so far removed, except `keep`.
    pub fn weights(&mut self, keep: Option<usize>) -> &[f64] {
        self.mask.fill(1.0);
        for (i, dom) in self.dominance.iter().enumerate() {
            if Some(i) == keep {
                continue;
            }
            for (m, d) in self.mask.iter_mut().zip(dom) {
                let k = 1.0 - d;
                *m *= if self.exponent == self.exponent.round() && self.exponent <= 8.0 {
                    k.powi(self.exponent as i32)
                } else {
                    k.powf(self.exponent)
                };
            }
        }
        &self.mask
    }

    /// Steering vector of `delays` at the first sub-band's centre in `steer`, and its change
    /// from one sub-band to the next in `step`.
    fn steering(&mut self, delays: &[f64]) {
        for ((a, s), t) in self.steer.iter_mut().zip(&mut self.step).zip(delays) {
            *a = Complex::from_polar(1.0, -self.omega0 * t);
            *s = Complex::from_polar(1.0, -self.omega_step * t);
        }
    }

    /// Power iterations from the steering vector of `delays` in every sub-band.
    fn find_principal(&mut self, delays: &[f64]) {
        let (np, m) = (self.pairs.len(), self.mics);
        self.steering(delays);
        for b in 0..self.diag.len() {
            let r = self.diag[b];
            let sub = &self.sub[b * np..(b + 1) * np];
            let v = &mut self.principal[b * m..(b + 1) * m];
            let norm = (m as f64).sqrt();
            for (x, a) in v.iter_mut().zip(&self.steer) {
                *x = a / norm;
            }
            for _ in 0..self.iterations {
                // (A + r I) v with A the off-diagonal covariance from the pair cross-spectra.
                for (n, x) in self.next.iter_mut().zip(v.iter()) {
                    *n = x * r;
                }
                for (&(i, j), s) in self.pairs.iter().zip(sub) {
                    self.next[i] += s * v[j];
                    self.next[j] += s.conj() * v[i];
                }
                let norm = self.next.iter().map(|c| c.norm_sqr()).sum::<f64>().sqrt();
                if !(norm.is_finite() && norm > 0.0) {
                    break;
                }
                for (x, n) in v.iter_mut().zip(&self.next) {
                    *x = n / norm;
                }
            }
            for (a, s) in self.steer.iter_mut().zip(&self.step) {
                *a *= s;
            }
        }
        self.has_principal = true;
    }

    /// |a^H v|^2 / M per sub-band for the steering vector of `delays`.
    fn dominance_of(&mut self, delays: &[f64], out: &mut [f64]) {
        let m = self.mics;
        self.steering(delays);
        for (b, o) in out.iter_mut().enumerate() {
            let v = &self.principal[b * m..(b + 1) * m];
            let proj: Complex = inner(&self.steer, v);
            *o = if self.diag[b] > 0.0 {
                (proj.norm_sqr() / m as f64).clamp(0.0, 1.0)
            } else {
                0.0
            };
            for (a, s) in self.steer.iter_mut().zip(&self.step) {
                *a *= s;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{MicArray, Vec3};
    use crate::localize::gcc::{GccSettings, lerp};
    use crate::localize::synth;

    const FS: f64 = 16000.0;
    const C: f64 = 343.0;
    const FRAME: usize = 2048;
    const BAND: (usize, usize) = (192, 767);

    /// Tones at the middle bin of every other sub-band of 8 bins, from `first`.
    fn tones(first: usize, len: usize) -> Vec<f64> {
        let bins: Vec<usize> = (first..72).step_by(2).map(|b| BAND.0 + 8 * b + 4).collect();
        (0..len)
            .map(|t| {
                bins.iter()
                    .enumerate()
                    .map(|(i, &k)| {
                        let w = 2.0 * PI * k as f64 / FRAME as f64;
                        (w * t as f64 + i as f64).sin()
                    })
                    .sum()
            })
            .collect()
    }

    fn delays(array: &MicArray, x: &Vec3) -> Vec<f64> {
        array.mics.iter().map(|m| (x - m).norm() / C).collect()
    }

    #[test]
    fn a_source_dominates_its_own_subbands_and_leaks_into_the_others() {
        // Two sources 90 degrees apart, one with tones in the even sub-bands, the other in the
        // odd ones: the first source's dominance is ~1 in its sub-bands and the array's beam
        // pattern |a1^H a2|^2 / M^2 in the other's.
        let array = synth::uca(8, 0.05, Vec3::zeros(), 0, "a");
        let (x1, x2) = (Vec3::new(3.0, 0.0, 0.0), Vec3::new(0.0, 3.0, 0.0));
        let (g1, g2) = (tones(0, 3 * FRAME), tones(1, 3 * FRAME));
        let x = synth::render(&array.mics, &[(x1, &g1), (x2, &g2)], FS, C, None, 1e-4, 3);
        // Without whitening (beta 0): PHAT would lift the sensor-noise bins between the tones
        // to the tones' level, and a sub-band made of them is dominated by no source.
        let settings = GccSettings {
            interpolation: 10,
            beta: 0.0,
            smoothing: 0.0,
            subband_bins: 8,
        };
        let mut bank = GccBank::new(&array, FRAME, BAND, settings, FS, C);
        bank.whiten(&synth::spectra_at(&x, FRAME, FRAME));
        bank.compute();
        let mut mask = SubbandMask::new(&bank, 8, 4.0, FS);
        mask.start(&bank);
        let (d1, d2) = (delays(&array, &x1), delays(&array, &x2));
        mask.add(&d1);
        for (b, dom) in mask.dominance[0].iter().enumerate() {
            let w = 2.0 * PI * FS / FRAME as f64 * (BAND.0 + 8 * b + 4) as f64;
            let overlap: Complex = d1
                .iter()
                .zip(&d2)
                .map(|(t1, t2)| Complex::from_polar(1.0, w * (t1 - t2)))
                .sum();
            let leak = overlap.norm_sqr() / 64.0;
            if b % 2 == 0 {
                assert!(*dom > 0.95, "own sub-band {b}: {dom}");
            } else {
                assert!(
                    (dom - leak).abs() < 0.05,
                    "sub-band {b}: {dom} vs leakage {leak}"
                );
            }
        }
        // Masking the first source leaves the second's peak and takes away the first's.
        let srp = |bank: &GccBank, d: &[f64]| {
            let sum: f64 = bank
                .pairs
                .iter()
                .map(|p| {
                    let pos =
                        (p.offset + p.half) as f64 + (d[p.a] - d[p.b]) * bank.steps_per_second;
                    lerp(&bank.table, pos)
                })
                .sum();
            sum / bank.pairs.len() as f64
        };
        let before = (srp(&bank, &d1), srp(&bank, &d2));
        assert!(before.0 > 0.3 && before.1 > 0.3, "{before:?}");
        mask.apply(&mut bank, None);
        let after = (srp(&bank, &d1), srp(&bank, &d2));
        assert!(
            after.1 > 0.9,
            "second source after masking the first: {after:?}"
        );
        assert!(
            after.0 < 0.5 * after.1,
            "first source after masking it: {after:?}"
        );
        // Keeping the only source removes nothing.
        mask.apply(&mut bank, Some(0));
        assert!((srp(&bank, &d1) - before.0).abs() < 1e-9);
    }
}
