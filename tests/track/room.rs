//! The shared room fixtures: a 6 x 5 x 2.5 m room with a camera on the y = 0 wall, audio
//! arrays on the walls, trackers over those sensors and a simulator of their measurements.

use std::f64::consts::PI;

use avsep::geometry::{Aabb, Camera, Pixel, Vec3, azimuth_of};
use avsep::track::{
    FilterKind, Measurement, Scan, SensorModel, TrackEstimate, Tracker, TrackerConfig,
    build_tracker,
};
use nalgebra::Matrix3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Tracker step (s): the localiser's hop.
pub const DT: f64 = 0.128;

/// The room's box, which is also the trackers' region.
pub fn room() -> Aabb {
    Aabb::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(6.0, 5.0, 2.5)).unwrap()
}

/// A camera at (3, 0.05, 2.0) looking along +y, pitched 15 degrees down, 1000 px focal length.
pub fn camera() -> Camera {
    let k = Matrix3::new(1000.0, 0.0, 960.0, 0.0, 1000.0, 540.0, 0.0, 0.0, 1.0);
    let (s, c) = 15f64.to_radians().sin_cos();
    // Rows: camera x, y (down), z (forward) in world coordinates.
    let r = Matrix3::new(1.0, 0.0, 0.0, 0.0, -s, -c, 0.0, c, -s);
    let centre = Vec3::new(3.0, 0.05, 2.0);
    Camera::from_krt("cam", 1920.0, 1080.0, k, r, -(r * centre), None).unwrap()
}

/// The camera as a point-detection sensor (10 px noise, P_D 0.9, one clutter a frame).
pub fn camera_sensor() -> SensorModel {
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

// Sensor indices of the room set-ups, in the order of `room_sensors`.
/// The camera.
pub const CAM: usize = 0;
const POS: usize = 1;
/// The array on the x = 0 wall.
pub const DIR_A: usize = 2;
/// The array in the far corner.
pub const DIR_B: usize = 3;

/// Camera, 3-D audio positions and two arrays' directions: the sensors of the room set-ups.
pub fn room_sensors() -> Vec<SensorModel> {
    vec![
        camera_sensor(),
        position_sensor(),
        direction_sensor(Vec3::new(0.1, 2.5, 1.0)),
        direction_sensor(Vec3::new(5.9, 4.9, 1.0)),
    ]
}

/// A tracker of `cfg`'s kind over `room_sensors` in the room.
pub fn room_tracker(cfg: &TrackerConfig, seed: u64) -> Box<dyn Tracker> {
    build_tracker(cfg, room_sensors(), Some(room()), seed).unwrap()
}

/// Synthetic measurements of the room sensors for sources at `sources` (speaking flags).
pub struct RoomSim {
    rng: ChaCha8Rng,
}

impl RoomSim {
    /// A simulator whose noise is drawn from `seed`.
    pub fn new(seed: u64) -> Self {
        Self {
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    fn normal(&mut self, sd: f64) -> f64 {
        Normal::new(0.0, sd).unwrap().sample(&mut self.rng)
    }

    /// Noisy pixels of the sources in view, each detected with `p_detect`.
    pub fn camera_scan(&mut self, sources: &[Vec3], p_detect: f64) -> Scan {
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

    /// Noisy 3-D positions of the speakers (P_D 0.6) and `clutter` uniform false ones.
    pub fn position_scan(&mut self, speaking: &[Vec3], activity: f64, clutter: usize) -> Scan {
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

    /// Noisy azimuths of the speakers from the array at `origin` (P_D 0.8), at times clutter.
    pub fn direction_scan(
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

/// The estimate closest to `p`, if any.
pub fn nearest<'a>(est: &'a [TrackEstimate], p: &Vec3) -> Option<&'a TrackEstimate> {
    est.iter()
        .min_by(|a, b| (a.position - p).norm().total_cmp(&(b.position - p).norm()))
}
