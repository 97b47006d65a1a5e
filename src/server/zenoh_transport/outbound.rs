//! One session's fan-out: reads the session's output broadcast (the one WebSocket clients read)
//! and publishes each output under `avsep/<session>/out/...` (the optional ones only while a
//! Zenoh subscriber wants them, see `wanted`). A fan-out that falls behind skips
//! ahead and publishes an `output_dropped` warning, like a slow WebSocket client; publications
//! use Zenoh's default congestion control for puts (drop rather than block), so a congested
//! network never holds up the runtime or the session.

use std::sync::Arc;

use crate::server::session::Subscription;
use tokio::sync::broadcast::error::RecvError;
use zenoh::bytes::Encoding;
use zenoh::pubsub::Subscriber;

use crate::protocol::zenoh_keys::{
    ClosedMessage, output_audio, output_events, output_measurements, output_tracks,
};
use crate::protocol::{LabelAudioFrame, SampleEncoding, ServerMessage, SessionEvent};
use crate::server::session::{Output, SessionHandle};

use super::wanted::Wanted;
use super::{Shared, ZENOH_CLIENT};

/// Publishes the session's outputs until it closes, then undeclares its input subscriber.
pub(super) async fn fan_out(
    shared: Arc<Shared>,
    s: SessionHandle,
    (mut subscription, wanted): (Subscription, Wanted),
    subscriber: Option<Subscriber<()>>,
) {
    let events = output_events(s.id());
    loop {
        match subscription.outputs.recv().await {
            Ok(out) => {
                let last = matches!(out.as_ref(), Output::Closed { .. });
                if !wanted.wants(&out) {
                    continue;
                }
                if let Some((key, payload, encoding)) = encode(&s, &out, &events) {
                    put(&shared.zenoh, key, payload, encoding).await;
                }
                if last {
                    break;
                }
            }
            Err(RecvError::Lagged(n)) => {
                s.counters.output_dropped(n);
                let warn = ServerMessage::Event(SessionEvent::Warning {
                    code: "output_dropped".into(),
                    message: format!(
                        "the Zenoh publisher fell behind and missed {n} output messages"
                    ),
                });
                put(
                    &shared.zenoh,
                    events.clone(),
                    json(&warn),
                    Encoding::APPLICATION_JSON,
                )
                .await;
            }
            Err(RecvError::Closed) => break,
        }
    }
    drop(subscriber);
    shared.detach(s.id());
    tracing::debug!(session = %s.id(), "zenoh fan-out ended");
}

async fn put(z: &zenoh::Session, key: String, payload: Vec<u8>, encoding: Encoding) {
    if let Err(e) = z.put(key.as_str(), payload).encoding(encoding).await {
        tracing::warn!(%key, "zenoh publication failed: {e}");
    }
}

fn json(m: &impl serde::Serialize) -> Vec<u8> {
    serde_json::to_vec(m).unwrap_or_default()
}

/// The key and payload of an output, if it goes to Zenoh (errors addressed to a WebSocket client
/// do not).
fn encode(s: &SessionHandle, out: &Output, events: &str) -> Option<(String, Vec<u8>, Encoding)> {
    let id = s.id();
    let j = Encoding::APPLICATION_JSON;
    Some(match out {
        Output::Tracks(snap) => {
            let m = ServerMessage::Tracks {
                step: snap.step,
                t: snap.t,
                tracks: snap.tracks.clone(),
            };
            (output_tracks(id), json(&m), j)
        }
        Output::Measurements(line) => (
            output_measurements(id, &line.array),
            json(&ServerMessage::Measurements(line.clone())),
            j,
        ),
        Output::Audio {
            label,
            first_sample,
            samples,
        } => {
            let frame = LabelAudioFrame {
                label: *label,
                first_sample: *first_sample,
                samples: samples.clone(),
                encoding: SampleEncoding::F32,
            };
            (
                output_audio(id, *label),
                frame.encode(),
                Encoding::APPLICATION_OCTET_STREAM,
            )
        }
        Output::Event(e) => (
            events.to_string(),
            json(&ServerMessage::Event(e.clone())),
            j,
        ),
        Output::Error { to, error } if to.is_none_or(|c| c == ZENOH_CLIENT) => {
            let m = ServerMessage::Error {
                error: error.clone(),
            };
            (events.to_string(), json(&m), j)
        }
        Output::Error { .. } => return None,
        Output::Closed { state, reason } => {
            let m = ClosedMessage {
                state: *state,
                reason: reason.clone(),
            };
            (events.to_string(), json(&m), j)
        }
    })
}
