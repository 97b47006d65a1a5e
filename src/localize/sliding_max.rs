//! The centred sliding maximum of a sequence in linear time, for the coarse direction scan's
//! max-filtered GCC tables.

/// Centred sliding maximum over +-`w` (clipped at the ends), van Herk/Gil-Werman in O(n).
/// `work` must hold at least `2 * src.len()` values.
pub(super) fn sliding_max(src: &[f64], w: usize, dst: &mut [f64], work: &mut [f64]) {
    let n = src.len();
    if w == 0 || n == 0 {
        dst.copy_from_slice(src);
        return;
    }
    let max = |a: f64, b: f64| if a > b { a } else { b };
    let block = 2 * w + 1;
    let (prefix, suffix) = work.split_at_mut(n);
    // prefix[i]: max from the start of i's block to i; suffix[i]: max from i to its block's end.
    let mut start = 0;
    while start < n {
        let end = (start + block).min(n);
        prefix[start] = src[start];
        for i in start + 1..end {
            prefix[i] = max(prefix[i - 1], src[i]);
        }
        suffix[end - 1] = src[end - 1];
        for i in (start..end - 1).rev() {
            suffix[i] = max(suffix[i + 1], src[i]);
        }
        start = end;
    }
    // A window of at most one block spans at most two blocks. Inside one block it either starts
    // at the block's start (use the prefix of its end) or ends at the signal's end (the suffix).
    let mut lo_block = 0;
    for (i, d) in dst.iter_mut().enumerate() {
        let lo = i.saturating_sub(w);
        let hi = (i + w).min(n - 1);
        if lo >= lo_block + block {
            lo_block += block;
        }
        *d = if hi >= lo_block + block {
            max(suffix[lo], prefix[hi])
        } else if lo == lo_block {
            prefix[hi]
        } else {
            suffix[lo]
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn matches_the_brute_force_maximum_at_every_width_and_length() {
        // Lengths around multiples of the block, widths from none to wider than the sequence.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for n in [1usize, 2, 5, 9, 10, 11, 64, 101] {
            let src: Vec<f64> = (0..n).map(|_| rng.random_range(-0.5..0.5)).collect();
            for w in [0usize, 1, 2, 4, 5, 13, 200] {
                let mut dst = vec![f64::NAN; n];
                let mut work = vec![0.0; 2 * n];
                sliding_max(&src, w, &mut dst, &mut work);
                for (i, got) in dst.iter().enumerate() {
                    let (lo, hi) = (i.saturating_sub(w), (i + w).min(n - 1));
                    let want = src[lo..=hi].iter().copied().fold(f64::MIN, f64::max);
                    assert_eq!(*got, want, "n {n} w {w} i {i}");
                }
            }
        }
    }
}
