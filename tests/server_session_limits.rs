//! The bounds on sessions themselves: sessions nobody uses end by themselves
//! (`limits.idle_timeout_s`): one never fed is removed, one fed and left finishes (its results
//! stay readable), and one with a client connected runs on however quiet it is; creations
//! past `limits.session_creations_per_min` are refused; a session's input queue holds at most
//! `limits.queue_bytes`, and the frames waiting for its audio at most
//! `limits.sensor_backlog_bytes`; and sessions are admitted by their memory bound under
//! `limits.max_memory_mb`, at creation and on every change that moves the bound.

mod server_support;

use std::time::{Duration, Instant};

use avsep::pipeline::Pipeline;
use avsep::protocol::rest::{SessionMetrics, SessionState};
use avsep::protocol::{AudioFrame, SampleEncoding};
use avsep::server::client::{
    FeedItem, FeedMessage, StreamOptions, connect, create_body, http, scene_feed, stream_feed,
};
use avsep::server::{Limits, ServerConfig};
use futures_util::SinkExt;
use server_support::hooked::{Hooked, hand_made_spec};
use server_support::{TestServer, scene, settings};
use tokio_tungstenite::tungstenite::Message;

/// A test server with the default settings but for its limits as `edit` leaves them.
async fn server_with(edit: impl FnOnce(&mut Limits)) -> TestServer {
    let mut cfg = ServerConfig::default();
    edit(&mut cfg.limits);
    TestServer::start(cfg).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unused_sessions_end_and_used_ones_run_on() {
    let server = server_with(|l| l.idle_timeout_s = 0.5).await;
    let sc = scene("uca8", 1.0, 1, 3);
    let never_fed = server.create(&sc, settings(1), None).await;
    let fed = server.create(&sc, settings(1), None).await;
    let watched = server.create(&sc, settings(1), None).await;

    let audio = sc.audio.as_ref().unwrap();
    let frame = AudioFrame {
        first_sample: 0,
        channels: audio.channels,
        samples: audio.samples[..1024 * audio.channels].to_vec(),
        encoding: SampleEncoding::F32,
    };
    let mut ws = connect(&server.ws_url(&fed), &fed.token).await.unwrap();
    ws.send(Message::binary(frame.encode())).await.unwrap();
    let session = |id: &str| server.registry.get(id);
    let deadline = Instant::now() + Duration::from_secs(20);
    while !session(&fed.id).unwrap().ever_fed() {
        assert!(Instant::now() < deadline, "the frame was never accepted");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    ws.close(None).await.unwrap();
    let _viewer = connect(&server.ws_url(&watched), &watched.token)
        .await
        .unwrap();

    // The reaper's own tick is 5 s; this test calls it when it wants.
    server.registry.reap();
    assert!(session(&never_fed.id).is_some(), "removed before its time");
    tokio::time::sleep(Duration::from_millis(700)).await;
    server.registry.reap();
    assert!(
        session(&never_fed.id).is_none(),
        "a never-fed session stays"
    );
    let fed_state = || session(&fed.id).map(|s| s.state());
    while fed_state() != Some(SessionState::Finished) {
        assert!(Instant::now() < deadline, "fed session: {:?}", fed_state());
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert_eq!(
        session(&watched.id).map(|s| s.state()),
        Some(SessionState::Running)
    );
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_zero_idle_timeout_never_ends_a_session() {
    let server = server_with(|l| l.idle_timeout_s = 0.0).await;
    let s = server
        .create(&scene("uca8", 1.0, 1, 3), settings(1), None)
        .await;
    tokio::time::sleep(Duration::from_millis(100)).await;
    server.registry.reap();
    assert_eq!(
        server.registry.get(&s.id).map(|s| s.state()),
        Some(SessionState::Running)
    );
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn creations_past_the_rate_are_refused_and_the_server_goes_on() {
    let server = server_with(|l| l.session_creations_per_min = 3.0).await;
    let sc = scene("uca8", 1.0, 1, 3);
    for _ in 0..3 {
        server.create(&sc, settings(1), None).await;
    }
    let body = serde_json::to_vec(&create_body(&sc.layout, Some(settings(1)))).unwrap();
    let r = http(&server.host(), "POST", "/v1/sessions", None, Some(&body))
        .await
        .unwrap();
    assert_eq!(r.status, 429, "{}", r.text());
    let e: avsep::protocol::rest::ErrorResponse = r.json().unwrap();
    assert_eq!(e.error.code, "rate_limited");
    assert!(e.error.message.contains("session_creations_per_min"));
    assert_eq!(server.registry.list().len(), 3);
    server.stop().await;
}

/// The test settings with a stream cap of `streams`.
fn capped(streams: usize) -> avsep::pipeline::PipelineConfig {
    let mut s = settings(1);
    s.separate.lifecycle.max_streams = streams;
    s
}

/// The memory bound of a session on `sc` with a stream cap of `streams` (pipeline and buffers,
/// at the default limits but for the budget).
fn memory_bound(sc: &avsep::scene::Scene, streams: usize) -> usize {
    let c = ServerConfig::default();
    avsep::server::budget::session_bound(&c.limits, &c.execution, &sc.layout, &capped(streams))
        .unwrap()
}

/// A settings patch that sets the stream cap to `streams`.
fn cap_patch(streams: usize) -> Vec<u8> {
    let p = serde_json::json!({"separate": {"lifecycle": {"max_streams": streams}}});
    serde_json::to_vec(&p).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sessions_past_the_memory_budget_are_refused_and_the_others_go_on() {
    let sc = scene("uca8", 1.0, 1, 3);
    let bound = |streams: usize| memory_bound(&sc, streams);
    // Room for a session with a stream cap of 4 and one with a cap of 1, not for two of 4,
    // nor for one of 16.
    let budget = bound(4) + bound(1);
    assert!(2 * bound(4) > budget && bound(16) > budget);
    let server = server_with(|l| l.max_memory_mb = budget.div_ceil(1 << 20)).await;
    let budget = budget.div_ceil(1 << 20) << 20;
    assert!(2 * bound(4) > budget && bound(16) > budget, "rounding");
    let first = server.create(&sc, capped(4), None).await;
    let host = server.host();
    let token = Some(first.token.as_str());
    let info = http(
        &host,
        "GET",
        &format!("/v1/sessions/{}", first.id),
        token,
        None,
    )
    .await
    .unwrap();
    let info: avsep::protocol::rest::SessionInfo = info.json().unwrap();
    assert_eq!(info.memory_bound_bytes, bound(4) as u64);

    let refused = |r: avsep::server::client::HttpResponse| {
        assert_eq!(r.status, 503, "{}", r.text());
        let e: avsep::protocol::rest::ErrorResponse = r.json().unwrap();
        assert_eq!(e.error.code, "memory_budget");
        assert!(
            e.error.message.contains("limits.max_memory_mb"),
            "{}",
            e.error.message
        );
    };
    let post = async |streams: usize| {
        let body = serde_json::to_vec(&create_body(&sc.layout, Some(capped(streams)))).unwrap();
        http(&host, "POST", "/v1/sessions", None, Some(&body)).await
    };
    refused(post(4).await.unwrap());
    assert_eq!(server.registry.list().len(), 1);

    // A settings change that raises the bound past the budget is refused and changes nothing;
    // one that lowers it is applied and makes room for the second session.
    let path = format!("/v1/sessions/{}/settings", first.id);
    refused(
        http(&host, "PATCH", &path, token, Some(&cap_patch(16)))
            .await
            .unwrap(),
    );
    let session = server.registry.get(&first.id).unwrap();
    assert_eq!(session.settings().separate.lifecycle.max_streams, 4);
    let narrower = http(&host, "PATCH", &path, token, Some(&cap_patch(1)))
        .await
        .unwrap();
    assert_eq!(narrower.status, 200, "{}", narrower.text());
    let second = post(4).await.unwrap();
    assert_eq!(second.status, 201, "{}", second.text());
    refused(post(1).await.unwrap());
    let metrics = http(&host, "GET", "/metrics", None, None).await.unwrap();
    let line = format!("avsep_sessions_memory_bound_bytes {}", bound(1) + bound(4));
    assert!(
        metrics.text().lines().any(|l| l == line),
        "{}",
        metrics.text()
    );
    // A recalibration that spreads the microphones grows the localiser's tables past the room
    // left: refused, and the calibration stays.
    let array = &sc.layout.arrays[0];
    let centre = array.centroid();
    let spread: Vec<[f64; 3]> = array
        .mics
        .iter()
        .map(|m| {
            let p = centre + (m - centre) * 30.0;
            [p.x, p.y, p.z]
        })
        .collect();
    let body = serde_json::to_vec(&serde_json::json!({ "mics": spread })).unwrap();
    let put = format!("/v1/sessions/{}/arrays/{}", first.id, array.id);
    refused(http(&host, "PUT", &put, token, Some(&body)).await.unwrap());
    assert_eq!(session.layout().arrays[0].mics, array.mics);
    assert_eq!(session.state(), SessionState::Running);
    server.stop().await;
}

/// Two sessions ask at once to raise their stream caps, with room for one: one change is
/// admitted and the other refused, whichever comes first (an admitted change counts for its
/// session from its admission until it is in force).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn concurrent_changes_cannot_pass_the_memory_budget_together() {
    let sc = scene("uca8", 1.0, 1, 3);
    let bound = |streams: usize| memory_bound(&sc, streams);
    let budget = (bound(1) + bound(8) + (1 << 20)) >> 20;
    assert!(2 * bound(8) > budget << 20);
    let server = server_with(|l| l.max_memory_mb = budget).await;
    let a = server.create(&sc, capped(1), None).await;
    let b = server.create(&sc, capped(1), None).await;
    let host = server.host();
    let body = cap_patch(8);
    let patch = |s: &avsep::protocol::rest::SessionCreated| {
        let path = format!("/v1/sessions/{}/settings", s.id);
        let (host, body, token) = (host.clone(), body.clone(), s.token.clone());
        tokio::spawn(async move {
            http(&host, "PATCH", &path, Some(&token), Some(&body))
                .await
                .unwrap()
                .status
        })
    };
    let (ra, rb) = (patch(&a), patch(&b));
    let mut statuses = [ra.await.unwrap(), rb.await.unwrap()];
    statuses.sort_unstable();
    assert_eq!(statuses, [200, 503]);
    let caps: Vec<usize> = [&a, &b]
        .iter()
        .map(|s| {
            server
                .registry
                .get(&s.id)
                .unwrap()
                .settings()
                .separate
                .lifecycle
                .max_streams
        })
        .collect();
    assert!(caps == [1, 8] || caps == [8, 1], "{caps:?}");
    server.stop().await;
}

/// While its pipeline is held, a session takes a dense detections message into its queue and
/// refuses the next two, which would take the queue past `limits.queue_bytes`, with `queue_full`
/// naming the limit; its audio goes on being accepted, and once the pipeline goes on the session
/// processes everything it accepted.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_input_queue_holds_at_most_queue_bytes() {
    let server = server_with(|l| {
        l.max_message_bytes = 256 << 10;
        l.queue_bytes = 1 << 20;
        l.max_measurements = 10_000;
    })
    .await;
    let sc = scene("uca8", 1.0, 1, 5);
    let pipeline = Pipeline::new(sc.layout.clone(), settings(5), 5).unwrap();
    let (token, id) = ("c".repeat(64), "0c0c0c0c0c0c0c0c");
    let spec = hand_made_spec(&server, id, "queued", &token, &sc, &pipeline);
    let (engine, release) = Hooked::held_after_first_step(pipeline);
    server.registry.insert(spec, engine).unwrap();

    // 7,000 boxes: about 210 kB of JSON, 504 kB decoded; one fits beside the audio, two do not.
    let camera = &sc.layout.cameras[0].id;
    let boxes = vec![r#"{"x":10,"y":10,"w":20,"h":20}"#; 7000].join(",");
    let dense = |t: f64| FeedItem {
        due_s: 0.0,
        message: FeedMessage::Json(format!(
            r#"{{"type":"detections","t":{t},"camera":"{camera}","boxes":[{boxes}]}}"#
        )),
    };
    let mut feed = scene_feed(&sc, 1024, SampleEncoding::F32);
    let k = feed
        .iter()
        .position(|i| matches!(i.message, FeedMessage::Audio { end: 4096, .. }))
        .unwrap();
    // Between the scene's camera frames at 0.2 s and 0.267 s.
    let inserted = [0.21, 0.22, 0.23].map(dense);
    feed.splice(k + 1..k + 1, inserted);
    let url = format!("ws://{}/v1/sessions/{id}/stream", server.host());
    let (feed_token, opts) = (token.clone(), StreamOptions::default());
    let run = tokio::spawn(async move { stream_feed(&url, &feed_token, &feed, &opts).await });

    let (host, path) = (server.host(), format!("/v1/sessions/{id}/metrics"));
    let metrics = async || -> SessionMetrics {
        let r = http(&host, "GET", &path, Some(&token), None);
        r.await.unwrap().json().unwrap()
    };
    let deadline = Instant::now() + Duration::from_secs(20);
    let held = loop {
        let m = metrics().await;
        if m.refused.get("queue_full") == Some(&2) {
            break m;
        }
        assert!(Instant::now() < deadline, "never refused: {m:?}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    assert_eq!(held.queue_bytes_capacity, 1 << 20);
    assert!(
        (500_000..=1 << 20).contains(&held.queue_bytes),
        "{}",
        held.queue_bytes
    );
    release.send(()).unwrap();
    let got = run.await.unwrap().unwrap();
    assert_eq!(got.errors.len(), 2, "{:?}", got.errors);
    for e in &got.errors {
        assert_eq!(e.code, "queue_full");
        assert!(e.message.contains("limits.queue_bytes"), "{}", e.message);
    }
    // Every step of the scene's second was processed, and the queue is empty.
    assert_eq!(got.tracks.len(), 8);
    let after = metrics().await;
    assert_eq!((after.queue_bytes, after.queue_depth), (0, 0));
    assert_eq!(after.refused.values().sum::<u64>(), 2);
    server.stop().await;
}

/// A client that sets a long lead (`max_lead_s`) and sends camera frames far ahead of its
/// audio holds at most `limits.sensor_backlog_bytes` of them in the session: the frames past
/// it are refused with `backlog_full` naming the limit, and the session goes on with its
/// audio and the frames it took.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_ahead_of_the_audio_hold_at_most_the_sensor_backlog() {
    let backlog = 8 << 10;
    let server = server_with(|l| {
        // The backlog must hold one frame of the most boxes.
        (l.sensor_backlog_bytes, l.max_measurements) = (backlog, 64);
    })
    .await;
    let sc = scene("uca8", 1.0, 1, 7);
    let cfg = avsep::pipeline::PipelineConfig {
        max_lead_s: 3600.0,
        ..settings(7)
    };
    let session = server.create(&sc, cfg, None).await;
    // The scene's audio alone, and right after its first block 100 frames of 20 faces each
    // from 0.5 s on, ahead of the audio but within the lead.
    let mut feed: Vec<FeedItem> = scene_feed(&sc, 1024, SampleEncoding::F32)
        .into_iter()
        .filter(|i| matches!(i.message, FeedMessage::Audio { .. }))
        .collect();
    let camera = &sc.layout.cameras[0].id;
    let boxes = vec![r#"{"x":10,"y":10,"w":20,"h":20}"#; 20].join(",");
    let ahead = (0..100).map(|i| FeedItem {
        due_s: 0.0,
        message: FeedMessage::Json(format!(
            r#"{{"type":"detections","t":{},"camera":"{camera}","boxes":[{boxes}]}}"#,
            0.5 + 0.004 * f64::from(i)
        )),
    });
    feed.splice(1..1, ahead);
    let opts = StreamOptions::default();
    let url = server.ws_url(&session);
    let got = stream_feed(&url, &session.token, &feed, &opts)
        .await
        .unwrap();

    let frame = avsep::scene::DetectionFrame {
        t: 0.0,
        camera: 0,
        boxes: Vec::new(),
    };
    let held = size_of_val(&frame) + 20 * size_of::<avsep::scene::FaceBox>();
    let fits = backlog / held;
    assert!((1..100).contains(&fits), "{fits}");
    assert_eq!(got.errors.len(), 100 - fits, "{:?}", got.errors);
    for e in &got.errors {
        assert_eq!(
            (e.code.as_str(), e.field.as_deref()),
            ("backlog_full", Some("t"))
        );
        assert!(
            e.message.contains("limits.sensor_backlog_bytes"),
            "{}",
            e.message
        );
    }
    // Every step of the scene's second ran, and the frames it took reached the tracker.
    assert_eq!(got.tracks.len(), 8);
    let (host, path) = (
        server.host(),
        format!("/v1/sessions/{}/metrics", session.id),
    );
    let r = http(&host, "GET", &path, Some(&session.token), None);
    let m: SessionMetrics = r.await.unwrap().json().unwrap();
    assert_eq!(m.refused.get("backlog_full"), Some(&((100 - fits) as u64)));
    server.stop().await;
}
