//! Tracks and true positions sampled on the common grid of tracker steps (the lines of
//! `tracks.jsonl`), and the per-step matching frames built from them.

use std::collections::BTreeMap;

use crate::geometry::Vec3;
use crate::label::Label;
use crate::scene::TruthSource;
use crate::scene::format::TracksLine;

use super::clear_mot::MotFrame;
use super::ospa::TrackSamples;

/// The tracks on a common grid of steps.
pub(crate) struct Grid {
    pub times: Vec<f64>,
    pub labels: Vec<Label>,
    /// Per step: (label index, position).
    pub est: Vec<Vec<(usize, Vec3)>>,
    /// Per step and label index: the track's `speaking` (NaN when the label is absent).
    pub speaking: Vec<Vec<f64>>,
    /// Per source, per step: position when present.
    pub truth: Vec<Vec<Option<Vec3>>>,
}

impl Grid {
    pub fn new(lines: &[TracksLine], sources: &[TruthSource]) -> Self {
        let mut index: BTreeMap<Label, usize> = BTreeMap::new();
        for l in lines {
            for tr in &l.tracks {
                index.entry(tr.label).or_insert(0);
            }
        }
        for (k, v) in index.values_mut().enumerate() {
            *v = k;
        }
        let est = lines
            .iter()
            .map(|l| {
                let mut seen = Vec::new();
                l.tracks
                    .iter()
                    .filter_map(|tr| {
                        let k = index[&tr.label];
                        // A label listed twice in one line keeps its first estimate.
                        if seen.contains(&k) {
                            return None;
                        }
                        seen.push(k);
                        Some((k, Vec3::from(tr.position)))
                    })
                    .collect()
            })
            .collect();
        let speaking = lines
            .iter()
            .map(|l| {
                let mut v = vec![f64::NAN; index.len()];
                for tr in l.tracks.iter().rev() {
                    // Reversed, so a label listed twice keeps its first value, as in `est`.
                    v[index[&tr.label]] = tr.speaking;
                }
                v
            })
            .collect();
        let times: Vec<f64> = lines.iter().map(|l| l.t).collect();
        let truth = sources
            .iter()
            .map(|s| times.iter().map(|&t| s.position_at(t)).collect())
            .collect();
        Self {
            times,
            labels: index.into_keys().collect(),
            est,
            speaking,
            truth,
        }
    }

    pub fn est_samples(&self) -> Vec<TrackSamples> {
        let mut out = vec![vec![None; self.times.len()]; self.labels.len()];
        for (k, step) in self.est.iter().enumerate() {
            for &(j, p) in step {
                out[j][k] = Some(p);
            }
        }
        out
    }

    /// MOT frames over the selected truths with distance `dist(truth, estimate)`.
    pub fn frames(
        &self,
        selected: &[Vec<bool>],
        dist: impl Fn(&Vec3, &Vec3) -> f64,
    ) -> Vec<MotFrame> {
        (0..self.times.len())
            .map(|k| {
                let truth: Vec<(usize, Vec3)> = self
                    .truth
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| selected[*i][k])
                    .filter_map(|(i, s)| s[k].map(|p| (i, p)))
                    .collect();
                let est = &self.est[k];
                MotFrame::new(
                    truth.iter().map(|t| t.0).collect(),
                    est.iter().map(|e| e.0).collect(),
                    |i, j| dist(&truth[i].1, &est[j].1),
                )
            })
            .collect()
    }
}
