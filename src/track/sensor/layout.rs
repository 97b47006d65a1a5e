//! The sensor list a layout gives the tracker: which sensors exist (one key per array's
//! positions and directions, one per camera) and their measurement models from the
//! configuration. `compile` turns each model into a [`Sensor`](super::Sensor) for the filters.

use nalgebra::DMatrix;

use crate::geometry::{ArrayShape, Camera, Layout, Vec3};
use crate::track::config::{FilterKind, TrackerConfig};

/// Which layout sensor a [`SensorModel`] stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SensorKey {
    /// 3-D position candidates of array i.
    ArrayPositions(usize),
    /// Directions of arrival of array i.
    ArrayDirections(usize),
    /// Point detections of camera j.
    Camera(usize),
}

impl SensorKey {
    /// The sensor's name in `layout`: the camera's id, or the array's id with what it measures.
    pub fn name(&self, layout: &Layout) -> String {
        let array = |i: usize| layout.arrays.get(i).map_or("?", |a| a.id.as_str());
        match *self {
            Self::ArrayPositions(i) => format!("{} positions", array(i)),
            Self::ArrayDirections(i) => format!("{} directions", array(i)),
            Self::Camera(j) => layout.cameras.get(j).map_or("?", |c| c.id.as_str()).into(),
        }
    }
}

/// A sensor's measurement model, built by the pipeline from the layout and the configuration.
#[derive(Debug, Clone, PartialEq)]
pub enum SensorModel {
    /// Audio 3-D position candidates: z = p + N(0, noise^2 I); clutter uniform on a volume.
    AudioPosition {
        /// Noise standard deviation per axis (m).
        noise_std_m: f64,
        /// Detection probability while the voice is active.
        p_detect: f64,
        /// Floor of the activity-scaled detection probability.
        min_p_detect: f64,
        /// Expected clutter per step.
        clutter_rate: f64,
        /// Volume (m^3) the clutter is uniform on.
        clutter_volume_m3: f64,
    },
    /// Audio direction of arrival from `origin` (the array centroid).
    AudioDirection {
        /// Array centroid (m).
        origin: Vec3,
        /// Angular noise standard deviation (rad).
        noise_std_rad: f64,
        /// Whether the elevation is measured (ignored for a cone sensor).
        uses_elevation: bool,
        /// For a linear array: its axis; the measurement is then the cone angle to the axis.
        cone_axis: Option<Vec3>,
        /// Detection probability while the voice is active.
        p_detect: f64,
        /// Floor of the activity-scaled detection probability.
        min_p_detect: f64,
        /// Expected clutter per step, uniform over the angle space.
        clutter_rate: f64,
        /// Single-object filter.
        filter: FilterKind,
    },
    /// Camera point detections (face centres).
    CameraPoint {
        /// The calibrated camera.
        camera: Box<Camera>,
        /// Pixel noise standard deviation.
        noise_std_px: f64,
        /// Detection probability of a track in view (0 out of view or behind).
        p_detect: f64,
        /// Expected clutter per frame, uniform on the image.
        clutter_rate: f64,
        /// Single-object filter.
        filter: FilterKind,
        /// Physical face (width, height) in metres when the detections' box sizes are used as a
        /// depth measurement; `None` uses the points only.
        face_size_m: Option<[f64; 2]>,
        /// Standard deviation of the log of the apparent face size (detector jitter and the
        /// spread of face sizes between people).
        face_size_log_std: f64,
    },
    /// A generic linear sensor z = H x + N(0, R) (H is m x N with m <= 3).
    GenericPoint {
        /// Observation matrix (m x state dimension).
        h: DMatrix<f64>,
        /// Noise covariance (m x m, positive definite).
        r: DMatrix<f64>,
        /// Detection probability.
        p_detect: f64,
        /// Expected clutter per step.
        clutter_rate: f64,
        /// Clutter density on the measurement space (1 / its volume).
        clutter_density: f64,
    },
}

/// The default sensor list of a layout: for every array its position candidates and its
/// directions (cone angles for linear arrays, no directions for a single microphone), then every
/// camera. Sensors that never report cost nothing.
pub fn sensors_from_layout(layout: &Layout, cfg: &TrackerConfig) -> Vec<(SensorKey, SensorModel)> {
    let mut out = Vec::new();
    let ap = &cfg.audio_position;
    let ad = &cfg.audio_direction;
    for (i, array) in layout.arrays.iter().enumerate() {
        out.push((
            SensorKey::ArrayPositions(i),
            SensorModel::AudioPosition {
                noise_std_m: ap.noise_std_m,
                p_detect: ap.p_detect,
                min_p_detect: ap.min_p_detect,
                clutter_rate: ap.clutter_rate,
                clutter_volume_m3: layout
                    .region
                    .map(|r| r.volume())
                    .unwrap_or(ap.clutter_volume_m3),
            },
        ));
        let (uses_elevation, cone_axis) = match array.shape() {
            ArrayShape::Point => continue,
            ArrayShape::Linear { axis } => (false, Some(axis)),
            ArrayShape::Planar { .. } => (ad.planar_elevation, None),
            ArrayShape::Volumetric => (true, None),
        };
        out.push((
            SensorKey::ArrayDirections(i),
            SensorModel::AudioDirection {
                origin: array.centroid(),
                noise_std_rad: ad.noise_std_deg.to_radians(),
                uses_elevation,
                cone_axis,
                p_detect: ad.p_detect,
                min_p_detect: ad.min_p_detect,
                clutter_rate: ad.clutter_rate,
                filter: ad.filter,
            },
        ));
    }
    let c = &cfg.camera;
    for (j, camera) in layout.cameras.iter().enumerate() {
        out.push((
            SensorKey::Camera(j),
            SensorModel::CameraPoint {
                camera: Box::new(camera.clone()),
                noise_std_px: c.noise_std_px * camera.height / c.reference_height_px,
                p_detect: c.p_detect,
                clutter_rate: c.clutter_rate,
                filter: c.filter,
                face_size_m: c.use_box_size.then_some(c.face_size_m),
                face_size_log_std: c.face_size_log_std,
            },
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Aabb, MicArray};

    #[test]
    fn layout_gives_positions_directions_and_cameras() {
        let lin: Vec<_> = (0..6)
            .map(|i| Vec3::new(1.0 + 0.04 * i as f64, 2.0, 1.0))
            .collect();
        let arrays = vec![MicArray::new("a0", lin, vec![]).unwrap()];
        let region = Aabb::new(Vec3::zeros(), Vec3::new(4.0, 5.0, 2.5)).unwrap();
        let layout = Layout::new(16000, 343.0, arrays, vec![], Some(region)).unwrap();
        let s = sensors_from_layout(&layout, &TrackerConfig::default());
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].0, SensorKey::ArrayPositions(0));
        match &s[1].1 {
            SensorModel::AudioDirection { cone_axis, .. } => assert!(cone_axis.is_some()),
            m => panic!("{m:?}"),
        }
        match &s[0].1 {
            SensorModel::AudioPosition {
                clutter_volume_m3, ..
            } => assert!((clutter_volume_m3 - 50.0).abs() < 1e-9),
            m => panic!("{m:?}"),
        }
    }
}
