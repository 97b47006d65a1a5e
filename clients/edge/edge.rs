//! The edge device: joins Zenoh (no HTTP), creates its session through the
//! `avsep/sessions/create` queryable unless it is given one, publishes audio frames (from a WAV
//! file, or a sound card with the `soundcard` feature) and camera detections or its own
//! directions of arrival (JSONL files) under `avsep/<session>/in/...`, and prints the tracks the
//! session publishes under `avsep/<session>/out/tracks` as they arrive.

// Paths relative to this file, so the integration test can include it as a module too.
// The live feed serves the sound card only, but is built (and unit-tested) without it too.
#[path = "live.rs"]
#[cfg_attr(not(feature = "soundcard"), allow(dead_code))]
mod live;
#[cfg(feature = "soundcard")]
#[path = "soundcard.rs"]
mod soundcard;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::time::Duration;

use avsep::label::Label;
use avsep::pipeline::PipelineConfig;
use avsep::protocol::rest::{CreateSession, SessionInfo, SessionState, TracksSnapshot};
use avsep::protocol::zenoh_keys::ClosedMessage;
use avsep::protocol::{ClientMessage, ErrorBody, SampleEncoding};
use avsep::scene::convert::layout_from_file;
use avsep::scene::format::{AudioMeasurementLine, DetectionLine, SceneFile, TracksLine};
use avsep::scene::{Audio, JsonlWriter, parse_json, read_jsonl};
use avsep::server::client::{
    FeedItem, Received, StreamOptions, ZenohClient, ZenohClientConfig, create_body, feed_channel,
    feed_from,
};
use avsep::server::zenoh_transport::ZenohMode;
use clap::Parser;

/// Arguments of the edge device.
#[derive(Debug, Parser)]
#[command(
    name = "zenoh-edge",
    about = "An avsep edge device that speaks only Zenoh"
)]
pub struct EdgeArgs {
    /// Zenoh endpoints to connect to (an avsep server or a Zenoh router), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "tcp/127.0.0.1:7447")]
    pub connect: Vec<String>,
    /// Zenoh role: peer, or client (through the router in --connect).
    #[arg(long, value_parser = parse_mode, default_value = "peer")]
    pub mode: ZenohMode,
    /// Join this session instead of creating one (needs --token).
    #[arg(long, requires = "token")]
    pub session: Option<String>,
    /// The session's token (from whoever created it).
    #[arg(long, env = "AVSEP_SESSION_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// Calibration of the session to create: a scene.json, or a body of POST /v1/sessions.
    #[arg(long, required_unless_present = "session")]
    pub calibration: Option<PathBuf>,
    /// Pipeline settings of the session to create (TOML or JSON, as `avsep process --config`).
    #[arg(long)]
    pub settings: Option<PathBuf>,
    /// Admin key, when the server guards session creation with one.
    #[arg(long, env = "AVSEP_ADMIN_KEY", hide_env_values = true)]
    pub admin_key: Option<String>,
    /// Multichannel WAV file to publish (the session's sample rate and channel count).
    #[arg(long, required_unless_present = "soundcard")]
    pub wav: Option<PathBuf>,
    /// Capture from a sound card instead of a WAV file (build with `--features soundcard`).
    #[arg(long, conflicts_with = "wav")]
    pub soundcard: bool,
    /// Sound card to capture from (a cpal device id; the default input device when absent).
    #[arg(long, requires = "soundcard")]
    pub device: Option<String>,
    /// Stop capturing after this many seconds (else at ctrl-c).
    #[arg(long, requires = "soundcard")]
    pub seconds: Option<f64>,
    /// Camera detections to publish (`detections.jsonl` lines of the scene format).
    #[arg(long)]
    pub detections: Option<PathBuf>,
    /// Directions or positions this device measured itself (`audio_measurements.jsonl` lines).
    #[arg(long)]
    pub doa: Option<PathBuf>,
    /// Sample encoding of the audio frames.
    #[arg(long, value_parser = parse_encoding, default_value = "f32")]
    pub format: SampleEncoding,
    /// Samples per channel in each audio frame.
    #[arg(long, default_value_t = 1024)]
    pub block: usize,
    /// Publish a WAV file in real time, as a microphone would (else as fast as the session
    /// keeps up).
    #[arg(long)]
    pub realtime: bool,
    /// Also write the tracks received as a `tracks.jsonl` file.
    #[arg(long)]
    pub tracks_out: Option<PathBuf>,
    /// Print only the summary, not every step.
    #[arg(long)]
    pub quiet: bool,
    /// Give up after this many seconds.
    #[arg(long, default_value_t = 600.0)]
    pub timeout_s: f64,
}

fn parse_mode(s: &str) -> Result<ZenohMode, String> {
    match s {
        "peer" => Ok(ZenohMode::Peer),
        "client" => Ok(ZenohMode::Client),
        _ => Err(format!("{s:?} is not a device's Zenoh mode (peer, client)")),
    }
}

fn parse_encoding(s: &str) -> Result<SampleEncoding, String> {
    match s {
        "f32" => Ok(SampleEncoding::F32),
        "i16" => Ok(SampleEncoding::I16),
        _ => Err(format!("{s:?} is not a sample format (f32, i16)")),
    }
}

/// What a run of the device saw.
#[derive(Debug)]
pub struct EdgeReport {
    /// The session it fed.
    pub session: String,
    /// Tracker steps received.
    pub tracks: Vec<TracksSnapshot>,
    /// Labels seen.
    pub labels: BTreeSet<Label>,
    /// Refusals and failures the session published.
    pub errors: Vec<ErrorBody>,
    /// The session's last message.
    pub closed: Option<ClosedMessage>,
}

/// Runs the device until its session closes.
pub fn run(args: EdgeArgs) -> Result<EdgeReport, String> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(|e| e.to_string())?;
    runtime.block_on(run_async(args))
}

async fn run_async(args: EdgeArgs) -> Result<EdgeReport, String> {
    let client = ZenohClient::connect(&ZenohClientConfig {
        mode: args.mode,
        connect: args.connect.clone(),
        ..Default::default()
    })
    .await
    .map_err(|e| e.to_string())?;
    let (info, token) = session(&client, &args).await?;
    let side = side_messages(&args)?;
    let mut stream = client
        .open(&info, &token)
        .await
        .map_err(|e| e.to_string())?;
    let opts = StreamOptions {
        realtime: args.realtime,
        timeout: Duration::from_secs_f64(args.timeout_s.max(1.0)),
        ..Default::default()
    };
    let mut printed = (0, 0);
    let quiet = args.quiet;
    let observe = |got: &Received| print_new(got, &mut printed, quiet);
    let got = match &args.wav {
        Some(wav) => {
            let audio = read_wav(wav, &info)?;
            let feed = feed_from(Some(&audio), side, args.block, args.format);
            stream.stream(feed_channel(feed), &opts, observe).await
        }
        None => {
            // The capture runs until the stream ends.
            let (feed, _capture) = capture(&args, &info, side)?;
            stream.stream(feed, &opts, observe).await
        }
    }
    .map_err(|e| e.to_string())?;
    drop(stream);
    client.close().await;
    if let Some(path) = &args.tracks_out {
        write_tracks(path, &got.tracks)?;
    }
    Ok(EdgeReport {
        session: info.id,
        labels: got
            .tracks
            .iter()
            .flat_map(|s| s.tracks.iter().map(|t| t.label))
            .collect(),
        tracks: got.tracks,
        errors: got.errors,
        closed: got.closed,
    })
}

/// The session to feed: the one given, inspected over Zenoh with its token, or a new one.
async fn session(client: &ZenohClient, args: &EdgeArgs) -> Result<(SessionInfo, String), String> {
    if let (Some(id), Some(token)) = (&args.session, &args.token) {
        let info = client.info(id, token).await.map_err(|e| e.to_string())?;
        return Ok((info, token.clone()));
    }
    let path = args
        .calibration
        .as_ref()
        .ok_or("--calibration is needed to create a session")?;
    let mut body = read_calibration(path)?;
    if let Some(p) = &args.settings {
        let text =
            std::fs::read_to_string(p).map_err(|e| format!("{}: cannot read: {e}", p.display()))?;
        body.settings = Some(
            PipelineConfig::parse(&text)
                .map_err(|e| format!("{}: field `{}`: {}", p.display(), e.field, e.message))?,
        );
    }
    let created = client
        .create(&body, args.admin_key.as_deref())
        .await
        .map_err(|e| format!("creating a session over Zenoh: {e}"))?;
    println!(
        "created session {} (other devices join it with --session {} --token <token>)",
        created.id, created.id
    );
    Ok((created.session, created.token))
}

/// A scene.json (its sensors) or a POST /v1/sessions body.
pub fn read_calibration(path: &Path) -> Result<CreateSession, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    if value.get("format").is_some() {
        let scene: SceneFile = parse_json(path, &text, None).map_err(|e| e.to_string())?;
        let layout = layout_from_file(&scene)
            .map_err(|e| format!("{}: {}: {}", path.display(), e.field, e.message))?;
        Ok(create_body(&layout, None))
    } else {
        parse_json(path, &text, None).map_err(|e| e.to_string())
    }
}

/// Detections and device measurements as `(t, JSON message)`, from the JSONL files given.
fn side_messages(args: &EdgeArgs) -> Result<Vec<(f64, String)>, String> {
    let mut side = Vec::new();
    let json = |m: &ClientMessage| serde_json::to_string(m).map_err(|e| e.to_string());
    if let Some(p) = &args.detections {
        for d in read_lines::<DetectionLine>(p)? {
            let t = d.t;
            let m = ClientMessage::Detections {
                t,
                camera: d.camera,
                boxes: d.boxes,
            };
            side.push((t, json(&m)?));
        }
    }
    if let Some(p) = &args.doa {
        for l in read_lines::<AudioMeasurementLine>(p)? {
            side.push((l.t, json(&ClientMessage::AudioMeasurements(l))?));
        }
    }
    Ok(side)
}

fn read_lines<T: serde::de::DeserializeOwned>(path: &Path) -> Result<Vec<T>, String> {
    let mut lines = Vec::new();
    read_jsonl(path, |_, l| {
        lines.push(l);
        Ok(())
    })
    .map_err(|e| e.to_string())?;
    Ok(lines)
}

fn read_wav(path: &Path, info: &SessionInfo) -> Result<Audio, String> {
    let audio = Audio::read(path).map_err(|e| e.to_string())?;
    if audio.sample_rate != info.sample_rate || audio.channels != info.channels {
        return Err(format!(
            "{}: {} channels at {} Hz, but session {} takes {} channels at {} Hz",
            path.display(),
            audio.channels,
            audio.sample_rate,
            info.id,
            info.channels,
            info.sample_rate
        ));
    }
    Ok(audio)
}

/// What keeps a sound-card capture running (dropping it stops the capture).
#[cfg(feature = "soundcard")]
type Capture = soundcard::Capture;
#[cfg(not(feature = "soundcard"))]
type Capture = ();

#[cfg(feature = "soundcard")]
fn capture(
    args: &EdgeArgs,
    info: &SessionInfo,
    side: Vec<(f64, String)>,
) -> Result<(tokio::sync::mpsc::UnboundedReceiver<FeedItem>, Capture), String> {
    let feed = live::LiveFeed::new(
        info.sample_rate,
        info.channels,
        args.block,
        args.format,
        side,
    );
    soundcard::start(args.device.as_deref(), info, args.seconds, feed)
}

#[cfg(not(feature = "soundcard"))]
fn capture(
    _: &EdgeArgs,
    _: &SessionInfo,
    _: Vec<(f64, String)>,
) -> Result<(tokio::sync::mpsc::UnboundedReceiver<FeedItem>, Capture), String> {
    Err("--soundcard needs the example built with `--features soundcard`".into())
}

/// Prints the steps and errors that arrived since the last call.
fn print_new(got: &Received, printed: &mut (usize, usize), quiet: bool) {
    for e in &got.errors[printed.1..] {
        eprintln!(
            "refused: {}{}: {}",
            e.code,
            e.field
                .as_deref()
                .map_or(String::new(), |f| format!(" (field {f})")),
            e.message
        );
    }
    printed.1 = got.errors.len();
    if !quiet {
        for s in &got.tracks[printed.0..] {
            let tracks: Vec<String> = s
                .tracks
                .iter()
                .map(|t| {
                    format!(
                        "{} at ({:.2}, {:.2}, {:.2}) m, speaking {:.2}",
                        t.label, t.position[0], t.position[1], t.position[2], t.speaking
                    )
                })
                .collect();
            println!("step {} t={:.3} s: {}", s.step, s.t, tracks.join("; "));
        }
    }
    printed.0 = got.tracks.len();
}

fn write_tracks(path: &Path, tracks: &[TracksSnapshot]) -> Result<(), String> {
    let mut w = JsonlWriter::create(path).map_err(|e| e.to_string())?;
    for s in tracks {
        w.write(&TracksLine {
            t: s.t,
            tracks: s.tracks.clone(),
        })
        .map_err(|e| e.to_string())?;
    }
    w.finish().map_err(|e| e.to_string())
}

/// The command line: runs the device and prints its summary; exit code 1 when it failed.
pub fn main(args: impl IntoIterator<Item = std::ffi::OsString>) -> std::process::ExitCode {
    let args = EdgeArgs::parse_from(args);
    match run(args) {
        Ok(r) => {
            let mut labels: Vec<String> = r.labels.iter().take(8).map(Label::to_string).collect();
            if r.labels.len() > labels.len() {
                labels.push("...".into());
            }
            println!(
                "session {}: {} steps, {} labels [{}], {} refused, {}",
                r.session,
                r.tracks.len(),
                r.labels.len(),
                labels.join(", "),
                r.errors.len(),
                r.closed.as_ref().map_or("not closed".into(), |c| format!(
                    "closed: {} ({})",
                    c.state.as_str(),
                    c.reason
                ))
            );
            if r.closed.is_some_and(|c| c.state == SessionState::Failed) {
                std::process::ExitCode::FAILURE
            } else {
                std::process::ExitCode::SUCCESS
            }
        }
        Err(e) => {
            eprintln!("zenoh-edge: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
