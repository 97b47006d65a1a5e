//! Scale-invariant SDR (Le Roux, Wisdom, Erdogan & Hershey 2019).

use super::sample_set::SampleSet;

/// Largest magnitude a decibel figure takes: a perfect estimate scores this instead of +inf.
pub const DB_LIMIT: f64 = 200.0;

/// `10 log10(num / den)` for energies, kept finite: ratios are clamped to +-[`DB_LIMIT`] dB.
pub fn db_ratio(num: f64, den: f64) -> f64 {
    let num = if num.is_finite() { num.max(0.0) } else { 0.0 };
    let den = if den.is_finite() { den.max(0.0) } else { 0.0 };
    let floor = (num + den) * 10f64.powf(-DB_LIMIT / 10.0) + f64::MIN_POSITIVE;
    (10.0 * (num.max(floor) / den.max(floor)).log10()).clamp(-DB_LIMIT, DB_LIMIT)
}

/// SI-SDR (dB) of `estimate` against `reference` over the samples `set`, both made zero-mean
/// over the set first: `10 log10(|a s|^2 / |a s - e|^2)` with `a = <e, s> / <s, s>`.
pub fn si_sdr(estimate: &[f64], reference: &[f64], set: &SampleSet) -> f64 {
    let n = set.len().max(1) as f64;
    let at = |x: &[f64], i: usize| x.get(i).copied().unwrap_or(0.0);
    let mean_e = set.indices().map(|i| at(estimate, i)).sum::<f64>() / n;
    let mean_s = set.indices().map(|i| at(reference, i)).sum::<f64>() / n;
    let (mut es, mut ss, mut ee) = (0.0, 0.0, 0.0);
    for i in set.indices() {
        let e = at(estimate, i) - mean_e;
        let s = at(reference, i) - mean_s;
        es += e * s;
        ss += s * s;
        ee += e * e;
    }
    // A silent reference or estimate carries nothing of the source.
    if ss <= 0.0 || ee <= 0.0 {
        return -DB_LIMIT;
    }
    // |a s|^2 = <e,s>^2 / <s,s>; the residual is orthogonal to s, so |e - a s|^2 = |e|^2 - that.
    let target = es * es / ss;
    db_ratio(target, ee - target)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let d = Normal::new(0.0, 1.0).unwrap();
        (0..n).map(|_| d.sample(&mut rng)).collect()
    }

    #[test]
    fn a_scaled_copy_is_perfect() {
        let s = noise(4000, 1);
        let e: Vec<f64> = s.iter().map(|v| -0.3 * v).collect();
        assert!(si_sdr(&e, &s, &SampleSet::all(4000)) > 150.0);
    }

    #[test]
    fn added_noise_at_known_power() {
        let s = noise(20000, 2);
        let n = noise(20000, 3);
        // Noise 10 dB below the signal: the noise is almost orthogonal to s, so SI-SDR ~ 10 dB.
        let g = 10f64.powf(-10.0 / 20.0);
        let e: Vec<f64> = s.iter().zip(&n).map(|(a, b)| a + g * b).collect();
        let v = si_sdr(&e, &s, &SampleSet::all(20000));
        assert!((v - 10.0).abs() < 0.2, "{v}");
    }

    #[test]
    fn only_the_given_samples_count() {
        let s = noise(2000, 4);
        let mut e = s.clone();
        for x in &mut e[1000..] {
            *x = 0.0;
        }
        let first = SampleSet::from_ranges([(0, 1000)], 2000);
        assert!(si_sdr(&e, &s, &first) > 150.0);
        assert!(si_sdr(&e, &s, &SampleSet::all(2000)) < 5.0);
    }

    #[test]
    fn silence_gives_finite_figures() {
        let z = vec![0.0; 100];
        assert_eq!(si_sdr(&z, &z, &SampleSet::all(100)), -DB_LIMIT);
        let s = noise(100, 5);
        assert_eq!(si_sdr(&z, &s, &SampleSet::all(100)), -DB_LIMIT);
        assert_eq!(db_ratio(1.0, 0.0), DB_LIMIT);
        assert!((db_ratio(10.0, 1.0) - 10.0).abs() < 1e-12);
    }
}
