//! Integration tests of the tracker: Vo's standard linear-Gaussian scenario (OSPA), and
//! behaviour in a room with a camera and microphone arrays.

use std::f64::consts::PI;

use avsep::eval::ospa::OspaParams;
use avsep::geometry::{Aabb, Camera, Layout, MicArray, Pixel, Vec3, angle_diff, azimuth_of};
use avsep::label::Label;
use avsep::track::{
    BirthTerm, FilterKind, Gaussian, GlmbTracker, Measurement, MotionKind, MotionModel, Scan,
    SensorKey, SensorModel, StepInput, TrackEstimate, Tracker, TrackerConfig, TrackerKind,
    build_tracker, sensors_from_layout,
};
use nalgebra::{DMatrix, Matrix3, SMatrix, SVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Poisson};

// ---------------------------------------------------------------------------------------------
// OSPA, from the project's own evaluation module.

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

// ---------------------------------------------------------------------------------------------
// Vo's standard linear-Gaussian scenario (Vo, Vo & Hoang 2017 / the GLMB toolbox).

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

// ---------------------------------------------------------------------------------------------
// A room: 6 x 5 x 2.5 m, a camera on the y = 0 wall, arrays on the walls.

const DT: f64 = 0.128;

fn room() -> Aabb {
    Aabb::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(6.0, 5.0, 2.5)).unwrap()
}

/// A camera at (3, 0.05, 2.0) looking along +y, pitched 15 degrees down, 1000 px focal length.
fn camera() -> Camera {
    let k = Matrix3::new(1000.0, 0.0, 960.0, 0.0, 1000.0, 540.0, 0.0, 0.0, 1.0);
    let (s, c) = 15f64.to_radians().sin_cos();
    // Rows: camera x, y (down), z (forward) in world coordinates.
    let r = Matrix3::new(1.0, 0.0, 0.0, 0.0, -s, -c, 0.0, c, -s);
    let centre = Vec3::new(3.0, 0.05, 2.0);
    Camera::from_krt("cam", 1920.0, 1080.0, k, r, -(r * centre), None).unwrap()
}

fn camera_sensor() -> SensorModel {
    SensorModel::CameraPoint {
        camera: Box::new(camera()),
        noise_std_px: 10.0,
        p_detect: 0.9,
        clutter_rate: 1.0,
        filter: TrackerConfig::default().camera.filter,
        face_size_m: None,
        face_size_log_std: 0.1,
    }
}

fn position_sensor() -> SensorModel {
    SensorModel::AudioPosition {
        noise_std_m: 0.1,
        p_detect: 0.6,
        min_p_detect: 0.02,
        clutter_rate: 10.0,
        clutter_volume_m3: room().volume(),
    }
}

fn direction_sensor(origin: Vec3) -> SensorModel {
    SensorModel::AudioDirection {
        origin,
        noise_std_rad: 3f64.to_radians(),
        uses_elevation: false,
        cone_axis: None,
        p_detect: 0.6,
        min_p_detect: 0.02,
        clutter_rate: 2.0,
        filter: FilterKind::Ekf,
    }
}

/// Sensor indices of the room set-ups.
const CAM: usize = 0;
const POS: usize = 1;
const DIR_A: usize = 2;
const DIR_B: usize = 3;

fn room_sensors() -> Vec<SensorModel> {
    vec![
        camera_sensor(),
        position_sensor(),
        direction_sensor(Vec3::new(0.1, 2.5, 1.0)),
        direction_sensor(Vec3::new(5.9, 4.9, 1.0)),
    ]
}

fn room_tracker(cfg: &TrackerConfig, seed: u64) -> Box<dyn Tracker> {
    build_tracker(cfg, room_sensors(), Some(room()), seed).unwrap()
}

/// Synthetic measurements of the room sensors for sources at `sources` (speaking flags).
struct RoomSim {
    rng: ChaCha8Rng,
}

impl RoomSim {
    fn new(seed: u64) -> Self {
        Self {
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    fn normal(&mut self, sd: f64) -> f64 {
        Normal::new(0.0, sd).unwrap().sample(&mut self.rng)
    }

    fn camera_scan(&mut self, sources: &[Vec3], p_detect: f64) -> Scan {
        let cam = camera();
        let mut z = Vec::new();
        for s in sources {
            if let Some(px) = cam.project(s)
                && cam.contains_pixel(&px)
                && self.rng.random::<f64>() < p_detect
            {
                let (nu, nv) = (self.normal(5.0), self.normal(5.0));
                z.push(Measurement::Pixel(Pixel::new(px.x + nu, px.y + nv)));
            }
        }
        Scan {
            sensor: CAM,
            measurements: z,
            activity: None,
            sounding: Vec::new(),
        }
    }

    fn position_scan(&mut self, speaking: &[Vec3], activity: f64, clutter: usize) -> Scan {
        let mut z = Vec::new();
        for s in speaking {
            if self.rng.random::<f64>() < 0.6 {
                let n = Vec3::new(self.normal(0.1), self.normal(0.1), self.normal(0.1));
                z.push(Measurement::Position(s + n));
            }
        }
        for _ in 0..clutter {
            z.push(Measurement::Position(room().sample(&mut self.rng)));
        }
        Scan {
            sensor: POS,
            measurements: z,
            activity: Some(activity),
            sounding: Vec::new(),
        }
    }

    fn direction_scan(
        &mut self,
        sensor: usize,
        origin: Vec3,
        speaking: &[Vec3],
        activity: f64,
    ) -> Scan {
        let mut z = Vec::new();
        for s in speaking {
            if self.rng.random::<f64>() < 0.8 {
                let az = azimuth_of(&(s - origin)) + self.normal(2f64.to_radians());
                z.push(Measurement::Direction {
                    azimuth: az,
                    elevation: None,
                });
            }
        }
        if self.rng.random::<f64>() < 0.5 {
            let az = self.rng.random_range(-PI..PI);
            z.push(Measurement::Direction {
                azimuth: az,
                elevation: None,
            });
        }
        Scan {
            sensor,
            measurements: z,
            activity: Some(activity),
            sounding: Vec::new(),
        }
    }
}

fn nearest<'a>(est: &'a [TrackEstimate], p: &Vec3) -> Option<&'a TrackEstimate> {
    est.iter()
        .min_by(|a, b| (a.position - p).norm().total_cmp(&(b.position - p).norm()))
}

#[test]
fn a_track_is_born_from_measurements_and_converges_on_the_source() {
    let source = Vec3::new(2.2, 3.1, 1.6);
    let mut tracker = room_tracker(&TrackerConfig::default(), 1);
    let mut sim = RoomSim::new(2);
    let mut first_seen = None;
    let mut out = Vec::new();
    for k in 0..30 {
        let scans = vec![
            sim.camera_scan(&[source], 0.9),
            sim.position_scan(&[source], 1.0, 10),
        ];
        out = tracker.step(&StepInput {
            k,
            t: k as f64 * DT,
            scans,
        });
        if first_seen.is_none() && !out.is_empty() {
            first_seen = Some(k);
        }
    }
    let first = first_seen.expect("a track was born");
    println!("born at step {first} ({:.2} s)", first as f64 * DT);
    assert!(first as f64 * DT <= 0.5, "born after {first} steps");
    assert_eq!(out.len(), 1, "{out:?}");
    let err = (out[0].position - source).norm();
    println!("position error after 30 steps: {err:.3} m");
    assert!(err < 0.1, "error {err}");
    assert!(out[0].existence > 0.9);
    assert!(out[0].speaking > 0.3, "speaking {}", out[0].speaking);
    assert!(
        out.iter()
            .all(|e| e.covariance.iter().all(|v| v.is_finite()))
    );
}

#[test]
fn a_label_survives_a_two_second_audio_only_pause() {
    // Audio only: 3-D position candidates with 10 clutter per step, two arrays' directions.
    let source = Vec3::new(4.0, 2.0, 1.5);
    let mut tracker = room_tracker(&TrackerConfig::default(), 3);
    let mut sim = RoomSim::new(4);
    let dir_a = Vec3::new(0.1, 2.5, 1.0);
    let dir_b = Vec3::new(5.9, 4.9, 1.0);
    let mut label: Option<Label> = None;
    let speech = |k: u64| !(25..41).contains(&k); // 16 silent steps = 2.05 s
    for k in 0..60u64 {
        let (speaking, activity): (Vec<Vec3>, f64) = if speech(k) {
            (vec![source], 1.0)
        } else {
            (vec![], 0.02)
        };
        let clutter = if speech(k) { 10 } else { 3 };
        let scans = vec![
            sim.position_scan(&speaking, activity, clutter),
            sim.direction_scan(DIR_A, dir_a, &speaking, activity),
            sim.direction_scan(DIR_B, dir_b, &speaking, activity),
        ];
        let out = tracker.step(&StepInput {
            k,
            t: k as f64 * DT,
            scans,
        });
        if k >= 15 {
            let e = nearest(&out, &source).unwrap_or_else(|| panic!("step {k}: no track"));
            assert!((e.position - source).norm() < 0.5, "step {k}: {e:?}");
            match label {
                None => label = Some(e.label),
                Some(l) => assert_eq!(e.label, l, "step {k}: label changed"),
            }
            if (36..41).contains(&k) {
                assert!(e.speaking < 0.2, "step {k}: speaking {}", e.speaking);
            }
        }
    }
}

#[test]
fn candidates_that_no_longer_sound_hold_the_track_but_not_its_speaking() {
    // A talker stops at step 20, but the localiser's smoothed maps keep reporting him, marked
    // as no longer sounding: the track stays where he is, and `speaking` falls.
    let source = Vec3::new(3.0, 2.5, 1.5);
    let mut tracker = room_tracker(&TrackerConfig::default(), 7);
    let mut sim = RoomSim::new(8);
    for k in 0..40u64 {
        let mut scan = sim.position_scan(&[source], 1.0, 2);
        if k >= 20 {
            scan.sounding = scan
                .measurements
                .iter()
                .map(|m| match m {
                    Measurement::Position(p) => (p - source).norm() > 0.5,
                    _ => true,
                })
                .collect();
        }
        let out = tracker.step(&StepInput {
            k,
            t: k as f64 * DT,
            scans: vec![scan],
        });
        if k == 19 || k >= 26 {
            let e = nearest(&out, &source).unwrap_or_else(|| panic!("step {k}: no track"));
            assert!((e.position - source).norm() < 0.3, "step {k}: {e:?}");
            if k == 19 {
                assert!(e.speaking > 0.5, "step {k}: speaking {}", e.speaking);
            } else {
                assert!(e.speaking < 0.1, "step {k}: speaking {}", e.speaking);
            }
        }
    }
}

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

/// A speaker tracked with camera and audio for 2 s, then silent (activity 0) for `silent` steps
/// in which the camera sends no frame (`frames` false) or frames without the face, then seen
/// again for 5 steps; the existence of the track at the speaker each step (0 when none is
/// reported) and the labels reported there.
fn silent_and_unseen(frames: bool, silent: u64, seed: u64) -> (Vec<f64>, Vec<Label>) {
    let source = Vec3::new(3.0, 2.5, 1.6);
    let mut tracker = room_tracker(&TrackerConfig::default(), seed);
    let mut sim = RoomSim::new(seed + 1);
    let (mut existence, mut labels) = (Vec::new(), Vec::new());
    for k in 0..16 + silent + 5 {
        let quiet = (16..16 + silent).contains(&k);
        let mut scans = vec![sim.position_scan(
            if quiet {
                &[]
            } else {
                std::slice::from_ref(&source)
            },
            if quiet { 0.0 } else { 1.0 },
            0,
        )];
        if !quiet {
            scans.push(sim.camera_scan(&[source], 1.0));
        } else if frames {
            scans.push(Scan {
                sensor: CAM,
                measurements: vec![],
                activity: None,
                sounding: Vec::new(),
            });
        }
        let out = tracker.step(&StepInput {
            k,
            t: k as f64 * DT,
            scans,
        });
        let e = out.iter().find(|e| (e.position - source).norm() < 0.5);
        existence.push(e.map_or(0.0, |e| e.existence));
        if let Some(e) = e
            && !labels.contains(&e.label)
        {
            labels.push(e.label);
        }
    }
    (existence, labels)
}

#[test]
fn an_absent_camera_does_not_penalise_but_an_empty_scan_does() {
    let (absent, _) = silent_and_unseen(false, 3, 7);
    let (empty, _) = silent_and_unseen(true, 3, 7);
    let (absent, empty) = (&absent[16..19], &empty[16..19]);
    println!("existence over 3 steps: camera absent {absent:.4?}, camera saw nothing {empty:.4?}");
    assert!(
        absent.iter().all(|&r| r > 0.99),
        "absent camera: {absent:?}"
    );
    assert!(empty[0] < absent[0], "{empty:?} vs {absent:?}");
    assert!(empty[1] < empty[0] && empty[2] < empty[1], "{empty:?}");
}

/// A silent speaker who looks away from the camera for 2 s (16 frames without the face) keeps
/// the label: after the first misses the face mode explains the rest. A plain camera P_D of 0.9
/// would cost 0.1 per frame and end the track within three.
#[test]
fn a_silent_speaker_turned_away_from_the_camera_for_two_seconds_keeps_the_label() {
    for seed in [7, 9, 11] {
        let (existence, labels) = silent_and_unseen(true, 16, seed);
        let pause = &existence[16..32];
        println!("seed {seed}: existence while turned away {pause:.3?}");
        assert!(pause.iter().all(|&r| r > 0.5), "seed {seed}: {pause:?}");
        assert_eq!(labels.len(), 1, "seed {seed}: {labels:?}");
        assert!(
            existence[33..].iter().all(|&r| r > 0.99),
            "{:?}",
            &existence[32..]
        );
    }
    let mut plain = TrackerConfig::default();
    plain.face.enabled = false;
    let mut tracker = room_tracker(&plain, 7);
    let mut sim = RoomSim::new(8);
    let source = Vec3::new(3.0, 2.5, 1.6);
    let mut last = Vec::new();
    for k in 0..22u64 {
        let seen = k < 16;
        let scans = vec![
            sim.position_scan(
                if seen {
                    std::slice::from_ref(&source)
                } else {
                    &[]
                },
                if seen { 1.0 } else { 0.0 },
                0,
            ),
            sim.camera_scan(
                if seen {
                    std::slice::from_ref(&source)
                } else {
                    &[]
                },
                1.0,
            ),
        ];
        last = tracker.step(&StepInput {
            k,
            t: k as f64 * DT,
            scans,
        });
    }
    assert!(last.is_empty(), "without the face mode: {last:?}");
}

/// A speaker who is gone for good (no face in view, no voice) is ended within a few seconds.
#[test]
fn a_track_nobody_sees_or_hears_any_more_ends() {
    let (existence, _) = silent_and_unseen(true, 80, 13);
    let gone = existence[16..96].iter().position(|&r| r == 0.0);
    println!("ended after {gone:?} silent steps without the face");
    let gone = gone.expect("the track was ended");
    assert!(gone as f64 * DT <= 6.0, "{gone} steps");
}

#[test]
fn a_camera_detection_and_an_audio_direction_give_a_birth_at_their_intersection() {
    let source = Vec3::new(1.5, 3.5, 1.0);
    let mut tracker = room_tracker(&TrackerConfig::default(), 9);
    let cam = camera();
    let px = cam.project(&source).unwrap();
    let dir_a = Vec3::new(0.1, 2.5, 1.0);
    let scans = || {
        vec![
            Scan {
                sensor: CAM,
                measurements: vec![Measurement::Pixel(px)],
                activity: None,
                sounding: Vec::new(),
            },
            Scan {
                sensor: DIR_A,
                measurements: vec![Measurement::Direction {
                    azimuth: azimuth_of(&(source - dir_a)),
                    elevation: None,
                }],
                activity: Some(1.0),
                sounding: Vec::new(),
            },
        ]
    };
    let first = tracker.step(&StepInput {
        k: 0,
        t: 0.0,
        scans: scans(),
    });
    assert!(first.is_empty(), "births are offered from the next step");
    let out = tracker.step(&StepInput {
        k: 1,
        t: DT,
        scans: scans(),
    });
    assert_eq!(out.len(), 1, "{out:?}");
    let err = (out[0].position - source).norm();
    println!("birth at the ray intersection: error {err:.3} m");
    assert!(err < 0.15, "{:?} vs {source:?}", out[0].position);
}

#[test]
fn bad_input_is_dropped_and_counted_and_never_yields_nan() {
    for kind in [TrackerKind::Glmb, TrackerKind::Gmphd] {
        let cfg = TrackerConfig {
            tracker: kind,
            ..TrackerConfig::default()
        };
        let mut tracker = room_tracker(&cfg, 11);
        let mut sim = RoomSim::new(12);
        let source = Vec3::new(3.0, 2.0, 1.5);
        let behind = Vec3::new(3.0, -1.0, 1.5);
        for k in 0..40u64 {
            let mut scans = vec![
                sim.camera_scan(&[source], 0.9),
                sim.position_scan(&[source, behind], 1.0, 5),
            ];
            scans[0]
                .measurements
                .push(Measurement::Pixel(Pixel::new(f64::NAN, 3.0)));
            scans[1]
                .measurements
                .push(Measurement::Position(Vec3::new(1.0, f64::INFINITY, 0.0)));
            // Wrong kinds, unknown sensors, a direction from the array centre itself, huge values.
            scans[1]
                .measurements
                .push(Measurement::Pixel(Pixel::new(1.0, 1.0)));
            scans.push(Scan {
                sensor: 99,
                measurements: vec![],
                activity: None,
                sounding: Vec::new(),
            });
            scans.push(Scan {
                sensor: DIR_A,
                measurements: vec![
                    Measurement::Direction {
                        azimuth: 1e300,
                        elevation: None,
                    },
                    Measurement::Direction {
                        azimuth: f64::NAN,
                        elevation: None,
                    },
                ],
                activity: Some(f64::NAN),
                sounding: Vec::new(),
            });
            if k % 7 == 3 {
                scans[1]
                    .measurements
                    .push(Measurement::Position(Vec3::new(1e200, -1e200, 1e200)));
            }
            // Time repeats and jumps backwards now and then.
            let t = if k % 10 == 5 { 0.0 } else { k as f64 * DT };
            let out = tracker.step(&StepInput { k, t, scans });
            for e in &out {
                let finite = e
                    .position
                    .iter()
                    .chain(e.velocity.iter())
                    .all(|v| v.is_finite())
                    && e.covariance.iter().all(|v| v.is_finite())
                    && e.existence.is_finite()
                    && e.speaking.is_finite();
                assert!(finite, "{kind:?} step {k}: {e:?}");
            }
        }
        let s = tracker.stats();
        println!("{kind:?}: {s:?}");
        assert_eq!(s.non_finite_measurements, 40 * 3);
        assert_eq!(s.mismatched_measurements, 40);
        assert_eq!(s.unknown_sensor_scans, 40);
        assert!(s.non_monotonic_steps >= 4);
    }
}

#[test]
fn gmphd_tracks_and_keeps_labels_of_two_static_speakers() {
    let cfg = TrackerConfig {
        tracker: TrackerKind::Gmphd,
        ..TrackerConfig::default()
    };
    let mut tracker = room_tracker(&cfg, 13);
    let mut sim = RoomSim::new(14);
    let sources = [Vec3::new(2.0, 3.0, 1.6), Vec3::new(4.0, 2.0, 1.5)];
    let mut labels: [Option<Label>; 2] = [None, None];
    let mut found = [0usize; 2];
    let steps = 40u64;
    for k in 0..steps {
        let scans = vec![
            sim.camera_scan(&sources, 0.9),
            sim.position_scan(&sources, 1.0, 5),
        ];
        let out = tracker.step(&StepInput {
            k,
            t: k as f64 * DT,
            scans,
        });
        if k < 10 {
            continue;
        }
        for i in 0..2 {
            // A PHD estimate needs weight > 0.5: a step where every sensor misses a target hides
            // it (spec 002 6.4); the label must come back unchanged (coasting).
            let Some(e) =
                nearest(&out, &sources[i]).filter(|e| (e.position - sources[i]).norm() < 0.3)
            else {
                continue;
            };
            found[i] += 1;
            match labels[i] {
                None => labels[i] = Some(e.label),
                Some(l) => assert_eq!(e.label, l, "step {k}: target {i}"),
            }
        }
    }
    println!(
        "GM-PHD: targets estimated in {found:?} of {} steps",
        steps - 10
    );
    // The PHD shares a camera detection between every component on its ray (a depth-ambiguous
    // camera-only birth keeps some weight), so a target is not estimated in every step; label
    // continuity is what this test is about.
    assert!(found.iter().all(|&n| n >= 15), "{found:?}");
    assert_ne!(labels[0], labels[1]);
}

/// The `uca8` situation: one compact circular array, azimuths only, two speakers who take turns
/// with pauses of up to 2 s (the array's voice activity is on while either speaks).
#[test]
fn azimuth_only_tracks_two_speakers_through_their_pauses() {
    let centre = Vec3::new(3.0, 2.5, 0.8);
    let mics: Vec<Vec3> = (0..8)
        .map(|i| {
            let a = 2.0 * PI * i as f64 / 8.0;
            centre + Vec3::new(0.05 * a.cos(), 0.05 * a.sin(), 0.0)
        })
        .collect();
    let array = MicArray::new("uca8", mics, (0..8).collect()).unwrap();
    let layout = Layout::new(16000, 343.0, vec![array], vec![], Some(room())).unwrap();
    let cfg = TrackerConfig::default();
    let keyed = sensors_from_layout(&layout, &cfg);
    let dir = keyed
        .iter()
        .position(|(k, _)| *k == SensorKey::ArrayDirections(0))
        .unwrap();
    let sensors = keyed.into_iter().map(|(_, m)| m).collect();
    let mut tracker = build_tracker(&cfg, sensors, layout.region, 21).unwrap();
    let sources = [Vec3::new(1.2, 4.2, 1.6), Vec3::new(5.0, 1.0, 1.5)];
    // Talk spurts (s); the gaps are the pauses, at most 2 s.
    let talks: [&[(f64, f64)]; 2] = [
        &[(0.0, 3.0), (5.0, 8.0), (10.0, 12.0)],
        &[(1.0, 4.5), (6.5, 9.0), (11.0, 12.0)],
    ];
    let mut rng = ChaCha8Rng::seed_from_u64(22);
    let noise = Normal::new(0.0, 2f64.to_radians()).unwrap();
    let clutter = Poisson::new(0.5).unwrap();
    let mut labels: [Option<Label>; 2] = [None, None];
    let mut errors = [Vec::new(), Vec::new()];
    for k in 0..94u64 {
        let t = k as f64 * DT;
        let talking: Vec<bool> = talks
            .iter()
            .map(|spans| spans.iter().any(|&(a, b)| t >= a && t < b))
            .collect();
        let mut z = Vec::new();
        for (i, s) in sources.iter().enumerate() {
            if talking[i] && rng.random::<f64>() < 0.8 {
                z.push(Measurement::Direction {
                    azimuth: azimuth_of(&(s - centre)) + noise.sample(&mut rng),
                    elevation: None,
                });
            }
        }
        let n: f64 = clutter.sample(&mut rng);
        for _ in 0..n as usize {
            z.push(Measurement::Direction {
                azimuth: rng.random_range(-PI..PI),
                elevation: None,
            });
        }
        let activity = if talking.iter().any(|&b| b) {
            0.9
        } else {
            0.05
        };
        let out = tracker.step(&StepInput {
            k,
            t,
            scans: vec![Scan {
                sensor: dir,
                measurements: z,
                activity: Some(activity),
                sounding: Vec::new(),
            }],
        });
        for (i, s) in sources.iter().enumerate() {
            // Scored from 1 s after the speaker first spoke.
            if t < talks[i][0].0 + 1.0 {
                continue;
            }
            let truth = azimuth_of(&(s - centre));
            let e = out
                .iter()
                .min_by(|a, b| {
                    let da = angle_diff(azimuth_of(&(a.position - centre)), truth).abs();
                    let db = angle_diff(azimuth_of(&(b.position - centre)), truth).abs();
                    da.total_cmp(&db)
                })
                .unwrap_or_else(|| panic!("t = {t:.2}: no track for speaker {i}"));
            let err = angle_diff(azimuth_of(&(e.position - centre)), truth).abs();
            errors[i].push(err.to_degrees());
            match labels[i] {
                None => labels[i] = Some(e.label),
                Some(l) => assert_eq!(e.label, l, "t = {t:.2}: speaker {i} changed label"),
            }
        }
    }
    assert_ne!(labels[0], labels[1]);
    for (i, e) in errors.iter().enumerate() {
        let mean = e.iter().sum::<f64>() / e.len() as f64;
        let max = e.iter().cloned().fold(0.0, f64::max);
        println!("speaker {i}: mean azimuth error {mean:.2} deg, max {max:.2} deg");
        assert!(mean <= 3.0, "speaker {i}: mean azimuth error {mean} deg");
    }
}

/// A linear array (cone angles) on a side wall and the camera: positions from the
/// intersection of cones and rays, two speakers who pause, labels kept.
#[test]
fn cone_angles_and_camera_rays_localise_two_speakers() {
    let axis_origin = Vec3::new(0.1, 2.5, 1.2);
    let sensors = vec![
        camera_sensor(),
        SensorModel::AudioDirection {
            origin: axis_origin,
            noise_std_rad: 3f64.to_radians(),
            uses_elevation: false,
            cone_axis: Some(Vec3::y()),
            p_detect: 0.6,
            min_p_detect: 0.02,
            clutter_rate: 2.0,
            filter: FilterKind::Ekf,
        },
    ];
    let mut tracker = build_tracker(&TrackerConfig::default(), sensors, Some(room()), 31).unwrap();
    let sources = [Vec3::new(2.0, 3.2, 1.6), Vec3::new(4.2, 2.0, 1.5)];
    let mut sim = RoomSim::new(32);
    let noise = Normal::new(0.0, 2f64.to_radians()).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(33);
    let mut labels: [Option<Label>; 2] = [None, None];
    let mut err = Vec::new();
    for k in 0..80u64 {
        let t = k as f64 * DT;
        // Speaker 0 pauses from 4 to 6 s, speaker 1 from 6.5 to 8.5 s.
        let talking = [!(4.0..6.0).contains(&t), !(6.5..8.5).contains(&t)];
        let mut cones = Vec::new();
        for (i, s) in sources.iter().enumerate() {
            if talking[i] && rng.random::<f64>() < 0.7 {
                // A cone-angle reading delivered as a direction in the plane z = const.
                let d = (s - axis_origin).normalize();
                let theta = d.y.clamp(-1.0, 1.0).acos() + noise.sample(&mut rng);
                cones.push(Measurement::Direction {
                    azimuth: PI / 2.0 - theta,
                    elevation: None,
                });
            }
        }
        let out = tracker.step(&StepInput {
            k,
            t,
            scans: vec![
                sim.camera_scan(&sources, 0.9),
                Scan {
                    sensor: 1,
                    measurements: cones,
                    activity: Some(1.0),
                    sounding: Vec::new(),
                },
            ],
        });
        if t < 1.0 {
            continue;
        }
        assert_eq!(out.len(), 2, "t = {t:.2}: {out:?}");
        for (i, s) in sources.iter().enumerate() {
            let e = nearest(&out, s).unwrap();
            err.push((e.position - s).norm());
            match labels[i] {
                None => labels[i] = Some(e.label),
                Some(l) => assert_eq!(e.label, l, "t = {t:.2}: speaker {i} changed label"),
            }
        }
    }
    let mean = err.iter().sum::<f64>() / err.len() as f64;
    println!("camera + cone: mean position error {mean:.3} m");
    assert!(mean < 0.15, "mean error {mean}");
}

/// Occlusion-aware camera detection: a speaker standing behind another one (same camera ray) is
/// not seen by the camera; with occlusion modelled, that costs it little existence. The face
/// mode (on by default) explains the missing face as well, so the comparison runs without it.
#[test]
fn occlusion_model_protects_a_hidden_track() {
    let front = Vec3::new(3.0, 1.8, 1.6);
    let behind = Vec3::new(3.0, 3.6, 1.58);
    let run = |occlusion: bool, face: bool| -> f64 {
        let mut cfg = TrackerConfig::default();
        cfg.camera.occlusion = occlusion;
        cfg.face.enabled = face;
        cfg.camera.occluder_half_size_m = [0.25, 0.25, 0.3];
        let mut tracker = room_tracker(&cfg, 41);
        let mut sim = RoomSim::new(42);
        let mut existence = 0.0;
        for k in 0..30u64 {
            // Both speak for 2 s, then only the audio stops; the camera sees the front one only
            // (plus, at first, the hidden one, as if it had just stepped out).
            let visible: Vec<Vec3> = if k < 10 {
                vec![front, behind]
            } else {
                vec![front]
            };
            let speaking: Vec<Vec3> = if k < 16 { vec![front, behind] } else { vec![] };
            let activity = if k < 16 { 1.0 } else { 0.0 };
            let scans = vec![
                sim.camera_scan(&visible, 1.0),
                sim.position_scan(&speaking, activity, 2),
            ];
            let out = tracker.step(&StepInput {
                k,
                t: k as f64 * DT,
                scans,
            });
            existence = out
                .iter()
                .find(|e| (e.position - behind).norm() < 0.5)
                .map_or(0.0, |e| e.existence);
        }
        existence
    };
    let with = run(true, false);
    let without = run(false, false);
    let face = run(false, true);
    println!(
        "hidden speaker's existence: occlusion modelled {with:.3}, not modelled {without:.3}, \
         face mode only {face:.3}"
    );
    assert!(with > 0.8, "{with}");
    assert!(without < 0.5, "{without}");
    assert!(face > 0.5, "{face}");
}

#[test]
fn recalibration_keeps_tracks_and_reset_forgets_them() {
    let source = Vec3::new(2.5, 3.0, 1.6);
    let mut tracker = room_tracker(&TrackerConfig::default(), 51);
    let mut sim = RoomSim::new(52);
    let mut label = None;
    for k in 0..20u64 {
        let scans = vec![
            sim.camera_scan(&[source], 0.9),
            sim.position_scan(&[source], 1.0, 3),
        ];
        let out = tracker.step(&StepInput {
            k,
            t: k as f64 * DT,
            scans,
        });
        label = out.first().map(|e| e.label);
    }
    assert!(label.is_some());
    tracker.set_sensors(room_sensors()).unwrap();
    let scans = vec![
        sim.camera_scan(&[source], 1.0),
        sim.position_scan(&[source], 1.0, 0),
    ];
    let out = tracker.step(&StepInput {
        k: 20,
        t: 20.0 * DT,
        scans,
    });
    assert_eq!(out.first().map(|e| e.label), label);
    let bad = vec![SensorModel::AudioPosition {
        noise_std_m: -1.0,
        p_detect: 0.6,
        min_p_detect: 0.0,
        clutter_rate: 1.0,
        clutter_volume_m3: 1.0,
    }];
    let e = tracker.set_sensors(bad).unwrap_err();
    assert_eq!(e.field, "sensors[0].noise_std_m");
    tracker.reset();
    let out = tracker.step(&StepInput {
        k: 0,
        t: 0.0,
        scans: vec![],
    });
    assert!(out.is_empty());
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

/// The seed paper's room (spec 003 4.3): its camera (Table II) and a 6-microphone linear array
/// along x next to it, as in the simulator's `paper-linear6`.
fn paper_layout() -> Layout {
    let p = nalgebra::Matrix3x4::new(
        -1021.7, -827.2, -575.8, 7071.5, 31.8, 142.0, -1184.0, 2012.8, 0.04, -0.83, -0.56, 3.81,
    );
    let cam = Camera::from_projection("cam0", 1920.0, 1080.0, p, None, None).unwrap();
    let mics = (0..6)
        .map(|i| Vec3::new(2.9 + 0.04 * i as f64, 3.25, 1.95))
        .collect();
    let array = MicArray::new("a0", mics, (0..6).collect()).unwrap();
    let region = Aabb::new(Vec3::new(0.2, 0.2, 0.9), Vec3::new(7.47, 3.21, 2.0)).unwrap();
    Layout::new(16000, 343.0, vec![array], vec![cam], Some(region)).unwrap()
}

/// The box a face detector draws around an upright 0.16 m x 0.22 m face at `mouth` turned to
/// the camera (the image hull of its corners, centred 6 cm above the mouth), with the point at
/// the mouth; `jitter` scales the box.
fn face_box(cam: &Camera, mouth: &Vec3, jitter: f64, noise: Pixel) -> Measurement {
    let centre = mouth + Vec3::new(0.0, 0.0, 0.06);
    let los = cam.centre() - centre;
    let right = Vec3::new(-los.y, los.x, 0.0).normalize();
    let (mut lo, mut hi) = (
        Pixel::new(f64::MAX, f64::MAX),
        Pixel::new(f64::MIN, f64::MIN),
    );
    for (sx, sy) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
        let p = cam
            .project(&(centre + right * (sx * 0.08) + Vec3::z() * (sy * 0.11)))
            .unwrap();
        lo = lo.inf(&p);
        hi = hi.sup(&p);
    }
    let size = ((hi.x - lo.x) * (hi.y - lo.y)).sqrt() * jitter;
    Measurement::Face {
        point: cam.project(mouth).unwrap() + noise,
        size_px: size,
    }
}

/// Mean 3-D error over the last 2 s of two talkers seen by the paper's camera and heard by the
/// linear array next to it (cone angles), and the largest error along the way after 1 s.
fn paper_room_run(cfg: &TrackerConfig) -> (f64, f64) {
    let layout = paper_layout();
    let (keys, models): (Vec<_>, Vec<_>) = sensors_from_layout(&layout, cfg).into_iter().unzip();
    let cam_idx = keys
        .iter()
        .position(|k| *k == SensorKey::Camera(0))
        .unwrap();
    let cone_idx = keys
        .iter()
        .position(|k| *k == SensorKey::ArrayDirections(0))
        .unwrap();
    let mut tracker = build_tracker(cfg, models, layout.region, 41).unwrap();
    let cam = &layout.cameras[0];
    let centroid = layout.arrays[0].centroid();
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let n = Normal::new(0.0, 1.0).unwrap();
    let (mut late, mut worst) = (Vec::new(), 0.0f64);
    for k in 0..40u64 {
        let t = k as f64 * DT;
        // One talker walks towards the sensors, one stands off-centre; both talk.
        let sources = [
            Vec3::new(3.1, 0.5 + 0.3 * t, 1.68),
            Vec3::new(1.95, 0.8, 1.65),
        ];
        let mut faces = Vec::new();
        let mut cones = Vec::new();
        for s in &sources {
            if rng.random::<f64>() < 0.9 {
                let noise = Pixel::new(4.0 * n.sample(&mut rng), 4.0 * n.sample(&mut rng));
                faces.push(face_box(cam, s, 1.0 + 0.05 * n.sample(&mut rng), noise));
            }
            if rng.random::<f64>() < 0.6 {
                let d = s - centroid;
                let e = 2f64.to_radians();
                cones.push(Measurement::Direction {
                    azimuth: azimuth_of(&d) + e * n.sample(&mut rng),
                    elevation: Some(d.z.atan2(d.x.hypot(d.y)) + e * n.sample(&mut rng)),
                });
            }
        }
        let out = tracker.step(&StepInput {
            k,
            t,
            scans: vec![
                Scan {
                    sensor: cam_idx,
                    measurements: faces,
                    activity: None,
                    sounding: Vec::new(),
                },
                Scan {
                    sensor: cone_idx,
                    measurements: cones,
                    activity: Some(1.0),
                    sounding: Vec::new(),
                },
            ],
        });
        if t < 1.0 {
            continue;
        }
        for s in &sources {
            let e = nearest(&out, s).map_or(f64::INFINITY, |e| (e.position - s).norm());
            worst = worst.max(e);
            if t >= 3.0 {
                late.push(e);
            }
        }
    }
    (late.iter().sum::<f64>() / late.len() as f64, worst)
}

/// A single camera next to a linear array: the image point gives a ray, the array a cone about
/// nearly the same origin, so neither fixes the depth; the face box's size does. With the
/// default model both talkers are within 0.3 m from 1 s on; with points only, the depth along
/// the ray is left to the birth prior and the motion noise.
#[test]
fn face_box_sizes_give_depth_to_a_camera_next_to_a_linear_array() {
    let cfg = TrackerConfig::default();
    let (mean, worst) = paper_room_run(&cfg);
    println!("box sizes: mean error over the last 2 s {mean:.3} m, worst after 1 s {worst:.3} m");
    assert!(mean < 0.12, "mean error {mean}");
    assert!(worst < 0.3, "worst error {worst}");
    let mut points_only = TrackerConfig::default();
    points_only.camera.use_box_size = false;
    let (mean, worst) = paper_room_run(&points_only);
    println!("points only: mean error over the last 2 s {mean:.3} m, worst after 1 s {worst:.3} m");
    assert!(
        worst > 0.3,
        "depth should be unobserved without box sizes: {worst}"
    );
}
