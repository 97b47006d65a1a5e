//! The Zenoh streamer, for devices that speak no HTTP: joins the Zenoh network, creates or
//! inspects a session through the `avsep/sessions/**` queryable, publishes a feed under
//! `avsep/<session>/in/...` (reliable, `CongestionControl::Block`, the session's token as the
//! attachment) and collects `avsep/<session>/out/**` until the session's `closed`. Keys and
//! payloads are those of `protocol::zenoh_keys`, the same bytes the WebSocket carries.

use std::time::{Duration, Instant};

use tokio::sync::mpsc::{UnboundedReceiver, unbounded_channel};
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::CongestionControl;

use crate::protocol::ClientMessage;
use crate::protocol::rest::{CreateSession, ErrorResponse, SessionCreated, SessionInfo};
use crate::protocol::zenoh_keys::{
    SESSIONS_CREATE, input_audio, input_detections, input_doa, input_finish, session_output,
    session_query,
};
use crate::server::zenoh_transport::{ZenohConfig, ZenohMode};

use super::{ClientError, FeedItem, FeedMessage, Pacer, Received, StreamOptions, cerr};

/// How a client joins Zenoh.
#[derive(Debug, Clone)]
pub struct ZenohClientConfig {
    /// `peer` (connects to a server or a router, talks to peers directly) or `client` (through
    /// the router it connects to).
    pub mode: ZenohMode,
    /// Endpoints to connect to, e.g. `tcp/127.0.0.1:7447` (a server or a router).
    pub connect: Vec<String>,
    /// How long to wait for a server to answer a query, and for a session's input subscriber
    /// to become visible (links and declarations take a moment to propagate).
    pub wait: Duration,
}

impl Default for ZenohClientConfig {
    fn default() -> Self {
        Self {
            mode: ZenohMode::Peer,
            connect: vec!["tcp/127.0.0.1:7447".into()],
            wait: Duration::from_secs(20),
        }
    }
}

/// A Zenoh session of a device or client (no listening endpoint, no multicast scouting: it
/// reaches exactly the endpoints it is given).
pub struct ZenohClient {
    z: zenoh::Session,
    wait: Duration,
}

impl ZenohClient {
    /// Joins Zenoh as `cfg` says.
    pub async fn connect(cfg: &ZenohClientConfig) -> Result<Self, ClientError> {
        // The server's own settings type builds the Zenoh configuration, so endpoints are
        // checked (and named in errors) the same way on both sides.
        let settings = ZenohConfig {
            enabled: true,
            mode: cfg.mode,
            connect: cfg.connect.clone(),
            listen: Vec::new(),
            multicast_scouting: false,
            ..ZenohConfig::default()
        };
        settings.validate().map_err(cerr)?;
        let z = zenoh::open(settings.to_zenoh().map_err(cerr)?)
            .await
            .map_err(|e| ClientError(format!("cannot join Zenoh at {:?}: {e}", cfg.connect)))?;
        Ok(Self { z, wait: cfg.wait })
    }

    /// Sends a query until a server answers (an empty answer means no queryable is known yet)
    /// and returns the answer's payload; an error answer becomes the REST error it carries.
    pub async fn query(
        &self,
        key: &str,
        payload: Option<Vec<u8>>,
        attachment: Option<&str>,
    ) -> Result<Vec<u8>, ClientError> {
        let deadline = Instant::now() + self.wait;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let mut get = self.z.get(key).timeout(left.max(Duration::from_secs(1)));
            if let Some(p) = &payload {
                get = get.payload(p.clone());
            }
            if let Some(a) = attachment {
                get = get.attachment(a);
            }
            let replies = get.await.map_err(cerr)?;
            if let Ok(reply) = replies.recv_async().await {
                return match reply.result() {
                    Ok(sample) => Ok(sample.payload().to_bytes().into_owned()),
                    Err(e) => Err(answer_error(key, &e.payload().to_bytes())),
                };
            }
            if Instant::now() >= deadline {
                return Err(ClientError(format!(
                    "no avsep server answered {key} within {:?}",
                    self.wait
                )));
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }

    /// Creates a session through `avsep/sessions/create` (the admin key, when the server has
    /// one, rides as the attachment).
    pub async fn create(
        &self,
        body: &CreateSession,
        admin_key: Option<&str>,
    ) -> Result<SessionCreated, ClientError> {
        let body = serde_json::to_vec(body).map_err(cerr)?;
        let answer = self.query(SESSIONS_CREATE, Some(body), admin_key).await?;
        serde_json::from_slice(&answer).map_err(cerr)
    }

    /// Inspects a session through `avsep/sessions/<id>` (its token or the admin key).
    pub async fn info(&self, session: &str, token: &str) -> Result<SessionInfo, ClientError> {
        let answer = self
            .query(&session_query(session), None, Some(token))
            .await?;
        serde_json::from_slice(&answer).map_err(cerr)
    }

    /// Opens a session's stream: subscribes to its outputs, then waits until the server's
    /// subscriber of its input is visible, so neither the first input nor the first output is
    /// lost.
    pub async fn open(&self, info: &SessionInfo, token: &str) -> Result<ZenohStream, ClientError> {
        let (tx, out) = unbounded_channel();
        let subscriber = self
            .z
            .declare_subscriber(session_output(&info.id))
            .callback(move |s| {
                let _ = tx.send((
                    s.key_expr().as_str().to_string(),
                    s.payload().to_bytes().into_owned(),
                ));
            })
            .await
            .map_err(cerr)?;
        let audio = self
            .z
            .declare_publisher(input_audio(&info.id))
            .congestion_control(CongestionControl::Block)
            .await
            .map_err(cerr)?;
        let deadline = Instant::now() + self.wait;
        while !audio.matching_status().await.map_err(cerr)?.matching() {
            if Instant::now() >= deadline {
                return Err(ClientError(format!(
                    "session {}: its input subscriber never appeared on Zenoh",
                    info.id
                )));
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        Ok(ZenohStream {
            z: self.z.clone(),
            session: info.id.clone(),
            token: token.to_string(),
            sample_rate: f64::from(info.sample_rate),
            step_s: info.step_s,
            out,
            audio,
            _subscriber: subscriber,
        })
    }

    /// Leaves Zenoh.
    pub async fn close(self) {
        if let Err(e) = self.z.close().await {
            tracing::debug!("closing zenoh: {e}");
        }
    }
}

fn answer_error(key: &str, payload: &[u8]) -> ClientError {
    match serde_json::from_slice::<ErrorResponse>(payload) {
        Ok(r) => ClientError(format!(
            "{key}: {}{}: {}",
            r.error.code,
            r.error
                .field
                .map_or(String::new(), |f| format!(" (field {f})")),
            r.error.message
        )),
        Err(_) => ClientError(format!(
            "{key}: error answer {}",
            String::from_utf8_lossy(payload)
        )),
    }
}

/// A feed as a channel (what [`ZenohStream::stream`] reads), for a feed known in advance.
pub fn feed_channel(items: Vec<FeedItem>) -> UnboundedReceiver<FeedItem> {
    let (tx, rx) = unbounded_channel();
    for i in items {
        let _ = tx.send(i);
    }
    rx
}

/// One session's stream over Zenoh.
pub struct ZenohStream {
    z: zenoh::Session,
    session: String,
    token: String,
    sample_rate: f64,
    step_s: f64,
    out: UnboundedReceiver<(String, Vec<u8>)>,
    audio: Publisher<'static>,
    _subscriber: Subscriber<()>,
}

impl ZenohStream {
    /// Publishes one feed message under the session's input key for it.
    pub async fn send(&self, message: &FeedMessage) -> Result<(), ClientError> {
        match message {
            FeedMessage::Audio { bytes, .. } => self
                .audio
                .put(bytes.clone())
                .attachment(self.token.as_str())
                .await
                .map_err(cerr),
            FeedMessage::Json(text) => {
                let key = match ClientMessage::parse(text) {
                    Ok(ClientMessage::Detections { camera, .. }) => {
                        input_detections(&self.session, &camera)
                    }
                    Ok(ClientMessage::AudioMeasurements(line)) => {
                        input_doa(&self.session, &line.array)
                    }
                    Ok(m) => {
                        return Err(ClientError(format!(
                            "{m:?} has no Zenoh input key (only detections and audio_measurements)"
                        )));
                    }
                    Err(e) => {
                        return Err(ClientError(format!("a feed message: {}", e.message)));
                    }
                };
                self.put(&key, text.clone().into_bytes()).await
            }
        }
    }

    async fn put(&self, key: &str, payload: Vec<u8>) -> Result<(), ClientError> {
        self.z
            .put(key, payload)
            .congestion_control(CongestionControl::Block)
            .attachment(self.token.as_str())
            .await
            .map_err(cerr)
    }

    /// Ends the session's input.
    pub async fn finish(&self) -> Result<(), ClientError> {
        self.put(&input_finish(&self.session), Vec::new()).await
    }

    /// Takes one output sample into `got`.
    fn take(&self, got: &mut Received, key: &str, payload: &[u8]) {
        let prefix = format!(
            "{}/{}/out/",
            crate::protocol::zenoh_keys::ROOT,
            self.session
        );
        let Some(rest) = key.strip_prefix(&prefix) else {
            return;
        };
        if rest.starts_with("audio/") {
            got.take_binary(payload);
        } else {
            got.take_text(payload);
        }
    }

    /// Streams `feed` (paced as `opts` says, like the WebSocket client), sends `finish` when the
    /// feed's channel closes, and collects the outputs until the session's `closed`. `observe`
    /// sees what has arrived after each output.
    pub async fn stream(
        &mut self,
        mut feed: UnboundedReceiver<FeedItem>,
        opts: &StreamOptions,
        mut observe: impl FnMut(&Received),
    ) -> Result<Received, ClientError> {
        let mut got = Received::default();
        let mut pacer = Pacer::new(opts, self.sample_rate, self.step_s, 0.0, 0);
        let mut pending: Option<FeedItem> = None;
        let mut feed_open = true;
        let mut finished = false;
        let deadline = tokio::time::Instant::now() + opts.timeout;
        while got.closed.is_none() {
            if pending.is_none() && !feed_open && !finished {
                self.finish().await?;
                finished = true;
            }
            let wait = pending
                .as_ref()
                .and_then(|item| pacer.wait(item, got.steps_done(0)));
            tokio::select! {
                biased;
                out = self.out.recv() => match out {
                    Some((key, payload)) => {
                        self.take(&mut got, &key, &payload);
                        observe(&got);
                    }
                    None => return Err(ClientError("the Zenoh subscriber closed".into())),
                },
                item = feed.recv(), if pending.is_none() && feed_open => match item {
                    Some(item) => pending = Some(item),
                    None => feed_open = false,
                },
                _ = tokio::time::sleep(wait.unwrap_or_default()), if wait.is_some() => {
                    if let Some(item) = pending.take() {
                        self.send(&item.message).await?;
                        pacer.sent(&item);
                        got.sent += 1;
                    }
                }
                _ = tokio::time::sleep_until(deadline) => {
                    return Err(ClientError(format!(
                        "session {}: no end of stream within {:?}",
                        self.session, opts.timeout
                    )));
                }
            }
        }
        Ok(got)
    }
}
