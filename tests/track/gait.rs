//! Walkers and standers: the tracks' gait (`[track.motion] gait`) carries a walker's velocity
//! through a gap in the camera's detections and keeps a standing talker's track still.

use avsep::geometry::Vec3;
use avsep::track::{StepInput, TrackerConfig};

use crate::room::{DIR_A, DIR_B, DT, RoomSim, nearest, room_tracker};

/// Mean 3-D error of the track nearest a talker at `at(t)` over `judged` (s), averaged over
/// seeds 1-6. The camera sees him except in `hidden` (he turns away); he talks throughout and
/// the array on the x = 0 wall hears him, which gives a direction and no range.
fn error(
    cfg: &TrackerConfig,
    at: impl Fn(f64) -> Vec3,
    hidden: (f64, f64),
    judged: (f64, f64),
) -> f64 {
    let origin = Vec3::new(0.1, 2.5, 1.0);
    let mut errors = Vec::new();
    for seed in 1..=6 {
        let mut tracker = room_tracker(cfg, seed);
        let mut sim = RoomSim::new(seed + 100);
        for k in 0..(judged.1 / DT).ceil() as u64 {
            let t = k as f64 * DT;
            let p = at(t);
            let seen = if (hidden.0..hidden.1).contains(&t) {
                0.0
            } else {
                0.95
            };
            let scans = vec![
                sim.camera_scan(&[p], seen),
                sim.direction_scan(DIR_A, origin, &[p], 1.0),
            ];
            let out = tracker.step(&StepInput { k, t, scans });
            if (judged.0..judged.1).contains(&t) {
                let e = nearest(&out, &p).map_or(f64::INFINITY, |e| (e.position - p).norm());
                errors.push(e.min(2.0));
            }
        }
    }
    errors.iter().sum::<f64>() / errors.len() as f64
}

fn without_gait() -> TrackerConfig {
    let mut cfg = TrackerConfig::default();
    cfg.motion.gait = false;
    cfg
}

/// A walker at 0.6 m/s across the camera's view turns away from it for 1.5 s. Heard by one
/// array only, his range is then unobserved: a standing track forgets his velocity within half
/// a second and falls behind him along the array's bearing, a walking one keeps going.
#[test]
fn a_walker_the_camera_loses_is_followed_by_his_gait() {
    let walker = |t: f64| Vec3::new(1.2 + 0.6 * t, 3.2 - 0.1 * t, 1.6);
    let (hidden, judged) = ((3.5, 5.0), (4.5, 5.0));
    let on = error(&TrackerConfig::default(), walker, hidden, judged);
    let off = error(&without_gait(), walker, hidden, judged);
    println!("walker unseen for 1.5 s, error at its end: gait {on:.3} m, without {off:.3} m");
    assert!(on < 0.8 * off, "gait {on} against {off}");
    assert!(on < 0.6, "gait {on}");
}

/// A talker who stands: the gait costs his track no accuracy.
#[test]
fn a_standing_talker_stays_put_with_a_gait() {
    let stander = |_: f64| Vec3::new(2.5, 3.0, 1.6);
    let judged = (2.0, 6.0);
    let on = error(&TrackerConfig::default(), stander, (0.0, 0.0), judged);
    let off = error(&without_gait(), stander, (0.0, 0.0), judged);
    println!("standing talker: error gait {on:.3} m, without {off:.3} m");
    assert!(on < 1.1 * off + 0.01, "gait {on} against {off}");
    assert!(on < 0.1, "gait {on}");
}

/// Heard only, by two arrays: a track no camera saw has no gait, and the tracker's output is
/// the same with the gait on or off, to the bit.
#[test]
fn a_track_no_camera_saw_moves_as_without_a_gait() {
    let (a, b) = (Vec3::new(0.1, 2.5, 1.0), Vec3::new(5.9, 4.9, 1.0));
    let run = |cfg: &TrackerConfig| {
        let mut tracker = room_tracker(cfg, 3);
        let mut sim = RoomSim::new(4);
        let mut out = Vec::new();
        for k in 0..60u64 {
            let t = k as f64 * DT;
            let p = [Vec3::new(1.5 + 0.5 * t, 3.0, 1.6)];
            let scans = vec![
                sim.direction_scan(DIR_A, a, &p, 1.0),
                sim.direction_scan(DIR_B, b, &p, 1.0),
            ];
            let est = tracker.step(&StepInput { k, t, scans });
            out.extend(est.iter().map(|e| (e.label, e.position, e.velocity)));
        }
        out
    };
    let on = run(&TrackerConfig::default());
    assert!(!on.is_empty(), "the talker was not tracked");
    assert_eq!(on, run(&without_gait()));
}
