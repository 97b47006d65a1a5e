//! `avsep loadgen`: load test of a running server. Simulates one scene (the uca8 preset by
//! default: 8 microphones, 16 kHz, 3 talkers, one camera), creates N sessions, streams the scene
//! into all of them concurrently (in real time by default), and reports step latency, refused
//! input, memory per session (measured, and the bound the server's memory budget counts) and
//! whether the server held real time. Several counts can be given
//! (`--sessions 10,20,50`) to find the largest that holds.

use std::time::{Duration, Instant};

use clap::Args;

use super::CliError;
use super::client::create_session;
use crate::protocol::rest::{SessionCreated, SessionMetrics};
use crate::protocol::{AudioSelection, OutputSelection, SampleEncoding};
use crate::scene::sim::{PresetOptions, SimConfig, simulate};
use crate::server::client::{
    ClientError, FeedItem, Received, StreamOptions, create_body, http, scene_feed, stream_feed,
};

/// Arguments of `avsep loadgen`.
#[derive(Debug, Args)]
pub struct LoadgenArgs {
    /// Server address (`http://host:port`).
    #[arg(long, default_value = "http://127.0.0.1:8080")]
    pub url: String,
    /// Concurrent sessions; a comma-separated list runs each count in turn.
    #[arg(long, value_delimiter = ',', default_value = "50")]
    pub sessions: Vec<usize>,
    /// Seconds of audio streamed into each session.
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
    /// Pace the streams in real time (the load test); without it, stream as fast as each
    /// session keeps up.
    #[arg(long)]
    pub realtime: bool,
    /// Simulator preset of the scene.
    #[arg(long, default_value = "uca8")]
    pub preset: String,
    /// Talkers in the scene.
    #[arg(long, default_value_t = 3)]
    pub speakers: usize,
    /// Also receive every label's separated audio (i16) on each stream.
    #[arg(long)]
    pub audio_out: bool,
    /// Admin key of the server, if it has one.
    #[arg(long, env = "AVSEP_ADMIN_KEY", hide_env_values = true)]
    pub admin_key: Option<String>,
    /// Target p99 step latency (ms) for the verdict.
    #[arg(long, default_value_t = 20.0)]
    pub target_p99_ms: f64,
    /// Seed of the simulated scene.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Start every stream at the same instant, so that all sessions' steps fall due together
    /// (the worst case). By default the starts are spread evenly over one tracker step, as
    /// clients that join a server independently are.
    #[arg(long)]
    pub lockstep: bool,
}

/// Figures of one run with `sessions` concurrent sessions.
#[derive(Debug, Clone, serde::Serialize)]
pub struct LoadReport {
    /// Concurrent sessions.
    pub sessions: usize,
    /// Largest per-session p99 step latency (ms).
    pub p99_ms_max: f64,
    /// Largest per-session p99 of the pipeline's processing time per step (ms): the compute
    /// alone, without the waiting for a core that `p99_ms_max` includes.
    pub processing_p99_ms_max: f64,
    /// Cores the server process kept busy while the streams ran (its CPU time over wall time).
    pub server_cores: f64,
    /// Median over sessions of the p99 step latency (ms).
    pub p99_ms_median: f64,
    /// Largest step latency seen (ms).
    pub max_ms: f64,
    /// Median real-time factor of the sessions' pipelines.
    pub rtf_median: f64,
    /// Input refused by the server, summed over sessions (queue_full and others).
    pub refused: u64,
    /// Output messages clients missed.
    pub output_dropped: u64,
    /// Server resident memory growth per session (MB).
    pub mb_per_session: f64,
    /// The memory bound the server's budget counts per session (MB), for comparison.
    pub bound_mb_per_session: f64,
    /// Wall time of the run (s).
    pub wall_s: f64,
    /// Every stream ended normally with every step.
    pub complete: bool,
    /// No input refused and p99 below one step period: the server kept up.
    pub holds_real_time: bool,
    /// p99 within the target as well.
    pub meets_target: bool,
}

fn prom_value(text: &str, name: &str) -> Option<f64> {
    text.lines()
        .find(|l| l.starts_with(name) && l[name.len()..].starts_with(' '))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse().ok())
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Runs the command.
pub fn run(args: LoadgenArgs) -> Result<(), CliError> {
    let addr = args
        .url
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .to_string();
    let opts = PresetOptions {
        duration_s: Some(args.seconds),
        speakers: Some(args.speakers),
        ..Default::default()
    };
    let sim = SimConfig::preset(&args.preset, &opts, args.seed).map_err(CliError::input)?;
    eprintln!(
        "simulating {:.0} s of the {} preset ...",
        args.seconds, args.preset
    );
    let scene = simulate(&sim, args.seed).map_err(CliError::runtime)?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(CliError::runtime)?;
    let mut reports = Vec::new();
    for &n in &args.sessions {
        eprintln!("{n} sessions ...");
        let r = runtime.block_on(run_once(&args, &addr, &scene, n))?;
        println!("{}", serde_json::to_string(&r).map_err(CliError::runtime)?);
        reports.push(r);
    }
    println!(
        "{:>8} {:>10} {:>10} {:>9} {:>8} {:>6} {:>6} {:>8} {:>8} {:>10} {:>6}",
        "sessions",
        "p99max_ms",
        "p99med_ms",
        "proc99_ms",
        "rtf_med",
        "cores",
        "refused",
        "dropped",
        "MB/sess",
        "bound/sess",
        "holds"
    );
    for r in &reports {
        println!(
            "{:>8} {:>10.2} {:>10.2} {:>9.2} {:>8.3} {:>6.2} {:>6} {:>8} {:>8.2} {:>10.2} {:>6}",
            r.sessions,
            r.p99_ms_max,
            r.p99_ms_median,
            r.processing_p99_ms_max,
            r.rtf_median,
            r.server_cores,
            r.refused,
            r.output_dropped,
            r.mb_per_session,
            r.bound_mb_per_session,
            if r.meets_target {
                "yes"
            } else if r.holds_real_time {
                "rt"
            } else {
                "no"
            }
        );
    }
    let best = reports
        .iter()
        .filter(|r| r.holds_real_time)
        .map(|r| r.sessions)
        .max();
    match best {
        Some(n) => println!("largest count that held real time: {n}"),
        None => println!("no count held real time"),
    }
    Ok(())
}

async fn run_once(
    args: &LoadgenArgs,
    addr: &str,
    scene: &crate::scene::Scene,
    n: usize,
) -> Result<LoadReport, CliError> {
    let key = args.admin_key.as_deref();
    let rss = |text: &str| prom_value(text, "avsep_process_resident_memory_bytes").unwrap_or(0.0);
    let before = http(addr, "GET", "/metrics", None, None)
        .await
        .map_err(CliError::runtime)?;
    let cpu = |text: &str| prom_value(text, "avsep_process_cpu_seconds_total").unwrap_or(0.0);
    let rss0 = rss(&before.text());
    let bound = |text: &str| prom_value(text, "avsep_sessions_memory_bound_bytes").unwrap_or(0.0);
    let bound0 = bound(&before.text());
    let sessions = create_sessions(addr, key, scene, n).await?;
    let bound1 = http(addr, "GET", "/metrics", None, None)
        .await
        .map(|m| bound(&m.text()))
        .unwrap_or(bound0);
    // The feed is built before the clock starts: the figures are of the streams alone.
    let (feed, opts) = feed_and_options(args, scene);
    let started = Instant::now();
    let cpu0 = http(addr, "GET", "/metrics", None, None)
        .await
        .map(|m| cpu(&m.text()))
        .unwrap_or(0.0);
    let step = Duration::from_secs_f64(crate::pipeline::PipelineConfig::default().step_s);
    let tasks = spawn_streams(args, addr, &sessions, &feed, &opts, step);
    // Sample the server's memory while the streams run.
    let mut peak = rss0;
    let mut all_done = false;
    while !all_done {
        tokio::time::sleep(Duration::from_millis(500)).await;
        if let Ok(m) = http(addr, "GET", "/metrics", None, None).await {
            peak = peak.max(rss(&m.text()));
        }
        all_done = tasks.iter().all(|t| t.is_finished());
    }
    let wall_s = started.elapsed().as_secs_f64();
    let cpu1 = http(addr, "GET", "/metrics", None, None)
        .await
        .map(|m| cpu(&m.text()))
        .unwrap_or(cpu0);
    let steps_expected = (args.seconds / step.as_secs_f64()).floor() as usize;
    let mut complete = true;
    for t in tasks {
        match t.await {
            Ok(Ok(r)) => complete &= r.close.is_some() && r.tracks.len() >= steps_expected,
            _ => complete = false,
        }
    }
    let m = collect_metrics(addr, key, &sessions).await?;
    let p99_max = m.p99s.iter().copied().fold(0.0, f64::max);
    // A session holds real time while each step's tracks leave within one step.
    let holds = complete && m.refused == 0 && p99_max < step.as_secs_f64() * 1e3;
    Ok(LoadReport {
        sessions: n,
        p99_ms_max: p99_max,
        processing_p99_ms_max: m.processing_p99,
        server_cores: (cpu1 - cpu0) / wall_s.max(1e-9),
        p99_ms_median: median(m.p99s),
        max_ms: m.max_ms,
        rtf_median: median(m.rtfs),
        refused: m.refused,
        output_dropped: m.dropped,
        mb_per_session: (peak - rss0).max(0.0) / n.max(1) as f64 / 1e6,
        bound_mb_per_session: (bound1 - bound0).max(0.0) / n.max(1) as f64 / 1e6,
        wall_s,
        complete,
        holds_real_time: holds,
        meets_target: holds && p99_max <= args.target_p99_ms && m.dropped == 0,
    })
}

/// The scene as the messages every session is sent, and the stream options of a run.
fn feed_and_options(
    args: &LoadgenArgs,
    scene: &crate::scene::Scene,
) -> (std::sync::Arc<Vec<FeedItem>>, StreamOptions) {
    let feed = std::sync::Arc::new(scene_feed(scene, 1024, SampleEncoding::I16));
    let outputs = OutputSelection {
        audio: args.audio_out.then_some(AudioSelection {
            format: SampleEncoding::I16,
            labels: None,
        }),
        ..Default::default()
    };
    let opts = StreamOptions {
        realtime: args.realtime,
        outputs,
        timeout: Duration::from_secs_f64(args.seconds * 3.0 + 60.0),
        ..Default::default()
    };
    (feed, opts)
}

/// Starts streaming `feed` to every session, the starts spread over one step (at once in
/// lockstep or when not paced in real time).
fn spawn_streams(
    args: &LoadgenArgs,
    addr: &str,
    sessions: &[SessionCreated],
    feed: &std::sync::Arc<Vec<FeedItem>>,
    opts: &StreamOptions,
    step: Duration,
) -> Vec<tokio::task::JoinHandle<Result<Received, ClientError>>> {
    let n = sessions.len();
    let mut tasks = Vec::new();
    for (i, s) in sessions.iter().enumerate() {
        let url = format!("ws://{addr}{}", s.stream);
        let (token, feed, opts) = (s.token.clone(), feed.clone(), opts.clone());
        let delay = if args.lockstep || !args.realtime {
            Duration::ZERO
        } else {
            step.mul_f64(i as f64 / n.max(1) as f64)
        };
        tasks.push(tokio::spawn(async move {
            tokio::time::sleep(delay).await;
            stream_feed(&url, &token, &feed, &opts).await
        }));
    }
    tasks
}

/// Creates `n` sessions for the scene's layout.
async fn create_sessions(
    addr: &str,
    key: Option<&str>,
    scene: &crate::scene::Scene,
    n: usize,
) -> Result<Vec<SessionCreated>, CliError> {
    let body = serde_json::to_vec(&create_body(&scene.layout, None)).map_err(CliError::runtime)?;
    let mut sessions = Vec::with_capacity(n);
    for _ in 0..n {
        sessions.push(create_session(addr, key, &body).await?);
    }
    Ok(sessions)
}

/// The sessions' own metrics after a run, gathered across them.
struct Gathered {
    p99s: Vec<f64>,
    rtfs: Vec<f64>,
    processing_p99: f64,
    max_ms: f64,
    refused: u64,
    dropped: u64,
}

/// Reads every session's metrics, then deletes the session.
async fn collect_metrics(
    addr: &str,
    key: Option<&str>,
    sessions: &[SessionCreated],
) -> Result<Gathered, CliError> {
    let mut g = Gathered {
        p99s: Vec::new(),
        rtfs: Vec::new(),
        processing_p99: 0.0,
        max_ms: 0.0,
        refused: 0,
        dropped: 0,
    };
    for s in sessions {
        let path = format!("/v1/sessions/{}/metrics", s.id);
        let r = http(addr, "GET", &path, Some(&s.token), None)
            .await
            .map_err(CliError::runtime)?;
        let m: SessionMetrics = r.json().map_err(CliError::runtime)?;
        g.p99s.push(m.step_latency_ms.p99);
        g.processing_p99 = g.processing_p99.max(m.step_processing_ms.p99);
        g.rtfs.push(m.real_time_factor);
        g.max_ms = g.max_ms.max(m.step_latency_ms.max);
        g.refused += m.refused.values().sum::<u64>();
        g.dropped += m.output_dropped;
        let del = format!("/v1/sessions/{}", s.id);
        let _ = http(addr, "DELETE", &del, Some(key.unwrap_or(&s.token)), None).await;
    }
    Ok(g)
}
