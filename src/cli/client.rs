//! `avsep client stream`: streams a scene folder to a running server over WebSocket (or Zenoh,
//! as an edge device would), as a meeting-room client would, and writes what comes back as an
//! output folder, so a live run is scored by `avsep eval` exactly like an offline one.

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use clap::{Args, Subcommand};

use super::CliError;
use super::process::load_config;
use super::serve::parse_mode;
use crate::pipeline::PipelineConfig;
use crate::protocol::rest::{SessionCreated, SessionState};
use crate::protocol::{AudioSelection, OutputSelection, SampleEncoding};
use crate::scene::format::TracksLine;
use crate::scene::output::{files, prepare_dir};
use crate::scene::{Audio, JsonlWriter, SampleFormat, Scene, write_json};
use crate::server::client::{
    Received, StreamOptions, ZenohClient, ZenohClientConfig, create_body, feed_channel, http,
    scene_feed, stream_feed,
};
use crate::server::zenoh_transport::ZenohMode;

/// Arguments of `avsep client`.
#[derive(Debug, Args)]
pub struct ClientArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: ClientCommand,
}

/// Client subcommands.
#[derive(Debug, Subcommand)]
pub enum ClientCommand {
    /// Create a session for a scene's sensors, stream its audio and detections, and write the
    /// tracks and separated audio received as an output folder.
    Stream(StreamArgs),
}

/// Arguments of `avsep client stream`.
#[derive(Debug, Args)]
pub struct StreamArgs {
    /// Scene folder to stream.
    pub scene: PathBuf,
    /// Server address (WebSocket streaming).
    #[arg(long, default_value = "http://127.0.0.1:8080")]
    pub url: String,
    /// Stream over Zenoh instead of WebSocket: create the session through the
    /// `avsep/sessions/create` queryable, publish under `avsep/<id>/in/...` and subscribe to
    /// `avsep/<id>/out/**` (no HTTP; `--url` is not used).
    #[arg(long)]
    pub zenoh: bool,
    /// Zenoh endpoints to connect to with `--zenoh` (a server or a router), comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "tcp/127.0.0.1:7447",
        requires = "zenoh"
    )]
    pub zenoh_connect: Vec<String>,
    /// Zenoh role with `--zenoh`: peer or client (through the router in `--zenoh-connect`).
    #[arg(long, value_parser = parse_mode, default_value = "peer", requires = "zenoh")]
    pub zenoh_mode: ZenohMode,
    /// Output folder to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Pace the stream in real time (as a live device would); without it, stream as fast as the
    /// session keeps up.
    #[arg(long)]
    pub realtime: bool,
    /// Pipeline settings for the new session (TOML or JSON, as `avsep process --config`).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Admin key, when the server has one.
    #[arg(long, env = "AVSEP_ADMIN_KEY", hide_env_values = true)]
    pub admin_key: Option<String>,
    /// Samples per channel in each audio message.
    #[arg(long, default_value_t = 1024)]
    pub block: usize,
    /// Give up after this many seconds.
    #[arg(long, default_value_t = 600.0)]
    pub timeout_s: f64,
}

/// Runs `avsep client`.
pub fn run(args: ClientArgs) -> Result<(), CliError> {
    match args.command {
        ClientCommand::Stream(a) => stream(a),
    }
}

fn stream(args: StreamArgs) -> Result<(), CliError> {
    let scene = Scene::load(&args.scene)?;
    let settings = match &args.config {
        Some(p) => Some(load_config(p)?),
        None => None,
    };
    if scene.audio.is_none() {
        return Err(CliError::input(format!(
            "{}: the scene has no audio to stream",
            args.scene.display()
        )));
    }
    let addr = args
        .url
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .to_string();
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(CliError::runtime)?;
    let started = Instant::now();
    let (created, got) = if args.zenoh {
        runtime.block_on(zenoh_create_and_stream(&args, &scene, settings))?
    } else {
        runtime.block_on(create_and_stream(&args, &addr, &scene, settings))?
    };
    let wall_s = started.elapsed().as_secs_f64();
    write_output(&args, &scene, &created, &got, wall_s)?;
    println!(
        "streamed {:.2} s of audio to session {} in {:.2} s; {} steps, {} labels, {} errors -> {}",
        scene.duration(),
        created.id,
        wall_s,
        got.tracks.len(),
        got.audio
            .iter()
            .map(|f| f.label)
            .collect::<BTreeSet<_>>()
            .len(),
        got.errors.len(),
        args.out.display()
    );
    Ok(())
}

/// Creates a session over REST from a serialised creation body (`key`: the admin key, when the
/// server wants one).
pub(super) async fn create_session(
    addr: &str,
    key: Option<&str>,
    body: &[u8],
) -> Result<SessionCreated, CliError> {
    let r = http(addr, "POST", "/v1/sessions", key, Some(body))
        .await
        .map_err(CliError::runtime)?;
    if r.status != 201 {
        return Err(CliError::runtime(format!(
            "creating a session: HTTP {}: {}",
            r.status,
            r.text()
        )));
    }
    r.json().map_err(CliError::runtime)
}

async fn create_and_stream(
    args: &StreamArgs,
    addr: &str,
    scene: &Scene,
    settings: Option<PipelineConfig>,
) -> Result<(SessionCreated, Received), CliError> {
    let body =
        serde_json::to_vec(&create_body(&scene.layout, settings)).map_err(CliError::runtime)?;
    let created = create_session(addr, args.admin_key.as_deref(), &body).await?;
    let feed = scene_feed(scene, args.block.max(1), SampleEncoding::F32);
    let url = format!("ws://{addr}{}", created.stream);
    let got = stream_feed(&url, &created.token, &feed, &stream_options(args))
        .await
        .map_err(CliError::runtime)?;
    Ok((created, got))
}

/// The same over Zenoh: the session is created through the queryable, the feed published under
/// its input keys, and its outputs collected until its `closed` message.
async fn zenoh_create_and_stream(
    args: &StreamArgs,
    scene: &Scene,
    settings: Option<PipelineConfig>,
) -> Result<(SessionCreated, Received), CliError> {
    let client = ZenohClient::connect(&ZenohClientConfig {
        mode: args.zenoh_mode,
        connect: args.zenoh_connect.clone(),
        ..Default::default()
    })
    .await
    .map_err(CliError::runtime)?;
    let body = create_body(&scene.layout, settings);
    let created = client
        .create(&body, args.admin_key.as_deref())
        .await
        .map_err(|e| CliError::runtime(format!("creating a session over Zenoh: {e}")))?;
    let mut stream = client
        .open(&created.session, &created.token)
        .await
        .map_err(CliError::runtime)?;
    let feed = feed_channel(scene_feed(scene, args.block.max(1), SampleEncoding::F32));
    let got = stream
        .stream(feed, &stream_options(args), |_| {})
        .await
        .map_err(CliError::runtime)?;
    drop(stream);
    client.close().await;
    if let Some(c) = &got.closed
        && c.state == SessionState::Failed
    {
        return Err(CliError::runtime(format!(
            "session {} failed: {}",
            created.id, c.reason
        )));
    }
    Ok((created, got))
}

fn stream_options(args: &StreamArgs) -> StreamOptions {
    StreamOptions {
        realtime: args.realtime,
        outputs: OutputSelection {
            measurements: true,
            audio: Some(AudioSelection {
                format: SampleEncoding::F32,
                labels: None,
            }),
            ..Default::default()
        },
        timeout: Duration::from_secs_f64(args.timeout_s.max(1.0)),
        ..Default::default()
    }
}

/// Writes the output folder of scene-format.md from what the stream delivered.
fn write_output(
    args: &StreamArgs,
    scene: &Scene,
    created: &SessionCreated,
    got: &Received,
    wall_s: f64,
) -> Result<(), CliError> {
    let out = &args.out;
    prepare_dir(out)?;
    let mut tracks = JsonlWriter::create(&out.join(files::TRACKS))?;
    for s in &got.tracks {
        tracks.write(&TracksLine {
            t: s.t,
            tracks: s.tracks.clone(),
        })?;
    }
    tracks.finish()?;
    let mut measurements = JsonlWriter::create(&out.join(files::MEASUREMENTS))?;
    for m in &got.measurements {
        measurements.write(m)?;
    }
    measurements.finish()?;
    let frames = scene.audio.as_ref().map_or(0, Audio::frames);
    for (label, samples) in got.audio_by_label(frames) {
        Audio::mono(scene.layout.sample_rate, samples).write(
            &out.join(files::AUDIO_DIR).join(format!("{label}.wav")),
            SampleFormat::F32,
        )?;
    }
    let mut errors: BTreeMap<String, u64> = BTreeMap::new();
    for e in &got.errors {
        *errors.entry(e.code.clone()).or_default() += 1;
    }
    let duration_s = scene.duration();
    let summary = serde_json::json!({
        "scene": scene.dir.display().to_string(),
        "server": if args.zenoh { format!("zenoh {}", args.zenoh_connect.join(",")) } else { args.url.clone() },
        "session": created.id,
        "realtime": args.realtime,
        "duration_s": duration_s,
        "processing_s": wall_s,
        "real_time_factor": if duration_s > 0.0 { wall_s / duration_s } else { 0.0 },
        "steps": got.tracks.len(),
        "errors": errors,
        "events": got.events.len(),
    });
    write_json(&out.join(files::SUMMARY), &summary)?;
    Ok(())
}
