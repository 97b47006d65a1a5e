//! Analysis windows.

use std::f64::consts::PI;

/// Periodic Hann window of length `n`: `w[t] = 0.5 - 0.5 cos(2 pi t / n)`.
///
/// The periodic form (not the symmetric one) sums to a constant at 50 % overlap, which is what
/// the STFT and the seed paper's framing use.
pub fn hann_periodic(n: usize) -> Vec<f64> {
    (0..n)
        .map(|t| 0.5 - 0.5 * (2.0 * PI * t as f64 / n as f64).cos())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hann_sums_to_one_at_half_overlap() {
        let w = hann_periodic(16);
        for t in 0..8 {
            assert!((w[t] + w[t + 8] - 1.0).abs() < 1e-12);
        }
        assert_eq!(w[0], 0.0);
    }
}
