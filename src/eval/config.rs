//! Settings of the evaluation, with the defaults of the seed paper where it gives them.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::EvalError;

/// Which time span a measurement line's `t` stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum FrameAnchor {
    /// `t` is the frame's first sample: the frame covers `[t, t + frame)`.
    Start,
    /// `t` is the frame's centre: the frame covers `[t - frame/2, t + frame/2)`.
    Centre,
}

/// Evaluation settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct EvalConfig {
    /// OSPA, OSPA(2) and GOSPA cut-off c in metres (the paper: 1 m).
    pub ospa_cutoff_m: f64,
    /// OSPA, OSPA(2) and GOSPA order p (the paper: 1, so the parts add up to the total).
    pub ospa_order: f64,
    /// OSPA(2) sliding window in tracker steps (the paper: 10).
    pub ospa2_window_steps: usize,
    /// CLEAR MOT / IDF1 distance gate in metres: a track farther than this from a true source
    /// does not match it. HOTA's similarity falls linearly from 1 to 0 at this distance.
    pub gate_m: f64,
    /// Gate in degrees of azimuth for the direction-space tracking figures (seen from the first
    /// array's centroid), and the angle where their HOTA similarity reaches 0.
    pub azimuth_gate_deg: f64,
    /// A direction candidate within this many degrees of a true source's azimuth counts as a hit.
    pub doa_tolerance_deg: f64,
    /// Measurement frame length in seconds; `null` infers it from the spacing of an array's
    /// measurement lines (their median), falling back to 0.128 s for a single line.
    pub measurement_frame_s: Option<f64>,
    /// Which span of time a measurement line's `t` refers to.
    pub measurement_anchor: FrameAnchor,
    /// A source is active in a measurement frame when it speaks during at least this fraction of
    /// the frame.
    pub active_fraction: f64,
    /// The "audible" figures keep the true sources that are present and spoke within this many
    /// seconds before the step (audio-only runs cannot see a silent source).
    pub audible_hold_s: f64,
    /// Taps of the BSS Eval v3 time-invariant distortion filter (mir_eval: 512).
    pub bss_filter_taps: usize,
    /// A label counts towards a source's stream continuity when it carries at least this share of
    /// the source's active time.
    pub continuity_share: f64,
    /// Block length in seconds for the energy-based stream continuity.
    pub continuity_block_s: f64,
    /// In a continuity block, the best stream must correlate with the source's signal at least
    /// this much (normalised correlation, 0..1) to count as carrying it.
    pub continuity_min_correlation: f64,
    /// Window (s) of the YIN analysis that reads each true source's pitch for scoring
    /// `pitch.jsonl` (the separator's default frame: 1024 samples at 16 kHz).
    pub pitch_frame_s: f64,
    /// Lowest F0 (Hz) YIN considers (the separator's default range).
    pub pitch_f0_min_hz: f64,
    /// Highest F0 (Hz) YIN considers.
    pub pitch_f0_max_hz: f64,
    /// Voicing (YIN's for the truth, the separator's for a label) at or above which a frame
    /// counts as voiced.
    pub pitch_voiced: f64,
    /// Relative F0 deviation within which a label's F0 counts as right: the harmonic grouping
    /// needs a few per cent (at 1 kHz, 3 % of a 150 Hz voice moves its 7th harmonic by two
    /// bins of a 1024-sample frame).
    pub pitch_tolerance: f64,
}

impl Default for EvalConfig {
    fn default() -> Self {
        Self {
            ospa_cutoff_m: 1.0,
            ospa_order: 1.0,
            ospa2_window_steps: 10,
            gate_m: 0.5,
            azimuth_gate_deg: 10.0,
            doa_tolerance_deg: 5.0,
            measurement_frame_s: None,
            measurement_anchor: FrameAnchor::Start,
            active_fraction: 0.5,
            audible_hold_s: 2.0,
            bss_filter_taps: 512,
            continuity_share: 0.1,
            continuity_block_s: 0.5,
            continuity_min_correlation: 0.3,
            pitch_frame_s: 0.064,
            pitch_f0_min_hz: 70.0,
            pitch_f0_max_hz: 400.0,
            pitch_voiced: 0.5,
            pitch_tolerance: 0.03,
        }
    }
}

impl EvalConfig {
    /// Checks every field, naming the first bad one.
    pub fn validate(&self) -> Result<(), EvalError> {
        let bad = |field: &str, message: &str| {
            Err(EvalError::Config {
                field: field.to_string(),
                message: message.to_string(),
            })
        };
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(self.ospa_cutoff_m) {
            return bad("ospa_cutoff_m", "must be a positive number of metres");
        }
        if !(self.ospa_order.is_finite() && self.ospa_order >= 1.0) {
            return bad("ospa_order", "must be at least 1");
        }
        if self.ospa2_window_steps == 0 {
            return bad("ospa2_window_steps", "must be at least 1 step");
        }
        if !positive(self.gate_m) {
            return bad("gate_m", "must be a positive number of metres");
        }
        if !(positive(self.azimuth_gate_deg) && self.azimuth_gate_deg <= 180.0) {
            return bad("azimuth_gate_deg", "must be in (0, 180] degrees");
        }
        if !(positive(self.doa_tolerance_deg) && self.doa_tolerance_deg <= 180.0) {
            return bad("doa_tolerance_deg", "must be in (0, 180] degrees");
        }
        if let Some(f) = self.measurement_frame_s
            && !positive(f)
        {
            return bad(
                "measurement_frame_s",
                "must be a positive number of seconds",
            );
        }
        if !(self.active_fraction > 0.0 && self.active_fraction <= 1.0) {
            return bad("active_fraction", "must be in (0, 1]");
        }
        if !(self.audible_hold_s.is_finite() && self.audible_hold_s >= 0.0) {
            return bad("audible_hold_s", "must be a number of seconds >= 0");
        }
        if !(1..=8192).contains(&self.bss_filter_taps) {
            return bad("bss_filter_taps", "must be between 1 and 8192");
        }
        if !(self.continuity_share > 0.0 && self.continuity_share <= 1.0) {
            return bad("continuity_share", "must be in (0, 1]");
        }
        if !positive(self.continuity_block_s) {
            return bad("continuity_block_s", "must be a positive number of seconds");
        }
        if !(0.0..=1.0).contains(&self.continuity_min_correlation) {
            return bad("continuity_min_correlation", "must be in [0, 1]");
        }
        if !positive(self.pitch_frame_s) {
            return bad("pitch_frame_s", "must be a positive number of seconds");
        }
        if !positive(self.pitch_f0_min_hz) {
            return bad("pitch_f0_min_hz", "must be a positive frequency");
        }
        if !(self.pitch_f0_max_hz.is_finite() && self.pitch_f0_max_hz > self.pitch_f0_min_hz) {
            return bad(
                "pitch_f0_max_hz",
                "must be finite and above pitch_f0_min_hz",
            );
        }
        if !(self.pitch_voiced > 0.0 && self.pitch_voiced <= 1.0) {
            return bad("pitch_voiced", "must be in (0, 1]");
        }
        if !positive(self.pitch_tolerance) {
            return bad("pitch_tolerance", "must be a positive fraction");
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_bad_fields_are_named() {
        EvalConfig::default().validate().unwrap();
        let c = EvalConfig {
            gate_m: -1.0,
            ..Default::default()
        };
        match c.validate() {
            Err(EvalError::Config { field, .. }) => assert_eq!(field, "gate_m"),
            other => panic!("{other:?}"),
        }
        let e = serde_json::from_str::<EvalConfig>(r#"{"gate": 1}"#).unwrap_err();
        assert!(e.to_string().contains("gate"), "{e}");
        let c: EvalConfig = serde_json::from_str(r#"{"gate_m": 0.3}"#).unwrap();
        assert_eq!((c.gate_m, c.ospa_cutoff_m), (0.3, 1.0));
    }
}
