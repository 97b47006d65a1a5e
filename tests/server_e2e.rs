//! End to end over real sockets: a server on 127.0.0.1:0, sessions created over REST from a
//! simulated scene's layout, the scene streamed over WebSocket, and what comes back compared
//! with the offline run (`process_scene`) of the same scene: tracks identical (labels, positions
//! within 1e-9 m) and separated audio identical (f32 on the wire, tolerance 0).

mod server_support;

use std::time::Duration;

use avsep::protocol::{AudioSelection, OutputSelection, SampleEncoding};
use avsep::server::ServerConfig;
use avsep::server::client::{
    FeedMessage, StreamOptions, http, resume_index, scene_feed, stream_feed,
};
use server_support::{
    TestServer, assert_same_tracks, audio_difference, offline, scene, settings, spawn_listener,
};

fn with_audio() -> OutputSelection {
    OutputSelection {
        audio: Some(AudioSelection {
            format: SampleEncoding::F32,
            labels: None,
        }),
        ..Default::default()
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn streamed_session_equals_offline_run_fast_and_paced() {
    let server = TestServer::start(ServerConfig::default()).await;
    // Faster than real time (paced only by the session's own progress), 3 s of uca8.
    let sc = scene("uca8", 3.0, 3, 21);
    let (tracks, audio) = offline(&sc, settings(5));
    let s = server.create(&sc, settings(5), None).await;
    let feed = scene_feed(&sc, 1024, SampleEncoding::F32);
    let opts = StreamOptions {
        outputs: with_audio(),
        ..Default::default()
    };
    let got = stream_feed(&server.ws_url(&s), &s.token, &feed, &opts)
        .await
        .unwrap();
    assert!(got.errors.is_empty(), "{:?}", got.errors);
    assert_eq!(
        got.close.as_ref().map(|c| c.0),
        Some(1000),
        "closed normally after finish"
    );
    assert_same_tracks(&tracks, &got.tracks);
    let n = sc.audio.as_ref().unwrap().frames();
    assert_eq!(audio_difference(&audio, &got.audio_by_label(n)), 0.0);

    // Paced in real time, 2 s: the same result, and the session keeps up.
    let sc = scene("uca8", 2.0, 2, 22);
    let (tracks, audio) = offline(&sc, settings(6));
    let s = server.create(&sc, settings(6), None).await;
    let feed = scene_feed(&sc, 1024, SampleEncoding::F32);
    let opts = StreamOptions {
        realtime: true,
        outputs: with_audio(),
        ..Default::default()
    };
    let t0 = std::time::Instant::now();
    let got = stream_feed(&server.ws_url(&s), &s.token, &feed, &opts)
        .await
        .unwrap();
    assert!(
        t0.elapsed() >= Duration::from_millis(1900),
        "paced in real time"
    );
    assert!(got.errors.is_empty(), "{:?}", got.errors);
    assert_same_tracks(&tracks, &got.tracks);
    let n = sc.audio.as_ref().unwrap().frames();
    assert_eq!(audio_difference(&audio, &got.audio_by_label(n)), 0.0);
    let m = server.metrics(&s).await;
    assert_eq!(m.steps as usize, tracks.len());
    assert!(
        m.step_latency_ms.count > 0 && m.step_latency_ms.p99 < 128.0,
        "{:?}",
        m.step_latency_ms
    );
    assert!(m.refused.is_empty(), "{:?}", m.refused);
    // The separation ran on its own thread and drained its queue before the stream closed.
    let execution = ServerConfig::default().execution;
    assert!(execution.separation_thread);
    assert_eq!(m.separation_queue_capacity, execution.separation_queue);
    assert_eq!(m.separation_queue_depth, 0);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn concurrent_sessions_stay_isolated() {
    let server = TestServer::start(ServerConfig::default()).await;
    let a = scene("uca8", 2.5, 3, 31);
    let b = scene("single", 2.5, 1, 32);
    let (ta, aa) = offline(&a, settings(1));
    let (tb, ab) = offline(&b, settings(2));
    let sa = server.create(&a, settings(1), None).await;
    let sb = server.create(&b, settings(2), None).await;
    let (fa, fb) = (
        scene_feed(&a, 1024, SampleEncoding::F32),
        scene_feed(&b, 1024, SampleEncoding::F32),
    );
    let opts = StreamOptions {
        outputs: with_audio(),
        ..Default::default()
    };
    let (ua, ub) = (server.ws_url(&sa), server.ws_url(&sb));
    let (ra, rb) = tokio::join!(
        stream_feed(&ua, &sa.token, &fa, &opts),
        stream_feed(&ub, &sb.token, &fb, &opts)
    );
    let (ra, rb) = (ra.unwrap(), rb.unwrap());
    assert_same_tracks(&ta, &ra.tracks);
    assert_same_tracks(&tb, &rb.tracks);
    assert_eq!(
        audio_difference(&aa, &ra.audio_by_label(a.audio.as_ref().unwrap().frames())),
        0.0
    );
    assert_eq!(
        audio_difference(&ab, &rb.audio_by_label(b.audio.as_ref().unwrap().frames())),
        0.0
    );
    // A token opens its own session only.
    let r = http(
        &server.host(),
        "GET",
        &format!("/v1/sessions/{}", sb.id),
        Some(&sa.token),
        None,
    )
    .await
    .unwrap();
    assert_eq!(r.status, 403);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn reconnecting_client_resumes_its_session() {
    let server = TestServer::start(ServerConfig::default()).await;
    let sc = scene("uca8", 3.0, 2, 41);
    let (tracks, audio) = offline(&sc, settings(3));
    let s = server.create(&sc, settings(3), None).await;
    let url = server.ws_url(&s);

    // A listener stays connected throughout and sees everything the session produces.
    let listener = spawn_listener(&url, &s.token, with_audio(), 120).await;

    // The source streams half the scene, then drops its connection without finishing.
    let feed = scene_feed(&sc, 1024, SampleEncoding::F32);
    let half = feed
        .iter()
        .enumerate()
        .filter(|(_, i)| matches!(i.message, FeedMessage::Audio { .. }))
        .map(|(k, _)| k + 1)
        .nth(feed.len() / 4)
        .unwrap();
    let first = StreamOptions {
        disconnect_at: Some(half),
        ..Default::default()
    };
    let part1 = stream_feed(&url, &s.token, &feed, &first).await.unwrap();
    assert_eq!(part1.sent, half);

    // It reconnects: the welcome says where to resume; the steps run meanwhile come from the
    // history; the rest of the stream follows on the new connection.
    tokio::time::sleep(Duration::from_millis(300)).await;
    let resume = StreamOptions::default();
    let mut ws = avsep::server::client::connect(&url, &s.token)
        .await
        .unwrap();
    use futures_util::StreamExt;
    let welcome = ws.next().await.unwrap().unwrap();
    drop(ws);
    let next_sample = match serde_json::from_str(welcome.to_text().unwrap()).unwrap() {
        avsep::protocol::ServerMessage::Welcome { next_sample, .. } => next_sample,
        m => panic!("{m:?}"),
    };
    let expected_end = match &feed[half - 1].message {
        FeedMessage::Audio { end, .. } => *end,
        _ => unreachable!(),
    };
    assert_eq!(
        next_sample, expected_end,
        "welcome.next_sample is where the source stopped"
    );
    let from = resume_index(&feed, next_sample);
    assert_eq!(from, half);
    let part2 = stream_feed(&url, &s.token, &feed, &StreamOptions { from, ..resume })
        .await
        .unwrap();
    assert!(part2.errors.is_empty(), "{:?}", part2.errors);

    // What the source saw, with the gap filled from the history, is the offline run.
    let seen_last = part1.tracks.last().map_or(0, |t| t.step + 1);
    let gap_end = part2.tracks.first().map_or(u64::MAX, |t| t.step);
    let hist = http(
        &server.host(),
        "GET",
        &format!("/v1/sessions/{}/tracks/history?from_step={seen_last}", s.id),
        Some(&s.token),
        None,
    )
    .await
    .unwrap();
    let hist: avsep::protocol::rest::TrackHistory = hist.json().unwrap();
    let mut source_view = part1.tracks.clone();
    source_view.extend(hist.steps.into_iter().filter(|t| t.step < gap_end));
    source_view.extend(part2.tracks.iter().cloned());
    assert_same_tracks(&tracks, &source_view);

    // The listener's view is complete: identical tracks and audio.
    let heard = listener.await.unwrap().unwrap();
    assert_same_tracks(&tracks, &heard.tracks);
    let n = sc.audio.as_ref().unwrap().frames();
    assert_eq!(audio_difference(&audio, &heard.audio_by_label(n)), 0.0);
    server.stop().await;
}

/// A face detector reporting 20 false boxes a frame (the tracker was told to expect one): the
/// session's metrics show the camera's clutter rate as the tracker estimated it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_noisy_face_detector_shows_in_the_session_metrics() {
    use rand::{Rng, SeedableRng};
    let server = TestServer::start(ServerConfig::default()).await;
    let mut sc = scene("uca8", 3.0, 2, 23);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
    let cam = sc.layout.cameras[0].clone();
    for frame in &mut sc.detections {
        for _ in 0..20 {
            frame.boxes.push(avsep::scene::FaceBox {
                x: rng.random_range(0.0..cam.width - 40.0),
                y: rng.random_range(0.0..cam.height - 48.0),
                w: rng.random_range(20.0..40.0),
                h: rng.random_range(24.0..48.0),
                score: None,
                point: None,
            });
        }
    }
    let mut cfg = settings(7);
    cfg.separation = false;
    let s = server.create(&sc, cfg, None).await;
    let feed = scene_feed(&sc, 1024, SampleEncoding::F32);
    let got = stream_feed(
        &server.ws_url(&s),
        &s.token,
        &feed,
        &StreamOptions::default(),
    )
    .await
    .unwrap();
    assert!(got.errors.is_empty(), "{:?}", got.errors);
    let m = server.metrics(&s).await;
    let cam = m.clutter.iter().find(|c| c.sensor == cam.id);
    let cam = cam.unwrap_or_else(|| panic!("no clutter rate for the camera: {:?}", m.clutter));
    assert_eq!(cam.configured, 1.0);
    assert!(cam.scans > 0, "{cam:?}");
    // 3 s of steps take the running mean (time constant 2 s) most of the way from 1 to 20.
    assert!(cam.estimated > 10.0 && cam.estimated < 25.0, "{cam:?}");
    server.stop().await;
}
