//! Configuration of the separator: framing, beamformer, adaptive canceller, adaptation control,
//! post-filter and the lifecycle of the per-label streams.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::dsp::FrameGeometry;

pub use crate::field_error::FieldError as ConfigError;

/// Which spatial filter each label gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum BeamformerKind {
    /// Generalised sidelobe canceller (seed paper eq. 27-32): null-steering fixed beamformer,
    /// blocking matrix of the target's steering vector, RLS interference canceller.
    Gsc,
    /// The GSC's fixed branch alone: unit response toward the label, nulls toward the others.
    NullSteering,
    /// MVDR with a noise-plus-interference covariance learned while the target is quiet.
    Mvdr,
    /// Delay-and-sum toward the label (the baseline).
    DelayAndSum,
}

/// Which microphones a label's beamformer uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum MicSelection {
    /// All microphones of the layout as one array (the scene format's arrays share one clock).
    All,
    /// Only the array nearest to the label (re-chosen with hysteresis when the label moves).
    NearestArray,
}

/// The time-frequency post-filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum PostFilterKind {
    /// No post-filter: the beamformer output is the stream.
    None,
    /// Power-comparison mask (thesis section 3.5.2): 1 where the label's output power beats every
    /// other label's by `mask_threshold`, else `gain_floor`.
    Mask,
    /// Soft mask P_i^a / (sum_j P_j^a + N_i^a) on smoothed powers, floored at `gain_floor`.
    Wiener,
}

/// What the post-filter gain multiplies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum PostFilterTarget {
    /// The label's beamformer output.
    BeamformerOutput,
    /// The reference microphone's spectrum (keeps the reverberant image the truth is defined on).
    ReferenceMic,
}

/// Recursive least squares interference canceller of the GSC.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct RlsConfig {
    /// Forgetting factor per STFT frame while adapting fully (memory about 1 / (1 - forgetting)
    /// frames). 0.98 (1.6 s at hop 512, 16 kHz) beat 0.99 on every measured scene: uca8 three
    /// talkers, oracle tracks, seeds 1-6, SI-SDRi +0.15 dB and SIRi +0.2 dB; full pipeline seeds
    /// 1-3 +0.17 / +0.28 dB; paper-linear6 +0.02 dB and fewer split streams.
    pub forgetting: f64,
    /// Start regularisation delta relative to the bin's input power: P0 = I / (delta * power).
    pub init_regularisation: f64,
    /// Leakage: a ridge term of this size relative to the bin's input power, kept in the
    /// correlation estimate at all times against the drift of unexcited directions.
    pub leakage: f64,
    /// Bound on the canceller's norm relative to the fixed beamformer's (white-noise-gain
    /// constraint); the weights are scaled back when they exceed it.
    pub max_norm_ratio: f64,
    /// Partial update: each bin's canceller adapts on one frame in this many, the bins staggered
    /// so every frame updates the same share, with the forgetting per update raised to this
    /// power (the memory in seconds stays the same). The output uses the latest weights on every
    /// frame. 2 halves the canceller's cost (a capacity setting for crowded servers) at about
    /// -0.2 dB SI-SDRi (uca8 three talkers, seeds 1-6); 1 updates every bin on every frame.
    pub update_every: usize,
}

impl Default for RlsConfig {
    fn default() -> Self {
        Self {
            forgetting: 0.98,
            init_regularisation: 1e-2,
            leakage: 1e-3,
            max_norm_ratio: 10.0,
            update_every: 1,
        }
    }
}

/// MVDR beamformer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct MvdrConfig {
    /// Forgetting factor per STFT frame of the noise-plus-interference covariance.
    pub forgetting: f64,
    /// Diagonal loading relative to the mean diagonal of the covariance.
    pub loading: f64,
}

impl Default for MvdrConfig {
    fn default() -> Self {
        Self {
            forgetting: 0.99,
            loading: 1e-2,
        }
    }
}

/// When the adaptive parts (RLS canceller, MVDR covariance) learn: mainly while the target is
/// quiet, so that the target is not cancelled.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct AdaptationConfig {
    /// Target presence (speaking x activity, times the bin's dominance when `per_bin`) at or
    /// below which the filter adapts at full speed.
    pub presence_low: f64,
    /// Target presence at or above which adaptation stops; between the two the step is weighted
    /// and the forgetting slowed in proportion.
    pub presence_high: f64,
    /// Refine the presence per frequency bin with the share of the label's fixed-beamformer
    /// power among all labels, so bins dominated by interferers are learnt while the target talks.
    pub per_bin: bool,
    /// Smoothing factor per frame of the fixed-beamformer powers used by `per_bin`.
    pub power_smoothing: f64,
    /// With `per_bin` and two labels or more: a bin where the label's own fixed beamformer
    /// (nulls toward the others) carries most of the labels' power counts as its target
    /// talking, whatever the tracker says, so a talker the localiser missed (speaking 0) is
    /// not cancelled by its own canceller. Full pipeline, on against off: paper-linear6 seeds
    /// 1-6 +5.39 / +5.14 dB SI-SDRi (1.33 / 1.28 streams per talker); uca8 three talkers
    /// seeds 1-3 +8.55 / +8.29 dB (1.11 / 1.22 streams), 4-6 +7.95 / +7.77 dB; with oracle
    /// tracks within 0.11 dB. Its cost: an untracked interferer is cancelled less in the bins
    /// where it dominates a label's output.
    pub dominance_guard: bool,
    /// Share of the bin's fixed-beamformer power (among all labels) at or below which the
    /// guard leaves the presence as it is. 0.5 / 0.8 (default) against 0.4 / 0.7, 0.6 / 0.9
    /// and 0.5 / 1.0 (measured with the guard also on a lone label): paper-linear6 +5.53
    /// against +5.41, +5.44 and +5.44 dB, uca8 +8.52 against +8.37, +8.46 and +8.46 dB.
    pub dominance_low: f64,
    /// Share at or above which the guard freezes the label's adaptation in the bin.
    pub dominance_high: f64,
}

impl Default for AdaptationConfig {
    fn default() -> Self {
        Self {
            presence_low: 0.1,
            presence_high: 0.4,
            per_bin: true,
            power_smoothing: 0.5,
            dominance_guard: true,
            dominance_low: 0.5,
            dominance_high: 0.8,
        }
    }
}

/// Time-frequency post-filter computed from all labels' beamformer outputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct PostFilterConfig {
    /// `none`, `mask` (power comparison, binary with floor) or `wiener` (soft).
    pub kind: PostFilterKind,
    /// `beamformer_output` or `reference_mic`: what the gain multiplies.
    pub apply_to: PostFilterTarget,
    /// Smallest gain, against musical noise (0.1 = -20 dB).
    pub gain_floor: f64,
    /// Smoothing factor per frame of the output powers (0 = no smoothing).
    pub power_smoothing: f64,
    /// Exponent a of the soft mask P_i^a / (sum_j P_j^a + N^a); larger is closer to binary.
    pub exponent: f64,
    /// `mask`: a label wins a bin when its power exceeds this factor times every other label's.
    pub mask_threshold: f64,
    /// `wiener`: include the stationary noise floor (minimum tracking) in the denominator.
    pub noise_floor: bool,
    /// Weight of the reference microphone's power that no label's output explains (untracked
    /// talkers, noise) as one more competitor of every label; 0 ignores it.
    pub untracked_weight: f64,
    /// How much more power than the labels' outputs the reference microphone may carry before the
    /// excess counts as untracked (their reverberation, which the beamformers remove).
    pub untracked_margin: f64,
    /// Rise of the tracked noise floor per second (dB/s) when the power stays above it.
    pub noise_rise_db_per_s: f64,
    /// Prior weight of a label the tracker believes silent, relative to one that talks: each
    /// label's claim on a bin is weighted by `presence_floor + (1 - presence_floor) x presence`
    /// (presence = speaking x activity) and by its fade envelope. 1 (default) ignores the
    /// speaking probabilities: with oracle talk spurts 0.1 gains 0.3 dB SI-SDR on uca8 (0.5 dB
    /// and 1.28 -> 1.14 streams per talker on paper-linear6 seeds 1-12), but estimated ones
    /// cost: the tracker's 0.2 dB (uca8) and 0.5 dB (paper-linear6), seeds 1-3; the filtered
    /// probe's (pipeline `speaking`), paper-linear6 seeds 1-12, 0.5: -0.13 dB and 1.25 -> 1.31
    /// streams, 0.3: -0.25 dB and 1.39 streams.
    pub presence_floor: f64,
    /// Harmonic grouping of the bins the array cannot resolve between labels.
    pub harmonic: HarmonicConfig,
}

/// Harmonic (F0) grouping of unresolved bins, after the spatial post-filter gains (see
/// `separate::harmonic`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct HarmonicConfig {
    /// How strongly a voiced label whose harmonic comb passes through an unresolved bin is
    /// preferred: its share of the labels' pooled gain is weighted by 1 + boost x evidence
    /// (evidence = ownership x comb membership, in [0, 1]). 0 turns the grouping off. 100
    /// (default) against 10 / 1000: +0.05 / +0.04 dB SI-SDR on paper-linear6 seeds 1-3 and
    /// about the same on 4-6 and uca8.
    pub boost: f64,
    /// How unresolved a label's claim on a bin is: the leakage (0..1) of its least resolved
    /// competitor through the loaded null-steering beamformer, to this power; 1 - that is the
    /// bin's reliability for the label's F0 analysis. 0.25 (default) against 0.5 / 1:
    /// paper-linear6 seeds 1-3 +5.4 / +5.0 / +4.7 dB SI-SDRi (4-6: +2.4 / +2.2 / +1.9) with
    /// `ownership_exponent` 1.
    pub leakage_exponent: f64,
    /// Exponent of a label's share of a bin's harmonic evidence: its comb's strength (salience
    /// x membership) relative to the strongest comb through the bin, so a neighbour's leaked
    /// harmonics, read at the same F0 or at a subharmonic of it, are discounted. Full pipeline,
    /// SI-SDRi (dB) for 1 / 2 / 4 (default) / 6 / 8: paper-linear6 seeds 1-6 +5.60 / +5.84 /
    /// +5.98 / +6.04 / +6.09 (streams per talker 1.33 / 1.28 / 1.17 / 1.11 / 1.11), seeds 7-12
    /// - / +5.73 / +5.93 / +6.01 / +6.04, uca8 seeds 1-3 +8.73 / +8.79 / +8.78 / +8.74 / +8.72.
    pub ownership_exponent: f64,
    /// How far the spatial gain's say in an unresolved bin shrinks with the pair's leakage l
    /// (the one `leakage_exponent` is applied to): the labels share the pooled gain in
    /// proportion to gain^(1 - spatial_discount x l) x (1 + boost x evidence). Where two
    /// labels' beamformers pass the same mixture, their power-comparison gains only say which
    /// talker is louder, so with 1 (default) a collinear bin is split by harmonic evidence alone
    /// and a quiet talker keeps its own harmonics; 0 weighs the spatial gain fully everywhere
    /// (the earlier rule). 1 against 0, full pipeline: paper-linear6 seeds 1-3 +6.18 / +5.92 dB
    /// SI-SDRi, seeds 4-6 +3.09 / +2.85 dB (1.33 / 1.44 streams per talker); uca8 three
    /// talkers seeds 1-3 +7.78 / +7.60 dB, oracle tracks +8.39 / +8.20 dB. Discounting by the
    /// steeper u = l^leakage_exponent instead gained more on paper-linear6 (+6.43 / +3.67 dB)
    /// but lost 0.7 dB SIR on uca8 and let spurious combs split disjoint tones.
    pub spatial_discount: f64,
    /// Lowest F0 candidate (Hz).
    pub f0_min_hz: f64,
    /// Highest F0 candidate (Hz).
    pub f0_max_hz: f64,
    /// Highest frequency the F0 analysis reads (Hz). On a small array the bins that tell two
    /// nearby labels apart lie high, so reading the comb there decides whose pitch it is;
    /// higher still, the harmonics of a 64 ms frame smear with the F0's movement. 4000
    /// (default) against 2000, full pipeline: paper-linear6 seeds 1-6 +5.14 / +4.64 dB SI-SDRi
    /// (1.28 / 1.33 streams per talker); uca8 three talkers seeds 1-3 +8.24 / +7.78 dB
    /// (oracle tracks +8.77 / +8.39 dB); 3000 and 6000 gave +5.07 and +5.32 dB on
    /// paper-linear6 but +8.28 and +8.08 dB on uca8.
    pub max_frequency_hz: f64,
    /// Normalised comb score (peak minus valley over peak plus valley, on magnitudes) at or
    /// below which a label counts as unvoiced: white noise scores about 0.2. 0.25 / 0.55
    /// (default) and 0.1 / 0.4 agree within 0.02 dB on paper-linear6 and uca8 seeds 1-3.
    pub voicing_low: f64,
    /// Comb score at or above which a label counts as fully voiced.
    pub voicing_high: f64,
    /// Width (semitones, one standard deviation) of a label's pitch register: the F0 search
    /// prefers candidates near the running mean of the label's own past F0s (weighted by
    /// their ownership, which includes voicing), so a label does not pick up a neighbour's pitch in the
    /// frames where that neighbour's leak is as strong as its own voice. 0 turns the register
    /// off. 4 (default) against off: paper-linear6 seeds 1-3 +5.99 / +5.57 dB SI-SDRi, seeds
    /// 4-6 +2.87 / +2.59 dB; uca8 three talkers seeds 1-3 oracle +8.20 / +7.93 dB, full
    /// pipeline +7.76 / +7.60 dB. 2.5 and 6: paper-linear6 +5.94 / +5.88 (1-3), +2.59 / +2.81
    /// (4-6).
    pub register_semitones: f64,
    /// Memory of the register (s): its mean forgets older F0s with this time constant. 5
    /// (default) and 20 agree within 0.04 dB on paper-linear6 seeds 1-6.
    pub register_memory_s: f64,
    /// Voiced, owned speech (s) after which the register weighs half its full strength. 0.5
    /// (default) against 2: paper-linear6 +0.10 / +0.17 dB SI-SDRi (seeds 1-3 / 4-6).
    pub register_confidence_s: f64,
    /// Exponent of the register's preference for a label's F0 in its comb's strength, where
    /// the labels contest a harmonic (`ownership_exponent`): 1 multiplies the salience by the
    /// register's prior, so of two labels reading the same F0 the one whose register holds it
    /// keeps the harmonics; 0 compares saliences alone. 1 (default) against 0, full pipeline,
    /// SI-SDRi (dB) / streams per talker: paper-linear6 seeds 1-12 +6.39 / 1.25 against +6.26 /
    /// 1.25, uca8 three talkers seeds 1-6 +8.66 / 1.17 against +8.58 / 1.22, recorded speech
    /// on paper-linear6 seeds 1-12 +4.86 / 1.19 either way; 2 and 4 gave +6.35 and +6.15 dB
    /// on paper-linear6 and +4.85 and +4.75 dB on recorded speech.
    pub register_ownership: f64,
    /// Scale each label's voicing by how much of the direct-path power its talker holds (a
    /// least-squares fit of the labels' direct paths plus a diffuse field to the covariance,
    /// 1-4 kHz), so a silent label that reads a neighbour's or the room's harmonics does not
    /// claim them. On against off, full pipeline, SI-SDRi (dB) / streams per talker: recorded
    /// speech on paper-linear6 seeds 1-12 +5.15 / 1.22 against +4.86 / 1.19 (oracle tracks
    /// +5.52 / 1.17 against +5.20 / 1.25), uca8 three talkers seeds 1-6 +5.94 / 1.28 against
    /// +5.63 / 1.33; synthetic voices paper-linear6 seeds 1-12 +6.40 / 1.22 against +6.39 /
    /// 1.25, uca8 seeds 1-6 +8.57 / 1.17 against +8.66 / 1.17. The synthetic voices, more
    /// harmonic than real ones, lose little to a silent label's spurious comb.
    pub activity_gate: bool,
    /// The label's share of the fitted power (smoothed) at or below which its voicing counts as
    /// none; a silent label's median share is about 0.07, a talker's 5 dB or more below a
    /// neighbour about 0.2 (paper-linear6).
    pub activity_low: f64,
    /// The share at or above which the voicing is kept whole; between the two it is scaled.
    /// Recorded speech gains from a stricter gate, 0.1 / 0.5 (`activity_low` / `activity_high`)
    /// against the defaults, full pipeline, SI-SDRi (dB) / streams per talker: paper-linear6
    /// seeds 1-12 +5.56 / 1.11 against +5.19 / 1.22 (seeds 13-24 +5.34 against +4.92), uca8
    /// three talkers seeds 1-6 +6.00 against +5.82 (seeds 7-12 +5.93 against +5.70); the labels'
    /// false voicing (`avsep eval`'s pitch section) falls from 12 % to 4 % of the silent or
    /// unvoiced frames and their voiced recall from 46 % to 34 %. The simulator's voices, more
    /// harmonic, lose with it: paper-linear6 +6.91 / 1.25 against +7.41 / 1.08, uca8 +8.31
    /// against +8.95.
    pub activity_high: f64,
    /// Smoothing factor per frame of each label's share.
    pub activity_smoothing: f64,
    /// A voiced segment that starts with the gate open is held open while its comb stays
    /// voiced and its F0 moves by less than this fraction per frame, and while held the label
    /// claims a low harmonic in the amplitude fit by its memory of it when that says more than
    /// the contest; 0 turns the hold off. A vowel with little energy above 1 kHz closes the
    /// gate (its talker's share of the direct-path power there is small) though the talker
    /// goes on, and a neighbour in unison, whose comb wins the contest in the upper bins, then
    /// takes the low harmonics. 0.04 (default) against 0, full pipeline, SI-SDRi (dB) / streams
    /// per talker: paper-linear6 seeds 1-12 +7.41 / 1.08 against +7.17 / 1.11, uca8 three
    /// talkers seeds 1-6 +8.95 against +8.50; recorded speech, whose combs seldom stay voiced
    /// with the gate closed (and, when they do, more often on a silent label than a talking
    /// one), on paper-linear6 seeds 1-12 +5.12 / 1.22 against +5.24 / 1.22 (per-scene changes
    /// of -0.3 to +0.3 dB either way), uca8 seeds 1-6 +5.82 against +5.86. Without the claim
    /// by memory: +7.39 / 1.11, +8.93, +5.18 and +5.84; 0.02 and 0.08 measured within 0.02 dB
    /// of 0.04.
    pub activity_hold: f64,
    /// Longest a voiced segment is held with the gate closed (s): a long vowel. Without a
    /// bound a label that stopped, reading a neighbour who holds one note, would be held for as
    /// long as the note lasts.
    pub activity_hold_max_s: f64,
    /// How far a comb's salience in the labels' contest for a harmonic is measured against the
    /// mixture's local level: each harmonic's peak-minus-valley magnitude is divided by the
    /// reference microphone's RMS magnitude over `whitening_bandwidth_hz` to this power (the F0
    /// search still reads raw magnitudes). 0 compares raw magnitudes, where the few loud
    /// harmonics below about 500 Hz decide, and a small array's spatial gains there follow the
    /// room more than the talker; 1 weighs every harmonic alike. 0.5 (default) against 0,
    /// full pipeline, SI-SDRi (dB) / streams per talker: paper-linear6 seeds 1-12 +6.74 / 1.25
    /// against +6.40 / 1.22 (oracle tracks +6.89 / 1.19 against +6.60 / 1.19), uca8 three
    /// talkers seeds 1-6 +8.64 against +8.57; recorded speech on paper-linear6 seeds 1-24
    /// +5.05 against +5.00, on uca8 seeds 1-18 +6.37 against +6.42. 0.3 and 0.7 gave +6.62 and
    /// +6.80 dB on paper-linear6, and +4.94 and +4.93 dB against +4.86 on recorded speech
    /// (paper-linear6 seeds 13-24).
    pub salience_whitening: f64,
    /// Width (Hz) of the band the mixture's local level is measured over.
    pub whitening_bandwidth_hz: f64,
    /// Below this frequency (Hz) the unresolved bins are divided by a joint least-squares fit
    /// of every voiced label's harmonics to the reference microphone (`harmonic/fit.rs`): each
    /// label gets the power its fitted harmonics have in the bin, and what no harmonic explains
    /// is shared as the grouping would share the bin. 0 turns the fit off. Below 1 kHz is where
    /// the separator falls short of the ideal ratio mask (its output with the ideal mask's bins
    /// below 1 kHz scores +13.0 dB SI-SDRi on paper-linear6, against +6.9 dB). 1000 (default)
    /// against 0, full pipeline, SI-SDRi (dB) / streams per talker: paper-linear6 seeds 1-12
    /// +7.08 / 1.11 against +6.74 / 1.25; uca8 three talkers seeds 1-6 +8.49 against +8.64;
    /// recorded speech on paper-linear6 seeds 1-12 +5.24 / 1.22 against +5.15 / 1.19, on uca8
    /// seeds 1-6 +5.86 against +5.88.
    pub fit_below_hz: f64,
    /// Regularisation of a fully claimed harmonic's amplitude in the fit, relative to the mean
    /// energy of a harmonic's column; a column claimed with evidence e gets this over e, so a
    /// label reading a neighbour's F0 with little claim takes little of it.
    pub fit_loading: f64,
    /// A label's harmonics enter the fit only in frames where its voicing is at least this (1:
    /// only wholly voiced frames, whose comb score reaches `voicing_high`). Fitting every voiced
    /// frame (0) gains more on the simulator's voices (paper-linear6 +7.56 / 1.14, uca8 +8.76)
    /// but loses on recorded speech (+4.68 and +5.22 dB), whose partly voiced frames the model
    /// of steady harmonics fits badly; 0.7 and 0.9 fall between.
    pub fit_min_voicing: f64,
    /// Smoothing per frame of each label's memory of its fitted power per bin (0.9: a time
    /// constant of about 0.3 s at 32 ms hops); a harmonic's claim in the fit is weighted by
    /// its label's memory there against the strongest label's, so where two labels' columns
    /// coincide (unison, octaves), and the fit cannot tell them apart, the bin's power is
    /// divided as their voices had it in the frames before rather than by their combs' strength
    /// alone. 0 turns the memory off. 0.9 (default, exponent 0.5) against 0, without the
    /// activity hold, full pipeline, SI-SDRi (dB) / streams per talker: paper-linear6 seeds
    /// 1-12 +7.17 / 1.11 against +7.08 / 1.11 (gains on 10 of 12 scenes), uca8 three talkers
    /// seeds 1-6 +8.50 against +8.49; recorded speech on paper-linear6 seeds 1-12 +5.24 / 1.22
    /// and on uca8 seeds 1-6 +5.86, both as without.
    pub fit_memory: f64,
    /// Exponent of the memory weight, (memory + floor) / (strongest memory + floor) with the
    /// floor a hundredth of the strongest; 0.5 divides two coinciding columns' amplitudes as
    /// their labels' remembered amplitudes. 1 gave paper-linear6 +7.20 / 1.14.
    pub fit_memory_exponent: f64,
}

impl Default for HarmonicConfig {
    fn default() -> Self {
        Self {
            boost: 100.0,
            leakage_exponent: 0.25,
            ownership_exponent: 4.0,
            spatial_discount: 1.0,
            f0_min_hz: 70.0,
            f0_max_hz: 400.0,
            max_frequency_hz: 4000.0,
            voicing_low: 0.25,
            voicing_high: 0.55,
            register_semitones: 4.0,
            register_memory_s: 5.0,
            register_confidence_s: 0.5,
            register_ownership: 1.0,
            activity_gate: true,
            activity_low: 0.05,
            activity_high: 0.2,
            activity_smoothing: 0.5,
            activity_hold: 0.04,
            activity_hold_max_s: 0.5,
            salience_whitening: 0.5,
            whitening_bandwidth_hz: 250.0,
            fit_below_hz: 1000.0,
            fit_loading: 1e-3,
            fit_min_voicing: 1.0,
            fit_memory: 0.9,
            fit_memory_exponent: 0.5,
        }
    }
}

impl Default for PostFilterConfig {
    fn default() -> Self {
        Self {
            kind: PostFilterKind::Wiener,
            apply_to: PostFilterTarget::ReferenceMic,
            gain_floor: 0.05,
            power_smoothing: 0.3,
            exponent: 2.0,
            mask_threshold: 1.0,
            noise_floor: false,
            untracked_weight: 0.0,
            untracked_margin: 1.0,
            noise_rise_db_per_s: 5.0,
            presence_floor: 1.0,
            harmonic: HarmonicConfig::default(),
        }
    }
}

/// Birth and death of a label's stream.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct LifecycleConfig {
    /// Fade-in of a new label's stream (s).
    pub fade_in_s: f64,
    /// Time a label may be missing from the targets before its stream fades out (s); it keeps its
    /// adaptive state and steers at its last position meanwhile.
    pub grace_s: f64,
    /// Fade-out of a disappeared label's stream (s), after which its state is dropped.
    pub fade_out_s: f64,
}

impl Default for LifecycleConfig {
    fn default() -> Self {
        Self {
            fade_in_s: 0.064,
            grace_s: 0.256,
            fade_out_s: 0.064,
        }
    }
}

/// Separator settings: one beamformer (plus post-filter) per tracked label.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct SeparatorConfig {
    /// STFT frame (window and FFT) length in samples (1024 at 16 kHz; the paper uses 2048).
    /// 2048 with hop 512 resolves harmonics twice as finely and scores more on the simulator's
    /// voices but splits more talkers and loses on recorded speech, at 1.5 times the
    /// pipeline's CPU. Full pipeline, SI-SDRi (dB) / streams per talker, 2048 against 1024:
    /// paper-linear6 seeds 1-12 +8.32 / 1.25 against +7.41 / 1.08, uca8 three talkers seeds
    /// 1-6 +9.56 against +8.95; recorded speech on paper-linear6 +4.83 against +5.11, on
    /// uca8 +5.96 against +5.82; a whole uca8 scene 0.041 against 0.028 of real time.
    pub frame: usize,
    /// STFT hop in samples (512; the paper uses 1024).
    pub hop: usize,
    /// `gsc` (default), `null_steering`, `mvdr` or `delay_and_sum` (baseline).
    pub beamformer: BeamformerKind,
    /// `all` layout microphones as one array, or the `nearest_array` to each label.
    pub mics: MicSelection,
    /// Lowest frequency processed (Hz); bins below it are output as silence.
    pub min_frequency_hz: f64,
    /// Highest frequency processed (Hz); `null` means up to Nyquist.
    pub max_frequency_hz: Option<f64>,
    /// Diagonal loading of the null-steering fixed beamformer relative to the mean diagonal of
    /// D^H D; keeps close-by labels and low frequencies from blowing up the white-noise gain.
    pub null_loading: f64,
    /// A label's steering (and with it the fixed beamformers and blocking matrices) is rebuilt
    /// only when its position moved enough to change some microphone's phase by more than this
    /// at the top processed frequency, or its relative gain by as much (rad; 0.2 is 1.4 mm of
    /// path at 8 kHz, far below the tracks' own jitter, and bounds the steering error at -14 dB
    /// at 8 kHz, -32 dB at 1 kHz). 0 rebuilds on every change. Against 0.05, 0.2 leaves uca8
    /// (oracle and tracker) and paper-linear6 within 0.12 dB SI-SDRi per seed set (seeds 1-6,
    /// mean change 0.00 dB) and single at the scorer's 40 dB, and takes 5 % off a session's
    /// work (most steps rebuilt every label's beamformers at 0.05).
    pub steering_tolerance_rad: f64,
    /// Adaptive canceller of the GSC.
    pub rls: RlsConfig,
    /// MVDR beamformer.
    pub mvdr: MvdrConfig,
    /// Adaptation control of the RLS canceller and the MVDR covariance.
    pub adaptation: AdaptationConfig,
    /// Time-frequency post-filter.
    pub post_filter: PostFilterConfig,
    /// Stream birth, grace period and death.
    pub lifecycle: LifecycleConfig,
}

impl Default for SeparatorConfig {
    fn default() -> Self {
        Self {
            frame: 1024,
            hop: 512,
            beamformer: BeamformerKind::Gsc,
            mics: MicSelection::All,
            min_frequency_hz: 0.0,
            max_frequency_hz: None,
            null_loading: 1e-2,
            steering_tolerance_rad: 0.2,
            rls: RlsConfig::default(),
            mvdr: MvdrConfig::default(),
            adaptation: AdaptationConfig::default(),
            post_filter: PostFilterConfig::default(),
            lifecycle: LifecycleConfig::default(),
        }
    }
}

impl SeparatorConfig {
    /// The STFT geometry the separator expects.
    pub fn frame_geometry(&self) -> FrameGeometry {
        FrameGeometry {
            frame: self.frame,
            hop: self.hop,
        }
    }
}

mod validate;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_round_trip() {
        let c = SeparatorConfig::default();
        c.validate().unwrap();
        let s = serde_json::to_string(&c).unwrap();
        let back: SeparatorConfig = serde_json::from_str(&s).unwrap();
        assert_eq!(back, c);
        let partial: SeparatorConfig =
            serde_json::from_str(r#"{"frame": 2048, "hop": 1024, "beamformer": "mvdr"}"#).unwrap();
        assert_eq!(partial.frame, 2048);
        assert_eq!(partial.beamformer, BeamformerKind::Mvdr);
        assert_eq!(partial.rls, RlsConfig::default());
    }

    #[test]
    fn rejects_unknown_fields_and_names_bad_ones() {
        assert!(serde_json::from_str::<SeparatorConfig>(r#"{"frmae": 1}"#).is_err());
        assert!(serde_json::from_str::<SeparatorConfig>(r#"{"rls": {"lambda": 1}}"#).is_err());
        let mut c = SeparatorConfig::default();
        c.rls.forgetting = 1.0;
        assert_eq!(c.validate().unwrap_err().field, "rls.forgetting");
        let c = SeparatorConfig {
            hop: 2048,
            ..SeparatorConfig::default()
        };
        assert_eq!(c.validate().unwrap_err().field, "frame");
        let mut c = SeparatorConfig::default();
        c.adaptation.presence_high = 0.1;
        assert_eq!(c.validate().unwrap_err().field, "adaptation.presence_high");
        let mut c = SeparatorConfig::default();
        c.adaptation.dominance_high = 0.5;
        assert_eq!(c.validate().unwrap_err().field, "adaptation.dominance_high");
        let c = SeparatorConfig {
            max_frequency_hz: Some(f64::NAN),
            ..SeparatorConfig::default()
        };
        assert_eq!(c.validate().unwrap_err().field, "max_frequency_hz");
    }

    #[test]
    fn each_section_is_named_in_its_errors() {
        let field = |edit: fn(&mut SeparatorConfig)| {
            let mut c = SeparatorConfig::default();
            edit(&mut c);
            c.validate().unwrap_err().field
        };
        assert_eq!(field(|c| c.rls.update_every = 9), "rls.update_every");
        assert_eq!(field(|c| c.mvdr.loading = 0.0), "mvdr.loading");
        assert_eq!(
            field(|c| c.post_filter.presence_floor = 0.0),
            "post_filter.presence_floor"
        );
        assert_eq!(
            field(|c| c.post_filter.harmonic.voicing_high = 0.1),
            "post_filter.harmonic.voicing_high"
        );
        assert_eq!(
            field(|c| c.post_filter.harmonic.f0_max_hz = 50.0),
            "post_filter.harmonic.f0_max_hz"
        );
        assert_eq!(field(|c| c.lifecycle.grace_s = -1.0), "lifecycle.grace_s");
    }
}
