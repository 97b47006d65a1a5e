//! The client side of the API, for `avsep client stream`, `avsep loadgen`, the edge example, the
//! end-to-end tests and scripts: a minimal HTTP/1.1 request helper, and streamers that feed a
//! scene into a session in the order the offline runner pushes it (so a streamed session
//! computes what `avsep process` computes), paced in real time or as fast as the session keeps
//! up, over WebSocket ([`stream_feed`]) or Zenoh ([`ZenohClient`]).

mod feed;
mod http;
mod ws;
mod zenoh_client;

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

pub use feed::{FeedItem, FeedMessage, create_body, feed_from, resume_index, scene_feed};
pub use http::{HttpResponse, http};
pub use ws::{connect, listen, stream_feed};
pub use zenoh_client::{ZenohClient, ZenohClientConfig, ZenohStream, feed_channel};

use crate::label::Label;
use crate::protocol::rest::TracksSnapshot;
use crate::protocol::zenoh_keys::ClosedMessage;
use crate::protocol::{ErrorBody, LabelAudioFrame, OutputSelection, ServerMessage, SessionEvent};
use crate::scene::format::AudioMeasurementLine;

/// A client-side failure (connection, protocol, unexpected answer).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct ClientError(pub String);

fn cerr(e: impl std::fmt::Display) -> ClientError {
    ClientError(e.to_string())
}

/// How to stream a feed.
#[derive(Debug, Clone)]
pub struct StreamOptions {
    /// Send each message at its due time (else as fast as the session keeps up).
    pub realtime: bool,
    /// Without pacing: how far (s of audio) the client may run ahead of the last step it saw,
    /// which keeps its messages within the session's queue.
    pub max_lead_s: f64,
    /// Outputs to ask for (tracks are always asked for: they pace the client). Zenoh publishes
    /// every output; there the selection does not apply.
    pub outputs: OutputSelection,
    /// Send items from this index (resuming; WebSocket only).
    pub from: usize,
    /// Stop after this index and drop the connection without finishing (simulating a client
    /// that goes away; WebSocket only); `None` sends everything and then `finish`.
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

/// When the next feed item may go: at its due time when pacing in real time, else as soon as the
/// audio sent stays within `max_lead_s` of the last step the session reported. Both streamers
/// use it, so a Zenoh device paces itself exactly as a WebSocket client does.
struct Pacer {
    realtime: bool,
    step_samples: u64,
    max_lead: u64,
    /// Due time of the first item sent (a resuming client starts its clock there).
    offset_s: f64,
    started: Instant,
    sent_audio_end: u64,
}

impl Pacer {
    fn new(
        opts: &StreamOptions,
        sample_rate: f64,
        step_s: f64,
        offset_s: f64,
        sent_audio_end: u64,
    ) -> Self {
        Self {
            realtime: opts.realtime,
            step_samples: (step_s * sample_rate).round() as u64,
            max_lead: (opts.max_lead_s * sample_rate) as u64,
            offset_s,
            started: Instant::now(),
            sent_audio_end,
        }
    }

    /// How long to wait before sending `item` once `steps_done` steps have been reported;
    /// `None` while it must wait for more steps.
    fn wait(&self, item: &FeedItem, steps_done: u64) -> Option<Duration> {
        if self.realtime {
            let due = Duration::from_secs_f64((item.due_s - self.offset_s).max(0.0));
            return Some(due.saturating_sub(self.started.elapsed()));
        }
        let is_audio = matches!(item.message, FeedMessage::Audio { .. });
        let processed = steps_done * self.step_samples;
        (!is_audio || self.sent_audio_end <= processed + self.max_lead).then_some(Duration::ZERO)
    }

    /// Records that `item` went out.
    fn sent(&mut self, item: &FeedItem) {
        if let FeedMessage::Audio { end, .. } = item.message {
            self.sent_audio_end = end;
        }
    }
}

/// Everything a client received.
#[derive(Debug, Clone, Default)]
pub struct Received {
    /// The welcome (WebSocket only).
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
    /// The close frame's code and reason (WebSocket).
    pub close: Option<(u16, String)>,
    /// The session's last message (Zenoh).
    pub closed: Option<ClosedMessage>,
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

    /// Steps the session has reported, counting from `next_step` (the welcome's, for a client
    /// that joined late).
    fn steps_done(&self, next_step: u64) -> u64 {
        self.tracks
            .last()
            .map_or(next_step, |t| (t.step + 1).max(next_step))
    }

    /// Separated audio per label, laid out on the input's sample axis (`len` samples); samples
    /// flushed past the input's end are left out.
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

    /// Takes a JSON message of the server (WebSocket text, or a Zenoh JSON payload).
    fn take_text(&mut self, text: &[u8]) {
        match serde_json::from_slice::<ServerMessage>(text) {
            Ok(ServerMessage::Tracks { step, t, tracks }) => {
                self.tracks.push(TracksSnapshot { step, t, tracks })
            }
            Ok(w @ ServerMessage::Welcome { .. }) => self.welcome = Some(w),
            Ok(ServerMessage::Measurements(m)) => self.measurements.push(m),
            Ok(ServerMessage::Event(e)) => self.events.push(e),
            Ok(ServerMessage::Error { error }) => self.errors.push(error),
            Err(e) => match serde_json::from_slice::<ClosedMessage>(text) {
                Ok(c) => self.closed = Some(c),
                Err(_) => self.errors.push(ErrorBody {
                    code: "client_parse".into(),
                    message: e.to_string(),
                    field: None,
                }),
            },
        }
    }

    /// Takes a binary separated-audio frame.
    fn take_binary(&mut self, bytes: &[u8]) {
        match LabelAudioFrame::decode(bytes) {
            Ok(f) => self.audio.push(f),
            Err(e) => self.errors.push(ErrorBody {
                code: "client_parse".into(),
                message: e.to_string(),
                field: Some(e.field.into()),
            }),
        }
    }
}
