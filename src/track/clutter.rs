//! Online estimate of each sensor's clutter rate, bootstrapped to the tracker.
//!
//! A sensor's clutter intensity is `kappa(z) = lambda * u(z)`, with `u` the uniform density over
//! its measurement space. The configured `clutter_rate` is a guess that a detector run at a lower
//! threshold, a busier scene or a noisier room can exceed many times over; with lambda too low
//! every false detection near a track scores as a detection of it, so false tracks are born and
//! kept alive by clutter alone (measurements in [`ClutterConfig`]'s doc). The thesis (spec 000 §3.9) bootstraps a clutter estimator to
//! the tracker; this one is the posterior expected clutter count of every scan,
//! `sum_z (1 - r_U(z))` with `r_U(z)` the probability that `z` was assigned to a track, averaged
//! over time. The configured rate stays the floor: a clean sensor keeps the model it was tuned
//! with, and the estimate can only make the tracker more sceptical of lone detections.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::config::ClutterConfig;
use super::scan::SensorScan;
use super::sensor::Sensor;

/// A sensor's clutter rate (expected false measurements per scan), as configured and as
/// estimated online; the model uses the larger.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ClutterRateReport {
    /// The configured `clutter_rate`.
    pub configured: f64,
    /// The running estimate (the configured rate until the sensor has scanned).
    pub estimated: f64,
    /// Scans the estimate has taken in.
    pub scans: u64,
}

/// One sensor's clutter rate: the configured floor and the running estimate, with the log
/// intensity the filters read in their inner loops, kept current by every change.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ClutterRate {
    /// The configured rate (expected false measurements per scan), the floor of the estimate.
    floor: f64,
    /// Running mean of the expected clutter count per scan.
    estimate: f64,
    /// log of the uniform density u(z) over the measurement space.
    log_density: f64,
    /// Scans taken in.
    scans: u64,
    /// log kappa(z) = ln(max(estimate, floor)) + log_density.
    log_intensity: f64,
}

impl ClutterRate {
    /// A rate that starts at the configured value.
    pub fn new(floor: f64, log_density: f64) -> Self {
        let mut c = Self {
            floor,
            estimate: floor,
            log_density,
            scans: 0,
            log_intensity: 0.0,
        };
        c.refresh();
        c
    }

    fn refresh(&mut self) {
        self.log_intensity = self.rate().ln() + self.log_density;
    }

    /// The rate the model uses: the estimate, never below the configured floor.
    pub fn rate(&self) -> f64 {
        self.estimate.max(self.floor)
    }

    /// The configured and estimated rates.
    pub fn report(&self) -> ClutterRateReport {
        ClutterRateReport {
            configured: self.floor,
            estimated: self.estimate,
            scans: self.scans,
        }
    }

    /// log of the clutter intensity kappa(z).
    #[inline]
    pub fn log_intensity(&self) -> f64 {
        self.log_intensity
    }

    /// Takes over another rate's estimate (same sensor, new configuration); keeps this floor.
    fn continue_from(&mut self, old: &ClutterRate) {
        self.estimate = old.estimate;
        self.scans = old.scans;
        self.refresh();
    }

    /// Back to the configured rate, as before any scan.
    fn forget(&mut self) {
        self.estimate = self.floor;
        self.scans = 0;
        self.refresh();
    }

    /// Folds one scan's expected clutter count into the running mean with weight
    /// `1 - exp(-dt / tau)`.
    fn observe(&mut self, count: f64, dt: f64, time_constant_s: f64) {
        if !(count.is_finite() && dt.is_finite() && dt > 0.0) {
            return;
        }
        let alpha = 1.0 - (-dt / time_constant_s).exp();
        self.estimate += alpha * (count - self.estimate);
        self.scans += 1;
        self.refresh();
    }
}

/// The expected number of clutter measurements in a scan, given the probability `r_u[j]` that
/// measurement `j` was assigned to a track.
pub(crate) fn expected_clutter(r_u: &[f64]) -> f64 {
    r_u.iter().map(|r| 1.0 - r.clamp(0.0, 1.0)).sum()
}

/// Updates the clutter rate of every sensor that scanned this step from the step's association
/// probabilities (`r_u[i]` belongs to `scans[i]`), for use from the next step on.
pub(crate) fn observe_step<const N: usize>(
    cfg: &ClutterConfig,
    sensors: &mut [Sensor<N>],
    scans: &[SensorScan],
    r_u: &[Vec<f64>],
    dt: f64,
) {
    if !cfg.estimate {
        return;
    }
    for (scan, r) in scans.iter().zip(r_u) {
        if let Some(sensor) = sensors.get_mut(scan.sensor) {
            sensor
                .clutter
                .observe(expected_clutter(r), dt, cfg.time_constant_s);
        }
    }
}

/// Carries the running estimates over to recompiled sensors (a live recalibration keeps the
/// sensors in order); the floors are the new configuration's.
pub(crate) fn carry_over<const N: usize>(old: &[Sensor<N>], new: &mut [Sensor<N>]) {
    if old.len() != new.len() {
        return;
    }
    for (o, n) in old.iter().zip(new.iter_mut()) {
        n.clutter.continue_from(&o.clutter);
    }
}

/// Applies new estimation settings: the running estimates go on under a new time constant,
/// and are dropped (back to the configured rates) when the estimate is turned off.
pub(crate) fn reconfigure<const N: usize>(
    current: &mut ClutterConfig,
    new: &ClutterConfig,
    sensors: &mut [Sensor<N>],
) {
    if !new.estimate {
        reset(sensors);
    }
    *current = new.clone();
}

/// Forgets the estimates (a tracker reset starts over from the configured rates).
pub(crate) fn reset<const N: usize>(sensors: &mut [Sensor<N>]) {
    for s in sensors {
        s.clutter.forget();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_estimate_follows_the_unexplained_count_and_never_drops_below_the_floor() {
        let mut c = ClutterRate::new(1.0, -(1280.0f64 * 720.0).ln());
        // 30 measurements none of which a track explains, for 20 s of 128 ms steps.
        for _ in 0..156 {
            c.observe(expected_clutter(&[0.0; 30]), 0.128, 2.0);
        }
        assert!((c.rate() - 30.0).abs() < 0.1, "{}", c.rate());
        // Measurements that tracks explain are not clutter: the rate falls back to the floor.
        for _ in 0..156 {
            c.observe(expected_clutter(&[1.0, 0.98]), 0.128, 2.0);
        }
        assert!(c.estimate < 0.1, "{}", c.estimate);
        assert_eq!(c.rate(), 1.0);
        assert!((c.log_intensity() - (1.0f64.ln() + c.log_density)).abs() < 1e-12);
    }

    #[test]
    fn a_bad_step_leaves_the_estimate_alone() {
        let mut c = ClutterRate::new(2.0, 0.0);
        c.observe(f64::NAN, 0.128, 2.0);
        c.observe(10.0, 0.0, 2.0);
        c.observe(10.0, f64::NAN, 2.0);
        assert_eq!((c.estimate, c.scans), (2.0, 0));
    }
}
