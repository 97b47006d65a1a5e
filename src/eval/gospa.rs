//! GOSPA, the generalised OSPA metric (Rahmathullah, García-Fernández & Svensson 2017) with
//! alpha = 2, which splits a set's error into localisation, missed and false objects.
//!
//! Why beside OSPA: OSPA divides by the larger set's size, so one ghost costs a quarter of the
//! cut-off beside three tracked talkers and the whole cut-off when it is alone; GOSPA is not
//! normalised and charges every missed or false object `c^p / 2` wherever it occurs, which is
//! what a count of errors per step needs. With order p = 1 the three parts add up to the total.

use serde::{Deserialize, Serialize};

use crate::geometry::Vec3;

use super::assignment::{CostMatrix, assign};
use super::ospa::OspaParams;

/// A GOSPA value with its parts: `total^p = localisation^p + missed^p + false_objects^p`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct GospaValue {
    /// The GOSPA distance.
    pub total: f64,
    /// Localisation part: `(sum over the assigned pairs of d^p)^(1/p)`, pairs closer than c.
    pub localisation: f64,
    /// Missed part: `(c^p / 2 * missed)^(1/p)`.
    pub missed: f64,
    /// False part: `(c^p / 2 * false estimates)^(1/p)`.
    pub false_objects: f64,
}

/// GOSPA between the true set `x` and the estimated set `y` (Euclidean base distance).
pub fn gospa(x: &[Vec3], y: &[Vec3], p: OspaParams) -> GospaValue {
    let (c, order) = (p.cutoff, p.order);
    let (m, n) = (x.len(), y.len());
    // A pair at c or farther costs as much as a miss plus a false object, so the optimal
    // assignment over min(d, c)^p, with the unassigned charged c^p / 2 each, is GOSPA^p.
    let costs = CostMatrix::from_fn(m, n, |i, j| p.capped_cost((x[i] - y[j]).norm()));
    let cp = c.powf(order);
    let mut loc = 0.0;
    let mut assigned = 0usize;
    for (i, j) in assign(&costs).pairs {
        let d = costs.at(i, j);
        if d < cp {
            loc += d;
            assigned += 1;
        }
    }
    let half = cp / 2.0;
    let (missed, false_objects) = (half * (m - assigned) as f64, half * (n - assigned) as f64);
    let root = |v: f64| v.powf(1.0 / order);
    GospaValue {
        total: root(loc + missed + false_objects),
        localisation: root(loc),
        missed: root(missed),
        false_objects: root(false_objects),
    }
}

/// Mean of GOSPA values part by part (zero for an empty list).
pub fn mean_gospa(values: &[GospaValue]) -> GospaValue {
    if values.is_empty() {
        return GospaValue::default();
    }
    let n = values.len() as f64;
    let mean = |f: fn(&GospaValue) -> f64| values.iter().map(f).sum::<f64>() / n;
    GospaValue {
        total: mean(|v| v.total),
        localisation: mean(|v| v.localisation),
        missed: mean(|v| v.missed),
        false_objects: mean(|v| v.false_objects),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const P1: OspaParams = OspaParams {
        cutoff: 1.0,
        order: 1.0,
    };

    fn v(x: f64) -> Vec3 {
        Vec3::new(x, 0.0, 1.5)
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-12
    }

    #[test]
    fn empty_sets_are_at_zero() {
        assert_eq!(gospa(&[], &[], P1), GospaValue::default());
    }

    #[test]
    fn every_miss_and_ghost_costs_half_the_cutoff_whatever_the_set_sizes() {
        // One ghost beside three tracked objects costs as much as a ghost alone.
        let truth = [v(0.0), v(3.0), v(6.0)];
        let est = [v(0.1), v(3.0), v(6.2), v(9.0)];
        let g = gospa(&truth, &est, P1);
        assert!(close(g.localisation, 0.3), "{g:?}");
        assert!(close(g.false_objects, 0.5) && close(g.missed, 0.0), "{g:?}");
        assert!(close(g.total, 0.8), "{g:?}");
        assert!(close(gospa(&[], &[v(9.0)], P1).total, 0.5));
        assert!(close(gospa(&[v(9.0)], &[], P1).missed, 0.5));
    }

    #[test]
    fn a_pair_beyond_the_cutoff_is_a_miss_and_a_ghost() {
        let g = gospa(&[v(0.0)], &[v(2.0)], P1);
        assert!(close(g.localisation, 0.0) && close(g.missed, 0.5), "{g:?}");
        assert!(close(g.false_objects, 0.5) && close(g.total, 1.0), "{g:?}");
    }

    #[test]
    fn order_two_adds_the_parts_squared() {
        let p = OspaParams::new(1.0, 2.0);
        let g = gospa(&[v(0.0), v(5.0)], &[v(0.3)], p);
        // 0.3^2 + 1/2 = 0.59.
        assert!(close(g.total, 0.59f64.sqrt()), "{g:?}");
        assert!(
            close(g.localisation, 0.3) && close(g.missed, 0.5f64.sqrt()),
            "{g:?}"
        );
        let parts = g.localisation.powi(2) + g.missed.powi(2) + g.false_objects.powi(2);
        assert!(close(g.total.powi(2), parts));
    }
}
