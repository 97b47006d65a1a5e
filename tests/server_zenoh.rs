//! The Zenoh transport over a real Zenoh network: the server's transport listens on a free
//! loopback port, and a second Zenoh peer in the test (connected explicitly, scouting off) plays
//! an edge device that needs no HTTP. It creates a session with the `avsep/sessions/create`
//! query, streams a simulated scene under `avsep/<id>/in/...`, and must receive tracks and
//! separated audio identical to the offline run of the scene; bad input must come back as error
//! events naming the field while the session goes on.

mod server_support;

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use avsep::label::Label;
use avsep::protocol::rest::{
    CreateSession, ErrorResponse, SessionCreated, SessionInfo, SessionList, TracksSnapshot,
};
use avsep::protocol::zenoh_keys::{
    self, ClosedMessage, SESSIONS_CREATE, SESSIONS_LIST, input_audio, input_detections, input_doa,
    input_finish, session_query,
};
use avsep::protocol::{ClientMessage, ErrorBody, LabelAudioFrame, SampleEncoding, ServerMessage};
use avsep::scene::Scene;
use avsep::server::ServerConfig;
use avsep::server::client::{FeedItem, FeedMessage, create_body, http, scene_feed};
use server_support::zenoh::ZenohServer;
use server_support::{assert_same_tracks, audio_difference, offline, scene, settings};
use tokio::sync::mpsc::{UnboundedReceiver, unbounded_channel};
use zenoh::Wait;
use zenoh::qos::CongestionControl;

const WAIT: Duration = Duration::from_secs(20);

/// What the edge peer received from one session.
#[derive(Default)]
struct Heard {
    tracks: Vec<TracksSnapshot>,
    audio: Vec<LabelAudioFrame>,
    errors: Vec<ErrorBody>,
    closed: Option<ClosedMessage>,
}

impl Heard {
    fn audio_by_label(&self, len: usize) -> BTreeMap<Label, Vec<f32>> {
        let mut out: BTreeMap<Label, Vec<f32>> = BTreeMap::new();
        for f in &self.audio {
            let buf = out.entry(f.label).or_insert_with(|| vec![0.0; len]);
            // The flush may run past the input's end; those samples are not compared.
            let start = (f.first_sample as usize).min(len);
            let n = f.samples.len().min(len - start);
            buf[start..start + n].copy_from_slice(&f.samples[..n]);
        }
        out
    }

    fn take(&mut self, session: &str, key: &str, payload: &[u8]) {
        let Some(rest) = key.strip_prefix(&format!("avsep/{session}/out/")) else {
            return;
        };
        if rest.starts_with("audio/") {
            let f = LabelAudioFrame::decode(payload).unwrap();
            assert_eq!(
                rest,
                format!("audio/{}", f.label),
                "audio is published under its label"
            );
            self.audio.push(f);
        } else if rest == "events" {
            if let Ok(c) = serde_json::from_slice::<ClosedMessage>(payload) {
                self.closed = Some(c);
            } else if let ServerMessage::Error { error } = serde_json::from_slice(payload).unwrap()
            {
                self.errors.push(error);
            }
        } else if rest == "tracks" {
            match serde_json::from_slice(payload).unwrap() {
                ServerMessage::Tracks { step, t, tracks } => {
                    self.tracks.push(TracksSnapshot { step, t, tracks })
                }
                m => panic!("{m:?} on out/tracks"),
            }
        }
    }
}

/// An edge device: a Zenoh peer that connects to the server only.
struct Edge {
    z: zenoh::Session,
    out: UnboundedReceiver<(String, Vec<u8>)>,
    _sub: zenoh::pubsub::Subscriber<()>,
}

/// A Zenoh peer connected to the server at `endpoint` only (scouting off).
async fn peer(endpoint: &str) -> zenoh::Session {
    let mut c = zenoh::Config::default();
    c.insert_json5("mode", r#""peer""#).unwrap();
    c.insert_json5("connect/endpoints", &format!(r#"["{endpoint}"]"#))
        .unwrap();
    c.insert_json5("listen/endpoints", "[]").unwrap();
    c.insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    zenoh::open(c).await.unwrap()
}

impl Edge {
    async fn connect(endpoint: &str) -> Self {
        let z = peer(endpoint).await;
        let (tx, out) = unbounded_channel();
        let sub = z
            .declare_subscriber("avsep/*/out/**")
            .callback(move |s| {
                let _ = tx.send((
                    s.key_expr().as_str().to_string(),
                    s.payload().to_bytes().into_owned(),
                ));
            })
            .await
            .unwrap();
        Self { z, out, _sub: sub }
    }

    /// Sends a query until some server answers (the link and declarations take a moment).
    async fn query(
        &self,
        key: &str,
        payload: Option<Vec<u8>>,
        attachment: Option<&str>,
    ) -> Result<Vec<u8>, ErrorResponse> {
        let deadline = Instant::now() + WAIT;
        loop {
            let mut get = self.z.get(key).timeout(Duration::from_secs(10));
            if let Some(p) = &payload {
                get = get.payload(p.clone());
            }
            if let Some(a) = attachment {
                get = get.attachment(a);
            }
            let replies = get.await.unwrap();
            if let Ok(reply) = replies.recv_async().await {
                return match reply.result() {
                    Ok(sample) => Ok(sample.payload().to_bytes().into_owned()),
                    Err(e) => Err(serde_json::from_slice(&e.payload().to_bytes()).unwrap()),
                };
            }
            assert!(Instant::now() < deadline, "no server answered {key}");
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }

    async fn create(&self, sc: &Scene, seed: u64, key: Option<&str>) -> SessionCreated {
        let body = serde_json::to_vec(&create_body(&sc.layout, Some(settings(seed)))).unwrap();
        let created = self
            .query(SESSIONS_CREATE, Some(body), key)
            .await
            .expect("created");
        serde_json::from_slice(&created).unwrap()
    }

    /// Waits until the server's subscriber of the session's input is known here.
    async fn wait_for_input(&self, session: &str) {
        let p = self
            .z
            .declare_publisher(input_audio(session))
            .await
            .unwrap();
        let deadline = Instant::now() + WAIT;
        while !p.matching_status().await.unwrap().matching() {
            assert!(
                Instant::now() < deadline,
                "the session's input subscriber never appeared"
            );
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }

    fn put(&self, key: &str, payload: Vec<u8>, token: Option<&str>) {
        let mut put = self
            .z
            .put(key, payload)
            .congestion_control(CongestionControl::Block);
        if let Some(t) = token {
            put = put.attachment(t);
        }
        put.wait().unwrap();
    }

    /// Takes what has arrived for `session` into `heard`, waiting at most `wait` for the first.
    async fn drain(&mut self, session: &str, heard: &mut Heard, wait: Duration) {
        if let Ok(Some((k, p))) = tokio::time::timeout(wait, self.out.recv()).await {
            heard.take(session, &k, &p);
            while let Ok((k, p)) = self.out.try_recv() {
                heard.take(session, &k, &p);
            }
        }
    }

    /// Waits until `heard` holds `n` errors.
    async fn errors(&mut self, session: &str, heard: &mut Heard, n: usize) {
        let deadline = Instant::now() + WAIT;
        while heard.errors.len() < n {
            assert!(
                Instant::now() < deadline,
                "expected {n} errors, got {:?}",
                heard.errors
            );
            self.drain(session, heard, Duration::from_millis(100)).await;
        }
    }

    /// Streams the feed (keeping at most `max_lead_s` of audio ahead of the last step heard, as
    /// the WebSocket client does, so the session's queue never fills), finishes, and collects
    /// until the session's `closed`.
    async fn stream(
        &mut self,
        s: &SessionCreated,
        feed: &[FeedItem],
        heard: &mut Heard,
        rate: f64,
        step_s: f64,
    ) {
        let step = (step_s * rate).round() as u64;
        let max_lead = (0.5 * rate) as u64;
        let deadline = Instant::now() + Duration::from_secs(300);
        for item in feed {
            match &item.message {
                FeedMessage::Audio { bytes, end } => {
                    while *end > heard.tracks.last().map_or(0, |t| (t.step + 1) * step) + max_lead {
                        assert!(
                            Instant::now() < deadline,
                            "the session stopped producing tracks"
                        );
                        self.drain(&s.id, heard, Duration::from_millis(200)).await;
                    }
                    self.put(&input_audio(&s.id), bytes.clone(), Some(&s.token));
                }
                FeedMessage::Json(text) => {
                    let key = match serde_json::from_str(text).unwrap() {
                        ClientMessage::Detections { camera, .. } => {
                            input_detections(&s.id, &camera)
                        }
                        ClientMessage::AudioMeasurements(line) => input_doa(&s.id, &line.array),
                        m => panic!("{m:?} in a feed"),
                    };
                    self.put(&key, text.clone().into_bytes(), Some(&s.token));
                }
            }
            self.drain(&s.id, heard, Duration::ZERO).await;
        }
        self.put(&input_finish(&s.id), Vec::new(), Some(&s.token));
        while heard.closed.is_none() {
            assert!(Instant::now() < deadline, "the session never closed");
            self.drain(&s.id, heard, Duration::from_millis(200)).await;
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn zenoh_only_device_gets_the_offline_result_and_errors_naming_the_field() {
    let server = ZenohServer::start(ServerConfig::default()).await;
    let mut edge = Edge::connect(&server.endpoint).await;
    let sc = scene("uca8", 2.5, 2, 23);
    let (tracks, audio) = offline(&sc, settings(7));

    let s = edge.create(&sc, 7, None).await;
    assert_eq!(s.token.len(), 64);
    assert_eq!(s.session.channels, sc.layout.channel_count());
    edge.wait_for_input(&s.id).await;

    // Bad input first: each comes back on out/events naming the field, nothing is accepted.
    let mut heard = Heard::default();
    send_bad_input(&edge, &s, &sc);
    edge.errors(&s.id, &mut heard, 5).await;
    let got: Vec<(&str, Option<&str>)> = heard
        .errors
        .iter()
        .map(|e| (e.code.as_str(), e.field.as_deref()))
        .collect();
    assert_eq!(got[0], ("truncated", Some("samples")));
    assert_eq!(got[1], ("unknown_camera", Some("camera")));
    assert_eq!(got[2], ("unauthorized", Some("attachment")));
    assert_eq!(got[3], ("forbidden", Some("attachment")));
    assert_eq!(got[4].0, "bad_json");
    heard.errors.clear();

    // The session goes on: the whole scene, streamed over Zenoh, gives the offline result.
    let feed = scene_feed(&sc, 1024, SampleEncoding::F32);
    let rate = f64::from(sc.layout.sample_rate);
    edge.stream(&s, &feed, &mut heard, rate, s.session.step_s)
        .await;
    assert!(heard.errors.is_empty(), "{:?}", heard.errors);
    assert_eq!(
        heard.closed.as_ref().unwrap().state,
        avsep::protocol::rest::SessionState::Finished
    );
    assert_same_tracks(&tracks, &heard.tracks);
    let n = sc.audio.as_ref().unwrap().frames();
    assert_eq!(audio_difference(&audio, &heard.audio_by_label(n)), 0.0);

    inspect_and_list_over_zenoh(&server, &edge, &s).await;
    server.stop().await;
}

/// Sends five bad inputs: a truncated audio frame, detections of an unknown camera, audio
/// without and with a wrong token, and broken JSON.
fn send_bad_input(edge: &Edge, s: &SessionCreated, sc: &Scene) {
    let audio_key = input_audio(&s.id);
    let mut frame = match &scene_feed(sc, 1024, SampleEncoding::F32)
        .into_iter()
        .find(|i| matches!(i.message, FeedMessage::Audio { .. }))
        .unwrap()
        .message
    {
        FeedMessage::Audio { bytes, .. } => bytes.clone(),
        _ => unreachable!(),
    };
    frame.truncate(frame.len() - 3);
    edge.put(&audio_key, frame, Some(&s.token));
    let nobody = r#"{"type":"detections","t":0.0,"camera":"nocam","boxes":[]}"#;
    edge.put(
        &input_detections(&s.id, "nocam"),
        nobody.into(),
        Some(&s.token),
    );
    edge.put(&audio_key, b"AVSA".to_vec(), None);
    edge.put(&audio_key, b"AVSA".to_vec(), Some("not-the-token"));
    edge.put(
        &input_detections(&s.id, "cam0"),
        b"{\"type\":\"detections\",".to_vec(),
        Some(&s.token),
    );
}

/// Inspects and lists the session over Zenoh, and checks the refusals were counted like the
/// WebSocket's.
async fn inspect_and_list_over_zenoh(server: &ZenohServer, edge: &Edge, s: &SessionCreated) {
    let info: SessionInfo = serde_json::from_slice(
        &edge
            .query(&session_query(&s.id), None, Some(&s.token))
            .await
            .unwrap(),
    )
    .unwrap();
    assert_eq!(info.id, s.id);
    let list: SessionList =
        serde_json::from_slice(&edge.query(SESSIONS_LIST, None, None).await.unwrap()).unwrap();
    assert!(list.sessions.iter().any(|x| x.id == s.id));
    let m = server.http.registry.get(&s.id).unwrap().metrics();
    assert_eq!(m.refused.values().sum::<u64>(), 5, "{:?}", m.refused);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn zenoh_queries_check_credentials_and_rest_sessions_stream_over_zenoh() {
    let key = "zenoh-admin-key-0123456789";
    let cfg = ServerConfig {
        admin_key: Some(key.into()),
        ..Default::default()
    };
    let server = ZenohServer::start(cfg).await;
    let mut edge = Edge::connect(&server.endpoint).await;
    let sc = scene("uca8", 0.5, 1, 29);
    let z = create_checks_credentials(&edge, &sc, key).await;

    // A session created over REST is on Zenoh too; another session's token does not open it.
    let r = server.http.create(&sc, settings(1), Some(key)).await;
    let mut heard = rest_session_checks_tokens(&mut edge, &r, &z, key).await;

    // Deleting it over REST ends its Zenoh stream with `closed`.
    let d = http(
        &server.http.host(),
        "DELETE",
        &format!("/v1/sessions/{}", r.id),
        Some(key),
        None,
    )
    .await
    .unwrap();
    assert_eq!(d.status, 204, "{}", d.text());
    let deadline = Instant::now() + WAIT;
    while heard.closed.is_none() {
        assert!(Instant::now() < deadline, "no closed message");
        edge.drain(&r.id, &mut heard, Duration::from_millis(200))
            .await;
    }
    assert_eq!(heard.closed.unwrap().reason, "session deleted");
    server.stop().await;
}

/// Create needs the admin key `key` when one is configured, and a bad body names the field;
/// returns the session created with the key.
async fn create_checks_credentials(edge: &Edge, sc: &Scene, key: &str) -> SessionCreated {
    let body = serde_json::to_vec(&create_body(&sc.layout, None)).unwrap();
    let e = edge
        .query(SESSIONS_CREATE, Some(body.clone()), None)
        .await
        .unwrap_err();
    assert_eq!(
        (e.error.code.as_str(), e.error.field.as_deref()),
        ("unauthorized", Some("attachment"))
    );
    let e = edge
        .query(
            SESSIONS_CREATE,
            Some(body.clone()),
            Some("wrong-key-wrong-key"),
        )
        .await
        .unwrap_err();
    assert_eq!(e.error.code, "forbidden");
    let mut bad: CreateSession = create_body(&sc.layout, None);
    bad.arrays[0].mics.clear();
    let bad = serde_json::to_string(&bad)
        .unwrap()
        .replace("\"mics\":[]", "\"mics\":[[0,0]]");
    let e = edge
        .query(SESSIONS_CREATE, Some(bad.into_bytes()), Some(key))
        .await
        .unwrap_err();
    assert_eq!(e.error.field.as_deref(), Some("arrays[0].mics[0]"), "{e:?}");
    let e = edge.query(SESSIONS_LIST, None, None).await.unwrap_err();
    assert_eq!(e.error.code, "unauthorized");
    serde_json::from_slice(
        &edge
            .query(SESSIONS_CREATE, Some(body), Some(key))
            .await
            .unwrap(),
    )
    .unwrap()
}

/// Session `r` (created over REST) refuses `z`'s token for inspection and input, opens with the
/// admin key, and names an unknown input key; returns what was heard of `r`.
async fn rest_session_checks_tokens(
    edge: &mut Edge,
    r: &SessionCreated,
    z: &SessionCreated,
    key: &str,
) -> Heard {
    let e = edge
        .query(&session_query(&r.id), None, Some(&z.token))
        .await
        .unwrap_err();
    assert_eq!(e.error.code, "forbidden");
    let info: SessionInfo = serde_json::from_slice(
        &edge
            .query(&session_query(&r.id), None, Some(key))
            .await
            .unwrap(),
    )
    .unwrap();
    assert_eq!(info.id, r.id);
    edge.wait_for_input(&r.id).await;
    let mut heard = Heard::default();
    edge.put(&input_audio(&r.id), b"AVSA".to_vec(), Some(&z.token));
    edge.put(
        &format!("{}/{}/in/video", zenoh_keys::ROOT, r.id),
        b"x".to_vec(),
        Some(&r.token),
    );
    edge.errors(&r.id, &mut heard, 2).await;
    assert_eq!(
        (
            heard.errors[0].code.as_str(),
            heard.errors[0].field.as_deref()
        ),
        ("forbidden", Some("attachment"))
    );
    assert_eq!(
        (
            heard.errors[1].code.as_str(),
            heard.errors[1].field.as_deref()
        ),
        ("unknown_key", Some("key"))
    );
    heard
}

/// A stranger without the token floods a session's input: every refusal is counted, but only
/// `limits.zenoh_refusals_per_s` of them a second are published, the device's own refusal
/// still gets through, and the next refusal published says how many were held back.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flood_without_credentials_is_published_at_a_bounded_rate() {
    let mut cfg = ServerConfig::default();
    cfg.limits.zenoh_refusals_per_s = 4.0;
    let server = ZenohServer::start(cfg).await;
    let mut edge = Edge::connect(&server.endpoint).await;
    let sc = scene("uca8", 1.0, 1, 5);
    let s = edge.create(&sc, 7, None).await;
    edge.wait_for_input(&s.id).await;

    let audio_key = input_audio(&s.id);
    let started = Instant::now();
    for _ in 0..300 {
        edge.put(&audio_key, b"AVSA".to_vec(), None);
    }
    let own = r#"{"type":"detections","t":0.1,"camera":"cam0","boxes":[{"x":"ten"}]}"#;
    edge.put(&input_detections(&s.id, "cam0"), own.into(), Some(&s.token));
    let refused = || -> u64 {
        let m = server.http.registry.get(&s.id).unwrap().metrics();
        m.refused.values().sum()
    };
    let deadline = Instant::now() + WAIT;
    while refused() < 301 {
        assert!(Instant::now() < deadline, "{} refusals counted", refused());
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let elapsed = started.elapsed().as_secs_f64();
    let mut heard = Heard::default();
    edge.drain(&s.id, &mut heard, Duration::from_millis(500))
        .await;
    let published = heard
        .errors
        .iter()
        .filter(|e| e.code == "unauthorized")
        .count();
    assert!(
        published >= 4 && published as f64 <= 5.0 + 4.0 * elapsed,
        "{published} published in {elapsed:.2} s"
    );
    assert!(
        heard
            .errors
            .iter()
            .any(|e| e.code == "bad_message" && e.field.as_deref() == Some("boxes[0].x")),
        "{:?}",
        heard.errors
    );

    tokio::time::sleep(Duration::from_millis(300)).await;
    heard.errors.clear();
    edge.put(&audio_key, b"AVSA".to_vec(), None);
    edge.errors(&s.id, &mut heard, 1).await;
    assert_eq!(heard.errors[0].code, "unauthorized");
    assert!(
        heard.errors[0].message.contains("were not published"),
        "{:?}",
        heard.errors[0]
    );
    server.stop().await;
}

/// A session nobody listens to over Zenoh neither broadcasts nor publishes its separated audio
/// and measurements: its interest in each follows the Zenoh subscribers whose keys match it, as
/// they come and go.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn optional_outputs_follow_the_zenoh_subscribers_that_want_them() {
    let server = ZenohServer::start(ServerConfig::default()).await;
    let sc = scene("uca8", 0.5, 1, 31);
    let s = server.http.create(&sc, settings(31), None).await;
    let session = server.http.registry.get(&s.id).unwrap();
    let wants = || {
        (
            session.interest().audio(),
            session.interest().measurements(),
        )
    };
    let until = async |want: (bool, bool)| {
        let deadline = Instant::now() + WAIT;
        while wants() != want {
            assert!(
                Instant::now() < deadline,
                "{:?} never became {want:?}",
                wants()
            );
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    };
    assert_eq!(wants(), (false, false), "nobody listens yet");
    let z = peer(&server.endpoint).await;
    let audio = z
        .declare_subscriber(format!("avsep/{}/out/audio/**", s.id))
        .await
        .unwrap();
    until((true, false)).await;
    let everything = z.declare_subscriber("avsep/*/out/**").await.unwrap();
    until((true, true)).await;
    drop(audio);
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert_eq!(
        wants(),
        (true, true),
        "the wildcard subscriber still wants both"
    );
    drop(everything);
    until((false, false)).await;
    z.close().await.unwrap();
    server.stop().await;
}
