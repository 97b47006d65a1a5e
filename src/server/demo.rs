//! The demo room of `avsep serve --demo`: a scene simulated in memory with the project's own
//! simulator, streamed into an ordinary session in real time and looped, so a fresh install
//! shows moving tracks and separated voices in the dashboard at once.
//!
//! The feeder submits through [`SessionHandle::submit`](crate::server::session::Session::submit),
//! the path the WebSocket and Zenoh transports use after decoding, so the demo session runs exactly
//! as a client-fed one. Its id and token are published on the registry ([`Registry::set_demo`]) for
//! the dashboard's `GET /dashboard/api/demo`, which answers whoever may list sessions.

use std::sync::Arc;
use std::time::Duration;

use serde::Serialize;

use crate::pipeline::PipelineConfig;
use crate::protocol::rest::CreateSession;
use crate::protocol::{AudioFrame, SampleEncoding};
use crate::scene::Scene;
use crate::scene::convert::{array_to_file, camera_to_file, region_to_file};
use crate::scene::sim::{PresetOptions, SimConfig, simulate};

use super::registry::Registry;
use super::session::{ClientId, Input, SessionHandle};

/// The demo session's credentials, as the dashboard reads them.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DemoAccess {
    /// Session id.
    pub id: String,
    /// Session token.
    pub token: String,
    /// Session name.
    pub name: String,
}

/// What the demo room simulates.
#[derive(Debug, Clone, PartialEq)]
pub struct DemoOptions {
    /// Simulator preset (`avsep simulate --list-presets`).
    pub preset: String,
    /// Length of the simulated scene (s); the feed loops over it.
    pub duration_s: f64,
    /// Seed of the simulation and of the session's pipeline.
    pub seed: u64,
    /// Audio frames per submitted block.
    pub block: usize,
}

impl Default for DemoOptions {
    fn default() -> Self {
        Self {
            preset: "uca8".into(),
            duration_s: 20.0,
            seed: 7,
            block: 1024,
        }
    }
}

/// Simulates the room (seconds of work: call from a blocking task).
pub fn simulate_room(opts: &DemoOptions) -> Result<Scene, String> {
    let preset = PresetOptions {
        duration_s: Some(opts.duration_s),
        ..Default::default()
    };
    let cfg = SimConfig::preset(&opts.preset, &preset, opts.seed).map_err(|e| e.to_string())?;
    let scene = simulate(&cfg, opts.seed).map_err(|e| e.to_string())?;
    if scene.audio.as_ref().is_none_or(|a| a.frames() == 0) {
        return Err(format!("preset {} produced no audio", opts.preset));
    }
    Ok(scene)
}

/// The body that creates the demo room's session, as a client would post it.
pub fn create_body(scene: &Scene, opts: &DemoOptions) -> CreateSession {
    let layout = &scene.layout;
    CreateSession {
        name: Some(format!("demo ({})", opts.preset)),
        sample_rate: layout.sample_rate,
        speed_of_sound: layout.speed_of_sound,
        arrays: layout.arrays.iter().map(array_to_file).collect(),
        cameras: layout.cameras.iter().map(camera_to_file).collect(),
        region: layout.region.as_ref().map(region_to_file),
        settings: Some(PipelineConfig {
            seed: Some(opts.seed),
            ..Default::default()
        }),
    }
}

/// Simulates the room, creates its session, publishes its credentials on the registry and
/// starts feeding it in real time (until the session ends: deleted or server shutdown).
pub async fn start(registry: Arc<Registry>, opts: DemoOptions) -> Result<DemoAccess, String> {
    let reg = registry.clone();
    let o = opts.clone();
    let (scene, session, token) = tokio::task::spawn_blocking(move || {
        let scene = simulate_room(&o)?;
        let (session, token) = reg
            .create(create_body(&scene, &o))
            .map_err(|e| format!("cannot create the demo session: {}", e.body.message))?;
        Ok::<_, String>((scene, session, token))
    })
    .await
    .map_err(|e| format!("demo simulation failed: {e}"))??;
    let access = DemoAccess {
        id: session.id().to_string(),
        token,
        name: format!("demo ({})", opts.preset),
    };
    registry.set_demo(access.clone());
    tokio::spawn(feed(session, Arc::new(scene), opts.block));
    Ok(access)
}

/// One message of the looped feed, with its due time in the scene.
enum Item {
    Side(Input),
    Audio { start: usize, end: usize },
}

/// Every camera frame and device measurement in time order, each placed before the audio
/// block whose end passes its time (the offline runner's order).
fn schedule(scene: &Scene, frames: usize, block: usize, sample_rate: f64) -> Vec<Item> {
    let mut side: Vec<(f64, Input)> = scene
        .detections
        .iter()
        .map(|d| (d.t, Input::Detections(d.clone())))
        .chain(
            scene
                .audio_measurements
                .iter()
                .map(|m| (m.t, Input::AudioMeasurements(m.clone()))),
        )
        .collect();
    side.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut side = side.into_iter().peekable();
    let mut items = Vec::new();
    let mut start = 0;
    while start < frames {
        let end = (start + block.max(1)).min(frames);
        while let Some((_, input)) = side.next_if(|(t, _)| *t < end as f64 / sample_rate) {
            items.push(Item::Side(input));
        }
        items.push(Item::Audio { start, end });
        start = end;
    }
    items
}

/// `input` moved `offset` samples (`offset_s` seconds) later, for a later lap of the loop.
fn shifted(input: &Input, offset_s: f64) -> Input {
    match input {
        Input::Detections(d) => {
            let mut d = d.clone();
            d.t += offset_s;
            Input::Detections(d)
        }
        Input::AudioMeasurements(m) => {
            let mut m = m.clone();
            m.t += offset_s;
            Input::AudioMeasurements(m)
        }
        Input::Audio(a) => Input::Audio(a.clone()),
    }
}

/// Submits `input`, waiting while the session's queue is full. False once the session no
/// longer takes input.
async fn send(session: &SessionHandle, me: ClientId, input: Input) -> bool {
    loop {
        match session.submit(me, input.clone()) {
            Ok(()) => return true,
            Err(r) if r.code == "queue_full" => tokio::time::sleep(Duration::from_millis(20)).await,
            Err(r) if r.code == "session_closed" || r.code == "session_failed" => return false,
            Err(r) => {
                // A late camera frame after a stall, say: the next lap goes on.
                tracing::debug!(code = r.code, message = %r.message, "demo input refused");
                return true;
            }
        }
    }
}

/// Streams `scene` into `session` in real time, lap after lap, until the session ends.
async fn feed(session: SessionHandle, scene: Arc<Scene>, block: usize) {
    let Some(audio) = scene.audio.as_ref() else {
        return;
    };
    let guard = match session.attach() {
        Ok(g) => g,
        Err(r) => {
            tracing::warn!(message = %r.message, "demo feeder cannot attach");
            return;
        }
    };
    let me = guard.id();
    let frames = audio.frames();
    let sample_rate = f64::from(audio.sample_rate);
    let items = schedule(&scene, frames, block, sample_rate);
    let started = tokio::time::Instant::now();
    tracing::info!(session = %session.id(), "demo room streaming");
    for lap in 0u64.. {
        let offset = lap * frames as u64;
        let offset_s = offset as f64 / sample_rate;
        for item in &items {
            let input = match item {
                Item::Side(input) => shifted(input, offset_s),
                Item::Audio { start, end } => {
                    let due = (offset + *end as u64) as f64 / sample_rate;
                    tokio::time::sleep_until(started + Duration::from_secs_f64(due)).await;
                    Input::Audio(AudioFrame {
                        first_sample: offset + *start as u64,
                        channels: audio.channels,
                        samples: audio.samples[start * audio.channels..end * audio.channels]
                            .to_vec(),
                        encoding: SampleEncoding::F32,
                    })
                }
            };
            if !send(&session, me, input).await {
                tracing::info!(session = %session.id(), "demo room stopped");
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schedule_puts_camera_frames_before_the_block_that_covers_them() {
        let opts = DemoOptions {
            preset: "single".into(),
            duration_s: 1.0,
            ..Default::default()
        };
        let scene = simulate_room(&opts).unwrap();
        let audio = scene.audio.as_ref().unwrap();
        let sr = f64::from(audio.sample_rate);
        let items = schedule(&scene, audio.frames(), 1000, sr);
        let blocks = items
            .iter()
            .filter(|i| matches!(i, Item::Audio { .. }))
            .count();
        assert_eq!(blocks, audio.frames().div_ceil(1000));
        let sides = items.len() - blocks;
        assert_eq!(
            sides,
            scene.detections.len() + scene.audio_measurements.len()
        );
        assert!(sides > 0, "the preset has a camera");
        // Every side item precedes the first block ending after its time, and follows the
        // blocks ending at or before it.
        let mut audio_end = 0.0;
        for i in &items {
            match i {
                Item::Side(Input::Detections(d)) => {
                    assert!(d.t >= audio_end, "{} < {audio_end}", d.t)
                }
                Item::Side(Input::AudioMeasurements(m)) => assert!(m.t >= audio_end),
                Item::Side(Input::Audio(_)) => unreachable!(),
                Item::Audio { end, .. } => audio_end = *end as f64 / sr,
            }
        }
        let d = Input::Detections(scene.detections[0].clone());
        match shifted(&d, 20.0) {
            Input::Detections(s) => assert_eq!(s.t, scene.detections[0].t + 20.0),
            _ => unreachable!(),
        }
    }
}
