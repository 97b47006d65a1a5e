//! Bad input over the stream and over REST: each gets an error that names the problem, and the
//! session keeps processing the valid input that follows (the result still equals the offline
//! run, since nothing refused touches the session).

mod server_support;

use avsep::protocol::{AudioFrame, ErrorBody, SampleEncoding};
use avsep::server::client::{FeedItem, FeedMessage, StreamOptions, http, scene_feed, stream_feed};
use avsep::server::{Limits, ServerConfig};
use server_support::{TestServer, assert_same_tracks, offline, scene, settings};

fn bad_audio(bytes: Vec<u8>, end: u64) -> FeedItem {
    FeedItem {
        due_s: 0.0,
        message: FeedMessage::Audio { bytes, end },
    }
}

fn bad_json(text: &str) -> FeedItem {
    FeedItem {
        due_s: 0.0,
        message: FeedMessage::Json(text.to_string()),
    }
}

/// The error `code` naming `field`, whose message says `text`.
fn find_saying(errors: &[ErrorBody], code: &str, field: &str, text: &str) {
    let e = find(errors, code, Some(field));
    assert!(e.message.contains(text), "{e:?}");
}

fn find<'a>(errors: &'a [ErrorBody], code: &str, field: Option<&str>) -> &'a ErrorBody {
    errors
        .iter()
        .find(|e| e.code == code && e.field.as_deref() == field)
        .unwrap_or_else(|| panic!("no error {code} {field:?} among {errors:#?}"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_stream_input_is_refused_by_name_and_valid_input_goes_on() {
    let cfg = ServerConfig {
        limits: Limits {
            max_audio_samples: 8 * 2048,
            ..Limits::default()
        },
        ..ServerConfig::default()
    };
    let server = TestServer::start(cfg).await;
    let sc = scene("uca8", 2.0, 2, 51);
    let (tracks, _) = offline(&sc, settings(9));
    let s = server.create(&sc, settings(9), None).await;
    let feed = scene_feed(&sc, 1024, SampleEncoding::F32);
    // Where the audio of samples [4096, 5120) is sent: bad messages go just after it.
    let k = feed
        .iter()
        .position(|i| matches!(i.message, FeedMessage::Audio { end: 5120, .. }))
        .unwrap();
    let inserted = bad_messages(&sc);
    let mut with_errors = feed[..=k].to_vec();
    with_errors.extend(inserted);
    with_errors.extend(feed[k + 1..].iter().cloned());

    let got = stream_feed(
        &server.ws_url(&s),
        &s.token,
        &with_errors,
        &StreamOptions::default(),
    )
    .await
    .unwrap();
    every_refusal_is_named(&got.errors);

    // Every refusal left the session untouched: the valid input around them gives exactly the
    // offline result.
    assert_same_tracks(&tracks, &got.tracks);
    let m = server.metrics(&s).await;
    assert_eq!(m.refused.values().sum::<u64>(), 15, "{:?}", m.refused);
    assert_eq!(m.refused["truncated"], 2);
    server.stop().await;
}

/// A REST client of the test server with the admin key and a valid session-creation body.
struct Rest {
    host: String,
    key: &'static str,
    body: Vec<u8>,
}

type Response = avsep::server::client::HttpResponse;
type Created = avsep::protocol::rest::SessionCreated;

impl Rest {
    async fn call(
        &self,
        method: &str,
        path: &str,
        auth: Option<&str>,
        body: Option<&[u8]>,
    ) -> Response {
        http(&self.host, method, path, auth, body).await.unwrap()
    }

    async fn post(&self, auth: Option<&str>, body: &[u8]) -> Response {
        self.call("POST", "/v1/sessions", auth, Some(body)).await
    }

    /// The valid creation body with `edit` applied, posted with the admin key.
    async fn post_edited(&self, edit: impl FnOnce(&mut serde_json::Value)) -> Response {
        let mut bad: serde_json::Value = serde_json::from_slice(&self.body).unwrap();
        edit(&mut bad);
        self.post(Some(self.key), &serde_json::to_vec(&bad).unwrap())
            .await
    }

    async fn send_json(
        &self,
        method: &str,
        path: String,
        token: &str,
        b: serde_json::Value,
    ) -> Response {
        let b = serde_json::to_vec(&b).unwrap();
        self.call(method, &path, Some(token), Some(&b)).await
    }
}

fn err(r: &Response) -> ErrorBody {
    r.json::<avsep::protocol::rest::ErrorResponse>()
        .unwrap()
        .error
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_rest_requests_get_statuses_that_name_the_problem() {
    let key = "an-admin-key-of-some-length";
    let cfg = ServerConfig {
        admin_key: Some(key.into()),
        limits: Limits {
            max_body_bytes: 64 << 10,
            max_sessions: 2,
            max_clients_per_session: 1,
            ..Limits::default()
        },
        ..ServerConfig::default()
    };
    let server = TestServer::start(cfg).await;
    let sc = scene("uca8", 0.5, 1, 61);
    let rest = Rest {
        host: server.host(),
        key,
        body: serde_json::to_vec(&avsep::server::client::create_body(&sc.layout, None)).unwrap(),
    };
    credentials_are_checked(&rest).await;
    bad_bodies_are_named(&rest).await;
    let s = session_access_needs_its_token(&rest).await;
    bad_stream_upgrades_are_refused(&rest, &s).await;
    impossible_changes_are_refused(&rest, &s, &sc).await;

    // Capacity: max_sessions = 2.
    assert_eq!(rest.post(Some(key), &rest.body).await.status, 201);
    let r = rest.post(Some(key), &rest.body).await;
    assert_eq!((r.status, err(&r).code.as_str()), (503, "at_capacity"));
    assert_eq!(rest.call("GET", "/readyz", None, None).await.status, 503);
    let r = rest.call("GET", "/v1/nothing", None, None).await;
    assert_eq!((r.status, err(&r).code.as_str()), (404, "not_found"));
    server.stop().await;
}

/// Credentials: missing 401, wrong 403, never data.
async fn credentials_are_checked(rest: &Rest) {
    let r = rest.post(None, &rest.body).await;
    assert_eq!((r.status, err(&r).code.as_str()), (401, "unauthorized"));
    let r = rest.post(Some("wrong-key-wrong-key"), &rest.body).await;
    assert_eq!((r.status, err(&r).code.as_str()), (403, "forbidden"));
    let r = rest.call("GET", "/v1/sessions", None, None).await;
    assert_eq!(r.status, 401);
    assert!(!r.text().contains("sessions\":["));
}

/// Body problems: malformed 400, wrong shape 422 naming the field, too large 413.
async fn bad_bodies_are_named(rest: &Rest) {
    let r = rest.post(Some(rest.key), b"{\"sample_rate\": ").await;
    assert_eq!((r.status, err(&r).code.as_str()), (400, "bad_json"));
    let r = rest
        .post_edited(|b| b["arrays"][0]["mics"][2] = serde_json::json!([0.0, 0.0]))
        .await;
    assert_eq!(
        (r.status, err(&r).field.as_deref()),
        (422, Some("arrays[0].mics[2]"))
    );
    let r = rest
        .post_edited(|b| b["cameras"][0]["projection"] = serde_json::Value::Null)
        .await;
    assert_eq!(
        (r.status, err(&r).field.as_deref()),
        (422, Some("cameras[0].projection"))
    );
    let r = rest
        .post_edited(|b| {
            b["settings"] = serde_json::json!({"track": {"survival_probability": 3.0}});
        })
        .await;
    assert_eq!(r.status, 422, "{}", r.text());
    assert_eq!(
        err(&r).field.as_deref(),
        Some("settings.track.survival_probability")
    );
    let r = rest
        .post_edited(|b| b["settings"] = serde_json::json!({"stepsize": 1}))
        .await;
    assert!(
        r.status == 422 && err(&r).message.contains("stepsize"),
        "{}",
        r.text()
    );
    // A frame past the server's limit, and one no pipeline can use, are named before anything
    // is sized from them.
    for (frame, says) in [(65536, "limits.max_frame"), (0, "64..=65536")] {
        let r = rest
            .post_edited(|b| b["settings"] = serde_json::json!({"localize": {"frame": frame}}))
            .await;
        assert_eq!(
            (r.status, err(&r).field.as_deref()),
            (422, Some("settings.localize.frame")),
            "{}",
            r.text()
        );
        assert!(err(&r).message.contains(says), "{}", r.text());
    }
    let r = rest.post(Some(rest.key), &vec![b' '; 70 << 10]).await;
    assert_eq!((r.status, err(&r).code.as_str()), (413, "too_large"));
    geometry_beyond_the_limits_is_named(rest).await;
}

/// Geometry that would size the localiser's tables beyond memory (microphones kilometres
/// apart, or more of them than the limit) is refused by name before anything is built.
async fn geometry_beyond_the_limits_is_named(rest: &Rest) {
    let refused_by = |r: &Response, limit: &str| {
        assert_eq!(
            (r.status, err(r).field.as_deref()),
            (422, Some("arrays[0].mics")),
            "{}",
            r.text()
        );
        assert!(err(r).message.contains(limit), "{}", r.text());
    };
    let r = rest
        .post_edited(|b| b["arrays"][0]["mics"][1] = serde_json::json!([20000.0, 0.0, 1.0]))
        .await;
    refused_by(&r, "limits.max_pair_span_m");
    let r = rest
        .post_edited(|b| {
            let mics: Vec<serde_json::Value> = (0..100)
                .map(|i| serde_json::json!([0.01 * f64::from(i), 0.0, 1.0]))
                .collect();
            b["arrays"][0]["mics"] = serde_json::Value::Array(mics);
            b["arrays"][0]["channels"] = serde_json::json!((0..100).collect::<Vec<_>>());
        })
        .await;
    refused_by(&r, "limits.max_microphones");
}

/// A session: its token (or the admin key) opens it, also as a query parameter; a wrong one
/// gets 403 and unknown ids 404; deleting needs the admin key.
async fn session_access_needs_its_token(rest: &Rest) -> Created {
    let r = rest.post(Some(rest.key), &rest.body).await;
    assert_eq!(r.status, 201);
    let s: Created = r.json().unwrap();
    let path = format!("/v1/sessions/{}", s.id);
    assert_eq!(
        rest.call("GET", &path, Some(&s.token), None).await.status,
        200
    );
    assert_eq!(
        rest.call("GET", &path, Some(rest.key), None).await.status,
        200
    );
    assert_eq!(rest.call("GET", &path, None, None).await.status, 401);
    let r = rest.call("GET", &path, Some(&s.token[..63]), None).await;
    assert_eq!(r.status, 403);
    assert!(!r.text().contains(&s.id) || err(&r).code == "forbidden");
    let r = rest
        .call("GET", &format!("{path}?token={}", s.token), None, None)
        .await;
    assert_eq!(r.status, 200, "the token also works as a query parameter");
    let r = rest
        .call("GET", "/v1/sessions/0000000000000000", Some(rest.key), None)
        .await;
    assert_eq!((r.status, err(&r).code.as_str()), (404, "not_found"));
    let r = rest.call("DELETE", &path, Some(&s.token), None).await;
    assert_eq!(
        r.status, 403,
        "deleting needs the admin key when one is configured"
    );
    s
}

/// Streams: a wrong or missing token is refused before the upgrade, a plain GET is not a
/// WebSocket, and one client is allowed (limits.max_clients_per_session = 1): the second
/// gets 429.
async fn bad_stream_upgrades_are_refused(rest: &Rest, s: &Created) {
    let url = format!("ws://{}{}", rest.host, s.stream);
    let e = avsep::server::client::connect(&url, "nope")
        .await
        .unwrap_err();
    assert!(e.0.contains("403"), "{e}");
    let e = tokio_tungstenite::connect_async(url.as_str())
        .await
        .unwrap_err();
    assert!(e.to_string().contains("401"), "{e}");
    let path = format!("/v1/sessions/{}/stream", s.id);
    let r = rest.call("GET", &path, Some(&s.token), None).await;
    assert_eq!((r.status, err(&r).code.as_str()), (400, "not_websocket"));
    let first = avsep::server::client::connect(&url, &s.token)
        .await
        .unwrap();
    let e = avsep::server::client::connect(&url, &s.token)
        .await
        .unwrap_err();
    assert!(e.0.contains("429"), "{e}");
    drop(first);
}

/// Calibration and settings: unknown sensors 404, changes that cannot happen live 409,
/// invalid values 422.
async fn impossible_changes_are_refused(rest: &Rest, s: &Created, sc: &avsep::scene::Scene) {
    let path = format!("/v1/sessions/{}", s.id);
    let put = |p: String, b: serde_json::Value| rest.send_json("PUT", p, &s.token, b);
    let r = put(
        format!("{path}/cameras/cam9"),
        serde_json::json!({"projection": [[1,0,0,0],[0,1,0,0],[0,0,1,0]]}),
    )
    .await;
    assert_eq!((r.status, err(&r).field.as_deref()), (404, Some("camera")));
    let a0 = &sc.layout.arrays[0].id;
    let r = put(
        format!("{path}/arrays/{a0}"),
        serde_json::json!({"mics": [[0, 0, 0]]}),
    )
    .await;
    assert_eq!((r.status, err(&r).field.as_deref()), (409, Some("mics")));
    // Moving one microphone 20 km away would size the localiser's tables beyond memory.
    let mut far: Vec<[f64; 3]> = sc.layout.arrays[0]
        .mics
        .iter()
        .map(|m| [m.x, m.y, m.z])
        .collect();
    far[1][0] += 20_000.0;
    let r = put(
        format!("{path}/arrays/{a0}"),
        serde_json::json!({ "mics": far }),
    )
    .await;
    assert_eq!((r.status, err(&r).field.as_deref()), (422, Some("mics")));
    assert!(err(&r).message.contains("max_pair_span_m"), "{}", r.text());
    let cam = &sc.layout.cameras[0].id;
    let r = put(
        format!("{path}/cameras/{cam}"),
        serde_json::json!({"rotation": [[1,0,0],[0,1,0],[0,0,1]]}),
    )
    .await;
    assert_eq!(
        (r.status, err(&r).field.as_deref()),
        (422, Some("translation"))
    );
    let settings = format!("{path}/settings");
    let patch = |b: serde_json::Value| rest.send_json("PATCH", settings.clone(), &s.token, b);
    let r = patch(serde_json::json!({"step_s": 0.064})).await;
    assert_eq!(
        (r.status, err(&r).code.as_str(), err(&r).field.as_deref()),
        (409, "not_live", Some("step_s"))
    );
    let r = patch(serde_json::json!({"separate": {"frame": 512}})).await;
    assert_eq!(
        (r.status, err(&r).field.as_deref()),
        (409, Some("separate.frame"))
    );
    // A frame no pipeline can use has no memory bound to admit: the change refuses it.
    let r = patch(serde_json::json!({"localize": {"frame": 0}})).await;
    assert_eq!(
        (r.status, err(&r).field.as_deref()),
        (409, Some("localize.frame")),
        "{}",
        r.text()
    );
    let r = patch(serde_json::json!({"camera_wait_s": 9.0})).await;
    assert_eq!(
        (r.status, err(&r).field.as_deref()),
        (422, Some("camera_wait_s"))
    );
    let r = patch(serde_json::json!({"separate": {"lifecycle": {"max_streams": 100}}})).await;
    assert_eq!(
        (r.status, err(&r).field.as_deref()),
        (422, Some("separate.lifecycle.max_streams"))
    );
    assert!(
        err(&r).message.contains("limits.max_streams"),
        "{}",
        r.text()
    );
    let r = patch(serde_json::json!({"bogus": 1})).await;
    assert_eq!(r.status, 422);
    assert!(err(&r).message.contains("bogus"));
}

/// One bad message of each kind, to send just after the audio of samples [4096, 5120) of `sc`:
/// six audio frames (wrong channel count, truncated, header only, over the size limit, NaN
/// sample, going backwards) and nine JSON messages (malformed, unknown type, a box with a
/// string for a coordinate, unknown camera, negative box width, detections going backwards,
/// detections from far ahead, a camera frame and a device frame past
/// `limits.max_measurements`).
fn bad_messages(sc: &avsep::scene::Scene) -> Vec<FeedItem> {
    let audio = sc.audio.as_ref().unwrap();
    let ch = audio.channels;
    let block = |first: usize, frames: usize| AudioFrame {
        first_sample: first as u64,
        channels: ch,
        samples: audio.samples[first * ch..(first + frames) * ch].to_vec(),
        encoding: SampleEncoding::F32,
    };
    let cam = &sc.layout.cameras[0].id;
    let last_det_t = sc
        .detections
        .iter()
        .filter(|d| d.t < 5120.0 / 16000.0)
        .map(|d| d.t)
        .fold(0.0, f64::max);

    let wrong_channels = AudioFrame {
        first_sample: 5120,
        channels: 4,
        samples: vec![0.0; 4 * 256],
        encoding: SampleEncoding::F32,
    }
    .encode();
    let good = block(5120, 1024).encode();
    let truncated = good[..good.len() - 3].to_vec();
    let header_only = good[..10].to_vec();
    let oversized = AudioFrame {
        first_sample: 5120,
        channels: ch,
        samples: vec![0.0; ch * 4096],
        encoding: SampleEncoding::F32,
    }
    .encode();
    assert!(oversized.len() < Limits::default().max_message_bytes);
    let mut with_nan = block(5120, 1024);
    with_nan.samples[3 * ch + 2] = f32::NAN;
    let backwards = block(4096, 1024).encode();
    let over = Limits::default().max_measurements + 1;
    let crowd = vec![r#"{"x":10,"y":10,"w":20,"h":20}"#; over].join(",");
    let doas = vec![r#"{"azimuth":10}"#; over].join(",");
    vec![
        bad_audio(wrong_channels, 5120),
        bad_audio(truncated, 5120),
        bad_audio(header_only, 5120),
        bad_audio(oversized, 5120),
        bad_audio(with_nan.encode(), 5120),
        bad_audio(backwards, 5120),
        bad_json("{\"type\": \"detections\", \"t\": 0.4,"),
        bad_json("{\"type\": \"teleport\"}"),
        bad_json(&format!(
            "{{\"type\":\"detections\",\"t\":0.3,\"camera\":\"{cam}\",\"boxes\":[{{\"x\":\"ten\",\"y\":1,\"w\":2,\"h\":3}}]}}"
        )),
        bad_json("{\"type\":\"detections\",\"t\":0.5,\"camera\":\"cam9\",\"boxes\":[]}"),
        bad_json(&format!(
            "{{\"type\":\"detections\",\"t\":0.2,\"camera\":\"{cam}\",\"boxes\":[{{\"x\":10,\"y\":10,\"w\":-5,\"h\":10}}]}}"
        )),
        // Earlier than this camera's last frame: the pipeline refuses it as going backwards.
        bad_json(&format!(
            "{{\"type\":\"detections\",\"t\":{},\"camera\":\"{cam}\",\"boxes\":[]}}",
            last_det_t - 0.05
        )),
        // From a clock a billion seconds ahead: refused, so the camera's next frame is not
        // locked out as going backwards.
        bad_json(&format!(
            "{{\"type\":\"detections\",\"t\":1e9,\"camera\":\"{cam}\",\"boxes\":[]}}"
        )),
        bad_json(&format!(
            r#"{{"type":"detections","t":0.3,"camera":"{cam}","boxes":[{crowd}]}}"#
        )),
        bad_json(&format!(
            r#"{{"type":"audio_measurements","t":0.3,"array":"a0","doas":[{doas}]}}"#
        )),
    ]
}

/// Each of [`bad_messages`] got its own error naming the field, and nothing else was refused.
fn every_refusal_is_named(e: &[ErrorBody]) {
    find_saying(e, "bad_channels", "channels", "4 channels");
    find(e, "truncated", Some("samples"));
    find(e, "truncated", Some("header"));
    find_saying(e, "oversized", "frame_count", "limit");
    find_saying(e, "non_finite", "samples", "sample 3 of channel 2");
    find_saying(e, "time_backwards", "first_sample", "5120");
    find(e, "bad_json", None);
    find_saying(e, "bad_message", "type", "teleport");
    find_saying(e, "bad_message", "boxes[0].x", "invalid type");
    find_saying(e, "unknown_camera", "camera", "cam9");
    find(e, "bad_box", Some("boxes[0].w"));
    find(e, "time_backwards", Some("t"));
    find_saying(e, "too_early", "t", "max_lead_s");
    find_saying(e, "too_many_measurements", "boxes", "257 boxes");
    find_saying(
        e,
        "too_many_measurements",
        "doas",
        "limits.max_measurements (256)",
    );
    assert_eq!(e.len(), 15, "{e:#?}");
}
