//! Settings of `avsep serve`: where to listen, who may do what, and every limit that bounds a
//! session's memory and work. Read from a TOML or JSON file; environment variables and flags
//! override single fields (see `cli/serve.rs`).

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::geometry::{GeometryError, Layout};
use crate::pipeline::{ConfigError, PipelineConfig, SizeBounds};

use super::zenoh_transport::ZenohConfig;

/// Server settings. Every field has a default; unknown fields are errors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct ServerConfig {
    /// Address and port to listen on. The default listens on this machine only.
    pub bind: String,
    /// Key that guards creating, listing and deleting sessions and opens every session's
    /// endpoints (`Authorization: Bearer <key>`). When absent anyone who can reach the server may
    /// create and list sessions, and each session is guarded by its own token only.
    pub admin_key: Option<String>,
    /// Origins allowed to call the API from a browser (`["*"]` for any); none when empty.
    pub cors_origins: Vec<String>,
    /// Seconds the server waits at shutdown for sessions to finish their pipelines.
    pub drain_timeout_s: f64,
    /// Limits that bound memory and work.
    pub limits: Limits,
    /// How a session's work is spread over threads.
    pub execution: Execution,
    /// How the server joins Zenoh (sessions stream over Zenoh as well as WebSocket).
    pub zenoh: ZenohConfig,
}

impl Default for ServerConfig {
    fn default() -> Self {
        Self {
            bind: "127.0.0.1:8080".into(),
            admin_key: None,
            cors_origins: Vec::new(),
            drain_timeout_s: 10.0,
            limits: Limits::default(),
            execution: Execution::default(),
            zenoh: ZenohConfig::default(),
        }
    }
}

/// Explicit bounds on sessions, clients, messages and queues.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct Limits {
    /// Sessions the server holds at once (running or finished but not yet deleted); what
    /// they may take together is bounded by `max_memory_mb`.
    pub max_sessions: usize,
    /// Stream clients connected to one session at once.
    pub max_clients_per_session: usize,
    /// Samples (frames x channels) one binary audio message may carry.
    pub max_audio_samples: usize,
    /// Largest WebSocket message (bytes).
    pub max_message_bytes: usize,
    /// Most boxes one camera frame, or directions and points one device frame, may carry.
    /// The tracker's work and memory for a frame grow with them (30,000 boxes in one frame
    /// took 29 MB to process), and no room holds more faces than this.
    pub max_measurements: usize,
    /// Largest REST request body (bytes).
    pub max_body_bytes: usize,
    /// Inbound messages a session queues for its pipeline; more are refused with `queue_full`.
    pub queue_depth: usize,
    /// Bytes the messages a session queues may hold together, decoded (a JSON message of
    /// many boxes or points takes about three times its size); more are refused with
    /// `queue_full`. At least 4 x `max_message_bytes`, so any message the size limit admits
    /// fits an empty queue. It counts in each session's memory bound; the default, 4 MiB, holds
    /// 127 audio frames of 1,024 samples on 8 channels.
    pub queue_bytes: usize,
    /// Bytes the camera and device frames a session holds until its audio reaches their time
    /// may take together (`max_lead_s` bounds how far ahead they may run, not how many a
    /// client sends in that time); a frame past it is refused with `backlog_full`. At least
    /// one frame of `max_measurements` boxes; it counts in each session's memory bound. The
    /// default, 2 MiB, holds 10 s of a 30 frames/s camera seeing 50 faces.
    pub sensor_backlog_bytes: usize,
    /// Output messages buffered for each stream client; a client that falls further behind
    /// skips ahead and is told how many it missed (`output_dropped`).
    pub output_buffer: usize,
    /// Tracker steps kept in a session's track history.
    pub history_steps: usize,
    /// Seconds a finished or failed session stays readable before it is removed.
    pub finished_ttl_s: f64,
    /// Seconds a REST call waits for the session's pipeline to apply a change.
    pub control_timeout_s: f64,
    /// Microphones in one session's arrays, all arrays together.
    pub max_microphones: usize,
    /// Sum over each array's microphone pairs of their distances (m), all arrays together: the
    /// localiser's tables grow with it (one pair's lags span its distance), so it bounds a
    /// session's memory. A 16-microphone array of 30 cm spans about 25 m.
    pub max_pair_span_m: f64,
    /// Largest STFT frame (samples) a session's settings may choose for its localisation or
    /// its separation: their per-bin tables grow with it, times the microphone pairs. On one
    /// 64-microphone array the localiser alone measured 186 MB at the default 2048-sample
    /// frame, 336 MB at 4096 and 4.5 GB at 65536 (`avsep process`, maximum resident size).
    pub max_frame: usize,
    /// Most labels a session's settings may have separated at once
    /// (`separate.lifecycle.max_streams`): each stream's state grows with the square of the
    /// microphones times the frame (about 17 MB per label at 64 microphones and the default
    /// frame, 72 MB at a 4096-sample frame).
    pub max_streams: usize,
    /// Cameras in one session's calibration: each is a sensor of every tracker step and keeps
    /// its latest frame (of up to `max_measurements` boxes).
    pub max_cameras: usize,
    /// Refusals of Zenoh input a session publishes on `out/events` per second (as many at
    /// once), counted apart for samples without valid credentials and for the rest. Those over
    /// the rate are still counted in the metrics; the next one published says how many were
    /// held back. Without it anyone on the network could flood the session's outputs.
    pub zenoh_refusals_per_s: f64,
    /// Memory (MB) the running sessions may take together, at most, each counted by the bound
    /// its layout and settings give for its pipeline and the server's buffers around it, with
    /// every stream its cap allows (`memory_bound_bytes` in its info; an everyday 8-microphone
    /// session counts about 62 MB, the largest the default limits admit about 1.65 GB). A
    /// creation, recalibration or settings change past it is refused with 503
    /// `memory_budget`; 0 sets no budget.
    pub max_memory_mb: usize,
    /// Seconds a running session may go without accepted input and without a connected stream
    /// client before it is ended (`idle`); 0 never ends one. One that never received input
    /// is removed at once; one that did finishes and stays readable for `finished_ttl_s`.
    pub idle_timeout_s: f64,
    /// Sessions the server creates per minute on average (as many at once): building a
    /// session's pipeline costs CPU, so a loop of creations cannot starve the running ones.
    /// More are refused with 429 `rate_limited`.
    pub session_creations_per_min: f64,
}

impl Limits {
    /// The bounds every session's layout and settings are checked against before anything is
    /// sized from them ([`SizeBounds`]).
    pub fn bounds(&self) -> SizeBounds {
        SizeBounds {
            max_microphones: self.max_microphones,
            max_pair_span_m: self.max_pair_span_m,
            max_frame: self.max_frame,
            max_streams: self.max_streams,
            max_cameras: self.max_cameras,
        }
    }

    /// Refuses settings past [`Limits::bounds`], naming the field.
    pub fn check_settings(&self, settings: &PipelineConfig) -> Result<(), ConfigError> {
        self.bounds().check_settings(settings)
    }

    /// Checks every limit; the error names the first bad one (`limits.<name>`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        let l = self;
        let positive = [
            ("limits.max_sessions", l.max_sessions),
            ("limits.max_clients_per_session", l.max_clients_per_session),
            ("limits.max_audio_samples", l.max_audio_samples),
            ("limits.max_message_bytes", l.max_message_bytes),
            ("limits.max_measurements", l.max_measurements),
            ("limits.max_body_bytes", l.max_body_bytes),
            ("limits.queue_depth", l.queue_depth),
            ("limits.queue_bytes", l.queue_bytes),
            ("limits.sensor_backlog_bytes", l.sensor_backlog_bytes),
            ("limits.output_buffer", l.output_buffer),
            ("limits.history_steps", l.history_steps),
            ("limits.max_microphones", l.max_microphones),
            ("limits.max_frame", l.max_frame),
            ("limits.max_streams", l.max_streams),
            ("limits.max_cameras", l.max_cameras),
        ];
        if let Some((field, _)) = positive.iter().find(|(_, v)| *v == 0) {
            return Err(ConfigError::new(*field, "must be at least 1"));
        }
        let frame_bytes = crate::protocol::audio_frame::AUDIO_IN_HEADER + 4 * l.max_audio_samples;
        if l.max_message_bytes < frame_bytes {
            return Err(ConfigError::new(
                "limits.max_message_bytes",
                format!("must hold a frame of max_audio_samples f32 samples ({frame_bytes} bytes)"),
            ));
        }
        if l.queue_bytes / 4 < l.max_message_bytes {
            return Err(ConfigError::new(
                "limits.queue_bytes",
                format!(
                    "must be at least 4 x max_message_bytes ({} bytes), so that any message \
                     the size limit admits fits an empty queue",
                    4 * l.max_message_bytes
                ),
            ));
        }
        let frame = crate::pipeline::largest_frame_bytes(l.max_measurements);
        if l.sensor_backlog_bytes < frame {
            return Err(ConfigError::new(
                "limits.sensor_backlog_bytes",
                format!(
                    "must hold one frame of max_measurements boxes ({frame} bytes), or such a \
                     frame could never wait for its step"
                ),
            ));
        }
        let numbers: [(&str, f64, bool, &str); 6] = [
            (
                "limits.finished_ttl_s",
                l.finished_ttl_s,
                l.finished_ttl_s >= 0.0,
                ">= 0 s",
            ),
            (
                "limits.zenoh_refusals_per_s",
                l.zenoh_refusals_per_s,
                l.zenoh_refusals_per_s >= 0.0,
                ">= 0",
            ),
            (
                "limits.idle_timeout_s",
                l.idle_timeout_s,
                l.idle_timeout_s >= 0.0,
                ">= 0 s",
            ),
            (
                "limits.session_creations_per_min",
                l.session_creations_per_min,
                l.session_creations_per_min > 0.0,
                "> 0",
            ),
            (
                "limits.max_pair_span_m",
                l.max_pair_span_m,
                l.max_pair_span_m > 0.0,
                "> 0 m",
            ),
            (
                "limits.control_timeout_s",
                l.control_timeout_s,
                l.control_timeout_s > 0.0 && l.control_timeout_s <= 600.0,
                "in (0, 600] s",
            ),
        ];
        for (field, v, ok, range) in numbers {
            if !(ok && v.is_finite()) {
                return Err(ConfigError::new(
                    field,
                    format!("must be a finite number {range}"),
                ));
            }
        }
        Ok(())
    }

    /// Refuses a layout past [`Limits::bounds`], naming the array (`arrays[i].mics`).
    pub fn check_layout(&self, layout: &Layout) -> Result<(), GeometryError> {
        self.bounds().check_layout(layout)
    }
}

impl Default for Limits {
    fn default() -> Self {
        let bounds = SizeBounds::default();
        Self {
            max_sessions: 64,
            max_clients_per_session: 8,
            max_audio_samples: 8 * 4096,
            max_message_bytes: 1 << 20,
            max_measurements: 256,
            max_body_bytes: 256 << 10,
            queue_depth: 64,
            queue_bytes: 4 << 20,
            sensor_backlog_bytes: 2 << 20,
            output_buffer: 1024,
            history_steps: 2048,
            finished_ttl_s: 600.0,
            control_timeout_s: 5.0,
            max_microphones: bounds.max_microphones,
            max_pair_span_m: bounds.max_pair_span_m,
            max_frame: bounds.max_frame,
            max_streams: bounds.max_streams,
            max_cameras: bounds.max_cameras,
            zenoh_refusals_per_s: 10.0,
            max_memory_mb: 4096,
            idle_timeout_s: 900.0,
            session_creations_per_min: 60.0,
        }
    }
}

/// How a session's work is spread over threads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct Execution {
    /// Run each session's separation on a thread of its own, behind its tracker: a session's step
    /// then sends its tracks without waiting for its own or any other session's separation.
    /// Results are the same either way.
    pub separation_thread: bool,
    /// Niceness of the separation threads (0 to 19; higher yields more readily), so that on a
    /// busy machine the tracker steps, whose latency clients see, go first.
    pub separation_nice: i32,
    /// Steps of separation work a session queues; when the separation is that far behind, the
    /// session's pipeline waits for it (and its input queue, then `queue_full`, takes the strain).
    pub separation_queue: usize,
}

impl Default for Execution {
    fn default() -> Self {
        Self {
            separation_thread: true,
            separation_nice: 19,
            separation_queue: 16,
        }
    }
}

impl ServerConfig {
    /// Parses a JSON or TOML file's text (TOML unless it starts with `{`), naming unknown or
    /// mistyped fields.
    pub fn parse(text: &str) -> Result<Self, ConfigError> {
        let cfg: Self = crate::field_error::parse_document(text)?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.bind.parse::<std::net::SocketAddr>().is_err() {
            return Err(ConfigError::new(
                "bind",
                format!(
                    "{:?} is not an ADDRESS:PORT such as 127.0.0.1:8080",
                    self.bind
                ),
            ));
        }
        if let Some(k) = &self.admin_key
            && k.len() < 16
        {
            return Err(ConfigError::new(
                "admin_key",
                "must be at least 16 characters long",
            ));
        }
        if !(0.0..=600.0).contains(&self.drain_timeout_s) {
            return Err(ConfigError::new("drain_timeout_s", "must be in 0..=600 s"));
        }
        self.limits.validate()?;
        if !(0..=19).contains(&self.execution.separation_nice) {
            return Err(ConfigError::new(
                "execution.separation_nice",
                "must be in 0..=19",
            ));
        }
        if self.execution.separation_queue == 0 {
            return Err(ConfigError::new(
                "execution.separation_queue",
                "must be at least 1",
            ));
        }
        self.zenoh.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_listen_locally() {
        let c = ServerConfig::default();
        c.validate().unwrap();
        assert!(c.bind.starts_with("127.0.0.1:"));
        assert!(c.admin_key.is_none() && c.cors_origins.is_empty());
        // As documented: 10 s of a 30 frames/s camera that sees 50 faces fit the backlog.
        let frame = crate::scene::DetectionFrame {
            t: 0.0,
            camera: 0,
            boxes: Vec::new(),
        };
        let faces = 50 * std::mem::size_of::<crate::scene::FaceBox>();
        assert!(300 * (std::mem::size_of_val(&frame) + faces) <= c.limits.sensor_backlog_bytes);
    }

    #[test]
    fn a_bad_time_or_rate_limit_is_named() {
        type Spoil = fn(&mut Limits);
        let cases: [(&str, Spoil); 8] = [
            ("limits.finished_ttl_s", |l| l.finished_ttl_s = -1.0),
            // A queue that could not take one message of the largest size.
            ("limits.queue_bytes", |l| {
                l.queue_bytes = 4 * l.max_message_bytes - 1
            }),
            // A backlog that could not hold one frame of the most boxes.
            ("limits.sensor_backlog_bytes", |l| {
                l.sensor_backlog_bytes =
                    crate::pipeline::largest_frame_bytes(l.max_measurements) - 1
            }),
            ("limits.zenoh_refusals_per_s", |l| {
                l.zenoh_refusals_per_s = f64::NAN
            }),
            ("limits.idle_timeout_s", |l| {
                l.idle_timeout_s = f64::INFINITY
            }),
            ("limits.session_creations_per_min", |l| {
                l.session_creations_per_min = 0.0
            }),
            ("limits.max_pair_span_m", |l| l.max_pair_span_m = 0.0),
            ("limits.control_timeout_s", |l| l.control_timeout_s = 601.0),
        ];
        for (field, spoil) in cases {
            let mut c = ServerConfig::default();
            spoil(&mut c.limits);
            assert_eq!(c.validate().unwrap_err().field, field);
        }
        let mut c = ServerConfig::default();
        (c.limits.idle_timeout_s, c.limits.zenoh_refusals_per_s) = (0.0, 0.0);
        c.validate().unwrap();
    }

    #[test]
    fn files_parse_and_errors_name_the_field() {
        let c =
            ServerConfig::parse("bind = \"0.0.0.0:9000\"\n[limits]\nqueue_depth = 8\n").unwrap();
        assert_eq!((c.bind.as_str(), c.limits.queue_depth), ("0.0.0.0:9000", 8));
        assert_eq!(c.limits.max_sessions, Limits::default().max_sessions);
        let c = ServerConfig::parse(r#"{"limits": {"max_sessions": 3}}"#).unwrap();
        assert_eq!(c.limits.max_sessions, 3);

        let e = ServerConfig::parse("[limits]\nqueue_dept = 8\n").unwrap_err();
        assert!(e.message.contains("queue_dept"), "{e}");
        let e = ServerConfig::parse(r#"{"limits": {"queue_depth": 0}}"#).unwrap_err();
        assert_eq!(e.field, "limits.queue_depth");
        let e = ServerConfig::parse(r#"{"bind": "localhost"}"#).unwrap_err();
        assert_eq!(e.field, "bind");
        let e = ServerConfig::parse(r#"{"admin_key": "short"}"#).unwrap_err();
        assert_eq!(e.field, "admin_key");
        let e = ServerConfig::parse(r#"{"limits": {"max_message_bytes": 100}}"#).unwrap_err();
        assert_eq!(e.field, "limits.max_message_bytes");
        let e = ServerConfig::parse("[execution]\nseparation_nice = 20\n").unwrap_err();
        assert_eq!(e.field, "execution.separation_nice");
    }
}
