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

    /// Bytes the message holds while it waits in a session's queue (its allocations, by
    /// capacity), which `limits.queue_bytes` bounds.
    pub fn bytes(&self) -> usize {
        fn held<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        std::mem::size_of::<Self>()
            + match self {
                Self::Audio(f) => held(&f.samples),
                Self::Detections(d) => held(&d.boxes),
                Self::AudioMeasurements(m) => held(&m.doas) + held(&m.points),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::ClientMessage;
    use crate::protocol::inbound::{detection_frame, device_frame, tests::layout};

    /// The decoded input a JSON text becomes on its way to a session's queue.
    fn decoded(text: &str) -> Input {
        match ClientMessage::parse(text).unwrap() {
            ClientMessage::Detections { t, camera, boxes } => {
                Input::Detections(detection_frame(&layout(), t, &camera, &boxes).unwrap())
            }
            ClientMessage::AudioMeasurements(line) => {
                Input::AudioMeasurements(device_frame(&layout(), &line).unwrap())
            }
            other => panic!("not a data message: {other:?}"),
        }
    }

    /// `limits.queue_bytes` must hold 4 of the largest messages because the densest JSON (the
    /// shortest boxes, directions and points) decodes to at most three times its size.
    #[test]
    fn the_densest_json_decodes_to_at_most_three_times_its_size() {
        let n = 5000;
        let boxes = vec![r#"{"x":0,"y":0,"w":1,"h":1}"#; n].join(",");
        let detections =
            format!(r#"{{"type":"detections","t":0,"camera":"cam0","boxes":[{boxes}]}}"#);
        let doas = vec![r#"{"azimuth":0}"#; n].join(",");
        let points = vec!["[0,0,1]"; n].join(",");
        let device = format!(
            r#"{{"type":"audio_measurements","t":0,"array":"a0","doas":[{doas}],"points":[{points}]}}"#
        );
        for text in [detections, device] {
            let held = decoded(&text).bytes();
            let ratio = held as f64 / text.len() as f64;
            assert!(
                (2.0..=3.0).contains(&ratio),
                "{ratio:.2}: {held} for {}",
                text.len()
            );
        }
    }

    #[test]
    fn audio_counts_its_samples() {
        let frame = AudioFrame {
            first_sample: 0,
            channels: 4,
            samples: vec![0.0; 4096],
            encoding: crate::protocol::SampleEncoding::I16,
        };
        let held = Input::Audio(frame).bytes();
        assert_eq!(held, 4 * 4096 + std::mem::size_of::<Input>());
        // What `limits.queue_bytes` documents its default holds.
        let block = AudioFrame {
            first_sample: 0,
            channels: 8,
            samples: vec![0.0; 8 * 1024],
            encoding: crate::protocol::SampleEncoding::F32,
        };
        let fit = crate::server::Limits::default().queue_bytes / Input::Audio(block).bytes();
        assert_eq!(fit, 127);
    }
}
