//! Reading a client's JSON message so that a refusal names the field at fault.
//!
//! serde's internally tagged enums buffer the message before choosing the variant, and the
//! buffer forgets where each value came from: a box with a string width was refused with no
//! field. So the `type` is read first and the variant's body is then read on its own, with its
//! path tracked (`boxes[0].w`, `doas[1].azimuth`).

use serde::Deserialize;
use serde::de::DeserializeOwned;
use serde_json::{Map, Value};

use crate::scene::format::BoxFile;

use super::{ClientMessage, ErrorBody, OutputSelection};

/// The message types, as the `type` field spells them.
const TYPES: [&str; 4] = ["hello", "detections", "audio_measurements", "finish"];

/// Body of a `hello` (the fields of [`ClientMessage::Hello`]).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Hello {
    #[serde(default)]
    client: String,
    #[serde(default)]
    outputs: OutputSelection,
}

/// Body of a `detections` message (the fields of [`ClientMessage::Detections`]).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Detections {
    t: f64,
    camera: String,
    boxes: Vec<BoxFile>,
}

/// Body of a `finish`: nothing.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Finish {}

impl ClientMessage {
    /// Parses one message. Text that is not JSON is `bad_json`; JSON that does not fit the
    /// protocol is `bad_message`, naming the field (`type`, `boxes[0].w`, ...).
    pub fn parse(text: &str) -> Result<Self, ErrorBody> {
        let value: Value = serde_json::from_str(text).map_err(|e| ErrorBody {
            code: "bad_json".into(),
            message: e.to_string(),
            field: None,
        })?;
        let Value::Object(mut body) = value else {
            return Err(bad(
                "",
                "a message is a JSON object with a `type` field".into(),
            ));
        };
        let kind = match body.remove("type") {
            Some(Value::String(s)) => s,
            Some(other) => return Err(bad("type", format!("must be a string, not {other}"))),
            None => return Err(bad("type", "missing; every message has a `type`".into())),
        };
        Ok(match kind.as_str() {
            "hello" => {
                let h: Hello = read(body)?;
                Self::Hello {
                    client: h.client,
                    outputs: h.outputs,
                }
            }
            "detections" => {
                let d: Detections = read(body)?;
                Self::Detections {
                    t: d.t,
                    camera: d.camera,
                    boxes: d.boxes,
                }
            }
            "audio_measurements" => Self::AudioMeasurements(read(body)?),
            "finish" => {
                let Finish {} = read(body)?;
                Self::Finish {}
            }
            other => {
                return Err(bad(
                    "type",
                    format!("unknown message type {other:?}; the types are {TYPES:?}"),
                ));
            }
        })
    }
}

/// Reads a variant's body, naming the field a refusal is about.
fn read<T: DeserializeOwned>(body: Map<String, Value>) -> Result<T, ErrorBody> {
    serde_path_to_error::deserialize(Value::Object(body)).map_err(|e| {
        let path = e.path().to_string();
        let message = e.into_inner().to_string();
        let mut field = if path == "." { String::new() } else { path };
        // A missing field is reported at the object that should hold it.
        if let Some(name) = message
            .strip_prefix("missing field `")
            .and_then(|rest| rest.split('`').next())
        {
            if !field.is_empty() {
                field.push('.');
            }
            field.push_str(name);
        }
        bad(&field, message)
    })
}

fn bad(field: &str, message: String) -> ErrorBody {
    ErrorBody {
        code: "bad_message".into(),
        message,
        field: (!field.is_empty()).then(|| field.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::AudioSelection;
    use crate::scene::format::{AudioMeasurementLine, DoaFile};

    fn refusal(text: &str) -> ErrorBody {
        match ClientMessage::parse(text) {
            Ok(m) => panic!("{text} was accepted as {m:?}"),
            Err(e) => e,
        }
    }

    /// Every message type reads back as what was written, and each is one of [`TYPES`].
    #[test]
    fn every_type_round_trips() {
        let messages = [
            ClientMessage::Hello {
                client: "room 4".into(),
                outputs: OutputSelection {
                    measurements: true,
                    audio: Some(AudioSelection::default()),
                    ..OutputSelection::default()
                },
            },
            ClientMessage::Detections {
                t: 0.1 + 0.2,
                camera: "cam0".into(),
                boxes: vec![BoxFile {
                    x: 1.5,
                    y: 2.0,
                    w: 30.0,
                    h: 40.0,
                    score: Some(0.9),
                    point: Some([3.0, 4.0]),
                }],
            },
            ClientMessage::AudioMeasurements(AudioMeasurementLine {
                t: 1.0,
                array: "a0".into(),
                doas: vec![DoaFile {
                    azimuth: 30.0,
                    elevation: Some(-5.0),
                    energy: Some(0.5),
                }],
                points: vec![[1.0, 2.0, 1.5]],
                activity: Some(0.7),
            }),
            ClientMessage::Finish {},
        ];
        for m in messages {
            let text = serde_json::to_string(&m).unwrap();
            let kind: Value = serde_json::from_str(&text).unwrap();
            assert!(TYPES.contains(&kind["type"].as_str().unwrap()), "{text}");
            assert_eq!(ClientMessage::parse(&text).unwrap(), m, "{text}");
            // The derived reader (what the schema describes) agrees.
            assert_eq!(serde_json::from_str::<ClientMessage>(&text).unwrap(), m);
        }
    }

    #[test]
    fn a_refused_message_names_its_field() {
        let cases = [
            (
                r#"{"type":"detections","t":0.1,"camera":"c","boxes":[{"x":"ten","y":1,"w":2,"h":3}]}"#,
                "boxes[0].x",
            ),
            (
                r#"{"type":"detections","t":"soon","camera":"c","boxes":[]}"#,
                "t",
            ),
            (r#"{"type":"detections","t":0.1,"camera":"c"}"#, "boxes"),
            (
                r#"{"type":"detections","t":0.1,"camera":"c","boxes":[],"zoom":2}"#,
                "zoom",
            ),
            (
                r#"{"type":"audio_measurements","t":0.1,"array":"a","doas":[{"azimuth":1},{"azimuth":null}]}"#,
                "doas[1].azimuth",
            ),
            (
                r#"{"type":"hello","outputs":{"tracks":1}}"#,
                "outputs.tracks",
            ),
            (
                r#"{"type":"hello","outputs":{"audio":{"format":"mp3"}}}"#,
                "outputs.audio.format",
            ),
            (r#"{"type":"finish","now":true}"#, "now"),
            (
                r#"{"type":"hello","outputs":{"tracks":true,"video":true}}"#,
                "outputs.video",
            ),
            (r#"{"type":"teleport"}"#, "type"),
            (r#"{"type":7}"#, "type"),
            (r#"{"t":0.1}"#, "type"),
            ("[1, 2]", ""),
        ];
        for (text, field) in cases {
            let e = refusal(text);
            assert_eq!(e.code, "bad_message", "{text}: {e:?}");
            assert_eq!(e.field.as_deref().unwrap_or(""), field, "{text}: {e:?}");
        }
        assert!(refusal(cases[9].0).message.contains("teleport"));
    }

    #[test]
    fn text_that_is_not_json_is_bad_json() {
        for text in ["{\"type\": \"detections\", \"t\": 0.4,", "", "type=finish"] {
            let e = refusal(text);
            assert_eq!((e.code.as_str(), e.field), ("bad_json", None), "{text}");
        }
    }
}
