//! Settings of one session's pipeline, with the stages' own settings nested.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::speaking::SpeakingConfig;
use crate::localize::LocalizerConfig;
use crate::separate::SeparatorConfig;
use crate::track::TrackerConfig;

/// Where the tracker's audio measurements come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum AudioMeasurementSource {
    /// Device measurements when the session receives them, else the built-in localiser.
    #[default]
    Auto,
    /// Only the built-in SRP-PHAT localiser.
    Localize,
    /// Only measurements sent by devices that localise themselves.
    Device,
    /// Both, as separate sensors.
    Both,
}

impl AudioMeasurementSource {
    /// Whether the built-in localiser runs.
    pub fn uses_localizer(self) -> bool {
        !matches!(self, Self::Device)
    }
}

/// Which of the localiser's candidates feed the tracker, per array.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum LocalizedMeasurements {
    /// Directions for every array (a linear array's as the cone angle to its axis). A compact
    /// array resolves direction, not range, and a linear one not even the roll about its axis:
    /// the seed paper's 3-D candidates carry no more than the direction, and their range and
    /// roll are the search's prior, which a tracker would take for measurements (on the
    /// paper's room they pulled tracks 0.3-1 m off in depth). Positions only for arrays
    /// without directions (a single microphone).
    #[default]
    Auto,
    /// 3-D position candidates from stochastic region contraction.
    Positions,
    /// Directions of arrival from the geodesic-sphere search.
    Directions,
}

/// Pipeline settings. Every field has a default; unknown fields are errors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct PipelineConfig {
    /// Tracker step period in seconds (the paper's 0.128 s by default; 0.032 to 1.0).
    pub step_s: f64,
    /// How long (seconds of audio) a step waits for cameras that have not yet sent a frame at or
    /// after the step's end; after that the step runs and such cameras count as absent. The
    /// audio history holds the wait's audio too, so it counts in the session's memory bound.
    pub camera_wait_s: f64,
    /// Seed of the session's random numbers; derived from the session id (or scene) when absent.
    pub seed: Option<u64>,
    /// Where audio measurements come from.
    pub audio_measurements: AudioMeasurementSource,
    /// Which localiser candidates (positions or directions) the tracker uses.
    pub localized_measurements: LocalizedMeasurements,
    /// The tracker takes only localiser candidates whose own frame's SRP (`fresh`, in null
    /// standard deviations) reaches this; 0 takes every candidate. The localiser's smoothed maps
    /// remember a talker for a second or more after he stops, at the place he stopped, so a
    /// walker who falls silent is pulled back to where he last spoke and kept there, and a
    /// reflection heard once lives on as a track. Full pipeline (`avsep process D --out O`,
    /// `avsep eval D O`), 0 against 8: 3-D MOTA / false-positive steps / SI-SDR improvement /
    /// streams per talker, on the seeds the value was chosen on: recorded-speech `uca8` 3
    /// talkers seeds 1-12 88.4 -> 92.7 % / 405 -> 205 / +6.34 -> +6.63 dB / 1.222 -> 1.139;
    /// `uca8` seeds 1-18 91.6 -> 93.5 % / 405 -> 272 / +9.10 -> +9.30 dB / 1.167 -> 1.130;
    /// `paper-linear6` seeds 1-24 94.5 -> 98.1 % / 191 -> 16 / +8.03 -> +8.02 dB / 1.125 ->
    /// 1.139; recorded `paper-linear6` seeds 1-24 94.7 -> 98.3 % / 185 -> 3 / +6.41 -> +6.44 dB
    /// / 1.125 -> 1.139. 2 / 3.5 / 5 / 12 / 16 gave less or mixed (16 loses 0.17 dB on `uca8`).
    /// On the seeds not used to choose it: `paper-linear6` 25-72 95.6 -> 98.1 % / 279 -> 26 /
    /// +7.87 -> +7.90 dB / 1.188 -> 1.188, recorded 25-52 93.3 -> 97.6 % / 294 -> 40 / +6.63 ->
    /// +6.67 dB / 1.083 -> 1.095, `uca8` 19-30 96.5 -> 96.3 % / 90 -> 94 / +9.83 -> +9.86 dB /
    /// 1.083 -> 1.083, recorded `uca8` 13-20 95.0 % either way.
    pub localized_min_fresh_sigmas: f64,
    /// Whether camera detections are used by the tracker.
    pub cameras: bool,
    /// Boxes with a detector score below this are ignored.
    pub min_box_score: f64,
    /// Longest gap in the audio (seconds) that is bridged with silence; a longer jump is refused.
    pub max_gap_s: f64,
    /// How far (seconds) a camera or device frame's time may run ahead of the session's present
    /// (the audio received so far, or in a session without audio its sensors' newest time);
    /// a frame further ahead is refused with `too_early`, so a wrong clock can neither make the
    /// session hold frames without bound nor step through hours of empty time. What the frames
    /// ahead may hold together is the server's limit (`limits.sensor_backlog_bytes`).
    pub max_lead_s: f64,
    /// Whether separated audio is produced.
    pub separation: bool,
    /// Settings of the SRP-PHAT localiser.
    pub localize: LocalizerConfig,
    /// Settings of the tracker.
    pub track: TrackerConfig,
    /// Settings of the separator.
    pub separate: SeparatorConfig,
    /// How each track's `speaking` follows the localiser's probe at the track.
    pub speaking: SpeakingConfig,
}

impl Default for PipelineConfig {
    fn default() -> Self {
        Self {
            step_s: 0.128,
            camera_wait_s: 0.15,
            seed: None,
            audio_measurements: AudioMeasurementSource::Auto,
            localized_measurements: LocalizedMeasurements::Auto,
            localized_min_fresh_sigmas: 8.0,
            cameras: true,
            min_box_score: 0.0,
            max_gap_s: 2.0,
            max_lead_s: 10.0,
            separation: true,
            localize: LocalizerConfig::default(),
            track: TrackerConfig::default(),
            separate: SeparatorConfig::default(),
            speaking: SpeakingConfig::default(),
        }
    }
}

pub use crate::field_error::FieldError as ConfigError;

impl PipelineConfig {
    /// Checks the pipeline's own fields (the stages check theirs when built).
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(0.032..=1.0).contains(&self.step_s) {
            return Err(ConfigError::new(
                "step_s",
                format!("{} is outside 0.032..=1.0 s", self.step_s),
            ));
        }
        if !(0.0..=2.0).contains(&self.camera_wait_s) {
            return Err(ConfigError::new(
                "camera_wait_s",
                format!("{} is outside 0..=2 s", self.camera_wait_s),
            ));
        }
        if !(self.localized_min_fresh_sigmas >= 0.0 && self.localized_min_fresh_sigmas <= 1e3) {
            return Err(ConfigError::new(
                "localized_min_fresh_sigmas",
                "must be in [0, 1000]",
            ));
        }
        if !(0.0..=1.0).contains(&self.min_box_score) {
            return Err(ConfigError::new("min_box_score", "must be in [0, 1]"));
        }
        if !(0.0..=60.0).contains(&self.max_gap_s) {
            return Err(ConfigError::new("max_gap_s", "must be in 0..=60 s"));
        }
        if !(0.1..=3600.0).contains(&self.max_lead_s) {
            return Err(ConfigError::new("max_lead_s", "must be in 0.1..=3600 s"));
        }
        self.speaking.validate().map_err(|e| e.within("speaking"))
    }

    /// Parses a JSON or TOML configuration (TOML unless the text starts with `{`), filling absent
    /// fields with defaults and naming unknown or mistyped fields in the error.
    pub fn parse(text: &str) -> Result<Self, ConfigError> {
        let cfg: Self = crate::field_error::parse_document(text)?;
        cfg.validate()?;
        Ok(cfg)
    }
}
