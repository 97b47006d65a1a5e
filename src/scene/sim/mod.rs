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
mod validate;
pub mod voice;

use std::path::{Path as FsPath, PathBuf};

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
use motion::{FacingPlan, Motion, Path};
use render::{RenderSettings, Renderer};
use room::ShoeboxRoom;

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

/// One talker, ready to render.
struct Talker {
    id: String,
    motion: Motion,
    dry: Vec<f64>,
    active: Vec<(f64, f64)>,
}

/// As [`simulate`], calling `progress(done, total)` as rendering advances.
pub fn simulate_with_progress(
    cfg: &SimConfig,
    seed: u64,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Scene, SimError> {
    cfg.validate()?;
    let layout = layout::build(cfg)?;
    let fs = cfg.sample_rate as f64;
    let len = (cfg.duration_s * fs).round() as usize;
    let mics: Vec<Vec3> = layout
        .arrays
        .iter()
        .flat_map(|a| a.mics.iter().copied())
        .collect();
    let talkers = make_talkers(cfg, seed, &layout, len)?;

    // Acoustics: tune the walls on a source at the region centre heard at the reference mic.
    let size = Vec3::from(cfg.room.size_m);
    let probe = layout.region.map_or(size * 0.5, |r| r.center());
    let rev = reverberation_for(&size, cfg.room.rt60_s, &probe, &mics[0], cfg.speed_of_sound)
        .map_err(|message| SimError::Config {
            field: "room.rt60_s".into(),
            message,
        })?;
    let room = ShoeboxRoom::new(size, rev.absorption, cfg.speed_of_sound, fs).map_err(|m| {
        SimError::Config {
            field: "room".into(),
            message: m,
        }
    })?;
    let response_s = cfg.room.response_s.unwrap_or(rev.response_s);
    let renderer = Renderer::new(
        room,
        mics.clone(),
        RenderSettings {
            hop: ((cfg.room.update_interval_s * fs).round() as usize).max(1),
            response_len: ((response_s * fs).ceil() as usize).max(1),
            early_len: (cfg.room.early_s * fs).round() as usize,
            late_update_m: cfg.room.late_update_m,
            highpass_hz: cfg.room.highpass_hz,
        },
    );
    let units_per = renderer.segments(len);
    let total = units_per * (talkers.len() + usize::from(cfg.noise.point.is_some()));
    let mut done = 0usize;
    progress(done, total);

    let mut mixture = vec![vec![0.0; len]; mics.len()];
    let mut images = Vec::with_capacity(talkers.len());
    for t in &talkers {
        let mut out = vec![vec![0.0; len]; mics.len()];
        renderer.render(
            &t.dry,
            &|time| t.motion.position(time),
            &mut out,
            &mut || {
                done += 1;
                progress(done, total);
            },
        );
        for (m, o) in mixture.iter_mut().zip(&out) {
            m.iter_mut().zip(o).for_each(|(a, b)| *a += b);
        }
        images.push(out.swap_remove(0));
    }

    // Noise, against the speech power at the reference microphone while anyone talks.
    let speech_ref: Vec<f64> = (0..len)
        .map(|n| images.iter().map(|s| s[n]).sum())
        .collect();
    let any_active: Vec<(f64, f64)> = talkers.iter().flat_map(|t| t.active.clone()).collect();
    let speech_power = noise::active_power(&speech_ref, &any_active, fs);
    if let Some(p) = &cfg.noise.point {
        let dry = noise::fan(
            len,
            fs,
            p.hum_hz,
            p.corner_hz,
            &mut rng_for(seed, streams::POINT, 0),
        );
        let mut out = vec![vec![0.0; len]; mics.len()];
        let at = Vec3::from(p.position);
        renderer.render(&dry, &|_| at, &mut out, &mut || {
            done += 1;
            progress(done, total);
        });
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

    let clocks: Vec<FrameClock> = cfg
        .cameras
        .iter()
        .map(|c| FrameClock {
            fps: c.fps,
            start_s: c.start_s,
        })
        .collect();
    let motions: Vec<Motion> = talkers.iter().map(|t| t.motion.clone()).collect();
    let detections = detect::detect(
        &cfg.detector,
        &layout.cameras,
        &clocks,
        &motions,
        cfg.duration_s,
        &mut rng_for(seed, streams::DETECT, 0),
    );
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

/// The talkers' motion, dry signals and speech intervals.
fn make_talkers(
    cfg: &SimConfig,
    seed: u64,
    layout: &crate::geometry::Layout,
    len: usize,
) -> Result<Vec<Talker>, SimError> {
    let fs = cfg.sample_rate as f64;
    let d = cfg.duration_s;
    let size = Vec3::from(cfg.room.size_m);
    // Sway never takes a mouth closer to a wall than a path may go.
    let m = WALL_MARGIN_M;
    let bounds = Aabb::new(Vec3::new(m, m, 0.3), size - Vec3::new(m, m, m)).map_err(|e| {
        SimError::Config {
            field: "room.size_m".into(),
            message: e.message,
        }
    })?;
    let default_look = layout
        .cameras
        .first()
        .map(|c| c.centre())
        .unwrap_or_else(|| layout.arrays[0].centroid());
    let files = match &cfg.speech_dir {
        Some(dir) => {
            let files = speech_files::load_speech(FsPath::new(dir), cfg.sample_rate)?;
            if files.len() < cfg.speakers.len() {
                return Err(SimError::Speech {
                    path: PathBuf::from(dir),
                    message: format!(
                        "holds {} WAV file(s) but the scene has {} talkers (one file each)",
                        files.len(),
                        cfg.speakers.len()
                    ),
                });
            }
            Some(files)
        }
        None => None,
    };
    let mut talkers = Vec::with_capacity(cfg.speakers.len());
    for (i, s) in cfg.speakers.iter().enumerate() {
        let idx = i as u64;
        let exit = s.exit_s.unwrap_or(d).min(d);
        let plan = FacingPlan {
            look_at: s.facing.look_at.unwrap_or([default_look.x, default_look.y]),
            follow_motion: s.facing.follow_motion,
            away: s.facing.away_s.iter().map(|a| (a[0], a[1])).collect(),
            jitter_rad: s.facing.jitter_deg.to_radians(),
        };
        let motion = Motion::new(
            s.enter_s,
            exit,
            Path::from_keyframes(&s.path),
            s.mouth_height_m,
            s.sway_m,
            bounds,
            &plan,
            &mut rng_for(seed, streams::MOTION, idx),
        );
        let phrases: Vec<(f64, f64)> = if s.speech.phrases.is_empty() {
            let from = s.enter_s + s.speech.lead_s;
            let mut rng = rng_for(seed, streams::PHRASES, idx);
            presets::draw_phrases(from, exit - 0.1, &s.speech, &mut rng)
                .into_iter()
                .map(|p| (p[0], p[1]))
                .collect()
        } else {
            s.speech
                .phrases
                .iter()
                .map(|p| (p[0], p[1].min(d)))
                .collect()
        };
        let (dry, active) = match &files {
            Some(files) => {
                let dry = speech_files::lay_out(&files[i].samples, &phrases, fs, len);
                let active = speech_files::speech_intervals(&dry, fs);
                (dry, active)
            }
            None => {
                let mut rng = rng_for(seed, streams::VOICE, idx);
                let dry = voice::synthesize(&s.voice, &phrases, fs, len, &mut rng);
                (dry, phrases)
            }
        };
        let id = s.id.clone().unwrap_or_else(|| format!("s{}", i + 1));
        if talkers.iter().any(|t: &Talker| t.id == id) {
            return Err(SimError::Config {
                field: format!("speakers[{i}].id"),
                message: format!("{id:?} is already used by another talker"),
            });
        }
        talkers.push(Talker {
            id,
            motion,
            dry,
            active,
        });
    }
    Ok(talkers)
}

/// The mouth positions every [`TRUTH_STEP_S`] from entry to exit (both included).
fn trajectory(m: &Motion) -> Vec<(f64, Vec3)> {
    let mut out = Vec::new();
    let mut j = 0usize;
    loop {
        let t = m.enter_s + j as f64 * TRUTH_STEP_S;
        if t >= m.exit_s - 1e-6 {
            break;
        }
        out.push((t, m.position(t)));
        j += 1;
    }
    out.push((m.exit_s, m.position(m.exit_s)));
    out
}
