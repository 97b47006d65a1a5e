//! Metrics: per-session counters and latency windows (the session's `/metrics` JSON) and their
//! aggregate in Prometheus text format (`/metrics`). Every server has its own Prometheus registry,
//! so several servers can live in one process (tests).

use std::collections::{BTreeMap, VecDeque};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::time::Duration;

use prometheus::{
    Encoder, Gauge, Histogram, HistogramOpts, IntCounter, IntCounterVec, IntGauge, IntGaugeVec,
    Opts, Registry, TextEncoder,
};

use crate::pipeline::SensorClutter;
use crate::protocol::rest::{FrameCounts, LatencySummary};

/// Steps kept in a session's latency windows.
const LATENCY_WINDOW: usize = 4096;

/// Kinds of inbound messages, as counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameKind {
    /// Binary audio.
    Audio,
    /// Camera detections.
    Detections,
    /// Device measurements.
    AudioMeasurements,
}

impl FrameKind {
    fn as_str(self) -> &'static str {
        match self {
            Self::Audio => "audio",
            Self::Detections => "detections",
            Self::AudioMeasurements => "audio_measurements",
        }
    }
}

/// The server-wide collectors.
pub struct ServerMetrics {
    registry: Registry,
    counters: RunCounters,
    gauges: ReadGauges,
}

/// Collectors the sessions count into as they run.
struct RunCounters {
    frames_in: IntCounterVec,
    refused: IntCounterVec,
    output_dropped: IntCounter,
    steps: IntCounter,
    step_latency: Histogram,
    step_processing: Histogram,
    audio_seconds: prometheus::Counter,
    processing_seconds: prometheus::Counter,
    panics: IntCounter,
    sessions_created: IntCounter,
    separation_waits: IntCounter,
}

/// Gauges set from the sessions and the process only when `/metrics` is read.
struct ReadGauges {
    sessions: IntGaugeVec,
    clients: IntGauge,
    queue_depth: IntGauge,
    separation_queue_depth: IntGauge,
    live_tracks: IntGauge,
    memory_bound_bytes: IntGauge,
    resident_bytes: IntGauge,
    cpu_seconds: Gauge,
    real_time_factor: Gauge,
}

/// Figures gathered from the sessions when `/metrics` is read.
#[derive(Debug, Clone, Default)]
pub struct Snapshot {
    /// Sessions by state name.
    pub sessions: BTreeMap<&'static str, i64>,
    /// Stream clients connected.
    pub clients: i64,
    /// Messages queued, summed over sessions.
    pub queue_depth: i64,
    /// Steps of separation work queued, summed over sessions.
    pub separation_queue_depth: i64,
    /// Tracks that exist now, summed over sessions.
    pub live_tracks: i64,
    /// Memory the running sessions (pipelines and buffers) may take at most, summed (bytes).
    pub memory_bound_bytes: i64,
}

fn latency_buckets() -> Vec<f64> {
    vec![
        0.0005, 0.001, 0.002, 0.005, 0.01, 0.015, 0.02, 0.03, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0,
    ]
}

/// A histogram of step times on the latency buckets.
fn latency_histogram(name: &str, help: &str) -> Result<Histogram, prometheus::Error> {
    Histogram::with_opts(HistogramOpts::new(name, help).buckets(latency_buckets()))
}

impl RunCounters {
    /// Creates the counters and histograms, unregistered.
    fn new() -> Result<Self, prometheus::Error> {
        Ok(Self {
            frames_in: IntCounterVec::new(
                Opts::new(
                    "avsep_frames_in_total",
                    "Inbound messages accepted, by kind",
                ),
                &["kind"],
            )?,
            refused: IntCounterVec::new(
                Opts::new(
                    "avsep_frames_refused_total",
                    "Inbound messages refused, by reason",
                ),
                &["reason"],
            )?,
            output_dropped: IntCounter::new(
                "avsep_output_dropped_total",
                "Output messages slow stream clients skipped",
            )?,
            steps: IntCounter::new("avsep_steps_total", "Tracker steps run")?,
            step_latency: latency_histogram(
                "avsep_step_latency_seconds",
                "From arrival of the message completing a step to the broadcast of its tracks",
            )?,
            step_processing: latency_histogram(
                "avsep_step_processing_seconds",
                "Pipeline processing time per tracker step",
            )?,
            audio_seconds: prometheus::Counter::new(
                "avsep_audio_seconds_total",
                "Audio processed (s)",
            )?,
            processing_seconds: prometheus::Counter::new(
                "avsep_processing_seconds_total",
                "Pipeline processing time (s)",
            )?,
            panics: IntCounter::new(
                "avsep_session_failures_total",
                "Sessions whose pipeline panicked",
            )?,
            sessions_created: IntCounter::new("avsep_sessions_created_total", "Sessions created")?,
            separation_waits: IntCounter::new(
                "avsep_separation_waits_total",
                "Steps whose pipeline waited for a full separation queue",
            )?,
        })
    }
}

impl ReadGauges {
    /// Creates the gauges, unregistered.
    fn new() -> Result<Self, prometheus::Error> {
        Ok(Self {
            sessions: IntGaugeVec::new(
                Opts::new("avsep_sessions", "Sessions held, by state"),
                &["state"],
            )?,
            clients: IntGauge::new("avsep_clients", "Stream clients connected")?,
            queue_depth: IntGauge::new(
                "avsep_queue_depth",
                "Inbound messages queued, summed over sessions",
            )?,
            separation_queue_depth: IntGauge::new(
                "avsep_separation_queue_depth",
                "Steps of separation work waiting for their sessions' separation threads, summed over sessions",
            )?,
            live_tracks: IntGauge::new("avsep_live_tracks", "Tracks that exist now")?,
            memory_bound_bytes: IntGauge::new(
                "avsep_sessions_memory_bound_bytes",
                "Memory the running sessions (pipelines and buffers) may take at most, summed: \
                 what limits.max_memory_mb bounds",
            )?,
            resident_bytes: IntGauge::new(
                "avsep_process_resident_memory_bytes",
                "Resident memory of the server process",
            )?,
            cpu_seconds: Gauge::new(
                "avsep_process_cpu_seconds_total",
                "CPU time (user and system) the server process has used since it started",
            )?,
            real_time_factor: Gauge::new(
                "avsep_real_time_factor",
                "Processing time over audio time, all sessions since start",
            )?,
        })
    }
}

impl ServerMetrics {
    /// Registers the collectors in a new registry.
    pub fn new() -> Result<Self, prometheus::Error> {
        let m = Self {
            registry: Registry::new(),
            counters: RunCounters::new()?,
            gauges: ReadGauges::new()?,
        };
        m.register_all()?;
        Ok(m)
    }

    /// Registers every collector with the registry.
    fn register_all(&self) -> Result<(), prometheus::Error> {
        let all: Vec<Box<dyn prometheus::core::Collector>> = vec![
            Box::new(self.counters.frames_in.clone()),
            Box::new(self.counters.refused.clone()),
            Box::new(self.counters.output_dropped.clone()),
            Box::new(self.counters.steps.clone()),
            Box::new(self.counters.step_latency.clone()),
            Box::new(self.counters.step_processing.clone()),
            Box::new(self.counters.audio_seconds.clone()),
            Box::new(self.counters.processing_seconds.clone()),
            Box::new(self.counters.panics.clone()),
            Box::new(self.counters.sessions_created.clone()),
            Box::new(self.gauges.sessions.clone()),
            Box::new(self.gauges.clients.clone()),
            Box::new(self.gauges.queue_depth.clone()),
            Box::new(self.gauges.separation_queue_depth.clone()),
            Box::new(self.counters.separation_waits.clone()),
            Box::new(self.gauges.live_tracks.clone()),
            Box::new(self.gauges.memory_bound_bytes.clone()),
            Box::new(self.gauges.resident_bytes.clone()),
            Box::new(self.gauges.cpu_seconds.clone()),
            Box::new(self.gauges.real_time_factor.clone()),
        ];
        for c in all {
            self.registry.register(c)?;
        }
        Ok(())
    }

    /// Counts a created session.
    pub fn session_created(&self) {
        self.counters.sessions_created.inc();
    }

    /// Counts a session whose pipeline panicked.
    pub fn session_failed(&self) {
        self.counters.panics.inc();
    }

    /// The Prometheus text exposition, with gauges set from `snap`.
    pub fn render(&self, snap: &Snapshot) -> String {
        self.gauges.sessions.reset();
        for state in ["running", "finishing", "finished", "failed"] {
            let n = snap.sessions.get(state).copied().unwrap_or(0);
            self.gauges.sessions.with_label_values(&[state]).set(n);
        }
        self.gauges.clients.set(snap.clients);
        self.gauges.queue_depth.set(snap.queue_depth);
        self.gauges
            .separation_queue_depth
            .set(snap.separation_queue_depth);
        self.gauges.live_tracks.set(snap.live_tracks);
        self.gauges.memory_bound_bytes.set(snap.memory_bound_bytes);
        self.gauges
            .resident_bytes
            .set(resident_memory_bytes().unwrap_or(0) as i64);
        self.gauges
            .cpu_seconds
            .set(process_cpu_seconds().unwrap_or(0.0));
        let audio = self.counters.audio_seconds.get();
        self.gauges.real_time_factor.set(if audio > 0.0 {
            self.counters.processing_seconds.get() / audio
        } else {
            0.0
        });
        let mut out = Vec::new();
        if TextEncoder::new()
            .encode(&self.registry.gather(), &mut out)
            .is_err()
        {
            return String::new();
        }
        String::from_utf8(out).unwrap_or_default()
    }
}

/// Resident memory of this process (`VmRSS` of /proc/self/status), when the system tells.
pub fn resident_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// CPU time (user + system) of this process (`/proc/self/stat`), when the system tells.
pub fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The command name (field 2) may hold spaces; the fields after its closing parenthesis
    // start at field 3, so utime and stime (fields 14 and 15) are the 12th and 13th there.
    let rest = &stat[stat.rfind(')')? + 1..];
    let mut fields = rest.split_whitespace().skip(11);
    let utime: f64 = fields.next()?.parse().ok()?;
    let stime: f64 = fields.next()?.parse().ok()?;
    #[cfg(unix)]
    // SAFETY: sysconf has no preconditions; it returns -1 for an unknown name.
    let ticks = unsafe { libc::sysconf(libc::_SC_CLK_TCK) };
    #[cfg(not(unix))]
    let ticks = 100;
    (ticks > 0).then(|| (utime + stime) / ticks as f64)
}

/// A bounded window of recent values (ms) with percentiles.
#[derive(Debug, Default)]
struct Window(VecDeque<f64>);

impl Window {
    fn push(&mut self, v: f64) {
        if self.0.len() == LATENCY_WINDOW {
            self.0.pop_front();
        }
        self.0.push_back(v);
    }

    fn summary(&self) -> LatencySummary {
        let mut v: Vec<f64> = self.0.iter().copied().collect();
        if v.is_empty() {
            return LatencySummary::default();
        }
        v.sort_by(f64::total_cmp);
        // Nearest-rank percentile.
        let at = |p: f64| v[((p * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1];
        LatencySummary {
            count: v.len(),
            p50: at(0.50),
            p95: at(0.95),
            p99: at(0.99),
            max: v[v.len() - 1],
        }
    }
}

/// One session's counters; each update also feeds the server-wide collectors.
pub struct SessionCounters {
    server: std::sync::Arc<ServerMetrics>,
    audio_in: AtomicU64,
    detections_in: AtomicU64,
    device_in: AtomicU64,
    refused: Mutex<BTreeMap<String, u64>>,
    output_dropped: AtomicU64,
    steps: AtomicU64,
    latency: Mutex<Window>,
    processing: Mutex<Window>,
    processing_ns: AtomicU64,
    audio_samples: AtomicU64,
    /// Messages waiting in the session's queue.
    pub queue_depth: AtomicUsize,
    /// Bytes those messages hold ([`crate::server::session::Input::bytes`]).
    pub queue_bytes: AtomicUsize,
    /// Steps of separation work waiting for the session's separation thread.
    pub separation_queued: AtomicUsize,
    /// Capacity of the separation queue (0 when the session separates on its worker).
    pub separation_capacity: AtomicUsize,
    separation_waits: AtomicU64,
    /// Tracks that exist now.
    pub live_tracks: AtomicUsize,
    /// Labels ever reported.
    pub labels_total: AtomicU64,
    clutter: Mutex<Vec<SensorClutter>>,
}

impl SessionCounters {
    /// Counters of a new session.
    pub fn new(server: std::sync::Arc<ServerMetrics>) -> Self {
        Self {
            server,
            audio_in: AtomicU64::new(0),
            detections_in: AtomicU64::new(0),
            device_in: AtomicU64::new(0),
            refused: Mutex::new(BTreeMap::new()),
            output_dropped: AtomicU64::new(0),
            steps: AtomicU64::new(0),
            latency: Mutex::new(Window::default()),
            processing: Mutex::new(Window::default()),
            processing_ns: AtomicU64::new(0),
            audio_samples: AtomicU64::new(0),
            queue_depth: AtomicUsize::new(0),
            queue_bytes: AtomicUsize::new(0),
            separation_queued: AtomicUsize::new(0),
            separation_capacity: AtomicUsize::new(0),
            separation_waits: AtomicU64::new(0),
            live_tracks: AtomicUsize::new(0),
            labels_total: AtomicU64::new(0),
            clutter: Mutex::new(Vec::new()),
        }
    }

    /// Records the tracker sensors' clutter rates after a message that ran steps.
    pub fn set_clutter(&self, rates: Vec<SensorClutter>) {
        if let Ok(mut c) = self.clutter.lock() {
            *c = rates;
        }
    }

    /// The clutter rates last recorded.
    pub fn clutter(&self) -> Vec<SensorClutter> {
        self.clutter.lock().map(|c| c.clone()).unwrap_or_default()
    }

    /// Counts a message accepted into the queue.
    pub fn accepted(&self, kind: FrameKind) {
        let c = match kind {
            FrameKind::Audio => &self.audio_in,
            FrameKind::Detections => &self.detections_in,
            FrameKind::AudioMeasurements => &self.device_in,
        };
        c.fetch_add(1, Ordering::Relaxed);
        self.server
            .counters
            .frames_in
            .with_label_values(&[kind.as_str()])
            .inc();
    }

    /// Counts a refused message by its error code.
    pub fn refused(&self, code: &str) {
        if let Ok(mut m) = self.refused.lock() {
            *m.entry(code.to_string()).or_default() += 1;
        }
        self.server
            .counters
            .refused
            .with_label_values(&[code])
            .inc();
    }

    /// Counts output messages a client skipped.
    pub fn output_dropped(&self, n: u64) {
        self.output_dropped.fetch_add(n, Ordering::Relaxed);
        self.server.counters.output_dropped.inc_by(n);
    }

    /// Records one tracker step: its latency since the completing message arrived, and the
    /// pipeline time spent on it.
    pub fn step(&self, latency: Duration, processing: Duration) {
        self.steps.fetch_add(1, Ordering::Relaxed);
        self.server.counters.steps.inc();
        self.server
            .counters
            .step_latency
            .observe(latency.as_secs_f64());
        self.server
            .counters
            .step_processing
            .observe(processing.as_secs_f64());
        if let Ok(mut w) = self.latency.lock() {
            w.push(latency.as_secs_f64() * 1e3);
        }
        if let Ok(mut w) = self.processing.lock() {
            w.push(processing.as_secs_f64() * 1e3);
        }
    }

    /// Adds pipeline processing time, and the audio samples that call consumed.
    pub fn processed(&self, time: Duration, samples: u64, sample_rate: u32) {
        self.processing_ns
            .fetch_add(time.as_nanos() as u64, Ordering::Relaxed);
        self.audio_samples.fetch_add(samples, Ordering::Relaxed);
        self.server
            .counters
            .processing_seconds
            .inc_by(time.as_secs_f64());
        if sample_rate > 0 {
            self.server
                .counters
                .audio_seconds
                .inc_by(samples as f64 / sample_rate as f64);
        }
    }

    /// Accepted messages by kind.
    pub fn frames_in(&self) -> FrameCounts {
        FrameCounts {
            audio: self.audio_in.load(Ordering::Relaxed),
            detections: self.detections_in.load(Ordering::Relaxed),
            audio_measurements: self.device_in.load(Ordering::Relaxed),
        }
    }

    /// Refusals by code.
    pub fn refusals(&self) -> BTreeMap<String, u64> {
        self.refused.lock().map(|m| m.clone()).unwrap_or_default()
    }

    /// Counts a step whose pipeline waited because the separation queue was full.
    pub fn separation_waited(&self) {
        self.separation_waits.fetch_add(1, Ordering::Relaxed);
        self.server.counters.separation_waits.inc();
    }

    /// Steps whose pipeline waited for a full separation queue.
    pub fn separation_waits(&self) -> u64 {
        self.separation_waits.load(Ordering::Relaxed)
    }

    /// Output messages skipped by slow clients.
    pub fn dropped(&self) -> u64 {
        self.output_dropped.load(Ordering::Relaxed)
    }

    /// Steps run.
    pub fn steps(&self) -> u64 {
        self.steps.load(Ordering::Relaxed)
    }

    /// Step latency and processing-time percentiles over the recent window.
    pub fn latencies(&self) -> (LatencySummary, LatencySummary) {
        let l = self.latency.lock().map(|w| w.summary()).unwrap_or_default();
        let p = self
            .processing
            .lock()
            .map(|w| w.summary())
            .unwrap_or_default();
        (l, p)
    }

    /// `(audio seconds processed, real-time factor)`.
    pub fn real_time(&self, sample_rate: u32) -> (f64, f64) {
        let audio_s =
            self.audio_samples.load(Ordering::Relaxed) as f64 / f64::from(sample_rate.max(1));
        let busy_s = self.processing_ns.load(Ordering::Relaxed) as f64 * 1e-9;
        (audio_s, if audio_s > 0.0 { busy_s / audio_s } else { 0.0 })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_use_nearest_rank() {
        let mut w = Window::default();
        for v in 1..=100 {
            w.push(f64::from(v));
        }
        let s = w.summary();
        assert_eq!(
            (s.count, s.p50, s.p95, s.p99, s.max),
            (100, 50.0, 95.0, 99.0, 100.0)
        );
        for _ in 0..LATENCY_WINDOW {
            w.push(1.0);
        }
        assert_eq!(w.summary().max, 1.0, "old values leave the window");
    }

    #[test]
    #[cfg(target_os = "linux")]
    fn process_cpu_time_counts_work_done() {
        let before = process_cpu_seconds().expect("linux has /proc/self/stat");
        let t = std::time::Instant::now();
        let mut x = 0u64;
        while t.elapsed() < Duration::from_millis(60) {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
        }
        let after = process_cpu_seconds().expect("linux has /proc/self/stat");
        assert!(after >= before + 0.02, "{before} -> {after}");
    }

    #[test]
    fn session_counters_feed_the_exposition() {
        let server = std::sync::Arc::new(ServerMetrics::new().unwrap());
        let c = SessionCounters::new(server.clone());
        c.accepted(FrameKind::Audio);
        c.refused("queue_full");
        c.refused("queue_full");
        c.step(Duration::from_millis(3), Duration::from_millis(2));
        c.processed(Duration::from_millis(10), 16_000, 16_000);
        assert_eq!(c.refusals()["queue_full"], 2);
        assert!((c.real_time(16_000).1 - 0.01).abs() < 1e-9);
        let text = server.render(&Snapshot::default());
        assert!(
            text.contains("avsep_frames_refused_total{reason=\"queue_full\"} 2"),
            "{text}"
        );
        assert!(text.contains("avsep_frames_in_total{kind=\"audio\"} 1"));
        assert!(text.contains("avsep_step_latency_seconds_bucket"));
        assert!(text.contains("avsep_process_cpu_seconds_total"));
        assert!(text.contains("avsep_sessions{state=\"running\"} 0"));
    }
}
