//! The seed paper's room: its camera and a linear array next to it, where face box sizes
//! supply the depth neither sensor observes.

use avsep::geometry::{Aabb, Camera, Layout, MicArray, Pixel, Vec3, azimuth_of};
use avsep::track::{
    Measurement, Scan, SensorKey, StepInput, TrackerConfig, build_tracker, sensors_from_layout,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::room::{DT, nearest};

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
