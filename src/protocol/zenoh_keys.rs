//! Key expressions of the Zenoh transport and the one message it adds to the WebSocket's
//! (`closed`, which stands for the WebSocket's close frame). Payloads are otherwise the
//! WebSocket's: AVSA/AVSO binary audio frames and the JSON messages of `messages.rs`. See the
//! Zenoh section of api/protocol.md.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::label::Label;

use super::rest::SessionState;

/// First chunk of every key.
pub const ROOT: &str = "avsep";
/// Queryable that creates a session (payload: the body of `POST /v1/sessions`).
pub const SESSIONS_CREATE: &str = "avsep/sessions/create";
/// Queryable that lists the sessions of every server that answers.
pub const SESSIONS_LIST: &str = "avsep/sessions/list";
/// Key expression of the session-management queryable that lists and inspects.
pub const SESSIONS_ALL: &str = "avsep/sessions/**";

/// Where a session's input goes: `avsep/<session>/in/**`.
pub fn session_input(session: &str) -> String {
    format!("{ROOT}/{session}/in/**")
}

/// Binary audio frames (AVSA header), in sample order.
pub fn input_audio(session: &str) -> String {
    format!("{ROOT}/{session}/in/audio")
}

/// One camera's detections (the WebSocket's `detections` message).
pub fn input_detections(session: &str, camera: &str) -> String {
    format!("{ROOT}/{session}/in/detections/{camera}")
}

/// One self-localising array's directions (the WebSocket's `audio_measurements` message).
pub fn input_doa(session: &str, array: &str) -> String {
    format!("{ROOT}/{session}/in/doa/{array}")
}

/// Ends the session's input (any payload).
pub fn input_finish(session: &str) -> String {
    format!("{ROOT}/{session}/in/finish")
}

/// Track estimates, one `tracks` message per step.
pub fn output_tracks(session: &str) -> String {
    format!("{ROOT}/{session}/out/tracks")
}

/// The localiser's `measurements` of one array, one per step.
pub fn output_measurements(session: &str, array: &str) -> String {
    format!("{ROOT}/{session}/out/measurements/{array}")
}

/// One label's separated audio (AVSO frames, f32).
pub fn output_audio(session: &str, label: Label) -> String {
    format!("{ROOT}/{session}/out/audio/{label}")
}

/// Events, warnings, errors and the final `closed`.
pub fn output_events(session: &str) -> String {
    format!("{ROOT}/{session}/out/events")
}

/// Every label's separated audio: `avsep/<session>/out/audio/**`.
pub fn output_audio_keys(session: &str) -> String {
    format!("{ROOT}/{session}/out/audio/**")
}

/// Every array's measurements: `avsep/<session>/out/measurements/**`.
pub fn output_measurement_keys(session: &str) -> String {
    format!("{ROOT}/{session}/out/measurements/**")
}

/// Everything a session publishes: `avsep/<session>/out/**`.
pub fn session_output(session: &str) -> String {
    format!("{ROOT}/{session}/out/**")
}

/// The inspect query of one session: `avsep/sessions/<session>`.
pub fn session_query(session: &str) -> String {
    format!("{ROOT}/sessions/{session}")
}

/// What an inbound sample under `avsep/<session>/in/` is, from the rest of its key.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum InputKey {
    /// `in/audio`.
    Audio,
    /// `in/detections/<camera>`.
    Detections(String),
    /// `in/doa/<array>`.
    Doa(String),
    /// `in/finish`.
    Finish,
}

impl InputKey {
    /// Parses the key of a sample published under `avsep/<session>/in/`; `None` for a key the
    /// protocol does not define.
    pub fn parse(key: &str, session: &str) -> Option<Self> {
        let rest = key
            .strip_prefix(ROOT)?
            .strip_prefix('/')?
            .strip_prefix(session)?
            .strip_prefix("/in/")?;
        let one = |s: &str| (!s.is_empty() && !s.contains('/')).then(|| s.to_string());
        match rest.split_once('/') {
            None if rest == "audio" => Some(Self::Audio),
            None if rest == "finish" => Some(Self::Finish),
            Some(("detections", camera)) => one(camera).map(Self::Detections),
            Some(("doa", array)) => one(array).map(Self::Doa),
            _ => None,
        }
    }
}

/// A query under `avsep/sessions/`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SessionQuery {
    /// `avsep/sessions/create`.
    Create,
    /// `avsep/sessions/list`.
    List,
    /// `avsep/sessions/<id>`.
    Inspect(String),
}

impl SessionQuery {
    /// Parses a query's key; `None` for a key the protocol does not define.
    pub fn parse(key: &str) -> Option<Self> {
        let rest = key.strip_prefix(ROOT)?.strip_prefix("/sessions/")?;
        match rest {
            "create" => Some(Self::Create),
            "list" => Some(Self::List),
            id if !id.is_empty() && id.bytes().all(|b| b.is_ascii_alphanumeric()) => {
                Some(Self::Inspect(id.to_string()))
            }
            _ => None,
        }
    }
}

/// The last message on `out/events`: the session ended and publishes nothing more.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "type", rename = "closed")]
pub struct ClosedMessage {
    /// `finished` or `failed`.
    pub state: SessionState,
    /// Why (input finished, session deleted, server shutting down, the failure).
    pub reason: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn input_keys_round_trip() {
        let s = "00ff";
        assert_eq!(InputKey::parse(&input_audio(s), s), Some(InputKey::Audio));
        assert_eq!(InputKey::parse(&input_finish(s), s), Some(InputKey::Finish));
        assert_eq!(
            InputKey::parse(&input_detections(s, "cam0"), s),
            Some(InputKey::Detections("cam0".into()))
        );
        assert_eq!(
            InputKey::parse(&input_doa(s, "a0"), s),
            Some(InputKey::Doa("a0".into()))
        );
        for bad in [
            "avsep/00ff/in/video",
            "avsep/00ff/in/detections",
            "avsep/00ff/in/detections/a/b",
            "avsep/0000/in/audio",
            "avsep/00ff/out/tracks",
        ] {
            assert_eq!(InputKey::parse(bad, s), None, "{bad}");
        }
    }

    #[test]
    fn session_queries_parse() {
        assert_eq!(
            SessionQuery::parse(SESSIONS_CREATE),
            Some(SessionQuery::Create)
        );
        assert_eq!(SessionQuery::parse(SESSIONS_LIST), Some(SessionQuery::List));
        assert_eq!(
            SessionQuery::parse(&session_query("0a1b")),
            Some(SessionQuery::Inspect("0a1b".into()))
        );
        assert_eq!(SessionQuery::parse("avsep/sessions/a/b"), None);
        assert_eq!(SessionQuery::parse("avsep/other"), None);
    }

    #[test]
    fn output_keys_and_closed_message() {
        assert_eq!(
            output_audio("ab", Label::new(3, 1)),
            "avsep/ab/out/audio/3.1"
        );
        let m = ClosedMessage {
            state: SessionState::Finished,
            reason: "input finished".into(),
        };
        assert_eq!(
            serde_json::to_string(&m).unwrap(),
            r#"{"type":"closed","state":"finished","reason":"input finished"}"#
        );
    }
}
