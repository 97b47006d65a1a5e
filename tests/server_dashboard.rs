//! The dashboard over a real socket: `/` and every file it loads, with their content types;
//! the demo room's discovery endpoint and its live session; the camera-detections endpoint.

mod server_support;

use std::time::{Duration, Instant};

use avsep::protocol::rest::{SessionInfo, SessionMetrics};
use avsep::server::ServerConfig;
use avsep::server::client::http;
use avsep::server::demo::{self, DemoOptions};
use server_support::TestServer;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

/// A raw GET: status, lower-cased headers, body.
async fn get(host: &str, path: &str) -> (u16, Vec<(String, String)>, String) {
    let mut tcp = TcpStream::connect(host).await.unwrap();
    let req = format!("GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n");
    tcp.write_all(req.as_bytes()).await.unwrap();
    let mut raw = Vec::new();
    tcp.read_to_end(&mut raw).await.unwrap();
    let text = String::from_utf8(raw).unwrap();
    let (head, body) = text.split_once("\r\n\r\n").unwrap();
    let mut lines = head.lines();
    let status = lines
        .next()
        .unwrap()
        .split_whitespace()
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    let headers = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect();
    (status, headers, body.to_string())
}

fn header<'a>(headers: &'a [(String, String)], name: &str) -> &'a str {
    headers
        .iter()
        .find(|(k, _)| k == name)
        .map_or("", |(_, v)| v.as_str())
}

/// Quoted strings in `text` that start with `prefix` and end with `suffix`.
fn references(text: &str, prefix: &str, suffix: &str) -> Vec<String> {
    text.split(['"', '\''])
        .filter(|s| s.starts_with(prefix) && s.ends_with(suffix))
        .map(str::to_string)
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn index_and_every_module_it_loads_are_served_with_their_types() {
    let server = TestServer::start(ServerConfig::default()).await;
    let host = server.host();
    let (status, headers, index) = get(&host, "/").await;
    assert_eq!(status, 200);
    assert_eq!(header(&headers, "content-type"), "text/html; charset=utf-8");
    assert!(header(&headers, "content-security-policy").contains("default-src 'self'"));
    let top = references(&index, "/dashboard/assets/", "");
    assert!(top.iter().any(|p| p.ends_with("/main.js")), "{top:?}");
    assert!(top.iter().any(|p| p.ends_with("/style.css")), "{top:?}");

    // Follow the module graph from main.js: every import resolves to a served module.
    let mut queue: Vec<String> = top;
    let mut seen = std::collections::BTreeSet::new();
    while let Some(path) = queue.pop() {
        if !seen.insert(path.clone()) {
            continue;
        }
        let (status, headers, body) = get(&host, &path).await;
        assert_eq!(status, 200, "{path}");
        assert!(!body.trim().is_empty(), "{path} is empty");
        assert_eq!(header(&headers, "x-content-type-options"), "nosniff");
        let expected = if path.ends_with(".js") {
            "text/javascript; charset=utf-8"
        } else {
            "text/css; charset=utf-8"
        };
        assert_eq!(header(&headers, "content-type"), expected, "{path}");
        if path.ends_with(".js") {
            for import in references(&body, "./", ".js") {
                queue.push(format!("/dashboard/assets/{}", &import[2..]));
            }
        }
    }
    for module in [
        "api", "stream", "roommap", "camera", "audio", "metrics", "live",
    ] {
        assert!(
            seen.contains(&format!("/dashboard/assets/{module}.js")),
            "{module}.js is not reached from main.js: {seen:?}"
        );
    }

    let (status, headers, body) = get(&host, "/dashboard/assets/nope.js").await;
    assert_eq!(status, 404);
    assert!(header(&headers, "content-type").starts_with("application/json"));
    assert!(body.contains("not_found"), "{body}");
    // No demo without --demo.
    let (status, _, body) = get(&host, "/dashboard/api/demo").await;
    assert_eq!(status, 404, "{body}");
    assert!(body.contains("no_demo"));
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn demo_room_is_discoverable_and_streams_in_real_time() {
    let cfg = ServerConfig {
        admin_key: Some("k".repeat(20)),
        ..Default::default()
    };
    let key = cfg.admin_key.clone().unwrap();
    let server = TestServer::start(cfg).await;
    let host = server.host();
    let opts = DemoOptions {
        preset: "single".into(),
        duration_s: 2.0,
        ..Default::default()
    };
    let access = demo::start(server.registry.clone(), opts).await.unwrap();
    let started = Instant::now();
    demo_is_listed_to_the_admin_only(&host, &key, &access).await;

    // The token opens the session; audio arrives at the real-time rate, and loops past the
    // 2 s scene without being refused.
    let path = format!("/v1/sessions/{}", access.id);
    tokio::time::sleep(Duration::from_millis(3000)).await;
    let (info, fed_s) = demo_is_fed_in_real_time(&host, &path, &access, started).await;
    camera_panel_shows_the_latest_frame(&host, &access, &info, fed_s).await;

    // Deleting the demo session stops the feeder and withdraws the token.
    let r = http(&host, "DELETE", &path, Some(&key), None)
        .await
        .unwrap();
    assert_eq!(r.status, 204);
    let r = http(&host, "GET", "/dashboard/api/demo", Some(&key), None)
        .await
        .unwrap();
    assert_eq!(r.status, 404);
    server.stop().await;
}

/// The demo's token is given only to whoever may list sessions: here the admin key's holder.
async fn demo_is_listed_to_the_admin_only(host: &str, key: &str, access: &demo::DemoAccess) {
    let r = http(host, "GET", "/dashboard/api/demo", None, None)
        .await
        .unwrap();
    assert_eq!(r.status, 401, "{}", r.text());
    let r = http(host, "GET", "/dashboard/api/demo", Some(key), None)
        .await
        .unwrap();
    assert_eq!(r.status, 200, "{}", r.text());
    let listed: serde_json::Value = r.json().unwrap();
    assert_eq!(listed["id"], access.id.as_str());
    assert_eq!(listed["token"], access.token.as_str());
}

/// Checks the demo session at `path` has been fed audio at the real-time rate since `started`,
/// with nothing refused; returns its info and the seconds of audio fed.
async fn demo_is_fed_in_real_time(
    host: &str,
    path: &str,
    access: &demo::DemoAccess,
    started: Instant,
) -> (SessionInfo, f64) {
    let r = http(host, "GET", path, Some(&access.token), None)
        .await
        .unwrap();
    let info: SessionInfo = r.json().unwrap();
    let elapsed = started.elapsed().as_secs_f64();
    let fed_s = info.next_sample as f64 / f64::from(info.sample_rate);
    assert!(
        fed_s > elapsed - 0.5 && fed_s < elapsed + 0.2,
        "fed {fed_s:.2} s of audio in {elapsed:.2} s"
    );
    assert!(fed_s > 2.0, "the 2 s scene loops ({fed_s:.2} s fed)");
    assert_eq!(info.name.as_deref(), Some("demo (single)"));
    let r = http(
        host,
        "GET",
        &format!("{path}/metrics"),
        Some(&access.token),
        None,
    )
    .await
    .unwrap();
    let m: SessionMetrics = r.json().unwrap();
    assert!(m.steps > 10, "{m:?}");
    assert!(m.refused.is_empty(), "nothing refused: {:?}", m.refused);
    assert_eq!(m.clients, 1, "the feeder is the session's one client");
    (info, fed_s)
}

/// The camera panel's endpoint gives the latest frame of the session's camera, close to the
/// `fed_s` seconds of audio fed, and refuses another token.
async fn camera_panel_shows_the_latest_frame(
    host: &str,
    access: &demo::DemoAccess,
    info: &SessionInfo,
    fed_s: f64,
) {
    let r = http(
        host,
        "GET",
        &format!("/dashboard/api/sessions/{}/detections", access.id),
        Some(&access.token),
        None,
    )
    .await
    .unwrap();
    assert_eq!(r.status, 200, "{}", r.text());
    let d: serde_json::Value = r.json().unwrap();
    let cams = d["cameras"].as_array().unwrap();
    assert_eq!(cams.len(), info.cameras.len());
    assert_eq!(cams[0]["camera"], info.cameras[0].id.as_str());
    let t = cams[0]["t"].as_f64().unwrap();
    assert!(
        (t - fed_s).abs() < 0.5,
        "latest frame at {t} s, audio at {fed_s} s"
    );
    let r = http(
        host,
        "GET",
        &format!("/dashboard/api/sessions/{}/detections", access.id),
        Some(&"x".repeat(64)),
        None,
    )
    .await
    .unwrap();
    assert_eq!(r.status, 403);
}
