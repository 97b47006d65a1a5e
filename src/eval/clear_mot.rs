//! CLEAR MOT (Bernardin & Stiefelhagen 2008) with a distance gate: MOTA, MOTP, misses, false
//! positives, identity switches, fragmentations and MT/PT/ML.
//!
//! The distance is whatever the caller puts in the frames (metres in 3-D, radians of azimuth,
//! pixels), so the same code scores every space.

use std::collections::BTreeMap;

use super::assignment::{CostMatrix, assign};

/// One time step: the ids of the true objects and of the estimates present, and their distances
/// (`truth.len() x est.len()`).
#[derive(Debug, Clone, PartialEq)]
pub struct MotFrame {
    /// Ids of the true objects present (distinct).
    pub truth: Vec<usize>,
    /// Ids of the estimated tracks present (distinct).
    pub est: Vec<usize>,
    /// `dist.at(i, j)` is the distance between `truth[i]` and `est[j]`.
    pub dist: CostMatrix,
}

impl MotFrame {
    /// A frame of objects and estimates on a line, `(id, x)` each: the metrics' test cases.
    #[cfg(test)]
    pub(crate) fn on_a_line(truth: &[(usize, f64)], est: &[(usize, f64)]) -> Self {
        Self::new(
            truth.iter().map(|p| p.0).collect(),
            est.iter().map(|p| p.0).collect(),
            |i, j| (truth[i].1 - est[j].1).abs(),
        )
    }

    /// A frame whose distances come from `dist(truth_index, est_index)`.
    pub fn new(truth: Vec<usize>, est: Vec<usize>, dist: impl FnMut(usize, usize) -> f64) -> Self {
        let d = CostMatrix::from_fn(truth.len(), est.len(), dist);
        Self {
            truth,
            est,
            dist: d,
        }
    }
}

/// Dense indices, in order of first appearance, of the ids in `ids` (the true objects' or the
/// estimates' ids over a sequence of frames).
pub(crate) fn dense_ids(ids: impl Iterator<Item = usize>) -> BTreeMap<usize, usize> {
    let mut map = BTreeMap::new();
    for id in ids {
        let n = map.len();
        map.entry(id).or_insert(n);
    }
    map
}

/// A correspondence between a true object and an estimate in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Match {
    /// True object id.
    pub truth: usize,
    /// Estimate id.
    pub est: usize,
    /// Their distance (at most the gate).
    pub dist: f64,
}

/// CLEAR MOT counts over a sequence of frames.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MotResult {
    /// The correspondences of every frame.
    pub matches: Vec<Vec<Match>>,
    /// Number of (frame, true object) pairs.
    pub truth_count: usize,
    /// Number of (frame, estimate) pairs.
    pub est_count: usize,
    /// Missed true objects (FN).
    pub misses: usize,
    /// Unmatched estimates (FP).
    pub false_positives: usize,
    /// Identity switches: a true object matched to an estimate other than its last one.
    pub switches: usize,
    /// Interruptions of a true object's matched span (matched segments minus one, summed).
    pub fragmentations: usize,
    /// True objects matched in at least 80 % of the frames they are present in.
    pub mostly_tracked: usize,
    /// True objects matched in 20 % to 80 % of their frames.
    pub partially_tracked: usize,
    /// True objects matched in less than 20 % of their frames.
    pub mostly_lost: usize,
    /// Sum of the matched distances.
    pub distance_sum: f64,
}

impl MotResult {
    /// Number of correspondences.
    pub fn match_count(&self) -> usize {
        self.matches.iter().map(Vec::len).sum()
    }

    /// MOTA = 1 - (FN + FP + IDSW) / GT; `None` without any true object.
    pub fn mota(&self) -> Option<f64> {
        (self.truth_count > 0).then(|| {
            1.0 - (self.misses + self.false_positives + self.switches) as f64
                / self.truth_count as f64
        })
    }

    /// MOTP: mean distance of the correspondences; `None` without any.
    pub fn motp(&self) -> Option<f64> {
        let n = self.match_count();
        (n > 0).then(|| self.distance_sum / n as f64)
    }
}

fn valid(d: f64, gate: f64) -> bool {
    d.is_finite() && d <= gate
}

/// The previous frame's correspondences still present and within the gate, marking their
/// objects and estimates used.
fn keep_previous(
    f: &MotFrame,
    prev: &[Match],
    gate: f64,
    truth_used: &mut [bool],
    est_used: &mut [bool],
) -> Vec<Match> {
    let mut kept = Vec::new();
    for m in prev {
        let i = f.truth.iter().position(|&t| t == m.truth);
        let j = f.est.iter().position(|&e| e == m.est);
        if let (Some(i), Some(j)) = (i, j) {
            let d = f.dist.at(i, j);
            if valid(d, gate) {
                truth_used[i] = true;
                est_used[j] = true;
                kept.push(Match {
                    truth: m.truth,
                    est: m.est,
                    dist: d,
                });
            }
        }
    }
    kept
}

/// Matches among the objects and estimates not yet used: most gated pairs first, then the least
/// total distance; marks the matched ones used.
fn match_free(
    f: &MotFrame,
    gate: f64,
    truth_used: &mut [bool],
    est_used: &mut [bool],
) -> Vec<Match> {
    let free_t: Vec<usize> = (0..truth_used.len()).filter(|&i| !truth_used[i]).collect();
    let free_e: Vec<usize> = (0..est_used.len()).filter(|&j| !est_used[j]).collect();
    // A forbidden pair costs more than any set of allowed ones, so the assignment first
    // maximises the number of gated matches and then minimises their total distance.
    let forbidden = gate.abs() * (free_t.len().min(free_e.len()) as f64 + 1.0) + 1.0;
    let costs = CostMatrix::from_fn(free_t.len(), free_e.len(), |a, b| {
        let d = f.dist.at(free_t[a], free_e[b]);
        if valid(d, gate) { d } else { forbidden }
    });
    let mut found = Vec::new();
    for (a, b) in assign(&costs).pairs {
        let (i, j) = (free_t[a], free_e[b]);
        let d = f.dist.at(i, j);
        if !valid(d, gate) {
            continue;
        }
        truth_used[i] = true;
        est_used[j] = true;
        found.push(Match {
            truth: f.truth[i],
            est: f.est[j],
            dist: d,
        });
    }
    found
}

/// Scores `frames` with distance gate `gate`: previous-frame correspondences that are still
/// within the gate are kept, the rest are matched by minimum total distance among the pairs
/// within the gate (most matches first), and a new match of an object to an estimate other than
/// the one it was last matched to is one identity switch.
pub fn clear_mot(frames: &[MotFrame], gate: f64) -> MotResult {
    let mut r = MotResult::default();
    let mut last_match: BTreeMap<usize, usize> = BTreeMap::new();
    let mut prev: Vec<Match> = Vec::new();
    // Per object: frames present, frames matched, matched segments, matched in previous frame.
    let mut present: BTreeMap<usize, (usize, usize, usize, bool)> = BTreeMap::new();
    for f in frames {
        let (nt, ne) = (f.truth.len(), f.est.len());
        let mut truth_used = vec![false; nt];
        let mut est_used = vec![false; ne];
        let mut matches = keep_previous(f, &prev, gate, &mut truth_used, &mut est_used);
        for m in match_free(f, gate, &mut truth_used, &mut est_used) {
            if last_match.get(&m.truth).is_some_and(|&old| old != m.est) {
                r.switches += 1;
            }
            matches.push(m);
        }
        for m in &matches {
            last_match.insert(m.truth, m.est);
            r.distance_sum += m.dist;
        }
        r.truth_count += nt;
        r.est_count += ne;
        r.misses += truth_used.iter().filter(|u| !**u).count();
        r.false_positives += est_used.iter().filter(|u| !**u).count();
        for (i, &o) in f.truth.iter().enumerate() {
            let e = present.entry(o).or_insert((0, 0, 0, false));
            e.0 += 1;
            if truth_used[i] {
                e.1 += 1;
            }
        }
        for (o, e) in present.iter_mut() {
            let matched_now = matches.iter().any(|m| m.truth == *o);
            if matched_now && !e.3 {
                e.2 += 1;
            }
            e.3 = matched_now;
        }
        matches.sort_by_key(|m| (m.truth, m.est));
        prev = matches.clone();
        r.matches.push(matches);
    }
    for &(frames_present, matched, segments, _) in present.values() {
        r.fragmentations += segments.saturating_sub(1);
        let ratio = matched as f64 / frames_present.max(1) as f64;
        if ratio >= 0.8 {
            r.mostly_tracked += 1;
        } else if ratio >= 0.2 {
            r.partially_tracked += 1;
        } else {
            r.mostly_lost += 1;
        }
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Objects of one frame on a line: `(id, x)`.
    type Objects<'a> = &'a [(usize, f64)];

    /// Frames of 1-D positions: `(truth id, x)` and `(est id, x)`.
    fn frames(steps: &[(Objects, Objects)]) -> Vec<MotFrame> {
        steps
            .iter()
            .map(|(t, e)| MotFrame::on_a_line(t, e))
            .collect()
    }

    #[test]
    fn perfect_tracking() {
        let f = frames(&[
            (&[(0, 0.0), (1, 5.0)], &[(7, 0.1), (8, 5.1)]),
            (&[(0, 0.0), (1, 5.0)], &[(7, 0.1), (8, 5.1)]),
        ]);
        let r = clear_mot(&f, 0.5);
        assert_eq!(r.mota(), Some(1.0));
        assert!((r.motp().unwrap() - 0.1).abs() < 1e-12);
        assert_eq!((r.switches, r.misses, r.false_positives), (0, 0, 0));
        assert_eq!(r.mostly_tracked, 2);
    }

    #[test]
    fn counts_misses_false_positives_and_a_switch() {
        // Frame 0: truth 0 tracked by 7. Frame 1: 7 gone, 9 takes over (a switch), and a false
        // track 8 far away. Frame 2: truth missed. Frame 3: tracked by 9 again (no new switch,
        // one fragmentation).
        let f = frames(&[
            (&[(0, 0.0)], &[(7, 0.0)]),
            (&[(0, 0.0)], &[(9, 0.2), (8, 3.0)]),
            (&[(0, 0.0)], &[]),
            (&[(0, 0.0)], &[(9, 0.1)]),
        ]);
        let r = clear_mot(&f, 0.5);
        assert_eq!(r.switches, 1);
        assert_eq!(r.misses, 1);
        assert_eq!(r.false_positives, 1);
        assert_eq!(r.fragmentations, 1);
        assert_eq!(r.truth_count, 4);
        assert!((r.mota().unwrap() - (1.0 - 3.0 / 4.0)).abs() < 1e-12);
        assert!((r.motp().unwrap() - 0.1).abs() < 1e-12);
        assert_eq!(r.partially_tracked, 1);
    }

    #[test]
    fn keeps_previous_correspondence_while_within_the_gate() {
        // Estimate 7 follows truth 0; at frame 1 estimate 8 is closer, but 7 is still within the
        // gate, so the correspondence is kept and 8 is a false positive, not a switch.
        let f = frames(&[
            (&[(0, 0.0)], &[(7, 0.1)]),
            (&[(0, 0.0)], &[(7, 0.4), (8, 0.0)]),
        ]);
        let r = clear_mot(&f, 0.5);
        assert_eq!(r.switches, 0);
        assert_eq!(r.false_positives, 1);
        assert_eq!(r.matches[1][0].est, 7);
    }

    #[test]
    fn a_crossing_counts_two_switches_when_labels_swap() {
        let f = frames(&[
            (&[(0, 0.0), (1, 2.0)], &[(7, 0.0), (8, 2.0)]),
            (&[(0, 0.0), (1, 2.0)], &[(7, 2.0), (8, 0.0)]),
        ]);
        let r = clear_mot(&f, 0.5);
        assert_eq!(r.switches, 2);
        assert_eq!(r.mota(), Some(0.5));
    }

    #[test]
    fn maximises_matches_before_distance() {
        // Greedy nearest would pair truth 0 with estimate 8 (0.1) and leave truth 1 unmatched;
        // the gated assignment matches both.
        let f = frames(&[(&[(0, 0.0), (1, 0.45)], &[(7, -0.4), (8, 0.1)])]);
        let r = clear_mot(&f, 0.5);
        assert_eq!(r.match_count(), 2);
        assert_eq!(r.misses, 0);
    }
}
