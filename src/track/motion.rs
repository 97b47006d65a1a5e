//! Motion models. The state is `[position (D); velocity (D)]` with D = N / 2 spatial axes
//! (D = 3 for the room, D = 2 for planar test scenarios).

use nalgebra::{SMatrix, SVector};

use super::config::{ConfigError, MotionConfig, MotionKind};
use crate::geometry::{Aabb, Vec3};

/// A linear-Gaussian motion model whose F and Q depend on the step length dt.
#[derive(Debug, Clone, PartialEq)]
pub enum MotionModel<const N: usize> {
    /// Langevin model (spec 003 eq. 14-15, [P-fix] reading): p+ = p + dt v,
    /// v+ = e^{-beta dt} v + nu sqrt(1 - e^{-2 beta dt}) diag(sigma) w, w ~ N(0, I).
    Langevin {
        /// Velocity decay rate (1/s).
        beta_per_s: f64,
        /// Steady-state RMS velocity (m/s).
        nu_m_per_s: f64,
        /// Per-axis velocity noise factor (m/s).
        sigma_m_per_s: [f64; 3],
    },
    /// Nearly constant velocity with piecewise-constant white acceleration:
    /// Q per axis = a^2 [[dt^4/4, dt^3/2], [dt^3/2, dt^2]].
    ConstantVelocity {
        /// Per-axis acceleration standard deviation (m/s^2).
        accel_std_m_per_s2: [f64; 3],
    },
}

impl<const N: usize> MotionModel<N> {
    /// Number of spatial axes of the state.
    pub const AXES: usize = N / 2;

    /// The model described by the configuration.
    pub fn from_config(cfg: &MotionConfig) -> Result<Self, ConfigError> {
        let m = match cfg.model {
            MotionKind::Langevin => Self::Langevin {
                beta_per_s: cfg.beta_per_s,
                nu_m_per_s: cfg.nu_m_per_s,
                sigma_m_per_s: cfg.sigma_m_per_s,
            },
            MotionKind::ConstantVelocity => Self::ConstantVelocity {
                accel_std_m_per_s2: cfg.accel_std_m_per_s2,
            },
        };
        m.validated()
    }

    /// Checks the state layout and the parameters.
    pub fn validated(self) -> Result<Self, ConfigError> {
        if !N.is_multiple_of(2) || !(2..=6).contains(&N) {
            return Err(ConfigError::new(
                "motion",
                "the state must be [position; velocity] with 1 to 3 axes",
            ));
        }
        let ok = match &self {
            Self::Langevin {
                beta_per_s,
                nu_m_per_s,
                sigma_m_per_s,
            } => {
                beta_per_s.is_finite()
                    && *beta_per_s > 0.0
                    && nu_m_per_s.is_finite()
                    && *nu_m_per_s > 0.0
                    && sigma_m_per_s.iter().all(|s| s.is_finite() && *s >= 0.0)
            }
            Self::ConstantVelocity { accel_std_m_per_s2 } => accel_std_m_per_s2
                .iter()
                .all(|s| s.is_finite() && *s >= 0.0),
        };
        if ok {
            Ok(self)
        } else {
            Err(ConfigError::new(
                "motion",
                "parameters must be finite and non-negative",
            ))
        }
    }

    /// The same model with velocity decay rate `beta_per_s` and velocity noise factors
    /// `sigma_m_per_s` (a Langevin model only; the constant-velocity model has neither and is
    /// returned as it is).
    pub fn with_decay(&self, beta_per_s: f64, sigma_m_per_s: [f64; 3]) -> Self {
        match self {
            Self::Langevin { nu_m_per_s, .. } => Self::Langevin {
                beta_per_s,
                nu_m_per_s: *nu_m_per_s,
                sigma_m_per_s,
            },
            other => other.clone(),
        }
    }

    /// Transition matrix F and process noise Q for a step of `dt` seconds (dt <= 0 gives I, 0).
    pub fn transition(&self, dt: f64) -> (SMatrix<f64, N, N>, SMatrix<f64, N, N>) {
        let d = Self::AXES;
        let mut f = SMatrix::<f64, N, N>::identity();
        let mut q = SMatrix::<f64, N, N>::zeros();
        if !(dt.is_finite() && dt > 0.0) {
            return (f, q);
        }
        match self {
            Self::Langevin {
                beta_per_s,
                nu_m_per_s,
                sigma_m_per_s,
            } => {
                let decay = (-beta_per_s * dt).exp();
                let var = nu_m_per_s * nu_m_per_s * (1.0 - decay * decay);
                for i in 0..d {
                    f[(i, d + i)] = dt;
                    f[(d + i, d + i)] = decay;
                    q[(d + i, d + i)] = var * sigma_m_per_s[i] * sigma_m_per_s[i];
                }
            }
            Self::ConstantVelocity { accel_std_m_per_s2 } => {
                let (dt2, dt3, dt4) = (dt * dt, dt * dt * dt, dt * dt * dt * dt);
                for i in 0..d {
                    let a2 = accel_std_m_per_s2[i] * accel_std_m_per_s2[i];
                    f[(i, d + i)] = dt;
                    q[(i, i)] = a2 * dt4 / 4.0;
                    q[(i, d + i)] = a2 * dt3 / 2.0;
                    q[(d + i, i)] = a2 * dt3 / 2.0;
                    q[(d + i, d + i)] = a2 * dt2;
                }
            }
        }
        (f, q)
    }
}

/// Position part of a state as a 3-D vector (missing axes are 0).
pub fn position_of<const N: usize>(x: &SVector<f64, N>) -> Vec3 {
    let d = N / 2;
    let mut p = Vec3::zeros();
    for i in 0..d.min(3) {
        p[i] = x[i];
    }
    p
}

/// Clamps the position part of a state into `region`.
pub(crate) fn clamp_position<const N: usize>(x: &mut SVector<f64, N>, region: &Aabb) {
    let p = region.clamp(&position_of(x));
    for i in 0..(N / 2).min(3) {
        x[i] = p[i];
    }
}

/// Velocity part of a state as a 3-D vector (missing axes are 0).
pub fn velocity_of<const N: usize>(x: &SVector<f64, N>) -> Vec3 {
    let d = N / 2;
    let mut v = Vec3::zeros();
    for i in 0..d.min(3) {
        v[i] = x[d + i];
    }
    v
}

/// A state from a position and a velocity (extra 3-D axes are dropped).
pub fn state_of<const N: usize>(position: &Vec3, velocity: &Vec3) -> SVector<f64, N> {
    let d = N / 2;
    let mut x = SVector::<f64, N>::zeros();
    for i in 0..d.min(3) {
        x[i] = position[i];
        x[d + i] = velocity[i];
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn langevin_matches_paper_table_iii() {
        // The paper's values (the defaults differ, see `MotionConfig`).
        let paper = MotionConfig {
            beta_per_s: 10.0,
            sigma_m_per_s: [1.2, 1.2, 0.2],
            ..MotionConfig::default()
        };
        let m = MotionModel::<6>::from_config(&paper).unwrap();
        let (f, q) = m.transition(0.128);
        // Spec 003 5.3: e^{-beta phi} = 0.278037, velocity noise variances 1.3287 / 0.0369.
        assert!((f[(3, 3)] - 0.278037).abs() < 1e-6);
        assert!((f[(0, 3)] - 0.128).abs() < 1e-12);
        assert_eq!(f[(3, 0)], 0.0);
        assert!((q[(3, 3)] - 1.3287).abs() < 1e-4);
        assert!((q[(5, 5)] - 0.0369).abs() < 1e-4);
        assert_eq!(q[(0, 0)], 0.0);
        // Position moves with the old velocity.
        let x = state_of::<6>(&Vec3::new(1.0, 2.0, 3.0), &Vec3::new(1.0, 0.0, -1.0));
        let y = f * x;
        assert!((position_of(&y) - Vec3::new(1.128, 2.0, 2.872)).norm() < 1e-12);
    }

    #[test]
    fn constant_velocity_matches_vo_model() {
        let m = MotionModel::<4>::ConstantVelocity {
            accel_std_m_per_s2: [5.0, 5.0, 0.0],
        }
        .validated()
        .unwrap();
        let (f, q) = m.transition(1.0);
        assert_eq!(f[(0, 2)], 1.0);
        assert_eq!(f[(1, 3)], 1.0);
        assert!((q[(0, 0)] - 6.25).abs() < 1e-12);
        assert!((q[(0, 2)] - 12.5).abs() < 1e-12);
        assert!((q[(2, 2)] - 25.0).abs() < 1e-12);
        let (f0, q0) = m.transition(-1.0);
        assert_eq!(f0, SMatrix::<f64, 4, 4>::identity());
        assert_eq!(q0, SMatrix::<f64, 4, 4>::zeros());
        assert!(MotionModel::<5>::from_config(&MotionConfig::default()).is_err());
    }
}
