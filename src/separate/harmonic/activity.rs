//! Whether a label is talking: the activity gate on its voicing (the share of the bins above
//! 1 kHz its direct path dominates), the gate's calibration to the room, the hold that keeps a
//! voiced segment whole through the gate, and how audible a label is as another's competitor.

use super::{Harmonic, Pitch, power};

/// Histogram cells of [`RoomLevel`] over dominances 0..1.
const LEVEL_CELLS: usize = 100;

/// The quantile of the strongest label's smoothed dominance per frame that [`RoomLevel`]
/// reads: a talker holds the strongest label in most frames of a conversation, so the upper
/// quartile is a talker's level whether the room is quiet a third of the time or never.
const LEVEL_QUANTILE: f64 = 0.75;

/// Seconds of frames at the reference level that a new [`RoomLevel`] starts with, so the gate
/// keeps its configured thresholds until the room has been heard for a while.
pub(super) const LEVEL_PRIOR_S: f64 = 2.0;

/// Lowest scale of the gate's thresholds: the gate never opens on a quarter of its setting.
const MIN_ROOM_SCALE: f64 = 0.25;

/// How far talkers' direct paths dominate in one microphone group's room: a running upper
/// quartile of the strongest label's smoothed dominance per frame, forgetting with a time
/// constant (see `HarmonicConfig::activity_room_level`).
#[derive(Debug, Clone, PartialEq)]
pub struct RoomLevel {
    /// Weight of each dominance cell (exponentially forgotten).
    cells: Vec<f64>,
    /// Weight of all cells.
    total: f64,
    /// The gate's scale this level sets, as of its last observation (kept, not read from the
    /// cells, since every label reads it every frame).
    scale: f64,
}

impl RoomLevel {
    /// The dominance level of the room: the configured quantile of what was observed, with the
    /// prior at the reference level as part of it.
    pub fn level(&self) -> f64 {
        let target = LEVEL_QUANTILE * self.total;
        let mut acc = 0.0;
        for (c, w) in self.cells.iter().enumerate() {
            acc += w;
            if acc >= target && *w > 0.0 {
                // The cell's centre: a resolution of a hundredth of the dominance range.
                return (c as f64 + 0.5) / LEVEL_CELLS as f64;
            }
        }
        1.0
    }

    /// The scale of the gate's thresholds in this room: its level over the reference, between
    /// a quarter and 1 (1 without the room calibration), as of its last observation.
    pub fn scale(&self) -> f64 {
        self.scale
    }
}

/// The cell of [`RoomLevel`]'s histogram that holds dominance `d`.
fn level_cell(d: f64) -> usize {
    ((d.clamp(0.0, 1.0) * LEVEL_CELLS as f64) as usize).min(LEVEL_CELLS - 1)
}

/// A label's voiced segment as the activity hold follows it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Segment {
    /// Its F0 in the last frame (0: no segment).
    f0: f64,
    /// Consecutive frames it has been held with the gate closed.
    held: usize,
    /// Frames the label's gate has been read.
    seen: usize,
}

impl Harmonic {
    /// Folds this frame's direct-path `dominance` of a label (none: no measurement, the
    /// smoothed value holds) into its smoothed `activity` and returns the factor, in [0, 1],
    /// its estimated voicing is scaled by (1 with the gate off), with the gate's thresholds
    /// times `scale` (the room's, [`RoomLevel::scale`]).
    pub fn activity_gate(&self, activity: &mut f64, dominance: Option<f64>, scale: f64) -> f64 {
        if let Some(d) = dominance.filter(|d| d.is_finite())
            && self.activity.is_some()
        {
            let a = self.activity_smoothing;
            *activity = a * *activity + (1.0 - a) * d.clamp(0.0, 1.0);
        }
        self.gate_of(*activity, scale)
    }

    /// The gate a label's smoothed `activity` opens, in [0, 1] (1 with the gate off), with the
    /// thresholds times `scale`.
    pub fn gate_of(&self, activity: f64, scale: f64) -> f64 {
        let Some((low, high)) = self.activity else {
            return 1.0;
        };
        let s = if scale.is_finite() {
            scale.clamp(MIN_ROOM_SCALE, 1.0)
        } else {
            1.0
        };
        ((activity - low * s) / ((high - low) * s)).clamp(0.0, 1.0)
    }

    /// A new room level for one microphone group: only the prior at the reference level.
    pub fn room_level(&self) -> RoomLevel {
        let mut level = RoomLevel {
            cells: vec![0.0; LEVEL_CELLS],
            total: 0.0,
            scale: 1.0,
        };
        if let Some(reference) = self.room_reference {
            level.cells[level_cell(reference)] = self.room_prior;
            level.total = self.room_prior;
        }
        level
    }

    /// Folds this frame's `strongest` smoothed dominance among a group's labels into the
    /// group's `level` (nothing without the room calibration).
    pub fn observe_room(&self, level: &mut RoomLevel, strongest: f64) {
        let Some(reference) = self.room_reference else {
            return;
        };
        if !strongest.is_finite() {
            return;
        }
        let f = self.room_forgetting;
        level.cells.iter_mut().for_each(|w| *w *= f);
        level.cells[level_cell(strongest)] += 1.0;
        level.total = f * level.total + 1.0;
        level.scale = (level.level() / reference).clamp(MIN_ROOM_SCALE, 1.0);
    }

    /// How much a label counts as a competitor where another label reads its F0, in [0, 1],
    /// from its smoothed `activity` (its gate at the room's `scale`) and the voicing its comb
    /// read last frame (see `competitor_audibility_exponent`; 1 with the exponent 0).
    pub fn audibility(&self, activity: f64, comb_voicing: f64, scale: f64) -> f64 {
        let a = self.gate_of(activity, scale).max(comb_voicing);
        if a.is_finite() {
            power(a.clamp(0.0, 1.0), self.audibility_exponent)
        } else {
            1.0
        }
    }

    /// The gate that applies to this frame's estimated `pitch` given the activity gate's
    /// value `gate`, keeping the label's voiced `segment`. A voiced segment starts where the
    /// gate is open and is held open while the comb stays voiced (voicing at least 0.5) and
    /// its F0 moves by less than `activity_hold` per frame, for at most `activity_hold_max_s`
    /// with the gate closed: one glottal source's harmonics do not change owner in mid-vowel,
    /// and a vowel with little energy above 1 kHz, where the gate measures, closes the gate
    /// though its talker goes on. A silent label reading a neighbour's voice has no open start
    /// to hold, and the bound ends the hold of one that stopped while a neighbour holds a note.
    pub fn hold(&self, segment: &mut Segment, pitch: &Pitch, gate: f64) -> f64 {
        segment.seen = segment.seen.saturating_add(1);
        let voiced = pitch.voicing >= 0.5 && pitch.f0 > 0.0;
        if self.hold_log_step <= 0.0 || !voiced {
            *segment = Segment {
                seen: segment.seen,
                ..Segment::default()
            };
            return gate;
        }
        let continues = segment.f0 > 0.0
            && (pitch.f0 / segment.f0).ln().abs() < self.hold_log_step
            && segment.held < self.hold_max_frames;
        // A new label's gate is open on the presumption that it talks until its own dominance
        // has been measured; a segment starts only on a measured one.
        let opens = gate >= 0.5 && segment.seen > self.hold_start_frames;
        if gate >= 0.5 {
            segment.held = 0;
        } else if continues {
            segment.held += 1;
        }
        segment.f0 = if continues || opens { pitch.f0 } else { 0.0 };
        if continues { 1.0 } else { gate }
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{harmonic, harmonic_with};
    use crate::separate::config::HarmonicConfig;

    #[test]
    fn audibility_is_the_louder_of_gate_and_comb_to_its_exponent() {
        let h = harmonic();
        // Default gate ramp 0.015..0.12, exponent 2.
        assert_eq!(h.audibility(0.0, 0.0, 1.0), 0.0);
        assert!((h.audibility(0.0675, 0.0, 1.0) - 0.25).abs() < 1e-12);
        assert!((h.audibility(0.0, 0.5, 1.0) - 0.25).abs() < 1e-12);
        assert_eq!(h.audibility(1.0, 0.0, 1.0), 1.0);
        // A dark vowel that shuts its gate still counts through its comb.
        assert_eq!(h.audibility(0.0, 1.0, 1.0), 1.0);
        // Exponent 0 counts every competitor fully.
        let cfg = HarmonicConfig {
            competitor_audibility_exponent: 0.0,
            ..HarmonicConfig::default()
        };
        let off = harmonic_with(&cfg);
        assert_eq!(off.audibility(0.0, 0.0, 1.0), 1.0);
    }

    #[test]
    fn the_room_level_follows_the_strongest_labels_and_scales_the_gate() {
        let h = harmonic();
        // New: the prior at the reference (0.25) keeps the thresholds as set.
        let mut level = h.room_level();
        assert_eq!(level.scale(), 1.0);
        // A far, reverberant room: talkers dominate a tenth of the bins at best. After 10 s
        // (one memory) most of the weight is the room's.
        for i in 0..313 {
            h.observe_room(&mut level, if i % 4 == 0 { 0.0 } else { 0.1 });
        }
        let scale = level.scale();
        assert!((scale - 0.42).abs() < 0.03, "{scale}");
        // Its gate opens where a dry room's would stay half shut (ramp 0.015..0.12 as set).
        assert!(h.gate_of(0.06, scale) > 0.95);
        assert!((h.gate_of(0.06, 1.0) - 0.43).abs() < 0.01);
        // A silent label stays shut.
        assert_eq!(h.gate_of(0.005, scale), 0.0);
        // A dry room's level is above the reference: the thresholds never rise.
        for _ in 0..2000 {
            h.observe_room(&mut level, 0.5);
        }
        assert_eq!(level.scale(), 1.0);
        // A room where nobody ever dominates scales down to a quarter, not to nothing.
        for _ in 0..2000 {
            h.observe_room(&mut level, 0.0);
        }
        assert_eq!(level.scale(), 0.25);
        // Non-finite readings are ignored, and a non-finite scale keeps the thresholds.
        let before = level.clone();
        h.observe_room(&mut level, f64::NAN);
        assert_eq!(level, before);
        assert_eq!(h.gate_of(0.06, f64::NAN), h.gate_of(0.06, 1.0));
    }

    #[test]
    fn without_a_room_reference_the_thresholds_stay_as_set() {
        let cfg = HarmonicConfig {
            activity_room_level: 0.0,
            ..HarmonicConfig::default()
        };
        let h = harmonic_with(&cfg);
        let mut level = h.room_level();
        for _ in 0..1000 {
            h.observe_room(&mut level, 0.01);
        }
        assert_eq!(level.scale(), 1.0);
    }

    #[test]
    fn a_frame_without_a_measurement_keeps_the_gate_where_it_was() {
        let h = harmonic();
        // A new label starts as talking; silent frames close its gate (smoothing 0.5).
        let mut activity = 1.0;
        for _ in 0..8 {
            h.activity_gate(&mut activity, Some(0.0), 1.0);
        }
        let closed = h.activity_gate(&mut activity, Some(0.0), 1.0);
        assert_eq!(closed, 0.0);
        // Frames with no counted bin (nothing above 1 kHz) or a non-finite reading leave it.
        let before = activity;
        assert_eq!(h.activity_gate(&mut activity, None, 1.0), 0.0);
        assert_eq!(h.activity_gate(&mut activity, Some(f64::NAN), 1.0), 0.0);
        assert_eq!(activity, before);
        // A label dominating a fifth of the bins opens it within two frames.
        h.activity_gate(&mut activity, Some(0.2), 1.0);
        assert_eq!(h.activity_gate(&mut activity, Some(0.2), 1.0), 1.0);
    }
}
