//! Mean and median of a sample of errors, as reported.

use serde::{Deserialize, Serialize};

/// Count, mean and median of a set of values (the latter two absent when the set is empty).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Summary {
    /// Number of values.
    pub count: usize,
    /// Their mean.
    pub mean: Option<f64>,
    /// Their median (mean of the two middle values for an even count).
    pub median: Option<f64>,
}

impl Summary {
    /// Summarises `values`; non-finite values are left out.
    pub fn of(values: &[f64]) -> Self {
        let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return Self::default();
        }
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        };
        Self {
            count: n,
            mean: Some(v.iter().sum::<f64>() / n as f64),
            median: Some(median),
        }
    }
}

/// Mean of the present values, `None` when there is none.
pub fn mean_of(values: impl IntoIterator<Item = Option<f64>>) -> Option<f64> {
    let (sum, n) = values
        .into_iter()
        .flatten()
        .filter(|v| v.is_finite())
        .fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    (n > 0).then(|| sum / n as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_and_median() {
        let s = Summary::of(&[3.0, 1.0, f64::NAN, 2.0, 10.0]);
        assert_eq!(s.count, 4);
        assert_eq!(s.mean, Some(4.0));
        assert_eq!(s.median, Some(2.5));
        assert_eq!(Summary::of(&[]).mean, None);
        assert_eq!(mean_of([Some(1.0), None, Some(3.0)]), Some(2.0));
        assert_eq!(mean_of([None]), None);
    }
}
