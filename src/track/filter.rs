//! Single-object Gaussian filters: Kalman / EKF (analytic Jacobian, Joseph form) and UKF.
//!
//! An update is split in two: [`prepare`] computes everything that does not depend on the
//! measured value (predicted measurement, innovation covariance, gain, posterior covariance),
//! once per track and sensor; [`Prepared`] then scores and applies any number of measurements
//! cheaply. This holds for all three filters because the gain and the posterior covariance of
//! KF, EKF (linearised at the predicted mean) and UKF do not depend on z.

use std::f64::consts::PI;

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use super::config::{FilterKind, UkfConfig};
use super::gaussian::{Gaussian, condition};
use super::sensor::Sensor;

/// The measurement-independent part of one track's update by one sensor.
#[derive(Debug, Clone)]
pub(crate) struct Prepared<const N: usize> {
    /// Predicted measurement.
    pub zhat: Vector3<f64>,
    s_inv: Matrix3<f64>,
    log_norm: f64,
    gain: SMatrix<f64, N, 3>,
    /// Posterior covariance (the same for every measurement).
    pub cov: SMatrix<f64, N, N>,
    prior_mean: SVector<f64, N>,
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

    /// log N(nu; 0, S) from the squared Mahalanobis distance.
    pub fn log_likelihood(&self, d2: f64) -> f64 {
        self.log_norm - 0.5 * d2
    }

    /// Posterior mean for an innovation.
    pub fn mean(&self, nu: &Vector3<f64>) -> SVector<f64, N> {
        self.prior_mean + self.gain * nu
    }
}

/// Kalman prediction N(F m, F P F' + Q), kept symmetric positive definite. None when the result
/// is not finite.
pub(crate) fn predict<const N: usize>(
    g: &Gaussian<N>,
    f: &SMatrix<f64, N, N>,
    q: &SMatrix<f64, N, N>,
) -> Option<Gaussian<N>> {
    let mean = f * g.mean;
    let mut cov = f * g.cov * f.transpose() + q;
    if mean.iter().any(|v| !v.is_finite()) || !condition(&mut cov) {
        return None;
    }
    Some(Gaussian { mean, cov })
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
    let nu = p.innovation(sensor, z);
    let ll = p.log_likelihood(p.mahalanobis(&nu));
    Some((
        Gaussian {
            mean: p.mean(&nu),
            cov: p.cov,
        },
        ll,
    ))
}

/// Inverse and log normaliser of an innovation covariance of true dimension `dim`.
fn invert_innovation(s: &mut Matrix3<f64>, dim: usize) -> Option<(Matrix3<f64>, f64)> {
    if !condition(s) {
        return None;
    }
    let chol = s.cholesky()?;
    let log_det: f64 = 2.0 * chol.l().diagonal().iter().map(|v| v.ln()).sum::<f64>();
    let s_inv = chol.inverse();
    let log_norm = -0.5 * (dim as f64 * (2.0 * PI).ln() + log_det);
    (log_norm.is_finite() && s_inv.iter().all(|v| v.is_finite())).then_some((s_inv, log_norm))
}

fn prepare_ekf<const N: usize>(sensor: &Sensor<N>, prior: &Gaussian<N>) -> Option<Prepared<N>> {
    let (zhat, h) = sensor.measure_with_jacobian(&prior.mean)?;
    let pht = prior.cov * h.transpose();
    let mut s = h * pht + sensor.r;
    let (s_inv, log_norm) = invert_innovation(&mut s, sensor.dim)?;
    let gain = pht * s_inv;
    // Joseph form keeps the posterior covariance positive definite under rounding.
    let a = SMatrix::<f64, N, N>::identity() - gain * h;
    let mut cov = a * prior.cov * a.transpose() + gain * sensor.r * gain.transpose();
    if !condition(&mut cov) || gain.iter().any(|v| !v.is_finite()) {
        return None;
    }
    Some(Prepared {
        zhat,
        s_inv,
        log_norm,
        gain,
        cov,
        prior_mean: prior.mean,
    })
}

fn prepare_ukf<const N: usize>(
    sensor: &Sensor<N>,
    prior: &Gaussian<N>,
    ukf: &UkfConfig,
) -> Option<Prepared<N>> {
    let n = N as f64;
    let lambda = ukf.alpha * ukf.alpha * (n + ukf.kappa) - n;
    let c = n + lambda;
    if !(c > 0.0) {
        return None;
    }
    let l = (prior.cov * c).cholesky()?.l();
    let wm0 = lambda / c;
    let wc0 = wm0 + 1.0 - ukf.alpha * ukf.alpha + ukf.beta;
    let wi = 0.5 / c;
    let z0 = sensor.measure(&prior.mean)?;
    let mut zs = [Vector3::zeros(); 12];
    let mut dx = [SVector::<f64, N>::zeros(); 12];
    if 2 * N > zs.len() {
        return None;
    }
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
    let gain = pxz * s_inv;
    let mut cov = prior.cov - gain * s * gain.transpose();
    if !condition(&mut cov) || gain.iter().any(|v| !v.is_finite()) {
        return None;
    }
    Some(Prepared {
        zhat,
        s_inv,
        log_norm,
        gain,
        cov,
        prior_mean: prior.mean,
    })
}
