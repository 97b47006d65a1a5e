//! Whether a label is talking: the activity gate on its voicing (the share of the bins above
//! 1 kHz its direct path dominates), the hold that keeps a voiced segment whole through the
//! gate, and how audible a label is as another's competitor.

use super::{Harmonic, Pitch, power};

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
    /// its estimated voicing is scaled by (1 with the gate off).
    pub fn activity_gate(&self, activity: &mut f64, dominance: Option<f64>) -> f64 {
        if let Some(d) = dominance.filter(|d| d.is_finite())
            && self.activity.is_some()
        {
            let a = self.activity_smoothing;
            *activity = a * *activity + (1.0 - a) * d.clamp(0.0, 1.0);
        }
        self.gate_of(*activity)
    }

    /// The gate a label's smoothed `activity` opens, in [0, 1] (1 with the gate off).
    pub fn gate_of(&self, activity: f64) -> f64 {
        let Some((low, high)) = self.activity else {
            return 1.0;
        };
        ((activity - low) / (high - low)).clamp(0.0, 1.0)
    }

    /// How much a label counts as a competitor where another label reads its F0, in [0, 1],
    /// from its smoothed `activity` and the voicing its comb read last frame (see
    /// `competitor_audibility_exponent`; 1 with the exponent 0).
    pub fn audibility(&self, activity: f64, comb_voicing: f64) -> f64 {
        let a = self.gate_of(activity).max(comb_voicing);
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
    use super::super::tests::{FS, N, harmonic};
    use super::*;
    use crate::separate::config::HarmonicConfig;

    #[test]
    fn audibility_is_the_louder_of_gate_and_comb_to_its_exponent() {
        let h = harmonic();
        // Default gate ramp 0.015..0.12, exponent 2.
        assert_eq!(h.audibility(0.0, 0.0), 0.0);
        assert!((h.audibility(0.0675, 0.0) - 0.25).abs() < 1e-12);
        assert!((h.audibility(0.0, 0.5) - 0.25).abs() < 1e-12);
        assert_eq!(h.audibility(1.0, 0.0), 1.0);
        // A dark vowel that shuts its gate still counts through its comb.
        assert_eq!(h.audibility(0.0, 1.0), 1.0);
        // Exponent 0 counts every competitor fully.
        let cfg = HarmonicConfig {
            competitor_audibility_exponent: 0.0,
            ..HarmonicConfig::default()
        };
        let off = Harmonic::new(&cfg, FS / N as f64, FS / (N / 2) as f64);
        assert_eq!(off.audibility(0.0, 0.0), 1.0);
    }

    #[test]
    fn a_frame_without_a_measurement_keeps_the_gate_where_it_was() {
        let h = harmonic();
        // A new label starts as talking; silent frames close its gate (smoothing 0.5).
        let mut activity = 1.0;
        for _ in 0..8 {
            h.activity_gate(&mut activity, Some(0.0));
        }
        let closed = h.activity_gate(&mut activity, Some(0.0));
        assert_eq!(closed, 0.0);
        // Frames with no counted bin (nothing above 1 kHz) or a non-finite reading leave it.
        let before = activity;
        assert_eq!(h.activity_gate(&mut activity, None), 0.0);
        assert_eq!(h.activity_gate(&mut activity, Some(f64::NAN)), 0.0);
        assert_eq!(activity, before);
        // A label dominating a fifth of the bins opens it within two frames.
        h.activity_gate(&mut activity, Some(0.2));
        assert_eq!(h.activity_gate(&mut activity, Some(0.2)), 1.0);
    }
}
