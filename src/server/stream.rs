//! The WebSocket transport, `/v1/sessions/{id}/stream`: binary audio frames and JSON messages
//! in; welcome, tracks, measurements, events, errors and binary separated audio out. One task
//! per connection reads the socket and the session's broadcast in turn; a client that reads
//! too slowly skips ahead in the broadcast (told with an `output_dropped` warning) rather than
//! holding up the session.

use std::sync::Arc;

use axum::extract::ws::rejection::WebSocketUpgradeRejection;
use axum::extract::ws::{CloseFrame, Message, Utf8Bytes, WebSocket, WebSocketUpgrade, close_code};
use axum::extract::{Path, RawQuery, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::Response;
use futures_util::{SinkExt, StreamExt};
use tokio::sync::broadcast::error::RecvError;

use crate::protocol::rest::SessionState;
use crate::protocol::{
    AudioFrame, ClientMessage, ErrorBody, LabelAudioFrame, OutputSelection, ServerMessage,
    SessionEvent,
};

use super::app::AppState;
use super::error::ApiError;
use super::routes::session_access;
use super::session::{ClientGuard, ClientId, Input, Output, SessionHandle, Subscription};

/// Version of the stream protocol (in the welcome).
pub const PROTOCOL_VERSION: u32 = 1;

/// Opens a session's stream (WebSocket upgrade).
#[utoipa::path(
    get,
    path = "/v1/sessions/{id}/stream",
    tag = "stream",
    params(("id" = String, Path, description = "Session id")),
    responses(
        (status = 101, description = "Switching to the WebSocket protocol of api/protocol.md"),
        (status = 400, description = "Not a WebSocket upgrade request", body = crate::protocol::rest::ErrorResponse),
        (status = 401, body = crate::protocol::rest::ErrorResponse),
        (status = 403, body = crate::protocol::rest::ErrorResponse),
        (status = 404, body = crate::protocol::rest::ErrorResponse),
        (status = 409, description = "The session has ended", body = crate::protocol::rest::ErrorResponse),
        (status = 429, description = "limits.max_clients_per_session reached", body = crate::protocol::rest::ErrorResponse),
    ),
    security(("bearer" = []), ("token_query" = []))
)]
pub(super) async fn open_stream(
    State(app): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
    ws: Result<WebSocketUpgrade, WebSocketUpgradeRejection>,
) -> Result<Response, ApiError> {
    let session = session_access(&app, &id, &headers, query.as_deref())?;
    let ws = ws.map_err(|e| {
        ApiError::new(
            StatusCode::BAD_REQUEST,
            "not_websocket",
            format!("this endpoint is a WebSocket: {}", e.body_text()),
        )
    })?;
    if session.state() != SessionState::Running {
        return Err(ApiError::new(
            StatusCode::CONFLICT,
            "session_closed",
            format!("the session is {}", session.state().as_str()),
        ));
    }
    let guard = session.attach()?;
    let max = app.registry.config().limits.max_message_bytes;
    Ok(ws
        .max_message_size(max)
        .max_frame_size(max)
        .on_upgrade(move |socket| run(socket, session, guard)))
}

/// One connection's life: welcome, then input and output until either side closes.
async fn run(socket: WebSocket, session: SessionHandle, guard: ClientGuard) {
    let me = guard.id();
    let (mut sink, mut inbound) = socket.split();
    // Subscribe before the welcome so nothing produced after it is missed.
    let mut subscription = session.subscribe();
    let mut selection = OutputSelection::default();
    if sink.send(json(&welcome(&session))).await.is_err() {
        return;
    }
    tracing::debug!(session = %session.id(), client = me, "stream opened");
    if session.state() != SessionState::Running {
        let _ = sink
            .send(close(session.state(), "the session has ended"))
            .await;
        return;
    }
    loop {
        tokio::select! {
            // Inbound first, so a hello sent before any output is in effect for that output.
            biased;
            msg = inbound.next() => {
                let reply = match msg {
                    Some(Ok(Message::Binary(bytes))) => on_audio(&session, me, &bytes),
                    Some(Ok(Message::Text(text))) => {
                        on_text(&session, me, text.as_str(), &mut selection, &mut subscription)
                    }
                    Some(Ok(Message::Ping(_) | Message::Pong(_))) => None,
                    Some(Ok(Message::Close(_))) | None => break,
                    Some(Err(e)) => {
                        // Most often a message past limits.max_message_bytes; the socket cannot
                        // be read further, so say why and close.
                        let error = ErrorBody {
                            code: "too_large".into(),
                            message: format!("the stream cannot continue: {e}"),
                            field: None,
                        };
                        session.counters.refused("too_large");
                        let _ = sink.send(json(&ServerMessage::Error { error })).await;
                        let _ = sink.send(Message::Close(Some(CloseFrame {
                            code: close_code::SIZE,
                            reason: Utf8Bytes::from_static("message too large or malformed"),
                        }))).await;
                        break;
                    }
                };
                if let Some(error) = reply
                    && sink.send(json(&ServerMessage::Error { error })).await.is_err()
                {
                    break;
                }
            }
            out = subscription.outputs.recv() => match out {
                Ok(out) => {
                    if let Output::Closed { state, reason } = out.as_ref() {
                        let _ = sink.send(close(*state, reason)).await;
                        break;
                    }
                    if let Some(m) = encode(&out, &selection, me)
                        && sink.send(m).await.is_err()
                    {
                        break;
                    }
                }
                Err(RecvError::Lagged(n)) => {
                    session.counters.output_dropped(n);
                    let warn = ServerMessage::Event(SessionEvent::Warning {
                        code: "output_dropped".into(),
                        message: format!("this client fell behind and missed {n} output messages"),
                    });
                    if sink.send(json(&warn)).await.is_err() {
                        break;
                    }
                }
                Err(RecvError::Closed) => break,
            },
        }
    }
    tracing::debug!(session = %session.id(), client = me, "stream closed");
    drop(guard);
}

fn welcome(s: &SessionHandle) -> ServerMessage {
    let layout = s.layout();
    let limits = s.limits();
    ServerMessage::Welcome {
        session: s.id().to_string(),
        protocol: PROTOCOL_VERSION,
        sample_rate: s.sample_rate(),
        channels: s.channels(),
        arrays: layout.arrays.iter().map(|a| a.id.clone()).collect(),
        cameras: layout.cameras.iter().map(|c| c.id.clone()).collect(),
        next_sample: s.next_sample(),
        next_step: s.next_step(),
        step_s: s.step_s(),
        audio_delay_samples: s.audio_delay_samples(),
        queue_depth: limits.queue_depth,
        max_audio_samples: limits.max_audio_samples,
        max_message_bytes: limits.max_message_bytes,
        max_measurements: limits.max_measurements,
    }
}

fn json(m: &ServerMessage) -> Message {
    Message::Text(serde_json::to_string(m).unwrap_or_default().into())
}

fn close(state: SessionState, reason: &str) -> Message {
    let code = match (state, reason) {
        (SessionState::Failed, _) => close_code::ERROR,
        (_, "server shutting down") => close_code::AWAY,
        _ => close_code::NORMAL,
    };
    // A close reason holds at most 123 bytes.
    let mut end = reason.len().min(123);
    while !reason.is_char_boundary(end) {
        end -= 1;
    }
    Message::Close(Some(CloseFrame {
        code,
        reason: reason[..end].to_string().into(),
    }))
}

/// A binary message: one audio frame.
fn on_audio(s: &SessionHandle, me: ClientId, bytes: &[u8]) -> Option<ErrorBody> {
    match AudioFrame::decode(bytes, s.limits().max_audio_samples) {
        Err(e) => {
            s.counters.refused(e.code);
            Some(ErrorBody {
                code: e.code.to_string(),
                message: e.message,
                field: Some(e.field.to_string()),
            })
        }
        Ok(frame) => s.submit(me, Input::Audio(frame)).err().map(|r| r.to_body()),
    }
}

/// A text message: JSON.
fn on_text(
    s: &SessionHandle,
    me: ClientId,
    text: &str,
    selection: &mut OutputSelection,
    subscription: &mut Subscription,
) -> Option<ErrorBody> {
    let msg = match ClientMessage::parse(text) {
        Ok(m) => m,
        Err(e) => {
            s.counters.refused(&e.code);
            return Some(e);
        }
    };
    let input = match msg {
        ClientMessage::Hello { client, outputs } => {
            tracing::debug!(session = %s.id(), client = me, name = %client, "hello");
            subscription.want(&outputs);
            *selection = outputs;
            return None;
        }
        ClientMessage::Finish {} => {
            s.finish("input finished");
            return None;
        }
        ClientMessage::Detections { t, camera, boxes } => {
            crate::protocol::inbound::detection_frame(&s.layout(), t, &camera, &boxes)
                .map(Input::Detections)
        }
        ClientMessage::AudioMeasurements(line) => {
            crate::protocol::inbound::device_frame(&s.layout(), &line).map(Input::AudioMeasurements)
        }
    };
    match input {
        Ok(input) => s.submit(me, input).err().map(|r| r.to_body()),
        Err(e) => {
            s.counters.refused(e.code);
            Some(super::session::Rejection::from(e).to_body())
        }
    }
}

/// The wire message of an output for this client, if its selection wants it.
fn encode(out: &Arc<Output>, sel: &OutputSelection, me: ClientId) -> Option<Message> {
    match out.as_ref() {
        Output::Tracks(snap) if sel.tracks => Some(json(&ServerMessage::Tracks {
            step: snap.step,
            t: snap.t,
            tracks: snap.tracks.clone(),
        })),
        Output::Measurements(line) if sel.measurements => {
            Some(json(&ServerMessage::Measurements(line.clone())))
        }
        Output::Audio {
            label,
            first_sample,
            samples,
        } => {
            let a = sel.audio.as_ref()?;
            if a.labels.as_ref().is_some_and(|l| !l.contains(label)) {
                return None;
            }
            let frame = LabelAudioFrame {
                label: *label,
                first_sample: *first_sample,
                samples: samples.clone(),
                encoding: a.format,
            };
            Some(Message::Binary(frame.encode().into()))
        }
        Output::Event(e) if sel.events => Some(json(&ServerMessage::Event(e.clone()))),
        Output::Error { to, error } if to.is_none_or(|c| c == me) => {
            Some(json(&ServerMessage::Error {
                error: error.clone(),
            }))
        }
        _ => None,
    }
}
