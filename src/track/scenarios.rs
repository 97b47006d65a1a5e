//! Vo's standard linear-Gaussian scenario (Vo, Vo & Hoang 2017; the GLMB toolbox's `gen_model`
//! and `gen_truth`): twelve targets crossing a 2 x 2 km surveillance region over 100 steps, for
//! the tracker's accuracy test and its speed benchmark.

use nalgebra::{DMatrix, SMatrix, SVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Poisson};

use super::{
    BirthTerm, Gaussian, GlmbTracker, Measurement, MotionModel, Scan, SensorModel, StepInput,
    TrackerConfig,
};
use crate::geometry::Vec3;

/// Steps of the scenario (k = 1..=100, T = 1 s).
pub const VO_STEPS: usize = 100;

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

/// True positions per step (index k - 1), noiseless constant velocity.
pub fn vo_truth() -> Vec<Vec<Vec3>> {
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

/// Measurements of `truth` drawn with `seed`: P_D 0.98, N(0, 10^2 I) noise, Poisson(30) clutter
/// uniform on [-1000, 1000]^2.
pub fn vo_measurements(truth: &[Vec<Vec3>], seed: u64) -> Vec<Vec<Measurement>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 10.0).expect("a positive standard deviation");
    let clutter = Poisson::new(30.0).expect("a positive rate");
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

/// Step `k` (from 1) of the scenario with these measurements, from the one sensor.
pub fn vo_step(k: usize, measurements: Vec<Measurement>) -> StepInput {
    StepInput {
        k: k as u64,
        t: k as f64,
        scans: vec![Scan {
            sensor: 0,
            measurements,
            activity: None,
            sounding: Vec::new(),
        }],
    }
}

/// The GLMB configured for Vo's model: state [x y vx vy], constant velocity sigma_v = 5, P_S
/// 0.99, four LMB birth terms r = 0.03, 1000 requested hypotheses, the plain estimator; `seed`
/// seeds its Gibbs sampler.
pub fn vo_tracker(seed: u64) -> GlmbTracker<4> {
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
    GlmbTracker::new(&cfg, motion, vec![sensor], None, births, seed)
        .expect("Vo's model is a valid tracker configuration")
}
