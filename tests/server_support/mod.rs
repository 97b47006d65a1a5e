//! Shared helpers of the server tests: an in-process server on 127.0.0.1:0, simulated scenes,
//! and the offline run to compare a streamed session with.

#![allow(dead_code)]

pub mod hooked;
pub mod zenoh;

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use avsep::label::Label;
use avsep::pipeline::PipelineConfig;
use avsep::pipeline::offline::{OfflineOptions, process_scene};
use avsep::protocol::OutputSelection;
use avsep::protocol::rest::{SessionCreated, TracksSnapshot};
use avsep::scene::Scene;
use avsep::scene::format::TracksLine;
use avsep::scene::output::Output;
use avsep::scene::sim::{PresetOptions, SimConfig, simulate};
use avsep::server::client::{ClientError, Received, create_body, http, listen};
use avsep::server::{Registry, Server, ServerConfig};

/// A listener of a session's output stream at `url` selecting `outputs`, returned once it is
/// subscribed; it ends when the session's streams close or after `timeout_s` seconds.
pub async fn spawn_listener(
    url: &str,
    token: &str,
    outputs: OutputSelection,
    timeout_s: u64,
) -> tokio::task::JoinHandle<Result<Received, ClientError>> {
    let (ready_tx, ready_rx) = tokio::sync::oneshot::channel();
    let (url, token) = (url.to_string(), token.to_string());
    let handle = tokio::spawn(async move {
        listen(
            &url,
            &token,
            outputs,
            Duration::from_secs(timeout_s),
            Some(ready_tx),
        )
        .await
    });
    ready_rx.await.unwrap();
    handle
}

/// A server running in the test's runtime.
pub struct TestServer {
    pub addr: SocketAddr,
    pub registry: Arc<Registry>,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    task: tokio::task::JoinHandle<std::io::Result<()>>,
}

impl TestServer {
    pub async fn start(mut cfg: ServerConfig) -> Self {
        cfg.bind = "127.0.0.1:0".into();
        let server = Server::bind(cfg).await.unwrap();
        let addr = server.local_addr().unwrap();
        let registry = server.registry();
        let (tx, rx) = tokio::sync::oneshot::channel::<()>();
        let task = tokio::spawn(server.run(async {
            let _ = rx.await;
        }));
        Self {
            addr,
            registry,
            stop: Some(tx),
            task,
        }
    }

    pub fn host(&self) -> String {
        self.addr.to_string()
    }

    pub fn ws_url(&self, s: &SessionCreated) -> String {
        format!("ws://{}{}", self.addr, s.stream)
    }

    /// Creates a session for `scene` with `settings`.
    pub async fn create(
        &self,
        scene: &Scene,
        settings: PipelineConfig,
        key: Option<&str>,
    ) -> SessionCreated {
        let body = serde_json::to_vec(&create_body(&scene.layout, Some(settings))).unwrap();
        let r = http(&self.host(), "POST", "/v1/sessions", key, Some(&body))
            .await
            .unwrap();
        assert_eq!(r.status, 201, "{}", r.text());
        r.json().unwrap()
    }

    /// The session's metrics (`GET /v1/sessions/{id}/metrics`).
    pub async fn metrics(&self, s: &SessionCreated) -> avsep::protocol::rest::SessionMetrics {
        let path = format!("/v1/sessions/{}/metrics", s.id);
        let r = http(&self.host(), "GET", &path, Some(&s.token), None)
            .await
            .unwrap();
        assert_eq!(r.status, 200, "{}", r.text());
        r.json().unwrap()
    }

    /// Stops the server (draining its sessions) and waits for it.
    pub async fn stop(mut self) {
        if let Some(tx) = self.stop.take() {
            let _ = tx.send(());
        }
        self.task.await.unwrap().unwrap();
    }
}

/// A simulated scene.
pub fn scene(preset: &str, seconds: f64, speakers: usize, seed: u64) -> Scene {
    let opts = PresetOptions {
        duration_s: Some(seconds),
        speakers: Some(speakers),
        ..Default::default()
    };
    simulate(&SimConfig::preset(preset, &opts, seed).unwrap(), seed).unwrap()
}

/// Settings with a fixed seed, shared by the offline run and the session.
pub fn settings(seed: u64) -> PipelineConfig {
    PipelineConfig {
        seed: Some(seed),
        ..Default::default()
    }
}

/// The offline run (`avsep process`): tracks and separated audio.
pub fn offline(scene: &Scene, cfg: PipelineConfig) -> (Vec<TracksLine>, BTreeMap<Label, Vec<f32>>) {
    let dir = tempfile::tempdir().unwrap();
    process_scene(scene, cfg, dir.path(), OfflineOptions::default(), &|_| {}).unwrap();
    let out = Output::load(dir.path(), &scene.layout).unwrap();
    (out.tracks.unwrap(), out.audio)
}

/// Asserts the streamed estimates equal the offline ones: same steps, labels, and positions
/// within 1e-9 m.
pub fn assert_same_tracks(offline: &[TracksLine], streamed: &[TracksSnapshot]) {
    assert_eq!(offline.len(), streamed.len(), "number of steps");
    let mut labels = 0;
    for (k, (a, b)) in offline.iter().zip(streamed).enumerate() {
        assert_eq!(b.step, k as u64);
        assert!((a.t - b.t).abs() < 1e-12, "step {k}: t {} vs {}", a.t, b.t);
        let la: Vec<Label> = a.tracks.iter().map(|t| t.label).collect();
        let lb: Vec<Label> = b.tracks.iter().map(|t| t.label).collect();
        assert_eq!(la, lb, "labels at step {k}");
        for (ta, tb) in a.tracks.iter().zip(&b.tracks) {
            for i in 0..3 {
                assert!(
                    (ta.position[i] - tb.position[i]).abs() <= 1e-9,
                    "step {k} label {}: {:?} vs {:?}",
                    ta.label,
                    ta.position,
                    tb.position
                );
            }
        }
        labels += la.len();
    }
    assert!(labels > 0, "the scene produced no tracks at all");
}

/// Largest absolute difference between the streamed and offline separated audio, over labels
/// that both have (and both must have the same labels).
pub fn audio_difference(
    offline: &BTreeMap<Label, Vec<f32>>,
    streamed: &BTreeMap<Label, Vec<f32>>,
) -> f32 {
    assert_eq!(
        offline.keys().collect::<Vec<_>>(),
        streamed.keys().collect::<Vec<_>>(),
        "separated labels"
    );
    let mut worst = 0.0f32;
    for (label, a) in offline {
        let b = &streamed[label];
        assert_eq!(a.len(), b.len());
        assert!(
            a.iter().any(|v| *v != 0.0),
            "label {label} is silent offline"
        );
        for (x, y) in a.iter().zip(b) {
            worst = worst.max((x - y).abs());
        }
    }
    worst
}
