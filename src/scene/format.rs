//! Wire types of scene format v1 (`scene.json`, the JSONL files, `truth.json`) and of the output
//! folder. These mirror ../shared/scene-format.md field for field; angles are in degrees here.
//!
//! Unknown fields are ignored (forward compatibility); missing required fields are errors.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::label::Label;

/// The `format` value this reader understands.
pub const SCENE_FORMAT: &str = "avsep-scene/1";

/// `scene.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SceneFile {
    /// Format and version tag; must be `"avsep-scene/1"`.
    pub format: String,
    /// Audio sample rate (Hz).
    pub sample_rate: u32,
    /// Speed of sound (m/s); 343 when absent.
    #[serde(default = "default_speed_of_sound")]
    pub speed_of_sound: f64,
    /// Multichannel WAV file, relative to the scene folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub audio: Option<String>,
    /// Microphone arrays.
    pub arrays: Vec<ArrayFile>,
    /// Cameras.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub cameras: Vec<CameraFile>,
    /// Where sources can be.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub region: Option<RegionFile>,
    /// Camera detections (JSONL), relative path.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub detections: Option<String>,
    /// Device-side audio localisation (JSONL), relative path.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub audio_measurements: Option<String>,
    /// Ground truth, relative path.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truth: Option<String>,
}

fn default_speed_of_sound() -> f64 {
    343.0
}

/// One microphone array in `scene.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ArrayFile {
    /// Array id.
    pub id: String,
    /// `channels[i]` is the audio column of `mics[i]`.
    #[serde(default)]
    pub channels: Vec<usize>,
    /// Microphone positions (m).
    pub mics: Vec<[f64; 3]>,
}

/// One camera in `scene.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct CameraFile {
    /// Camera id.
    pub id: String,
    /// Image width (px).
    pub width: f64,
    /// Image height (px).
    pub height: f64,
    /// 3x4 projection matrix, row by row. Required unless `rotation` and `translation` (with
    /// `intrinsics`) are given instead.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub projection: Option<[[f64; 4]; 3]>,
    /// 3x3 intrinsics K.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intrinsics: Option<[[f64; 3]; 3]>,
    /// OpenCV distortion `[k1, k2, p1, p2, k3]` (shorter lists mean trailing zeros).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distortion: Option<Vec<f64>>,
    /// World-to-camera rotation R (alternative to `projection`, with `translation`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation: Option<[[f64; 3]; 3]>,
    /// World-to-camera translation t (P = K [R | t]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translation: Option<[f64; 3]>,
}

/// `region` in `scene.json`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RegionFile {
    /// Lower corner (m).
    pub min: [f64; 3],
    /// Upper corner (m).
    pub max: [f64; 3],
}

/// One line of `detections.jsonl`: one camera frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct DetectionLine {
    /// Frame time (s).
    pub t: f64,
    /// Camera id.
    pub camera: String,
    /// Detected faces; empty when the camera looked and saw nobody.
    pub boxes: Vec<BoxFile>,
}

/// A detected face box.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct BoxFile {
    /// Left edge (px).
    pub x: f64,
    /// Top edge (px).
    pub y: f64,
    /// Width (px).
    pub w: f64,
    /// Height (px).
    pub h: f64,
    /// Detector confidence in [0, 1].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub score: Option<f64>,
    /// Measurement point (e.g. the mouth) when not the box centre.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point: Option<[f64; 2]>,
}

/// One line of `audio_measurements.jsonl` or `measurements.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct AudioMeasurementLine {
    /// Frame time (s).
    pub t: f64,
    /// Array id.
    pub array: String,
    /// Directions of arrival around the array centroid.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub doas: Vec<DoaFile>,
    /// 3-D position candidates (m, world frame).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub points: Vec<[f64; 3]>,
    /// Voice-activity score of the frame in [0, 1] (written by avsep, optional on input).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub activity: Option<f64>,
}

/// A direction of arrival (degrees).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct DoaFile {
    /// Azimuth (deg) in the x-y plane from +x towards +y.
    pub azimuth: f64,
    /// Elevation (deg) from the x-y plane towards +z; absent for azimuth-only arrays.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elevation: Option<f64>,
    /// Relative strength.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub energy: Option<f64>,
}

/// `truth/truth.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TruthFile {
    /// The true sources.
    pub sources: Vec<TruthSourceFile>,
}

/// One true source.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TruthSourceFile {
    /// Source id.
    pub id: String,
    /// Its image at the reference microphone (mono WAV), relative path.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub signal: Option<String>,
    /// `[t, x, y, z]` samples of the mouth position.
    pub trajectory: Vec<[f64; 4]>,
    /// `[t_start, t_end]` speech intervals.
    #[serde(default)]
    pub active: Vec<[f64; 2]>,
}

/// One line of `tracks.jsonl`: the tracker's estimate at time `t`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TracksLine {
    /// Time the estimate refers to (s).
    pub t: f64,
    /// The tracks that exist at `t`.
    pub tracks: Vec<TrackFile>,
}

/// One line of `pitch.jsonl`: each label's pitch as the separator's harmonic grouping read it
/// in the STFT frame centred at `t` (an avsep extension of the output folder, written by
/// `avsep process` so `avsep eval` can score the grouping on its own).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PitchLine {
    /// Centre of the frame (s).
    pub t: f64,
    /// The labels the separator had a stream for in that frame.
    pub labels: Vec<LabelPitch>,
}

/// One label's pitch in `pitch.jsonl`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct LabelPitch {
    /// The track.
    pub label: Label,
    /// F0 (Hz); 0 when the label read none.
    pub f0: f64,
    /// Voicing in [0, 1], with the activity gate folded in: how far the grouping treats the
    /// label as a voice at `f0`.
    pub voicing: f64,
}

/// One estimated track in `tracks.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TrackFile {
    /// Identity, never reused.
    pub label: Label,
    /// Position (m).
    pub position: [f64; 3],
    /// Velocity (m/s).
    #[serde(default)]
    pub velocity: [f64; 3],
    /// Existence probability.
    #[serde(default = "one")]
    pub existence: f64,
    /// Probability that the track is speaking now.
    #[serde(default)]
    pub speaking: f64,
    /// Position covariance (m^2), row by row.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance: Option<[[f64; 3]; 3]>,
}

fn one() -> f64 {
    1.0
}
