//! Multi-object tracking: labelled tracks of speakers from audio and camera measurements.
//!
//! The default tracker is the multi-sensor GLMB filter with joint prediction and update (Vo, Vo
//! & Beard 2019; spec 000 3.4-3.7, spec 003 5.9-5.10) over a state `[position; velocity]`, with
//! a Gibbs sampler per parent hypothesis, measurement-driven births, detection probabilities that
//! follow per-track modes (talking or silent; face towards each camera or turned away) and the
//! standard GLMB estimator with a short hysteresis. A GM-PHD filter with label
//! propagation (spec 002) sits behind the same [`Tracker`] trait for comparison.
//!
//! A tracker is a plain struct: no I/O, no clocks, no threads. The caller passes the step time and
//! the scans of the sensors that reported; a sensor absent from a step neither updates nor
//! penalises, while a scan with no measurements is a look that saw nothing.
//!
//! # Where things are
//!
//! - `config`: [`TrackerConfig`], every parameter with its default and the reason for it.
//! - `motion`: Langevin (spec 003 eq. 14-15, F = [[I, dt I], [0, e^{-beta dt} I]]) and constant
//!   velocity over a `[position; velocity]` state of any dimension N (N = 6 in the room, N = 4
//!   in Vo's planar benchmark).
//! - `gait`: each track of a Langevin model stands or walks, an interacting multiple model of
//!   two velocity decays (standing: `beta_per_s`, walking: `walking_beta_per_s`) whose mode
//!   probability the measurements update, for tracks a camera saw lately.
//! - `sensor`: the measurement models ([`SensorModel`], [`sensors_from_layout`]): audio 3-D
//!   candidates, audio azimuth (and elevation) from an array centroid with the azimuth wrapped
//!   in the innovation, the cone angle of a linear array, camera pixels through
//!   `geometry::Camera` (distortion included; undefined behind the camera), generic linear points.
//!   A camera detects a track with its P_D times the probability that the track is in the image
//!   (the predicted pixel's spread against the borders), so a track that drifted just out of
//!   view can take a detection and be corrected.
//!   Measurements are held in a 3-vector; smaller ones are padded with zero innovation, a zero
//!   Jacobian row and unit noise, which changes neither the update nor the distance.
//! - `filter`: KF / EKF (analytic Jacobians, Joseph form) and UKF (alpha, beta, kappa), split into
//!   innovation statistics (enough to gate and score), gain and mean, so the GLMB only pays for
//!   the parts it uses. Covariances are symmetrised and eigenvalue-floored when a Cholesky pivot
//!   fails; non-finite numbers make the update unavailable instead of producing NaN.
//! - `gibbs`, `joint_update`, `glmb`: the MS-GLMB joint prediction-update (see below).
//! - `birth`: fixed birth points and measurement-driven births. A birth is conditioned on the
//!   scans of its step that did not place it (a voice where the camera sees no face starts with
//!   the camera's miss against it), and no birth is seeded from a measurement in the gate of a
//!   track density of weight 0.01 or more (a duplicate label could only share that track's
//!   existence and later take its identity).
//! - `modes`: the per-track detectability modes, two-state Markov chains: the voice (talking or
//!   silent) behind the audio P_D, and per camera the face (towards it or turned away).
//! - `clutter`: each sensor's clutter rate estimated online (the unexplained measurements'
//!   running mean, the configured rate its floor), so a detector noisier than configured does
//!   not breed tracks.
//! - `estimator`: reporting hysteresis and `speaking` smoothing; `gmphd`: the GM-PHD (its label matching uses
//!   `eval::assignment`, the project's one assignment solver).
//!
//! # The GLMB step
//!
//! Candidates are this step's births plus every track density of the posterior, predicted once.
//! For each parent hypothesis, T_h = round(H_upd sqrt(w_h) / sum sqrt(w)) association maps are
//! drawn by Gibbs sampling with the factorised multi-sensor proposal (one P_S or r_B factor in the
//! alive mass, per-sensor rows, exclusions on the fly). Every distinct map is weighted exactly:
//! the sensors that detect a track update it in sequence, the first from statistics cached at the
//! prediction; single-object updates are shared through a table keyed by (candidate, measurement
//! per sensor). Children are merged when identical, normalised in the log domain, pruned and
//! capped. Existence of a label = sum of the weights of the hypotheses holding it; the estimate is
//! the best hypothesis of the MAP cardinality, with a short hysteresis.
//!
//! Two departures from the reference code, both leaving the target distribution unchanged:
//! the Gibbs chain starts with births unborn (the reference starts with every candidate alive,
//! which stores for every parent a negligible child holding every birth), and the occlusion-aware
//! camera P_D (off by default) enters the proposal unoccluded and the exact weight occluded.
//!
//! # Behaviour of the defaults (measured in `tests/track.rs`)
//!
//! - A talking, visible person gets a track at the second step (0.26 s at 128 ms steps): the
//!   first step's detections seed a birth on the camera ray at the depth an audio measurement
//!   picks, confirmed by the next step's measurements.
//! - Camera P_D 0.9 (the paper: 0.99) for a face towards the camera, 0.05 for one turned away,
//!   with a face mode per track and camera (mean 10 s towards, 2 s away): a silent speaker's
//!   existence goes 0.99, 0.95, 0.91 over three frames without the face and stays above 0.6
//!   through 2 s of them, so looking away keeps the label; a speaker gone for good (no face in
//!   view, no voice) is ended within about 3 s. Without the mode the 0.1 of every miss would end
//!   the track within three frames (spec 003 5.12). A camera that sends no frame costs nothing
//!   beyond P_S.
//! - Audio P_D follows the array's voice activity and, per track, a talking/silent Markov mode
//!   (mean talk and pause 2 s): a speaker who pauses 2 s while another talks keeps the label.
//! - P_S is per step (the paper's 0.999 at 128 ms steps). The Langevin model keeps velocity for
//!   about 0.5 s (beta 2/s instead of the paper's 10/s) with velocity noise 0.27 m/s instead of 1.2 (see
//!   `MotionConfig`) while a track stands, and for about 2 s (0.5/s, velocity noise 0.5 m/s)
//!   while it walks: a walker the camera loses for 1.5 s and one array hears is followed
//!   within 0.41 m at the gap's end against 0.60 m with one decay, a stander as closely.
//! - Measurement-driven births start with r_B = 0.01 (the paper's fixed births: 0.005).

mod birth;
mod clutter;
mod config;
mod estimator;
mod filter;
mod gait;
mod gaussian;
mod gibbs;
mod glmb;
mod gmphd;
mod joint_update;
mod modes;
mod motion;
mod occlusion;
mod posterior;
mod scan;
pub mod scenarios;
mod sensor;
mod slice_set;

use nalgebra::Matrix6;

pub(crate) use modes::ModeModel;

pub use birth::BirthTerm;
pub use clutter::ClutterRateReport;
pub use config::{
    AudioDirectionConfig, AudioPositionConfig, BirthConfig, CameraConfig, ClutterConfig,
    ConfigError, EstimatorConfig, FaceConfig, FilterKind, FixedBirth, GlmbConfig, GmphdConfig,
    MotionConfig, MotionKind, TrackerConfig, TrackerKind, UkfConfig, VoiceConfig,
};
pub use gaussian::Gaussian;
pub use glmb::GlmbTracker;
pub use gmphd::GmphdTracker;
pub use motion::{MotionModel, position_of, state_of, velocity_of};
pub use sensor::{Measurement, SensorKey, SensorModel, sensors_from_layout};

use crate::geometry::{Aabb, Vec3};
use crate::label::Label;

/// One tracker step's input.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StepInput {
    /// Step index; labels born in this step are `k.i`. Must increase from step to step (a repeated
    /// or decreasing index is replaced by the previous one plus 1, so labels stay unique).
    pub k: u64,
    /// Time of the estimate (s); the prediction spans dt = t - t_prev.
    pub t: f64,
    /// The scans of the sensors that reported in this step.
    pub scans: Vec<Scan>,
}

/// What one sensor reported in one step.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Scan {
    /// Index into the tracker's sensor list.
    pub sensor: usize,
    /// The measurements; empty means the sensor looked and saw nothing.
    pub measurements: Vec<Measurement>,
    /// Voice activity in [0, 1] for audio sensors (scales their detection probability).
    pub activity: Option<f64>,
    /// Per measurement of an audio sensor: whether it is evidence that its source is speaking
    /// now (a localiser candidate found in the smoothed maps may be only the memory of a talker
    /// who stopped). Empty: every measurement is. Only `speaking` reads it.
    pub sounding: Vec<bool>,
}

/// One reported track.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackEstimate {
    /// The track's identity, never reused.
    pub label: Label,
    /// Position (m).
    pub position: Vec3,
    /// Velocity (m/s).
    pub velocity: Vec3,
    /// Covariance of `[position; velocity]`.
    pub covariance: Matrix6<f64>,
    /// Existence probability: the weight of the hypotheses holding the label.
    pub existence: f64,
    /// Probability that the track produced an audio measurement that sounds now (see
    /// [`Scan::sounding`]), exponentially smoothed.
    pub speaking: f64,
}

/// Counters of input the tracker could not use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TrackerStats {
    /// Steps run.
    pub steps: u64,
    /// Measurements dropped because they held NaN or infinite numbers.
    pub non_finite_measurements: u64,
    /// Measurements dropped because they were not of the kind their sensor measures.
    pub mismatched_measurements: u64,
    /// Measurements dropped beyond the per-scan limit.
    pub excess_measurements: u64,
    /// Scans naming a sensor index outside the sensor list.
    pub unknown_sensor_scans: u64,
    /// Steps whose time or index did not increase (treated as dt = 0 / next index).
    pub non_monotonic_steps: u64,
}

/// A multi-object tracker.
pub trait Tracker: Send {
    /// One tracker step: predict to the step time and update with the scans of the sensors that
    /// reported.
    fn step(&mut self, input: &StepInput) -> Vec<TrackEstimate>;
    /// Replaces the sensor models (live recalibration); tracks are kept.
    fn set_sensors(&mut self, sensors: Vec<SensorModel>) -> Result<(), ConfigError>;
    /// Replaces the clutter-rate estimation settings (a live change); tracks are kept. Turning
    /// the estimate off returns every sensor to its configured rate.
    fn set_clutter(&mut self, cfg: &ClutterConfig);
    /// Forgets every track and starts over (the label counter restarts with the step index).
    fn reset(&mut self);
    /// Counters of input that could not be used.
    fn stats(&self) -> TrackerStats;
    /// Each sensor's clutter rate as configured and as estimated, in sensor order.
    fn clutter_rates(&self) -> Vec<ClutterRateReport>;
}

/// Builds the configured tracker over the 3-D state `[position; velocity]`.
pub fn build_tracker(
    cfg: &TrackerConfig,
    sensors: Vec<SensorModel>,
    region: Option<Aabb>,
    seed: u64,
) -> Result<Box<dyn Tracker>, ConfigError> {
    cfg.validate()?;
    let motion = MotionModel::<6>::from_config(&cfg.motion)?;
    let fixed = birth::fixed_births(&cfg.birth);
    Ok(match cfg.tracker {
        TrackerKind::Glmb => Box::new(GlmbTracker::new(cfg, motion, sensors, region, fixed, seed)?),
        TrackerKind::Gmphd => Box::new(GmphdTracker::new(cfg, motion, sensors, region, fixed)?),
    })
}

/// Covariance of `[position; velocity]` as a 6x6 matrix from a state covariance.
pub(crate) fn covariance6<const N: usize>(p: &nalgebra::SMatrix<f64, N, N>) -> Matrix6<f64> {
    let d = N / 2;
    let map = |i: usize| if i < d { i } else { 3 + i - d };
    let mut out = Matrix6::zeros();
    for i in 0..N {
        for j in 0..N {
            out[(map(i), map(j))] = p[(i, j)];
        }
    }
    out
}
