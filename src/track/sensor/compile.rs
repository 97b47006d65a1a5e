//! Building a [`Sensor`] from its [`SensorModel`]: validation (errors name the sensor and field),
//! the observation, the noise covariance and the clutter density of each kind.

use std::f64::consts::PI;

use nalgebra::{DMatrix, Matrix3, SMatrix};

use super::{CLUTTER_SIZE_RANGE_PX, Observation, Sensor, SensorModel};
use crate::geometry::{Camera, Vec3};
use crate::track::clutter::ClutterRate;
use crate::track::config::{ConfigError, FilterKind, TrackerConfig};
use crate::track::gaussian::chi_square_quantile;

fn bad(index: usize, field: &str, message: &str) -> ConfigError {
    ConfigError::new(format!("sensors[{index}].{field}"), message)
}

fn check_probability(v: f64, index: usize, field: &str) -> Result<(), ConfigError> {
    if v.is_finite() && (0.0..1.0).contains(&v) {
        Ok(())
    } else {
        Err(bad(index, field, "must be in [0, 1)"))
    }
}

fn check_positive(v: f64, index: usize, field: &str) -> Result<(), ConfigError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(bad(index, field, "must be a positive number"))
    }
}

/// What a sensor kind observes: the observation, its dimension and the log of the clutter's
/// spatial density over the measurement space (the noise goes into the covariance passed along).
struct Observed<const N: usize> {
    obs: Observation<N>,
    dim: usize,
    log_density: f64,
}

/// The detection and clutter settings every kind has.
struct Detection {
    p_detect: f64,
    min_p_detect: f64,
    clutter_rate: f64,
    filter: FilterKind,
    audio: bool,
}

impl Detection {
    /// The settings of an audio sensor.
    fn audio(p_detect: f64, min_p_detect: f64, clutter_rate: f64, filter: FilterKind) -> Self {
        Self {
            p_detect,
            min_p_detect,
            clutter_rate,
            filter,
            audio: true,
        }
    }

    /// The settings of a camera or generic sensor (never talking-dependent).
    fn other(p_detect: f64, clutter_rate: f64, filter: FilterKind) -> Self {
        Self {
            p_detect,
            min_p_detect: 0.0,
            clutter_rate,
            filter,
            audio: false,
        }
    }
}

impl<const N: usize> Sensor<N> {
    /// Validates a sensor model and prepares it for a state of dimension N.
    pub fn compile(
        model: &SensorModel,
        index: usize,
        cfg: &TrackerConfig,
    ) -> Result<Self, ConfigError> {
        let needs_3d = !matches!(model, SensorModel::GenericPoint { .. });
        if needs_3d && N != 6 {
            return Err(bad(
                index,
                "kind",
                "audio and camera sensors need the 3-D state [position; velocity]",
            ));
        }
        let mut r = Matrix3::identity();
        let (observed, det) = observation_model(model, index, &mut r)?;
        check_probability(det.p_detect, index, "p_detect")?;
        check_probability(det.min_p_detect, index, "min_p_detect")?;
        check_positive(det.clutter_rate, index, "clutter_rate")?;
        let off_p_detect = if det.audio {
            det.min_p_detect
        } else {
            cfg.face.away_p_detect.min(det.p_detect)
        };
        let dim = observed.dim;
        let clutter = ClutterRate::new(det.clutter_rate, observed.log_density);
        Ok(Self {
            obs: observed.obs,
            dim,
            r,
            p_detect: det.p_detect,
            min_p_detect: det.min_p_detect,
            off_p_detect,
            mode: None,
            clutter,
            filter: det.filter,
            audio: det.audio,
            gate: chi_square_quantile(cfg.gate_probability, dim),
            birth_gate: chi_square_quantile(cfg.birth.suppress_gate_probability, dim),
        })
    }
}

/// What a sensor kind observes (writing its noise covariance into `r`) and its detection
/// settings, with the kind's own fields checked.
fn observation_model<const N: usize>(
    model: &SensorModel,
    index: usize,
    r: &mut Matrix3<f64>,
) -> Result<(Observed<N>, Detection), ConfigError> {
    Ok(match model {
        SensorModel::AudioPosition {
            noise_std_m,
            p_detect,
            min_p_detect,
            clutter_rate,
            clutter_volume_m3,
        } => {
            let observed = position(index, *noise_std_m, *clutter_volume_m3, r)?;
            let det = Detection::audio(*p_detect, *min_p_detect, *clutter_rate, FilterKind::Ekf);
            (observed, det)
        }
        SensorModel::AudioDirection {
            origin,
            noise_std_rad,
            uses_elevation,
            cone_axis,
            p_detect,
            min_p_detect,
            clutter_rate,
            filter,
        } => {
            let observed = direction(
                index,
                origin,
                *noise_std_rad,
                *uses_elevation,
                cone_axis.as_ref(),
                r,
            )?;
            let det = Detection::audio(*p_detect, *min_p_detect, *clutter_rate, *filter);
            (observed, det)
        }
        SensorModel::CameraPoint {
            camera,
            noise_std_px,
            p_detect,
            clutter_rate,
            filter,
            face_size_m,
            face_size_log_std,
        } => {
            let observed = camera_point(
                index,
                camera,
                *noise_std_px,
                *face_size_m,
                *face_size_log_std,
                r,
            )?;
            (
                observed,
                Detection::other(*p_detect, *clutter_rate, *filter),
            )
        }
        SensorModel::GenericPoint {
            h,
            r: noise,
            p_detect,
            clutter_rate,
            clutter_density,
        } => {
            check_positive(*clutter_density, index, "clutter_density")?;
            let observed = linear(index, h, noise, *clutter_density, r)?;
            (
                observed,
                Detection::other(*p_detect, *clutter_rate, FilterKind::Ekf),
            )
        }
    })
}

/// An array's 3-D position fix with isotropic noise, clutter uniform over `clutter_volume_m3`.
fn position<const N: usize>(
    index: usize,
    noise_std_m: f64,
    clutter_volume_m3: f64,
    r: &mut Matrix3<f64>,
) -> Result<Observed<N>, ConfigError> {
    check_positive(noise_std_m, index, "noise_std_m")?;
    check_positive(clutter_volume_m3, index, "clutter_volume_m3")?;
    *r *= noise_std_m * noise_std_m;
    Ok(Observed {
        obs: Observation::Position,
        dim: 3,
        log_density: -clutter_volume_m3.ln(),
    })
}

/// An array's direction: a cone angle about `cone_axis` (a linear array), or azimuth with or
/// without elevation from `origin`.
fn direction<const N: usize>(
    index: usize,
    origin: &Vec3,
    noise_std_rad: f64,
    uses_elevation: bool,
    cone_axis: Option<&Vec3>,
    r: &mut Matrix3<f64>,
) -> Result<Observed<N>, ConfigError> {
    check_positive(noise_std_rad, index, "noise_std_rad")?;
    if origin.iter().any(|v| !v.is_finite()) {
        return Err(bad(index, "origin", "must be finite"));
    }
    let (obs, dim, log_density) = match cone_axis {
        Some(axis) => {
            let n = axis.norm();
            if !(n.is_finite() && n > 1e-9) {
                return Err(bad(index, "cone_axis", "must be a non-zero vector"));
            }
            let obs = Observation::Cone {
                origin: *origin,
                axis: axis / n,
            };
            (obs, 1, -PI.ln())
        }
        None if uses_elevation => {
            let obs = Observation::Direction {
                origin: *origin,
                elevation: true,
            };
            (obs, 2, -(2.0 * PI * PI).ln())
        }
        None => {
            let obs = Observation::Direction {
                origin: *origin,
                elevation: false,
            };
            (obs, 1, -(2.0 * PI).ln())
        }
    };
    for i in 0..dim {
        r[(i, i)] = noise_std_rad * noise_std_rad;
    }
    Ok(Observed {
        obs,
        dim,
        log_density,
    })
}

/// A camera's pixel, with the log of the face box's size when `face_size_m` is set.
fn camera_point<const N: usize>(
    index: usize,
    camera: &Camera,
    noise_std_px: f64,
    face_size_m: Option<[f64; 2]>,
    face_size_log_std: f64,
    r: &mut Matrix3<f64>,
) -> Result<Observed<N>, ConfigError> {
    check_positive(noise_std_px, index, "noise_std_px")?;
    let var = noise_std_px * noise_std_px;
    r[(0, 0)] = var;
    r[(1, 1)] = var;
    let mut dim = 2;
    let mut log_density = -(camera.width * camera.height).ln();
    if let Some([w, h]) = face_size_m {
        check_positive(w, index, "face_size_m")?;
        check_positive(h, index, "face_size_m")?;
        check_positive(face_size_log_std, index, "face_size_log_std")?;
        r[(2, 2)] = face_size_log_std * face_size_log_std;
        dim = 3;
        // Clutter sizes are uniform in log over CLUTTER_SIZE_RANGE_PX.
        let [lo, hi] = CLUTTER_SIZE_RANGE_PX;
        log_density -= (hi / lo).ln().ln();
    }
    Ok(Observed {
        obs: Observation::Camera {
            camera: Box::new(camera.clone()),
            face_size: face_size_m,
        },
        dim,
        log_density,
    })
}

/// A generic linear measurement z = H x + v, v ~ N(0, R), with 1 to 3 rows.
fn linear<const N: usize>(
    index: usize,
    h: &DMatrix<f64>,
    noise: &DMatrix<f64>,
    clutter_density: f64,
    r: &mut Matrix3<f64>,
) -> Result<Observed<N>, ConfigError> {
    let m = h.nrows();
    if !(1..=3).contains(&m) || h.ncols() != N {
        return Err(bad(
            index,
            "h",
            &format!("must be m x {N} with 1 <= m <= 3 (got {m} x {})", h.ncols()),
        ));
    }
    if noise.nrows() != m || noise.ncols() != m {
        return Err(bad(index, "r", "must be m x m, matching h"));
    }
    if h.iter().chain(noise.iter()).any(|v| !v.is_finite()) {
        return Err(bad(index, "h", "h and r must be finite"));
    }
    let sym = (noise + noise.transpose()) * 0.5;
    if (noise - &sym).amax() > 1e-9 * sym.amax().max(1.0) || sym.clone().cholesky().is_none() {
        return Err(bad(index, "r", "must be symmetric positive definite"));
    }
    let mut hh = SMatrix::<f64, 3, N>::zeros();
    for i in 0..m {
        for j in 0..N {
            hh[(i, j)] = h[(i, j)];
        }
        for j in 0..m {
            r[(i, j)] = sym[(i, j)];
        }
    }
    Ok(Observed {
        obs: Observation::Linear(hh),
        dim: m,
        log_density: clutter_density.ln(),
    })
}
