//! Settings of the harmonic grouping (`separate::harmonic`), each with the measurements that
//! chose its default.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

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
    /// Whether a label's voicing is read from its periodicity, the normalised autocorrelation
    /// peak (Boersma's, with the window's own autocorrelation divided out) of its whole
    /// post-filtered frame, instead of from its comb score (`voicing_low` / `voicing_high`).
    /// The comb still reads the F0, and its score still says how audible the label is to the
    /// others. A label's spectrum can hold a comb its talker does not voice (a neighbour's
    /// leak) and lose the comb its talker does voice (under a louder neighbour); its upper
    /// band, which the array resolves, is noise when the talker is unvoiced. Against the
    /// truth's voicing (YIN on each talker's image), the label's final voicing separates
    /// voiced from unvoiced frames with an AUC of 0.91 against 0.80 (recorded speech on
    /// paper-linear6, seeds 1-12), and 0.93 against 0.85 on the simulator's voices (oracle
    /// tracks, seeds 1-12). On (default) against off, full pipeline, SI-SDRi / streams per
    /// talker: recorded speech paper-linear6 seeds 1-36 +6.13 / 1.185 against +5.69 / 1.185,
    /// uca8 three talkers seeds 1-6 +6.33 / 1.278 against +6.18 / 1.278; the simulator's
    /// voices paper-linear6 seeds 1-48 +7.74 / 1.160 against +7.82 / 1.160, uca8 seeds 1-6
    /// +8.73 / 1.167 against +8.74 / 1.111.
    pub periodicity_voicing: bool,
    /// Autocorrelation peak at or below which a label counts as unvoiced, with
    /// `periodicity_voicing`. A label's frame mixes its talker with what the array leaks, so
    /// its peak stays well under 1 even when its talker is voiced (median 0.40 on recorded
    /// speech against 0.15 unvoiced). 0.2 / 0.4 (default) against 0.15 / 0.35 and 0.1 / 0.3,
    /// full pipeline, recorded speech paper-linear6 seeds 1-36: +6.13 / +6.02 / +5.87 dB
    /// SI-SDRi; the simulator's voices seeds 1-48: +7.74 / +7.78 / +7.83 dB.
    pub periodicity_low: f64,
    /// Autocorrelation peak at or above which a label counts as fully voiced.
    pub periodicity_high: f64,
    /// Exponent of the weight a label's periodicity puts on each F0 candidate of its search:
    /// the comb's selection score is multiplied by (r + 0.05)^this, with r the normalised
    /// autocorrelation of the label's post-filtered frame (the one `periodicity_voicing`
    /// reads) at the candidate's period. The comb reads the resolved harmonics bin by bin,
    /// the autocorrelation the whole frame's periodicity; under a louder neighbour they fail
    /// on different frames, and the product picks the talker's own period more often. 0
    /// searches by the comb alone. 1 (default) against 0, full pipeline, SI-SDRi / streams
    /// per talker / half-second blocks on another label / F0 within 3 %: recorded speech on
    /// paper-linear6 seeds 1-36 +6.25 / 1.157 / 24 / 84.1 % against +6.13 / 1.185 / 28 / 81.0
    /// %, seeds 37-52 (held out) +6.40 / 1.125 / 6 / 84.3 % against +6.30 / 1.104 / 7 / 81.4
    /// %, uca8 seeds 1-12 +6.30 / 1.194 / 45 against +6.28 / 1.222 / 45; the simulator's voices
    /// on paper-linear6 seeds 1-48 +7.79 / 1.146 / 35 / 85.0 % against +7.74 / 1.160 / 37 /
    /// 84.2 %, seeds 49-72 (held out) +7.81 / 1.250 / 26 against +7.68 / 1.250 / 28, uca8 three
    /// talkers seeds 1-18 +9.06 / 1.167 / 60 against +9.04 / 1.148 / 59. Exponents 0.5, 1.5 and
    /// 2, and floors 0.02-0.2, were within 0.05 dB of 1 on paper-linear6 (simulated seeds 1-48,
    /// recorded 1-36).
    pub periodicity_weight: f64,
    /// Width (semitones, one standard deviation) of a label's pitch register: the F0 search prefers
    /// candidates near the running mean of the label's own past F0s (weighted by their ownership,
    /// which includes voicing), so a label does not pick up a neighbour's pitch in the frames where
    /// that neighbour's leak is as strong as its own voice. 0 turns the register off. 4 (default)
    /// against off: paper-linear6 seeds 1-3 +5.99 / +5.57 dB SI-SDRi, seeds 4-6 +2.87 / +2.59 dB;
    /// uca8 three talkers seeds 1-3 oracle +8.20 / +7.93 dB, full pipeline +7.76 / +7.60 dB. 2.5
    /// and 6: paper-linear6 +5.94 / +5.88 (1-3), +2.59 / +2.81 (4-6).
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
    /// How fast a label's F0 is expected to glide (semitones per second, one standard deviation):
    /// each label's F0 is followed as a track over frames (a causal Viterbi pass over the F0
    /// candidates, no added delay), and a change of F0 between two voiced frames costs (Δ / (this x
    /// hop))² / 2 nats, up to `track_jump`. 0 searches every frame on its own (the earlier rule).
    /// On (16, jump 0.3) against off (before the competitors' audibility), full pipeline, SI-SDRi
    /// (dB) / streams per talker: paper-linear6 seeds 1-24 +7.51 / 1.15 against +7.29 / 1.13, seeds
    /// 25-36 (not used to choose) +7.42 / 1.22 against +7.20 / 1.25, oracle tracks seeds 1-12 +7.88
    /// / 1.11 against +7.66 / 1.14; recorded speech on paper-linear6 seeds 1-24 +5.07 / 1.21
    /// against +5.05 / 1.22, on uca8 three talkers seeds 1-12 +5.76 / 1.25 against +5.76 / 1.22;
    /// uca8 seeds 1-6 +8.95 either way. 8 and 32: paper-linear6 +7.49 and +7.46 dB against +7.52
    /// (jump 0.5, every candidate scored).
    pub track_semitones_per_s: f64,
    /// Cost (nats) of any larger change of F0 between voiced frames: a new F0 is taken at once
    /// where its comb's selection score is e^track_jump times the continuing one's. 0.3
    /// (default) against 0.2 / 0.5 / 1, full pipeline: paper-linear6 seeds 1-24 +7.51 against
    /// +7.50 / +7.51 / +7.46 dB (1.15 against 1.14 / 1.14 / 1.15 streams per talker), recorded
    /// speech on paper-linear6 +5.07 against +5.07 / +5.05 dB; scoring every candidate instead
    /// of those the search refines and those near the last frame's pitch gave +7.54 and +5.13
    /// dB at 0.27 ms more per hop.
    pub track_jump: f64,
    /// Exponent of a competitor's audibility where a label reads its F0: a bin the label shares
    /// with a competitor it cannot be told apart from counts as unreliable as far as that
    /// competitor was audible last frame (the larger of its activity gate and the voicing its
    /// comb read, to this power), so a talker beside a silent label reads its F0 from the low
    /// harmonics they share, where a dark vowel has its energy. 0 counts every competitor
    /// fully (the earlier rule). 2 (default) against 0, full pipeline, SI-SDRi (dB) / streams
    /// per talker: recorded speech on paper-linear6 seeds 1-24 +5.22 / 1.17 against +5.07 /
    /// 1.21, on uca8 three talkers seeds 1-12 +6.00 / 1.22 against +5.76 / 1.25; uca8 seeds
    /// 1-6 +9.02 / 1.11 against +8.95 / 1.17; paper-linear6 seeds 1-24 +7.51 / 1.15 either way.
    /// 1 and 4: +5.17 and +5.24 dB on recorded paper-linear6, +9.03 and +8.99 dB on uca8. The
    /// activity gate alone as audibility (exponent 3): +5.34 dB recorded, but +8.60 dB on uca8
    /// and +7.39 on paper-linear6, since a talking dark vowel closes its gate.
    pub competitor_audibility_exponent: f64,
    /// Scale each label's voicing by its dominance: the share of the bins in 1-4 kHz where its
    /// direct path holds more than half of the power (a least-squares fit of the labels' direct
    /// paths plus a diffuse field to the covariance), so a silent label that reads a
    /// neighbour's or the room's harmonics does not claim them. On against off (measured when
    /// the gate read the label's share of the band's summed fitted power), full pipeline,
    /// SI-SDRi (dB) / streams per talker: recorded speech on paper-linear6 seeds 1-12 +5.15 /
    /// 1.22 against +4.86 / 1.19 (oracle tracks +5.52 / 1.17 against +5.20 / 1.25), uca8
    /// three talkers seeds 1-6 +5.94 / 1.28 against +5.63 / 1.33; synthetic voices
    /// paper-linear6 seeds 1-12 +6.40 / 1.22 against +6.39 / 1.25, uca8 seeds 1-6 +8.57 / 1.17
    /// against +8.66 / 1.17. The synthetic voices, more harmonic than real ones, lose little to
    /// a silent label's spurious comb.
    pub activity_gate: bool,
    /// The label's dominance (smoothed) at or below which its voicing counts as none; a silent
    /// label's median dominance is about 0.02, a talker's 5 dB or more below a neighbour about
    /// 0.15 (paper-linear6, full pipeline). The gate read the label's share of the band's
    /// summed fitted power (ramp 0.05 to 0.2) before; the dominance tells a quiet talker from a
    /// silent label better (area under the ROC curve 0.90 against 0.77 on paper-linear6, 0.86
    /// against 0.79 on recorded speech), and with this ramp opens silent labels about half as
    /// much (mean gate 0.18 against 0.33; recorded 0.17 against 0.31) and quiet talkers more or
    /// as much (0.78 against 0.71; recorded 0.69 against 0.72). Full pipeline, SI-SDRi
    /// (dB) / streams per talker / half-second blocks on another label, dominance against
    /// share: paper-linear6 seeds 1-48 +7.82 / 1.160 / 35 against +7.53 / 1.181 / 50; recorded
    /// speech on paper-linear6 seeds 1-36 +5.69 / 1.185 / 30 against +5.35 / 1.194 / 43, on
    /// uca8 seeds 1-12 +6.14 / 1.222 / 47 against +5.96 / 1.222 / 48; uca8 three talkers seeds
    /// 1-6 +8.74 / 1.111 / 18 against +8.96 / 1.111 / 17. Other ramps, the same four sets:
    /// 0.01 to 0.08 +7.83 / +5.43 / +5.99 / +9.06 dB, 0.02 to 0.1 +7.82 / +5.59 / +6.08 /
    /// +8.83, 0.03 to 0.12 +7.73 / +5.75 / +6.12 / +8.38.
    pub activity_low: f64,
    /// The dominance at or above which the voicing is kept whole; between the two it is
    /// scaled. Recorded speech gains from a stricter gate, 0.03 / 0.3 (`activity_low` /
    /// `activity_high`) against the defaults, full pipeline, SI-SDRi (dB) / streams per
    /// talker: paper-linear6 seeds 1-36 +5.90 / 1.231 against +5.69 / 1.185, uca8 seeds 1-12
    /// +6.23 / 1.222 against +6.14 / 1.222. The simulator's voices, more harmonic, lose with
    /// it: paper-linear6 seeds 1-48 +7.04 / 1.201 against +7.82 / 1.160, uca8 three talkers
    /// +8.30 against +8.74. A far, reverberant room gains from a looser gate, where a talker's
    /// direct path dominates few bins: 0.005 / 0.06 against these, with the low band and before
    /// the room calibration, `two-arrays` seeds 1-12 +4.28 / 1.528 against +3.87 / 1.556
    /// (oracle tracks +5.68 / 1.389 against +5.26 / 1.472), uca8 seeds 1-18 +9.59 against
    /// +9.37, paper-linear6 seeds 1-48 +7.95 against +7.87; recorded speech loses with it:
    /// paper-linear6 seeds 1-36 +6.12 / 1.130 against +6.43 / 1.093, uca8 seeds 1-12 +6.45
    /// against +6.60. `activity_room_level` now loosens both thresholds in such a room only.
    pub activity_high: f64,
    /// Smoothing factor per frame of each label's dominance.
    pub activity_smoothing: f64,
    /// Also fit 250 Hz-1 kHz and read a label's dominance as the mean of its dominances there
    /// and in 1-4 kHz, so a vowel with no power above 1 kHz (a nasal murmur, a dark back vowel),
    /// or a far talker whose direct path holds little of the band above it in a reverberant
    /// room, still opens its label's gate. The low band counts a label's bin only where the
    /// array tells the label from the other labels and from the diffuse field
    /// (`separate::direct_power::LOW_BAND_MAX_COSINE`): counting every bin undid the gate for a
    /// silent label beside a talker on a small array. On against off, full pipeline, SI-SDRi
    /// (dB) / streams per talker: `two-arrays` seeds 1-12 +3.87 / 1.556 against +3.16 /
    /// 1.722, recorded speech seeds 1-6 +2.39 / 1.556 against +1.45 / 1.722; uca8 seeds 1-18
    /// +9.37 / 1.148 against +9.30 / 1.130, seeds 19-30 +9.96 / 1.056 against +9.86 / 1.083,
    /// recorded seeds 1-12 +6.60 against +6.63, 13-20 +7.72 against +7.70 (1.139 and 1.042
    /// both); paper-linear6 seeds 1-48 +7.87 / 1.139 against +7.89 / 1.153, seeds 49-72
    /// +7.99 / 1.222 against +8.03 / 1.208, recorded seeds 1-36 +6.43 / 1.093 against +6.47 /
    /// 1.130, 37-52 +6.70 against +6.78 (1.083 both).
    pub activity_low_band: bool,
    /// The room level at which the gate's thresholds hold as set: where talkers' direct paths
    /// dominate fewer bins (a far talker in a reverberant room), both thresholds scale down by
    /// the room's level over this one, to a quarter at most; 0 keeps them as set. The room's
    /// level is the upper quartile of the strongest label's smoothed dominance per frame on a
    /// microphone group, over the last `activity_room_memory_s`. A talker's and a silent
    /// label's dominance fall together with the room's direct-to-reverberant ratio (upper
    /// quartiles, oracle tracks: `two-arrays` 0.09-0.18, uca8 0.21-0.39, paper-linear6
    /// 0.41-0.56), so thresholds set for the small arrays keep a far talker's gate shut
    /// while it talks. 0.25 (default) against 0, full pipeline, SI-SDRi (dB) / streams per
    /// talker: `two-arrays` seeds 1-12 +4.21 / 1.500 against +3.87 / 1.556 (oracle tracks +5.62
    /// / 1.333 against +5.26 / 1.472), seeds 13-24 +5.26 against +5.09 (1.472 both); recorded
    /// speech seeds 1-6 +2.54 / 1.444 against +2.39 / 1.556, 7-12 +4.32 / 1.278 against +4.15 /
    /// 1.389. The small arrays' rooms stay above 0.25 and come out the same within 0.01 dB and
    /// block for block (paper-linear6 seeds 1-72, recorded 1-52; uca8 seeds 1-30, recorded
    /// 1-20). 0.3 and 0.35: `two-arrays` +4.14 and +4.17 dB, recorded +2.51 both (memory 30 s).
    pub activity_room_level: f64,
    /// Memory (s) of the room level: the time constant over which it forgets. 10 (default)
    /// against 30: `two-arrays` seeds 1-12 +4.21 against +4.08 dB, recorded speech seeds 1-6
    /// +2.54 against +2.50 dB; the scenes last 15 s, and the longer memory has not left the
    /// level's start (the reference) behind by their end.
    pub activity_room_memory_s: f64,
    /// A voiced segment that starts with the gate open is held open while its comb stays
    /// voiced and its F0 moves by less than this fraction per frame, and while held the label
    /// claims a low harmonic in the amplitude fit by its memory of it when that says more than
    /// the contest; 0 turns the hold off. A vowel with little energy above 1 kHz closes the
    /// gate (its talker's direct path dominates few bins there) though the talker
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
    /// of steady harmonics fits badly; 0.7 and 0.9 fall between. Re-measured on the current
    /// defaults, 0 against 1, full pipeline, SI-SDRi (dB) / streams per talker / half-second
    /// blocks on another label: paper-linear6 seeds 1-48 +8.30 / 1.111 / 29 against +7.87 /
    /// 1.139 / 35, seeds 49-72 +8.38 / 1.208 / 19 against +7.99 / 1.222 / 23; recorded speech
    /// seeds 1-36 +6.07 / 1.083 / 10 against +6.43 / 1.093 / 12, seeds 37-52 +6.30 / 1.083 / 5
    /// against +6.70 / 1.083 / 4; uca8 seeds 1-18 +9.62 / 1.111 against +9.37 / 1.148,
    /// recorded seeds 1-12 +6.32 against +6.60. On an earlier landing 0.5 gave paper-linear6
    /// +8.05 / 28 and recorded +6.35 / 15 (against +7.89 / 33 and +6.47 / 17 then), and the
    /// lower threshold only for labels the tracker hears speaking (presence 0.5 or more) kept
    /// recorded speech's loss (+6.23) without the gain (+8.03 / 36).
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
            periodicity_voicing: true,
            periodicity_low: 0.2,
            periodicity_high: 0.4,
            periodicity_weight: 1.0,
            register_semitones: 4.0,
            register_memory_s: 5.0,
            register_confidence_s: 0.5,
            register_ownership: 1.0,
            track_semitones_per_s: 16.0,
            track_jump: 0.3,
            competitor_audibility_exponent: 2.0,
            activity_gate: true,
            activity_low: 0.015,
            activity_high: 0.12,
            activity_smoothing: 0.5,
            activity_low_band: true,
            activity_room_level: 0.25,
            activity_room_memory_s: 10.0,
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
