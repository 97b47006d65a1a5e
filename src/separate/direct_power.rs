//! Each label's direct-path power, from a least-squares fit of the spatial covariance model.
//!
//! A bin's covariance is modelled as the labels' direct paths plus a diffuse field (late
//! reverberation, noise): R = sum_j phi_j a_j a_j^H + phi_d Gamma, with a_j the label's steering
//! (relative transfer function) and Gamma the spherically diffuse coherence sin(w d / c) / (w d / c).
//! The powers phi >= 0 that fit the smoothed snapshot covariance best in Frobenius norm solve a
//! small non-negative least-squares problem: its Gram matrix holds |a_i^H a_j|^2, a_i^H Gamma a_i
//! and ||Gamma||^2 and depends on the steering only, and its right-hand side holds |a_j^H y|^2 and
//! y^H Gamma y (the informed PSD estimators of the spatial-filtering literature).
//!
//! Why it is here: where a far talker's reverberation reaches a silent label's beamformer about
//! as strongly as the talker's own, comparing the beamformers' output powers cannot tell the
//! silent label from a quiet talker, and the harmonic grouping reads the far talker's pitch in
//! both. The fit puts that reverberation in phi_d, so a silent label seldom holds most of a
//! bin's fitted power.
//!
//! What the activity gate reads is a label's dominance: the share of the band's bins in which
//! its direct path holds more than half of the fitted power. Speech is sparse in time and
//! frequency, so a quiet talker still dominates the bins between its neighbours' harmonics,
//! while its share of the band's summed power is set by the loud bins it loses. Telling a
//! talker 5 dB or more below a neighbour from a silent label (area under the ROC curve, label
//! frames of the full pipeline, smoothed as the gate smooths): paper-linear6 seeds 1-48 0.90
//! against 0.77 for the summed-power share, recorded speech on paper-linear6 seeds 1-36 0.86
//! against 0.79; any talker against a silent label 0.96 against 0.93 and 0.97 against 0.95.

use super::nnls::Nnls;
use crate::dsp::{Complex, inner};
use crate::geometry::Vec3;

/// Band of the fit (Hz). Below 1 kHz a small array's steering vectors of nearby labels and the
/// diffuse coherence are nearly collinear and the fitted powers carry little (area under the
/// ROC curve silent against quiet talker, summed-power share: 0.55 in 0.3-1 kHz against 0.77 in
/// 1-4 kHz, paper-linear6).
pub const BAND_HZ: (f64, f64) = (1000.0, 4000.0);

/// Lower edge (Hz) of the optional low band (up to `BAND_HZ.0`), whose dominance is averaged
/// with the main band's: a vowel with no power above 1 kHz (a nasal murmur, a dark back vowel)
/// dominates no bin of the main band, however loud it is below. A far talker in a reverberant
/// room, whose direct path holds little of the main band, is heard there too. The low band
/// counts a label's bin only where the array resolves it ([`LOW_BAND_MAX_COSINE`]).
pub const LOW_BAND_HZ: f64 = 250.0;

/// The fit reads every this many bins of the band: the dominances are counts over the band, and
/// neighbouring bins of one frame are strongly correlated (the analysis window's main lobe spans
/// four), so one bin per main lobe carries nearly all of the information. Against every second
/// bin, full pipeline, SI-SDRi (dB): paper-linear6 seeds 1-36 +7.50 against +7.48 (37-48 +7.61
/// against +7.77), recorded speech on paper-linear6 seeds 1-24 +5.23 against +5.22 (25-36
/// +5.60 against +5.54), on uca8 seeds 1-12 +5.96 against +6.00, uca8 seeds 1-6 +8.96 against
/// +9.02; the separator's hop 5 % faster (the fit was 8 % of it). Measured with the gate on the
/// summed-power share, before the dominance.
const BIN_STRIDE: usize = 4;

/// In the low band a bin counts towards a label's dominance only where the label's direct-path
/// term and every other term of the fit are this far apart: their cosine as covariance
/// matrices, |a_i^H a_j|^2 / (|a_i|^2 |a_j|^2) against another label's and
/// a^H Gamma a / (|a|^2 |Gamma|) against the diffuse field's, stays below it. Where it does not,
/// the fit's split of the bin between the two is a guess. A 10 cm circle of eight tells a
/// label from the diffuse field from about 400 Hz; a 20 cm line or a 5 cm circle only from
/// about 750 Hz, so on those the low band counts little. In the main band every bin counts.
///
/// Measured (full pipeline, SI-SDRi dB / streams per talker): with the labels' pairs only in
/// the rule, `two-arrays` seeds 1-12 +4.07 / 1.583 against +3.87 / 1.556 with the diffuse term
/// too, and the small arrays alike (paper-linear6 seeds 1-48 +7.92 / 1.132 against +7.87 /
/// 1.139, recorded 1-36 +6.42 / 1.093 both); but a silent label beside a far reverberant
/// talker on a 20 cm line then kept -6.1 dB of the talker in its stream against -8.1 dB with
/// the gate off, and -11.7 dB with the diffuse term in the rule (`tests/separate/echoic.rs`).
/// Thresholds for the pairs only, 0.7 / 0.8 / 0.9 / every bin counted: `two-arrays` +4.03 /
/// +4.07 / +4.10 / +3.92 dB, paper-linear6 1-48 +7.89 / 1.139, +7.92 / 1.132, +7.97 / 1.174,
/// +8.02 / 1.160, recorded 1-36 +6.42 / 1.130, +6.42 / 1.093, +6.31 / 1.074, +6.22 / 1.074.
/// The rule in the main band too (pairs only, 0.8): paper-linear6 1-48 43 half-second blocks
/// on another label against 34, uca8 seeds 1-18 +9.29 against +9.40 dB.
pub const LOW_BAND_MAX_COSINE: f64 = 0.8;

/// Smoothing per frame of the fit's right-hand side (the snapshot covariance it sees).
const FEATURE_SMOOTHING: f64 = 0.3;

/// The fit on one microphone group.
#[derive(Debug, Clone, Default)]
pub struct DirectPowerFit {
    /// First bin of the band and one past its last.
    k0: usize,
    k1: usize,
    m: usize,
    /// Per band bin: the diffuse coherence, `m x m` row-major.
    coherence: Vec<f64>,
    /// Per band bin: the coherence's squared Frobenius norm.
    coherence_norm: Vec<f64>,
    /// Labels in the current fit.
    n: usize,
    /// Per band bin: the Gram matrix, `(n + 1) x (n + 1)` row-major (the diffuse term last).
    gram: Vec<f64>,
    /// Per band bin: the smoothed right-hand side (`n + 1` values); negative until first seen.
    rhs: Vec<f64>,
    /// Per band bin: the last frame's support (bit j: power j was positive), the next solve's
    /// start (it rarely changes from frame to frame).
    support: Vec<u32>,
    /// Per band bin: the labels whose dominance the bin counts towards (bit j; every label in
    /// the main band, those [`resolved_labels`] keeps in the low band).
    resolved: Vec<u32>,
    /// [`LOW_BAND_MAX_COSINE`] (a field so that the tests can compare it with counting all).
    low_band_max_cosine: f64,
    /// First bin of the main band: bins below it (from `k0`) make up the low band.
    split: usize,
    /// This frame's floor of a counted bin's fitted power (see [`DirectPowerFit::begin`]).
    floor: f64,
    /// This frame's main band: per label, the counted bins it dominates, and the bins counted.
    main: BandCount,
    /// The same over the low band (left at zero without one).
    low: BandCount,
    solver: Nnls,
}

impl DirectPowerFit {
    /// A fit for microphones `mics` (speed of sound `c`) on STFT bins of `hz_per_bin` Hz, the
    /// band limited to bins below `bins`, with the low band from [`LOW_BAND_HZ`] when
    /// `low_band`.
    pub fn new(mics: &[Vec3], c: f64, hz_per_bin: f64, bins: usize, low_band: bool) -> Self {
        let split = (BAND_HZ.0 / hz_per_bin).ceil().max(1.0) as usize;
        let k1 = ((BAND_HZ.1 / hz_per_bin).ceil() as usize)
            .min(bins)
            .max(split);
        // The low band's bins continue the main band's stride, so those stay the same.
        let low = (LOW_BAND_HZ / hz_per_bin).ceil().max(1.0) as usize;
        let k0 = if low_band && low < split {
            split - (split - low) / BIN_STRIDE * BIN_STRIDE
        } else {
            split
        };
        let m = mics.len();
        let fitted = (k1 - k0).div_ceil(BIN_STRIDE);
        let mut coherence = Vec::with_capacity(fitted * m * m);
        let mut coherence_norm = Vec::with_capacity(fitted);
        for k in (k0..k1).step_by(BIN_STRIDE) {
            let omega = std::f64::consts::TAU * hz_per_bin * k as f64;
            let mut norm = 0.0;
            for a in mics {
                for b in mics {
                    let x = omega * (a - b).norm() / c;
                    let g = if x.abs() < 1e-9 { 1.0 } else { x.sin() / x };
                    coherence.push(g);
                    norm += g * g;
                }
            }
            coherence_norm.push(norm);
        }
        Self {
            k0,
            k1,
            split,
            m,
            coherence,
            coherence_norm,
            low_band_max_cosine: LOW_BAND_MAX_COSINE,
            ..Self::default()
        }
    }

    /// Whether the fit reads bin `k` (in its band, on its stride).
    pub fn covers(&self, k: usize) -> bool {
        (self.k0..self.k1).contains(&k) && (k - self.k0).is_multiple_of(BIN_STRIDE)
    }

    /// Bins the fit reads.
    fn fitted(&self) -> usize {
        (self.k1 - self.k0).div_ceil(BIN_STRIDE)
    }

    /// Starts a frame with `n` labels whose mean power per bin and microphone is `level`; a bin
    /// counts towards the dominances only if its fitted power is above [`COUNTED_FLOOR`] times
    /// that. A change of the labels' number forgets the smoothed covariance. (A label that
    /// replaces another within one frame inherits its column for the few frames the smoothing
    /// remembers; the Gram matrix is rebuilt with the steering.)
    pub fn begin(&mut self, n: usize, level: f64) {
        let bins = self.fitted();
        if n != self.n || self.rhs.len() != bins * (n + 1) {
            self.n = n;
            self.rhs.clear();
            self.rhs.resize(bins * (n + 1), -1.0);
            self.gram.clear();
            self.gram.resize(bins * (n + 1) * (n + 1), 0.0);
            self.support.clear();
            self.support.resize(bins, 0);
            self.resolved.clear();
            self.resolved.resize(bins, u32::MAX);
        }
        self.floor = if level.is_finite() {
            COUNTED_FLOOR * level.max(0.0)
        } else {
            f64::INFINITY
        };
        self.main.reset(n);
        self.low.reset(n);
    }

    /// Fits bin `k` (in the band) from the snapshot `y` of the group's microphones and the
    /// labels' steering there (`n x m`, label after label); `rebuild` recomputes the Gram matrix
    /// (the steering moved).
    pub fn observe(&mut self, k: usize, y: &[Complex], steering: &[Complex], rebuild: bool) {
        let (n, m) = (self.n, self.m);
        if !self.covers(k) || n == 0 || y.len() != m || steering.len() < n * m {
            return;
        }
        let b = (k - self.k0) / BIN_STRIDE;
        let nn = n + 1;
        let gamma = &self.coherence[b * m * m..(b + 1) * m * m];
        let gram = &mut self.gram[b * nn * nn..(b + 1) * nn * nn];
        if rebuild || gram[n * nn + n] == 0.0 {
            for i in 0..n {
                let ai = &steering[i * m..(i + 1) * m];
                for j in i..n {
                    let g = inner(ai, &steering[j * m..(j + 1) * m]).norm_sqr();
                    gram[i * nn + j] = g;
                    gram[j * nn + i] = g;
                }
                let d = quadratic(gamma, ai, m);
                gram[i * nn + n] = d;
                gram[n * nn + i] = d;
            }
            gram[n * nn + n] = self.coherence_norm[b];
            self.resolved[b] = if k < self.split {
                resolved_labels(gram, n, self.low_band_max_cosine)
            } else {
                u32::MAX
            };
        }
        if !y.iter().all(|v| v.re.is_finite() && v.im.is_finite()) {
            return;
        }
        let rhs = &mut self.rhs[b * nn..(b + 1) * nn];
        for (j, r) in rhs.iter_mut().enumerate() {
            let v = if j < n {
                inner(&steering[j * m..(j + 1) * m], y).norm_sqr()
            } else {
                quadratic(gamma, y, m)
            };
            *r = if *r < 0.0 {
                v
            } else {
                FEATURE_SMOOTHING * *r + (1.0 - FEATURE_SMOOTHING) * v
            };
        }
        let phi = self.solver.solve(gram, rhs, nn, &mut self.support[b]);
        let total: f64 = phi.iter().sum();
        if total.is_finite() && total > self.floor {
            let band = if k < self.split {
                &mut self.low
            } else {
                &mut self.main
            };
            let resolved = self.resolved[b];
            for (j, (c, (d, &p))) in band
                .counted
                .iter_mut()
                .zip(band.dominated.iter_mut().zip(&phi[..n]))
                .enumerate()
            {
                if j >= 32 || resolved & (1 << j) != 0 {
                    *c += 1;
                    // At most one term holds more than half; the diffuse field's is not counted.
                    if p > 0.5 * total {
                        *d += 1;
                    }
                }
            }
        }
    }

    /// Label `j`'s dominance this frame, in [0, 1]: the share of the band's counted bins in
    /// which its direct path holds more than half of the fitted power (direct paths and diffuse
    /// field); `None` when no bin was counted (the band is empty, or nothing was fitted). With
    /// the low band, the mean of its dominance there and in the main band.
    pub fn dominance(&self, j: usize) -> Option<f64> {
        let main = self.main.dominance(j);
        match self.low.dominance(j) {
            Some(low) => Some(main.map_or(low, |m| 0.5 * (m + low))),
            None => main,
        }
    }
}

/// Ignored bins: fitted power below this times the frame's mean power per bin (-60 dB), which
/// is numerical residue (a signal with nothing above 1 kHz), not a measurement of who talks.
pub const COUNTED_FLOOR: f64 = 1e-6;

/// One band's counts over a frame.
#[derive(Debug, Clone, Default)]
struct BandCount {
    /// Per label: the counted bins where its direct path holds more than half of the power.
    dominated: Vec<u32>,
    /// Per label: the bins counted for it.
    counted: Vec<u32>,
}

impl BandCount {
    fn reset(&mut self, n: usize) {
        self.dominated.clear();
        self.dominated.resize(n, 0);
        self.counted.clear();
        self.counted.resize(n, 0);
    }

    fn dominance(&self, j: usize) -> Option<f64> {
        let d = *self.dominated.get(j)?;
        let c = *self.counted.get(j)?;
        (c > 0).then(|| f64::from(d) / f64::from(c))
    }
}

/// The labels (bit j) whose direct-path term the fit tells from every other term at a bin:
/// the cosine between the terms in the space of covariance matrices, read from the fit's Gram
/// matrix `gram` (`n` labels, the diffuse field's term last), stays below `max_cosine` against
/// every other label's and the diffuse field's. Labels past the 32nd are always counted.
fn resolved_labels(gram: &[f64], n: usize, max_cosine: f64) -> u32 {
    let nn = n + 1;
    let mut mask = 0u32;
    for i in 0..n.min(32) {
        let gii = gram[i * nn + i];
        let apart = (0..nn).filter(|&j| j != i).all(|j| {
            let c = gram[i * nn + j] / (gii * gram[j * nn + j]).sqrt();
            // A NaN (a zero column) is no evidence that the pair is unresolved.
            c.is_nan() || c < max_cosine
        });
        if apart && gii > 0.0 {
            mask |= 1 << i;
        }
    }
    mask
}

/// x^H G x for the real symmetric `m x m` matrix `g` (each pair once).
fn quadratic(g: &[f64], x: &[Complex], m: usize) -> f64 {
    let mut acc = 0.0;
    for (i, xi) in x.iter().enumerate().take(m) {
        let row = &g[i * m..(i + 1) * m];
        let mut cross = 0.0;
        for (gij, xj) in row[i + 1..].iter().zip(&x[i + 1..]) {
            cross += gij * (xi.re * xj.re + xi.im * xj.im);
        }
        acc += row[i] * xi.norm_sqr() + 2.0 * cross;
    }
    acc
}

#[cfg(test)]
mod tests;
