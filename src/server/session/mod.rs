//! One live session, independent of any transport: a bounded queue into its pipeline's worker
//! thread, a broadcast of everything the pipeline produces, and what REST reads (state,
//! calibration, track history, metrics). WebSocket streams, and later Zenoh, attach through
//! [`SessionHandle`]: `submit` input, `subscribe` to output.

use std::collections::{BTreeMap, VecDeque};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::sync::{Arc, Mutex, RwLock};
use std::time::{Duration, Instant};

use tokio::sync::{broadcast, oneshot};

use crate::geometry::Layout;
use crate::label::Label;
use crate::pipeline::{ConfigError, PipelineConfig};
use crate::protocol::ErrorBody;
use crate::protocol::rest::{SessionState, TracksSnapshot};
use crate::scene::DetectionFrame;

use super::auth;
use super::config::{Execution, Limits};
use super::engine::Engine;
use super::metrics::{ServerMetrics, SessionCounters};
use super::worker;

mod admission;
mod idle;
mod interest;
mod messages;
mod reads;

pub use interest::{Claim, Interest, OptionalOutput, Subscription};
pub use messages::{ControlError, Input, Output, Rejection};

/// Identifies one attached client within its session (errors are addressed to it).
pub type ClientId = u64;

/// A message for the worker.
pub(super) struct Queued {
    pub client: ClientId,
    pub received: Instant,
    pub work: Work,
    /// What it counts against `limits.queue_bytes` (input only).
    pub bytes: usize,
}

/// What the worker does with a message.
pub(super) enum Work {
    Input(Input),
    Recalibrate(Layout, oneshot::Sender<Result<(), ConfigError>>),
    Configure(
        Box<PipelineConfig>,
        oneshot::Sender<Result<(), ConfigError>>,
    ),
}

/// The sending side of the queue, and the audio position it has accepted up to.
struct Inbox {
    tx: Option<SyncSender<Queued>>,
    next_sample: u64,
}

/// Life-cycle state with the reason of its end.
struct Life {
    state: SessionState,
    error: Option<ErrorBody>,
    close_reason: String,
    ended: Option<Instant>,
}

/// What a session is created from.
pub struct SessionSpec {
    /// Session id.
    pub id: String,
    /// Name given by the creator.
    pub name: Option<String>,
    /// Bearer token of the session.
    pub token: String,
    /// Calibrated sensors.
    pub layout: Layout,
    /// Pipeline settings in force.
    pub settings: PipelineConfig,
    /// Tracker step period (s), as the pipeline rounds it.
    pub step_s: f64,
    /// Separated-audio delay (samples) beyond one step.
    pub audio_delay_samples: u64,
    /// Bounds on queues and clients.
    pub limits: Limits,
    /// Threads of the session's work.
    pub execution: Execution,
}

/// One live session's shared state (see the module documentation).
pub struct Session {
    id: String,
    name: Option<String>,
    token: String,
    created_unix_s: f64,
    sample_rate: u32,
    channels: usize,
    step_s: f64,
    audio_delay_samples: u64,
    limits: Limits,
    /// How its work is spread over threads (the separation queue counts in its memory bound).
    execution: Execution,
    layout: RwLock<Arc<Layout>>,
    settings: RwLock<PipelineConfig>,
    inbox: Mutex<Inbox>,
    outputs: broadcast::Sender<Arc<Output>>,
    interest: Arc<Interest>,
    life: Mutex<Life>,
    history: Mutex<VecDeque<TracksSnapshot>>,
    live_labels: Mutex<Vec<Label>>,
    /// The latest accepted frame of each camera (by index), for viewers (the dashboard).
    latest_detections: Mutex<BTreeMap<usize, DetectionFrame>>,
    /// `max_gap_s` of the settings in force, in samples (read for every audio frame).
    max_gap_samples: AtomicU64,
    /// Held by a REST change (calibration, settings) from reading what is in force to its
    /// being applied, so two concurrent changes cannot both start from the same state and the
    /// later silently undo the earlier.
    changes: tokio::sync::Mutex<()>,
    clients: AtomicUsize,
    next_client: AtomicU64,
    last_use: idle::LastUse,
    server: Arc<ServerMetrics>,
    /// The session's counters.
    pub counters: SessionCounters,
}

/// A transport's handle on a session.
#[derive(Clone)]
pub struct SessionHandle(Arc<Session>);

impl std::ops::Deref for SessionHandle {
    type Target = Session;

    fn deref(&self) -> &Session {
        &self.0
    }
}

/// A client's place in a session; leaving drops it.
pub struct ClientGuard {
    session: SessionHandle,
    id: ClientId,
}

impl ClientGuard {
    /// The client's id within its session.
    pub fn id(&self) -> ClientId {
        self.id
    }
}

impl Drop for ClientGuard {
    fn drop(&mut self) {
        self.session.clients.fetch_sub(1, Ordering::AcqRel);
        self.session.last_use.touch(false);
    }
}

fn gap_samples(settings: &PipelineConfig, sample_rate: u32) -> u64 {
    (settings.max_gap_s * f64::from(sample_rate)) as u64
}

fn unix_now() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

impl SessionHandle {
    /// Starts a session: its worker thread drives `engine` from a queue of `limits.queue_depth`.
    pub fn start<E: Engine>(
        spec: SessionSpec,
        engine: E,
        server: Arc<ServerMetrics>,
    ) -> std::io::Result<Self> {
        let (tx, rx): (SyncSender<Queued>, Receiver<Queued>) =
            sync_channel(spec.limits.queue_depth);
        let (outputs, _) = broadcast::channel(spec.limits.output_buffer);
        let max_gap = gap_samples(&spec.settings, spec.layout.sample_rate);
        let session = Arc::new(Session {
            max_gap_samples: AtomicU64::new(max_gap),
            changes: tokio::sync::Mutex::new(()),
            created_unix_s: unix_now(),
            sample_rate: spec.layout.sample_rate,
            channels: spec.layout.channel_count(),
            step_s: spec.step_s,
            audio_delay_samples: spec.audio_delay_samples,
            layout: RwLock::new(Arc::new(spec.layout)),
            settings: RwLock::new(spec.settings),
            inbox: Mutex::new(Inbox {
                tx: Some(tx),
                next_sample: 0,
            }),
            outputs,
            interest: Arc::default(),
            life: Mutex::new(Life {
                state: SessionState::Running,
                error: None,
                close_reason: "input finished".into(),
                ended: None,
            }),
            history: Mutex::new(VecDeque::new()),
            live_labels: Mutex::new(Vec::new()),
            latest_detections: Mutex::new(BTreeMap::new()),
            clients: AtomicUsize::new(0),
            next_client: AtomicU64::new(1),
            last_use: idle::LastUse::new(),
            counters: SessionCounters::new(server.clone()),
            server,
            id: spec.id,
            name: spec.name,
            token: spec.token,
            limits: spec.limits,
            execution: spec.execution.clone(),
        });
        let handle = Self(session);
        let for_worker = handle.clone();
        let execution = spec.execution;
        std::thread::Builder::new()
            .name(format!("session-{}", handle.id))
            .spawn(move || worker::run(engine, for_worker, rx, &execution))?;
        Ok(handle)
    }

    /// Attaches a client (counted against `max_clients_per_session`).
    pub fn attach(&self) -> Result<ClientGuard, Rejection> {
        let max = self.limits.max_clients_per_session;
        let joined = self
            .clients
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |n| {
                (n < max).then_some(n + 1)
            });
        if joined.is_err() {
            return Err(Rejection::new(
                "too_many_clients",
                format!("the session already has {max} clients (limits.max_clients_per_session)"),
            ));
        }
        Ok(ClientGuard {
            session: self.clone(),
            id: self.next_client.fetch_add(1, Ordering::Relaxed),
        })
    }
}

impl Session {
    /// Session id.
    pub fn id(&self) -> &str {
        &self.id
    }

    /// Creation time (Unix seconds).
    pub fn created_unix_s(&self) -> f64 {
        self.created_unix_s
    }

    /// Whether `presented` is this session's token (constant-time comparison).
    pub fn token_matches(&self, presented: &str) -> bool {
        auth::same_secret(&self.token, presented)
    }

    /// Life state.
    pub fn state(&self) -> SessionState {
        self.life.lock().map_or(SessionState::Failed, |l| l.state)
    }

    /// When the session finished or failed, if it did.
    pub fn ended(&self) -> Option<Instant> {
        self.life.lock().ok().and_then(|l| l.ended)
    }

    /// The calibration in force.
    pub fn layout(&self) -> Arc<Layout> {
        self.layout
            .read()
            .map_or_else(|e| e.into_inner().clone(), |l| l.clone())
    }

    /// The settings in force.
    pub fn settings(&self) -> PipelineConfig {
        self.settings
            .read()
            .map_or_else(|e| e.into_inner().clone(), |s| s.clone())
    }

    /// Audio sample rate (Hz).
    pub fn sample_rate(&self) -> u32 {
        self.sample_rate
    }

    /// Channels an audio frame must carry.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Tracker step period (s).
    pub fn step_s(&self) -> f64 {
        self.step_s
    }

    /// Separated-audio delay beyond one step (samples).
    pub fn audio_delay_samples(&self) -> u64 {
        self.audio_delay_samples
    }

    /// The session's limits.
    pub fn limits(&self) -> &Limits {
        &self.limits
    }

    /// Connected clients.
    pub fn clients(&self) -> usize {
        self.clients.load(Ordering::Acquire)
    }

    /// Index of the next audio sample frame the session accepts (a resuming client sends from
    /// here).
    pub fn next_sample(&self) -> u64 {
        self.inbox.lock().map_or(0, |i| i.next_sample)
    }

    /// Index of the next tracker step the pipeline will report (0 before the first).
    pub fn next_step(&self) -> u64 {
        self.history
            .lock()
            .ok()
            .and_then(|h| h.back().map(|s| s.step + 1))
            .unwrap_or(0)
    }

    /// Labels of the tracks that exist now.
    pub fn live_labels(&self) -> Vec<Label> {
        self.live_labels
            .lock()
            .map(|l| l.clone())
            .unwrap_or_default()
    }

    /// A receiver of everything the session produces from now on, counted as wanting every
    /// output until it says what it wants.
    pub fn subscribe(&self) -> Subscription {
        Subscription::new(self.outputs.subscribe(), self.interest.clone())
    }

    /// Which optional outputs some subscriber wants (the worker skips the others).
    pub fn interest(&self) -> &Interest {
        &self.interest
    }

    /// Ends the input: the worker processes what is queued, flushes, and closes every stream
    /// with `reason`. Later input is refused.
    pub fn finish(&self, reason: &str) {
        // The reason goes in before the queue closes: the worker may see the closed queue,
        // flush and read the reason at once.
        if let Ok(mut life) = self.life.lock()
            && life.state == SessionState::Running
        {
            life.state = SessionState::Finishing;
            life.close_reason = reason.to_string();
        }
        if let Ok(mut inbox) = self.inbox.lock() {
            inbox.tx = None;
        }
    }

    async fn control(
        &self,
        make: impl FnOnce(oneshot::Sender<Result<(), ConfigError>>) -> Work,
    ) -> Result<(), ControlError> {
        let (tx, rx) = oneshot::channel();
        {
            let inbox = self.inbox.lock().map_err(|_| ControlError::Ended)?;
            self.enqueue(&inbox, 0, make(tx))
                .map_err(ControlError::Rejected)?;
        }
        let wait = Duration::from_secs_f64(self.limits.control_timeout_s);
        match tokio::time::timeout(wait, rx).await {
            Err(_) => Err(ControlError::Timeout),
            Ok(Err(_)) => Err(ControlError::Ended),
            Ok(Ok(r)) => r.map_err(ControlError::Invalid),
        }
    }

    /// Replaces the calibration; the pipeline applies it after the input queued before it, at
    /// its next step, keeping its tracks.
    pub async fn recalibrate(&self, layout: Layout) -> Result<(), ControlError> {
        self.control(|tx| Work::Recalibrate(layout, tx)).await
    }

    /// Waits for the session's other REST changes to finish; hold the guard from reading the
    /// calibration or settings in force until the change built on them is applied.
    pub async fn begin_change(&self) -> tokio::sync::MutexGuard<'_, ()> {
        self.changes.lock().await
    }

    /// Changes settings that can change live (others are refused, naming the field).
    pub async fn configure(&self, settings: PipelineConfig) -> Result<(), ControlError> {
        self.control(|tx| Work::Configure(Box::new(settings), tx))
            .await
    }

    // ---- used by the worker ----

    /// Sends an output to every subscriber (none listening is fine).
    pub(super) fn broadcast(&self, out: Output) {
        let _ = self.outputs.send(Arc::new(out));
    }

    /// Records a step's estimate in the history ring and the live labels.
    pub(super) fn record_tracks(&self, snap: &TracksSnapshot) {
        let labels: Vec<Label> = snap.tracks.iter().map(|t| t.label).collect();
        self.counters
            .live_tracks
            .store(labels.len(), Ordering::Relaxed);
        if let Ok(mut l) = self.live_labels.lock() {
            *l = labels;
        }
        if let Ok(mut h) = self.history.lock() {
            if h.len() == self.limits.history_steps {
                h.pop_front();
            }
            h.push_back(snap.clone());
        }
    }

    /// The calibration the pipeline now uses.
    pub(super) fn set_layout(&self, layout: Layout) {
        if let Ok(mut l) = self.layout.write() {
            *l = Arc::new(layout);
        }
    }

    /// The settings the pipeline now uses.
    pub(super) fn set_settings(&self, settings: PipelineConfig) {
        self.max_gap_samples
            .store(gap_samples(&settings, self.sample_rate), Ordering::Relaxed);
        if let Ok(mut s) = self.settings.write() {
            *s = settings;
        }
    }

    /// The worker has flushed everything: the session is finished.
    pub(super) fn close_finished(&self) {
        let reason = match self.life.lock() {
            Ok(mut life) => {
                life.state = SessionState::Finished;
                life.ended = Some(Instant::now());
                life.close_reason.clone()
            }
            Err(_) => String::new(),
        };
        self.counters.live_tracks.store(0, Ordering::Relaxed);
        self.broadcast(Output::Closed {
            state: SessionState::Finished,
            reason,
        });
    }

    /// The pipeline panicked: the session fails, its streams get an error and close.
    pub(super) fn close_failed(&self, message: String) {
        if let Ok(mut inbox) = self.inbox.lock() {
            inbox.tx = None;
        }
        let error = ErrorBody {
            code: "session_failed".into(),
            message: format!("the session's pipeline failed: {message}"),
            field: None,
        };
        if let Ok(mut life) = self.life.lock() {
            life.state = SessionState::Failed;
            life.error = Some(error.clone());
            life.ended = Some(Instant::now());
        }
        self.server.session_failed();
        self.counters.live_tracks.store(0, Ordering::Relaxed);
        tracing::error!(session = %self.id, "{}", error.message);
        self.broadcast(Output::Error {
            to: None,
            error: error.clone(),
        });
        self.broadcast(Output::Closed {
            state: SessionState::Failed,
            reason: error.message,
        });
    }
}
