//! What flows through a session: the checked input its pipeline takes, the output it
//! broadcasts, and why an input or a control request was refused.

use crate::label::Label;
use crate::pipeline::{ConfigError, InputError};
use crate::protocol::rest::{SessionState, TracksSnapshot};
use crate::protocol::{AudioFrame, ErrorBody, SessionEvent};
use crate::scene::format::AudioMeasurementLine;
use crate::scene::{AudioMeasurementFrame, DetectionFrame};
use crate::server::metrics::FrameKind;

use super::ClientId;

/// Inbound data for a session's pipeline, already decoded and checked against the layout.
#[derive(Debug, Clone, PartialEq)]
pub enum Input {
    /// Interleaved multichannel audio.
    Audio(AudioFrame),
    /// One camera frame.
    Detections(DetectionFrame),
    /// One frame of a device that localises itself.
    AudioMeasurements(AudioMeasurementFrame),
}

impl Input {
    pub(super) fn kind(&self) -> FrameKind {
        match self {
            Self::Audio(_) => FrameKind::Audio,
            Self::Detections(_) => FrameKind::Detections,
            Self::AudioMeasurements(_) => FrameKind::AudioMeasurements,
        }
    }
}

/// What the pipeline produced, as broadcast to every subscriber.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// The tracker's estimate after one step.
    Tracks(TracksSnapshot),
    /// The localiser's measurements of one array for one step.
    Measurements(AudioMeasurementLine),
    /// A chunk of one label's separated audio, aligned with the input's sample indices.
    Audio {
        /// Whose voice.
        label: Label,
        /// Input sample index of the first sample.
        first_sample: u64,
        /// Mono samples.
        samples: Vec<f32>,
    },
    /// Track born or ended, or a warning.
    Event(SessionEvent),
    /// An error; `to` is the client whose message caused it (`None`: everyone).
    Error {
        /// Addressee.
        to: Option<ClientId>,
        /// The error.
        error: ErrorBody,
    },
    /// The session ended: nothing follows.
    Closed {
        /// `finished` or `failed`.
        state: SessionState,
        /// Why (input finished, deleted, server shutting down, the failure).
        reason: String,
    },
}

/// Why a message or request was not accepted; the session keeps running.
#[derive(Debug, Clone, PartialEq)]
pub struct Rejection {
    /// Machine-readable reason (`queue_full`, `bad_channels`, `session_closed`, ...).
    pub code: &'static str,
    /// The field at fault, when one is.
    pub field: Option<String>,
    /// Explanation.
    pub message: String,
}

impl Rejection {
    /// A rejection without a field.
    pub fn new(code: &'static str, message: impl Into<String>) -> Self {
        Self {
            code,
            field: None,
            message: message.into(),
        }
    }

    /// The wire form.
    pub fn to_body(&self) -> ErrorBody {
        ErrorBody {
            code: self.code.to_string(),
            message: self.message.clone(),
            field: self.field.clone(),
        }
    }
}

impl From<InputError> for Rejection {
    fn from(e: InputError) -> Self {
        Self {
            code: e.code,
            field: (!e.field.is_empty()).then_some(e.field),
            message: e.message,
        }
    }
}

/// Why a calibration or settings change did not happen.
#[derive(Debug, Clone, PartialEq)]
pub enum ControlError {
    /// The pipeline refused the change (the error names the field).
    Invalid(ConfigError),
    /// The session did not take the request (queue full, closed).
    Rejected(Rejection),
    /// The pipeline did not answer within the control timeout.
    Timeout,
    /// The session failed or ended before applying it.
    Ended,
}
