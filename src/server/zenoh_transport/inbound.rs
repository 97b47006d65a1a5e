//! Inbound samples of one session (`avsep/<session>/in/**`): checked for the session's token,
//! decoded with the WebSocket's decoders, and handed to the session's bounded queue with
//! [`Session::submit`](crate::server::session::Session::submit) (which never blocks: a full
//! queue refuses with `queue_full`). Every refusal is counted and published on `out/events` as
//! an error naming the field, at most `limits.zenoh_refusals_per_s` a second (apart for samples
//! without credentials, so a stranger's flood cannot hide a device's own refusals); the
//! session goes on.

use std::sync::Mutex;
use std::time::Instant;

use zenoh::bytes::ZBytes;
use zenoh::sample::Sample;

use crate::protocol::inbound::{detection_frame, device_frame};
use crate::protocol::zenoh_keys::InputKey;
use crate::protocol::{AudioFrame, ClientMessage, ErrorBody};
use crate::server::auth;
use crate::server::rate_limit::TokenBucket;
use crate::server::session::{Input, Output, Rejection, SessionHandle};

use super::ZENOH_CLIENT;

/// The subscriber callback of a session's input.
pub(super) fn handler(
    session: SessionHandle,
    admin_key: Option<String>,
) -> impl Fn(Sample) + Send + Sync + 'static {
    let rate = session.limits().zenoh_refusals_per_s;
    let published = Mutex::new([TokenBucket::new(rate, rate), TokenBucket::new(rate, rate)]);
    move |sample| {
        let Err(mut error) = on_sample(&session, admin_key.as_deref(), &sample) else {
            return;
        };
        tracing::debug!(session = %session.id(), code = %error.code, "zenoh input refused");
        let bucket = usize::from(!UNAUTHENTICATED.contains(&error.code.as_str()));
        let Some(held) = published
            .lock()
            .ok()
            .and_then(|mut b| b[bucket].admit(Instant::now()))
        else {
            return;
        };
        if held > 0 {
            error.message = format!(
                "{} ({held} refusals before this one were not published: \
                 limits.zenoh_refusals_per_s)",
                error.message
            );
        }
        session.broadcast(Output::Error {
            to: Some(ZENOH_CLIENT),
            error,
        });
    }
}

/// Refusals of samples that did not show valid credentials (or any input key), published at a
/// rate of their own.
const UNAUTHENTICATED: [&str; 3] = ["unknown_key", "unauthorized", "forbidden"];

/// An error the transport finds itself (the session's `submit` counts its own refusals).
fn refused(s: &SessionHandle, code: &'static str, field: &str, message: String) -> ErrorBody {
    s.counters.refused(code);
    ErrorBody {
        code: code.to_string(),
        message,
        field: (!field.is_empty()).then(|| field.to_string()),
    }
}

/// Whether the attachment is the session's token or the admin key.
pub(super) fn check_credential(
    attachment: Option<&ZBytes>,
    accepts: impl Fn(&str) -> bool,
    what: &str,
) -> Result<(), (&'static str, String)> {
    let Some(bytes) = attachment else {
        return Err((
            "unauthorized",
            format!("{what} needs a credential: put it in the attachment (UTF-8)"),
        ));
    };
    let presented = bytes.try_to_string().unwrap_or_default();
    if accepts(presented.trim()) {
        Ok(())
    } else {
        Err(("forbidden", format!("the attachment does not open {what}")))
    }
}

fn on_sample(s: &SessionHandle, admin: Option<&str>, sample: &Sample) -> Result<(), ErrorBody> {
    let key = sample.key_expr().as_str();
    let Some(kind) = InputKey::parse(key, s.id()) else {
        return Err(refused(
            s,
            "unknown_key",
            "key",
            format!(
                "{key:?} is not an input key (in/audio, in/detections/<camera>, in/doa/<array>, in/finish)"
            ),
        ));
    };
    let accepts = |p: &str| s.token_matches(p) || admin.is_some_and(|k| auth::same_secret(k, p));
    check_credential(sample.attachment(), accepts, "this session")
        .map_err(|(code, message)| refused(s, code, "attachment", message))?;
    let max = s.limits().max_message_bytes;
    if sample.payload().len() > max {
        return Err(refused(
            s,
            "too_large",
            "payload",
            format!(
                "{} bytes is more than limits.max_message_bytes ({max})",
                sample.payload().len()
            ),
        ));
    }
    let payload = sample.payload().to_bytes();
    let input = match kind {
        InputKey::Finish => {
            s.finish("input finished");
            return Ok(());
        }
        InputKey::Audio => AudioFrame::decode(&payload, s.limits().max_audio_samples)
            .map(Input::Audio)
            .map_err(|e| refused(s, e.code, e.field, e.message))?,
        InputKey::Detections(camera) => detections(s, &camera, &payload)?,
        InputKey::Doa(array) => doa(s, &array, &payload)?,
    };
    s.submit(ZENOH_CLIENT, input).map_err(|r| r.to_body())
}

fn message(s: &SessionHandle, payload: &[u8]) -> Result<ClientMessage, ErrorBody> {
    let text = std::str::from_utf8(payload).map_err(|e| {
        refused(
            s,
            "bad_json",
            "",
            format!("the payload is not UTF-8 JSON: {e}"),
        )
    })?;
    ClientMessage::parse(text).inspect_err(|e| s.counters.refused(&e.code))
}

fn wrong_type(s: &SessionHandle, expected: &str) -> ErrorBody {
    refused(
        s,
        "bad_message",
        "type",
        format!("this key takes `{expected}` messages"),
    )
}

fn detections(s: &SessionHandle, key_camera: &str, payload: &[u8]) -> Result<Input, ErrorBody> {
    let ClientMessage::Detections { t, camera, boxes } = message(s, payload)? else {
        return Err(wrong_type(s, "detections"));
    };
    if camera != key_camera {
        return Err(refused(
            s,
            "key_mismatch",
            "camera",
            format!("camera {camera:?} published under the key of camera {key_camera:?}"),
        ));
    }
    detection_frame(&s.layout(), t, &camera, &boxes)
        .map(Input::Detections)
        .map_err(|e| {
            s.counters.refused(e.code);
            Rejection::from(e).to_body()
        })
}

fn doa(s: &SessionHandle, key_array: &str, payload: &[u8]) -> Result<Input, ErrorBody> {
    let ClientMessage::AudioMeasurements(line) = message(s, payload)? else {
        return Err(wrong_type(s, "audio_measurements"));
    };
    if line.array != key_array {
        return Err(refused(
            s,
            "key_mismatch",
            "array",
            format!(
                "array {:?} published under the key of array {key_array:?}",
                line.array
            ),
        ));
    }
    device_frame(&s.layout(), &line)
        .map(Input::AudioMeasurements)
        .map_err(|e| {
            s.counters.refused(e.code);
            Rejection::from(e).to_body()
        })
}
