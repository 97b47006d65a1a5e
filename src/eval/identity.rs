//! Identity scores IDF1, IDP, IDR (Ristani et al. 2016): one global minimum-cost bipartite
//! matching between true and estimated trajectories.
//!
//! With the usual cost (a pair costs the frames where exactly one of them is present or they are
//! farther apart than the gate, an unmatched trajectory costs all its frames), the total cost is
//! `|truth frames| + |estimate frames| - 2 IDTP`, so the optimal matching is the one that
//! maximises the summed identity true positives; that is what is solved here.

use std::collections::BTreeMap;

use super::assignment::{CostMatrix, assign};
use super::clear_mot::{MotFrame, dense_ids};

/// Identity scores.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct IdentityScores {
    /// Frames where a true object is matched to its assigned estimate within the gate.
    pub idtp: usize,
    /// Estimate frames not covered by IDTP.
    pub idfp: usize,
    /// Truth frames not covered by IDTP.
    pub idfn: usize,
    /// The trajectory matching `(truth id, estimate id)` (pairs sharing at least one frame).
    pub pairs: Vec<(usize, usize)>,
}

impl IdentityScores {
    /// IDF1 = 2 IDTP / (2 IDTP + IDFP + IDFN); `None` when there is nothing at all.
    pub fn idf1(&self) -> Option<f64> {
        ratio(2 * self.idtp, 2 * self.idtp + self.idfp + self.idfn)
    }

    /// IDP = IDTP / (IDTP + IDFP).
    pub fn idp(&self) -> Option<f64> {
        ratio(self.idtp, self.idtp + self.idfp)
    }

    /// IDR = IDTP / (IDTP + IDFN).
    pub fn idr(&self) -> Option<f64> {
        ratio(self.idtp, self.idtp + self.idfn)
    }
}

fn ratio(a: usize, b: usize) -> Option<f64> {
    (b > 0).then(|| a as f64 / b as f64)
}

/// Identity scores of `frames` with distance gate `gate`.
pub fn identity_scores(frames: &[MotFrame], gate: f64) -> IdentityScores {
    let truth_ids = dense_ids(frames.iter().flat_map(|f| f.truth.iter().copied()));
    let est_ids = dense_ids(frames.iter().flat_map(|f| f.est.iter().copied()));
    let truth_total: usize = frames.iter().map(|f| f.truth.len()).sum();
    let est_total: usize = frames.iter().map(|f| f.est.len()).sum();
    let (nt, ne) = (truth_ids.len(), est_ids.len());
    let mut shared = vec![0usize; nt * ne];
    for f in frames {
        for (i, t) in f.truth.iter().enumerate() {
            for (j, e) in f.est.iter().enumerate() {
                let d = f.dist.at(i, j);
                if d.is_finite() && d <= gate {
                    shared[truth_ids[t] * ne + est_ids[e]] += 1;
                }
            }
        }
    }
    let costs = CostMatrix::from_fn(nt, ne, |i, j| -(shared[i * ne + j] as f64));
    let truth_of: Vec<usize> = invert(&truth_ids);
    let est_of: Vec<usize> = invert(&est_ids);
    let mut idtp = 0;
    let mut pairs = Vec::new();
    for (i, j) in assign(&costs).pairs {
        let n = shared[i * ne + j];
        if n > 0 {
            idtp += n;
            pairs.push((truth_of[i], est_of[j]));
        }
    }
    pairs.sort_unstable();
    IdentityScores {
        idtp,
        idfp: est_total - idtp,
        idfn: truth_total - idtp,
        pairs,
    }
}

fn invert(ids: &BTreeMap<usize, usize>) -> Vec<usize> {
    let mut out = vec![0; ids.len()];
    for (&id, &k) in ids {
        out[k] = id;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(t: &[(usize, f64)], e: &[(usize, f64)]) -> MotFrame {
        MotFrame::on_a_line(t, e)
    }

    #[test]
    fn a_label_switch_halves_the_identity_score() {
        // One object over 4 frames: estimate 7 for two frames, then estimate 8.
        let f = vec![
            frame(&[(0, 0.0)], &[(7, 0.0)]),
            frame(&[(0, 0.0)], &[(7, 0.0)]),
            frame(&[(0, 0.0)], &[(8, 0.0)]),
            frame(&[(0, 0.0)], &[(8, 0.0)]),
        ];
        let s = identity_scores(&f, 0.5);
        assert_eq!((s.idtp, s.idfp, s.idfn), (2, 2, 2));
        assert_eq!(s.idf1(), Some(0.5));
        assert_eq!(s.pairs.len(), 1);
    }

    #[test]
    fn global_matching_beats_per_frame_choice() {
        // Truth 0 is covered by 7 for 3 frames and 8 for 1; truth 1 by 8 for 2 frames.
        // Best: 0-7 (3) + 1-8 (2) = 5 of 6 truth frames.
        let f = vec![
            frame(&[(0, 0.0), (1, 5.0)], &[(7, 0.0), (8, 5.0)]),
            frame(&[(0, 0.0), (1, 5.0)], &[(7, 0.0), (8, 5.0)]),
            frame(&[(0, 0.0)], &[(7, 0.0)]),
            frame(&[(0, 0.0)], &[(8, 0.0)]),
        ];
        let s = identity_scores(&f, 0.5);
        assert_eq!(s.idtp, 5);
        assert_eq!(s.pairs, vec![(0, 7), (1, 8)]);
        assert_eq!(s.idfn, 1);
        assert_eq!(s.idfp, 1);
        assert!((s.idp().unwrap() - 5.0 / 6.0).abs() < 1e-12);
        assert!((s.idf1().unwrap() - 10.0 / 12.0).abs() < 1e-12);
    }

    #[test]
    fn distances_beyond_the_gate_do_not_count() {
        let f = vec![frame(&[(0, 0.0)], &[(7, 1.0)])];
        let s = identity_scores(&f, 0.5);
        assert_eq!((s.idtp, s.idfp, s.idfn), (0, 1, 1));
        assert_eq!(s.idf1(), Some(0.0));
        assert_eq!(identity_scores(&[], 0.5).idf1(), None);
    }
}
