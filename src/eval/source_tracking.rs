//! Per true source: when it became trackable, how long until a track matched it, and which
//! labels carried it.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::geometry::Layout;
use crate::label::Label;
use crate::scene::TruthSource;

use super::clear_mot::{Match, MotResult};
use super::config::EvalConfig;
use super::track_grid::Grid;

/// Share of a source's active time matched to one label.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LabelShare {
    /// The label.
    pub label: Label,
    /// Fraction of the source's active steps matched to it.
    pub share: f64,
}

/// A track counts as speaking at a step when its `speaking` is at least this.
pub const SPEAKING_THRESHOLD: f64 = 0.5;

/// How well the `speaking` of the track matched to a source (3-D) follows the source's own
/// talk spurts, over the steps at which it is matched.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct SpeakingScore {
    /// Matched steps at which the source talks.
    pub talking_steps: usize,
    /// ... of which its track reads speaking (at least `SPEAKING_THRESHOLD`).
    pub detected: usize,
    /// Matched steps at which the source is silent but its track reads speaking.
    pub false_alarms: usize,
    /// Matched steps at which the source is silent.
    pub silent_steps: usize,
    /// Changes of the read (speaking or not) between consecutive matched steps: what a "who is
    /// speaking" display shows switching for this person (across an identity switch the two
    /// reads are of different tracks, as the display would show them).
    #[serde(default)]
    pub changes: usize,
    /// Changes of the source's own talking between the same pairs of steps.
    #[serde(default)]
    pub true_changes: usize,
}

impl SpeakingScore {
    /// detected / (detected + false alarms); None without any step read as speaking.
    pub fn precision(&self) -> Option<f64> {
        let n = self.detected + self.false_alarms;
        (n > 0).then(|| self.detected as f64 / n as f64)
    }

    /// detected / talking steps; None when the source never talks while matched.
    pub fn recall(&self) -> Option<f64> {
        (self.talking_steps > 0).then(|| self.detected as f64 / self.talking_steps as f64)
    }

    /// changes / true changes: 1 when the read switches only as often as the talker does
    /// (flicker shows as more); None when the talker never switches while matched.
    pub fn change_ratio(&self) -> Option<f64> {
        (self.true_changes > 0).then(|| self.changes as f64 / self.true_changes as f64)
    }

    /// Sum of two scores.
    pub fn add(&self, o: &Self) -> Self {
        Self {
            talking_steps: self.talking_steps + o.talking_steps,
            detected: self.detected + o.detected,
            false_alarms: self.false_alarms + o.false_alarms,
            silent_steps: self.silent_steps + o.silent_steps,
            changes: self.changes + o.changes,
            true_changes: self.true_changes + o.true_changes,
        }
    }
}

/// Tracking of one true source.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SourceTracking {
    /// Source id.
    pub id: String,
    /// Steps at which it is selected (present, or audible).
    pub steps: usize,
    /// Steps at which it is matched in 3-D.
    pub matched_steps: usize,
    /// First step at which it is present, speaking and in some camera's view (present and
    /// speaking when the layout has no camera).
    pub onset_s: Option<f64>,
    /// Time from the onset to its first 3-D match at or after it.
    pub initiation_delay_s: Option<f64>,
    /// Time from the onset to its first azimuth match at or after it.
    pub direction_initiation_delay_s: Option<f64>,
    /// Distinct labels matched to it in 3-D.
    pub labels_matched: usize,
    /// Labels matched in 3-D during its active (speaking) steps, largest share first.
    pub active_labels: Vec<LabelShare>,
    /// Labels matched in azimuth during its active steps, largest share first.
    pub direction_active_labels: Vec<LabelShare>,
    /// Labels carrying at least `continuity_share` of its active steps (3-D); the target is 1.
    pub stream_labels: usize,
    /// Whether its matched track's `speaking` follows its talk spurts.
    pub speaking: SpeakingScore,
}

/// The label matched to source `i` at each step, if any.
fn matched_label(m: &MotResult, i: usize) -> Vec<Option<usize>> {
    m.matches
        .iter()
        .map(|ms: &Vec<Match>| ms.iter().find(|x| x.truth == i).map(|x| x.est))
        .collect()
}

/// Shares of the active steps matched to each label, largest first.
fn active_shares(labels: &[Label], matched: &[Option<usize>], active: &[bool]) -> Vec<LabelShare> {
    let n = active.iter().filter(|a| **a).count();
    let mut counts: BTreeMap<usize, usize> = BTreeMap::new();
    for (m, &a) in matched.iter().zip(active) {
        if let (Some(j), true) = (m, a) {
            *counts.entry(*j).or_default() += 1;
        }
    }
    let mut shares: Vec<LabelShare> = counts
        .into_iter()
        .map(|(j, c)| LabelShare {
            label: labels[j],
            share: c as f64 / n.max(1) as f64,
        })
        .collect();
    shares.sort_by(|a, b| b.share.total_cmp(&a.share).then(a.label.cmp(&b.label)));
    shares
}

/// What the per-source figures are computed from.
pub(crate) struct SourceContext<'a> {
    /// Sensor layout (for camera visibility).
    pub layout: &'a Layout,
    /// The tracks on the step grid.
    pub grid: &'a Grid,
    /// `selected[source][step]`: the truths scored.
    pub selected: &'a [Vec<bool>],
    /// The 3-D matching.
    pub pos: &'a MotResult,
    /// The azimuth matching.
    pub dir: &'a MotResult,
    /// Settings.
    pub cfg: &'a EvalConfig,
}

/// Initiation delay and label usage of source `i` (`s`).
pub(crate) fn source_tracking(ctx: &SourceContext, s: &TruthSource, i: usize) -> SourceTracking {
    let SourceContext {
        layout,
        grid,
        selected,
        pos,
        dir,
        cfg,
    } = *ctx;
    let sel = &selected[i];
    let pos_match = matched_label(pos, i);
    let dir_match = matched_label(dir, i);
    let onset = grid.times.iter().enumerate().position(|(k, &t)| {
        sel[k]
            && s.is_active(t)
            && grid.truth[i][k].is_some_and(|p| {
                layout.cameras.is_empty() || layout.cameras.iter().any(|c| c.in_view(&p))
            })
    });
    let delay = |m: &[Option<usize>]| -> Option<f64> {
        let k0 = onset?;
        let k = (k0..m.len()).find(|&k| m[k].is_some())?;
        Some(grid.times[k] - grid.times[k0])
    };
    let active: Vec<bool> = grid
        .times
        .iter()
        .enumerate()
        .map(|(k, &t)| sel[k] && s.is_active(t))
        .collect();
    let active_labels = active_shares(&grid.labels, &pos_match, &active);
    let mut speaking = SpeakingScore::default();
    // (step, read, talking) at the last matched step.
    let mut last: Option<(usize, bool, bool)> = None;
    for (k, m) in pos_match.iter().enumerate() {
        let Some(j) = *m else { continue };
        let says = grid.speaking[k]
            .get(j)
            .is_some_and(|&v| v >= SPEAKING_THRESHOLD);
        let talks = s.is_active(grid.times[k]);
        if talks {
            speaking.talking_steps += 1;
            speaking.detected += usize::from(says);
        } else {
            speaking.silent_steps += 1;
            speaking.false_alarms += usize::from(says);
        }
        if let Some((k0, said, talked)) = last
            && k0 + 1 == k
        {
            speaking.changes += usize::from(said != says);
            speaking.true_changes += usize::from(talked != talks);
        }
        last = Some((k, says, talks));
    }
    let mut distinct: Vec<usize> = pos_match.iter().flatten().copied().collect();
    distinct.sort_unstable();
    distinct.dedup();
    SourceTracking {
        id: s.id.clone(),
        steps: sel.iter().filter(|b| **b).count(),
        matched_steps: pos_match.iter().flatten().count(),
        onset_s: onset.map(|k| grid.times[k]),
        initiation_delay_s: delay(&pos_match),
        direction_initiation_delay_s: delay(&dir_match),
        labels_matched: distinct.len(),
        stream_labels: active_labels
            .iter()
            .filter(|l| l.share >= cfg.continuity_share)
            .count(),
        active_labels,
        direction_active_labels: active_shares(&grid.labels, &dir_match, &active),
        speaking,
    }
}
