//! A step's input made safe: scans validated and grouped per sensor, and the step clock.

use nalgebra::Vector3;

use super::sensor::{Rejection, Sensor};
use super::{StepInput, TrackerStats};

/// Most measurements used from one sensor in one step (the rest are dropped and counted).
pub(crate) const MAX_MEASUREMENTS: usize = 2048;

/// The usable measurements of one sensor in one step.
#[derive(Debug, Clone)]
pub(crate) struct SensorScan {
    /// Index of the sensor.
    pub sensor: usize,
    /// Measurements in the sensor's padded form.
    pub z: Vec<Vector3<f64>>,
    /// Voice activity, if reported.
    pub activity: Option<f64>,
    /// Per measurement in `z`: whether it is evidence of speech now (see [`super::Scan`]).
    pub sounding: Vec<bool>,
}

/// Validates the scans of a step: drops (and counts) non-finite or mismatched measurements and
/// scans of unknown sensors, and merges several scans of one sensor. Sorted by sensor index.
pub(crate) fn collect<const N: usize>(
    input: &StepInput,
    sensors: &[Sensor<N>],
    stats: &mut TrackerStats,
) -> Vec<SensorScan> {
    let mut out: Vec<SensorScan> = Vec::new();
    for scan in &input.scans {
        let Some(sensor) = sensors.get(scan.sensor) else {
            stats.unknown_sensor_scans += 1;
            continue;
        };
        let pos = match out.iter().position(|s| s.sensor == scan.sensor) {
            Some(p) => p,
            None => {
                out.push(SensorScan {
                    sensor: scan.sensor,
                    z: Vec::new(),
                    activity: None,
                    sounding: Vec::new(),
                });
                out.len() - 1
            }
        };
        let entry = &mut out[pos];
        if let Some(a) = scan.activity.filter(|a| a.is_finite()) {
            let a = a.clamp(0.0, 1.0);
            entry.activity = Some(entry.activity.map_or(a, |b: f64| b.max(a)));
        }
        for (i, m) in scan.measurements.iter().enumerate() {
            match sensor.convert(m) {
                Ok(z) if entry.z.len() < MAX_MEASUREMENTS => {
                    entry.z.push(z);
                    entry
                        .sounding
                        .push(scan.sounding.get(i).copied().unwrap_or(true));
                }
                Ok(_) => stats.excess_measurements += 1,
                Err(Rejection::NonFinite) => stats.non_finite_measurements += 1,
                Err(Rejection::WrongKind) => stats.mismatched_measurements += 1,
            }
        }
    }
    out.sort_by_key(|s| s.sensor);
    out
}

/// Step index and time bookkeeping.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct StepClock {
    t_prev: Option<f64>,
    k_prev: Option<u64>,
}

impl StepClock {
    /// The effective step index (strictly increasing) and the prediction interval dt >= 0.
    pub fn advance(&mut self, input: &StepInput, stats: &mut TrackerStats) -> (u64, f64) {
        let mut anomaly = false;
        let k = match self.k_prev {
            Some(p) if input.k <= p => {
                anomaly = true;
                p + 1
            }
            _ => input.k,
        };
        let dt = match (self.t_prev, input.t.is_finite()) {
            (Some(p), true) if input.t >= p => input.t - p,
            (None, true) => 0.0,
            _ => {
                anomaly = true;
                0.0
            }
        };
        if input.t.is_finite() {
            self.t_prev = Some(self.t_prev.map_or(input.t, |p| p.max(input.t)));
        }
        self.k_prev = Some(k);
        stats.steps += 1;
        if anomaly {
            stats.non_monotonic_steps += 1;
        }
        (k, dt)
    }
}
