//! JSON messages of live sessions (WebSocket text frames, Zenoh payloads). Every message is an
//! object with a `type` field. Field names and units follow the scene format (seconds, metres,
//! degrees, pixels).

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::label::Label;
use crate::scene::format::{AudioMeasurementLine, BoxFile, TrackFile};

use super::SampleEncoding;

/// What a client wants to receive.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct OutputSelection {
    /// Track estimates after every tracker step.
    pub tracks: bool,
    /// Track born / ended events and warnings.
    pub events: bool,
    /// The localiser's measurements per step.
    pub measurements: bool,
    /// Separated audio; absent or null for none.
    pub audio: Option<AudioSelection>,
}

impl Default for OutputSelection {
    fn default() -> Self {
        Self {
            tracks: true,
            events: true,
            measurements: false,
            audio: None,
        }
    }
}

/// Which separated streams a client receives, and how they are encoded.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct AudioSelection {
    /// Sample encoding of the binary frames.
    pub format: SampleEncoding,
    /// Only these labels ("k.i"); all labels when absent.
    pub labels: Option<Vec<Label>>,
}

/// Messages a client sends (JSON text). Audio is sent as binary frames (see `audio_frame`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ClientMessage {
    /// Introduces the client and chooses its outputs; may be sent again to change them.
    Hello {
        /// Free-form client name, for logs and metrics.
        #[serde(default)]
        client: String,
        /// Outputs wanted (defaults: tracks and events).
        #[serde(default)]
        outputs: OutputSelection,
    },
    /// One camera frame's detections (same fields as a `detections.jsonl` line).
    Detections {
        /// Frame time (s, session time).
        t: f64,
        /// Camera id.
        camera: String,
        /// Detected faces; empty when the camera looked and saw nobody.
        boxes: Vec<BoxFile>,
    },
    /// Directions or positions measured by a device that localises itself.
    AudioMeasurements(AudioMeasurementLine),
    /// The input has ended: the session processes what it holds, flushes the separated audio,
    /// and closes every stream (state `finished`).
    Finish {},
}

/// Body of an error, also used by the REST API (`{"error": {...}}`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, utoipa::ToSchema)]
pub struct ErrorBody {
    /// Machine-readable reason, e.g. `time_backwards`.
    pub code: String,
    /// Human-readable explanation.
    pub message: String,
    /// The offending field, when one is to blame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub field: Option<String>,
}

/// Kinds of session events.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum SessionEvent {
    /// A new track (and its audio stream) began.
    TrackBorn {
        /// Estimate time (s).
        t: f64,
        /// The new label.
        label: Label,
    },
    /// A track ended; its label will not be used again.
    TrackEnded {
        /// Time of the last estimate that held it (s).
        t: f64,
        /// The ended label.
        label: Label,
    },
    /// Something the client should know about (input dropped, camera absent, ...).
    Warning {
        /// Machine-readable reason.
        code: String,
        /// Explanation.
        message: String,
    },
}

/// Messages the server sends (JSON text); separated audio goes as binary frames.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ServerMessage {
    /// Sent once on connect: what the session expects.
    Welcome {
        /// Session id.
        session: String,
        /// Protocol version (1).
        protocol: u32,
        /// Audio sample rate (Hz).
        sample_rate: u32,
        /// Channels expected in audio frames.
        channels: usize,
        /// Array ids, in channel order.
        arrays: Vec<String>,
        /// Camera ids.
        cameras: Vec<String>,
        /// Index of the next audio sample frame the session expects.
        next_sample: u64,
        /// Index of the next tracker step the session will report: the steps before it have
        /// run (a resuming client finds their estimates in the track history).
        #[serde(default)]
        next_step: u64,
        /// Tracker step period (s).
        step_s: f64,
        /// Separated audio lags the input by at most one step plus this many samples.
        #[serde(default)]
        audio_delay_samples: u64,
        /// Messages the session queues before refusing input with `queue_full`.
        #[serde(default)]
        queue_depth: usize,
        /// Most samples (frames x channels) one binary audio message may carry.
        #[serde(default)]
        max_audio_samples: usize,
        /// Largest message (bytes) the server accepts.
        #[serde(default)]
        max_message_bytes: usize,
        /// Most boxes a camera frame, or directions and points a device frame, may carry.
        #[serde(default)]
        max_measurements: usize,
    },
    /// The tracker's estimate after one step.
    Tracks {
        /// Tracker step index.
        step: u64,
        /// Time the estimate refers to (s).
        t: f64,
        /// Tracks that exist at `t`.
        tracks: Vec<TrackFile>,
    },
    /// The localiser's output for one array and step.
    Measurements(AudioMeasurementLine),
    /// A session event.
    Event(SessionEvent),
    /// A refused message or a failure; the session keeps running unless it says otherwise.
    Error {
        /// What went wrong.
        error: ErrorBody,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn client_messages_parse_from_documented_json() {
        let h: ClientMessage = serde_json::from_str(
            r#"{"type":"hello","client":"cli","outputs":{"audio":{"format":"i16","labels":["3.0"]}}}"#,
        )
        .unwrap();
        match h {
            ClientMessage::Hello { client, outputs } => {
                assert_eq!(client, "cli");
                assert!(outputs.tracks && outputs.events);
                let a = outputs.audio.unwrap();
                assert_eq!(
                    (a.format, a.labels),
                    (SampleEncoding::I16, Some(vec![Label::new(3, 0)]))
                );
            }
            m => panic!("{m:?}"),
        }
        let d: ClientMessage = serde_json::from_str(
            r#"{"type":"detections","t":0.5,"camera":"cam0","boxes":[{"x":1,"y":2,"w":3,"h":4}]}"#,
        )
        .unwrap();
        assert!(matches!(d, ClientMessage::Detections { ref boxes, .. } if boxes.len() == 1));
        let m: ClientMessage = serde_json::from_str(
            r#"{"type":"audio_measurements","t":0.1,"array":"a0","doas":[{"azimuth":10}]}"#,
        )
        .unwrap();
        assert!(matches!(m, ClientMessage::AudioMeasurements(_)));
        assert!(serde_json::from_str::<ClientMessage>(r#"{"type":"hello","bogus":1}"#).is_err());
        let f: ClientMessage = serde_json::from_str(r#"{"type":"finish"}"#).unwrap();
        assert_eq!(f, ClientMessage::Finish {});
    }

    #[test]
    fn server_messages_have_a_type_tag() {
        let e = ServerMessage::Event(SessionEvent::TrackBorn {
            t: 1.0,
            label: Label::new(7, 0),
        });
        assert_eq!(
            serde_json::to_string(&e).unwrap(),
            r#"{"type":"event","event":"track_born","t":1.0,"label":"7.0"}"#
        );
        let err = ServerMessage::Error {
            error: ErrorBody {
                code: "bad_channels".into(),
                message: "m".into(),
                field: Some("channels".into()),
            },
        };
        assert_eq!(
            serde_json::to_string(&err).unwrap(),
            r#"{"type":"error","error":{"code":"bad_channels","message":"m","field":"channels"}}"#
        );
    }
}
