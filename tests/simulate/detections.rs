//! Camera detections: visibility, facing, point accuracy, miss and clutter rates.

use avsep::geometry::{Camera, angle_diff};
use avsep::scene::Scene;
use avsep::scene::sim::{
    self, CameraConfig, DetectorConfig, FacingConfig, SimConfig, SpeakerConfig, SpeechConfig,
};

/// A talker standing at `xy` facing `look_at`, turned away during `away`, silent.
fn still_talker(
    xy: [f64; 2],
    look_at: [f64; 2],
    away: Vec<[f64; 2]>,
    phrases: Vec<[f64; 2]>,
) -> SpeakerConfig {
    SpeakerConfig {
        path: vec![[0.0, xy[0], xy[1]]],
        mouth_height_m: 1.6,
        sway_m: 0.0,
        facing: FacingConfig {
            look_at: Some(look_at),
            follow_motion: false,
            away_s: away,
            jitter_deg: 0.0,
        },
        speech: SpeechConfig {
            phrases,
            ..Default::default()
        },
        ..Default::default()
    }
}

#[test]
fn detections_follow_visibility_and_facing() {
    let camera = CameraConfig::default();
    let cam_xy = [camera.position.unwrap()[0], camera.position.unwrap()[1]];
    let mut cfg = SimConfig {
        duration_s: 3.0,
        cameras: vec![camera],
        detector: DetectorConfig {
            detection_probability: 1.0,
            clutter_per_frame: 0.0,
            point_sigma_px: 6.0,
            ..Default::default()
        },
        speakers: vec![
            // In view and facing the camera until it turns away at 1.5 s.
            still_talker([3.4, 3.5], cam_xy, vec![[1.5, 10.0]], vec![[0.2, 1.2]]),
            // Facing the camera but outside the field of view (far left, near the camera wall).
            still_talker([0.4, 0.5], cam_xy, vec![], vec![[0.5, 1.5]]),
        ],
        ..Default::default()
    };
    let scene = sim::simulate(&cfg, 7).unwrap();
    let cam = &scene.layout.cameras[0];
    let sigma = 6.0 * cam.height / 1080.0;
    assert_only_the_visible_facing_talker_is_detected(&scene, sigma);

    // Missed detections and clutter at the configured rates.
    cfg.duration_s = 6.0;
    cfg.detector.detection_probability = 0.7;
    cfg.detector.clutter_per_frame = 2.0;
    cfg.speakers[0].facing.away_s.clear();
    assert_miss_and_clutter_rates(&sim::simulate(&cfg, 8).unwrap(), cam, sigma);
}

/// In `scene`, the first talker is detected (near its mouth, within `sigma` px noise) until it
/// turns away, and the second, out of view, never is.
fn assert_only_the_visible_facing_talker_is_detected(scene: &Scene, sigma: f64) {
    let cam = &scene.layout.cameras[0];
    let truth = &scene.truth.as_ref().unwrap().sources;
    assert_eq!(
        scene.detections.len(),
        45,
        "one frame per 1/15 s, also when empty"
    );
    let hidden = truth[1].position_at(0.5).unwrap();
    assert!(
        !cam.in_view(&hidden),
        "the second talker must be out of view"
    );
    let mut seen = 0;
    for f in &scene.detections {
        if f.t < 1.5 {
            // Exactly the first talker, with its point near the projected mouth.
            assert_eq!(f.boxes.len(), 1, "frame at {}", f.t);
            let mouth = cam.project(&truth[0].position_at(f.t).unwrap()).unwrap();
            let b = f.boxes[0];
            let p = b.point.unwrap();
            assert!(
                (p - mouth).norm() < 4.0 * sigma,
                "point {p:?} vs mouth {mouth:?}"
            );
            assert!(p.x >= b.x && p.x <= b.x + b.w && p.y >= b.y && p.y <= b.y + b.h);
            assert!(b.h > b.w, "a face box is taller than wide");
            assert!((0.5..=1.0).contains(&b.score.unwrap()));
            seen += 1;
        } else if f.t > 2.2 {
            // Turned away (the turn takes about half a second): nobody is detected.
            assert!(f.boxes.is_empty(), "frame at {}: {:?}", f.t, f.boxes);
        }
    }
    assert!(seen >= 22);
}

/// In `scene` (detection probability 0.7, 2 clutter boxes per frame), boxes near the first
/// talker's mouth in `cam` come at the detection rate and the others at the clutter rate.
fn assert_miss_and_clutter_rates(scene: &Scene, cam: &Camera, sigma: f64) {
    let truth = &scene.truth.as_ref().unwrap().sources;
    let frames = scene.detections.len() as f64;
    let (mut true_hits, mut clutter) = (0.0, 0.0);
    for f in &scene.detections {
        let mouth = cam.project(&truth[0].position_at(f.t).unwrap()).unwrap();
        for b in &f.boxes {
            let p = b.point.unwrap();
            assert!(cam.contains_pixel(&p));
            if (p - mouth).norm() < 5.0 * sigma && b.score.unwrap() > 0.78 {
                true_hits += 1.0;
            } else {
                clutter += 1.0;
            }
        }
    }
    let (pd, rate) = (true_hits / frames, clutter / frames);
    assert!((pd - 0.7).abs() < 0.15, "detection rate {pd}");
    assert!((rate - 2.0).abs() < 0.4, "clutter rate {rate}");
}

#[test]
fn the_facing_direction_decides_detection() {
    // Facing at most max_yaw from the camera is detectable; beyond it is not.
    let cfg = SimConfig {
        duration_s: 1.0,
        detector: DetectorConfig {
            detection_probability: 1.0,
            clutter_per_frame: 0.0,
            ..Default::default()
        },
        speakers: vec![still_talker(
            [3.0, 3.5],
            [0.0, 3.5],
            vec![],
            vec![[0.2, 0.8]],
        )],
        ..Default::default()
    };
    let scene = sim::simulate(&cfg, 1).unwrap();
    let cam = &scene.layout.cameras[0];
    let mouth = scene.truth.as_ref().unwrap().sources[0]
        .position_at(0.5)
        .unwrap();
    let to_cam = cam.centre() - mouth;
    // Looking along -x while the camera is towards -y: about 90 degrees off, beyond 75.
    let yaw = angle_diff(to_cam.y.atan2(to_cam.x), std::f64::consts::PI).abs();
    assert!(yaw.to_degrees() > 80.0);
    assert!(scene.detections.iter().all(|f| f.boxes.is_empty()));
}
