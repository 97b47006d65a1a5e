//! Talkers walking around a table watched by two arrays and three cameras (`two-arrays`).

use rand::Rng;

use super::super::config::{
    ArrayConfig, ArrayGeometry, CameraConfig, FacingConfig, PointNoiseConfig, SimConfig,
    SpeakerConfig, SpeechConfig, VoiceConfig,
};
use super::super::validate::{WALL_MARGIN_M, inside_room};
use super::super::{rng_for, streams};
use super::{
    PresetOptions, base, draw_phrases, draw_voices, place_apart, r3, segment_hits_box, u, walk,
};

/// AV16.3-like: two circular arrays on a table, three cameras, talkers walking around.
pub(super) fn two_arrays(opts: &PresetOptions, seed: u64) -> SimConfig {
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
    // A projector fan above the table.
    cfg.noise.point = Some(PointNoiseConfig {
        position: [4.1, 1.8, 2.25],
        snr_db: 20.0,
        hum_hz: 100.0,
        corner_hz: 500.0,
    });
    let floor = Floor {
        table: [4.1, 1.8],
        // The table (3.2-5.0 x 1.4-2.2 m) with room for chairs and elbows.
        keep_out: ([2.75, 0.95], [5.45, 2.65]),
        area: ([0.5, 0.5], [7.7, 3.1]),
        door: [0.5, 3.1],
        duration: d,
    };
    let voices = draw_voices(n, &mut rng);
    let room = cfg.room.size_m;
    cfg.speakers = place_apart(d, || {
        let s: Vec<SpeakerConfig> = (0..n)
            .map(|i| {
                // The second talker comes in late, the third leaves early.
                let enters_late = i == 1;
                let leaves = i == 2;
                floor.walker(enters_late, leaves, voices[i].clone(), &mut rng)
            })
            .collect();
        // A long leg's bend (the walk to the door) can swing past a wall: draw again.
        let clear =
            !s.iter().any(|t| floor.crosses_table(t)) && s.iter().all(|t| stays_inside(t, room));
        (s, clear)
    });
    cfg
}

/// Whether every keyframe of a talker's path keeps the walls' margin in a room of `size` (m),
/// as the scene's validation requires.
fn stays_inside(s: &SpeakerConfig, size: [f64; 3]) -> bool {
    s.path
        .iter()
        .all(|k| inside_room([k[1], k[2], s.mouth_height_m], size, WALL_MARGIN_M))
}

/// Mean walking speed (m/s) of a talker heading for the door.
const DOOR_SPEED: f64 = 0.5;

/// The walkable floor around a table.
struct Floor {
    table: [f64; 2],
    keep_out: ([f64; 2], [f64; 2]),
    area: ([f64; 2], [f64; 2]),
    door: [f64; 2],
    duration: f64,
}

impl Floor {
    /// A walker wandering around the table with stops; `enters_late` comes in through the door
    /// at 20-35 % of the scene, `leaves` walks out through it after 50-70 %.
    fn walker<R: Rng + ?Sized>(
        &self,
        enters_late: bool,
        leaves: bool,
        voice: VoiceConfig,
        rng: &mut R,
    ) -> SpeakerConfig {
        let d = self.duration;
        let enter = if enters_late {
            r3(u(rng, 0.2, 0.35) * d)
        } else {
            0.0
        };
        let start = if enters_late {
            self.door
        } else {
            self.free_point(rng)
        };
        // A leaver is out of the door by 65-85 % of the scene.
        let leave_by = leaves.then(|| u(rng, 0.65, 0.85) * d);
        let mut path = Vec::new();
        let (here, t) = self.wander(start, enter, leave_by, &mut path, rng);
        let exit = leaves.then(|| {
            let t = walk(&mut path, here, self.door, t, DOOR_SPEED, rng);
            r3(t + 0.2)
        });
        let speech = SpeechConfig::default();
        let lead = u(rng, 0.2, 0.6);
        let quiet_from = exit.map_or(d - 0.1, |e| e.min(d) - 0.5);
        SpeakerConfig {
            id: None,
            enter_s: enter,
            exit_s: exit.filter(|e| *e < d),
            mouth_height_m: r3(u(rng, 1.5, 1.75)),
            path,
            sway_m: 0.02,
            facing: FacingConfig {
                look_at: Some(self.table),
                follow_motion: true,
                away_s: Vec::new(),
                jitter_deg: 15.0,
            },
            voice,
            speech: SpeechConfig {
                phrases: draw_phrases(enter + lead, quiet_from, &speech, rng),
                ..speech
            },
        }
    }

    /// A point of the walkable area outside the table's keep-out box.
    fn free_point<R: Rng + ?Sized>(&self, rng: &mut R) -> [f64; 2] {
        let (lo, hi) = self.keep_out;
        loop {
            let p = [
                u(rng, self.area.0[0], self.area.1[0]),
                u(rng, self.area.0[1], self.area.1[1]),
            ];
            if !(0..2).all(|k| p[k] > lo[k] && p[k] < hi[k]) {
                return p.map(r3);
            }
        }
    }

    /// Keyframes of a walk from `start` at `t0`: stops of 0.5-2.5 s, legs of 0.8-3 m at 0.3-0.6 m/s
    /// that go around the table, until the end of the scene or, with `leave_by`, as long as the
    /// door can still be reached by then. Returns where and when the walk ends.
    fn wander<R: Rng + ?Sized>(
        &self,
        start: [f64; 2],
        t0: f64,
        leave_by: Option<f64>,
        keys: &mut Vec<[f64; 3]>,
        rng: &mut R,
    ) -> ([f64; 2], f64) {
        let dist = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
        keys.push([r3(t0), r3(start[0]), r3(start[1])]);
        let (mut here, mut t) = (start, t0);
        while t < self.duration {
            let dwell = u(rng, 0.5, 2.5);
            let speed = u(rng, 0.3, 0.6);
            let next = (0..100).map(|_| self.free_point(rng)).find(|p| {
                let len = dist(here, *p);
                let in_time = leave_by.is_none_or(|by| {
                    t + dwell + len / speed + dist(*p, self.door) / DOOR_SPEED <= by
                });
                (0.8..=3.0).contains(&len)
                    && in_time
                    && !segment_hits_box(here, *p, self.keep_out.0, self.keep_out.1)
            });
            if next.is_none() && leave_by.is_some() {
                break;
            }
            t = r3(t + dwell);
            keys.push([t, r3(here[0]), r3(here[1])]);
            if let Some(next) = next {
                t = walk(keys, here, next, t, speed, rng);
                here = next;
            }
        }
        (here, t)
    }

    /// Whether any leg of a talker's path passes over the table.
    fn crosses_table(&self, s: &SpeakerConfig) -> bool {
        s.path.windows(2).any(|w| {
            let (a, b) = ([w[0][1], w[0][2]], [w[1][1], w[1][2]]);
            segment_hits_box(a, b, self.keep_out.0, self.keep_out.1)
        })
    }
}
