//! HOTA, Higher Order Tracking Accuracy (Luiten et al. 2021, IJCV), with its detection (DetA),
//! association (AssA) and localisation (LocA) parts, for point objects.
//!
//! Why beside MOTA and IDF1: MOTA weighs detection far above association (an identity switch
//! costs one step, a miss every step) and IDF1 the other way round; HOTA is the geometric mean
//! of the two accuracies, averaged over localisation thresholds, so a tracker that keeps labels
//! and one that finds every talker are both visible in one figure.
//!
//! The similarity of a true object and an estimate at distance `d` is `max(0, 1 - d / scale)`
//! (the distance form used for points; `scale` is the distance at which it reaches 0). For
//! each threshold alpha in 0.05, 0.10, ..., 0.95 the pairs of a frame's optimal matching with
//! similarity at least alpha are true positives. The matching maximises the similarity weighted
//! by each pair's global alignment score, as in the reference implementation (TrackEval), so a
//! frame prefers the estimate that follows the object over the sequence.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::assignment::{CostMatrix, assign};
use super::clear_mot::{MotFrame, dense_ids};

/// Localisation thresholds alpha: 0.05 to 0.95 in steps of 0.05.
const ALPHAS: usize = 19;

/// Tolerance of the threshold comparison (the reference implementation's).
const EPS: f64 = 1e-10;

/// HOTA and its parts, each averaged over the localisation thresholds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HotaScores {
    /// HOTA = sqrt(DetA * AssA), averaged over alpha.
    pub hota: f64,
    /// Detection accuracy TP / (TP + FN + FP).
    pub deta: f64,
    /// Association accuracy: over the true positives, the mean of
    /// TPA / (TPA + FNA + FPA) of their (object, estimate) pair.
    pub assa: f64,
    /// Localisation accuracy: mean similarity of the true positives.
    pub loca: f64,
}

/// HOTA of `frames`, whose distances reach similarity 0 at `scale` (> 0). `None` when the
/// frames hold neither true objects nor estimates.
pub fn hota(frames: &[MotFrame], scale: f64) -> Option<HotaScores> {
    let ids = Ids {
        truth: dense_ids(frames.iter().flat_map(|f| f.truth.iter().copied())),
        est: dense_ids(frames.iter().flat_map(|f| f.est.iter().copied())),
    };
    if ids.truth.is_empty() && ids.est.is_empty() {
        return None;
    }
    let similarity = |f: &MotFrame, i: usize, j: usize| {
        let d = f.dist.at(i, j);
        if d.is_nan() {
            0.0
        } else {
            (1.0 - d / scale).max(0.0)
        }
    };
    let sims: Vec<CostMatrix> = frames
        .iter()
        .map(|f| CostMatrix::from_fn(f.truth.len(), f.est.len(), |i, j| similarity(f, i, j)))
        .collect();
    let alignment = Alignment::over(frames, &sims, &ids);
    let matches = Matches::over(frames, &sims, &ids, &alignment);
    Some(alignment.scores(&matches))
}

/// Dense indices of the true objects' and the estimates' ids.
struct Ids {
    truth: BTreeMap<usize, usize>,
    est: BTreeMap<usize, usize>,
}

/// Pass 1: how much each (object, estimate) pair is matched over the sequence.
struct Alignment {
    /// Estimates (columns of `global`).
    ne: usize,
    /// Frames each true object appears in.
    truth_count: Vec<usize>,
    /// Frames each estimate appears in.
    est_count: Vec<usize>,
    /// Per pair (object-major): the global alignment score, the Jaccard index of the summed
    /// Jaccard-normalised similarities of each frame.
    global: Vec<f64>,
}

impl Alignment {
    fn over(frames: &[MotFrame], sims: &[CostMatrix], ids: &Ids) -> Self {
        let (nt, ne) = (ids.truth.len(), ids.est.len());
        let mut potential = vec![0.0; nt * ne];
        let (mut truth_count, mut est_count) = (vec![0usize; nt], vec![0usize; ne]);
        for (f, s) in frames.iter().zip(sims) {
            let row_sum: Vec<f64> = (0..s.rows())
                .map(|i| (0..s.cols()).map(|j| s.at(i, j)).sum())
                .collect();
            let col_sum: Vec<f64> = (0..s.cols())
                .map(|j| (0..s.rows()).map(|i| s.at(i, j)).sum())
                .collect();
            for (i, t) in f.truth.iter().enumerate() {
                for (j, e) in f.est.iter().enumerate() {
                    let denom = row_sum[i] + col_sum[j] - s.at(i, j);
                    if denom > 0.0 {
                        potential[ids.truth[t] * ne + ids.est[e]] += s.at(i, j) / denom;
                    }
                }
            }
            f.truth.iter().for_each(|t| truth_count[ids.truth[t]] += 1);
            f.est.iter().for_each(|e| est_count[ids.est[e]] += 1);
        }
        let mut alignment = Self {
            ne,
            truth_count,
            est_count,
            global: Vec::new(),
        };
        alignment.global = (0..nt * ne)
            .map(|k| alignment.jaccard(k, potential[k]))
            .collect();
        alignment
    }

    /// The Jaccard index of pair `k` (object-major) given the frames it `shared`.
    fn jaccard(&self, k: usize, shared: f64) -> f64 {
        let denom = (self.truth_count[k / self.ne] + self.est_count[k % self.ne]) as f64 - shared;
        if denom > 0.0 { shared / denom } else { 0.0 }
    }

    /// HOTA and its parts from pass 2's `matches`, averaged over the thresholds.
    fn scores(&self, matches: &Matches) -> HotaScores {
        let truth_total: usize = self.truth_count.iter().sum();
        let est_total: usize = self.est_count.iter().sum();
        let mut sums = HotaScores {
            hota: 0.0,
            deta: 0.0,
            assa: 0.0,
            loca: 0.0,
        };
        for a in 0..ALPHAS {
            let tp = matches.tp[a] as f64;
            let deta = tp / ((truth_total + est_total - matches.tp[a]) as f64).max(1.0);
            let assa = (0..self.global.len())
                .map(|k| {
                    let m = matches.pairs[k][a] as f64;
                    m * self.jaccard(k, m)
                })
                .sum::<f64>()
                / tp.max(1.0);
            sums.hota += (deta * assa).sqrt();
            sums.deta += deta;
            sums.assa += assa;
            // The reference implementation's convention: 1 where nothing matched.
            sums.loca += matches.similarity[a].max(EPS) / tp.max(EPS);
        }
        let n = ALPHAS as f64;
        HotaScores {
            hota: sums.hota / n,
            deta: sums.deta / n,
            assa: sums.assa / n,
            loca: sums.loca / n,
        }
    }
}

/// Pass 2: each frame's matching, thresholded at every alpha.
struct Matches {
    /// True positives per threshold.
    tp: [usize; ALPHAS],
    /// Summed similarity of the true positives per threshold.
    similarity: [f64; ALPHAS],
    /// Per pair (object-major) and threshold: the frames it is a true positive in.
    pairs: Vec<[usize; ALPHAS]>,
}

impl Matches {
    fn over(frames: &[MotFrame], sims: &[CostMatrix], ids: &Ids, alignment: &Alignment) -> Self {
        let ne = alignment.ne;
        let mut m = Self {
            tp: [0; ALPHAS],
            similarity: [0.0; ALPHAS],
            pairs: vec![[0; ALPHAS]; alignment.global.len()],
        };
        for (f, sim) in frames.iter().zip(sims) {
            let (ti, ej): (Vec<usize>, Vec<usize>) = (
                f.truth.iter().map(|t| ids.truth[t]).collect(),
                f.est.iter().map(|e| ids.est[e]).collect(),
            );
            // The matching weighs each pair's similarity by its global alignment.
            let cost = CostMatrix::from_fn(ti.len(), ej.len(), |i, j| {
                -alignment.global[ti[i] * ne + ej[j]] * sim.at(i, j)
            });
            for (i, j) in assign(&cost).pairs {
                let s = sim.at(i, j);
                for a in 0..ALPHAS {
                    if s >= alpha(a) - EPS {
                        m.tp[a] += 1;
                        m.similarity[a] += s;
                        m.pairs[ti[i] * ne + ej[j]][a] += 1;
                    }
                }
            }
        }
        m
    }
}

/// The `a`-th localisation threshold.
fn alpha(a: usize) -> f64 {
    0.05 * (a + 1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(t: &[(usize, f64)], e: &[(usize, f64)]) -> MotFrame {
        MotFrame::on_a_line(t, e)
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    #[test]
    fn a_perfect_track_scores_one() {
        let f: Vec<_> = (0..5).map(|_| frame(&[(0, 1.0)], &[(3, 1.0)])).collect();
        let h = hota(&f, 1.0).unwrap();
        assert!(close(h.hota, 1.0) && close(h.deta, 1.0) && close(h.assa, 1.0));
        assert!(close(h.loca, 1.0));
    }

    #[test]
    fn a_label_switch_halfway_leaves_detection_whole_and_halves_association() {
        // One object over 4 frames, estimate 7 on the first two and 8 on the last two: every
        // pair has TPA 2, FNA 2, FPA 0, so AssA = 1/2 and HOTA = sqrt(1/2).
        let f = vec![
            frame(&[(0, 0.0)], &[(7, 0.0)]),
            frame(&[(0, 0.0)], &[(7, 0.0)]),
            frame(&[(0, 0.0)], &[(8, 0.0)]),
            frame(&[(0, 0.0)], &[(8, 0.0)]),
        ];
        let h = hota(&f, 1.0).unwrap();
        assert!(close(h.deta, 1.0), "{h:?}");
        assert!(close(h.assa, 0.5), "{h:?}");
        assert!(close(h.hota, 0.5f64.sqrt()), "{h:?}");
    }

    #[test]
    fn an_offset_counts_only_at_the_thresholds_it_meets() {
        // An estimate 0.3 off at scale 1: similarity 0.7, a true positive for alpha <= 0.7
        // (14 of the 19 thresholds) and both a miss and a false positive above.
        let f: Vec<_> = (0..3).map(|_| frame(&[(0, 0.0)], &[(1, 0.3)])).collect();
        let h = hota(&f, 1.0).unwrap();
        assert!(close(h.deta, 14.0 / 19.0), "{h:?}");
        assert!(close(h.hota, 14.0 / 19.0), "{h:?}");
        // LocA: 0.7 where matched, 1 (nothing matched) at the other five thresholds.
        assert!(close(h.loca, (14.0 * 0.7 + 5.0) / 19.0), "{h:?}");
    }

    #[test]
    fn a_false_track_lowers_detection_but_not_association() {
        // One object tracked perfectly over 4 frames, and a ghost far away in 2 of them:
        // DetA = 4 / (4 + 2), AssA = 1.
        let mut f: Vec<_> = (0..4).map(|_| frame(&[(0, 0.0)], &[(1, 0.0)])).collect();
        for g in f.iter_mut().take(2) {
            *g = frame(&[(0, 0.0)], &[(1, 0.0), (9, 5.0)]);
        }
        let h = hota(&f, 1.0).unwrap();
        assert!(close(h.deta, 4.0 / 6.0), "{h:?}");
        assert!(close(h.assa, 1.0), "{h:?}");
        assert!(close(h.hota, (4.0f64 / 6.0).sqrt()), "{h:?}");
    }

    #[test]
    fn the_matching_keeps_the_estimate_that_follows_the_object() {
        // Two estimates equally near object 0 in the last frame; estimate 5 followed it in the
        // frames before, so the global alignment gives it the match and AssA stays 1 (with
        // estimate 6 it would be (4 * 4/5 + 1/9) / 5).
        let mut f: Vec<_> = (0..4)
            .map(|_| frame(&[(0, 0.0)], &[(5, 0.0), (6, 3.0)]))
            .collect();
        f.push(frame(&[(0, 0.0)], &[(5, 0.0), (6, 0.0)]));
        let h = hota(&f, 1.0).unwrap();
        assert!(close(h.assa, 1.0), "{h:?}");
    }

    #[test]
    fn nothing_at_all_has_no_score_and_no_estimates_score_zero() {
        assert_eq!(hota(&[], 1.0), None);
        let h = hota(&[frame(&[(0, 0.0)], &[])], 1.0).unwrap();
        assert_eq!((h.hota, h.deta, h.assa), (0.0, 0.0, 0.0));
    }
}
