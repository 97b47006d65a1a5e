//! Bodies of the REST API under `/v1`. Geometry follows the scene format (`scene.json`): metres,
//! camera matrices row by row; pipeline settings are those of `avsep config --defaults`.
//!
//! The OpenAPI document refers to the JSON Schemas of the scene format and of the pipeline
//! settings (files under `api/`) for the fields typed by them, so neither is written twice.

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;
use utoipa::openapi::schema::{ArrayBuilder, ObjectBuilder, Schema, Type};
use utoipa::openapi::{Ref, RefOr};

use crate::label::Label;
use crate::pipeline::{PipelineConfig, SensorClutter};
use crate::scene::format::{ArrayFile, CameraFile, RegionFile, TrackFile};

use super::ErrorBody;

/// JSON Schema file of the pipeline settings, next to `openapi.yaml`.
pub const PIPELINE_CONFIG_SCHEMA: &str = "pipeline-config.schema.json";

fn scene_def(name: &str) -> Ref {
    Ref::new(format!("scene.schema.json#/$defs/{name}"))
}

fn arrays_schema() -> RefOr<Schema> {
    ArrayBuilder::new()
        .items(scene_def("ArrayFile"))
        .build()
        .into()
}

fn cameras_schema() -> RefOr<Schema> {
    ArrayBuilder::new()
        .items(scene_def("CameraFile"))
        .build()
        .into()
}

fn region_schema() -> RefOr<Schema> {
    RefOr::Ref(scene_def("RegionFile"))
}

fn settings_schema() -> RefOr<Schema> {
    RefOr::Ref(Ref::new(PIPELINE_CONFIG_SCHEMA))
}

fn tracks_schema() -> RefOr<Schema> {
    ArrayBuilder::new()
        .items(Ref::new("tracks-line.schema.json#/$defs/TrackFile"))
        .build()
        .into()
}

fn labels_schema() -> RefOr<Schema> {
    let label = ObjectBuilder::new()
        .schema_type(Type::String)
        .pattern(Some(r"^\d+\.\d+$"))
        .description(Some("Track label \"<birth step>.<index>\""));
    ArrayBuilder::new().items(label).build().into()
}

fn default_speed_of_sound() -> f64 {
    343.0
}

/// Body of `POST /v1/sessions`: the room's sensors with their calibration, and settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CreateSession {
    /// Free-form name, for listings and logs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Audio sample rate (Hz).
    pub sample_rate: u32,
    /// Speed of sound (m/s); 343 when absent.
    #[serde(default = "default_speed_of_sound")]
    pub speed_of_sound: f64,
    /// Microphone arrays, as in `scene.json`; `channels[i]` is the audio column of `mics[i]`.
    #[schema(schema_with = arrays_schema)]
    pub arrays: Vec<ArrayFile>,
    /// Cameras, as in `scene.json`.
    #[serde(default)]
    #[schema(schema_with = cameras_schema)]
    pub cameras: Vec<CameraFile>,
    /// Where sources can be.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(schema_with = region_schema)]
    pub region: Option<RegionFile>,
    /// Pipeline settings; absent fields keep their defaults (`avsep config --defaults`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(schema_with = settings_schema)]
    pub settings: Option<PipelineConfig>,
}

/// Life of a session.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, JsonSchema, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum SessionState {
    /// Accepting input.
    Running,
    /// Input has ended; the pipeline is processing what it holds.
    Finishing,
    /// Everything was processed and the streams are closed.
    Finished,
    /// The pipeline failed; the session accepts nothing more (see `error`).
    Failed,
}

impl SessionState {
    /// The name used in JSON and metrics labels.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Running => "running",
            Self::Finishing => "finishing",
            Self::Finished => "finished",
            Self::Failed => "failed",
        }
    }
}

/// Answer of `POST /v1/sessions`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, ToSchema)]
pub struct SessionCreated {
    /// Session id.
    pub id: String,
    /// Bearer token of the session's endpoints and streams; shown only here.
    pub token: String,
    /// Path of the session's WebSocket stream.
    pub stream: String,
    /// The session as created.
    pub session: SessionInfo,
}

/// One session in a listing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, ToSchema)]
pub struct SessionSummary {
    /// Session id.
    pub id: String,
    /// Name given at creation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Life state.
    pub state: SessionState,
    /// Creation time (Unix seconds).
    pub created_unix_s: f64,
    /// Connected stream clients.
    pub clients: usize,
    /// Index of the next audio sample frame the session expects.
    pub next_sample: u64,
}

/// Answer of `GET /v1/sessions`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, ToSchema)]
pub struct SessionList {
    /// Every session the server holds, oldest first.
    pub sessions: Vec<SessionSummary>,
}

/// Answer of `GET /v1/sessions/{id}`: the session with its current calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, ToSchema)]
pub struct SessionInfo {
    /// Session id.
    pub id: String,
    /// Name given at creation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Life state.
    pub state: SessionState,
    /// Why the session failed, when it did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorBody>,
    /// Creation time (Unix seconds).
    pub created_unix_s: f64,
    /// Audio sample rate (Hz).
    pub sample_rate: u32,
    /// Speed of sound (m/s).
    pub speed_of_sound: f64,
    /// Channels an audio frame carries.
    pub channels: usize,
    /// Arrays with their current calibration.
    #[schema(schema_with = arrays_schema)]
    pub arrays: Vec<ArrayFile>,
    /// Cameras with their current calibration (as projection matrices).
    #[schema(schema_with = cameras_schema)]
    pub cameras: Vec<CameraFile>,
    /// Where sources can be.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(schema_with = region_schema)]
    pub region: Option<RegionFile>,
    /// Tracker step period (s).
    pub step_s: f64,
    /// Index of the next audio sample frame the session expects.
    pub next_sample: u64,
    /// Connected stream clients.
    pub clients: usize,
    /// Memory the session's pipeline and the server's buffers around it may take at most
    /// (bytes), from its layout and settings with every stream its cap allows: what the
    /// server's memory budget counts for it.
    pub memory_bound_bytes: u64,
    /// Labels of the tracks that exist now.
    #[schema(schema_with = labels_schema)]
    pub live_labels: Vec<Label>,
}

/// Body of `PUT /v1/sessions/{id}/arrays/{array}`: new microphone positions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ArrayCalibration {
    /// Microphone positions (m), as many as the array has.
    pub mics: Vec<[f64; 3]>,
    /// Audio columns of the microphones; unchanged when absent (they cannot change live).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub channels: Option<Vec<usize>>,
}

/// Body of `PUT /v1/sessions/{id}/cameras/{camera}`: a new calibration, either a 3x4 projection
/// matrix or intrinsics K with rotation R and translation t (P = K [R | t]), and distortion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CameraCalibration {
    /// Image width (px); unchanged when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub width: Option<f64>,
    /// Image height (px); unchanged when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height: Option<f64>,
    /// 3x4 projection matrix, row by row.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub projection: Option<[[f64; 4]; 3]>,
    /// 3x3 intrinsics K, row by row.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intrinsics: Option<[[f64; 3]; 3]>,
    /// OpenCV distortion `[k1, k2, p1, p2, k3]` (shorter lists mean trailing zeros).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distortion: Option<Vec<f64>>,
    /// World-to-camera rotation R, row by row.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation: Option<[[f64; 3]; 3]>,
    /// World-to-camera translation t (m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translation: Option<[f64; 3]>,
}

impl CameraCalibration {
    /// The scene-format camera this calibration describes, keeping `current`'s id and the image
    /// size it does not give.
    pub fn to_file(&self, current: &CameraFile) -> CameraFile {
        CameraFile {
            id: current.id.clone(),
            width: self.width.unwrap_or(current.width),
            height: self.height.unwrap_or(current.height),
            projection: self.projection,
            intrinsics: self.intrinsics,
            distortion: self.distortion.clone(),
            rotation: self.rotation,
            translation: self.translation,
        }
    }
}

/// The tracker's estimate after one step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, ToSchema)]
pub struct TracksSnapshot {
    /// Tracker step index.
    pub step: u64,
    /// Time the estimate refers to (s).
    pub t: f64,
    /// Tracks that exist at `t`.
    #[schema(schema_with = tracks_schema)]
    pub tracks: Vec<TrackFile>,
}

/// Answer of `GET /v1/sessions/{id}/tracks/history`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, ToSchema)]
pub struct TrackHistory {
    /// Oldest step the session still holds (the history is a bounded ring).
    pub oldest_step: Option<u64>,
    /// Estimates in step order.
    pub steps: Vec<TracksSnapshot>,
}

/// Percentiles of a latency (ms) over a window of recent steps.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, JsonSchema, ToSchema)]
pub struct LatencySummary {
    /// Steps in the window.
    pub count: usize,
    /// Median (ms).
    pub p50: f64,
    /// 95th percentile (ms).
    pub p95: f64,
    /// 99th percentile (ms).
    pub p99: f64,
    /// Largest (ms).
    pub max: f64,
}

/// Inbound messages accepted, by kind.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, JsonSchema, ToSchema)]
pub struct FrameCounts {
    /// Binary audio frames.
    pub audio: u64,
    /// Camera detection frames.
    pub detections: u64,
    /// Device measurement frames.
    pub audio_measurements: u64,
}

/// Answer of `GET /v1/sessions/{id}/metrics`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, ToSchema)]
pub struct SessionMetrics {
    /// Life state.
    pub state: SessionState,
    /// Messages accepted into the session's queue.
    pub frames_in: FrameCounts,
    /// Messages refused, by error code (`queue_full`, `late`, `bad_channels`, ...).
    pub refused: BTreeMap<String, u64>,
    /// Output messages a slow client missed (its stream skipped ahead), summed over clients.
    pub output_dropped: u64,
    /// Tracker steps run.
    pub steps: u64,
    /// From the arrival of the message that completed a step to the broadcast of its tracks.
    pub step_latency_ms: LatencySummary,
    /// Processing time of the pipeline alone per step.
    pub step_processing_ms: LatencySummary,
    /// Pipeline processing time over the audio time processed (below 1 keeps up).
    pub real_time_factor: f64,
    /// Audio processed (s).
    pub audio_s: f64,
    /// Tracks that exist now.
    pub live_tracks: usize,
    /// Labels ever reported.
    pub labels_total: u64,
    /// Messages waiting in the queue.
    pub queue_depth: usize,
    /// Queue capacity.
    pub queue_capacity: usize,
    /// Bytes the waiting messages hold, decoded.
    pub queue_bytes: usize,
    /// Bytes the queue may hold (`limits.queue_bytes`).
    pub queue_bytes_capacity: usize,
    /// Steps of separation work waiting for the session's separation thread (which runs at a
    /// lower priority than the tracker, so it may lag under load without delaying the tracks).
    pub separation_queue_depth: usize,
    /// Capacity of the separation queue (`execution.separation_queue`; 0 when the session
    /// separates on its worker thread).
    pub separation_queue_capacity: usize,
    /// Steps whose pipeline waited because the separation queue was full (the input queue,
    /// then `queue_full`, takes the strain).
    pub separation_waits: u64,
    /// Connected stream clients.
    pub clients: usize,
    /// Each tracker sensor's clutter rate (false measurements per scan), configured and as the
    /// tracker estimates it now: an estimate far above the configured rate is a detector or
    /// localiser reporting more false detections than it was tuned for.
    pub clutter: Vec<SensorClutter>,
}

/// `{"error": {...}}`, the body of every error answer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, ToSchema)]
pub struct ErrorResponse {
    /// What went wrong.
    pub error: ErrorBody,
}

/// Answer of `/healthz` and `/readyz`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, ToSchema)]
pub struct Health {
    /// `ok`, `ready`, `draining` or `full`.
    pub status: String,
    /// Sessions held.
    pub sessions: usize,
}
