//! The client side of the API, for `avsep loadgen`, the end-to-end tests and scripts: a minimal
//! HTTP/1.1 request helper, and a WebSocket streamer that feeds a scene into a session in the
//! order the offline runner pushes it (so a streamed session computes what `avsep process`
//! computes), paced in real time or as fast as the session keeps up.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::http::HeaderValue;

use crate::geometry::Layout;
use crate::label::Label;
use crate::pipeline::PipelineConfig;
use crate::protocol::rest::{CreateSession, TracksSnapshot};
use crate::protocol::{
    AudioFrame, ClientMessage, ErrorBody, LabelAudioFrame, OutputSelection, SampleEncoding,
    ServerMessage, SessionEvent,
};
use crate::scene::Scene;
use crate::scene::convert::{array_to_file, camera_to_file};
use crate::scene::format::{AudioMeasurementLine, BoxFile, DoaFile, RegionFile};

/// A client-side failure (connection, protocol, unexpected answer).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct ClientError(pub String);

fn cerr(e: impl std::fmt::Display) -> ClientError {
    ClientError(e.to_string())
}

/// An HTTP answer.
#[derive(Debug, Clone)]
pub struct HttpResponse {
    /// Status code.
    pub status: u16,
    /// Body bytes.
    pub body: Vec<u8>,
}

impl HttpResponse {
    /// The body parsed as JSON.
    pub fn json<T: serde::de::DeserializeOwned>(&self) -> Result<T, ClientError> {
        serde_json::from_slice(&self.body).map_err(|e| {
            ClientError(format!(
                "HTTP {}: {e}: {}",
                self.status,
                String::from_utf8_lossy(&self.body)
            ))
        })
    }

    /// The body as text.
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }
}

/// Sends one HTTP/1.1 request to `addr` (`host:port`) and reads the whole answer
/// (`Connection: close`).
pub async fn http(
    addr: &str,
    method: &str,
    path: &str,
    bearer: Option<&str>,
    body: Option<&[u8]>,
) -> Result<HttpResponse, ClientError> {
    let mut tcp = TcpStream::connect(addr).await.map_err(cerr)?;
    let mut head = format!("{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    if let Some(t) = bearer {
        head.push_str(&format!("Authorization: Bearer {t}\r\n"));
    }
    let body = body.unwrap_or_default();
    if !body.is_empty() || matches!(method, "POST" | "PUT" | "PATCH") {
        head.push_str(&format!(
            "Content-Type: application/json\r\nContent-Length: {}\r\n",
            body.len()
        ));
    }
    head.push_str("\r\n");
    tcp.write_all(head.as_bytes()).await.map_err(cerr)?;
    // A server may answer (413) and close before reading the whole body: read its answer anyway.
    let wrote = tcp.write_all(body).await;
    let mut raw = Vec::new();
    let read = tcp.read_to_end(&mut raw).await;
    if raw.is_empty() {
        wrote.map_err(cerr)?;
        read.map_err(cerr)?;
    }
    parse_response(&raw)
}

fn parse_response(raw: &[u8]) -> Result<HttpResponse, ClientError> {
    let split = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .ok_or_else(|| ClientError("HTTP answer without a header end".into()))?;
    let head = String::from_utf8_lossy(&raw[..split]);
    let status = head
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| ClientError(format!("bad status line in {head:?}")))?;
    let chunked = head.lines().any(|l| {
        let l = l.to_ascii_lowercase();
        l.starts_with("transfer-encoding:") && l.contains("chunked")
    });
    let mut body = raw[split + 4..].to_vec();
    if chunked {
        body = dechunk(&body)?;
    }
    Ok(HttpResponse { status, body })
}

fn dechunk(mut b: &[u8]) -> Result<Vec<u8>, ClientError> {
    let mut out = Vec::new();
    loop {
        let eol = b
            .windows(2)
            .position(|w| w == b"\r\n")
            .ok_or_else(|| ClientError("bad chunk".into()))?;
        let size_text = String::from_utf8_lossy(&b[..eol]);
        let size = usize::from_str_radix(size_text.split(';').next().unwrap_or("").trim(), 16)
            .map_err(|_| ClientError(format!("bad chunk size {size_text:?}")))?;
        b = &b[eol + 2..];
        if size == 0 {
            return Ok(out);
        }
        if b.len() < size + 2 {
            return Err(ClientError("truncated chunk".into()));
        }
        out.extend_from_slice(&b[..size]);
        b = &b[size + 2..];
    }
}

/// The body that creates a session for `layout` with `settings`.
pub fn create_body(layout: &Layout, settings: Option<PipelineConfig>) -> CreateSession {
    CreateSession {
        name: None,
        sample_rate: layout.sample_rate,
        speed_of_sound: layout.speed_of_sound,
        arrays: layout.arrays.iter().map(array_to_file).collect(),
        cameras: layout.cameras.iter().map(camera_to_file).collect(),
        region: layout.region.map(|r| RegionFile {
            min: r.min.into(),
            max: r.max.into(),
        }),
        settings,
    }
}

/// One message of a scene feed.
#[derive(Debug, Clone, PartialEq)]
pub struct FeedItem {
    /// When a live source would have it (s from the start): audio when its block is captured,
    /// a camera frame at its time.
    pub due_s: f64,
    /// The message.
    pub message: FeedMessage,
}

/// A wire message of a feed.
#[derive(Debug, Clone, PartialEq)]
pub enum FeedMessage {
    /// An encoded binary audio frame ending at sample `end`.
    Audio {
        /// The frame's bytes.
        bytes: Vec<u8>,
        /// One past its last sample frame.
        end: u64,
    },
    /// A JSON message.
    Json(String),
}

/// The scene as the messages a live client would send, in the offline runner's order: before
/// each audio block of `block` samples, every camera frame and device measurement with t before
/// the block's end.
pub fn scene_feed(scene: &Scene, block: usize, encoding: SampleEncoding) -> Vec<FeedItem> {
    let layout = &scene.layout;
    let mut side: Vec<(f64, String)> = scene
        .detections
        .iter()
        .map(|d| {
            let msg = ClientMessage::Detections {
                t: d.t,
                camera: layout.cameras[d.camera].id.clone(),
                boxes: d
                    .boxes
                    .iter()
                    .map(|b| BoxFile {
                        x: b.x,
                        y: b.y,
                        w: b.w,
                        h: b.h,
                        score: b.score,
                        point: b.point.map(|p| [p.x, p.y]),
                    })
                    .collect(),
            };
            (d.t, serde_json::to_string(&msg).unwrap_or_default())
        })
        .collect();
    side.extend(scene.audio_measurements.iter().map(|m| {
        let line = AudioMeasurementLine {
            t: m.t,
            array: layout.arrays[m.array].id.clone(),
            doas: m
                .doas
                .iter()
                .map(|d| DoaFile {
                    azimuth: d.azimuth.to_degrees(),
                    elevation: d.elevation.map(f64::to_degrees),
                    energy: d.energy,
                })
                .collect(),
            points: m.points.iter().map(|p| [p.x, p.y, p.z]).collect(),
            activity: m.activity,
        };
        let msg = ClientMessage::AudioMeasurements(line);
        (m.t, serde_json::to_string(&msg).unwrap_or_default())
    }));
    side.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut items = Vec::new();
    let mut next = 0;
    let push_side = |items: &mut Vec<FeedItem>, next: &mut usize, until: f64| {
        while *next < side.len() && side[*next].0 < until {
            items.push(FeedItem {
                due_s: side[*next].0.max(0.0),
                message: FeedMessage::Json(side[*next].1.clone()),
            });
            *next += 1;
        }
    };
    if let Some(audio) = &scene.audio {
        let sr = f64::from(audio.sample_rate);
        let frames = audio.frames();
        let mut start = 0;
        while start < frames {
            let end = (start + block.max(1)).min(frames);
            push_side(&mut items, &mut next, end as f64 / sr);
            let frame = AudioFrame {
                first_sample: start as u64,
                channels: audio.channels,
                samples: audio.samples[start * audio.channels..end * audio.channels].to_vec(),
                encoding,
            };
            items.push(FeedItem {
                due_s: end as f64 / sr,
                message: FeedMessage::Audio {
                    bytes: frame.encode(),
                    end: end as u64,
                },
            });
            start = end;
        }
    }
    push_side(&mut items, &mut next, f64::INFINITY);
    items
}

/// Where a client resumes a feed after reconnecting: just after the audio frame that ends at
/// the welcome's `next_sample`.
pub fn resume_index(feed: &[FeedItem], next_sample: u64) -> usize {
    if next_sample == 0 {
        return 0;
    }
    feed.iter()
        .position(|i| matches!(i.message, FeedMessage::Audio { end, .. } if end == next_sample))
        .map_or(feed.len(), |i| i + 1)
}

/// How to stream a feed.
#[derive(Debug, Clone)]
pub struct StreamOptions {
    /// Send each message at its due time (else as fast as the session keeps up).
    pub realtime: bool,
    /// Without pacing: how far (s of audio) the client may run ahead of the last step it saw,
    /// which keeps its messages within the session's queue.
    pub max_lead_s: f64,
    /// Outputs to ask for (tracks are always asked for: they pace the client).
    pub outputs: OutputSelection,
    /// Send items from this index (resuming).
    pub from: usize,
    /// Stop after this index and drop the connection without finishing (simulating a client
    /// that goes away); `None` sends everything and then `finish`.
    pub disconnect_at: Option<usize>,
    /// Give up after this long.
    pub timeout: Duration,
}

impl Default for StreamOptions {
    fn default() -> Self {
        Self {
            realtime: false,
            max_lead_s: 0.5,
            outputs: OutputSelection::default(),
            from: 0,
            disconnect_at: None,
            timeout: Duration::from_secs(300),
        }
    }
}

/// Everything a client received.
#[derive(Debug, Clone, Default)]
pub struct Received {
    /// The welcome.
    pub welcome: Option<ServerMessage>,
    /// Track estimates in order.
    pub tracks: Vec<TracksSnapshot>,
    /// Separated audio frames in order.
    pub audio: Vec<LabelAudioFrame>,
    /// Measurements.
    pub measurements: Vec<AudioMeasurementLine>,
    /// Events.
    pub events: Vec<SessionEvent>,
    /// Errors addressed to this client or to everyone.
    pub errors: Vec<ErrorBody>,
    /// The close frame's code and reason.
    pub close: Option<(u16, String)>,
    /// Feed items sent.
    pub sent: usize,
}

impl Received {
    /// The welcome's `next_sample`.
    pub fn next_sample(&self) -> Option<u64> {
        match &self.welcome {
            Some(ServerMessage::Welcome { next_sample, .. }) => Some(*next_sample),
            _ => None,
        }
    }

    /// Separated audio per label, laid out on the input's sample axis (`len` samples).
    pub fn audio_by_label(&self, len: usize) -> BTreeMap<Label, Vec<f32>> {
        let mut out: BTreeMap<Label, Vec<f32>> = BTreeMap::new();
        for f in &self.audio {
            let buf = out.entry(f.label).or_insert_with(|| vec![0.0; len]);
            let start = f.first_sample as usize;
            if start < buf.len() {
                let n = f.samples.len().min(buf.len() - start);
                buf[start..start + n].copy_from_slice(&f.samples[..n]);
            }
        }
        out
    }

    fn take(&mut self, msg: Message) -> bool {
        match msg {
            Message::Text(t) => match serde_json::from_str::<ServerMessage>(t.as_str()) {
                Ok(ServerMessage::Tracks { step, t, tracks }) => {
                    self.tracks.push(TracksSnapshot { step, t, tracks })
                }
                Ok(w @ ServerMessage::Welcome { .. }) => self.welcome = Some(w),
                Ok(ServerMessage::Measurements(m)) => self.measurements.push(m),
                Ok(ServerMessage::Event(e)) => self.events.push(e),
                Ok(ServerMessage::Error { error }) => self.errors.push(error),
                Err(e) => self.errors.push(ErrorBody {
                    code: "client_parse".into(),
                    message: e.to_string(),
                    field: None,
                }),
            },
            Message::Binary(b) => {
                if let Ok(f) = LabelAudioFrame::decode(&b) {
                    self.audio.push(f);
                }
            }
            Message::Close(c) => {
                self.close = Some(c.map_or((1005, String::new()), |c| {
                    (u16::from(c.code), c.reason.to_string())
                }));
                return false;
            }
            _ => {}
        }
        true
    }
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
            if !got.take(m.map_err(cerr)?) {
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

async fn drive(
    mut ws: Ws,
    feed: &[FeedItem],
    opts: &StreamOptions,
) -> Result<Received, ClientError> {
    let mut got = Received::default();
    let first = ws
        .next()
        .await
        .ok_or_else(|| ClientError("closed before the welcome".into()))?
        .map_err(cerr)?;
    got.take(first);
    let (sample_rate, step_s, next_step) = match &got.welcome {
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
    let step_samples = (step_s * sample_rate).round() as u64;
    let max_lead = (opts.max_lead_s * sample_rate) as u64;
    let stop = opts.disconnect_at.unwrap_or(feed.len()).min(feed.len());
    let mut idx = opts.from.min(stop);
    let mut sent_audio_end = feed[..idx]
        .iter()
        .rev()
        .find_map(|i| match i.message {
            FeedMessage::Audio { end, .. } => Some(end),
            _ => None,
        })
        .unwrap_or(0);
    let offset_s = feed.get(idx).map_or(0.0, |i| i.due_s);
    let started = Instant::now();
    let mut finished = false;
    loop {
        if idx == stop && !finished {
            if opts.disconnect_at.is_some() {
                got.sent = idx;
                return Ok(got);
            }
            let finish = serde_json::to_string(&ClientMessage::Finish {}).map_err(cerr)?;
            ws.send(Message::text(finish)).await.map_err(cerr)?;
            finished = true;
        }
        // A resuming client paces on the steps that ran before it connected as well: waiting
        // for a step the session cannot run without more input would stall both.
        let steps_done = got
            .tracks
            .last()
            .map_or(next_step, |t| (t.step + 1).max(next_step));
        let processed = steps_done * step_samples;
        let can_send = idx < stop
            && (opts.realtime || sent_audio_end <= processed + max_lead || !is_audio(&feed[idx]));
        let wait = if opts.realtime && idx < stop {
            Duration::from_secs_f64((feed[idx].due_s - offset_s).max(0.0))
                .saturating_sub(started.elapsed())
        } else {
            Duration::ZERO
        };
        tokio::select! {
            biased;
            msg = ws.next() => match msg {
                Some(Ok(m)) => if !got.take(m) { break },
                Some(Err(e)) => return Err(cerr(e)),
                None => break,
            },
            _ = tokio::time::sleep(wait), if can_send => {
                let item = &feed[idx];
                let m = match &item.message {
                    FeedMessage::Audio { bytes, end } => {
                        sent_audio_end = *end;
                        Message::binary(bytes.clone())
                    }
                    FeedMessage::Json(t) => Message::text(t.clone()),
                };
                ws.send(m).await.map_err(cerr)?;
                idx += 1;
            }
        }
    }
    got.sent = idx;
    Ok(got)
}

fn is_audio(i: &FeedItem) -> bool {
    matches!(i.message, FeedMessage::Audio { .. })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn http_answers_parse_plain_and_chunked() {
        let r = parse_response(b"HTTP/1.1 201 Created\r\ncontent-length: 2\r\n\r\n{}").unwrap();
        assert_eq!((r.status, r.text().as_str()), (201, "{}"));
        let r = parse_response(
            b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n3\r\nabc\r\n2\r\nde\r\n0\r\n\r\n",
        )
        .unwrap();
        assert_eq!(r.text(), "abcde");
    }

    /// A session computes bit for bit what the offline run computes only if the layout and the
    /// side messages reach it unchanged. -231.29575740048358 (the projection of the uca8
    /// preset's camera) is one the default serde_json parser reads one ulp off.
    #[test]
    fn layouts_and_feed_messages_cross_the_wire_bit_for_bit() {
        use crate::geometry::{Camera, MicArray, Vec3};
        use crate::scene::convert::layout_from_file;
        use crate::scene::format::{SCENE_FORMAT, SceneFile};
        use nalgebra::Matrix3x4;

        #[rustfmt::skip]
        let p = Matrix3x4::new(
            640.0000000000001, 596.7430540932476, -231.29575740048358, -1482.7585002101262,
            0.0, 104.3722105269681, -726.8469176310197, 1586.538553525007,
            0.0, 0.9324110220206993, -0.3613996209382556, 0.6831898434216785,
        );
        let cam = Camera::from_projection("cam0", 1280.0, 720.0, p, None, None).unwrap();
        let mics = (0..4)
            .map(|i| {
                let a = f64::from(i) * std::f64::consts::FRAC_PI_2 + 0.1;
                Vec3::new(3.0 + 0.05 * a.cos(), 2.5 + 0.05 * a.sin(), 0.75)
            })
            .collect();
        let array = MicArray::new("a0", mics, vec![0, 1, 2, 3]).unwrap();
        let layout = Layout::new(16_000, 343.0, vec![array], vec![cam], None).unwrap();
        let text = serde_json::to_string(&create_body(&layout, None)).unwrap();
        let body: CreateSession = serde_json::from_str(&text).unwrap();
        let file = SceneFile {
            format: SCENE_FORMAT.into(),
            sample_rate: body.sample_rate,
            speed_of_sound: body.speed_of_sound,
            audio: None,
            arrays: body.arrays,
            cameras: body.cameras,
            region: body.region,
            detections: None,
            audio_measurements: None,
            truth: None,
        };
        assert_eq!(layout_from_file(&file).unwrap(), layout);

        let sent = ClientMessage::Detections {
            t: 0.1 + 0.2,
            camera: "cam0".into(),
            boxes: vec![BoxFile {
                x: -231.29575740048358,
                y: 1.0 / 3.0,
                w: 2.0f64.sqrt(),
                h: 1e-7 / 3.0,
                score: Some(0.9324110220206993),
                point: None,
            }],
        };
        let text = serde_json::to_string(&sent).unwrap();
        assert_eq!(crate::server::stream::parse_message(&text).unwrap(), sent);
    }
}
