//! Single-object Gaussian filters: Kalman / EKF (analytic Jacobian, Joseph form) and UKF.
//!
//! An update is split in stages that the GLMB uses separately. [`prepare`] computes the
//! innovation statistics (predicted measurement, innovation covariance, cross covariance), which
//! is all that gating and scoring any number of measurements needs; [`Prepared::complete`] then
//! computes the gain and the posterior covariance, only for tracks that a hypothesis actually
//! updates; [`Gain::mean`] applies a measurement. This split holds for all three filters because
//! the gain and the posterior covariance of KF, EKF (linearised at the predicted mean) and UKF do
//! not depend on the measured value.

use std::f64::consts::PI;

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use super::config::{FilterKind, UkfConfig};
use super::gaussian::{Gaussian, condition};
use super::sensor::Sensor;

/// Innovation statistics of one track's update by one sensor.
#[derive(Debug, Clone)]
pub(crate) struct Prepared<const N: usize> {
    /// Predicted measurement.
    pub zhat: Vector3<f64>,
    s: Matrix3<f64>,
    s_inv: Matrix3<f64>,
    log_norm: f64,
    /// Cross covariance of state and measurement (EKF: P H').
    pxz: SMatrix<f64, N, 3>,
    /// The EKF Jacobian, for the Joseph form; None for the UKF.
    jac: Option<SMatrix<f64, 3, N>>,
}

/// Gain and posterior covariance of one track's update by one sensor.
#[derive(Debug, Clone)]
pub(crate) struct Gain<const N: usize> {
    gain: SMatrix<f64, N, 3>,
    /// Posterior covariance (the same for every measurement).
    pub cov: SMatrix<f64, N, N>,
}

impl<const N: usize> Prepared<N> {
    /// Innovation z - zhat (angles wrapped).
    pub fn innovation(&self, sensor: &Sensor<N>, z: &Vector3<f64>) -> Vector3<f64> {
        sensor.residual(z, &self.zhat)
    }

    /// Squared Mahalanobis distance of an innovation.
    pub fn mahalanobis(&self, nu: &Vector3<f64>) -> f64 {
        nu.dot(&(self.s_inv * nu))
    }

    /// Standard deviation of component `i` of the predicted measurement h(x) from the state's
    /// uncertainty alone (the innovation covariance without the measurement noise).
    pub fn state_spread(&self, sensor: &Sensor<N>, i: usize) -> f64 {
        (self.s[(i, i)] - sensor.r[(i, i)]).max(0.0).sqrt()
    }

    /// log N(nu; 0, S) from the squared Mahalanobis distance.
    pub fn log_likelihood(&self, d2: f64) -> f64 {
        self.log_norm - 0.5 * d2
    }

    /// Gain and posterior covariance (Joseph form for the EKF), kept symmetric positive definite.
    pub fn complete(&self, sensor: &Sensor<N>, prior: &Gaussian<N>) -> Option<Gain<N>> {
        let gain = self.pxz * self.s_inv;
        if gain.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let mut cov = match &self.jac {
            // Joseph form (I - K H) P (I - K H)' + K R K', evaluated as AP = P - K (P H')' and
            // AP - (AP H') K': a sum of two positive semi-definite terms.
            Some(h) => {
                let ap = prior.cov - gain * self.pxz.transpose();
                ap - (ap * h.transpose()) * gain.transpose() + gain * sensor.r * gain.transpose()
            }
            None => prior.cov - gain * self.s * gain.transpose(),
        };
        if !condition(&mut cov) {
            return None;
        }
        Some(Gain { gain, cov })
    }
}

impl<const N: usize> Gain<N> {
    /// Posterior mean for an innovation.
    pub fn mean(&self, prior_mean: &SVector<f64, N>, nu: &Vector3<f64>) -> SVector<f64, N> {
        prior_mean + self.gain * nu
    }
}

/// A step's linear-Gaussian transition, with the non-zero pattern of F kept so that F P F'
/// skips the zeros (the motion models' F has two non-zeros per row).
#[derive(Debug, Clone)]
pub(crate) struct Transition<const N: usize> {
    f: SMatrix<f64, N, N>,
    q: SMatrix<f64, N, N>,
    /// (row, column, value) of the non-zero entries of F.
    nonzeros: Vec<(usize, usize, f64)>,
}

impl<const N: usize> Transition<N> {
    /// The transition x+ = F x + w, w ~ N(0, Q).
    pub fn new(f: SMatrix<f64, N, N>, q: SMatrix<f64, N, N>) -> Self {
        let mut nonzeros = Vec::new();
        for i in 0..N {
            for k in 0..N {
                if f[(i, k)] != 0.0 {
                    nonzeros.push((i, k, f[(i, k)]));
                }
            }
        }
        Self { f, q, nonzeros }
    }

    /// Kalman prediction N(F m, F P F' + Q), kept symmetric positive definite. None when the
    /// result is not finite.
    pub fn predict(&self, g: &Gaussian<N>) -> Option<Gaussian<N>> {
        let mean = self.f * g.mean;
        // F P, then (F P) F', each over the non-zeros of F only.
        let mut fp = SMatrix::<f64, N, N>::zeros();
        for &(i, k, v) in &self.nonzeros {
            for j in 0..N {
                fp[(i, j)] += v * g.cov[(k, j)];
            }
        }
        let mut cov = self.q;
        for &(j, k, v) in &self.nonzeros {
            for i in 0..N {
                cov[(i, j)] += fp[(i, k)] * v;
            }
        }
        if mean.iter().any(|v| !v.is_finite()) || !condition(&mut cov) {
            return None;
        }
        Some(Gaussian { mean, cov })
    }
}

/// Prepares the update of N(mean, cov) by `sensor` with its configured filter. None when the
/// sensor cannot observe the state (behind the camera, at the array centre) or the numbers
/// degenerate.
pub(crate) fn prepare<const N: usize>(
    sensor: &Sensor<N>,
    prior: &Gaussian<N>,
    ukf: &UkfConfig,
) -> Option<Prepared<N>> {
    if sensor.filter == FilterKind::Ukf && sensor.nonlinear() {
        // Sigma points behind the camera or through the array centre have no image: fall back
        // to the linearisation at the mean, which is defined whenever the mean is.
        prepare_ukf(sensor, prior, ukf).or_else(|| prepare_ekf(sensor, prior))
    } else {
        prepare_ekf(sensor, prior)
    }
}

/// Applies one measurement: posterior and log predictive likelihood.
pub(crate) fn update<const N: usize>(
    sensor: &Sensor<N>,
    prior: &Gaussian<N>,
    z: &Vector3<f64>,
    ukf: &UkfConfig,
) -> Option<(Gaussian<N>, f64)> {
    let p = prepare(sensor, prior, ukf)?;
    let g = p.complete(sensor, prior)?;
    let nu = p.innovation(sensor, z);
    let ll = p.log_likelihood(p.mahalanobis(&nu));
    Some((
        Gaussian {
            mean: g.mean(&prior.mean, &nu),
            cov: g.cov,
        },
        ll,
    ))
}

/// Inverse and log normaliser of an innovation covariance of true dimension `dim` (closed-form
/// 3x3 inverse; positive definiteness by the leading minors, repaired when it fails).
fn invert_innovation(s: &mut Matrix3<f64>, dim: usize) -> Option<(Matrix3<f64>, f64)> {
    if s.iter().any(|v| !v.is_finite()) {
        return None;
    }
    *s = (*s + s.transpose()) * 0.5;
    let inverse = |m: &Matrix3<f64>| -> Option<(Matrix3<f64>, f64)> {
        let minor2 = m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)];
        let c00 = m[(1, 1)] * m[(2, 2)] - m[(1, 2)] * m[(2, 1)];
        let c01 = m[(1, 2)] * m[(2, 0)] - m[(1, 0)] * m[(2, 2)];
        let c02 = m[(1, 0)] * m[(2, 1)] - m[(1, 1)] * m[(2, 0)];
        let det = m[(0, 0)] * c00 + m[(0, 1)] * c01 + m[(0, 2)] * c02;
        let scale = m[(0, 0)].max(m[(1, 1)]).max(m[(2, 2)]);
        if !(m[(0, 0)] > 0.0 && minor2 > 0.0 && det > 1e-30 * scale * scale * scale) {
            return None;
        }
        let adj = Matrix3::new(
            c00,
            m[(0, 2)] * m[(2, 1)] - m[(0, 1)] * m[(2, 2)],
            m[(0, 1)] * m[(1, 2)] - m[(0, 2)] * m[(1, 1)],
            c01,
            m[(0, 0)] * m[(2, 2)] - m[(0, 2)] * m[(2, 0)],
            m[(0, 2)] * m[(1, 0)] - m[(0, 0)] * m[(1, 2)],
            c02,
            m[(0, 1)] * m[(2, 0)] - m[(0, 0)] * m[(2, 1)],
            minor2,
        );
        Some((adj / det, det.ln()))
    };
    let (s_inv, log_det) = match inverse(s) {
        Some(r) => r,
        None => {
            if !condition(s) {
                return None;
            }
            inverse(s)?
        }
    };
    let log_norm = -0.5 * (dim as f64 * (2.0 * PI).ln() + log_det);
    (log_norm.is_finite() && s_inv.iter().all(|v| v.is_finite())).then_some((s_inv, log_norm))
}

fn prepare_ekf<const N: usize>(sensor: &Sensor<N>, prior: &Gaussian<N>) -> Option<Prepared<N>> {
    let (zhat, h) = sensor.measure_with_jacobian(&prior.mean)?;
    let pxz = prior.cov * h.transpose();
    let mut s = h * pxz + sensor.r;
    let (s_inv, log_norm) = invert_innovation(&mut s, sensor.dim)?;
    Some(Prepared {
        zhat,
        s,
        s_inv,
        log_norm,
        pxz,
        jac: Some(h),
    })
}

fn prepare_ukf<const N: usize>(
    sensor: &Sensor<N>,
    prior: &Gaussian<N>,
    ukf: &UkfConfig,
) -> Option<Prepared<N>> {
    const MAX_POINTS: usize = 12;
    if 2 * N > MAX_POINTS {
        return None;
    }
    let n = N as f64;
    let lambda = ukf.alpha * ukf.alpha * (n + ukf.kappa) - n;
    let c = n + lambda;
    if c.is_nan() || c <= 0.0 {
        return None;
    }
    let l = (prior.cov * c).cholesky()?.l();
    let wm0 = lambda / c;
    let wc0 = wm0 + 1.0 - ukf.alpha * ukf.alpha + ukf.beta;
    let wi = 0.5 / c;
    let z0 = sensor.measure(&prior.mean)?;
    let mut zs = [Vector3::zeros(); MAX_POINTS];
    let mut dx = [SVector::<f64, N>::zeros(); MAX_POINTS];
    for i in 0..N {
        let col: SVector<f64, N> = l.column(i).into();
        for (k, sign) in [(2 * i, 1.0), (2 * i + 1, -1.0)] {
            dx[k] = col * sign;
            zs[k] = sensor.measure(&(prior.mean + dx[k]))?;
        }
    }
    // Angles are averaged as offsets from the central point so wrapping cannot bias the mean.
    let mut zhat = z0;
    for z in &zs[..2 * N] {
        zhat += sensor.residual(z, &z0) * wi;
    }
    let r0 = sensor.residual(&z0, &zhat);
    let mut s = r0 * r0.transpose() * wc0 + sensor.r;
    let mut pxz = SMatrix::<f64, N, 3>::zeros();
    for k in 0..2 * N {
        let r = sensor.residual(&zs[k], &zhat);
        s += r * r.transpose() * wi;
        pxz += dx[k] * r.transpose() * wi;
    }
    let (s_inv, log_norm) = invert_innovation(&mut s, sensor.dim)?;
    Some(Prepared {
        zhat,
        s,
        s_inv,
        log_norm,
        pxz,
        jac: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Camera, Vec3};
    use crate::track::config::TrackerConfig;
    use crate::track::motion::{position_of, state_of};
    use crate::track::sensor::SensorModel;
    use nalgebra::{Matrix6, Vector6};

    fn sensor(m: SensorModel) -> Sensor<6> {
        Sensor::compile(&m, 0, &TrackerConfig::default()).unwrap()
    }

    fn camera_sensor(filter: FilterKind) -> Sensor<6> {
        let k = Matrix3::new(1000.0, 0.0, 960.0, 0.0, 1000.0, 540.0, 0.0, 0.0, 1.0);
        let r = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0);
        let c = Vec3::new(2.0, 0.0, 1.5);
        let cam =
            Camera::from_krt("c", 1920.0, 1080.0, k, r, -(r * c), Some(&[-0.1, 0.02])).unwrap();
        sensor(SensorModel::CameraPoint {
            camera: Box::new(cam),
            noise_std_px: 10.0,
            p_detect: 0.9,
            clutter_rate: 1.0,
            filter,
            face_size_m: None,
            face_size_log_std: 0.1,
        })
    }

    fn gaussian(p: Vec3, sd: f64) -> Gaussian<6> {
        Gaussian {
            mean: state_of(&p, &Vec3::zeros()),
            cov: Matrix6::identity() * sd * sd,
        }
    }

    #[test]
    fn linear_update_is_the_kalman_update() {
        let s = sensor(SensorModel::AudioPosition {
            noise_std_m: 0.1,
            p_detect: 0.6,
            min_p_detect: 0.0,
            clutter_rate: 10.0,
            clutter_volume_m3: 50.0,
        });
        let mut prior = gaussian(Vec3::new(1.0, 2.0, 1.5), 0.3);
        prior.cov[(0, 3)] = 0.02;
        prior.cov[(3, 0)] = 0.02;
        let z = Vector3::new(1.2, 1.9, 1.5);
        let (post, ll) = update(&s, &prior, &z, &UkfConfig::default()).unwrap();
        // Textbook form: K = P H' S^-1, P+ = (I - K H) P, log N(z; H m, S).
        let mut h = SMatrix::<f64, 3, 6>::zeros();
        h.fixed_view_mut::<3, 3>(0, 0).fill_with_identity();
        let sm = h * prior.cov * h.transpose() + Matrix3::identity() * 0.01;
        let k = prior.cov * h.transpose() * sm.try_inverse().unwrap();
        let nu = z - h * prior.mean;
        assert!((post.mean - (prior.mean + k * nu)).amax() < 1e-12);
        assert!((post.cov - (Matrix6::identity() - k * h) * prior.cov).amax() < 1e-12);
        let expect = -0.5 * (3.0 * (2.0 * PI).ln() + sm.determinant().ln())
            - 0.5 * nu.dot(&(sm.try_inverse().unwrap() * nu));
        assert!((ll - expect).abs() < 1e-9);
        // The velocity is corrected through the position-velocity correlation.
        assert!(post.mean[3] > 0.0);
    }

    #[test]
    fn ukf_and_ekf_agree_for_a_camera_with_distortion() {
        let prior = gaussian(Vec3::new(2.4, 3.0, 1.6), 0.05);
        let x = state_of::<6>(&Vec3::new(2.45, 3.0, 1.58), &Vec3::zeros());
        let z = camera_sensor(FilterKind::Ekf).measure(&x).unwrap();
        let ukf = UkfConfig::default();
        let (pe, le) = update(&camera_sensor(FilterKind::Ekf), &prior, &z, &ukf).unwrap();
        let (pu, lu) = update(&camera_sensor(FilterKind::Ukf), &prior, &z, &ukf).unwrap();
        assert!((position_of(&pe.mean) - position_of(&pu.mean)).norm() < 2e-3);
        assert!((le - lu).abs() < 0.05, "{le} {lu}");
        // The pixel pulls the lateral position towards the truth.
        assert!((pe.mean[0] - 2.45).abs() < (prior.mean[0] - 2.45).abs());
    }

    #[test]
    fn behind_the_camera_and_degenerate_covariances_give_no_nan() {
        let ukf = UkfConfig::default();
        let z = Vector3::new(960.0, 540.0, 0.0);
        for filter in [FilterKind::Ekf, FilterKind::Ukf] {
            let s = camera_sensor(filter);
            // Mean behind the camera: not observable.
            assert!(prepare(&s, &gaussian(Vec3::new(2.0, -1.0, 1.5), 0.1), &ukf).is_none());
            // Mean in front, but sigma points reach behind: the EKF fallback answers.
            let (g, ll) = update(&s, &gaussian(Vec3::new(2.0, 0.3, 1.5), 1.0), &z, &ukf).unwrap();
            assert!(g.mean.iter().chain(g.cov.iter()).all(|v| v.is_finite()) && ll.is_finite());
            // A zero and a rank-one covariance.
            let mut zero = gaussian(Vec3::new(2.0, 3.0, 1.5), 0.0);
            let (g, _) = update(&s, &zero, &z, &ukf).unwrap();
            assert!(g.cov.cholesky().is_some());
            let v = Vector6::new(1.0, 1.0, 0.0, 0.0, 0.0, 0.0);
            zero.cov = v * v.transpose();
            let (g, ll) = update(&s, &zero, &z, &ukf).unwrap();
            assert!(g.cov.cholesky().is_some() && ll.is_finite());
        }
        // NaN in the prior is refused.
        let mut bad = gaussian(Vec3::new(2.0, 3.0, 1.5), 0.1);
        bad.cov[(0, 0)] = f64::NAN;
        assert!(prepare(&camera_sensor(FilterKind::Ukf), &bad, &ukf).is_none());
    }

    #[test]
    fn azimuth_innovation_wraps_across_pi() {
        let s = sensor(SensorModel::AudioDirection {
            origin: Vec3::zeros(),
            noise_std_rad: 0.05,
            uses_elevation: false,
            cone_axis: None,
            p_detect: 0.6,
            min_p_detect: 0.0,
            clutter_rate: 1.0,
            filter: FilterKind::Ukf,
        });
        // A track just below azimuth +pi, a measurement just above -pi.
        let prior = gaussian(Vec3::new(-2.0, 0.02, 1.0), 0.1);
        let z = Vector3::new(-PI + 0.01, 0.0, 0.0);
        for filter in [FilterKind::Ekf, FilterKind::Ukf] {
            let mut s = s.clone();
            s.filter = filter;
            let p = prepare(&s, &prior, &UkfConfig::default()).unwrap();
            let nu = p.innovation(&s, &z);
            assert!(nu[0].abs() < 0.05, "{filter:?}: {nu:?}");
            let m = p.complete(&s, &prior).unwrap().mean(&prior.mean, &nu);
            assert!(m[1] < 0.02, "pulled towards the measurement across the cut");
        }
    }
}
