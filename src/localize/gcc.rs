//! GCC-PHAT of every microphone pair of one array, tabulated on a fine lag grid.
//!
//! Per frame: the band bins of each channel are whitened (PHAT, Y / |Y|^beta), each pair's cross-spectrum
//! W_a W_b^* is transformed to the integer lags inside the physically possible range
//! |tau| <= d_ab / c (sub-band by sub-band, so masked re-tabulations are cheap: `subband_lags`),
//! and those are interpolated to `interpolation` points per sample with a
//! Kaiser-windowed sinc (band-limited interpolation; the band stays well below Nyquist). With the
//! forward FFT kernel e^{-j omega t}, a source with times of flight tau_a, tau_b gives
//! W_a W_b^* ~ e^{-j omega (tau_a - tau_b)}, so the GCC r_ab(tau) = sum_k Re(W_a W_b^* e^{+j omega_k tau})
//! peaks at tau = tau_a - tau_b (spec 000 section 2.3 with the corrected sign). Values are
//! normalised by the number of band bins, so r = 1 for a perfectly coherent pair.

use std::f64::consts::PI;

use crate::dsp::{Complex, MultiSpectrum};
use crate::geometry::MicArray;

use super::lag_kernel::{SINC_TAPS, band_kernel, sinc_kernel};
use super::sliding_max::sliding_max;
use super::subband_lags::SubbandLags;

/// Extra lag range (samples) tabulated beyond d_ab / c, so lookups at the physical limit interpolate.
pub(super) const LAG_MARGIN_SAMPLES: f64 = 1.0;

/// One microphone pair and where its fine GCC table lives.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Pair {
    /// First microphone (index within the array).
    pub a: usize,
    /// Second microphone.
    pub b: usize,
    /// Start of the pair's table in the concatenated storage.
    pub offset: usize,
    /// Fine index of zero lag; the table covers fine indices 0..=2*half (+1 guard entry).
    pub half: usize,
}

/// The normalisation of a pair's GCC with weighted bin norms `t1` (sum w n1) and `t2`
/// (sum w^2 n2), adding its share of the null variance to `null_var`: each bin adds a cosine
/// of uniform phase (variance w^2 / 2) under incoherence.
fn null_term(t1: f64, t2: f64, null_var: &mut f64) -> f64 {
    if t1 > 0.0 {
        *null_var += t2 / (2.0 * t1 * t1);
        1.0 / (2.0 * t1)
    } else {
        0.0
    }
}

/// Linear interpolation of the concatenated tables at absolute fine position `pos` (>= 0).
#[inline(always)]
pub(crate) fn lerp(table: &[f64], pos: f64) -> f64 {
    let i = pos as usize;
    let f = pos - i as f64;
    let a = table[i];
    a + f * (table[i + 1] - a)
}

/// How the GCC tables are computed (from the localiser configuration).
#[derive(Debug, Clone, Copy)]
pub(crate) struct GccSettings {
    /// Fine table steps per sample of lag.
    pub interpolation: usize,
    /// PHAT exponent beta: bins are divided by |Y|^beta.
    pub beta: f64,
    /// The smoothed cross-spectrum is this frame's plus `smoothing` times the previous smoothed
    /// one (0: none).
    pub smoothing: f64,
    /// Bins per sub-band of the masks that remove found sources.
    pub subband_bins: usize,
}

/// GCC-PHAT tables of all pairs of one array, with the buffers to compute them in place.
pub(crate) struct GccBank {
    pub pairs: Vec<Pair>,
    /// Concatenated fine tables, one per pair, each `2*half + 2` long (the last entry repeats the
    /// one before so linear interpolation never reads past a table).
    pub table: Vec<f64>,
    /// The tables as computed, before any source removal.
    pristine: Vec<f64>,
    /// Fine table steps per second of lag (interpolation * sample rate).
    pub steps_per_second: f64,
    interpolation: usize,
    /// Inclusive range of the FFT bins used.
    pub band: (usize, usize),
    channels: Vec<usize>,
    white: Vec<Complex>,
    /// |W| of every whitened bin (|Y|^(1 - beta)), channel-major like `white`.
    mags: Vec<f64>,
    /// Mean power over the channels of every band bin in the current frame.
    pub bin_power: Vec<f64>,
    /// PHAT exponent beta: bins are divided by |Y|^beta (1 = classic PHAT).
    beta: f64,
    /// Variance of the normalised SRP of incoherent signals in the current frame.
    null_var: f64,
    /// `null_var` of the tables as computed.
    pristine_null_var: f64,
    /// The band's smoothed cross-spectra, pair-major: sum over the frames since the last
    /// `forget` of decay^age times the frame's whitened cross-spectrum.
    pub smoothed: Vec<Complex>,
    /// Per pair and band bin: the same sum of |W_a| |W_b|, the most a bin's smoothed
    /// cross-spectrum can reach.
    norm1: Vec<f64>,
    /// Per pair and band bin: the sum of (decay^age |W_a| |W_b|)^2.
    norm2: Vec<f64>,
    /// Per band bin: `norm1` summed over the pairs.
    pub bin_norm: Vec<f64>,
    /// This frame's own whitened cross-spectra, pair-major (for [`GccBank::fresh_srp`]).
    cross: Vec<Complex>,
    /// Per pair and sub-band: this frame's sum of |W_a| |W_b| and of its square.
    cross_norm1: Vec<f64>,
    cross_norm2: Vec<f64>,
    /// Weight of the previous smoothed cross-spectra in this frame's.
    decay: f64,
    /// Whether the smoothed cross-spectra hold nothing to carry over (start, or after `forget`).
    fresh: bool,
    lags: Vec<f64>,
    kernels: Vec<f64>,
    /// The band's PHAT kernel K(d) = mean over band bins of cos(omega_k d), at fine offsets d >= 0
    /// (the normalised GCC of a lone, perfectly coherent source, centred on its lag).
    kernel: Vec<f64>,
    /// Sub-band contributions to the integer lags, from which every table is computed.
    subbands: SubbandLags,
    /// `subbands` predate this frame's cross-spectra.
    subbands_stale: bool,
    window_power: f64,
    /// FFT length (samples).
    pub frame: usize,
}

impl GccBank {
    /// Tables for every pair of `array`; `band` is the inclusive range of bins used.
    pub fn new(
        array: &MicArray,
        frame: usize,
        band: (usize, usize),
        settings: GccSettings,
        sample_rate: f64,
        speed_of_sound: f64,
    ) -> Self {
        let GccSettings {
            interpolation,
            beta,
            smoothing: decay,
            subband_bins,
        } = settings;
        let mut pairs = Vec::new();
        let mut offset = 0;
        for (a, b) in array.pairs() {
            let max_lag = (array.mics[a] - array.mics[b]).norm() / speed_of_sound * sample_rate;
            let half = ((max_lag + LAG_MARGIN_SAMPLES) * interpolation as f64).ceil() as usize;
            pairs.push(Pair { a, b, offset, half });
            offset += 2 * half + 2;
        }
        let max_half = pairs.iter().map(|p| p.half).max().unwrap_or(0);
        let npairs = pairs.len();
        let lag_span = max_half / interpolation + 2 + SINC_TAPS;
        // kernels[r * 2K + i] weights integer lag (n0 - K + 1 + i) for the fraction r / I.
        let mut kernels = Vec::with_capacity(interpolation * 2 * SINC_TAPS);
        for r in 0..interpolation {
            let frac = r as f64 / interpolation as f64;
            for i in 0..2 * SINC_TAPS {
                let n = i as f64 - (SINC_TAPS as f64 - 1.0);
                kernels.push(sinc_kernel(frac - n));
            }
        }
        let subbands = SubbandLags::new(band, subband_bins, frame, npairs, lag_span);
        let nsub = subbands.count;
        let nb = band.1 + 1 - band.0;
        let kernel = (0..2 * max_half + 4)
            .map(|j| band_kernel(band, frame, j as f64 / interpolation as f64))
            .collect();
        let window_power: f64 = crate::dsp::hann_periodic(frame).iter().map(|w| w * w).sum();
        Self {
            pairs,
            table: vec![0.0; offset],
            pristine: vec![0.0; offset],
            steps_per_second: interpolation as f64 * sample_rate,
            interpolation,
            band,
            channels: array.channels.clone(),
            white: vec![Complex::new(0.0, 0.0); nb * array.len()],
            mags: vec![0.0; nb * array.len()],
            bin_power: vec![0.0; nb],
            beta,
            null_var: 0.0,
            pristine_null_var: 0.0,
            smoothed: vec![Complex::new(0.0, 0.0); nb * npairs],
            norm1: vec![0.0; nb * npairs],
            norm2: vec![0.0; nb * npairs],
            bin_norm: vec![0.0; nb],
            cross: vec![Complex::new(0.0, 0.0); nb * npairs],
            cross_norm1: vec![0.0; npairs * nsub],
            cross_norm2: vec![0.0; npairs * nsub],
            decay,
            fresh: true,
            lags: vec![0.0; 2 * lag_span + 1],
            kernels,
            kernel,
            subbands,
            subbands_stale: true,
            window_power,
            frame,
        }
    }

    /// Standard deviation of the normalised SRP (mean GCC over pairs) that incoherent signals
    /// with this frame's bin weights would give: each bin adds a cosine of uniform phase, and the
    /// pairs are uncorrelated for independent microphone signals.
    pub fn null_std(&self) -> f64 {
        self.null_var.sqrt()
    }

    /// The band's PHAT kernel at fine lag offsets 0, 1, ... (one per table step).
    pub fn kernel(&self) -> &[f64] {
        &self.kernel
    }

    /// Whitens the band bins of the array's channels and returns the mean in-band power per
    /// sample and channel (Hann-window compensated; non-finite bins count as zero).
    pub fn whiten(&mut self, spectra: &MultiSpectrum) -> f64 {
        let nb = self.band.1 + 1 - self.band.0;
        let mut energy = 0.0;
        self.bin_power.fill(0.0);
        for (m, &ch) in self.channels.iter().enumerate() {
            let bins = &spectra.channel(ch)[self.band.0..=self.band.1];
            let out = &mut self.white[m * nb..(m + 1) * nb];
            let mags = &mut self.mags[m * nb..(m + 1) * nb];
            for (((o, w), y), bp) in out
                .iter_mut()
                .zip(mags.iter_mut())
                .zip(bins)
                .zip(self.bin_power.iter_mut())
            {
                // |Y|^2 without hypot: non-finite or overflowing bins fail the test and count as zero.
                let p = y.re * y.re + y.im * y.im;
                if p.is_finite() && p > 1e-60 {
                    let scale = if self.beta == 1.0 {
                        1.0 / p.sqrt()
                    } else {
                        p.powf(-0.5 * self.beta)
                    };
                    *o = y * scale;
                    *w = p.sqrt() * scale;
                    energy += p;
                    *bp += p;
                } else {
                    *o = Complex::new(0.0, 0.0);
                    *w = 0.0;
                }
            }
        }
        let per_channel = 1.0 / self.channels.len().max(1) as f64;
        for bp in &mut self.bin_power {
            *bp = if bp.is_finite() {
                *bp * per_channel
            } else {
                0.0
            };
        }
        // One-sided bins of a Hann-windowed frame: sum |Y|^2 = (N/2) * sum w^2 * power per sample.
        let power =
            energy / (self.channels.len() as f64 * self.window_power * self.frame as f64 / 2.0);
        if power.is_finite() { power } else { f64::MAX }
    }

    /// Weights every whitened bin by P / (P + margin * N), with P its power and N its noise
    /// floor: bins where noise (sensor noise, or a talker's spectral gaps) dominates weigh less,
    /// without ever being dropped while the floor is still unknown.
    pub fn weight_bins(&mut self, floor: &[f64], margin: f64) {
        let nb = self.band.1 + 1 - self.band.0;
        for (k, (p, n)) in self.bin_power.iter().zip(floor).enumerate() {
            let w = if *p > 0.0 { p / (p + margin * n) } else { 0.0 };
            for m in 0..self.channels.len() {
                self.white[m * nb + k] *= w;
                self.mags[m * nb + k] *= w;
            }
        }
    }

    /// Computes every pair's smoothed cross-spectrum and fine GCC table from the whitened
    /// spectra. Each pair's GCC is normalised by the sum over bins of |W_a| |W_b|, so it lies in
    /// [-1, 1] and equals 1 for a perfectly coherent pair whatever the exponent.
    pub fn compute(&mut self) {
        self.smooth();
        self.tabulate_subbands(None);
        self.pristine.copy_from_slice(&self.table);
        self.pristine_null_var = self.null_var;
    }

    /// Adds this frame's whitened cross-spectra to the band's smoothed ones (recursively: the
    /// previous sum decays by `decay`), and the same for their per-bin norms.
    fn smooth(&mut self) {
        let nb = self.band.1 + 1 - self.band.0;
        // A fresh start carries nothing over.
        let (lam, lam2) = if self.fresh {
            (0.0, 0.0)
        } else {
            (self.decay, self.decay * self.decay)
        };
        self.bin_norm.fill(0.0);
        for (q, p) in self.pairs.iter().enumerate() {
            let range = q * nb..(q + 1) * nb;
            let (wa, wb) = (
                &self.white[p.a * nb..(p.a + 1) * nb],
                &self.white[p.b * nb..(p.b + 1) * nb],
            );
            let (ma, mb) = (
                &self.mags[p.a * nb..(p.a + 1) * nb],
                &self.mags[p.b * nb..(p.b + 1) * nb],
            );
            let smoothed = &mut self.smoothed[range.clone()];
            let n1 = &mut self.norm1[range.clone()];
            let n2 = &mut self.norm2[range];
            // The phase of a source that keeps its place adds up over the frames, that of
            // reverberation and noise does not.
            let cross = &mut self.cross[q * nb..(q + 1) * nb];
            let (width, count) = (self.subbands.width, self.subbands.count);
            for b in 0..count {
                let (mut s1, mut s2) = (0.0, 0.0);
                for k in b * width..((b + 1) * width).min(nb) {
                    let m = ma[k] * mb[k];
                    cross[k] = wa[k] * wb[k].conj();
                    smoothed[k] = cross[k] + smoothed[k] * lam;
                    n1[k] = m + lam * n1[k];
                    n2[k] = m * m + lam2 * n2[k];
                    s1 += m;
                    s2 += m * m;
                }
                self.cross_norm1[q * count + b] = s1;
                self.cross_norm2[q * count + b] = s2;
            }
            for (b, n) in self.bin_norm.iter_mut().zip(n1.iter()) {
                *b += n;
            }
        }
        self.fresh = false;
        self.subbands_stale = true;
    }

    /// Recomputes every pair's fine table (and the null variance) with sub-band `b` of the band
    /// weighted by `gains[b]` (sub-bands of [`GccBank::subband_width`] bins, the last one may be
    /// shorter; `None` weighs all by one): exactly the tables of the cross-spectra masked that way. The sub-band
    /// contributions are computed once per frame, so each call costs a weighted sum per lag
    /// (see [`SubbandLags`]).
    pub fn tabulate_subbands(&mut self, gains: Option<&[f64]>) {
        let nb = self.band.1 + 1 - self.band.0;
        let npairs = self.pairs.len();
        if self.subbands_stale {
            for q in 0..npairs {
                let range = q * nb..(q + 1) * nb;
                self.subbands.rebuild(
                    q,
                    &self.smoothed[range.clone()],
                    &self.norm1[range.clone()],
                    &self.norm2[range],
                );
            }
            self.subbands_stale = false;
        }
        let mut null_var = 0.0;
        for q in 0..npairs {
            let (t1, t2) = self.subbands.combine(q, gains, &mut self.lags);
            let norm = null_term(t1, t2, &mut null_var);
            self.lags.iter_mut().for_each(|l| *l *= norm);
            self.interpolate(q);
        }
        let np = npairs.max(1) as f64;
        self.null_var = null_var / (np * np);
    }

    /// Bins per sub-band of [`GccBank::tabulate_subbands`].
    pub fn subband_width(&self) -> usize {
        self.subbands.width
    }

    /// Sub-bands of [`GccBank::tabulate_subbands`].
    pub fn subband_count(&self) -> usize {
        self.subbands.count
    }

    /// Pair `q`'s fine table from its normalised GCC at the integer lags (`lags`).
    fn interpolate(&mut self, q: usize) {
        let interp = self.interpolation as isize;
        let taps = 2 * SINC_TAPS;
        let lag_span = (self.lags.len() / 2) as isize;
        let p = self.pairs[q];
        let half = p.half as isize;
        let table = &mut self.table[p.offset..p.offset + 2 * p.half + 2];
        for (j, t) in table.iter_mut().take(2 * p.half + 1).enumerate() {
            let rel = j as isize - half;
            let n0 = rel.div_euclid(interp);
            let r = rel.rem_euclid(interp) as usize;
            let kern = &self.kernels[r * taps..(r + 1) * taps];
            let start = (n0 + lag_span - SINC_TAPS as isize + 1) as usize;
            *t = kern
                .iter()
                .zip(&self.lags[start..start + taps])
                .map(|(k, v)| k * v)
                .sum();
        }
        table[2 * p.half + 1] = table[2 * p.half];
    }

    /// This frame's own normalised SRP at a source whose wave reaches the microphones at
    /// `delays` (seconds), without the smoothing's memory, with sub-band `b` weighted by
    /// `gains[b]` as in [`GccBank::tabulate_subbands`]; and the standard deviation the same
    /// SRP would have for incoherent signals. The smoothed maps find a source from the evidence
    /// of several frames; this tells whether it is still sounding now.
    pub fn fresh_srp(&self, delays: &[f64], gains: Option<&[f64]>) -> (f64, f64) {
        let nb = self.band.1 + 1 - self.band.0;
        let (width, count) = (self.subbands.width, self.subbands.count);
        let bin =
            2.0 * PI * self.steps_per_second / (self.interpolation as f64 * self.frame as f64);
        let (mut total, mut var) = (0.0, 0.0);
        let mut offsets: Vec<Complex> = Vec::with_capacity(width);
        for (q, p) in self.pairs.iter().enumerate() {
            let x = &self.cross[q * nb..(q + 1) * nb];
            let tau =
                delays.get(p.a).copied().unwrap_or(0.0) - delays.get(p.b).copied().unwrap_or(0.0);
            // e^{j w_k tau} = (phasor of the sub-band's first bin) x (phasor of the offset
            // within the sub-band): the offsets' phasors are shared by all sub-bands, so the
            // bins' products are independent of one another (no serial recurrence over the
            // band) and removed sub-bands cost nothing.
            let step = Complex::from_polar(1.0, bin * tau);
            offsets.clear();
            let mut r = Complex::new(1.0, 0.0);
            for _ in 0..width {
                offsets.push(r);
                r *= step;
            }
            let mut start = Complex::from_polar(1.0, bin * self.band.0 as f64 * tau);
            let jump = Complex::from_polar(1.0, bin * width as f64 * tau);
            let (mut num, mut t1, mut t2) = (0.0, 0.0, 0.0);
            for b in 0..count {
                let g = gains.map_or(1.0, |g| g.get(b).copied().unwrap_or(0.0));
                if g > 0.0 {
                    let (mut re, mut im) = (0.0, 0.0);
                    for (c, w) in x[b * width..((b + 1) * width).min(nb)].iter().zip(&offsets) {
                        re += c.re * w.re - c.im * w.im;
                        im += c.re * w.im + c.im * w.re;
                    }
                    num += g * (start.re * re - start.im * im);
                    t1 += g * self.cross_norm1[q * count + b];
                    t2 += g * g * self.cross_norm2[q * count + b];
                }
                start *= jump;
            }
            if t1 > 0.0 {
                total += num / t1;
                var += t2 / (2.0 * t1 * t1);
            }
        }
        let np = self.pairs.len().max(1) as f64;
        (total / np, var.sqrt() / np)
    }

    /// Forgets the past frames' cross-spectra (after silence, or when the input jumps).
    pub fn forget(&mut self) {
        self.fresh = true;
    }

    /// Restores the tables as computed, undoing every removal and mask.
    pub fn restore(&mut self) {
        self.table.copy_from_slice(&self.pristine);
        self.null_var = self.pristine_null_var;
    }

    /// Writes into `out` (same layout as `table`) each pair's table max-filtered over
    /// +-`widths[q]` fine steps: the best value anywhere in a grid cell, so a coarse scan cannot
    /// step over a narrow peak (ODAS's maximum sliding window). `work` needs twice the longest table's length.
    pub fn max_filter(&self, widths: &[usize], out: &mut [f64], work: &mut [f64]) {
        for (q, p) in self.pairs.iter().enumerate() {
            let len = 2 * p.half + 2;
            let src = &self.table[p.offset..p.offset + len];
            let dst = &mut out[p.offset..p.offset + len];
            sliding_max(src, widths[q], dst, &mut work[..2 * len]);
        }
    }

    /// Length of the longest pair table.
    pub fn longest_table(&self) -> usize {
        self.pairs.iter().map(|p| 2 * p.half + 2).max().unwrap_or(0)
    }
}

/// Time-domain GCC of a pair computed directly (for tests): sum over band bins, normalised.
#[cfg(test)]
pub(crate) fn direct_gcc(
    wa: &[Complex],
    wb: &[Complex],
    band: (usize, usize),
    frame: usize,
    tau_samples: f64,
) -> f64 {
    let nb = band.1 + 1 - band.0;
    let mut acc = 0.0;
    for (i, k) in (band.0..=band.1).enumerate() {
        let omega = 2.0 * PI * k as f64 / frame as f64;
        let c = wa[i] * wb[i].conj();
        acc += (c * Complex::from_polar(1.0, omega * tau_samples)).re;
    }
    acc / nb as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use crate::localize::synth;

    const FS: f64 = 16000.0;
    const C: f64 = 343.0;

    #[test]
    fn max_filter_is_the_sliding_maximum_of_each_pair_table() {
        let array = MicArray::new(
            "a",
            vec![Vec3::zeros(), Vec3::new(0.3, 0.0, 0.0)],
            vec![0, 1],
        )
        .unwrap();
        let sig = synth::white(4096, 9);
        let x = synth::render(
            &array.mics,
            &[(Vec3::new(1.0, 1.0, 0.0), &sig)],
            FS,
            C,
            None,
            0.3,
            4,
        );
        let mut bank = GccBank::new(
            &array,
            2048,
            (128, 256),
            GccSettings {
                interpolation: 10,
                beta: 1.0,
                smoothing: 0.0,
                subband_bins: 8,
            },
            FS,
            C,
        );
        bank.whiten(&synth::spectra_at(&x, 0, 2048));
        bank.compute();
        let len = bank.table.len();
        for w in [0usize, 1, 3, 17, 200] {
            let mut out = vec![0.0; len];
            let mut work = vec![0.0; 2 * len];
            bank.max_filter(&[w], &mut out, &mut work);
            for (i, got) in out.iter().enumerate() {
                let lo = i.saturating_sub(w);
                let hi = (i + w).min(len - 1);
                let m = bank.table[lo..=hi].iter().copied().fold(f64::MIN, f64::max);
                assert_eq!(*got, m, "w {w} i {i}");
            }
        }
    }
}
