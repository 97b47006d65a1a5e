//! Scores of the localiser's output (`measurements.jsonl`) per array: OSPA of the 3-D candidates
//! against the sources active in each frame (the paper's Table VI), and the azimuth error of the
//! direction candidates.
//!
//! A source is active in a frame when it speaks during at least `active_fraction` (default half)
//! of the frame's span and is present at the span's centre, where its position is taken. The span
//! is `[t, t + frame)` by default (`measurement_anchor = "start"`, the convention of the pipeline's
//! framing) or centred on `t`.

use serde::{Deserialize, Serialize};

use crate::geometry::{Vec3, angle_diff, azimuth_of, deg, rad};
use crate::scene::{AudioMeasurementFrame, Doa, Scene, TruthSource};

use super::config::{EvalConfig, FrameAnchor};
use super::ospa::{OspaParams, OspaValue, mean_ospa, ospa};
use super::stats::Summary;

/// Frame length used when an array has a single measurement line and none is configured (the
/// seed paper's 128 ms frame).
const FALLBACK_FRAME_S: f64 = 0.128;

/// Localiser scores of every array that produced measurements.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeasurementsReport {
    /// One entry per array, in layout order.
    pub arrays: Vec<ArrayMeasurements>,
}

/// Localiser scores of one array.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArrayMeasurements {
    /// Array id.
    pub array: String,
    /// Measurement lines of this array.
    pub frames: usize,
    /// Frame length used to decide which sources are active (s).
    pub frame_s: f64,
    /// Mean number of active sources per frame.
    pub mean_active_sources: f64,
    /// 3-D candidates, when the array produced any.
    pub points: Option<PointScores>,
    /// Direction candidates, when the array produced any.
    pub doas: Option<DoaScores>,
}

/// OSPA of the 3-D candidate sets.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PointScores {
    /// Mean number of candidates per frame.
    pub mean_candidates: f64,
    /// Mean over frames of the OSPA (m) against the active sources' positions.
    pub ospa: OspaValue,
}

/// Azimuth accuracy of the direction candidates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DoaScores {
    /// Number of (frame, active source) pairs.
    pub pairs: usize,
    /// Pairs whose frame has no direction candidate at all.
    pub missed: usize,
    /// Fraction of the pairs whose nearest candidate is within the tolerance.
    pub within_tolerance: Option<f64>,
    /// Azimuth error (deg) of the nearest candidate, over pairs with a candidate.
    pub error_deg: Summary,
    /// Number of candidates.
    pub candidates: usize,
    /// Fraction of the candidates farther than the tolerance from every active source.
    pub false_candidate_rate: Option<f64>,
    /// The tolerance (deg).
    pub tolerance_deg: f64,
}

/// Median spacing of consecutive frame times, when there are at least two distinct times.
fn inferred_frame(times: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = times
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 1e-9)
        .collect();
    if d.is_empty() {
        return None;
    }
    d.sort_by(f64::total_cmp);
    Some(d[d.len() / 2])
}

/// The active sources of a frame at `t` with their positions at the span's centre.
fn active_sources<'a>(
    sources: &'a [TruthSource],
    t: f64,
    frame_s: f64,
    cfg: &EvalConfig,
) -> Vec<(&'a TruthSource, Vec3)> {
    let start = match cfg.measurement_anchor {
        FrameAnchor::Start => t,
        FrameAnchor::Centre => t - 0.5 * frame_s,
    };
    let mid = start + 0.5 * frame_s;
    sources
        .iter()
        .filter(|s| s.active_fraction(start, start + frame_s) >= cfg.active_fraction)
        .filter_map(|s| s.position_at(mid).map(|p| (s, p)))
        .collect()
}

/// Running counts of the direction candidates of one array.
#[derive(Default)]
struct DoaTally {
    pairs: usize,
    missed: usize,
    hits: usize,
    errors_deg: Vec<f64>,
    candidates: usize,
    false_candidates: usize,
}

impl DoaTally {
    /// Adds one frame: its candidates and the azimuths of its active sources (rad).
    fn add(&mut self, doas: &[Doa], truth_az: &[f64], tol: f64) {
        for &az in truth_az {
            self.pairs += 1;
            let nearest = doas
                .iter()
                .map(|d| angle_diff(d.azimuth, az).abs())
                .min_by(f64::total_cmp);
            match nearest {
                Some(e) => {
                    self.errors_deg.push(deg(e));
                    if e <= tol {
                        self.hits += 1;
                    }
                }
                None => self.missed += 1,
            }
        }
        self.candidates += doas.len();
        self.false_candidates += doas
            .iter()
            .filter(|d| {
                !truth_az
                    .iter()
                    .any(|&az| angle_diff(d.azimuth, az).abs() <= tol)
            })
            .count();
    }

    fn finish(self, tolerance_deg: f64) -> DoaScores {
        DoaScores {
            pairs: self.pairs,
            missed: self.missed,
            within_tolerance: (self.pairs > 0).then(|| self.hits as f64 / self.pairs as f64),
            error_deg: Summary::of(&self.errors_deg),
            candidates: self.candidates,
            false_candidate_rate: (self.candidates > 0)
                .then(|| self.false_candidates as f64 / self.candidates as f64),
            tolerance_deg,
        }
    }
}

/// Scores the measurements of every array against the truth.
pub fn score_measurements(
    scene: &Scene,
    sources: &[TruthSource],
    frames: &[AudioMeasurementFrame],
    cfg: &EvalConfig,
) -> MeasurementsReport {
    let params = OspaParams::new(cfg.ospa_cutoff_m, cfg.ospa_order);
    let tol = rad(cfg.doa_tolerance_deg);
    let mut arrays = Vec::new();
    for (ai, array) in scene.layout.arrays.iter().enumerate() {
        let mine: Vec<&AudioMeasurementFrame> = frames.iter().filter(|f| f.array == ai).collect();
        if mine.is_empty() {
            continue;
        }
        let times: Vec<f64> = mine.iter().map(|f| f.t).collect();
        let frame_s = cfg
            .measurement_frame_s
            .or_else(|| inferred_frame(&times))
            .unwrap_or(FALLBACK_FRAME_S);
        let centroid = array.centroid();
        let has_points = mine.iter().any(|f| !f.points.is_empty());
        let has_doas = mine.iter().any(|f| !f.doas.is_empty());
        let mut ospas = Vec::new();
        let mut n_points = 0usize;
        let mut n_active = 0usize;
        let mut doas = DoaTally::default();
        for f in &mine {
            let active = active_sources(sources, f.t, frame_s, cfg);
            n_active += active.len();
            if has_points {
                let truth: Vec<Vec3> = active.iter().map(|(_, p)| *p).collect();
                ospas.push(ospa(&f.points, &truth, params));
                n_points += f.points.len();
            }
            if has_doas {
                let truth_az: Vec<f64> = active
                    .iter()
                    .map(|(_, p)| azimuth_of(&(p - centroid)))
                    .collect();
                doas.add(&f.doas, &truth_az, tol);
            }
        }
        let n = mine.len() as f64;
        arrays.push(ArrayMeasurements {
            array: array.id.clone(),
            frames: mine.len(),
            frame_s,
            mean_active_sources: n_active as f64 / n,
            points: has_points.then(|| PointScores {
                mean_candidates: n_points as f64 / n,
                ospa: mean_ospa(&ospas),
            }),
            doas: has_doas.then(|| doas.finish(cfg.doa_tolerance_deg)),
        });
    }
    MeasurementsReport { arrays }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_length_is_the_median_spacing() {
        assert_eq!(
            inferred_frame(&[0.0, 0.128, 0.256, 0.384, 1.0]),
            Some(0.128)
        );
        assert_eq!(inferred_frame(&[0.5]), None);
    }

    #[test]
    fn a_source_is_active_when_it_speaks_most_of_the_frame() {
        let s = TruthSource {
            id: "s".into(),
            signal: None,
            trajectory: vec![(0.0, Vec3::zeros()), (10.0, Vec3::zeros())],
            active: vec![(1.0, 2.0)],
        };
        let cfg = EvalConfig::default();
        let srcs = [s];
        // [0.9, 1.1): half the frame -> active; [0.95, 1.15) -> 75 %; [0.8, 1.0) -> not.
        assert_eq!(active_sources(&srcs, 0.9, 0.2, &cfg).len(), 1);
        assert_eq!(active_sources(&srcs, 0.8, 0.2, &cfg).len(), 0);
        assert_eq!(active_sources(&srcs, 1.95, 0.2, &cfg).len(), 0);
        let centred = EvalConfig {
            measurement_anchor: FrameAnchor::Centre,
            ..Default::default()
        };
        // Centred at 1.0: [0.9, 1.1) -> active.
        assert_eq!(active_sources(&srcs, 1.0, 0.2, &centred).len(), 1);
    }
}
