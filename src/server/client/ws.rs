//! The WebSocket streamer: opens a session's stream, sends a feed paced like a live client, and
//! collects what comes back until the session closes the stream.

use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::http::HeaderValue;

use crate::protocol::{ClientMessage, OutputSelection, ServerMessage};

use super::{ClientError, FeedItem, FeedMessage, Pacer, Received, StreamOptions, cerr};

/// Takes one WebSocket message; `false` once the stream is closed.
fn take(got: &mut Received, msg: Message) -> bool {
    match msg {
        Message::Text(t) => got.take_text(t.as_bytes()),
        Message::Binary(b) => got.take_binary(&b),
        Message::Close(c) => {
            got.close = Some(c.map_or((1005, String::new()), |c| {
                (u16::from(c.code), c.reason.to_string())
            }));
            return false;
        }
        _ => {}
    }
    true
}

type Ws = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<TcpStream>>;

/// Opens a session's stream (`ws://host:port/v1/sessions/{id}/stream`) with a bearer token.
pub async fn connect(url: &str, token: &str) -> Result<Ws, ClientError> {
    let mut req = url.into_client_request().map_err(cerr)?;
    let auth = HeaderValue::from_str(&format!("Bearer {token}")).map_err(cerr)?;
    req.headers_mut().insert("authorization", auth);
    let (ws, _) = tokio_tungstenite::connect_async(req).await.map_err(cerr)?;
    Ok(ws)
}

/// Streams `feed` into the session at `url` and collects what comes back, until the session
/// closes the stream (after `finish`) or the client disconnects on purpose.
pub async fn stream_feed(
    url: &str,
    token: &str,
    feed: &[FeedItem],
    opts: &StreamOptions,
) -> Result<Received, ClientError> {
    let ws = connect(url, token).await?;
    tokio::time::timeout(opts.timeout, drive(ws, feed, opts))
        .await
        .map_err(|_| ClientError(format!("no end of stream within {:?}", opts.timeout)))?
}

/// Listens to a session without sending input, until it closes the stream; `ready` is told
/// once the welcome has arrived (from then on nothing the session produces is missed).
pub async fn listen(
    url: &str,
    token: &str,
    outputs: OutputSelection,
    timeout: Duration,
    ready: Option<tokio::sync::oneshot::Sender<()>>,
) -> Result<Received, ClientError> {
    let mut ws = connect(url, token).await?;
    let hello = ClientMessage::Hello {
        client: "listener".into(),
        outputs,
    };
    ws.send(Message::text(serde_json::to_string(&hello).map_err(cerr)?))
        .await
        .map_err(cerr)?;
    let mut got = Received::default();
    let run = async {
        let mut ready = ready;
        while let Some(m) = ws.next().await {
            if let Some(r) = ready.take() {
                let _ = r.send(());
            }
            if !take(&mut got, m.map_err(cerr)?) {
                break;
            }
        }
        Ok::<(), ClientError>(())
    };
    tokio::time::timeout(timeout, run)
        .await
        .map_err(|_| ClientError("listener timed out".into()))??;
    Ok(got)
}

/// Reads the welcome (into `got`) and answers with the hello asking for `opts.outputs` and the
/// tracks; returns the session's sample rate, step and the step it runs next.
async fn handshake(
    ws: &mut Ws,
    got: &mut Received,
    opts: &StreamOptions,
) -> Result<(f64, f64, u64), ClientError> {
    let first = ws
        .next()
        .await
        .ok_or_else(|| ClientError("closed before the welcome".into()))?
        .map_err(cerr)?;
    take(got, first);
    let welcome = match &got.welcome {
        Some(ServerMessage::Welcome {
            sample_rate,
            step_s,
            next_step,
            ..
        }) => (f64::from(*sample_rate), *step_s, *next_step),
        _ => return Err(ClientError("the first message was not a welcome".into())),
    };
    let mut outputs = opts.outputs.clone();
    outputs.tracks = true;
    let hello = ClientMessage::Hello {
        client: "avsep-client".into(),
        outputs,
    };
    ws.send(Message::text(serde_json::to_string(&hello).map_err(cerr)?))
        .await
        .map_err(cerr)?;
    Ok(welcome)
}

async fn drive(
    mut ws: Ws,
    feed: &[FeedItem],
    opts: &StreamOptions,
) -> Result<Received, ClientError> {
    let mut got = Received::default();
    let (sample_rate, step_s, next_step) = handshake(&mut ws, &mut got, opts).await?;
    let stop = opts.disconnect_at.unwrap_or(feed.len()).min(feed.len());
    let mut idx = opts.from.min(stop);
    let sent_audio_end = feed[..idx]
        .iter()
        .rev()
        .find_map(|i| match i.message {
            FeedMessage::Audio { end, .. } => Some(end),
            _ => None,
        })
        .unwrap_or(0);
    let offset_s = feed.get(idx).map_or(0.0, |i| i.due_s);
    let mut pacer = Pacer::new(opts, sample_rate, step_s, offset_s, sent_audio_end);
    let mut finished = false;
    loop {
        if idx == stop && !finished {
            if opts.disconnect_at.is_some() {
                got.sent = idx;
                // Leave as a well-behaved client does: a close frame, then read until the server
                // closes. Dropping the socket with outputs still unread makes the kernel reset
                // the connection, and the server loses the input it had not read yet.
                let _ = ws.close(None).await;
                let drain = async {
                    while let Some(Ok(m)) = ws.next().await {
                        take(&mut got, m);
                    }
                };
                let _ = tokio::time::timeout(Duration::from_secs(5), drain).await;
                return Ok(got);
            }
            let finish = serde_json::to_string(&ClientMessage::Finish {}).map_err(cerr)?;
            ws.send(Message::text(finish)).await.map_err(cerr)?;
            finished = true;
        }
        // A resuming client paces on the steps that ran before it connected as well: waiting
        // for a step the session cannot run without more input would stall both.
        let wait = feed[..stop]
            .get(idx)
            .and_then(|item| pacer.wait(item, got.steps_done(next_step)));
        tokio::select! {
            biased;
            msg = ws.next() => match msg {
                Some(Ok(m)) => if !take(&mut got, m) { break },
                Some(Err(e)) => return Err(cerr(e)),
                None => break,
            },
            _ = tokio::time::sleep(wait.unwrap_or_default()), if wait.is_some() => {
                let item = &feed[idx];
                let m = match &item.message {
                    FeedMessage::Audio { bytes, .. } => Message::binary(bytes.clone()),
                    FeedMessage::Json(t) => Message::text(t.clone()),
                };
                ws.send(m).await.map_err(cerr)?;
                pacer.sent(item);
                idx += 1;
            }
        }
    }
    got.sent = idx;
    Ok(got)
}
