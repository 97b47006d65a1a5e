//! Conversions between the stages' own types: localiser output to measurement lines and tracker
//! scans, tracker output to estimates, estimates to separator targets (interpolated in time).

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::geometry::{ArrayShape, Layout, Vec3, deg};
use crate::label::Label;
use crate::localize::{ArrayObservation, DirectionCandidate};
use crate::scene::format::{AudioMeasurementLine, DoaFile, TrackFile};
use crate::scene::{AudioMeasurementFrame, DetectionFrame, FaceBox};
use crate::separate::Target;
use crate::track::{Measurement, Scan, SensorKey, TrackEstimate};

use super::config::{AudioMeasurementSource, LocalizedMeasurements, PipelineConfig};

/// A track estimate as the pipeline passes it on (from the tracker or from the truth).
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// Identity.
    pub label: Label,
    /// Position (m).
    pub position: Vec3,
    /// Velocity (m/s).
    pub velocity: Vec3,
    /// Existence probability.
    pub existence: f64,
    /// Speaking probability.
    pub speaking: f64,
    /// Position covariance (m^2), when known.
    pub covariance: Option<[[f64; 3]; 3]>,
}

impl From<TrackEstimate> for Estimate {
    fn from(e: TrackEstimate) -> Self {
        let c = &e.covariance;
        Self {
            label: e.label,
            position: e.position,
            velocity: e.velocity,
            existence: e.existence,
            speaking: e.speaking,
            covariance: Some(std::array::from_fn(|r| {
                std::array::from_fn(|col| c[(r, col)])
            })),
        }
    }
}

impl Estimate {
    /// The `tracks.jsonl` form.
    pub fn to_file(&self) -> TrackFile {
        TrackFile {
            label: self.label,
            position: self.position.into(),
            velocity: self.velocity.into(),
            existence: self.existence,
            speaking: self.speaking,
            covariance: self.covariance,
        }
    }

    /// Largest position standard deviation (m), 0 when unknown.
    fn position_std(&self) -> f64 {
        self.covariance
            .map_or(0.0, |c| c[0][0].max(c[1][1]).max(c[2][2]).max(0.0).sqrt())
    }
}

/// A track whose position is this uncertain (m) is steered by direction only.
const DIRECTION_ONLY_STD_M: f64 = 1.0;

/// The last two steps' estimates, to give the separator positions at any frame time.
#[derive(Debug, Clone, Default)]
pub struct Timeline {
    prev: Option<(f64, Vec<Estimate>)>,
    cur: Option<(f64, Vec<Estimate>, f64)>,
}

impl Timeline {
    /// Records a step's estimates at time `t` with the step's voice activity.
    pub fn push(&mut self, t: f64, estimates: Vec<Estimate>, activity: f64) {
        self.prev = self.cur.take().map(|(t, e, _)| (t, e));
        self.cur = Some((t, estimates, activity));
    }

    /// Time of the latest step.
    pub fn last_time(&self) -> Option<f64> {
        self.cur.as_ref().map(|c| c.0)
    }

    /// Time of the step before the latest.
    pub fn previous_time(&self) -> Option<f64> {
        self.prev.as_ref().map(|p| p.0)
    }

    /// Separator targets at time `t`: the latest step's labels, positions interpolated between
    /// the last two steps (extrapolated along the velocity for at most one step past the latest).
    pub fn targets_at(&self, t: f64) -> Vec<Target> {
        let Some((t1, cur, activity)) = &self.cur else {
            return Vec::new();
        };
        let prev: BTreeMap<Label, &Estimate> = match &self.prev {
            Some((_, p)) => p.iter().map(|e| (e.label, e)).collect(),
            None => BTreeMap::new(),
        };
        let t0 = self.prev.as_ref().map(|p| p.0);
        cur.iter()
            .map(|e| {
                let position = match (t0, prev.get(&e.label)) {
                    (Some(t0), Some(p)) if t < *t1 && *t1 > t0 => {
                        let a = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
                        p.position + (e.position - p.position) * a
                    }
                    _ => {
                        let ahead = (t - t1).clamp(0.0, t1 - t0.unwrap_or(*t1 - 0.128));
                        e.position + e.velocity * ahead
                    }
                };
                Target {
                    label: e.label,
                    position,
                    direction_only: e.position_std() > DIRECTION_ONLY_STD_M,
                    speaking: e.speaking,
                    activity: *activity,
                    pitch: None,
                }
            })
            .collect()
    }
}

/// The measurement line of one localiser observation (degrees, as in the scene format).
pub fn measurement_line(layout: &Layout, obs: &ArrayObservation, t: f64) -> AudioMeasurementLine {
    AudioMeasurementLine {
        t: t.max(0.0),
        array: layout.arrays[obs.array].id.clone(),
        doas: obs
            .doas
            .iter()
            .map(|d| DoaFile {
                azimuth: deg(d.azimuth),
                elevation: Some(deg(d.elevation)),
                energy: Some(d.power),
            })
            .collect(),
        points: obs.points.iter().map(|p| p.position.into()).collect(),
        activity: Some(obs.activity),
    }
}

/// A tracker sensor's clutter rate (expected false measurements per scan), configured and
/// estimated online.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, ToSchema)]
pub struct SensorClutter {
    /// The sensor: a camera's id, or an array's id with `positions` or `directions`.
    pub sensor: String,
    /// The configured rate, the floor of the one the tracker uses.
    pub configured: f64,
    /// The online estimate.
    pub estimated: f64,
    /// Scans the estimate has taken in (0: the sensor has not reported, e.g. an array whose
    /// directions the tracker takes rather than its positions).
    pub scans: u64,
}

/// Which tracker sensor each input feeds.
#[derive(Debug, Clone)]
pub struct SensorRoutes {
    keys: Vec<SensorKey>,
    positions: Vec<Option<usize>>,
    directions: Vec<Option<usize>>,
    cameras: Vec<Option<usize>>,
    /// Per array: whether the localiser's positions (true) or directions (false) are used.
    localized_positions: Vec<bool>,
    source: AudioMeasurementSource,
    device_seen: Vec<bool>,
    /// (width, height) of every camera's image (px).
    image_sizes: Vec<(f64, f64)>,
}

impl SensorRoutes {
    /// Routes for the tracker's sensors `keys` (in sensor-index order).
    pub fn new(layout: &Layout, cfg: &PipelineConfig, keys: Vec<SensorKey>) -> Self {
        let find = |want: SensorKey| keys.iter().position(|k| *k == want);
        let n = layout.arrays.len();
        Self {
            positions: (0..n).map(|i| find(SensorKey::ArrayPositions(i))).collect(),
            directions: (0..n)
                .map(|i| find(SensorKey::ArrayDirections(i)))
                .collect(),
            cameras: (0..layout.cameras.len())
                .map(|j| find(SensorKey::Camera(j)))
                .collect(),
            localized_positions: layout
                .arrays
                .iter()
                .map(|a| match cfg.localized_measurements {
                    LocalizedMeasurements::Positions => true,
                    LocalizedMeasurements::Directions => false,
                    LocalizedMeasurements::Auto => matches!(a.shape(), ArrayShape::Point),
                })
                .collect(),
            source: cfg.audio_measurements,
            device_seen: vec![false; n],
            image_sizes: layout.cameras.iter().map(|c| (c.width, c.height)).collect(),
            keys,
        }
    }

    /// Per array: whether the tracker takes the localiser's positions (else its directions).
    pub fn localized_positions(&self) -> &[bool] {
        &self.localized_positions
    }

    /// The tracker's sensor keys in index order.
    pub fn keys(&self) -> &[SensorKey] {
        &self.keys
    }

    /// Scans from the localiser's observations, keeping the candidates whose own frame's SRP
    /// reaches `min_fresh` (null standard deviations; 0 keeps every candidate, since a
    /// candidate's own-frame SRP can be below zero).
    pub fn localized(
        &self,
        observations: &[ArrayObservation],
        min_fresh: f64,
        scans: &mut Vec<Scan>,
    ) {
        let keep = |fresh: f64| min_fresh <= 0.0 || fresh >= min_fresh;
        for obs in observations {
            let a = obs.array;
            if self.source == AudioMeasurementSource::Device
                || (self.source == AudioMeasurementSource::Auto
                    && self.device_seen.get(a).copied().unwrap_or(false))
            {
                continue;
            }
            // One pass over the kept candidates gives both their measurements and soundings.
            let (sensor, (measurements, sounding)): (_, (Vec<_>, Vec<_>)) =
                if self.localized_positions[a] {
                    let kept = obs.points.iter().filter(|p| keep(p.fresh));
                    (
                        self.positions[a],
                        kept.map(|p| (Measurement::Position(p.position), p.sounding))
                            .unzip(),
                    )
                } else {
                    let kept = obs.doas.iter().filter(|d| keep(d.fresh));
                    let direction = |d: &DirectionCandidate| Measurement::Direction {
                        azimuth: d.azimuth,
                        elevation: Some(d.elevation),
                    };
                    (
                        self.directions[a],
                        kept.map(|d| (direction(d), d.sounding)).unzip(),
                    )
                };
            if let Some(sensor) = sensor {
                scans.push(Scan {
                    sensor,
                    measurements,
                    activity: Some(obs.activity),
                    sounding,
                });
            }
        }
    }

    /// Scans from device-side measurements (the latest frame of each array in the step).
    pub fn devices(&mut self, frames: &[AudioMeasurementFrame], scans: &mut Vec<Scan>) {
        if self.source == AudioMeasurementSource::Localize {
            return;
        }
        let mut latest: BTreeMap<usize, &AudioMeasurementFrame> = BTreeMap::new();
        for f in frames {
            latest.insert(f.array, f);
        }
        for (a, f) in latest {
            self.device_seen[a] = true;
            if !f.doas.is_empty()
                && let Some(sensor) = self.directions[a]
            {
                let measurements = f
                    .doas
                    .iter()
                    .map(|d| Measurement::Direction {
                        azimuth: d.azimuth,
                        elevation: d.elevation,
                    })
                    .collect();
                scans.push(Scan {
                    sensor,
                    measurements,
                    activity: f.activity,
                    sounding: Vec::new(),
                });
            }
            if !f.points.is_empty()
                && let Some(sensor) = self.positions[a]
            {
                let measurements = f.points.iter().map(|p| Measurement::Position(*p)).collect();
                scans.push(Scan {
                    sensor,
                    measurements,
                    activity: f.activity,
                    sounding: Vec::new(),
                });
            }
        }
    }

    /// Scans from camera frames (one frame per camera).
    pub fn cameras(&self, frames: &[(usize, DetectionFrame)], scans: &mut Vec<Scan>) {
        for (j, f) in frames {
            if let Some(sensor) = self.cameras.get(*j).copied().flatten() {
                let image = self.image_sizes.get(*j).copied();
                let measurements = f
                    .boxes
                    .iter()
                    .map(|b| Measurement::Face {
                        point: b.measurement_point(),
                        size_px: face_size_px(b, image),
                    })
                    .collect();
                scans.push(Scan {
                    sensor,
                    measurements,
                    activity: None,
                    sounding: Vec::new(),
                });
            }
        }
    }
}

/// Width over height of a face box, used to recover the size of a box cut by the image border.
const FACE_ASPECT: f64 = 0.16 / 0.22;

/// Apparent size sqrt(w h) of a face box (px). A box cut by the image border keeps its full
/// extent across the cut, from which the size follows with the usual aspect ratio.
fn face_size_px(b: &FaceBox, image: Option<(f64, f64)>) -> f64 {
    const EDGE_PX: f64 = 1.0;
    let (cut_x, cut_y) = match image {
        Some((w, h)) => (
            b.x <= EDGE_PX || b.x + b.w >= w - EDGE_PX,
            b.y <= EDGE_PX || b.y + b.h >= h - EDGE_PX,
        ),
        None => (false, false),
    };
    let from_height = b.h * FACE_ASPECT.sqrt();
    let from_width = b.w / FACE_ASPECT.sqrt();
    match (cut_x, cut_y) {
        (false, false) => (b.w * b.h).sqrt(),
        (true, false) => from_height,
        (false, true) => from_width,
        (true, true) => from_height.max(from_width),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::localize::DirectionCandidate;

    fn doa(azimuth_deg: f64, fresh: f64) -> DirectionCandidate {
        let a = azimuth_deg.to_radians();
        DirectionCandidate {
            direction: Vec3::new(a.cos(), a.sin(), 0.0),
            azimuth: a,
            elevation: 0.0,
            power: 0.3,
            fresh,
            sounding: fresh >= 5.0,
        }
    }

    #[test]
    fn the_smoothings_memory_of_a_talker_who_stopped_is_kept_from_the_tracker_when_asked() {
        let layout = crate::protocol::inbound::tests::layout();
        let mut cfg = PipelineConfig {
            localized_measurements: LocalizedMeasurements::Directions,
            ..PipelineConfig::default()
        };
        let obs = [ArrayObservation {
            array: 0,
            // A talker now, one who stopped a second ago, and a candidate below the null.
            doas: vec![doa(30.0, 19.0), doa(135.0, 1.5), doa(-90.0, -0.7)],
            points: Vec::new(),
            activity: 0.9,
        }];
        let azimuths = |cfg: &PipelineConfig| -> Vec<f64> {
            let routes = SensorRoutes::new(&layout, cfg, vec![SensorKey::ArrayDirections(0)]);
            let mut scans = Vec::new();
            routes.localized(&obs, cfg.localized_min_fresh_sigmas, &mut scans);
            assert_eq!(scans.len(), 1);
            assert_eq!(scans[0].sounding.len(), scans[0].measurements.len());
            scans[0]
                .measurements
                .iter()
                .map(|m| match m {
                    Measurement::Direction { azimuth, .. } => azimuth.to_degrees().round(),
                    other => panic!("{other:?}"),
                })
                .collect()
        };
        // By default only what sounds in this frame; 0 takes every candidate, memory and all.
        assert_eq!(azimuths(&cfg), vec![30.0]);
        cfg.localized_min_fresh_sigmas = 0.0;
        assert_eq!(azimuths(&cfg), vec![30.0, 135.0, -90.0]);
        cfg.localized_min_fresh_sigmas = -1.0;
        assert_eq!(
            cfg.validate().unwrap_err().field,
            "localized_min_fresh_sigmas"
        );
    }
}
