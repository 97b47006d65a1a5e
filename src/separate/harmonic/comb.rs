//! The peak-minus-valley harmonic comb that scores F0 candidates on one magnitude spectrum,
//! and the analysis window's response that says how far a harmonic spreads over the bins.

/// Coarse candidate spacing of the F0 search (in fine grid steps).
pub(super) const COARSE: usize = 4;
/// Coarse candidates refined on the fine grid.
pub(super) const REFINED: usize = 4;

/// A comb's normalised score, its salience (mean peak-minus-valley magnitude) and its
/// selection score.
pub(super) type Score = (f64, f64, f64);

/// One spectrum's interpolation table for scoring harmonic combs.
pub(super) struct Comb<'a> {
    /// Per bin: the magnitude and reliability there and at the next bin (the last bin's next is
    /// itself), so each linear interpolation reads one entry.
    table: &'a [[f64; 4]],
    kmax: f64,
    hz_per_bin: f64,
}

impl<'a> Comb<'a> {
    pub(super) fn new(
        mag: &[f64],
        reliability: &[f64],
        k_max: f64,
        hz_per_bin: f64,
        scratch: &'a mut Vec<[f64; 4]>,
    ) -> Option<Self> {
        let len = mag.len().min(reliability.len());
        let kmax = k_max.min(len as f64 - 1.0);
        if kmax < 2.0 {
            return None;
        }
        scratch.clear();
        scratch.extend((0..len).map(|i| {
            let j = (i + 1).min(len - 1);
            [mag[i], mag[j], reliability[i], reliability[j]]
        }));
        Some(Self {
            table: scratch,
            kmax,
            hz_per_bin,
        })
    }

    /// Raises `best` to the best of `f0s` by selection score times `prefer(f0)` (the first of
    /// equals); the kept score is the comb's own.
    pub(super) fn best(
        &self,
        f0s: &[f64],
        prefer: impl Fn(f64) -> f64,
        best: &mut (f64, Score, f64),
    ) {
        for &f0 in f0s {
            let sc = self.score(f0);
            let select = sc.2 * prefer(f0);
            if select > best.2 {
                *best = (f0, sc, select);
            }
        }
    }

    /// Peak-minus-valley comb of `f0` over the harmonics up to `kmax`, each weighted by its
    /// bin's reliability.
    pub(super) fn score(&self, f0: f64) -> Score {
        self.score_below(f0, self.kmax)
    }

    /// [`Comb::score`] over the harmonics up to bin `kmax` only (at most the comb's own top).
    pub(super) fn score_below(&self, f0: f64, kmax: f64) -> Score {
        let kmax = kmax.min(self.kmax);
        let table = self.table;
        // 0 <= x <= kmax < len: truncation is the floor.
        let entry = |x: f64| {
            let i = x as usize;
            (&table[i.min(table.len() - 1)], x - i as f64)
        };
        let step = f0 / self.hz_per_bin;
        // One harmonic's terms (weighted peak-minus-valley, peak-plus-valley, weight).
        // Branch-free: a bin of no reliability (w = 0) adds zeros, as a branch on it would,
        // without the mispredictions of the reliability's gaps.
        let term = |x: f64| -> [f64; 3] {
            let (e, t) = entry(x);
            let w = e[2] * (1.0 - t) + e[3] * t;
            let peak = e[0] * (1.0 - t) + e[1] * t;
            let (v, tv) = entry(x - 0.5 * step);
            let valley = v[0] * (1.0 - tv) + v[1] * tv;
            [w * (peak - valley), w * (peak + valley), w]
        };
        // Odd and even harmonics in two sums: the sums' chains of dependent additions, not the
        // table reads, set the time of this loop.
        let (mut odd, mut even) = ([0.0; 3], [0.0; 3]);
        let mut x = step;
        while x + step <= kmax {
            let (a, b) = (term(x), term(x + step));
            for q in 0..3 {
                odd[q] += a[q];
                even[q] += b[q];
            }
            x += 2.0 * step;
        }
        if x <= kmax {
            let a = term(x);
            for q in 0..3 {
                odd[q] += a[q];
            }
        }
        let (num, den, wsum) = (odd[0] + even[0], odd[1] + even[1], odd[2] + even[2]);
        // The normalised score alone ties F0 with its odd multiples (their valleys fall on
        // inter-harmonic gaps too) and the peak sum alone ties it with F0 / 2; their product
        // peaks at F0 only.
        let score = if den > 1e-300 { num / den } else { 0.0 };
        let salience = if wsum > 0.0 { num / wsum } else { 0.0 };
        (score, salience, num.max(0.0) * score)
    }
}

/// Samples per bin of the tabulated window response: linear interpolation between them is
/// within 2e-7 of the exact value, and the table spares a `sin` per comb and bin.
const HANN_TABLE_PER_BIN: usize = 2048;

/// The window's power response at `2 * HANN_TABLE_PER_BIN + 1` points over [0, 2] bins.
static HANN_TABLE: std::sync::LazyLock<Vec<f64>> = std::sync::LazyLock::new(|| {
    (0..=2 * HANN_TABLE_PER_BIN)
        .map(|i| hann_power_exact(i as f64 / HANN_TABLE_PER_BIN as f64))
        .collect()
});

/// The tabulated window response, held by its user: a lookup through it inlines, without the
/// table's initialisation check on every call.
#[derive(Debug, Clone, Copy)]
pub(super) struct HannTable(&'static [f64]);

impl HannTable {
    pub(super) fn new() -> Self {
        Self(HANN_TABLE.as_slice())
    }

    /// Power response of the periodic Hann window at `d` bins from a sinusoid (1 at 0, 0 from
    /// 2), interpolated in the table.
    #[inline]
    pub(super) fn power(self, d: f64) -> f64 {
        let d = d.abs();
        if d.is_nan() || d >= 2.0 {
            return 0.0;
        }
        let x = d * HANN_TABLE_PER_BIN as f64;
        let i = x as usize;
        match (self.0.get(i), self.0.get(i + 1)) {
            (Some(a), Some(b)) => a + (x - i as f64) * (b - a),
            _ => 0.0,
        }
    }
}

/// [`HannTable::power`] computed exactly.
fn hann_power_exact(d: f64) -> f64 {
    if d >= 2.0 {
        return 0.0;
    }
    if d < 1e-9 {
        return 1.0;
    }
    if (d - 1.0).abs() < 1e-9 {
        return 0.25;
    }
    let x = std::f64::consts::PI * d;
    let a = x.sin() / x / (1.0 - d * d);
    a * a
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tabulated_window_response_matches_the_exact_one() {
        let table = HannTable::new();
        let hann_power = |d: f64| table.power(d);
        let mut worst = 0.0f64;
        for i in 0..=40_000 {
            let d = i as f64 * 2.2 / 40_000.0;
            worst = worst.max((hann_power(d) - hann_power_exact(d)).abs());
            assert_eq!(hann_power(-d), hann_power(d));
        }
        assert!(worst < 2e-7, "worst {worst}");
        assert_eq!(hann_power(0.0), 1.0);
        assert!((hann_power(1.0) - 0.25).abs() < 1e-12);
        assert_eq!(hann_power(2.0), 0.0);
        assert_eq!(hann_power(f64::NAN), 0.0);
    }

    #[test]
    fn the_comb_sums_every_harmonic_up_to_its_top_once() {
        // A spectrum with structure everywhere and gaps in the reliability, scored against a
        // plain one-harmonic-at-a-time sum, for combs with odd and even harmonic counts.
        let len = 300;
        let mag: Vec<f64> = (0..len)
            .map(|k| 1.0 + (k as f64 * 0.37).sin().abs())
            .collect();
        let rel: Vec<f64> = (0..len)
            .map(|k| if k % 7 == 3 { 0.0 } else { 0.8 })
            .collect();
        let hz = 15.625;
        let mut scratch = Vec::new();
        let comb = Comb::new(&mag, &rel, 250.0, hz, &mut scratch).expect("a comb");
        let lerp = |v: &[f64], x: f64| {
            let i = x as usize;
            v[i] + (x - i as f64) * (v[(i + 1).min(len - 1)] - v[i])
        };
        for (f0, kmax) in [
            (100.0, 250.0),
            (113.0, 64.0),
            (87.5, 57.0),
            (250.0, 16.0),
            (250.0, 40.0),
        ] {
            let step = f0 / hz;
            let (mut num, mut den, mut wsum, mut count) = (0.0, 0.0, 0.0, 0);
            let mut h = 1.0;
            while h * step <= kmax + 1e-9 {
                let x = h * step;
                let w = lerp(&rel, x);
                if w > 0.0 {
                    let (peak, valley) = (lerp(&mag, x), lerp(&mag, x - 0.5 * step));
                    num += w * (peak - valley);
                    den += w * (peak + valley);
                    wsum += w;
                }
                count += 1;
                h += 1.0;
            }
            let (score, salience, select) = comb.score_below(f0, kmax);
            assert!(count >= 1, "{f0} Hz: no harmonic");
            assert!(
                (score - num / den).abs() < 1e-9,
                "{f0} Hz: {score} against {}",
                num / den
            );
            assert!((salience - num / wsum).abs() < 1e-9, "{f0} Hz: {salience}");
            assert!(
                (select - num.max(0.0) * num / den).abs() < 1e-9,
                "{f0} Hz: {select}"
            );
        }
    }
}
