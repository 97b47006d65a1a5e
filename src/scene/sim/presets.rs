//! Presets: rooms of a documented kind whose talkers are placed and scripted from the seed, so
//! that different seeds give different scenes of the same kind.

use std::f64::consts::PI;

use rand::Rng;

use super::config::{
    ArrayConfig, ArrayGeometry, CameraConfig, DetectorConfig, FacingConfig, NoiseConfig,
    PointNoiseConfig, RoomConfig, SimConfig, SpeakerConfig, SpeechConfig, VoiceConfig,
};
use super::motion::Path;
use super::{SimError, rng_for, streams};

/// The presets with a one-line description each.
pub const PRESETS: &[(&str, &str)] = &[
    (
        "paper-linear6",
        "the seed paper's room (7.67 x 3.41 x 2.7 m, RT60 0.25 s): 6-mic linear array under the \
         paper's camera P(1) (1920x1080, 8 fps); talkers enter near (2.0,0.7), (3.0,0.5), \
         (4.0,0.6) at about 0.5, 3 and 6 s and walk towards the sensors; one turns away near \
         the end. 12 s, 3 talkers, SNR 25 dB",
    ),
    (
        "uca8",
        "meeting room 6 x 5 x 3 m, RT60 0.3 s: 8-mic circular array (5 cm radius) on a table at \
         the centre, wall camera 1280x720 at 15 fps; talkers seated or standing around the table \
         1.0-1.8 m away, 40 deg or more apart, the third walks in late. 20 s, 3 talkers, SNR 25 dB",
    ),
    (
        "two-arrays",
        "AV16.3-like room 8.2 x 3.6 x 2.4 m, RT60 0.3 s: two 8-mic circular arrays (10 cm radius) \
         0.8 m apart on a table, 3 corner/wall cameras 720x576 at 25 fps, a projector fan at \
         20 dB SNR; talkers walk around the table, one enters late and one leaves. 15 s, \
         3 talkers, SNR 25 dB",
    ),
    (
        "single",
        "one talker in a quiet uca8-like room (RT60 0.2 s, SNR 40 dB, no point noise), standing \
         or seated, moving little, talking with pauses. 10 s",
    ),
];

/// Overrides of a preset's defaults (the command line's --duration, --speakers, --rt60, --snr).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PresetOptions {
    /// Scene length (s).
    pub duration_s: Option<f64>,
    /// Number of talkers.
    pub speakers: Option<usize>,
    /// Reverberation time (s).
    pub rt60_s: Option<f64>,
    /// Sensor-noise SNR (dB).
    pub snr_db: Option<f64>,
}

impl SimConfig {
    /// The configuration of preset `name` (see [`PRESETS`]) with talkers drawn from `seed`.
    pub fn preset(name: &str, opts: &PresetOptions, seed: u64) -> Result<Self, SimError> {
        let bad = |field: &str, message: String| SimError::Config {
            field: field.into(),
            message,
        };
        let max_speakers = match name {
            "paper-linear6" | "two-arrays" => 4,
            "uca8" => 6,
            "single" => 1,
            _ => {
                let known: Vec<&str> = PRESETS.iter().map(|p| p.0).collect();
                return Err(bad(
                    "preset",
                    format!("unknown preset {name:?} (known: {})", known.join(", ")),
                ));
            }
        };
        if let Some(d) = opts.duration_s
            && !(d.is_finite() && d > 0.0 && d <= 3600.0)
        {
            return Err(bad("duration_s", format!("{d} s is not in (0, 3600]")));
        }
        if let Some(n) = opts.speakers
            && !(1..=max_speakers).contains(&n)
        {
            return Err(bad(
                "speakers",
                format!("preset {name} takes 1 to {max_speakers} talkers, not {n}"),
            ));
        }
        if let Some(r) = opts.rt60_s
            && !(r.is_finite() && r > 0.0 && r <= 3.0)
        {
            return Err(bad("room.rt60_s", format!("{r} s is not in (0, 3]")));
        }
        if let Some(s) = opts.snr_db
            && !(s.is_finite() && (-20.0..=120.0).contains(&s))
        {
            return Err(bad("noise.snr_db", format!("{s} dB is not in [-20, 120]")));
        }
        Ok(match name {
            "paper-linear6" => paper_linear6(opts, seed),
            "uca8" => uca8(opts, seed),
            "two-arrays" => two_arrays(opts, seed),
            _ => single(opts, seed),
        })
    }
}

/// Rounds to the millisecond or millimetre, so that configurations print readably.
fn r3(x: f64) -> f64 {
    (x * 1000.0).round() / 1000.0
}

fn u<R: Rng + ?Sized>(rng: &mut R, lo: f64, hi: f64) -> f64 {
    rng.random_range(lo..hi)
}

fn base(opts: &PresetOptions, duration: f64, size: [f64; 3], rt60: f64, snr: f64) -> SimConfig {
    SimConfig {
        duration_s: opts.duration_s.unwrap_or(duration),
        sample_rate: 16000,
        speed_of_sound: 343.0,
        room: RoomConfig {
            size_m: size,
            rt60_s: opts.rt60_s.unwrap_or(rt60),
            ..RoomConfig::default()
        },
        arrays: Vec::new(),
        cameras: Vec::new(),
        detector: DetectorConfig::default(),
        speakers: Vec::new(),
        noise: NoiseConfig {
            snr_db: opts.snr_db.unwrap_or(snr),
            point: None,
        },
        region: None,
        speech_dir: None,
        peak_level: 0.5,
    }
}

/// Distinct voices: sexes alternate from a random first one, F0s at least 12 % apart.
pub(crate) fn draw_voices<R: Rng + ?Sized>(n: usize, rng: &mut R) -> Vec<VoiceConfig> {
    let first_female = rng.random_range(0.0..1.0) < 0.5;
    let mut voices: Vec<VoiceConfig> = Vec::with_capacity(n);
    for i in 0..n {
        let female = i.is_multiple_of(2) == first_female;
        let mut v = VoiceConfig::default();
        for _ in 0..100 {
            v = VoiceConfig {
                f0_hz: r3(if female {
                    u(rng, 175.0, 240.0)
                } else {
                    u(rng, 95.0, 140.0)
                }),
                f0_range_st: r3(u(rng, 4.0, 7.0)),
                formant_scale: r3(if female {
                    u(rng, 1.12, 1.2)
                } else {
                    u(rng, 0.95, 1.05)
                }),
                syllable_rate_hz: r3(u(rng, 3.5, 5.5)),
                level_db: r3(u(rng, -2.0, 2.0)),
                breathiness: r3(if female {
                    u(rng, 0.15, 0.3)
                } else {
                    u(rng, 0.05, 0.15)
                }),
                open_quotient: r3(if female {
                    u(rng, 0.6, 0.75)
                } else {
                    u(rng, 0.5, 0.6)
                }),
            };
            let distinct = voices
                .iter()
                .all(|w| (w.f0_hz / v.f0_hz).ln().abs() > 1.12f64.ln());
            if distinct {
                break;
            }
        }
        voices.push(v);
    }
    voices
}

/// Phrases drawn between `from` and `to` (s) from the speech timing ranges.
pub(crate) fn draw_phrases<R: Rng + ?Sized>(
    from: f64,
    to: f64,
    speech: &SpeechConfig,
    rng: &mut R,
) -> Vec<[f64; 2]> {
    let range = |r: [f64; 2], rng: &mut R| {
        if r[1] > r[0] {
            rng.random_range(r[0]..r[1])
        } else {
            r[0]
        }
    };
    let shortest = speech.phrase_s[0].min(0.5);
    let mut out = Vec::new();
    let mut t = from;
    loop {
        let len = range(speech.phrase_s, rng).min(to - t);
        if len < shortest {
            break;
        }
        out.push([r3(t), r3(t + len)]);
        t = r3(t + len) + range(speech.pause_s, rng);
    }
    out
}

/// Appends keyframes walking from `from` to `to` at mean speed `speed` starting at `t`, with a
/// slight bend half way; returns the arrival time.
fn walk<R: Rng + ?Sized>(
    keys: &mut Vec<[f64; 3]>,
    from: [f64; 2],
    to: [f64; 2],
    t: f64,
    speed: f64,
    rng: &mut R,
) -> f64 {
    let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
    let len = dx.hypot(dy);
    if len < 1e-6 {
        return t;
    }
    let bend = u(rng, -0.08, 0.08) * len;
    let mid = [
        from[0] + 0.5 * dx - bend * dy / len,
        from[1] + 0.5 * dy + bend * dx / len,
    ];
    let arrive = r3(t + len / speed);
    keys.push([r3(0.5 * (t + arrive)), r3(mid[0]), r3(mid[1])]);
    keys.push([arrive, r3(to[0]), r3(to[1])]);
    arrive
}

/// Smallest distance between two talkers present at the same time (paths sampled every 0.1 s).
fn min_separation(speakers: &[SpeakerConfig], duration: f64) -> f64 {
    let paths: Vec<Path> = speakers
        .iter()
        .map(|s| Path::from_keyframes(&s.path))
        .collect();
    let mut best = f64::INFINITY;
    let mut t = 0.0;
    while t <= duration {
        for i in 0..speakers.len() {
            for j in i + 1..speakers.len() {
                let here = |s: &SpeakerConfig| t >= s.enter_s && s.exit_s.is_none_or(|e| t <= e);
                if here(&speakers[i]) && here(&speakers[j]) {
                    let (a, b) = (paths[i].at(t), paths[j].at(t));
                    best = best.min((a[0] - b[0]).hypot(a[1] - b[1]));
                }
            }
        }
        t += 0.1;
    }
    best
}

/// Smallest distance of a path (sampled every 0.1 s) to `point`.
fn clearance(keys: &[[f64; 3]], point: [f64; 2]) -> f64 {
    let path = Path::from_keyframes(keys);
    let (t0, t1) = (keys[0][0], keys[keys.len() - 1][0]);
    let mut best = f64::INFINITY;
    let mut t = t0;
    while t <= t1 + 1e-9 {
        let p = path.at(t);
        best = best.min((p[0] - point[0]).hypot(p[1] - point[1]));
        t += 0.1;
    }
    best
}

/// Whether the segment a-b passes through the box [lo, hi] (slab test).
fn segment_hits_box(a: [f64; 2], b: [f64; 2], lo: [f64; 2], hi: [f64; 2]) -> bool {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for k in 0..2 {
        let d = b[k] - a[k];
        if d.abs() < 1e-12 {
            if a[k] < lo[k] || a[k] > hi[k] {
                return false;
            }
        } else {
            let (mut s0, mut s1) = ((lo[k] - a[k]) / d, (hi[k] - a[k]) / d);
            if s0 > s1 {
                std::mem::swap(&mut s0, &mut s1);
            }
            t0 = t0.max(s0);
            t1 = t1.min(s1);
            if t0 > t1 {
                return false;
            }
        }
    }
    true
}

fn speech_timing() -> SpeechConfig {
    SpeechConfig::default()
}

/// The seed paper's recording room (spec 003 sections 4.3, 7.1-7.2).
fn paper_linear6(opts: &PresetOptions, seed: u64) -> SimConfig {
    let mut rng = rng_for(seed, streams::PRESET, 0);
    let mut cfg = base(opts, 12.0, [7.67, 3.41, 2.7], 0.25, 25.0);
    let d = cfg.duration_s;
    let n = opts.speakers.unwrap_or(3);
    cfg.arrays = vec![ArrayConfig {
        id: "a0".into(),
        geometry: ArrayGeometry::Linear {
            centre: [3.0, 3.25, 1.95],
            count: 6,
            spacing_m: 0.04,
            axis: [1.0, 0.0, 0.0],
        },
    }];
    cfg.cameras = vec![CameraConfig {
        id: "cam0".into(),
        width: 1920,
        height: 1080,
        fps: 8.0,
        start_s: 0.0,
        projection: Some([
            [-1021.7, -827.2, -575.8, 7071.5],
            [31.8, 142.0, -1184.0, 2012.8],
            [0.04, -0.83, -0.56, 3.81],
        ]),
        position: None,
        look_at: None,
        hfov_deg: 84.0,
    }];
    cfg.detector.clutter_per_frame = 0.5;
    let camera_xy = [3.048, 3.270];
    let entries = [[2.0, 0.7], [3.0, 0.5], [4.0, 0.6], [5.0, 0.7]];
    let enter_nominal = [0.5, 3.0, 6.0, 8.0];
    // Short scenes keep the choreography, compressed in time.
    let squeeze = (d / 12.0).min(1.0);
    let voices = draw_voices(n, &mut rng);
    let away = rng.random_range(0..n);
    let mut speakers = Vec::new();
    for _attempt in 0..200 {
        speakers = (0..n)
            .map(|i| {
                let enter = r3(((enter_nominal[i] + u(&mut rng, -0.3, 0.3)) * squeeze).max(0.0));
                let start = [
                    r3(entries[i][0] + u(&mut rng, -0.15, 0.15)),
                    r3(entries[i][1] + u(&mut rng, -0.1, 0.1)),
                ];
                // Converge a little towards the sensors so that nobody leaves the camera's
                // field of view on the way.
                let end = [
                    start[0] + 0.3 * (camera_xy[0] - start[0]) + u(&mut rng, -0.1, 0.1),
                    u(&mut rng, 1.8, 2.2),
                ];
                let depart = r3(enter + u(&mut rng, 0.3, 1.0) * squeeze);
                let mut path = vec![[enter, start[0], start[1]], [depart, start[0], start[1]]];
                let speed = u(&mut rng, 0.2, 0.45);
                walk(&mut path, start, end, depart, speed, &mut rng);
                let away_s = if i == away {
                    vec![[r3(d - u(&mut rng, 1.5, 2.5) * squeeze), r3(d + 1.0)]]
                } else {
                    Vec::new()
                };
                let quiet_from = away_s.first().map_or(d - 0.1, |a| a[0] - 0.3);
                let speech = speech_timing();
                let lead = u(&mut rng, 0.2, 0.6) * squeeze.max(0.5);
                SpeakerConfig {
                    id: None,
                    enter_s: enter,
                    exit_s: None,
                    mouth_height_m: r3(u(&mut rng, 1.6, 1.75)),
                    path,
                    sway_m: 0.02,
                    facing: FacingConfig {
                        look_at: Some(camera_xy),
                        follow_motion: true,
                        away_s,
                        jitter_deg: 10.0,
                    },
                    voice: voices[i].clone(),
                    speech: SpeechConfig {
                        phrases: draw_phrases(enter + lead, quiet_from, &speech, &mut rng),
                        ..speech
                    },
                }
            })
            .collect();
        if min_separation(&speakers, d) >= 0.6 {
            break;
        }
    }
    cfg.speakers = speakers;
    cfg
}

/// Room, array and camera shared by `uca8` and `single`.
fn meeting_room(cfg: &mut SimConfig) -> ([f64; 2], [f64; 2]) {
    let table = [3.0, 2.5];
    cfg.arrays = vec![ArrayConfig {
        id: "a0".into(),
        geometry: ArrayGeometry::Circular {
            centre: [table[0], table[1], 0.8],
            count: 8,
            radius_m: 0.05,
            start_azimuth_deg: 0.0,
        },
    }];
    let camera = [3.0, 0.12, 2.2];
    cfg.cameras = vec![CameraConfig {
        id: "cam0".into(),
        width: 1280,
        height: 720,
        fps: 15.0,
        start_s: 0.0,
        projection: None,
        position: Some(camera),
        look_at: Some([3.0, 2.7, 1.2]),
        hfov_deg: 90.0,
    }];
    (table, [camera[0], camera[1]])
}

/// Azimuths in [lo, hi] (rad) at least `gap` apart, in random order.
fn spaced_azimuths<R: Rng + ?Sized>(n: usize, lo: f64, hi: f64, gap: f64, rng: &mut R) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::new();
    for _ in 0..1000 {
        out.clear();
        for _ in 0..n {
            let a = rng.random_range(lo..hi);
            if out.iter().all(|b| (a - b).abs() >= gap) {
                out.push(a);
            }
        }
        if out.len() == n {
            break;
        }
    }
    // Fall back to even spacing when random draws keep colliding (many talkers).
    if out.len() < n {
        out = (0..n)
            .map(|i| lo + (hi - lo) * (i as f64 + 0.5) / n as f64)
            .collect();
    }
    out
}

/// A meeting around a table with a circular array.
fn uca8(opts: &PresetOptions, seed: u64) -> SimConfig {
    let mut rng = rng_for(seed, streams::PRESET, 1);
    let mut cfg = base(opts, 20.0, [6.0, 5.0, 3.0], 0.3, 25.0);
    let d = cfg.duration_s;
    let n = opts.speakers.unwrap_or(3);
    let (table, camera_xy) = meeting_room(&mut cfg);
    // Faces turn between the table and the camera.
    let look = [
        table[0] + 0.4 * (camera_xy[0] - table[0]),
        table[1] + 0.4 * (camera_xy[1] - table[1]),
    ];
    let door = [0.5, 4.5];
    let voices = draw_voices(n, &mut rng);
    let squeeze = (d / 20.0).min(1.0);
    let mut speakers = Vec::new();
    for _attempt in 0..200 {
        let az = spaced_azimuths(
            n,
            -10f64.to_radians(),
            190f64.to_radians(),
            40f64.to_radians(),
            &mut rng,
        );
        let walker = (n >= 3).then_some(n - 1);
        let away = rng.random_range(0..n.saturating_sub(walker.map_or(0, |_| 1)).max(1));
        let mut ok = true;
        speakers = (0..n)
            .map(|i| {
                let r = u(&mut rng, 1.0, 1.8);
                let seat = [
                    r3(table[0] + r * az[i].cos()),
                    r3(table[1] + r * az[i].sin()),
                ];
                let standing = match i {
                    0 => false,
                    1 => true,
                    _ => Some(i) == walker || rng.random_range(0.0..1.0) < 0.5,
                };
                let height = if standing {
                    u(&mut rng, 1.5, 1.75)
                } else {
                    u(&mut rng, 1.1, 1.3)
                };
                let (enter, path) = if Some(i) == walker {
                    let enter = r3(u(&mut rng, 0.15, 0.3) * d);
                    let via_r = r + 0.7;
                    let via = [
                        (table[0] + via_r * az[i].cos()).clamp(0.5, 5.5),
                        (table[1] + via_r * az[i].sin()).clamp(0.5, 4.5),
                    ];
                    let mut path = vec![[enter, door[0], door[1]]];
                    let speed = u(&mut rng, 0.35, 0.55);
                    let t = walk(&mut path, door, via, enter, speed, &mut rng);
                    walk(&mut path, via, seat, t, speed, &mut rng);
                    ok &= clearance(&path, table) >= 0.9;
                    (enter, path)
                } else {
                    let mut path = vec![[0.0, seat[0], seat[1]]];
                    if standing && rng.random_range(0.0..1.0) < 0.5 {
                        // A step sideways around the table half way through.
                        let t = r3(u(&mut rng, 0.3, 0.6) * d);
                        let a = az[i] + u(&mut rng, -0.15, 0.15);
                        let to = [table[0] + r * a.cos(), table[1] + r * a.sin()];
                        path.push([t, seat[0], seat[1]]);
                        walk(&mut path, seat, to, t, 0.3, &mut rng);
                    }
                    (0.0, path)
                };
                let away_s = if i == away && d >= 4.0 {
                    let a = r3(u(&mut rng, 0.3, 0.6) * d);
                    vec![[a, r3(a + u(&mut rng, 1.5, 3.0) * squeeze)]]
                } else {
                    Vec::new()
                };
                let speech = speech_timing();
                let lead = u(&mut rng, 0.2, 0.6);
                SpeakerConfig {
                    id: None,
                    enter_s: enter,
                    exit_s: None,
                    mouth_height_m: r3(height),
                    path,
                    sway_m: if standing { 0.03 } else { 0.015 },
                    facing: FacingConfig {
                        look_at: Some(look),
                        follow_motion: true,
                        away_s,
                        jitter_deg: 15.0,
                    },
                    voice: voices[i].clone(),
                    speech: SpeechConfig {
                        phrases: draw_phrases(enter + lead, d - 0.1, &speech, &mut rng),
                        ..speech
                    },
                }
            })
            .collect();
        if ok && min_separation(&speakers, d) >= 0.6 {
            break;
        }
    }
    cfg.speakers = speakers;
    cfg
}

/// A wandering path inside `area` avoiding the box `keep_out`, from `start` at `t0` until `t1`.
#[allow(clippy::too_many_arguments)]
fn wander<R: Rng + ?Sized>(
    start: [f64; 2],
    t0: f64,
    t1: f64,
    area: ([f64; 2], [f64; 2]),
    keep_out: ([f64; 2], [f64; 2]),
    keys: &mut Vec<[f64; 3]>,
    rng: &mut R,
) -> ([f64; 2], f64) {
    keys.push([r3(t0), r3(start[0]), r3(start[1])]);
    let (mut here, mut t) = (start, t0);
    while t < t1 {
        let dwell = u(rng, 0.5, 2.5);
        t = r3(t + dwell);
        keys.push([t, r3(here[0]), r3(here[1])]);
        let mut next = here;
        for _ in 0..100 {
            let cand = [u(rng, area.0[0], area.1[0]), u(rng, area.0[1], area.1[1])];
            let len = (cand[0] - here[0]).hypot(cand[1] - here[1]);
            if (0.8..=3.0).contains(&len) && !segment_hits_box(here, cand, keep_out.0, keep_out.1) {
                next = cand;
                break;
            }
        }
        if next == here {
            continue;
        }
        let speed = u(rng, 0.3, 0.6);
        t = walk(keys, here, next, t, speed, rng);
        here = [r3(next[0]), r3(next[1])];
    }
    (here, t)
}

/// AV16.3-like: two circular arrays on a table, three cameras, talkers walking around.
fn two_arrays(opts: &PresetOptions, seed: u64) -> SimConfig {
    let mut rng = rng_for(seed, streams::PRESET, 2);
    let mut cfg = base(opts, 15.0, [8.2, 3.6, 2.4], 0.3, 25.0);
    let d = cfg.duration_s;
    let n = opts.speakers.unwrap_or(3);
    let circular = |id: &str, x: f64| ArrayConfig {
        id: id.into(),
        geometry: ArrayGeometry::Circular {
            centre: [x, 1.8, 0.75],
            count: 8,
            radius_m: 0.1,
            start_azimuth_deg: 0.0,
        },
    };
    cfg.arrays = vec![circular("a0", 3.7), circular("a1", 4.5)];
    let camera = |id: &str, pos: [f64; 3], look: [f64; 3]| CameraConfig {
        id: id.into(),
        width: 720,
        height: 576,
        fps: 25.0,
        start_s: 0.0,
        projection: None,
        position: Some(pos),
        look_at: Some(look),
        hfov_deg: 75.0,
    };
    cfg.cameras = vec![
        camera("cam0", [0.15, 0.15, 2.25], [4.1, 1.8, 1.2]),
        camera("cam1", [8.05, 0.15, 2.25], [4.1, 1.8, 1.2]),
        camera("cam2", [4.1, 3.45, 2.25], [4.1, 1.4, 1.2]),
    ];
    cfg.noise.point = Some(PointNoiseConfig {
        position: [4.1, 1.8, 2.25],
        snr_db: 20.0,
        hum_hz: 100.0,
        corner_hz: 500.0,
    });
    let table = [4.1, 1.8];
    let keep_out = ([3.2 - 0.45, 1.4 - 0.45], [5.0 + 0.45, 2.2 + 0.45]);
    let area = ([0.5, 0.5], [7.7, 3.1]);
    let door = [0.5, 3.1];
    let voices = draw_voices(n, &mut rng);
    let mut speakers = Vec::new();
    for _attempt in 0..200 {
        speakers = (0..n)
            .map(|i| {
                let late = i == 1 && n >= 2;
                let leaves = i == 2;
                let enter = if late {
                    r3(u(&mut rng, 0.2, 0.35) * d)
                } else {
                    0.0
                };
                let start = if late {
                    door
                } else {
                    loop {
                        let p = [
                            u(&mut rng, area.0[0], area.1[0]),
                            u(&mut rng, area.0[1], area.1[1]),
                        ];
                        let inside = (0..2).all(|k| p[k] > keep_out.0[k] && p[k] < keep_out.1[k]);
                        if !inside {
                            break [r3(p[0]), r3(p[1])];
                        }
                    }
                };
                let until = if leaves { u(&mut rng, 0.5, 0.7) * d } else { d };
                let mut path = Vec::new();
                let (here, t) = wander(start, enter, until, area, keep_out, &mut path, &mut rng);
                let exit = if leaves {
                    let t = walk(&mut path, here, door, t, u(&mut rng, 0.4, 0.6), &mut rng);
                    Some(r3(t + 0.2))
                } else {
                    None
                };
                let speech = speech_timing();
                let lead = u(&mut rng, 0.2, 0.6);
                let quiet_from = exit.map_or(d - 0.1, |e| e.min(d) - 0.5);
                SpeakerConfig {
                    id: None,
                    enter_s: enter,
                    exit_s: exit.filter(|e| *e < d),
                    mouth_height_m: r3(u(&mut rng, 1.5, 1.75)),
                    path,
                    sway_m: 0.02,
                    facing: FacingConfig {
                        look_at: Some(table),
                        follow_motion: true,
                        away_s: Vec::new(),
                        jitter_deg: 15.0,
                    },
                    voice: voices[i].clone(),
                    speech: SpeechConfig {
                        phrases: draw_phrases(enter + lead, quiet_from, &speech, &mut rng),
                        ..speech
                    },
                }
            })
            .collect();
        let crosses = speakers.iter().any(|s| {
            s.path.windows(2).any(|w| {
                segment_hits_box(
                    [w[0][1], w[0][2]],
                    [w[1][1], w[1][2]],
                    keep_out.0,
                    keep_out.1,
                )
            })
        });
        if !crosses && min_separation(&speakers, d) >= 0.6 {
            break;
        }
    }
    cfg.speakers = speakers;
    cfg
}

/// One talker in a quiet meeting room.
pub(crate) fn single(opts: &PresetOptions, seed: u64) -> SimConfig {
    let mut rng = rng_for(seed, streams::PRESET, 3);
    let mut cfg = base(opts, 10.0, [6.0, 5.0, 3.0], 0.2, 40.0);
    let d = cfg.duration_s;
    let (table, camera_xy) = meeting_room(&mut cfg);
    let az = u(&mut rng, 40.0, 140.0) * PI / 180.0;
    let r = u(&mut rng, 1.0, 1.8);
    let spot = [r3(table[0] + r * az.cos()), r3(table[1] + r * az.sin())];
    let standing = rng.random_range(0.0..1.0) < 0.5;
    let mut path = vec![[0.0, spot[0], spot[1]]];
    if standing && rng.random_range(0.0..1.0) < 0.5 {
        let t = r3(u(&mut rng, 0.3, 0.6) * d);
        let to = [spot[0] + u(&mut rng, -0.3, 0.3), spot[1]];
        path.push([t, spot[0], spot[1]]);
        walk(&mut path, spot, to, t, 0.3, &mut rng);
    }
    let voice = draw_voices(1, &mut rng).remove(0);
    let speech = speech_timing();
    let lead = u(&mut rng, 0.2, 0.6);
    cfg.speakers = vec![SpeakerConfig {
        id: None,
        enter_s: 0.0,
        exit_s: None,
        mouth_height_m: r3(if standing {
            u(&mut rng, 1.5, 1.75)
        } else {
            u(&mut rng, 1.1, 1.3)
        }),
        path,
        sway_m: 0.015,
        facing: FacingConfig {
            look_at: Some(camera_xy),
            follow_motion: false,
            away_s: Vec::new(),
            jitter_deg: 8.0,
        },
        voice,
        speech: SpeechConfig {
            phrases: draw_phrases(lead, d - 0.1, &speech, &mut rng),
            ..speech
        },
    }];
    cfg
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_is_valid_and_seeds_change_placements() {
        for (name, _) in PRESETS {
            let a = SimConfig::preset(name, &PresetOptions::default(), 1).unwrap();
            a.validate().unwrap_or_else(|e| panic!("{name}: {e}"));
            let b = SimConfig::preset(name, &PresetOptions::default(), 2).unwrap();
            assert_ne!(a.speakers[0].path, b.speakers[0].path, "{name}");
            let short = PresetOptions {
                duration_s: Some(2.0),
                ..Default::default()
            };
            SimConfig::preset(name, &short, 7)
                .unwrap()
                .validate()
                .unwrap_or_else(|e| panic!("{name} (2 s): {e}"));
        }
        let e = SimConfig::preset("nope", &PresetOptions::default(), 1).unwrap_err();
        assert!(e.to_string().contains("uca8"), "{e}");
        let two = PresetOptions {
            speakers: Some(2),
            ..Default::default()
        };
        assert_eq!(
            SimConfig::preset("uca8", &two, 1).unwrap().speakers.len(),
            2
        );
    }

    #[test]
    fn presets_keep_talkers_apart_and_voices_distinct() {
        for seed in 1..6 {
            for name in ["paper-linear6", "uca8", "two-arrays"] {
                let c = SimConfig::preset(name, &PresetOptions::default(), seed).unwrap();
                let sep = min_separation(&c.speakers, c.duration_s);
                assert!(sep >= 0.6, "{name} seed {seed}: {sep}");
                for (i, a) in c.speakers.iter().enumerate() {
                    for b in &c.speakers[i + 1..] {
                        let ratio = (a.voice.f0_hz / b.voice.f0_hz).ln().abs();
                        assert!(ratio > 1.1f64.ln(), "{name} seed {seed}");
                    }
                }
            }
        }
    }

    #[test]
    fn segments_crossing_a_box_are_found() {
        let (lo, hi) = ([1.0, 1.0], [2.0, 2.0]);
        assert!(segment_hits_box([0.0, 1.5], [3.0, 1.5], lo, hi));
        assert!(!segment_hits_box([0.0, 0.0], [3.0, 0.5], lo, hi));
        assert!(segment_hits_box([1.5, 1.5], [1.6, 1.6], lo, hi));
    }
}
