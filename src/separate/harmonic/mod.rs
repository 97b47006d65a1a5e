//! Harmonic grouping of the bins the array cannot resolve (CASA-style, after the post-filter).
//!
//! Where two labels' steering vectors are nearly collinear (low frequencies, labels a few degrees
//! apart on a small array) their beamformer outputs carry the same mixture and the spatial gains
//! split each bin by chance. Voiced speech carries a second cue there: its energy sits on the
//! harmonics of its F0. Per frame, each label's F0 is estimated from its own post-filtered
//! spectrum in the bins the array does resolve for it (peak-minus-valley harmonic comb,
//! Hermes-style subharmonic summation) and its voicing from the periodicity of its whole
//! post-filtered frame ([`Periodicity`]), and in the unresolved bins the labels' pooled gain
//! is redistributed towards the labels whose harmonic comb passes through the bin (a product of
//! the harmonic evidence and the spatial gain, the latter counting only as far as the pair is
//! resolved: where the beamformers pass the same mixture it only says who is louder).
//! Each label keeps a pitch register, the running mean of the log F0s it owned, and the search
//! prefers candidates inside it: in a frame where a neighbour's leak is as strong as the label's
//! own voice, the label keeps its own pitch instead of taking the neighbour's. Where two labels
//! still read the same F0 (a silent label reading a neighbour's leak as loud as its voice, which
//! a far talker's reverberation makes common), the register also weighs each comb's claim on the
//! harmonics: the talker whose usual range holds the F0 is more likely its owner.
//!
//! How unresolved a pair of labels is at a bin follows from their steering vectors and the
//! null-steering loading: the loaded two-column beamformer's leakage of one label into the
//! other's output relative to its own response (0 = perfect null, 1 = identical outputs).

use super::config::HarmonicConfig;
use crate::dsp::Complex;
use comb::HannTable;

mod activity;
mod comb;
mod fit;
mod periodicity;
mod reading;
mod track;

pub use activity::{RoomLevel, Segment};
#[cfg(test)]
pub(crate) use fit::tests as fit_signals;
pub use fit::{HarmonicFit, hann_transform};
pub use periodicity::Periodicity;
pub use track::PitchTrack;
use track::Transition;

/// Relative step of the F0 candidate grid (0.5 %: the 20th harmonic moves by a tenth of its
/// frequency's bin spacing at 2 kHz and 16 kHz / 1024). Half of it, with the analysis read
/// up to 4 kHz, measured within noise (paper-linear6 seeds 1-6 +0.15 dB, uca8 seeds 1-3
/// -0.05 dB SI-SDRi) at twice the F0 search's cost.
const GRID_STEP: f64 = 0.005;

/// Highest frequency (Hz) the coarse stage of the F0 search reads: it only has to find the
/// neighbourhoods the fine stage searches with every harmonic up to `max_frequency_hz`.
/// With the analysis up to 4 kHz this keeps the full search's separation (paper-linear6 seeds
/// 1-6 +5.14 dB SI-SDRi either way, uca8 seeds 1-3 +8.29 / +8.24 dB) at a third of its extra
/// cost (whole pipeline, uca8: +3 % CPU against the 2 kHz analysis instead of +10 %).
const COARSE_TOP_HZ: f64 = 2000.0;

/// Added to a label's periodicity at a candidate's period before it weighs the candidate's
/// comb, so a comb at a period the frame's autocorrelation does not show (negative there, or
/// a frame too mixed to show any) still counts; floors 0.02 to 0.2 measured alike.
const PERIODIC_FLOOR: f64 = 0.05;

/// One label's pitch in one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Pitch {
    /// F0 (Hz); 0 when unknown.
    pub f0: f64,
    /// Voicing in [0, 1] from the normalised comb score (0 at or below `voicing_low`); the
    /// separator replaces it with the label's periodicity when `periodicity_voicing` is on.
    pub voicing: f64,
    /// Mean peak-minus-valley magnitude over the comb's harmonics (the scale of the input;
    /// relative to the mixture's local level once [`Harmonic::whiten_salience`] has measured it).
    pub salience: f64,
    /// How well the F0 fits the label's pitch register: its preference there, in (0, 1], to
    /// the power `register_ownership` (1 without a register or for a known pitch).
    pub register_fit: f64,
}

impl Pitch {
    /// The comb's strength in the labels' contest for a harmonic: its salience weighted by the
    /// register's prior for its F0.
    fn strength(&self) -> f64 {
        self.salience * self.register_fit
    }
}

/// A label's pitch register: the running, evidence-weighted mean of its log F0.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Register {
    log_f0: f64,
    /// Discounted sum of the evidence (ownership per frame, which includes voicing) behind
    /// the mean.
    weight: f64,
}

/// The register's pull never exceeds this: a candidate far outside it still wins with ten
/// times the comb's selection score (a talker may leave their usual range). Measured against
/// 0.6: paper-linear6 seeds 1-3 / 4-6 +0.08 / +0.14 dB SI-SDRi. Its known cost: a lone voice
/// about an octave above the register is read at its subharmonic inside it.
const REGISTER_MAX_CONFIDENCE: f64 = 0.9;

/// Harmonic grouping constants for one framing.
#[derive(Debug, Clone)]
pub struct Harmonic {
    /// The analysis window's response, for a comb's membership of a bin.
    hann: HannTable,
    boost: f64,
    leakage_exponent: f64,
    /// 1 / `leakage_exponent`: recovers a leakage from its unresolved value.
    inverse_leakage_exponent: f64,
    ownership_exponent: f64,
    spatial_discount: f64,
    voicing_low: f64,
    voicing_high: f64,
    /// The periodicity ramp that reads a label's voicing; `None`: the comb's score reads it.
    periodicity: Option<(f64, f64)>,
    /// Exponent of the periodicity's weight on each F0 candidate's comb (0: none).
    periodicity_weight: f64,
    hz_per_bin: f64,
    /// Highest bin (exclusive, fractional) the F0 analysis reads.
    k_max: f64,
    /// Highest bin the coarse stage of the F0 search reads.
    k_coarse: f64,
    /// F0 candidates (Hz), log-spaced.
    candidates: Vec<f64>,
    unresolved_floor: f64,
    /// Register width (natural log of F0; 0 disables the register).
    register_sigma: f64,
    /// Register forgetting per frame.
    register_forgetting: f64,
    /// Register weight at half confidence.
    register_half: f64,
    /// Exponent of the register's preference in a comb's strength (0: salience alone).
    register_ownership: f64,
    /// Direct-path dominance ramp of the activity gate; `None` when the gate is off.
    activity: Option<(f64, f64)>,
    activity_smoothing: f64,
    /// The room level at which the gate's thresholds hold as set; `None`: they always do.
    room_reference: Option<f64>,
    /// Forgetting per frame of the room level.
    room_forgetting: f64,
    /// Weight (frames) of a new room level's prior at the reference.
    room_prior: f64,
    /// Largest |ln| change of F0 per frame that continues a held voiced segment (0: no hold).
    hold_log_step: f64,
    /// Frames a segment may be held with the gate closed.
    hold_max_frames: usize,
    /// Frames after a label's birth before its gate is its own measurement: the smoothed
    /// dominance starts at 1 and has forgotten 90 % of that after this many.
    hold_start_frames: usize,
    /// Power of the mixture's local level that divides a contest salience (0: raw magnitudes).
    salience_whitening: f64,
    /// Half-width (bins) of the band the local level is measured over.
    whitening_half_width: usize,
    /// The pitch track's transition; `None`: each frame's F0 is searched on its own.
    transition: Option<Transition>,
    /// Exponent of a competitor's audibility in the F0 analysis's reliability.
    audibility_exponent: f64,
}

impl Harmonic {
    /// Constants from the configuration at `hz_per_bin` Hz per STFT bin and `frames_per_s`
    /// analysis frames per second.
    pub fn new(cfg: &HarmonicConfig, hz_per_bin: f64, frames_per_s: f64) -> Self {
        let mut candidates = Vec::new();
        let mut f = cfg.f0_min_hz;
        while f <= cfg.f0_max_hz {
            candidates.push(f);
            f *= 1.0 + GRID_STEP;
        }
        Self {
            hann: HannTable::new(),
            boost: cfg.boost,
            leakage_exponent: cfg.leakage_exponent,
            inverse_leakage_exponent: 1.0 / cfg.leakage_exponent.max(1e-9),
            ownership_exponent: cfg.ownership_exponent,
            spatial_discount: cfg.spatial_discount,
            voicing_low: cfg.voicing_low,
            voicing_high: cfg.voicing_high,
            periodicity: cfg
                .periodicity_voicing
                .then_some((cfg.periodicity_low, cfg.periodicity_high)),
            periodicity_weight: cfg.periodicity_weight,
            hz_per_bin,
            k_max: cfg.max_frequency_hz / hz_per_bin.max(1e-12),
            k_coarse: COARSE_TOP_HZ / hz_per_bin.max(1e-12),
            candidates,
            unresolved_floor: power(0.0, cfg.leakage_exponent),
            register_sigma: cfg.register_semitones * std::f64::consts::LN_2 / 12.0,
            register_forgetting: (-1.0 / (cfg.register_memory_s * frames_per_s).max(1e-9)).exp(),
            register_half: (cfg.register_confidence_s * frames_per_s).max(1e-9),
            register_ownership: cfg.register_ownership,
            activity: cfg
                .activity_gate
                .then_some((cfg.activity_low, cfg.activity_high)),
            activity_smoothing: cfg.activity_smoothing,
            room_reference: (cfg.activity_gate && cfg.activity_room_level > 0.0)
                .then_some(cfg.activity_room_level),
            room_forgetting: (-1.0 / (cfg.activity_room_memory_s * frames_per_s).max(1e-9)).exp(),
            room_prior: activity::LEVEL_PRIOR_S * frames_per_s,
            hold_log_step: cfg.activity_hold.ln_1p(),
            hold_max_frames: (cfg.activity_hold_max_s * frames_per_s).round() as usize,
            hold_start_frames: if cfg.activity_smoothing > 0.0 {
                (0.1f64.ln() / cfg.activity_smoothing.ln()).ceil() as usize
            } else {
                0
            },
            salience_whitening: cfg.salience_whitening,
            whitening_half_width: (0.5 * cfg.whitening_bandwidth_hz / hz_per_bin.max(1e-12))
                .round()
                .max(0.0) as usize,
            audibility_exponent: cfg.competitor_audibility_exponent,
            transition: Transition::new(
                cfg.track_semitones_per_s * std::f64::consts::LN_2 / 12.0 / frames_per_s.max(1e-9),
                cfg.track_jump,
                GRID_STEP.ln_1p(),
            ),
        }
    }

    /// The register's preference over F0, in (0, 1]: 1 without a register, else a Gaussian in
    /// log F0 around its mean, mixed with 1 by how established it is (fixed for one search).
    fn preference(&self, register: &Register) -> impl Fn(f64) -> f64 {
        let c = if self.register_sigma > 0.0 && register.weight > 0.0 {
            REGISTER_MAX_CONFIDENCE * register.weight / (register.weight + self.register_half)
        } else {
            0.0
        };
        let (mean, sigma) = (register.log_f0, self.register_sigma);
        move |f0: f64| {
            if c == 0.0 {
                return 1.0;
            }
            let d = (f0.ln() - mean) / sigma;
            1.0 - c + c * (-0.5 * d * d).exp()
        }
    }

    /// Folds this frame's pitch of a label into its register, weighted by `evidence`
    /// (its ownership, which includes its voicing), after forgetting one frame.
    pub fn observe(&self, register: &mut Register, pitch: &Pitch, evidence: f64) {
        register.weight *= self.register_forgetting;
        if pitch.f0 <= 0.0 || evidence.is_nan() || evidence <= 0.0 {
            return;
        }
        let w = register.weight + evidence;
        register.log_f0 += evidence / w * (pitch.f0.ln() - register.log_f0);
        register.weight = w;
    }

    /// How unresolved a claim is, in [0, 1], from the leakage of the nearest competitor.
    pub fn unresolved(&self, leakage: f64) -> f64 {
        power(leakage.clamp(0.0, 1.0), self.leakage_exponent)
    }

    /// [`Harmonic::unresolved`] of a perfectly resolved claim (0, or 1 with exponent 0).
    pub fn unresolved_floor(&self) -> f64 {
        self.unresolved_floor
    }

    /// One past the highest bin [`Harmonic::pitch`] reads (with interpolation).
    pub fn top_bin(&self) -> usize {
        self.k_max.max(0.0) as usize + 2
    }

    /// Whether the grouping changes anything.
    pub fn enabled(&self) -> bool {
        self.boost > 0.0 && !self.candidates.is_empty()
    }

    /// Whether voicing is scaled by the labels' direct-path dominances (the grouping is on and so
    /// is its activity gate).
    pub fn gates_activity(&self) -> bool {
        self.enabled() && self.activity.is_some()
    }

    /// The voicing read from a label's periodicity `peak` (see [`Periodicity::peak`]); `None`
    /// when the comb's score reads the voicing.
    pub fn periodic_voicing(&self, peak: f64) -> Option<f64> {
        let (lo, hi) = self.periodicity?;
        let v = ((peak - lo) / (hi - lo)).clamp(0.0, 1.0);
        Some(if v.is_finite() { v } else { 0.0 })
    }

    /// Whether a label's periodicity is read at all: for its voicing, its F0 search or both.
    pub fn reads_periodicity(&self) -> bool {
        self.enabled() && (self.periodicity.is_some() || self.periodicity_weight > 0.0)
    }

    /// The weight of an F0 candidate's comb by the frame's autocorrelation at its period,
    /// (r + floor)^`periodicity_weight`; 1 everywhere without a frame or a weight.
    fn periodic_weight<'a>(
        &self,
        periodicity: Option<&'a Periodicity>,
    ) -> impl Fn(f64) -> f64 + 'a {
        let g = self.periodicity_weight;
        let read = periodicity.filter(|_| g > 0.0);
        move |f0: f64| match read {
            Some(p) => power(p.at(f0).max(0.0) + PERIODIC_FLOOR, g),
            None => 1.0,
        }
    }

    /// How much each label's pitch is its own, in [0, 1]: its voicing times the mean, over its
    /// harmonics up to `max_frequency_hz`, of its comb's share there (see
    /// [`Harmonic::evidence`]). A talker's harmonics leak, attenuated by the spatial gains, into
    /// the other labels' outputs; there they show its F0, or a subharmonic of it whose comb
    /// passes through every one of its harmonics, with less salience and are discounted.
    pub fn ownership(&self, pitch: &[Pitch], out: &mut [f64]) {
        for (o, p) in out.iter_mut().zip(pitch) {
            let step = p.f0 / self.hz_per_bin;
            if !(step > 0.0 && p.voicing > 0.0) {
                *o = 0.0;
                continue;
            }
            let (mut sum, mut count) = (0.0, 0usize);
            let mut kf = step;
            while kf < self.k_max {
                sum += self.share(pitch, p, kf);
                count += 1;
                kf += step;
            }
            *o = if count > 0 {
                p.voicing * sum / count as f64
            } else {
                0.0
            };
        }
    }

    /// Each label's harmonic evidence at bin `k`: its voicing times its comb's membership there
    /// times its share of the bin, (its comb's strength / the strongest
    /// comb's)^`ownership_exponent`, a comb's strength being its salience times its register fit
    /// times its membership. Two labels with the same F0 compare their saliences, each weighted by
    /// how well the F0 fits that label's register; a label whose F0 is a subharmonic of a louder
    /// one's loses the bins the louder comb passes through and keeps those between them.
    pub fn evidence(&self, pitch: &[Pitch], k: usize, out: &mut [f64]) {
        let kf = k as f64;
        let mut top = 0.0f64;
        for (e, p) in out.iter_mut().zip(pitch) {
            *e = self.membership(p.f0, kf);
            top = top.max(p.strength() * *e);
        }
        for (e, p) in out.iter_mut().zip(pitch) {
            *e = if *e > 0.0 {
                p.voicing * *e * self.share_against(p.strength() * *e, top)
            } else {
                0.0
            };
        }
    }

    /// Label `i`'s claim on its own harmonic at (fractional) bin `kf`: its voicing times its
    /// share there in the labels' contest (as in [`Harmonic::evidence`]).
    pub fn claim(&self, pitch: &[Pitch], i: usize, kf: f64) -> f64 {
        pitch
            .get(i)
            .map_or(0.0, |p| p.voicing * self.share(pitch, p, kf))
    }

    /// `p`'s share of (fractional) bin `kf` among the combs of `pitch` (which includes `p`).
    fn share(&self, pitch: &[Pitch], p: &Pitch, kf: f64) -> f64 {
        let own = p.strength() * self.membership(p.f0, kf);
        let top = pitch
            .iter()
            .map(|q| q.strength() * self.membership(q.f0, kf))
            .fold(own, f64::max);
        self.share_against(own, top)
    }

    /// The share of a comb of strength `own` in a bin whose strongest comb has strength `top`
    /// (at least `own`).
    fn share_against(&self, own: f64, top: f64) -> f64 {
        if top > 0.0 {
            power(own / top, self.ownership_exponent)
        } else {
            0.0
        }
    }

    /// How much of the comb of `f0` passes through (fractional) bin `kf`: the analysis
    /// window's (periodic Hann) power response at the distance to the nearest harmonic, 1 on a
    /// harmonic, 0 two bins or more away.
    pub fn membership(&self, f0: f64, kf: f64) -> f64 {
        if f0 <= 0.0 {
            return 0.0;
        }
        let step = f0 / self.hz_per_bin;
        let h = (kf / step).round().max(1.0);
        self.hann.power(kf - h * step)
    }

    /// Regroups one bin: `gains` are the labels' spatial gains, `unresolved` how ambiguous each
    /// label's claim is (0 keeps its gain), `evidence` each label's voicing times comb membership.
    /// The pooled gain of the unresolved claims is shared in proportion to
    /// gain^(1 - spatial_discount x leakage) x (1 + boost x evidence): the spatial gain counts
    /// as far as the bin is resolved. The result is floored at `floor`. `shares` is scratch.
    pub fn regroup(
        &self,
        gains: &mut [f64],
        unresolved: &[f64],
        evidence: &[f64],
        floor: f64,
        shares: &mut Vec<f64>,
    ) {
        shares.clear();
        let mut pool = 0.0;
        let mut weight = 0.0;
        for ((g, u), e) in gains.iter().zip(unresolved).zip(evidence) {
            let w = u * self.spatial_weight(*g, *u) * (1.0 + self.boost * e);
            shares.push(w);
            pool += u * g;
            weight += w;
        }
        if pool <= 0.0 || weight <= 0.0 {
            return;
        }
        for ((g, u), w) in gains.iter_mut().zip(unresolved).zip(shares.iter()) {
            let v = (1.0 - u) * *g + pool * (w / weight);
            *g = if v.is_finite() { v.max(floor) } else { *g };
        }
    }

    /// A spatial gain `g` (>= 0) as evidence in a bin of ambiguity `u`: g^(1 - discount x
    /// leakage). The bank keeps only `u` per bin and label; the leakage it came from follows
    /// exactly, since [`Harmonic::unresolved`] is a power of it.
    fn spatial_weight(&self, g: f64, u: f64) -> f64 {
        if self.spatial_discount <= 0.0 {
            return g;
        }
        let leakage = power(u, self.inverse_leakage_exponent);
        let e = 1.0 - self.spatial_discount * leakage;
        if e >= 1.0 {
            g
        } else if e <= 0.0 {
            1.0
        } else if g > 0.0 {
            // Single precision is ample for a weight and halves libm's cost per bin and label.
            f64::from((g as f32).powf(e as f32))
        } else {
            0.0
        }
    }
}

/// Leakage of a source with steering `b` into the output of the loaded two-column null-steering
/// beamformer aimed at `a`, relative to its response to `a` (loading relative to the mean
/// diagonal of the Gram matrix, as in the fixed branch): 0 when the steering vectors are
/// orthogonal, 1 when they are collinear.
pub fn leakage(a: &[Complex], b: &[Complex], loading: f64) -> f64 {
    let (mut ab, mut aa, mut bb) = (Complex::new(0.0, 0.0), 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        ab += x.conj() * y;
        aa += x.norm_sqr();
        bb += y.norm_sqr();
    }
    if aa <= 0.0 || bb <= 0.0 {
        return 0.0;
    }
    let c = (ab.norm_sqr() / (aa * bb)).sqrt().min(1.0);
    // Eigenvalues 1 +- c of the normalised Gram matrix, each passed as lambda / (lambda + delta).
    let e1 = (1.0 + c) / (1.0 + c + loading);
    let e2 = (1.0 - c) / (1.0 - c + loading);
    let l = (e1 - e2) / (e1 + e2);
    if l.is_finite() {
        l.clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// `x` (>= 0) to the power `e`, without libm's `pow` for the exponents the settings use
/// (it runs per bin and pair whenever a steering moves).
fn power(x: f64, e: f64) -> f64 {
    if e == 0.25 {
        x.sqrt().sqrt()
    } else if e == 0.5 {
        x.sqrt()
    } else if e == 1.0 {
        x
    } else if e == 2.0 {
        x * x
    } else if e == 4.0 {
        let y = x * x;
        y * y
    } else {
        x.powf(e)
    }
}

#[cfg(test)]
mod tests;
