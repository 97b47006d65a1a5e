//! The bounds on sessions themselves: sessions nobody uses end by themselves
//! (`limits.idle_timeout_s`): one never fed is removed, one fed and left finishes (its results
//! stay readable), and one with a client connected runs on however quiet it is; and creations
//! past `limits.session_creations_per_min` are refused.

mod server_support;

use std::time::{Duration, Instant};

use avsep::protocol::rest::SessionState;
use avsep::protocol::{AudioFrame, SampleEncoding};
use avsep::server::client::{connect, create_body, http};
use avsep::server::{Limits, ServerConfig};
use futures_util::SinkExt;
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
