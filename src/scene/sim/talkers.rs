//! The talkers of a scene, ready to render: motion, dry signal, speech intervals, and the truth
//! trajectory sampled from the motion.

use std::path::{Path as FsPath, PathBuf};

use crate::geometry::{Aabb, Layout, Vec3};

use super::config::{SimConfig, SpeakerConfig};
use super::motion::{FacingPlan, Motion, Path};
use super::speech_files::{self, SpeechFile};
use super::{SimError, TRUTH_STEP_S, WALL_MARGIN_M, presets, rng_for, streams, voice};

/// One talker, ready to render.
pub struct Talker {
    /// Truth id.
    pub id: String,
    /// Where the mouth is and where the face points.
    pub motion: Motion,
    /// The dry (anechoic) speech, as long as the scene.
    pub dry: Vec<f64>,
    /// Speech intervals (s).
    pub active: Vec<(f64, f64)>,
}

/// The talkers of `cfg`, with `len` samples of speech each.
pub fn make_talkers(
    cfg: &SimConfig,
    seed: u64,
    layout: &Layout,
    len: usize,
) -> Result<Vec<Talker>, SimError> {
    let size = Vec3::from(cfg.room.size_m);
    // Sway never takes a mouth closer to a wall than a path may go.
    let m = WALL_MARGIN_M;
    let bounds = Aabb::new(Vec3::new(m, m, 0.3), size - Vec3::new(m, m, m)).map_err(|e| {
        SimError::Config {
            field: "room.size_m".into(),
            message: e.message,
        }
    })?;
    let look = layout
        .cameras
        .first()
        .map(|c| c.centre())
        .unwrap_or_else(|| layout.arrays[0].centroid());
    let files = match &cfg.speech_dir {
        Some(dir) => Some(speech_for(cfg, FsPath::new(dir))?),
        None => None,
    };
    let mut talkers: Vec<Talker> = Vec::with_capacity(cfg.speakers.len());
    for (i, s) in cfg.speakers.iter().enumerate() {
        let file = files.as_ref().map(|f| &f[i]);
        let t = make_talker(cfg, seed, i, s, bounds, [look.x, look.y], file, len);
        if talkers.iter().any(|o| o.id == t.id) {
            return Err(SimError::Config {
                field: format!("speakers[{i}].id"),
                message: format!("{:?} is already used by another talker", t.id),
            });
        }
        talkers.push(t);
    }
    Ok(talkers)
}

/// One speech file per talker from `dir`.
fn speech_for(cfg: &SimConfig, dir: &FsPath) -> Result<Vec<SpeechFile>, SimError> {
    let files = speech_files::load_speech(dir, cfg.sample_rate)?;
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
    Ok(files)
}

/// Talker `i`: its motion, phrases, and speech (synthetic, or laid out from `file`).
#[allow(clippy::too_many_arguments)]
fn make_talker(
    cfg: &SimConfig,
    seed: u64,
    i: usize,
    s: &SpeakerConfig,
    bounds: Aabb,
    default_look: [f64; 2],
    file: Option<&SpeechFile>,
    len: usize,
) -> Talker {
    let (fs, d, idx) = (cfg.sample_rate as f64, cfg.duration_s, i as u64);
    let exit = s.exit_s.unwrap_or(d).min(d);
    let plan = FacingPlan {
        look_at: s.facing.look_at.unwrap_or(default_look),
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
        let mut rng = rng_for(seed, streams::PHRASES, idx);
        let from = s.enter_s + s.speech.lead_s;
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
    let (dry, active) = match file {
        Some(f) => {
            let dry = speech_files::lay_out(&f.samples, &phrases, fs, len);
            let active = speech_files::speech_intervals(&dry, fs);
            (dry, active)
        }
        None => {
            let mut rng = rng_for(seed, streams::VOICE, idx);
            (
                voice::synthesize(&s.voice, &phrases, fs, len, &mut rng),
                phrases,
            )
        }
    };
    Talker {
        id: s.id.clone().unwrap_or_else(|| format!("s{}", i + 1)),
        motion,
        dry,
        active,
    }
}

/// The mouth positions every [`TRUTH_STEP_S`] from entry to exit (both included).
pub fn trajectory(m: &Motion) -> Vec<(f64, Vec3)> {
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
