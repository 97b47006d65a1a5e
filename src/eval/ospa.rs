//! OSPA (Schuhmacher, Vo & Vo 2008) between point sets and OSPA(2) (Beard, Vo & Vo 2020)
//! between sets of tracks over a sliding window (spec 000 A9, spec 003 section 8.4).

use serde::{Deserialize, Serialize};

use crate::geometry::Vec3;

use super::assignment::{CostMatrix, assign};

/// An OSPA value with its two parts. For order p = 1 the parts add up to the total; for other
/// orders `total^p = localisation^p + cardinality^p`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct OspaValue {
    /// The OSPA distance.
    pub total: f64,
    /// Localisation part: `((1/n) min sum d_c^p)^(1/p)`.
    pub localisation: f64,
    /// Cardinality part: `(c^p (n - m) / n)^(1/p)`.
    pub cardinality: f64,
}

/// OSPA cut-off `c` (same unit as the distances) and order `p >= 1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OspaParams {
    /// Cut-off c > 0.
    pub cutoff: f64,
    /// Order p >= 1.
    pub order: f64,
}

impl OspaParams {
    /// Cut-off `cutoff` and order `order`.
    pub fn new(cutoff: f64, order: f64) -> Self {
        Self { cutoff, order }
    }

    /// A pair's cost `min(d, c)^p`; a NaN distance means "unknown": the worst admissible value.
    pub(crate) fn capped_cost(&self, d: f64) -> f64 {
        let d = if d.is_nan() {
            self.cutoff
        } else {
            d.min(self.cutoff)
        };
        d.max(0.0).powf(self.order)
    }
}

/// OSPA between two sets whose base distances are `dist(i, j)` for `i < m`, `j < n`.
pub fn ospa_with(
    m: usize,
    n: usize,
    dist: impl Fn(usize, usize) -> f64,
    p: OspaParams,
) -> OspaValue {
    let (c, order) = (p.cutoff, p.order);
    if m == 0 && n == 0 {
        return OspaValue::default();
    }
    if m == 0 || n == 0 {
        return OspaValue {
            total: c,
            localisation: 0.0,
            cardinality: c,
        };
    }
    let costs = CostMatrix::from_fn(m, n, |i, j| p.capped_cost(dist(i, j)));
    let loc_sum = assign(&costs).cost;
    let big = m.max(n) as f64;
    let card_sum = c.powf(order) * (m.abs_diff(n)) as f64;
    OspaValue {
        total: ((loc_sum + card_sum) / big).powf(1.0 / order),
        localisation: (loc_sum / big).powf(1.0 / order),
        cardinality: (card_sum / big).powf(1.0 / order),
    }
}

/// OSPA between two sets of 3-D points (Euclidean base distance).
pub fn ospa(x: &[Vec3], y: &[Vec3], p: OspaParams) -> OspaValue {
    ospa_with(x.len(), y.len(), |i, j| (x[i] - y[j]).norm(), p)
}

/// A track sampled on a common grid of time steps: `None` where it does not exist.
pub type TrackSamples = Vec<Option<Vec3>>;

/// Base distance of OSPA(2) between two tracks over the steps `window`: the mean over the steps
/// where at least one of them exists of `min(c, |f - g|)` (both exist) or `c` (one exists).
/// `None` when neither exists anywhere in the window.
pub fn track_distance(
    f: &[Option<Vec3>],
    g: &[Option<Vec3>],
    window: std::ops::Range<usize>,
    cutoff: f64,
) -> Option<f64> {
    let mut sum = 0.0;
    let mut count = 0usize;
    for k in window {
        let a = f.get(k).copied().flatten();
        let b = g.get(k).copied().flatten();
        match (a, b) {
            (Some(a), Some(b)) => {
                sum += (a - b).norm().min(cutoff);
                count += 1;
            }
            (Some(_), None) | (None, Some(_)) => {
                sum += cutoff;
                count += 1;
            }
            (None, None) => {}
        }
    }
    (count > 0).then(|| sum / count as f64)
}

/// OSPA(2) between track sets `x` and `y` over the steps `window`; only the tracks that exist at
/// some step of the window take part.
pub fn ospa2_window(
    x: &[TrackSamples],
    y: &[TrackSamples],
    window: std::ops::Range<usize>,
    p: OspaParams,
) -> OspaValue {
    let alive = |t: &&TrackSamples| {
        t.get(window.clone())
            .is_some_and(|s| s.iter().any(Option::is_some))
    };
    let xs: Vec<&TrackSamples> = x.iter().filter(alive).collect();
    let ys: Vec<&TrackSamples> = y.iter().filter(alive).collect();
    ospa_with(
        xs.len(),
        ys.len(),
        |i, j| track_distance(xs[i], ys[j], window.clone(), p.cutoff).unwrap_or(p.cutoff),
        p,
    )
}

/// OSPA(2) at every step k over the window of the last `window` steps `[k + 1 - window, k]`
/// (shorter at the start), for tracks sampled on `steps` time steps.
pub fn ospa2_series(
    x: &[TrackSamples],
    y: &[TrackSamples],
    steps: usize,
    window: usize,
    p: OspaParams,
) -> Vec<OspaValue> {
    let w = window.max(1);
    (0..steps)
        .map(|k| ospa2_window(x, y, (k + 1).saturating_sub(w)..k + 1, p))
        .collect()
}

/// Mean of OSPA values part by part (zero for an empty list).
pub fn mean_ospa(values: &[OspaValue]) -> OspaValue {
    if values.is_empty() {
        return OspaValue::default();
    }
    let n = values.len() as f64;
    OspaValue {
        total: values.iter().map(|v| v.total).sum::<f64>() / n,
        localisation: values.iter().map(|v| v.localisation).sum::<f64>() / n,
        cardinality: values.iter().map(|v| v.cardinality).sum::<f64>() / n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const P1: OspaParams = OspaParams {
        cutoff: 1.0,
        order: 1.0,
    };

    fn v(x: f64, y: f64) -> Vec3 {
        Vec3::new(x, y, 1.5)
    }

    #[test]
    fn empty_sets() {
        assert_eq!(ospa(&[], &[], P1), OspaValue::default());
        let one = ospa(&[v(0.0, 0.0)], &[], P1);
        assert_eq!(
            (one.total, one.localisation, one.cardinality),
            (1.0, 0.0, 1.0)
        );
        let c2 = OspaParams::new(2.0, 2.0);
        assert_eq!(ospa(&[], &[v(0.0, 0.0), v(1.0, 1.0)], c2).total, 2.0);
    }

    #[test]
    fn hand_computed_values() {
        // Offsets 0.2 and 0.3 after optimal pairing (the naive pairing would cost more).
        let x = [v(0.0, 0.0), v(2.0, 0.0)];
        let y = [v(2.3, 0.0), v(0.0, 0.2)];
        let o = ospa(&x, &y, P1);
        assert!((o.total - 0.25).abs() < 1e-12, "{o:?}");
        assert!((o.cardinality).abs() < 1e-12);
        // One missed point: (0.2 + 1) / 2 = 0.6, split 0.1 + 0.5.
        let o = ospa(&x[..1], &y, P1);
        assert!((o.total - 0.6).abs() < 1e-12, "{o:?}");
        assert!((o.localisation - 0.1).abs() < 1e-12);
        assert!((o.cardinality - 0.5).abs() < 1e-12);
        assert!((o.localisation + o.cardinality - o.total).abs() < 1e-12);
        // Distances beyond the cut-off count as c.
        let o = ospa(&[v(0.0, 0.0)], &[v(5.0, 0.0)], P1);
        assert!((o.total - 1.0).abs() < 1e-12);
        // Order 2: sqrt((0.3^2 + 1^2) / 2).
        let o = ospa(
            &[v(0.0, 0.0)],
            &[v(0.3, 0.0), v(9.0, 9.0)],
            OspaParams::new(1.0, 2.0),
        );
        assert!((o.total - ((0.09 + 1.0) / 2.0f64).sqrt()).abs() < 1e-12);
        assert!((o.total.powi(2) - o.localisation.powi(2) - o.cardinality.powi(2)).abs() < 1e-12);
    }

    #[test]
    fn track_distance_counts_single_existence_as_cutoff() {
        let f = vec![Some(v(0.0, 0.0)), Some(v(0.0, 0.0)), None, None];
        let g = vec![None, Some(v(0.4, 0.0)), Some(v(0.0, 0.0)), None];
        // Steps 0 (c), 1 (0.4), 2 (c); step 3 neither.
        let d = track_distance(&f, &g, 0..4, 1.0).unwrap();
        assert!((d - 2.4 / 3.0).abs() < 1e-12);
        assert_eq!(track_distance(&f, &g, 3..4, 1.0), None);
    }

    #[test]
    fn ospa2_penalises_a_label_switch_that_ospa_does_not_see() {
        // Two truths far apart; the estimates swap labels half-way through.
        let a = v(0.0, 0.0);
        let b = v(3.0, 0.0);
        let truth = vec![vec![Some(a); 4], vec![Some(b); 4]];
        let est = vec![
            vec![Some(a), Some(a), Some(b), Some(b)],
            vec![Some(b), Some(b), Some(a), Some(a)],
        ];
        for k in 0..4 {
            let xs: Vec<Vec3> = truth.iter().filter_map(|t| t[k]).collect();
            let ys: Vec<Vec3> = est.iter().filter_map(|t| t[k]).collect();
            assert_eq!(ospa(&xs, &ys, P1).total, 0.0);
        }
        // Over the whole window each pairing agrees on half the steps: base distance 0.5.
        let o = ospa2_window(&truth, &est, 0..4, P1);
        assert!((o.total - 0.5).abs() < 1e-12, "{o:?}");
        let series = ospa2_series(&truth, &est, 4, 2, P1);
        let totals: Vec<f64> = series.iter().map(|o| o.total).collect();
        assert_eq!(totals, vec![0.0, 0.0, 0.5, 0.0]);
    }

    #[test]
    fn ospa2_of_a_late_track() {
        // The estimate starts one step late and is offset 0.2 m: window of 4 steps gives a base
        // distance (1 + 3 * 0.2) / 4 = 0.4.
        let truth = vec![vec![Some(v(0.0, 0.0)); 4]];
        let est = vec![vec![
            None,
            Some(v(0.2, 0.0)),
            Some(v(0.2, 0.0)),
            Some(v(0.2, 0.0)),
        ]];
        let o = ospa2_window(&truth, &est, 0..4, P1);
        assert!((o.total - 0.4).abs() < 1e-12, "{o:?}");
        // Tracks absent from the window do not take part.
        assert_eq!(ospa2_window(&[], &est, 0..1, P1).total, 0.0);
    }
}
