//! Meetings around a table with a circular array: `uca8` and `single`.

use std::f64::consts::PI;

use rand::Rng;

use super::super::config::{
    ArrayConfig, ArrayGeometry, CameraConfig, FacingConfig, SimConfig, SpeakerConfig, SpeechConfig,
    VoiceConfig,
};
use super::super::{rng_for, streams};
use super::{PresetOptions, base, clearance, draw_phrases, draw_voices, place_apart, r3, u, walk};

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
pub(super) fn uca8(opts: &PresetOptions, seed: u64) -> SimConfig {
    let mut rng = rng_for(seed, streams::PRESET, 1);
    let mut cfg = base(opts, 20.0, [6.0, 5.0, 3.0], 0.3, 25.0);
    let d = cfg.duration_s;
    let n = opts.speakers.unwrap_or(3);
    let (table, camera_xy) = meeting_room(&mut cfg);
    let meeting = Meeting {
        table,
        // Faces turn between the table and the camera.
        look: [
            table[0] + 0.4 * (camera_xy[0] - table[0]),
            table[1] + 0.4 * (camera_xy[1] - table[1]),
        ],
        door: [0.5, 4.5],
        duration: d,
    };
    let voices = draw_voices(n, &mut rng);
    cfg.speakers = place_apart(d, || {
        // Around the table on the far side from the camera (and its flanks).
        let (lo, hi, gap) = (
            (-10f64).to_radians(),
            190f64.to_radians(),
            40f64.to_radians(),
        );
        let az = spaced_azimuths(n, lo, hi, gap, &mut rng);
        let walker = (n >= 3).then_some(n - 1);
        let away = rng.random_range(0..n.saturating_sub(usize::from(walker.is_some())).max(1));
        let mut ok = true;
        let speakers = (0..n)
            .map(|i| {
                let role = match i {
                    _ if Some(i) == walker => Role::WalksIn,
                    0 => Role::Seated,
                    1 => Role::Standing,
                    _ if rng.random_range(0.0..1.0) < 0.5 => Role::Standing,
                    _ => Role::Seated,
                };
                let (s, clear) =
                    meeting.talker(az[i], role, i == away, voices[i].clone(), &mut rng);
                ok &= clear;
                s
            })
            .collect();
        (speakers, ok)
    });
    cfg
}

/// How a meeting participant behaves.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Role {
    /// Seated at the table, swaying a little.
    Seated,
    /// Standing at the table; may take a step sideways.
    Standing,
    /// Comes in through the door late and stands at the table.
    WalksIn,
}

/// The layout of a meeting around a table.
struct Meeting {
    table: [f64; 2],
    look: [f64; 2],
    door: [f64; 2],
    duration: f64,
}

impl Meeting {
    /// A participant at azimuth `az` around the table; false when a walk-in path would cross
    /// the table.
    fn talker<R: Rng + ?Sized>(
        &self,
        az: f64,
        role: Role,
        turns_away: bool,
        voice: VoiceConfig,
        rng: &mut R,
    ) -> (SpeakerConfig, bool) {
        let (d, table) = (self.duration, self.table);
        let r = u(rng, 1.0, 1.8);
        let at = |r: f64, a: f64| [table[0] + r * a.cos(), table[1] + r * a.sin()];
        let seat = at(r, az).map(r3);
        let height = if role == Role::Seated {
            u(rng, 1.1, 1.3)
        } else {
            u(rng, 1.5, 1.75)
        };
        let mut clear = true;
        let (enter, path) = if role == Role::WalksIn {
            let enter = r3(u(rng, 0.15, 0.3) * d);
            let via = at(r + 0.7, az);
            let via = [via[0].clamp(0.5, 5.5), via[1].clamp(0.5, 4.5)];
            let mut path = vec![[enter, self.door[0], self.door[1]]];
            let speed = u(rng, 0.35, 0.55);
            let t = walk(&mut path, self.door, via, enter, speed, rng);
            walk(&mut path, via, seat, t, speed, rng);
            clear = clearance(&path, table) >= 0.9;
            (enter, path)
        } else {
            let mut path = vec![[0.0, seat[0], seat[1]]];
            if role == Role::Standing && rng.random_range(0.0..1.0) < 0.5 {
                // A step sideways around the table half way through.
                let t = r3(u(rng, 0.3, 0.6) * d);
                let to = at(r, az + u(rng, -0.15, 0.15));
                path.push([t, seat[0], seat[1]]);
                walk(&mut path, seat, to, t, 0.3, rng);
            }
            (0.0, path)
        };
        let away_s = if turns_away && d >= 4.0 {
            let a = r3(u(rng, 0.3, 0.6) * d);
            vec![[a, r3(a + u(rng, 1.5, 3.0) * (d / 20.0).min(1.0))]]
        } else {
            Vec::new()
        };
        let speech = SpeechConfig::default();
        let lead = u(rng, 0.2, 0.6);
        let talker = SpeakerConfig {
            id: None,
            enter_s: enter,
            exit_s: None,
            mouth_height_m: r3(height),
            path,
            sway_m: if role == Role::Seated { 0.015 } else { 0.03 },
            facing: FacingConfig {
                look_at: Some(self.look),
                follow_motion: true,
                away_s,
                jitter_deg: 15.0,
            },
            voice,
            speech: SpeechConfig {
                phrases: draw_phrases(enter + lead, d - 0.1, &speech, rng),
                ..speech
            },
        };
        (talker, clear)
    }
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
    let speech = SpeechConfig::default();
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
