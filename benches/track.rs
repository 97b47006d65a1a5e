//! Tracker speed: Vo's standard linear-Gaussian scenario (100 steps, 1000 requested
//! hypotheses) and one audio-visual step with 3 tracks, 10 audio and 3 visual measurements.

use std::hint::black_box;

use avsep::geometry::{Aabb, Camera, Pixel, Vec3};
use avsep::track::scenarios::{vo_measurements, vo_step, vo_tracker, vo_truth};
use avsep::track::{
    GlmbTracker, Measurement, MotionModel, Scan, SensorModel, StepInput, Tracker, TrackerConfig,
};
use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use nalgebra::Matrix3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// The scenario's 100 step inputs with measurements drawn from `seed`.
fn vo_inputs(seed: u64) -> Vec<StepInput> {
    vo_measurements(&vo_truth(), seed)
        .into_iter()
        .enumerate()
        .map(|(i, z)| vo_step(i + 1, z))
        .collect()
}

fn camera() -> Camera {
    let k = Matrix3::new(1000.0, 0.0, 960.0, 0.0, 1000.0, 540.0, 0.0, 0.0, 1.0);
    let (s, c) = 15f64.to_radians().sin_cos();
    let r = Matrix3::new(1.0, 0.0, 0.0, 0.0, -s, -c, 0.0, c, -s);
    let centre = Vec3::new(3.0, 0.05, 2.0);
    Camera::from_krt("cam", 1920.0, 1080.0, k, r, -(r * centre), None).unwrap()
}

/// One audio-visual step input: 3 speakers seen by the camera, 3 true + 7 clutter audio
/// candidates.
fn av_input(k: u64, rng: &mut ChaCha8Rng, room: &Aabb, sources: &[Vec3; 3]) -> StepInput {
    let cam = camera();
    let n = Normal::new(0.0, 1.0).unwrap();
    let mut pixels = Vec::new();
    let mut audio = Vec::new();
    for s in sources {
        let px = cam.project(s).unwrap();
        // Face boxes of 0.19 m at 1000 px focal length, with 5 % size jitter.
        let size = 1000.0 * 0.19 / cam.depth(s) * (1.0 + 0.05 * n.sample(rng));
        pixels.push(Measurement::Face {
            point: Pixel::new(px.x + 5.0 * n.sample(rng), px.y + 5.0 * n.sample(rng)),
            size_px: size,
        });
        let e = Vec3::new(n.sample(rng), n.sample(rng), n.sample(rng)) * 0.1;
        audio.push(Measurement::Position(s + e));
    }
    for _ in 0..7 {
        audio.push(Measurement::Position(room.sample(rng)));
    }
    StepInput {
        k,
        t: k as f64 * 0.128,
        scans: vec![
            Scan {
                sensor: 0,
                measurements: pixels,
                activity: None,
                sounding: Vec::new(),
            },
            Scan {
                sensor: 1,
                measurements: audio,
                activity: Some(1.0),
                sounding: Vec::new(),
            },
        ],
    }
}

fn benches(c: &mut Criterion) {
    let inputs = vo_inputs(7);
    c.bench_function("vo_scenario_100_steps_1000_hypotheses", |b| {
        b.iter(|| {
            let mut t = vo_tracker(1);
            for input in &inputs {
                black_box(t.step(input));
            }
        })
    });

    let mut without_gait = TrackerConfig::default();
    without_gait.motion.gait = false;
    for (name, cfg) in [
        (
            "av_step_3_tracks_10_audio_3_visual",
            TrackerConfig::default(),
        ),
        (
            "av_step_3_tracks_10_audio_3_visual_without_gait",
            without_gait,
        ),
    ] {
        let (tracker, input) = av_tracker(&cfg);
        c.bench_function(name, |b| {
            b.iter_batched(
                || tracker.clone(),
                |mut t| black_box(t.step(&input)),
                BatchSize::SmallInput,
            )
        });
    }
}

/// A tracker with settings `cfg` over a camera and 3-D audio candidates, run 41 steps into a
/// room with 3 talkers, and the next step's input.
fn av_tracker(cfg: &TrackerConfig) -> (GlmbTracker<6>, StepInput) {
    let room = Aabb::new(Vec3::zeros(), Vec3::new(6.0, 5.0, 2.5)).unwrap();
    let sensors = vec![
        SensorModel::CameraPoint {
            camera: Box::new(camera()),
            noise_std_px: 10.0,
            p_detect: 0.9,
            clutter_rate: 1.0,
            filter: cfg.camera.filter,
            face_size_m: Some(cfg.camera.face_size_m),
            face_size_log_std: cfg.camera.face_size_log_std,
        },
        SensorModel::AudioPosition {
            noise_std_m: 0.1,
            p_detect: 0.6,
            min_p_detect: 0.02,
            clutter_rate: 10.0,
            clutter_volume_m3: room.volume(),
        },
    ];
    let motion = MotionModel::<6>::from_config(&cfg.motion).unwrap();
    let mut tracker = GlmbTracker::new(cfg, motion, sensors, Some(room), vec![], 3).unwrap();
    let sources = [
        Vec3::new(1.5, 3.0, 1.6),
        Vec3::new(3.0, 2.5, 1.5),
        Vec3::new(4.5, 3.5, 1.7),
    ];
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for k in 0..40 {
        tracker.step(&av_input(k, &mut rng, &room, &sources));
    }
    let tracks = tracker.step(&av_input(40, &mut rng, &room, &sources)).len();
    assert_eq!(tracks, 3, "the benchmark needs 3 established tracks");
    let input = av_input(41, &mut rng, &room, &sources);
    (tracker, input)
}

criterion_group!(track, benches);
criterion_main!(track);
