//! A simulated face detector: what each camera reports in each frame.
//!
//! A talker is detectable when the mouth is in front of the camera and projects inside the image,
//! and the face is turned at most `max_yaw_deg` from the camera (in the horizontal plane). A
//! detectable face is detected with probability `detection_probability`; its box is the projected
//! face rectangle (a billboard facing the camera) and its point is the projected mouth, both moved
//! by the same Gaussian pixel error. Each frame also gets Poisson clutter: face-sized boxes at
//! points uniform over the image. Occlusion between people is not modelled.

use rand::Rng;
use rand_distr::{Distribution, Normal, Poisson, StandardNormal};

use crate::geometry::{Camera, Pixel, Vec3, angle_diff};

use super::config::DetectorConfig;
use super::motion::Motion;
use crate::scene::{DetectionFrame, FaceBox};

/// Frame timing of one camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameClock {
    /// Frames per second.
    pub fps: f64,
    /// Time of the first frame (s).
    pub start_s: f64,
}

/// Whether the talker's face can be detected by `camera` at `t`.
pub fn detectable(cfg: &DetectorConfig, camera: &Camera, talker: &Motion, t: f64) -> bool {
    if !talker.present(t) {
        return false;
    }
    let mouth = talker.position(t);
    if !camera.in_view(&mouth) {
        return false;
    }
    let to_cam = camera.centre() - mouth;
    let yaw = angle_diff(to_cam.y.atan2(to_cam.x), talker.facing(t)).abs();
    yaw <= cfg.max_yaw_deg.to_radians()
}

/// Detection frames of every camera, in time order (ties by camera index).
pub fn detect<R: Rng + ?Sized>(
    cfg: &DetectorConfig,
    cameras: &[Camera],
    clocks: &[FrameClock],
    talkers: &[Motion],
    duration_s: f64,
    rng: &mut R,
) -> Vec<DetectionFrame> {
    let mut frames = Vec::new();
    for (c, (camera, clock)) in cameras.iter().zip(clocks).enumerate() {
        let sigma = cfg.point_sigma_px * camera.height / 1080.0;
        let focal = focal_px(camera);
        let mut j = 0usize;
        loop {
            let t = clock.start_s + j as f64 / clock.fps;
            if t >= duration_s {
                break;
            }
            j += 1;
            let mut boxes = Vec::new();
            for talker in talkers {
                if !detectable(cfg, camera, talker, t)
                    || rng.random_range(0.0..1.0) >= cfg.detection_probability
                {
                    continue;
                }
                if let Some(b) = face_box(cfg, camera, talker, t, sigma, rng) {
                    boxes.push(b);
                }
            }
            let clutter = if cfg.clutter_per_frame > 0.0 {
                Poisson::new(cfg.clutter_per_frame).map_or(0.0, |p| p.sample(rng)) as usize
            } else {
                0
            };
            for _ in 0..clutter {
                boxes.push(clutter_box(cfg, camera, focal, rng));
            }
            frames.push(DetectionFrame {
                t,
                camera: c,
                boxes,
            });
        }
    }
    frames.sort_by(|a, b| a.t.total_cmp(&b.t).then(a.camera.cmp(&b.camera)));
    frames
}

/// The detected box of a detectable talker.
fn face_box<R: Rng + ?Sized>(
    cfg: &DetectorConfig,
    camera: &Camera,
    talker: &Motion,
    t: f64,
    sigma: f64,
    rng: &mut R,
) -> Option<FaceBox> {
    let mouth = talker.position(t);
    let centre = mouth + Vec3::new(0.0, 0.0, cfg.face_above_mouth_m);
    let los = camera.centre() - centre;
    let right = Vec3::new(-los.y, los.x, 0.0).try_normalize(1e-9)?;
    let up = Vec3::z();
    let (hw, hh) = (0.5 * cfg.face_width_m, 0.5 * cfg.face_height_m);
    let mut lo = Pixel::new(f64::INFINITY, f64::INFINITY);
    let mut hi = Pixel::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
    for (sx, sy) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
        let p = camera.project(&(centre + right * (sx * hw) + up * (sy * hh)))?;
        lo = lo.inf(&p);
        hi = hi.sup(&p);
    }
    let mouth_px = camera.project(&mouth)?;
    let noise = Pixel::new(
        sigma * rng.sample::<f64, _>(StandardNormal),
        sigma * rng.sample::<f64, _>(StandardNormal),
    );
    let point = clamp_to_image(camera, mouth_px + noise);
    let size_jitter = 1.0 + 0.05 * rng.sample::<f64, _>(StandardNormal);
    let mid = (lo + hi) * 0.5 + noise;
    let half = (hi - lo) * 0.5 * size_jitter.max(0.5);
    let yaw = {
        let to_cam = camera.centre() - mouth;
        angle_diff(to_cam.y.atan2(to_cam.x), talker.facing(t)).abs()
    };
    let frontal = 1.0 - (yaw / cfg.max_yaw_deg.to_radians().max(1e-6)).powi(2);
    let score = Normal::new(0.8 + 0.15 * frontal, 0.04)
        .map_or(0.9, |n| n.sample(rng))
        .clamp(0.5, 1.0);
    clipped_box(camera, mid - half, mid + half, point, score)
}

/// A false detection: a face-sized box around a point uniform over the image.
fn clutter_box<R: Rng + ?Sized>(
    cfg: &DetectorConfig,
    camera: &Camera,
    focal: f64,
    rng: &mut R,
) -> FaceBox {
    let point = Pixel::new(
        rng.random_range(0.0..camera.width),
        rng.random_range(0.0..camera.height),
    );
    let depth = rng.random_range(1.0..6.0);
    let w = (focal * cfg.face_width_m / depth).max(4.0);
    let h = w * cfg.face_height_m / cfg.face_width_m;
    // The mouth sits below the face centre by face_above_mouth of the face height.
    let below = h * cfg.face_above_mouth_m / cfg.face_height_m;
    let lo = Pixel::new(point.x - 0.5 * w, point.y - below - 0.5 * h);
    let hi = Pixel::new(point.x + 0.5 * w, point.y - below + 0.5 * h);
    let score = rng.random_range(0.5..0.8);
    clipped_box(camera, lo, hi, point, score).unwrap_or(FaceBox {
        x: point.x.floor().clamp(0.0, camera.width - 1.0),
        y: point.y.floor().clamp(0.0, camera.height - 1.0),
        w: 1.0,
        h: 1.0,
        score: Some(score),
        point: Some(point),
    })
}

/// The box [lo, hi] clipped to the image, or `None` when nothing of it is inside.
fn clipped_box(camera: &Camera, lo: Pixel, hi: Pixel, point: Pixel, score: f64) -> Option<FaceBox> {
    let x0 = lo.x.clamp(0.0, camera.width);
    let y0 = lo.y.clamp(0.0, camera.height);
    let x1 = hi.x.clamp(0.0, camera.width);
    let y1 = hi.y.clamp(0.0, camera.height);
    (x1 - x0 > 0.5 && y1 - y0 > 0.5).then_some(FaceBox {
        x: x0,
        y: y0,
        w: x1 - x0,
        h: y1 - y0,
        score: Some(score),
        point: Some(point),
    })
}

fn clamp_to_image(camera: &Camera, p: Pixel) -> Pixel {
    Pixel::new(p.x.clamp(0.0, camera.width), p.y.clamp(0.0, camera.height))
}

/// Pixels per metre at 1 m depth on the optical axis (the focal length in pixels).
pub fn focal_px(camera: &Camera) -> f64 {
    let axis = camera.optical_axis();
    let x = camera.centre() + axis;
    let side = axis
        .cross(&Vec3::z())
        .try_normalize(1e-9)
        .unwrap_or_else(Vec3::x);
    match (camera.project(&x), camera.project(&(x + side * 0.01))) {
        (Some(a), Some(b)) => (b - a).norm() / 0.01,
        _ => camera.width,
    }
}
