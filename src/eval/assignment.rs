//! Optimal assignment for rectangular cost matrices (Kuhn-Munkres with potentials, the O(n^2 m)
//! shortest-augmenting-path form).
//!
//! Every metric that pairs estimates with truths (OSPA, OSPA(2), CLEAR MOT, IDF1, the audio
//! mapping) goes through [`assign`], and so does the GM-PHD tracker's label matching.

/// A rectangular cost matrix stored row by row.
#[derive(Debug, Clone, PartialEq)]
pub struct CostMatrix {
    rows: usize,
    cols: usize,
    data: Vec<f64>,
}

impl CostMatrix {
    /// A `rows x cols` matrix filled by `f(row, col)`.
    pub fn from_fn(rows: usize, cols: usize, mut f: impl FnMut(usize, usize) -> f64) -> Self {
        let mut data = Vec::with_capacity(rows * cols);
        for r in 0..rows {
            for c in 0..cols {
                data.push(f(r, c));
            }
        }
        Self { rows, cols, data }
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Number of columns.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Entry at (`row`, `col`).
    pub fn at(&self, row: usize, col: usize) -> f64 {
        self.data[row * self.cols + col]
    }
}

/// An optimal assignment: `min(rows, cols)` pairs `(row, col)` sorted by row, and their total cost.
#[derive(Debug, Clone, PartialEq)]
pub struct Assignment {
    /// Assigned `(row, col)` pairs, by increasing row.
    pub pairs: Vec<(usize, usize)>,
    /// Sum of the assigned costs.
    pub cost: f64,
}

/// Minimum-cost assignment of `min(rows, cols)` rows to distinct columns.
///
/// Costs must be finite (callers encode "forbidden" pairs as a large finite cost); a non-finite
/// entry is treated as that large cost so that no NaN can spread.
pub fn assign(cost: &CostMatrix) -> Assignment {
    if cost.rows == 0 || cost.cols == 0 {
        return Assignment {
            pairs: Vec::new(),
            cost: 0.0,
        };
    }
    let finite_max = cost
        .data
        .iter()
        .filter(|v| v.is_finite())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let big = (finite_max + 1.0) * (cost.rows.max(cost.cols) as f64 + 1.0);
    let entry = |r: usize, c: usize| {
        let v = cost.at(r, c);
        if v.is_finite() { v } else { big }
    };
    let transposed = cost.rows > cost.cols;
    let (n, m) = if transposed {
        (cost.cols, cost.rows)
    } else {
        (cost.rows, cost.cols)
    };
    let a = |i: usize, j: usize| if transposed { entry(j, i) } else { entry(i, j) };
    let row_of_col = hungarian(n, m, a);
    let mut pairs: Vec<(usize, usize)> = row_of_col
        .iter()
        .enumerate()
        .filter_map(|(j, r)| r.map(|i| if transposed { (j, i) } else { (i, j) }))
        .collect();
    pairs.sort_unstable();
    let total = pairs.iter().map(|&(r, c)| cost.at(r, c)).sum();
    Assignment { pairs, cost: total }
}

/// Shortest augmenting paths with row/column potentials for `n <= m`; returns for every column
/// the row assigned to it.
fn hungarian(n: usize, m: usize, a: impl Fn(usize, usize) -> f64) -> Vec<Option<usize>> {
    // 1-based arrays as in the classical formulation; index 0 is the virtual start column.
    let mut u = vec![0.0; n + 1];
    let mut v = vec![0.0; m + 1];
    let mut p = vec![0usize; m + 1];
    let mut way = vec![0usize; m + 1];
    for i in 1..=n {
        p[0] = i;
        let mut j0 = 0usize;
        let mut minv = vec![f64::INFINITY; m + 1];
        let mut used = vec![false; m + 1];
        loop {
            used[j0] = true;
            let i0 = p[j0];
            let mut delta = f64::INFINITY;
            let mut j1 = 0usize;
            for j in 1..=m {
                if used[j] {
                    continue;
                }
                let cur = a(i0 - 1, j - 1) - u[i0] - v[j];
                if cur < minv[j] {
                    minv[j] = cur;
                    way[j] = j0;
                }
                if minv[j] < delta {
                    delta = minv[j];
                    j1 = j;
                }
            }
            for j in 0..=m {
                if used[j] {
                    u[p[j]] += delta;
                    v[j] -= delta;
                } else {
                    minv[j] -= delta;
                }
            }
            j0 = j1;
            if p[j0] == 0 {
                break;
            }
        }
        loop {
            let j1 = way[j0];
            p[j0] = p[j1];
            j0 = j1;
            if j0 == 0 {
                break;
            }
        }
    }
    (1..=m)
        .map(|j| if p[j] == 0 { None } else { Some(p[j] - 1) })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Minimum over every injective map of the smaller side into the larger one.
    fn brute_force(c: &CostMatrix) -> f64 {
        fn rec(c: &CostMatrix, row: usize, used: &mut Vec<bool>, transposed: bool) -> f64 {
            let (n, m) = if transposed {
                (c.cols(), c.rows())
            } else {
                (c.rows(), c.cols())
            };
            if row == n {
                return 0.0;
            }
            let mut best = f64::INFINITY;
            for j in 0..m {
                if used[j] {
                    continue;
                }
                used[j] = true;
                let here = if transposed {
                    c.at(j, row)
                } else {
                    c.at(row, j)
                };
                best = best.min(here + rec(c, row + 1, used, transposed));
                used[j] = false;
            }
            best
        }
        let transposed = c.rows() > c.cols();
        let m = c.rows().max(c.cols());
        rec(c, 0, &mut vec![false; m], transposed)
    }

    #[test]
    fn solves_a_known_square_case() {
        let rows = [[4.0, 1.0, 3.0], [2.0, 0.0, 5.0], [3.0, 2.0, 2.0]];
        let c = CostMatrix::from_fn(3, 3, |r, k| rows[r][k]);
        let a = assign(&c);
        assert_eq!(a.pairs, vec![(0, 1), (1, 0), (2, 2)]);
        assert_eq!(a.cost, 5.0);
    }

    #[test]
    fn handles_empty_and_rectangular_shapes() {
        assert!(
            assign(&CostMatrix::from_fn(0, 3, |_, _| 1.0))
                .pairs
                .is_empty()
        );
        assert!(
            assign(&CostMatrix::from_fn(2, 0, |_, _| 1.0))
                .pairs
                .is_empty()
        );
        let tall = CostMatrix::from_fn(3, 1, |r, _| [5.0, 1.0, 3.0][r]);
        assert_eq!(assign(&tall).pairs, vec![(1, 0)]);
        let wide = CostMatrix::from_fn(1, 3, |_, c| [5.0, 1.0, 3.0][c]);
        assert_eq!(assign(&wide).pairs, vec![(0, 1)]);
    }

    #[test]
    fn non_finite_entries_are_avoided_when_possible() {
        let c = CostMatrix::from_fn(2, 2, |r, k| if r == k { f64::NAN } else { 1.0 });
        let a = assign(&c);
        assert_eq!(a.pairs, vec![(0, 1), (1, 0)]);
        assert_eq!(a.cost, 2.0);
    }

    proptest! {
        #[test]
        fn matches_brute_force(
            rows in 1usize..6,
            cols in 1usize..6,
            values in proptest::collection::vec(-10.0f64..10.0, 36),
        ) {
            let c = CostMatrix::from_fn(rows, cols, |r, k| values[r * 6 + k]);
            let a = assign(&c);
            prop_assert_eq!(a.pairs.len(), rows.min(cols));
            let mut seen_r = std::collections::HashSet::new();
            let mut seen_c = std::collections::HashSet::new();
            for &(r, k) in &a.pairs {
                prop_assert!(seen_r.insert(r) && seen_c.insert(k));
            }
            let best = brute_force(&c);
            prop_assert!((a.cost - best).abs() < 1e-9, "hungarian {} vs brute force {}", a.cost, best);
        }
    }
}
