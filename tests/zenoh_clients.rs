//! The Zenoh clients against a real `avsep serve` (HTTP and Zenoh on free loopback ports, never
//! Zenoh's default 7447): `avsep client stream --zenoh` writes the output folder `avsep process`
//! writes on the same scene, and the edge example (clients/edge, included here as a module and
//! run with its own command line) publishes the scene's WAV file as i16 frames and its
//! detections, once creating its session through the queryable and once joining a session
//! created over REST, and receives the offline tracks. Both live runs must equal the offline one
//! exactly (tracks within 1e-9 m, audio sample for sample): Zenoh keeps one publisher's order,
//! and the feed is the offline runner's order.

mod server_support;

#[allow(dead_code)]
#[path = "../clients/edge/edge.rs"]
mod edge;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use avsep::protocol::rest::{SessionCreated, SessionState, TracksSnapshot};
use avsep::scene::Scene;
use avsep::scene::format::TracksLine;
use avsep::scene::output::Output;
use avsep::server::client::{create_body, http};
use clap::Parser;
use server_support::{assert_same_tracks, audio_difference, scene, settings};

const BIN: &str = env!("CARGO_BIN_EXE_avsep");

/// `avsep serve` as a process, on a free HTTP port and a free Zenoh port.
struct Serve {
    child: Child,
    host: String,
    zenoh: String,
}

impl Serve {
    fn start() -> Self {
        // The Zenoh port is found free and then given to the server, so another process may
        // take it in between: try a few.
        for _ in 0..5 {
            let port = std::net::TcpListener::bind("127.0.0.1:0")
                .and_then(|l| l.local_addr())
                .unwrap()
                .port();
            let zenoh = format!("tcp/127.0.0.1:{port}");
            let mut child = Command::new(BIN)
                .args(["serve", "--bind", "127.0.0.1:0", "--zenoh-listen", &zenoh])
                .env("AVSEP_LOG", "warn")
                .stdout(Stdio::piped())
                .stderr(Stdio::inherit())
                .spawn()
                .unwrap();
            let mut line = String::new();
            BufReader::new(child.stdout.take().unwrap())
                .read_line(&mut line)
                .unwrap();
            if let Some(host) = line.trim().strip_prefix("listening on http://") {
                return Self {
                    host: host.to_string(),
                    zenoh,
                    child,
                };
            }
            let _ = child.wait();
        }
        panic!("avsep serve did not start");
    }

    /// SIGTERM, and the server drains and exits cleanly.
    fn stop(mut self) {
        let rc = unsafe { libc::kill(self.child.id() as libc::pid_t, libc::SIGTERM) };
        assert_eq!(rc, 0);
        let status = self.child.wait().unwrap();
        assert!(status.success(), "avsep serve exited with {status}");
    }
}

/// A simulated scene whose audio lies on the i16 grid, so i16 and f32 frames carry the same
/// samples and every run below has one offline result to equal.
fn quantised_scene(dir: &Path) -> Scene {
    let mut sc = scene("uca8", 2.0, 2, 61);
    if let Some(a) = sc.audio.as_mut() {
        for s in &mut a.samples {
            *s = ((*s * 32768.0).round().clamp(-32768.0, 32767.0)) / 32768.0;
        }
    }
    sc.save(dir).unwrap();
    // What the offline run reads is what the clients read.
    Scene::load(dir).unwrap()
}

fn run_ok(cmd: &mut Command) {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{cmd:?}: {}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

fn snapshots(lines: Vec<TracksLine>) -> Vec<TracksSnapshot> {
    lines
        .into_iter()
        .enumerate()
        .map(|(k, l)| TracksSnapshot {
            step: k as u64,
            t: l.t,
            tracks: l.tracks,
        })
        .collect()
}

fn edge_args(server: &Serve, scene_dir: &Path, config: &Path, extra: &[&str]) -> edge::EdgeArgs {
    let path = |p: PathBuf| p.to_str().unwrap().to_string();
    let mut args: Vec<String> = vec![
        "zenoh-edge".into(),
        "--connect".into(),
        server.zenoh.clone(),
        "--wav".into(),
        path(scene_dir.join("audio.wav")),
        "--detections".into(),
        path(scene_dir.join("detections.jsonl")),
        "--format".into(),
        "i16".into(),
        "--quiet".into(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    if !extra.contains(&"--session") {
        args.extend([
            "--calibration".into(),
            path(scene_dir.join("scene.json")),
            "--settings".into(),
            path(config.to_path_buf()),
        ]);
    }
    edge::EdgeArgs::parse_from(args)
}

#[test]
fn zenoh_client_and_edge_device_get_the_offline_result() {
    let server = Serve::start();
    let dir = tempfile::tempdir().unwrap();
    let scene_dir = dir.path().join("scene");
    let sc = quantised_scene(&scene_dir);
    let config = dir.path().join("settings.toml");
    std::fs::write(&config, "seed = 5\n").unwrap();
    let (offline_dir, live_dir) = (dir.path().join("offline"), dir.path().join("live"));
    let offline = process_offline(&scene_dir, &offline_dir, &config, &sc);
    let offline_tracks = offline.tracks.clone().unwrap();

    // The CLI over Zenoh and the edge device (creating its session through the queryable) at
    // once: two independent sessions on one server.
    let cli = spawn_cli_stream(&server, &scene_dir, &live_dir, &config);
    let tracks_out = dir.path().join("edge-tracks.jsonl");
    let created = edge::run(edge_args(
        &server,
        &scene_dir,
        &config,
        &["--tracks-out", tracks_out.to_str().unwrap()],
    ))
    .unwrap();
    cli.join().unwrap();

    assert_cli_output_equals_offline(&live_dir, &sc, &offline);
    assert_edge_session_equals_offline(&created, &tracks_out, &offline_tracks);
    edge_joins_a_session_created_over_rest(&server, &scene_dir, &config, &sc, &offline_tracks);
    server.stop();
}

/// Runs `avsep process` on the scene into `offline_dir` and loads what it wrote.
fn process_offline(scene_dir: &Path, offline_dir: &Path, config: &Path, sc: &Scene) -> Output {
    run_ok(
        Command::new(BIN)
            .args(["process", scene_dir.to_str().unwrap(), "--out"])
            .arg(offline_dir)
            .arg("--config")
            .arg(config),
    );
    Output::load(offline_dir, &sc.layout).unwrap()
}

/// Starts `avsep client stream --zenoh` on the scene, writing into `live_dir`, on a thread.
fn spawn_cli_stream(
    server: &Serve,
    scene_dir: &Path,
    live_dir: &Path,
    config: &Path,
) -> std::thread::JoinHandle<()> {
    let (zenoh, scene_dir, live_dir, config) = (
        server.zenoh.clone(),
        scene_dir.to_path_buf(),
        live_dir.to_path_buf(),
        config.to_path_buf(),
    );
    std::thread::spawn(move || {
        run_ok(
            Command::new(BIN)
                .args(["client", "stream", scene_dir.to_str().unwrap()])
                .args(["--zenoh", "--zenoh-connect", &zenoh, "--out"])
                .arg(&live_dir)
                .arg("--config")
                .arg(&config),
        )
    })
}

/// Asserts the CLI's output folder equals the offline one and its summary names the Zenoh link.
fn assert_cli_output_equals_offline(live_dir: &Path, sc: &Scene, offline: &Output) {
    let live = Output::load(live_dir, &sc.layout).unwrap();
    assert_same_tracks(
        offline.tracks.as_ref().unwrap(),
        &snapshots(live.tracks.unwrap()),
    );
    assert_eq!(audio_difference(&offline.audio, &live.audio), 0.0);
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(live_dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["errors"], serde_json::json!({}));
    assert!(
        summary["server"]
            .as_str()
            .unwrap()
            .starts_with("zenoh tcp/")
    );
}

/// Asserts the edge device's own session finished with the offline tracks, received and written.
fn assert_edge_session_equals_offline(
    created: &edge::EdgeReport,
    tracks_out: &Path,
    offline_tracks: &[TracksLine],
) {
    assert!(created.errors.is_empty(), "{:?}", created.errors);
    assert_eq!(
        created.closed.as_ref().unwrap().state,
        SessionState::Finished
    );
    assert_same_tracks(offline_tracks, &created.tracks);
    let mut from_file = Vec::new();
    avsep::scene::read_jsonl(tracks_out, |_, l: TracksLine| {
        from_file.push(l);
        Ok(())
    })
    .unwrap();
    assert_same_tracks(offline_tracks, &snapshots(from_file));
}

/// Creates a session over REST, as another device would.
fn create_over_rest(server: &Serve, sc: &Scene) -> SessionCreated {
    let body = serde_json::to_vec(&create_body(&sc.layout, Some(settings(5)))).unwrap();
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let r = rt
        .block_on(http(
            &server.host,
            "POST",
            "/v1/sessions",
            None,
            Some(&body),
        ))
        .unwrap();
    assert_eq!(r.status, 201, "{}", r.text());
    r.json().unwrap()
}

/// The edge device joins a session created over REST (another device's) with its token and
/// gets the offline tracks; a wrong token is refused by name.
fn edge_joins_a_session_created_over_rest(
    server: &Serve,
    scene_dir: &Path,
    config: &Path,
    sc: &Scene,
    offline_tracks: &[TracksLine],
) {
    let s = create_over_rest(server, sc);
    let e = edge::run(edge_args(
        server,
        scene_dir,
        config,
        &["--session", &s.id, "--token", "not-the-token"],
    ))
    .unwrap_err();
    assert!(e.contains("forbidden"), "{e}");
    let joined = edge::run(edge_args(
        server,
        scene_dir,
        config,
        &["--session", &s.id, "--token", &s.token],
    ))
    .unwrap();
    assert_eq!(joined.session, s.id);
    assert!(joined.errors.is_empty(), "{:?}", joined.errors);
    assert_same_tracks(offline_tracks, &joined.tracks);
}
