//! Whether a label is talking: the activity gate on its voicing (its share of the direct-path
//! power above 1 kHz) and the hold that keeps a voiced segment whole through the gate.

use super::{Harmonic, Pitch};

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
    /// Folds this frame's direct-power `share` of a label into its smoothed `activity` and
    /// returns the factor, in [0, 1], its estimated voicing is scaled by (1 with the gate off).
    pub fn activity_gate(&self, activity: &mut f64, share: f64) -> f64 {
        let Some((low, high)) = self.activity else {
            return 1.0;
        };
        if share.is_finite() {
            let a = self.activity_smoothing;
            *activity = a * *activity + (1.0 - a) * share.clamp(0.0, 1.0);
        }
        ((*activity - low) / (high - low)).clamp(0.0, 1.0)
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
        // A new label's gate is open on the presumption that it talks until its own share
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
