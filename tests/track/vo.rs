//! Vo's standard linear-Gaussian scenario (`avsep::track::scenarios`), scored with the project's
//! own OSPA.

use avsep::eval::ospa::OspaParams;
use avsep::geometry::Vec3;
use avsep::track::Tracker;
use avsep::track::scenarios::{VO_STEPS, vo_measurements, vo_step, vo_tracker, vo_truth};

/// OSPA distance of order p with cut-off c between two point sets.
fn ospa(x: &[Vec3], y: &[Vec3], c: f64, p: f64) -> f64 {
    avsep::eval::ospa::ospa(x, y, OspaParams::new(c, p)).total
}

#[test]
fn ospa_brute_force_check() {
    let x = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(10.0, 0.0, 0.0)];
    let y = [
        Vec3::new(9.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(500.0, 0.0, 0.0),
    ];
    // Best pairing: (0,1) and (10,9) cost 2; one unmatched at c = 100: (2 + 100) / 3.
    assert!((ospa(&x, &y, 100.0, 1.0) - 34.0).abs() < 1e-12);
    assert_eq!(ospa(&[], &[], 100.0, 1.0), 0.0);
    assert_eq!(ospa(&x, &[], 100.0, 1.0), 100.0);
}

fn vo_run(seed: u64) -> Vec<f64> {
    let truth = vo_truth();
    let meas = vo_measurements(&truth, 1000 + seed);
    let mut tracker = vo_tracker(seed);
    (0..VO_STEPS)
        .map(|k| {
            let est = tracker.step(&vo_step(k + 1, meas[k].clone()));
            let pos: Vec<Vec3> = est.iter().map(|e| e.position).collect();
            ospa(&pos, &truth[k], 100.0, 1.0)
        })
        .collect()
}

#[test]
fn vo_linear_gaussian_scenario_mean_ospa() {
    let seeds = 20;
    let mut total = 0.0;
    let mut per_step = vec![0.0; VO_STEPS];
    for seed in 0..seeds {
        let o = vo_run(seed);
        for (a, b) in per_step.iter_mut().zip(&o) {
            *a += b / seeds as f64;
        }
        total += o.iter().sum::<f64>() / VO_STEPS as f64;
    }
    let mean = total / seeds as f64;
    println!("Vo scenario: mean OSPA(c=100, p=1) over {seeds} seeds = {mean:.3}");
    let late: f64 = per_step[85..].iter().sum::<f64>() / 15.0;
    println!("  mean over steps 86-100 (12 targets established) = {late:.3}");
    assert!(mean <= 11.5, "mean OSPA {mean}");
}
