//! Sensor (measurement) models: what each sensor measures of a state, with what noise, how often
//! it detects and how much clutter it reports.
//!
//! Every measurement is held in a 3-vector; sensors that measure fewer components pad the rest
//! with zeros, a zero Jacobian row and unit noise variance. Padded components then carry zero
//! innovation, leave the update unchanged and add nothing to the Mahalanobis distance; the
//! likelihood normalisation uses the true dimension.

use std::f64::consts::PI;

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

mod compile;
mod layout;

pub use layout::{SensorKey, SensorModel, sensors_from_layout};

use super::clutter::ClutterRate;
use super::config::FilterKind;
use super::filter::Prepared;
use super::gaussian::normal_cdf;
use super::motion::position_of;
use crate::geometry::{Aabb, Camera, Pixel, Vec3, direction_from_angles, wrap_angle};

/// A measurement as delivered to the tracker.
#[derive(Debug, Clone, PartialEq)]
pub enum Measurement {
    /// A 3-D position candidate (m, world frame).
    Position(Vec3),
    /// A direction of arrival from the sensor's origin (rad, scene convention).
    Direction {
        /// Azimuth in the x-y plane from +x towards +y.
        azimuth: f64,
        /// Elevation from the x-y plane, when the array resolves it.
        elevation: Option<f64>,
    },
    /// A camera point (px).
    Pixel(Pixel),
    /// A camera face detection: the point (px) and the apparent face size sqrt(w h) of its box
    /// (px), which falls with the distance from the camera and so measures depth.
    Face {
        /// The detected point (mouth or box centre).
        point: Pixel,
        /// Apparent size of the face box (px), the geometric mean of its width and height.
        size_px: f64,
    },
    /// A point of a generic linear sensor z = H x + noise.
    Point {
        /// The measured vector (its length is the sensor's measurement dimension, at most 3).
        z: Vec<f64>,
    },
}

/// What a compiled sensor observes of the state.
#[derive(Debug, Clone)]
pub(crate) enum Observation<const N: usize> {
    /// The 3-D position.
    Position,
    /// Azimuth (and elevation) from an origin.
    Direction { origin: Vec3, elevation: bool },
    /// Angle between `axis` and the direction from `origin`.
    Cone { origin: Vec3, axis: Vec3 },
    /// Pixel through a calibrated camera, and the log of the apparent size (px) of the box of
    /// a face of `face_size` = (width, height) metres when set.
    Camera {
        camera: Box<Camera>,
        face_size: Option<[f64; 2]>,
    },
    /// A linear map of the state (rows beyond the dimension are zero).
    Linear(SMatrix<f64, 3, N>),
}

/// Why a measurement was not used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Rejection {
    /// It holds NaN or infinite numbers.
    NonFinite,
    /// It is not the kind (or dimension) this sensor measures.
    WrongKind,
}

/// A sensor model ready for the filters.
#[derive(Debug, Clone)]
pub(crate) struct Sensor<const N: usize> {
    pub obs: Observation<N>,
    /// Number of measured components (1..=3).
    pub dim: usize,
    /// Noise covariance, padded with unit variances.
    pub r: Matrix3<f64>,
    pub p_detect: f64,
    /// Audio: floor of the activity-scaled P_D, and the P_D of a silent track.
    pub min_p_detect: f64,
    /// Detection probability while the track's mode is "off" (silent, face turned away).
    pub off_p_detect: f64,
    /// The track's detectability mode slot this sensor follows (see `modes`); None: plain P_D.
    pub mode: Option<usize>,
    /// The clutter rate (configured floor and online estimate) and its log intensity.
    pub clutter: ClutterRate,
    pub filter: FilterKind,
    /// An audio sensor: its detection follows the voice activity and feeds `speaking`.
    pub audio: bool,
    /// Squared Mahalanobis gate.
    pub gate: f64,
    /// Squared Mahalanobis radius inside which a measurement belongs to a confirmed track.
    pub birth_gate: f64,
}

impl<const N: usize> Sensor<N> {
    /// Whether the measurement is nonlinear in the state.
    pub fn nonlinear(&self) -> bool {
        !matches!(self.obs, Observation::Position | Observation::Linear(_))
    }

    /// The camera of a camera sensor.
    pub fn camera(&self) -> Option<&Camera> {
        match &self.obs {
            Observation::Camera { camera, .. } => Some(camera),
            _ => None,
        }
    }

    /// The physical face (width, height) in metres of a camera sensor that measures box sizes.
    pub fn face_size(&self) -> Option<[f64; 2]> {
        match &self.obs {
            Observation::Camera { face_size, .. } => *face_size,
            _ => None,
        }
    }

    /// Predicted measurement h(x), or None where it is undefined (behind the camera, at the
    /// array centre).
    pub fn measure(&self, x: &SVector<f64, N>) -> Option<Vector3<f64>> {
        match &self.obs {
            Observation::Position => Some(position_of(x)),
            Observation::Linear(h) => Some(h * x),
            Observation::Direction { origin, elevation } => {
                let d = position_of(x) - origin;
                if d.norm() < 1e-6 {
                    return None;
                }
                let el = if *elevation {
                    d.z.atan2(d.x.hypot(d.y))
                } else {
                    0.0
                };
                Some(Vector3::new(d.y.atan2(d.x), el, 0.0))
            }
            Observation::Cone { origin, axis } => {
                let d = position_of(x) - origin;
                let n = d.norm();
                if n < 1e-6 {
                    return None;
                }
                Some(Vector3::new(
                    (axis.dot(&d) / n).clamp(-1.0, 1.0).acos(),
                    0.0,
                    0.0,
                ))
            }
            Observation::Camera { camera, face_size } => {
                let p = position_of(x);
                let (px, j) = camera.project_with_jacobian(&p)?;
                let s = match face_size {
                    Some(size) => log_face_size(camera, &p, &j, *size)?,
                    None => 0.0,
                };
                Some(Vector3::new(px.x, px.y, s))
            }
        }
    }

    /// h(x) and its Jacobian with respect to the state.
    pub fn measure_with_jacobian(
        &self,
        x: &SVector<f64, N>,
    ) -> Option<(Vector3<f64>, SMatrix<f64, 3, N>)> {
        let mut jac = SMatrix::<f64, 3, N>::zeros();
        let z = match &self.obs {
            Observation::Position => {
                for i in 0..3 {
                    jac[(i, i)] = 1.0;
                }
                position_of(x)
            }
            Observation::Linear(h) => {
                jac = *h;
                h * x
            }
            Observation::Direction { origin, elevation } => {
                let d = position_of(x) - origin;
                let r2 = d.norm_squared();
                if r2 < 1e-12 {
                    return None;
                }
                // Floor the horizontal range so a source straight above the array stays finite.
                let rho2 = (d.x * d.x + d.y * d.y).max(1e-8);
                let rho = rho2.sqrt();
                jac[(0, 0)] = -d.y / rho2;
                jac[(0, 1)] = d.x / rho2;
                let el = if *elevation {
                    jac[(1, 0)] = -d.x * d.z / (rho * r2);
                    jac[(1, 1)] = -d.y * d.z / (rho * r2);
                    jac[(1, 2)] = rho / r2;
                    d.z.atan2(d.x.hypot(d.y))
                } else {
                    0.0
                };
                Vector3::new(d.y.atan2(d.x), el, 0.0)
            }
            Observation::Cone { origin, axis } => {
                let d = position_of(x) - origin;
                let n = d.norm();
                if n < 1e-6 {
                    return None;
                }
                let c = (axis.dot(&d) / n).clamp(-1.0, 1.0);
                // d(theta)/dp = -(axis - c u) / (n sin(theta)); sin floored on the axis.
                let s = (1.0 - c * c).sqrt().max(1e-3);
                let g = -(axis - d * (c / n)) / (n * s);
                for i in 0..3 {
                    jac[(0, i)] = g[i];
                }
                Vector3::new(c.acos(), 0.0, 0.0)
            }
            Observation::Camera { camera, face_size } => {
                let pos = position_of(x);
                let (p, j) = camera.project_with_jacobian(&pos)?;
                for r in 0..2 {
                    for col in 0..3 {
                        jac[(r, col)] = j[(r, col)];
                    }
                }
                let s = match face_size {
                    Some(size) => {
                        let g = log_face_size_gradient(camera, &pos, *size)?;
                        for col in 0..3 {
                            jac[(2, col)] = g[col];
                        }
                        log_face_size(camera, &pos, &j, *size)?
                    }
                    None => 0.0,
                };
                Vector3::new(p.x, p.y, s)
            }
        };
        if z.iter().chain(jac.iter()).all(|v| v.is_finite()) {
            Some((z, jac))
        } else {
            None
        }
    }

    /// Measurement difference a - b, with the azimuth wrapped to (-pi, pi].
    pub fn residual(&self, a: &Vector3<f64>, b: &Vector3<f64>) -> Vector3<f64> {
        let mut d = a - b;
        if matches!(self.obs, Observation::Direction { .. }) {
            d[0] = wrap_angle(d[0]);
        }
        d
    }

    /// Detection probability of a track with the prepared update `prep` of its density: for a
    /// camera, `p_detect` times the probability that the track is in the image (the predicted
    /// pixel's spread from the state uncertainty against the image borders), so a track whose
    /// mean has drifted just out of view can still take a detection and be corrected; for other
    /// sensors as [`Self::p_detect_at`] at the mean.
    pub fn p_detect_of(
        &self,
        mean: &SVector<f64, N>,
        prep: &Prepared<N>,
        activity: Option<f64>,
    ) -> f64 {
        let Observation::Camera { camera, .. } = &self.obs else {
            return self.p_detect_at(mean, activity);
        };
        // A mean that projects into the image but is not in view was folded there by a strong
        // distortion polynomial: it is far off-axis.
        let p = position_of(mean);
        if !camera.in_view(&p)
            && camera
                .project(&p)
                .is_some_and(|px| camera.contains_pixel(&px))
        {
            return 0.0;
        }
        let inside = |c: f64, sd: f64, size: f64| -> f64 {
            if sd < 1e-9 {
                return if (0.0..=size).contains(&c) { 1.0 } else { 0.0 };
            }
            (normal_cdf((size - c) / sd) - normal_cdf(-c / sd)).clamp(0.0, 1.0)
        };
        let u = inside(prep.zhat[0], prep.state_spread(self, 0), camera.width);
        let v = inside(prep.zhat[1], prep.state_spread(self, 1), camera.height);
        self.p_detect * u * v
    }

    /// Detection probability of a track at state `x` given the scan's voice activity.
    pub fn p_detect_at(&self, x: &SVector<f64, N>, activity: Option<f64>) -> f64 {
        match &self.obs {
            Observation::Camera { camera, .. } => {
                if camera.in_view(&position_of(x)) {
                    self.p_detect
                } else {
                    0.0
                }
            }
            _ if self.audio => match activity {
                Some(a) if a.is_finite() => {
                    (self.p_detect * a.clamp(0.0, 1.0)).max(self.min_p_detect)
                }
                _ => self.p_detect,
            },
            _ => self.p_detect,
        }
    }

    /// Converts a delivered measurement into this sensor's padded measurement vector.
    pub fn convert(&self, m: &Measurement) -> Result<Vector3<f64>, Rejection> {
        let finite = |vs: &[f64]| {
            if vs.iter().all(|v| v.is_finite()) {
                Ok(())
            } else {
                Err(Rejection::NonFinite)
            }
        };
        match (&self.obs, m) {
            (Observation::Position, Measurement::Position(p)) => {
                finite(p.as_slice())?;
                Ok(*p)
            }
            (
                Observation::Direction { elevation, .. },
                Measurement::Direction {
                    azimuth,
                    elevation: el,
                },
            ) => {
                finite(&[*azimuth])?;
                if *elevation {
                    let e = el.ok_or(Rejection::WrongKind)?;
                    finite(&[e])?;
                    Ok(Vector3::new(
                        wrap_angle(*azimuth),
                        e.clamp(-PI / 2.0, PI / 2.0),
                        0.0,
                    ))
                } else {
                    Ok(Vector3::new(wrap_angle(*azimuth), 0.0, 0.0))
                }
            }
            (Observation::Cone { axis, .. }, Measurement::Direction { azimuth, elevation }) => {
                let e = elevation.unwrap_or(0.0);
                finite(&[*azimuth, e])?;
                let u = direction_from_angles(*azimuth, e);
                Ok(Vector3::new(u.dot(axis).clamp(-1.0, 1.0).acos(), 0.0, 0.0))
            }
            (Observation::Camera { face_size, .. }, Measurement::Pixel(p)) => {
                // A sized sensor needs the size: a bare point is of another kind.
                if face_size.is_some() {
                    return Err(Rejection::WrongKind);
                }
                finite(p.as_slice())?;
                Ok(Vector3::new(p.x, p.y, 0.0))
            }
            (Observation::Camera { face_size, .. }, Measurement::Face { point, size_px }) => {
                finite(&[point.x, point.y, *size_px])?;
                let s = match face_size {
                    Some(_) if *size_px > 0.0 => size_px.ln(),
                    Some(_) => return Err(Rejection::WrongKind),
                    None => 0.0,
                };
                Ok(Vector3::new(point.x, point.y, s))
            }
            (Observation::Linear(_), Measurement::Point { z }) => {
                if z.len() != self.dim {
                    return Err(Rejection::WrongKind);
                }
                finite(z)?;
                let mut v = Vector3::zeros();
                for (i, zi) in z.iter().enumerate() {
                    v[i] = *zi;
                }
                Ok(v)
            }
            _ => Err(Rejection::WrongKind),
        }
    }
}

/// Range (px) over which the apparent sizes of false face detections are taken to be
/// log-uniform.
const CLUTTER_SIZE_RANGE_PX: [f64; 2] = [8.0, 512.0];

/// Log of the apparent size sqrt(w h) (px) of the box around an upright face of `size` =
/// (width, height) metres at `p`, turned towards the camera: the face's horizontal and vertical
/// edges map through the projection Jacobian `j` at `p`, and the box is the axis-aligned hull
/// of their images (so a face seen tilted, off the image centre of a pitched camera, gets the
/// larger box a detector draws).
pub(crate) fn log_face_size(
    camera: &Camera,
    p: &Vec3,
    j: &nalgebra::Matrix2x3<f64>,
    size: [f64; 2],
) -> Option<f64> {
    let los = p - camera.centre();
    let right = Vec3::new(-los.y, los.x, 0.0).try_normalize(1e-9)?;
    let (a, b) = (j * right * size[0], j * Vec3::z() * size[1]);
    let w = a.x.abs() + b.x.abs();
    let h = a.y.abs() + b.y.abs();
    let area = w * h;
    (area > 0.0 && area.is_finite()).then(|| 0.5 * area.ln())
}

/// Gradient of [`log_face_size`] with respect to the position (central differences with a step
/// of 1e-4 of the distance to the camera; the size is smooth there).
fn log_face_size_gradient(camera: &Camera, p: &Vec3, size: [f64; 2]) -> Option<Vec3> {
    let h = 1e-4 * (p - camera.centre()).norm().max(1e-3);
    let at = |q: Vec3| -> Option<f64> {
        let (_, j) = camera.project_with_jacobian(&q)?;
        log_face_size(camera, &q, &j, size)
    };
    let mut g = Vec3::zeros();
    for i in 0..3 {
        let mut e = Vec3::zeros();
        e[i] = h;
        g[i] = (at(p + e)? - at(p - e)?) / (2.0 * h);
    }
    Some(g)
}

/// The depth interval [near, far] (m) of a ray inside `region`, or None if it misses it.
pub(crate) fn ray_interval(origin: &Vec3, dir: &Vec3, region: &Aabb) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for i in 0..3 {
        if dir[i].abs() < 1e-12 {
            if origin[i] < region.min[i] || origin[i] > region.max[i] {
                return None;
            }
            continue;
        }
        let a = (region.min[i] - origin[i]) / dir[i];
        let b = (region.max[i] - origin[i]) / dir[i];
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t1 > t0).then_some((t0, t1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track::config::TrackerConfig;
    use crate::track::motion::state_of;

    fn direction_sensor(elevation: bool, cone: Option<Vec3>) -> Sensor<6> {
        let m = SensorModel::AudioDirection {
            origin: Vec3::new(1.0, 1.0, 1.0),
            noise_std_rad: 0.05,
            uses_elevation: elevation,
            cone_axis: cone,
            p_detect: 0.6,
            min_p_detect: 0.02,
            clutter_rate: 2.0,
            filter: FilterKind::Ekf,
        };
        Sensor::compile(&m, 0, &TrackerConfig::default()).unwrap()
    }

    fn numeric_jacobian(s: &Sensor<6>, x: &SVector<f64, 6>) -> SMatrix<f64, 3, 6> {
        let mut j = SMatrix::<f64, 3, 6>::zeros();
        for c in 0..6 {
            let mut xp = *x;
            let mut xm = *x;
            xp[c] += 1e-6;
            xm[c] -= 1e-6;
            let d = s.residual(&s.measure(&xp).unwrap(), &s.measure(&xm).unwrap()) / 2e-6;
            j.set_column(c, &d);
        }
        j
    }

    #[test]
    fn direction_and_cone_jacobians_match_finite_differences() {
        let x = state_of::<6>(&Vec3::new(2.5, -0.3, 1.7), &Vec3::new(0.1, 0.2, 0.0));
        for s in [
            direction_sensor(true, None),
            direction_sensor(false, None),
            direction_sensor(false, Some(Vec3::new(1.0, 1.0, 0.0))),
        ] {
            let (_, j) = s.measure_with_jacobian(&x).unwrap();
            assert!((j - numeric_jacobian(&s, &x)).amax() < 1e-6, "{:?}", s.obs);
        }
    }

    #[test]
    fn azimuth_residual_wraps_and_cone_measurement_uses_the_axis() {
        let s = direction_sensor(false, None);
        let a = Vector3::new(3.1, 0.0, 0.0);
        let b = Vector3::new(-3.1, 0.0, 0.0);
        assert!((s.residual(&a, &b)[0] - (6.2 - 2.0 * PI)).abs() < 1e-12);
        let cone = direction_sensor(false, Some(Vec3::x()));
        // A direction 60 degrees off the axis, whatever its roll about the axis.
        let z = cone
            .convert(&Measurement::Direction {
                azimuth: 60f64.to_radians(),
                elevation: None,
            })
            .unwrap();
        assert!((z[0] - 60f64.to_radians()).abs() < 1e-12);
        let x = state_of::<6>(&Vec3::new(2.0, 1.0, 1.0 + 3f64.sqrt()), &Vec3::zeros());
        assert!((cone.measure(&x).unwrap()[0] - 60f64.to_radians()).abs() < 1e-9);
    }

    #[test]
    fn conversion_rejects_non_finite_and_wrong_kinds() {
        let s = direction_sensor(true, None);
        let nan = Measurement::Direction {
            azimuth: f64::NAN,
            elevation: Some(0.0),
        };
        assert_eq!(s.convert(&nan), Err(Rejection::NonFinite));
        let no_el = Measurement::Direction {
            azimuth: 0.1,
            elevation: None,
        };
        assert_eq!(s.convert(&no_el), Err(Rejection::WrongKind));
        let px = Measurement::Pixel(Pixel::new(1.0, 2.0));
        assert_eq!(s.convert(&px), Err(Rejection::WrongKind));
    }

    #[test]
    fn activity_drives_audio_detection_probability() {
        let s = direction_sensor(false, None);
        let x = state_of::<6>(&Vec3::new(3.0, 1.0, 1.0), &Vec3::zeros());
        assert!((s.p_detect_at(&x, None) - 0.6).abs() < 1e-12);
        assert!((s.p_detect_at(&x, Some(0.5)) - 0.3).abs() < 1e-12);
        assert!((s.p_detect_at(&x, Some(0.0)) - 0.02).abs() < 1e-12);
        assert!((s.p_detect_at(&x, Some(f64::NAN)) - 0.6).abs() < 1e-12);
    }

    #[test]
    fn a_camera_detects_a_track_with_the_probability_that_it_is_in_view() {
        use crate::track::filter::prepare;
        use crate::track::gaussian::Gaussian;
        // Looking along +y from (2, 0, 1.5), 1000 px focal length, 1920 x 1080.
        let k = Matrix3::new(1000.0, 0.0, 960.0, 0.0, 1000.0, 540.0, 0.0, 0.0, 1.0);
        let r = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0);
        let c = Vec3::new(2.0, 0.0, 1.5);
        let camera = Camera::from_krt("cam", 1920.0, 1080.0, k, r, -(r * c), None).unwrap();
        let cfg = TrackerConfig::default();
        let model = SensorModel::CameraPoint {
            camera: Box::new(camera),
            noise_std_px: 10.0,
            p_detect: 0.9,
            clutter_rate: 1.0,
            filter: FilterKind::Ekf,
            face_size_m: None,
            face_size_log_std: 0.1,
        };
        let s = Sensor::<6>::compile(&model, 0, &cfg).unwrap();
        let pd = |x: f64, sd: f64| {
            let mut cov = SMatrix::<f64, 6, 6>::identity() * 0.01;
            cov[(0, 0)] = sd * sd;
            let g = Gaussian {
                mean: state_of::<6>(&Vec3::new(x, 3.0, 1.5), &Vec3::zeros()),
                cov,
            };
            let p = prepare(&s, &g, &cfg.ukf).unwrap();
            s.p_detect_of(&g.mean, &p, None)
        };
        // The left image border is at x = 2 - 3 * 0.96 = -0.88 at 3 m.
        assert!((pd(2.0, 0.05) - 0.9).abs() < 1e-6);
        let edge = pd(-0.95, 0.3);
        assert!(edge > 0.2 && edge < 0.45, "{edge}");
        assert!(pd(-1.6, 0.01) < 1e-6);
    }

    #[test]
    fn ray_box_interval() {
        let b = Aabb::new(Vec3::zeros(), Vec3::new(2.0, 2.0, 2.0)).unwrap();
        let (t0, t1) = ray_interval(&Vec3::new(-1.0, 1.0, 1.0), &Vec3::x(), &b).unwrap();
        assert!((t0 - 1.0).abs() < 1e-12 && (t1 - 3.0).abs() < 1e-12);
        assert!(ray_interval(&Vec3::new(-1.0, 5.0, 1.0), &Vec3::x(), &b).is_none());
    }
}
