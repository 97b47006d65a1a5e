//! A session's life over REST and the stream: live recalibration and settings, history and
//! metrics, deletion, a pipeline that panics (its session fails, the others go on), and graceful
//! shutdown of `avsep serve` on SIGTERM.

mod server_support;

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::Duration;

use avsep::pipeline::{Pipeline, PipelineConfig};
use avsep::protocol::rest::{SessionInfo, SessionMetrics, TrackHistory, TracksSnapshot};
use avsep::protocol::{OutputSelection, SampleEncoding};
use avsep::server::client::{FeedItem, FeedMessage, StreamOptions, http, scene_feed, stream_feed};
use avsep::server::{ServerConfig, client::create_body};
use server_support::hooked::{Hooked, hand_made_spec};
use server_support::{TestServer, assert_same_tracks, offline, scene, settings, spawn_listener};

/// One session's REST resources under its token.
struct SessionApi {
    host: String,
    path: String,
    token: String,
}

impl SessionApi {
    /// `method` on the session's `sub` path (`""` for the session itself) with a JSON body.
    async fn call(
        &self,
        method: &str,
        sub: &str,
        body: Option<serde_json::Value>,
    ) -> avsep::server::client::HttpResponse {
        let body = body.map(|b| serde_json::to_vec(&b).unwrap());
        let path = format!("{}{sub}", self.path);
        http(
            &self.host,
            method,
            &path,
            Some(&self.token),
            body.as_deref(),
        )
        .await
        .unwrap()
    }

    /// Polls the current tracks until step `step` has run.
    async fn wait_for_step(&self, step: u64) -> TracksSnapshot {
        for _ in 0..100 {
            let r = self.call("GET", "/tracks", None).await;
            if r.status == 200 {
                let t: TracksSnapshot = r.json().unwrap();
                if t.step >= step {
                    return t;
                }
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        panic!("the pipeline did not reach step {step}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn live_recalibration_settings_history_metrics_and_deletion() {
    let cfg = ServerConfig {
        cors_origins: vec!["http://example.org".into()],
        ..ServerConfig::default()
    };
    let server = TestServer::start(cfg).await;
    let host = server.host();
    let sc = scene("uca8", 3.0, 2, 71);
    let s = server.create(&sc, settings(4), None).await;
    let api = SessionApi {
        host: host.clone(),
        path: format!("/v1/sessions/{}", s.id),
        token: s.token.clone(),
    };
    let url = server.ws_url(&s);
    let listener = spawn_listener(&url, &s.token, OutputSelection::default(), 120).await;

    let feed = scene_feed(&sc, 1024, SampleEncoding::F32);
    let (half, before) = stream_first_half(&api, &url, &feed).await;
    recalibrate_live(&api, &sc).await;

    // The rest of the scene; the tracks alive before go on after the recalibration.
    let opts = StreamOptions {
        from: half,
        ..Default::default()
    };
    let rest = stream_feed(&url, &s.token, &feed, &opts).await.unwrap();
    assert!(rest.errors.is_empty(), "{:?}", rest.errors);
    let heard = listener.await.unwrap().unwrap();
    assert_tracks_kept_across_recalibration(&before, &heard.tracks);
    let audio_frames = feed
        .iter()
        .filter(|i| matches!(i.message, FeedMessage::Audio { .. }))
        .count() as u64;
    history_and_metrics_match_the_stream(&api, &heard.tracks, audio_frames, &sc).await;
    cors_allows_the_configured_origin(&host).await;

    // Deletion: 204, then gone.
    assert_eq!(api.call("DELETE", "", None).await.status, 204);
    assert_eq!(api.call("GET", "", None).await.status, 404);
    deleting_a_running_session_closes_its_streams(&server, &sc).await;
    server.stop().await;
}

/// Streams the first half of `feed` and lets the pipeline catch up with what was sent; returns
/// where the rest starts and the tracks then.
async fn stream_first_half(
    api: &SessionApi,
    url: &str,
    feed: &[FeedItem],
) -> (usize, TracksSnapshot) {
    let half = feed
        .iter()
        .position(|i| matches!(i.message, FeedMessage::Audio { end: 24576, .. }))
        .unwrap()
        + 1;
    let opts = StreamOptions {
        disconnect_at: Some(half),
        ..Default::default()
    };
    let first = stream_feed(url, &api.token, feed, &opts).await.unwrap();
    assert!(first.errors.is_empty(), "{:?}", first.errors);
    let before = api.wait_for_step(24576 / 2048 - 3).await;
    assert!(
        !before.tracks.is_empty(),
        "tracks exist before the recalibration"
    );
    (half, before)
}

/// Some label alive `before` the recalibration is still there a step after it, and every step of
/// the scene was reported.
fn assert_tracks_kept_across_recalibration(before: &TracksSnapshot, heard: &[TracksSnapshot]) {
    let after = heard.iter().find(|t| t.step > before.step + 1).unwrap();
    let kept = before
        .tracks
        .iter()
        .filter(|t| after.tracks.iter().any(|u| u.label == t.label))
        .count();
    assert!(
        kept > 0,
        "labels {:?} before, {:?} after",
        before.tracks,
        after.tracks
    );
    assert_eq!(heard.len(), 3 * 16000 / 2048 + 1, "every step was reported");
}

/// A CORS preflight from the configured origin is allowed.
async fn cors_allows_the_configured_origin(host: &str) {
    let raw = raw_request(
        host,
        "OPTIONS /v1/sessions HTTP/1.1\r\nHost: x\r\nOrigin: http://example.org\r\nAccess-Control-Request-Method: POST\r\nConnection: close\r\n\r\n",
    )
    .await;
    assert!(
        raw.to_ascii_lowercase()
            .contains("access-control-allow-origin: http://example.org"),
        "{raw}"
    );
}

/// Moves the array by 1 cm (applied at the next step, tracks kept), sets the camera's
/// projection again, and patches the settings that can change live.
async fn recalibrate_live(api: &SessionApi, sc: &avsep::scene::Scene) {
    let a0 = &sc.layout.arrays[0];
    let moved: Vec<[f64; 3]> = a0.mics.iter().map(|m| [m.x + 0.01, m.y, m.z]).collect();
    let body = serde_json::json!({ "mics": moved });
    let r = api
        .call("PUT", &format!("/arrays/{}", a0.id), Some(body))
        .await;
    assert_eq!(r.status, 200, "{}", r.text());
    let info: SessionInfo = r.json().unwrap();
    assert_eq!(info.arrays[0].mics, moved);
    let cam = &info.cameras[0];
    let body = serde_json::json!({ "projection": cam.projection });
    let r = api
        .call("PUT", &format!("/cameras/{}", cam.id), Some(body))
        .await;
    assert_eq!(r.status, 200, "{}", r.text());

    let projection = cam.projection.expect("the camera's projection");
    concurrent_recalibrations_both_apply(api, (&a0.id, &moved), &cam.id, &projection).await;

    let patch = serde_json::json!({
        "camera_wait_s": 0.2,
        "track": {"camera": {"p_detect": 0.8}},
        "separate": {"post_filter": {"gain_floor": 0.2}}
    });
    let r = api.call("PATCH", "/settings", Some(patch)).await;
    assert_eq!(r.status, 200, "{}", r.text());
    let now: PipelineConfig = r.json().unwrap();
    assert_eq!((now.camera_wait_s, now.track.camera.p_detect), (0.2, 0.8));
    assert_eq!(now.separate.post_filter.gain_floor, 0.2);
    let r = api.call("GET", "/settings", None).await;
    assert_eq!(r.json::<PipelineConfig>().unwrap(), now);
}

/// The array moved by another millimetre and the camera by one, at once: each change waits
/// for the other instead of both starting from the same layout, so neither is lost.
async fn concurrent_recalibrations_both_apply(
    api: &SessionApi,
    (array, mics): (&str, &[[f64; 3]]),
    camera: &str,
    projection: &[[f64; 4]; 3],
) {
    let moved: Vec<[f64; 3]> = mics.iter().map(|m| [m[0] + 0.001, m[1], m[2]]).collect();
    let mut shifted = *projection;
    shifted[0][3] += 0.001 * shifted[2][3].abs().max(1.0);
    let (array_path, camera_path) = (format!("/arrays/{array}"), format!("/cameras/{camera}"));
    let a = api.call(
        "PUT",
        &array_path,
        Some(serde_json::json!({ "mics": moved })),
    );
    let c = api.call(
        "PUT",
        &camera_path,
        Some(serde_json::json!({ "projection": shifted })),
    );
    let (a, c) = tokio::join!(a, c);
    assert_eq!(
        (a.status, c.status),
        (200, 200),
        "{} {}",
        a.text(),
        c.text()
    );
    let applied: SessionInfo = c.json().unwrap();
    let now: SessionInfo = api.call("GET", "", None).await.json().unwrap();
    assert_eq!(now.arrays[0].mics, moved, "the array's change was kept");
    assert_eq!(
        now.cameras[0].projection, applied.cameras[0].projection,
        "the camera's change was kept"
    );
    assert_ne!(now.cameras[0].projection.as_ref(), Some(projection));
}

/// The track history equals what the stream reported; the session's metrics and the
/// Prometheus text count what was sent.
async fn history_and_metrics_match_the_stream(
    api: &SessionApi,
    heard: &[TracksSnapshot],
    audio_frames: u64,
    sc: &avsep::scene::Scene,
) {
    let r = api
        .call("GET", "/tracks/history?from_step=3&limit=4", None)
        .await;
    let h: TrackHistory = r.json().unwrap();
    assert_eq!(
        h.steps.iter().map(|t| t.step).collect::<Vec<_>>(),
        vec![3, 4, 5, 6]
    );
    assert_eq!(h.oldest_step, Some(0));
    assert_eq!(h.steps, heard[3..7].to_vec());
    let r = api.call("GET", "/tracks/history?limit=x", None).await;
    assert_eq!(r.status, 400);
    let m: SessionMetrics = api.call("GET", "/metrics", None).await.json().unwrap();
    assert_eq!(m.frames_in.audio, audio_frames);
    assert_eq!(m.frames_in.detections, sc.detections.len() as u64);
    assert_eq!(m.steps as usize, heard.len());
    assert!(m.real_time_factor > 0.0 && m.step_processing_ms.p50 > 0.0);
    let r = http(&api.host, "GET", "/metrics", None, None)
        .await
        .unwrap();
    let text = r.text();
    assert!(
        text.contains(&format!(
            "avsep_frames_in_total{{kind=\"audio\"}} {audio_frames}"
        )),
        "{text}"
    );
    assert!(text.contains("avsep_sessions{state=\"finished\"} 1"));
    assert!(text.contains("avsep_process_resident_memory_bytes"));
    assert!(text.contains("avsep_separation_queue_depth 0"), "{text}");
    assert!(text.contains("avsep_separation_waits_total"), "{text}");
}

/// A running session that is deleted closes its streams normally after flushing.
async fn deleting_a_running_session_closes_its_streams(
    server: &TestServer,
    sc: &avsep::scene::Scene,
) {
    let host = server.host();
    let s2 = server.create(sc, settings(4), None).await;
    let l2 = spawn_listener(
        &server.ws_url(&s2),
        &s2.token,
        OutputSelection::default(),
        60,
    )
    .await;
    let list: avsep::protocol::rest::SessionList = http(&host, "GET", "/v1/sessions", None, None)
        .await
        .unwrap()
        .json()
        .unwrap();
    assert_eq!(list.sessions.len(), 1);
    assert_eq!(list.sessions[0].clients, 1);
    let r = http(
        &host,
        "DELETE",
        &format!("/v1/sessions/{}", s2.id),
        Some(&s2.token),
        None,
    )
    .await
    .unwrap();
    assert_eq!(r.status, 204);
    let heard = l2.await.unwrap().unwrap();
    assert_eq!(heard.close, Some((1000, "session deleted".into())));
}

async fn raw_request(host: &str, req: &str) -> String {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut tcp = tokio::net::TcpStream::connect(host).await.unwrap();
    tcp.write_all(req.as_bytes()).await.unwrap();
    let mut out = Vec::new();
    tcp.read_to_end(&mut out).await.unwrap();
    String::from_utf8_lossy(&out).into_owned()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_panicking_pipeline_fails_its_session_only() {
    let server = TestServer::start(ServerConfig::default()).await;
    let host = server.host();
    let sc = scene("uca8", 2.0, 2, 81);
    let (tracks, _) = offline(&sc, settings(8));
    // The failing session, made through the registry with its own engine.
    let pipeline = Pipeline::new(sc.layout.clone(), settings(8), 8).unwrap();
    let token = "f".repeat(64);
    let spec = hand_made_spec(
        &server,
        "badbadbadbadbad0",
        "exploding",
        &token,
        &sc,
        &pipeline,
    );
    let mut engine = Hooked::new(pipeline);
    engine.on_audio =
        Box::new(|first| assert!(first < 16000, "synthetic failure at sample {first}"));
    server.registry.insert(spec, engine).unwrap();
    let bad_url = format!("ws://{host}/v1/sessions/badbadbadbadbad0/stream");
    let good = server.create(&sc, settings(8), None).await;

    let bad_listener = spawn_listener(&bad_url, &token, OutputSelection::default(), 60).await;
    let feed = scene_feed(&sc, 1024, SampleEncoding::F32);
    let opts = StreamOptions::default();
    let good_url = server.ws_url(&good);
    let (bad_run, good_run) = tokio::join!(
        stream_feed(&bad_url, &token, &feed, &opts),
        stream_feed(&good_url, &good.token, &feed, &opts)
    );
    // The failing session's streams get an error and a close frame (1011).
    let heard = bad_listener.await.unwrap().unwrap();
    let e = heard
        .errors
        .iter()
        .find(|e| e.code == "session_failed")
        .expect("session_failed");
    assert!(e.message.contains("synthetic failure"), "{e:?}");
    assert_eq!(heard.close.as_ref().map(|c| c.0), Some(1011));
    // The source is either told and closed, or cut off while sending.
    if let Ok(r) = bad_run {
        assert!(
            r.errors.iter().any(|e| e.code == "session_failed"),
            "{:?}",
            r.errors
        );
    }
    let r = http(
        &host,
        "GET",
        "/v1/sessions/badbadbadbadbad0",
        Some(&token),
        None,
    )
    .await
    .unwrap();
    let info: SessionInfo = r.json().unwrap();
    assert_eq!(info.state, avsep::protocol::rest::SessionState::Failed);
    assert_eq!(info.error.unwrap().code, "session_failed");
    // New input is refused with a clear error.
    let e = avsep::server::client::connect(&bad_url, &token)
        .await
        .unwrap_err();
    assert!(e.0.contains("409"), "{e}");
    // The other session never noticed.
    let good_run = good_run.unwrap();
    assert!(good_run.errors.is_empty(), "{:?}", good_run.errors);
    assert_same_tracks(&tracks, &good_run.tracks);
    let text = http(&host, "GET", "/metrics", None, None)
        .await
        .unwrap()
        .text();
    assert!(text.contains("avsep_session_failures_total 1"), "{text}");
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_steps_tracks_are_published_before_the_rest_of_its_work() {
    let server = TestServer::start(ServerConfig::default()).await;
    let host = server.host();
    let sc = scene("uca8", 1.0, 1, 83);
    let pipeline = Pipeline::new(sc.layout.clone(), settings(8), 8).unwrap();
    let token = "e".repeat(64);
    let id = "0e1d0e1d0e1d0e1d";
    let spec = hand_made_spec(&server, id, "held", &token, &sc, &pipeline);
    // After its first step's tracks the engine stops until the test lets it go on.
    let (engine, release) = Hooked::held_after_first_step(pipeline);
    server.registry.insert(spec, engine).unwrap();
    let url = format!("ws://{host}/v1/sessions/{id}/stream");
    let feed = scene_feed(&sc, 1024, SampleEncoding::F32);
    let opts = StreamOptions::default();
    let run = tokio::spawn(async move { stream_feed(&url, &token, &feed, &opts).await });
    // The engine is still inside the message that completed step 0, yet its tracks are out.
    let tracks_path = format!("/v1/sessions/{id}/tracks");
    let mut seen = None;
    for _ in 0..100 {
        let r = http(&host, "GET", &tracks_path, Some(&"e".repeat(64)), None)
            .await
            .unwrap();
        if r.status == 200 {
            let t: TracksSnapshot = r.json().unwrap();
            seen = Some(t.step);
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert_eq!(
        seen,
        Some(0),
        "step 0's tracks were not published while the engine held"
    );
    release.send(()).unwrap();
    let r = run.await.unwrap().unwrap();
    assert!(r.errors.is_empty(), "{:?}", r.errors);
    assert!(!r.tracks.is_empty());
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn serve_drains_sessions_on_sigterm() {
    // No Zenoh: its default listener (tcp/127.0.0.1:7447) is one fixed port that concurrent
    // test runs on the machine would contend for.
    let mut child = Command::new(env!("CARGO_BIN_EXE_avsep"))
        .args(["serve", "--bind", "127.0.0.1:0", "--no-zenoh"])
        .env("AVSEP_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let host = line
        .trim()
        .trim_start_matches("listening on http://")
        .to_string();
    let sc = scene("uca8", 1.0, 1, 91);
    let body = serde_json::to_vec(&create_body(&sc.layout, Some(settings(2)))).unwrap();
    let r = http(&host, "POST", "/v1/sessions", None, Some(&body))
        .await
        .unwrap();
    let s: avsep::protocol::rest::SessionCreated = r.json().unwrap();
    let url = format!("ws://{host}{}", s.stream);
    let listener = spawn_listener(&url, &s.token, OutputSelection::default(), 60).await;
    // The source sends 0.75 s of audio and goes away without finishing.
    let feed = scene_feed(&sc, 1024, SampleEncoding::F32);
    let stop = feed
        .iter()
        .position(|i| matches!(i.message, FeedMessage::Audio { end: 12288, .. }))
        .unwrap()
        + 1;
    let opts = StreamOptions {
        disconnect_at: Some(stop),
        ..Default::default()
    };
    stream_feed(&url, &s.token, &feed, &opts).await.unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;

    // SIGTERM: the pipeline finishes (every step of the audio received is reported), the stream
    // closes with 1001, and the process exits cleanly.
    let rc = unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
    assert_eq!(rc, 0);
    let heard = listener.await.unwrap().unwrap();
    assert_eq!(heard.close, Some((1001, "server shutting down".into())));
    assert_eq!(heard.tracks.len(), 12288 / 2048);
    let status = child.wait().unwrap();
    assert!(status.success(), "{status}");
    let r = http(&host, "GET", "/healthz", None, None).await;
    assert!(r.is_err(), "the listener is closed");
}
