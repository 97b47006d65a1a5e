//! The set of samples a separation metric is computed over (a source's active samples).

/// Sorted, disjoint, non-empty half-open sample ranges `[start, end)`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SampleSet {
    ranges: Vec<(usize, usize)>,
}

impl SampleSet {
    /// Every sample of a signal of length `len`.
    pub fn all(len: usize) -> Self {
        Self::from_ranges([(0, len)], len)
    }

    /// The union of `ranges`, clipped to `[0, len)`; empty and overlapping ranges are merged away.
    pub fn from_ranges(ranges: impl IntoIterator<Item = (usize, usize)>, len: usize) -> Self {
        let mut r: Vec<(usize, usize)> = ranges
            .into_iter()
            .map(|(a, b)| (a.min(len), b.min(len)))
            .filter(|(a, b)| b > a)
            .collect();
        r.sort_unstable();
        let mut merged: Vec<(usize, usize)> = Vec::with_capacity(r.len());
        for (a, b) in r {
            match merged.last_mut() {
                Some(last) if a <= last.1 => last.1 = last.1.max(b),
                _ => merged.push((a, b)),
            }
        }
        Self { ranges: merged }
    }

    /// The samples of the time intervals `(t0, t1)` (seconds) at `sample_rate`.
    pub fn from_intervals(intervals: &[(f64, f64)], sample_rate: f64, len: usize) -> Self {
        let to_index = |t: f64| {
            let n = (t * sample_rate).round();
            if n.is_finite() && n > 0.0 {
                n.min(len as f64) as usize
            } else {
                0
            }
        };
        Self::from_ranges(
            intervals.iter().map(|&(a, b)| (to_index(a), to_index(b))),
            len,
        )
    }

    /// The ranges.
    pub fn ranges(&self) -> &[(usize, usize)] {
        &self.ranges
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.ranges.iter().map(|(a, b)| b - a).sum()
    }

    /// Whether the set has no sample.
    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }

    /// First sample and one past the last, when not empty.
    pub fn span(&self) -> Option<(usize, usize)> {
        Some((self.ranges.first()?.0, self.ranges.last()?.1))
    }

    /// The sample indices in order.
    pub fn indices(&self) -> impl Iterator<Item = usize> + '_ {
        self.ranges.iter().flat_map(|&(a, b)| a..b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merges_and_clips() {
        let s = SampleSet::from_ranges([(5, 8), (0, 2), (7, 10), (12, 12), (20, 30)], 25);
        assert_eq!(s.ranges(), &[(0, 2), (5, 10), (20, 25)]);
        assert_eq!(s.len(), 12);
        assert_eq!(s.span(), Some((0, 25)));
        let t = SampleSet::from_intervals(&[(0.5, 1.0), (-1.0, 0.1)], 10.0, 100);
        assert_eq!(t.ranges(), &[(0, 1), (5, 10)]);
        assert_eq!(t.indices().collect::<Vec<_>>(), vec![0, 5, 6, 7, 8, 9]);
    }
}
