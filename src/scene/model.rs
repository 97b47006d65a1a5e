//! The validated in-memory scene: geometry, audio, detections, device measurements and truth,
//! in internal units (radians, indices instead of ids).

use std::path::PathBuf;

use crate::geometry::{Layout, Pixel, Vec3};

use super::Audio;

/// A validated scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// The folder it was read from (or will be written to).
    pub dir: PathBuf,
    /// Sensor layout and acoustic constants.
    pub layout: Layout,
    /// The multichannel recording, columns as the layout's channels say.
    pub audio: Option<Audio>,
    /// Camera frames in time order.
    pub detections: Vec<DetectionFrame>,
    /// Device-side localisation frames in time order.
    pub audio_measurements: Vec<AudioMeasurementFrame>,
    /// Ground truth, when known.
    pub truth: Option<Truth>,
}

impl Scene {
    /// Duration in seconds: of the audio, or else of the last measurement or detection.
    pub fn duration(&self) -> f64 {
        if let Some(a) = &self.audio {
            return a.duration();
        }
        let last_meas = self.audio_measurements.last().map_or(0.0, |m| m.t);
        let last_det = self.detections.last().map_or(0.0, |d| d.t);
        last_meas.max(last_det)
    }
}

/// One camera frame: the boxes a camera detected at time `t`.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectionFrame {
    /// Frame time (s).
    pub t: f64,
    /// Index of the camera in the layout.
    pub camera: usize,
    /// Detected faces (possibly none).
    pub boxes: Vec<FaceBox>,
}

/// A detected face box in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaceBox {
    /// Left edge.
    pub x: f64,
    /// Top edge.
    pub y: f64,
    /// Width.
    pub w: f64,
    /// Height.
    pub h: f64,
    /// Detector confidence.
    pub score: Option<f64>,
    /// Explicit measurement point (e.g. the mouth).
    pub point: Option<Pixel>,
}

/// What is wrong with a box of left edge `x`, top `y`, width `w` and height `h`, if anything:
/// the field to blame (`x`, `y`, `w` or `h`) and why. Shared by the scene reader and the live
/// input, so a box is judged and named the same way whichever way it comes.
pub fn box_problem(x: f64, y: f64, w: f64, h: f64) -> Option<(&'static str, &'static str)> {
    let coordinates = [("x", x), ("y", y), ("w", w), ("h", h)];
    if let Some((field, _)) = coordinates.iter().find(|(_, v)| !v.is_finite()) {
        return Some((field, "must be a finite number"));
    }
    [("w", w), ("h", h)]
        .into_iter()
        .find(|&(_, v)| v <= 0.0)
        .map(|(field, _)| (field, "must be positive"))
}

impl FaceBox {
    /// The pixel that stands for the source: `point` when given, else the box centre.
    pub fn measurement_point(&self) -> Pixel {
        self.point
            .unwrap_or_else(|| Pixel::new(self.x + 0.5 * self.w, self.y + 0.5 * self.h))
    }
}

/// One device-side localisation frame of one array.
#[derive(Debug, Clone, PartialEq)]
pub struct AudioMeasurementFrame {
    /// Frame time (s).
    pub t: f64,
    /// Index of the array in the layout.
    pub array: usize,
    /// Directions of arrival.
    pub doas: Vec<Doa>,
    /// 3-D position candidates.
    pub points: Vec<Vec3>,
    /// Voice-activity score in [0, 1], when reported.
    pub activity: Option<f64>,
}

/// A direction of arrival around an array's centroid (radians).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Doa {
    /// Azimuth (rad), from +x towards +y.
    pub azimuth: f64,
    /// Elevation (rad), when the array resolves it.
    pub elevation: Option<f64>,
    /// Relative strength.
    pub energy: Option<f64>,
}

/// Ground truth of a scene.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Truth {
    /// The true sources.
    pub sources: Vec<TruthSource>,
}

/// One true source: where it was, when it spoke, and its image at the reference microphone.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthSource {
    /// Source id.
    pub id: String,
    /// Its reverberant image at the reference microphone, as long as the scene audio.
    pub signal: Option<Vec<f32>>,
    /// Mouth positions `(t, position)`, strictly increasing in t.
    pub trajectory: Vec<(f64, Vec3)>,
    /// Speech intervals `(start, end)`.
    pub active: Vec<(f64, f64)>,
}

impl TruthSource {
    /// Whether the source is in the scene at time `t`.
    pub fn exists_at(&self, t: f64) -> bool {
        match (self.trajectory.first(), self.trajectory.last()) {
            (Some(a), Some(b)) => t >= a.0 && t <= b.0,
            _ => false,
        }
    }

    /// Position at `t` by linear interpolation, or `None` when the source is absent.
    pub fn position_at(&self, t: f64) -> Option<Vec3> {
        if !self.exists_at(t) {
            return None;
        }
        let i = self.trajectory.partition_point(|(ti, _)| *ti <= t);
        if i == 0 {
            return Some(self.trajectory[0].1);
        }
        if i >= self.trajectory.len() {
            return self.trajectory.last().map(|p| p.1);
        }
        let (t0, p0) = self.trajectory[i - 1];
        let (t1, p1) = self.trajectory[i];
        let a = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
        Some(p0 + (p1 - p0) * a)
    }

    /// Whether the source speaks at time `t`.
    pub fn is_active(&self, t: f64) -> bool {
        self.active.iter().any(|&(a, b)| t >= a && t < b)
    }

    /// Fraction of `[t0, t1)` during which the source speaks.
    pub fn active_fraction(&self, t0: f64, t1: f64) -> f64 {
        if t1 <= t0 {
            return 0.0;
        }
        let overlap: f64 = self
            .active
            .iter()
            .map(|&(a, b)| (b.min(t1) - a.max(t0)).max(0.0))
            .sum();
        overlap / (t1 - t0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bad_box_is_blamed_on_the_field_at_fault() {
        assert_eq!(box_problem(1.0, 2.0, 3.0, 4.0), None);
        let field = |x, y, w, h| box_problem(x, y, w, h).map(|p| p.0);
        assert_eq!(field(1.0, f64::NAN, 3.0, 4.0), Some("y"));
        assert_eq!(field(1.0, 2.0, 3.0, f64::INFINITY), Some("h"));
        assert_eq!(field(1.0, 2.0, 3.0, 0.0), Some("h"));
        assert_eq!(field(1.0, 2.0, -3.0, 0.0), Some("w"));
        // Finiteness first: a NaN height is not blamed on a negative width.
        assert_eq!(field(1.0, 2.0, -3.0, f64::NAN), Some("h"));
    }

    #[test]
    fn interpolates_trajectories_and_activity() {
        let s = TruthSource {
            id: "s1".into(),
            signal: None,
            trajectory: vec![
                (1.0, Vec3::new(0.0, 0.0, 1.0)),
                (2.0, Vec3::new(1.0, 2.0, 1.0)),
            ],
            active: vec![(1.0, 1.5)],
        };
        assert_eq!(s.position_at(0.5), None);
        assert_eq!(s.position_at(1.5), Some(Vec3::new(0.5, 1.0, 1.0)));
        assert_eq!(s.position_at(2.0), Some(Vec3::new(1.0, 2.0, 1.0)));
        assert!(s.is_active(1.2) && !s.is_active(1.6));
        assert!((s.active_fraction(1.0, 2.0) - 0.5).abs() < 1e-12);
    }
}
