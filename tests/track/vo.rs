//! Vo's standard linear-Gaussian scenario (Vo, Vo & Hoang 2017 / the GLMB toolbox), scored with
//! the project's own OSPA.

use avsep::eval::ospa::OspaParams;
use avsep::geometry::Vec3;
use avsep::track::{
    BirthTerm, Gaussian, GlmbTracker, Measurement, MotionModel, Scan, SensorModel, StepInput,
    Tracker, TrackerConfig,
};
use nalgebra::{DMatrix, SMatrix, SVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Poisson};

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

const VO_STEPS: usize = 100;

/// [x vx y vy] at birth, birth step, last step (inclusive).
const VO_TARGETS: [([f64; 4], usize, usize); 12] = [
    ([0.0, 0.0, 0.0, -10.0], 1, 70),
    ([400.0, -10.0, -600.0, 5.0], 1, 100),
    ([-800.0, 20.0, -200.0, -5.0], 1, 70),
    ([400.0, -7.0, -600.0, -4.0], 20, 100),
    ([400.0, -2.5, -600.0, 10.0], 20, 100),
    ([0.0, 7.5, 0.0, -5.0], 20, 100),
    ([-800.0, 12.0, -200.0, 7.0], 40, 100),
    ([-200.0, 15.0, 800.0, -10.0], 40, 100),
    ([-800.0, 3.0, -200.0, 15.0], 60, 100),
    ([-200.0, -3.0, 800.0, -15.0], 60, 100),
    ([0.0, -20.0, 0.0, -15.0], 80, 100),
    ([-200.0, 15.0, 800.0, -5.0], 80, 100),
];

/// True positions per step (k = 1..=100), noiseless constant velocity with T = 1.
fn vo_truth() -> Vec<Vec<Vec3>> {
    let mut truth = vec![Vec::new(); VO_STEPS];
    for (x0, birth, death) in VO_TARGETS {
        let [mut x, vx, mut y, vy] = x0;
        for k in birth..=death.min(VO_STEPS) {
            truth[k - 1].push(Vec3::new(x, y, 0.0));
            x += vx;
            y += vy;
        }
    }
    truth
}

/// Measurements: P_D 0.98, N(0, 10^2 I) noise, Poisson(30) clutter uniform on [-1000, 1000]^2.
fn vo_measurements(truth: &[Vec<Vec3>], seed: u64) -> Vec<Vec<Measurement>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 10.0).unwrap();
    let clutter = Poisson::new(30.0).unwrap();
    truth
        .iter()
        .map(|objs| {
            let mut z = Vec::new();
            for p in objs {
                if rng.random::<f64>() < 0.98 {
                    z.push(Measurement::Point {
                        z: vec![p.x + noise.sample(&mut rng), p.y + noise.sample(&mut rng)],
                    });
                }
            }
            let n: f64 = clutter.sample(&mut rng);
            for _ in 0..n as usize {
                z.push(Measurement::Point {
                    z: vec![
                        rng.random_range(-1000.0..1000.0),
                        rng.random_range(-1000.0..1000.0),
                    ],
                });
            }
            z
        })
        .collect()
}

/// The GLMB configured for Vo's model: state [x y vx vy], constant velocity sigma_v = 5,
/// P_S 0.99, four LMB birth terms r = 0.03, 1000 requested hypotheses, the plain estimator.
fn vo_tracker(seed: u64) -> GlmbTracker<4> {
    let mut cfg = TrackerConfig {
        survival_probability: 0.99,
        gate_probability: 0.9999999,
        ..TrackerConfig::default()
    };
    cfg.birth.from_measurements = false;
    cfg.estimator.hysteresis_steps = 0;
    cfg.glmb.requested_hypotheses = 1000;
    cfg.glmb.max_hypotheses = 1000;
    let motion = MotionModel::<4>::ConstantVelocity {
        accel_std_m_per_s2: [5.0, 5.0, 0.0],
    };
    let sensor = SensorModel::GenericPoint {
        h: DMatrix::from_row_slice(2, 4, &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]),
        r: DMatrix::from_diagonal_element(2, 2, 100.0),
        p_detect: 0.98,
        clutter_rate: 30.0,
        clutter_density: 1.0 / (2000.0 * 2000.0),
    };
    let births = [
        [0.1, 0.1],
        [400.0, -600.0],
        [-800.0, -200.0],
        [-200.0, 800.0],
    ]
    .iter()
    .map(|p| BirthTerm {
        density: Gaussian {
            mean: SVector::<f64, 4>::new(p[0], p[1], 0.0, 0.0),
            cov: SMatrix::<f64, 4, 4>::identity() * 100.0,
        },
        existence: 0.03,
    })
    .collect();
    GlmbTracker::new(&cfg, motion, vec![sensor], None, births, seed).unwrap()
}

fn vo_run(seed: u64) -> Vec<f64> {
    let truth = vo_truth();
    let meas = vo_measurements(&truth, 1000 + seed);
    let mut tracker = vo_tracker(seed);
    (0..VO_STEPS)
        .map(|k| {
            let est = tracker.step(&StepInput {
                k: k as u64 + 1,
                t: k as f64 + 1.0,
                scans: vec![Scan {
                    sensor: 0,
                    measurements: meas[k].clone(),
                    activity: None,
                    sounding: Vec::new(),
                }],
            });
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
