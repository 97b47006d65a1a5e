//! `avsep client stream` against a real server: the live run of a simulated scene writes an
//! output folder equal to `avsep process` on the same scene (same tracks within 1e-9 m, the same
//! separated audio sample for sample), so `avsep eval` scores both the same.

mod server_support;

use std::process::Command;

use avsep::protocol::rest::TracksSnapshot;
use avsep::scene::output::Output;
use avsep::server::ServerConfig;
use server_support::{TestServer, assert_same_tracks, audio_difference, scene};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn client_stream_writes_the_offline_output_folder() {
    let server = TestServer::start(ServerConfig::default()).await;
    let dir = tempfile::tempdir().unwrap();
    let sc = scene("uca8", 2.5, 2, 51);
    let scene_dir = dir.path().join("scene");
    sc.save(&scene_dir).unwrap();
    let config = dir.path().join("settings.toml");
    std::fs::write(&config, "seed = 5\n").unwrap();
    let bin = env!("CARGO_BIN_EXE_avsep");
    let (offline_dir, live_dir) = (dir.path().join("offline"), dir.path().join("live"));

    let offline = Command::new(bin)
        .args(["process", scene_dir.to_str().unwrap(), "--out"])
        .arg(&offline_dir)
        .arg("--config")
        .arg(&config)
        .output()
        .unwrap();
    assert!(
        offline.status.success(),
        "{}",
        String::from_utf8_lossy(&offline.stderr)
    );
    let url = format!("http://{}", server.host());
    let live = tokio::task::spawn_blocking({
        let (scene_dir, live_dir, config) = (scene_dir.clone(), live_dir.clone(), config.clone());
        move || {
            Command::new(bin)
                .args([
                    "client",
                    "stream",
                    scene_dir.to_str().unwrap(),
                    "--url",
                    &url,
                ])
                .arg("--out")
                .arg(&live_dir)
                .arg("--config")
                .arg(&config)
                .output()
                .unwrap()
        }
    })
    .await
    .unwrap();
    assert!(
        live.status.success(),
        "{}",
        String::from_utf8_lossy(&live.stderr)
    );

    let a = Output::load(&offline_dir, &sc.layout).unwrap();
    let b = Output::load(&live_dir, &sc.layout).unwrap();
    let streamed: Vec<TracksSnapshot> = b
        .tracks
        .unwrap()
        .into_iter()
        .enumerate()
        .map(|(k, l)| TracksSnapshot {
            step: k as u64,
            t: l.t,
            tracks: l.tracks,
        })
        .collect();
    assert_same_tracks(&a.tracks.unwrap(), &streamed);
    assert_eq!(audio_difference(&a.audio, &b.audio), 0.0);

    // A scene folder that does not exist is bad input: exit code 2, naming the folder.
    let bad = Command::new(bin)
        .args(["client", "stream", "/nonexistent-scene", "--url"])
        .arg(format!("http://{}", server.host()))
        .args(["--out", dir.path().join("x").to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("nonexistent-scene"));
    server.stop().await;
}
