//! The room simulator: scenes with known truth.
//!
//! A [`SimConfig`] describes a shoebox room (image-source method, reverberation tuned to a target
//! RT60), microphone arrays, cameras, talkers (paths, facing, synthetic voices or recorded
//! speech, phrase timing) and noise. [`simulate`] turns it into a validated [`Scene`]: the
//! multichannel mixture, one detection frame per camera frame, and the truth (trajectories every
//! 20 ms from entry to exit, speech intervals, and each talker's image at the reference
//! microphone, rendered with exactly the response used for the mixture, so that the reference
//! channel equals the sum of the truth signals plus the noise). Presets
//! ([`SimConfig::preset`]) draw talker placements and scripts from the seed. Every random choice
//! comes from a ChaCha8 stream derived from the seed, the purpose and the talker index, so the
//! same seed gives the same scene bit for bit.

pub mod calibrate;
pub mod config;
pub mod decay;
pub mod detect;
pub mod layout;
pub mod motion;
pub mod noise;
mod presets;
pub mod render;
pub mod room;
pub mod speech_files;
mod syllables;
mod talkers;
mod validate;
pub mod voice;

use std::path::PathBuf;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::geometry::{Aabb, Vec3};
use crate::scene::{Audio, Scene, Truth, TruthSource};

pub use config::{
    ArrayConfig, ArrayGeometry, CameraConfig, DetectorConfig, FacingConfig, NoiseConfig,
    PointNoiseConfig, RegionConfig, RoomConfig, SimConfig, SpeakerConfig, SpeechConfig,
    VoiceConfig,
};
pub use presets::{PRESETS, PresetOptions};
pub use validate::{MAX_SPEED_MPS, WALL_MARGIN_M};

use calibrate::reverberation_for;
use detect::FrameClock;
use motion::Motion;
use render::{RenderSettings, Renderer};
use room::ShoeboxRoom;
use talkers::{Talker, make_talkers, trajectory};

/// Truth trajectories are sampled at this step (s).
pub const TRUTH_STEP_S: f64 = 0.02;

/// Why a scene could not be simulated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// A configuration field is invalid.
    #[error("{field}: {message}")]
    Config {
        /// Dotted path of the field.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// A speech file or folder cannot be used.
    #[error("{}: {message}", path.display())]
    Speech {
        /// The file or folder.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

/// Purposes of the random streams (each talker gets its own stream per purpose).
pub(crate) mod streams {
    /// Preset placement and scripts.
    pub const PRESET: u64 = 1;
    /// Sway and head turns.
    pub const MOTION: u64 = 2;
    /// Synthetic voices.
    pub const VOICE: u64 = 3;
    /// Phrases drawn when a configuration gives none.
    pub const PHRASES: u64 = 4;
    /// Sensor noise (per microphone).
    pub const SENSOR: u64 = 5;
    /// The point noise source.
    pub const POINT: u64 = 6;
    /// Camera detections.
    pub const DETECT: u64 = 7;
}

/// The random stream for `purpose` and `index` of a run seeded with `seed`.
pub(crate) fn rng_for(seed: u64, purpose: u64, index: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream((purpose << 32) | index);
    rng
}

/// Simulates the scene described by `cfg` with random choices drawn from `seed`.
pub fn simulate(cfg: &SimConfig, seed: u64) -> Result<Scene, SimError> {
    simulate_with_progress(cfg, seed, &mut |_, _| {})
}

/// As [`simulate`], calling `progress(done, total)` as rendering advances.
pub fn simulate_with_progress(
    cfg: &SimConfig,
    seed: u64,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Scene, SimError> {
    cfg.validate()?;
    let layout = layout::build(cfg)?;
    let len = (cfg.duration_s * cfg.sample_rate as f64).round() as usize;
    let mics: Vec<Vec3> = layout
        .arrays
        .iter()
        .flat_map(|a| a.mics.iter().copied())
        .collect();
    let talkers = make_talkers(cfg, seed, &layout, len)?;
    let renderer = acoustics(cfg, layout.region, &mics)?;
    let sources = talkers.len() + usize::from(cfg.noise.point.is_some());
    let total = renderer.segments(len) * sources;
    let mut done = 0usize;
    progress(done, total);
    let mut tick = || {
        done += 1;
        progress(done, total);
    };
    let (mut mixture, images) = render_talkers(&renderer, &talkers, len, &mut tick);
    add_noise(
        cfg,
        seed,
        &renderer,
        &talkers,
        &images,
        &mut mixture,
        &mut tick,
    );

    // One common gain puts the mixture's peak at the configured level.
    let peak = mixture
        .iter()
        .flat_map(|m| m.iter())
        .fold(0.0f64, |p, v| p.max(v.abs()));
    if !peak.is_finite() {
        return Err(SimError::Config {
            field: "room".into(),
            message: "the simulation produced non-finite samples".into(),
        });
    }
    let gain = if peak > 0.0 {
        cfg.peak_level / peak
    } else {
        1.0
    };
    let mut samples = vec![0f32; len * mics.len()];
    for (c, m) in mixture.iter().enumerate() {
        for (n, v) in m.iter().enumerate() {
            samples[n * mics.len() + c] = (v * gain) as f32;
        }
    }
    let detections = camera_frames(cfg, seed, &layout.cameras, &talkers);
    let sources = talkers
        .into_iter()
        .zip(images)
        .map(|(t, image)| TruthSource {
            trajectory: trajectory(&t.motion),
            active: t.active,
            signal: Some(image.iter().map(|v| (v * gain) as f32).collect()),
            id: t.id,
        })
        .collect();
    Ok(Scene {
        dir: PathBuf::new(),
        audio: Some(Audio {
            sample_rate: cfg.sample_rate,
            channels: mics.len(),
            samples,
        }),
        layout,
        detections,
        audio_measurements: Vec::new(),
        truth: Some(Truth { sources }),
    })
}

/// The room and its renderer; the walls are tuned on a source at the centre of `region` heard
/// at the reference microphone `mics[0]`.
fn acoustics(cfg: &SimConfig, region: Option<Aabb>, mics: &[Vec3]) -> Result<Renderer, SimError> {
    let fs = cfg.sample_rate as f64;
    let size = Vec3::from(cfg.room.size_m);
    let probe = region.map_or(size * 0.5, |r| r.center());
    let config_error = |message: String| SimError::Config {
        field: "room.rt60_s".into(),
        message,
    };
    let rev = reverberation_for(&size, cfg.room.rt60_s, &probe, &mics[0], cfg.speed_of_sound)
        .map_err(config_error)?;
    let room =
        ShoeboxRoom::new(size, rev.absorption, cfg.speed_of_sound, fs).map_err(config_error)?;
    let response_s = cfg.room.response_s.unwrap_or(rev.response_s);
    Ok(Renderer::new(
        room,
        mics.to_vec(),
        RenderSettings {
            hop: ((cfg.room.update_interval_s * fs).round() as usize).max(1),
            response_len: ((response_s * fs).ceil() as usize).max(1),
            early_len: (cfg.room.early_s * fs).round() as usize,
            late_update_m: cfg.room.late_update_m,
            highpass_hz: cfg.room.highpass_hz,
        },
    ))
}

/// Renders every talker: the mixture at each microphone, and each talker's image at the
/// reference microphone.
fn render_talkers(
    renderer: &Renderer,
    talkers: &[Talker],
    len: usize,
    tick: &mut dyn FnMut(),
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let channels = renderer.channels();
    let mut mixture = vec![vec![0.0; len]; channels];
    let mut images = Vec::with_capacity(talkers.len());
    for t in talkers {
        let mut out = vec![vec![0.0; len]; channels];
        renderer.render(&t.dry, &|time| t.motion.position(time), &mut out, tick);
        for (m, o) in mixture.iter_mut().zip(&out) {
            m.iter_mut().zip(o).for_each(|(a, b)| *a += b);
        }
        images.push(out.swap_remove(0));
    }
    (mixture, images)
}

/// Adds the point noise source and the sensor noise at their SNRs (see [`noise`] for the
/// definition) to the mixture.
fn add_noise(
    cfg: &SimConfig,
    seed: u64,
    renderer: &Renderer,
    talkers: &[Talker],
    images: &[Vec<f64>],
    mixture: &mut [Vec<f64>],
    tick: &mut dyn FnMut(),
) {
    let fs = cfg.sample_rate as f64;
    let len = mixture.first().map_or(0, |m| m.len());
    let speech_ref: Vec<f64> = (0..len)
        .map(|n| images.iter().map(|s| s[n]).sum())
        .collect();
    let any_active: Vec<(f64, f64)> = talkers.iter().flat_map(|t| t.active.clone()).collect();
    let speech_power = noise::active_power(&speech_ref, &any_active, fs);
    if let Some(p) = &cfg.noise.point {
        let mut rng = rng_for(seed, streams::POINT, 0);
        let dry = noise::fan(len, fs, p.hum_hz, p.corner_hz, &mut rng);
        let mut out = vec![vec![0.0; len]; mixture.len()];
        let at = Vec3::from(p.position);
        renderer.render(&dry, &|_| at, &mut out, tick);
        let level = noise::mean_power(&out[0]);
        let target = speech_power / 10f64.powf(p.snr_db / 10.0);
        let g = if level > 0.0 {
            (target / level).sqrt()
        } else {
            0.0
        };
        for (m, o) in mixture.iter_mut().zip(&out) {
            m.iter_mut().zip(o).for_each(|(a, b)| *a += g * b);
        }
    }
    let sensor_power = speech_power / 10f64.powf(cfg.noise.snr_db / 10.0);
    for (i, m) in mixture.iter_mut().enumerate() {
        let w = noise::white(
            len,
            sensor_power,
            &mut rng_for(seed, streams::SENSOR, i as u64),
        );
        m.iter_mut().zip(&w).for_each(|(a, b)| *a += b);
    }
}

/// Every camera's detection frames.
fn camera_frames(
    cfg: &SimConfig,
    seed: u64,
    cameras: &[crate::geometry::Camera],
    talkers: &[Talker],
) -> Vec<crate::scene::DetectionFrame> {
    let clocks: Vec<FrameClock> = cfg
        .cameras
        .iter()
        .map(|c| FrameClock {
            fps: c.fps,
            start_s: c.start_s,
        })
        .collect();
    let motions: Vec<Motion> = talkers.iter().map(|t| t.motion.clone()).collect();
    detect::detect(
        &cfg.detector,
        cameras,
        &clocks,
        &motions,
        cfg.duration_s,
        &mut rng_for(seed, streams::DETECT, 0),
    )
}
