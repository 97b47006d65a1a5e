//! Speakers whose paths cross: labels must follow the right target through the crossing.

use avsep::geometry::Vec3;
use avsep::label::Label;
use avsep::track::{MotionKind, StepInput, TrackerConfig, TrackerKind};

use crate::room::{DT, RoomSim, nearest, room_tracker};

#[test]
fn two_crossing_targets_keep_their_labels() {
    // Two speakers walk past each other at 0.8 m/s; camera + audio candidates.
    let mut tracker = room_tracker(&TrackerConfig::default(), 5);
    let mut sim = RoomSim::new(6);
    let path = |i: usize, t: f64| -> Vec3 {
        let x = if i == 0 { 1.0 + 0.8 * t } else { 5.0 - 0.8 * t };
        Vec3::new(
            x.clamp(1.0, 5.0),
            3.0 + if i == 0 { 0.25 } else { -0.25 },
            1.6,
        )
    };
    let mut labels: [Option<Label>; 2] = [None, None];
    let (mut err_sum, mut err_n) = (0.0, 0);
    for k in 0..60u64 {
        let t = (k as f64 - 10.0).max(0.0) * DT;
        let sources = [path(0, t), path(1, t)];
        let scans = vec![
            sim.camera_scan(&sources, 0.9),
            sim.position_scan(&sources, 1.0, 10),
        ];
        let out = tracker.step(&StepInput {
            k,
            t: k as f64 * DT,
            scans,
        });
        if k >= 10 {
            assert_eq!(out.len(), 2, "step {k}: {out:?}");
            for i in 0..2 {
                let e = nearest(&out, &sources[i]).unwrap();
                let err = (e.position - sources[i]).norm();
                // A single step can follow a clutter candidate (P_D 0.6 audio, 10 clutter per
                // step, Langevin sigma 1.2 m/s); the mean error is the accuracy check.
                assert!(err < 0.6, "step {k} target {i}: {e:?}");
                err_sum += err;
                err_n += 1;
                match labels[i] {
                    None => labels[i] = Some(e.label),
                    Some(l) => assert_eq!(e.label, l, "step {k}: target {i} changed label"),
                }
            }
        }
    }
    assert_ne!(labels[0], labels[1]);
    let mean = err_sum / err_n as f64;
    println!("crossing targets: mean position error {mean:.3} m");
    assert!(mean < 0.15, "mean error {mean}");
}

/// Two targets cross in an X: A walks from (1.5, 2) to (4.5, 4), B from (1.5, 4) to (4.5, 2),
/// meeting at (3, 3). Returns how many target-steps (outside the crossing, where they are not
/// resolvable) had an estimate within 0.3 m, and out of how many, after asserting that each
/// target kept one label.
fn x_crossing(cfg: &TrackerConfig, seed: u64) -> (usize, usize) {
    let mut tracker = room_tracker(cfg, seed);
    let mut sim = RoomSim::new(seed + 1);
    let path = |i: usize, t: f64| -> Vec3 {
        let a = (t / 5.0).clamp(0.0, 1.0);
        let (y0, y1) = if i == 0 { (2.0, 4.0) } else { (4.0, 2.0) };
        Vec3::new(1.5 + 3.0 * a, y0 + (y1 - y0) * a, 1.6)
    };
    let mut labels: [Option<Label>; 2] = [None, None];
    let (mut found, mut eligible) = (0, 0);
    for k in 0..60u64 {
        let t = (k as f64 - 10.0).max(0.0) * DT;
        let sources = [path(0, t), path(1, t)];
        let scans = vec![
            sim.camera_scan(&sources, 0.95),
            sim.position_scan(&sources, 1.0, 3),
        ];
        let out = tracker.step(&StepInput {
            k,
            t: k as f64 * DT,
            scans,
        });
        if k < 10 || (sources[0] - sources[1]).norm() < 0.6 {
            continue;
        }
        for (i, s) in sources.iter().enumerate() {
            eligible += 1;
            let Some(e) = nearest(&out, s).filter(|e| (e.position - s).norm() < 0.3) else {
                continue;
            };
            found += 1;
            match labels[i] {
                None => labels[i] = Some(e.label),
                Some(l) => assert_eq!(e.label, l, "{:?} step {k}: target {i}", cfg.tracker),
            }
        }
    }
    assert_ne!(labels[0], labels[1]);
    (found, eligible)
}

/// Through an X crossing only the velocity tells the two tracks apart: the Langevin default
/// remembers it for about half a second (beta = 2/s), which carries the labels through on about
/// half of the seeds; the constant-velocity model keeps them on nearly all (19 of 20 seeds
/// measured), so that is what this scenario runs, as the GM-PHD one below.
#[test]
fn glmb_keeps_labels_through_an_x_crossing() {
    let mut cfg = TrackerConfig::default();
    cfg.motion.model = MotionKind::ConstantVelocity;
    cfg.motion.accel_std_m_per_s2 = [1.0, 1.0, 0.3];
    let (found, eligible) = x_crossing(&cfg, 61);
    println!("GLMB X crossing: {found} of {eligible} target-steps estimated");
    assert_eq!(found, eligible);
}

/// GM-PHD label propagation (spec 002 5.3, Fig. 4.1): at the crossing the PHD's components take
/// the same measurements, and afterwards each estimate must take back the label of the target
/// whose predicted position it continues. Matching by predicted position needs a motion model
/// with velocity memory (the thesis used CV/CT models); the Langevin model forgets velocity in
/// a few steps.
#[test]
fn gmphd_label_propagation_through_an_x_crossing() {
    let mut cfg = TrackerConfig {
        tracker: TrackerKind::Gmphd,
        ..TrackerConfig::default()
    };
    cfg.motion.model = MotionKind::ConstantVelocity;
    cfg.motion.accel_std_m_per_s2 = [1.0, 1.0, 0.3];
    let (found, eligible) = x_crossing(&cfg, 61);
    println!("GM-PHD X crossing: {found} of {eligible} target-steps estimated");
    assert!(found * 10 >= eligible * 8, "{found} of {eligible}");
}
