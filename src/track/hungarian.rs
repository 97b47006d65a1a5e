//! Minimum-cost assignment (Kuhn-Munkres with potentials, O(n^2 m)) for label matching.

/// Assigns rows to distinct columns minimising the total cost. Returns, for each row, its
/// column, or None for rows left over when there are more rows than columns.
pub(crate) fn assign(cost: &[Vec<f64>]) -> Vec<Option<usize>> {
    let n = cost.len();
    let m = cost.first().map_or(0, |r| r.len());
    if n == 0 || m == 0 {
        return vec![None; n];
    }
    if n > m {
        // Solve the transpose so that rows <= columns.
        let t: Vec<Vec<f64>> = (0..m)
            .map(|j| (0..n).map(|i| cost[i][j]).collect())
            .collect();
        let cols = assign(&t);
        let mut out = vec![None; n];
        for (j, i) in cols.iter().enumerate() {
            if let Some(i) = i {
                out[*i] = Some(j);
            }
        }
        return out;
    }
    let inf = f64::INFINITY;
    let mut u = vec![0.0; n + 1];
    let mut v = vec![0.0; m + 1];
    let mut p = vec![0usize; m + 1];
    let mut way = vec![0usize; m + 1];
    for i in 1..=n {
        p[0] = i;
        let mut j0 = 0;
        let mut minv = vec![inf; m + 1];
        let mut used = vec![false; m + 1];
        loop {
            used[j0] = true;
            let i0 = p[j0];
            let mut delta = inf;
            let mut j1 = 0;
            for j in 1..=m {
                if !used[j] {
                    let cur = cost[i0 - 1][j - 1] - u[i0] - v[j];
                    if cur < minv[j] {
                        minv[j] = cur;
                        way[j] = j0;
                    }
                    if minv[j] < delta {
                        delta = minv[j];
                        j1 = j;
                    }
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
    let mut out = vec![None; n];
    for j in 1..=m {
        if p[j] != 0 {
            out[p[j] - 1] = Some(j - 1);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn total(cost: &[Vec<f64>], a: &[Option<usize>]) -> f64 {
        a.iter()
            .enumerate()
            .filter_map(|(i, j)| j.map(|j| cost[i][j]))
            .sum()
    }

    #[test]
    fn matches_brute_force() {
        let cost = vec![
            vec![4.0, 1.0, 3.0, 9.0],
            vec![2.0, 0.0, 5.0, 1.0],
            vec![3.0, 2.0, 2.0, 7.0],
        ];
        let a = assign(&cost);
        let mut best = f64::INFINITY;
        for x in 0..4 {
            for y in 0..4 {
                for z in 0..4 {
                    if x != y && y != z && x != z {
                        best = best.min(cost[0][x] + cost[1][y] + cost[2][z]);
                    }
                }
            }
        }
        assert_eq!(total(&cost, &a), best);
        // More rows than columns: one row is left out.
        let t: Vec<Vec<f64>> = (0..4)
            .map(|j| (0..3).map(|i| cost[i][j]).collect())
            .collect();
        let b = assign(&t);
        assert_eq!(b.iter().filter(|x| x.is_none()).count(), 1);
        assert_eq!(total(&t, &b), best);
    }
}
