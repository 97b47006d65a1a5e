//! Reading one label's pitch from its spectrum: the coarse-to-fine comb search, a known or
//! given F0, and the salience re-measured against the mixture's local level.

use super::comb::{COARSE, Comb, REFINED, Score};
use super::{Harmonic, Periodicity, Pitch, Register, power};
use crate::dsp::VoicePitch;

impl Harmonic {
    /// The divisor of each bin's magnitude in a contest salience, for bins `lo..len`: the
    /// mixture's RMS magnitude over the whitening band around the bin (`bin_power(k)` is the
    /// mixture's power in bin k), to the power `salience_whitening`. Other bins, and every bin
    /// without whitening, get 1.
    pub fn whitening(
        &self,
        bin_power: impl Fn(usize) -> f64,
        lo: usize,
        len: usize,
        out: &mut Vec<f64>,
    ) {
        out.clear();
        out.resize(len, 1.0);
        if self.salience_whitening <= 0.0 || lo >= len {
            return;
        }
        let hw = self.whitening_half_width;
        // A window sliding over [max(lo, k - hw), min(len - 1, k + hw)].
        let (mut sum, mut count) = (0.0, 0usize);
        for j in lo..(lo + hw + 1).min(len) {
            sum += bin_power(j);
            count += 1;
        }
        let e = 0.5 * self.salience_whitening;
        for (k, o) in out.iter_mut().enumerate().take(len).skip(lo) {
            let mean = sum.max(0.0) / count.max(1) as f64;
            *o = if mean > 0.0 { power(mean, e) } else { 1.0 };
            if k >= lo + hw {
                sum -= bin_power(k - hw);
                count -= 1;
            }
            if k + hw + 1 < len {
                sum += bin_power(k + hw + 1);
                count += 1;
            }
        }
    }

    /// Re-measures `p`'s salience, the strength it contests harmonics with, on `mag` divided by
    /// the mixture's local level `level` (from [`Harmonic::whitening`]), so the loud harmonics
    /// below about 500 Hz, where spatial gains are least reliable, do not decide alone. The
    /// F0 itself was found on `mag`. `whitened` and `scratch` are scratch.
    pub fn whiten_salience(
        &self,
        p: &mut Pitch,
        mag: &[f64],
        level: &[f64],
        reliability: &[f64],
        whitened: &mut Vec<f64>,
        scratch: &mut Vec<[f64; 4]>,
    ) {
        // A NaN F0 is no pitch either.
        if self.salience_whitening <= 0.0 || p.f0.is_nan() || p.f0 <= 0.0 {
            return;
        }
        whitened.clear();
        whitened.extend(mag.iter().zip(level).map(|(m, l)| m / l));
        if let Some((_, salience, _)) = self.score_at(whitened, reliability, p.f0, scratch) {
            p.salience = salience.max(0.0);
        }
    }

    /// The pitch of a magnitude spectrum `mag` (one value per bin from 0), reading bin k with
    /// weight `reliability[k]` (0 ignores it), preferring F0s inside the label's `register`.
    /// `scratch` holds the interpolation table.
    ///
    /// Coarse to fine: the comb is scored on every `COARSE`th candidate with the harmonics up
    /// to `COARSE_TOP_HZ`, then with all of them on the fine grid around the `REFINED` best
    /// coarse ones (a fraction of the exhaustive search's work; the selection score varies
    /// smoothly enough over a coarse step that the exhaustive search's winner lies next to one
    /// of the best coarse candidates). With the frame's `periodicity` read, each candidate's
    /// comb is also weighed by the autocorrelation at its period.
    pub fn pitch(
        &self,
        mag: &[f64],
        reliability: &[f64],
        register: &Register,
        periodicity: Option<&Periodicity>,
        scratch: &mut Vec<[f64; 4]>,
    ) -> Pitch {
        let Some(comb) = Comb::new(mag, reliability, self.k_max, self.hz_per_bin, scratch) else {
            return Pitch::default();
        };
        let (register, periodic) = (self.preference(register), self.periodic_weight(periodicity));
        let prefer = |f0: f64| register(f0) * periodic(f0);
        let mut best = (0.0, Score::default(), 0.0);
        for range in self.refined_ranges(&comb, &prefer) {
            comb.best(&self.candidates[range], prefer, &mut best);
        }
        let mut p = self.pitch_of(best.0, best.1);
        if p.f0 > 0.0 {
            p.register_fit = power(register(p.f0), self.register_ownership);
        }
        p
    }

    /// The fine-grid ranges of candidates around the `REFINED` best coarse candidates by
    /// selection score times `prefer` (read up to `COARSE_TOP_HZ`), best first.
    pub(super) fn refined_ranges(
        &self,
        comb: &Comb,
        prefer: impl Fn(f64) -> f64,
    ) -> impl Iterator<Item = std::ops::Range<usize>> {
        let n = self.candidates.len();
        let mut top = [(usize::MAX, 0.0f64); REFINED];
        for i in (0..n).step_by(COARSE) {
            let f0 = self.candidates[i];
            let select = comb.score_below(f0, self.k_coarse).2 * prefer(f0);
            if let Some(at) = top.iter().position(|t| select > t.1) {
                top[at..].rotate_right(1);
                top[at] = (i, select);
            }
        }
        top.into_iter()
            .filter(|t| t.0 != usize::MAX)
            .map(move |(centre, _)| centre.saturating_sub(COARSE - 1)..(centre + COARSE).min(n))
    }

    /// The pitch of `mag` (read as [`Harmonic::pitch`] reads it) when its F0 and voicing are
    /// known: only the comb's salience there is measured.
    pub fn known_pitch(
        &self,
        mag: &[f64],
        reliability: &[f64],
        known: VoicePitch,
        scratch: &mut Vec<[f64; 4]>,
    ) -> Pitch {
        if !(known.f0 > 0.0 && known.voicing > 0.0 && known.f0.is_finite()) {
            return Pitch::default();
        }
        match self.score_at(mag, reliability, known.f0, scratch) {
            Some((_, salience, _)) => Pitch {
                f0: known.f0,
                voicing: known.voicing.clamp(0.0, 1.0),
                salience: salience.max(0.0),
                register_fit: 1.0,
            },
            None => Pitch::default(),
        }
    }

    /// The pitch of `mag` (read as [`Harmonic::pitch`] reads it) when only its F0 is known: the
    /// comb's voicing and salience at that F0.
    pub fn pitch_at(
        &self,
        mag: &[f64],
        reliability: &[f64],
        f0: f64,
        scratch: &mut Vec<[f64; 4]>,
    ) -> Pitch {
        if !(f0 > 0.0 && f0.is_finite()) {
            return Pitch::default();
        }
        self.score_at(mag, reliability, f0, scratch)
            .map_or_else(Pitch::default, |score| self.pitch_of(f0, score))
    }

    /// The comb of `f0` on `mag` (read as [`Harmonic::pitch`] reads it); `None` when the
    /// spectrum is too short for one.
    fn score_at(
        &self,
        mag: &[f64],
        reliability: &[f64],
        f0: f64,
        scratch: &mut Vec<[f64; 4]>,
    ) -> Option<Score> {
        Comb::new(mag, reliability, self.k_max, self.hz_per_bin, scratch).map(|c| c.score(f0))
    }

    /// The exhaustive search over every candidate (the reference of [`Harmonic::pitch`]).
    #[cfg(test)]
    pub(super) fn pitch_exhaustive(&self, mag: &[f64], reliability: &[f64]) -> Pitch {
        let mut scratch = Vec::new();
        let Some(comb) = Comb::new(mag, reliability, self.k_max, self.hz_per_bin, &mut scratch)
        else {
            return Pitch::default();
        };
        let mut best = (0.0, Score::default(), 0.0);
        comb.best(&self.candidates, |_| 1.0, &mut best);
        self.pitch_of(best.0, best.1)
    }

    pub(super) fn pitch_of(&self, f0: f64, (score, salience, _): Score) -> Pitch {
        let v =
            ((score - self.voicing_low) / (self.voicing_high - self.voicing_low)).clamp(0.0, 1.0);
        if !(v.is_finite() && salience.is_finite()) || f0 <= 0.0 {
            return Pitch::default();
        }
        Pitch {
            f0,
            voicing: v,
            salience: salience.max(0.0),
            register_fit: 1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{FS, N, harmonic, harmonic_with, spectrum, voiced};
    use super::*;
    use crate::separate::config::HarmonicConfig;

    /// The analysis, full reliability, a voice's magnitudes at 150 Hz and comb scratch.
    fn voice_at_150_hz() -> (Harmonic, Vec<f64>, Vec<f64>, Vec<[f64; 4]>) {
        let mag = spectrum(&voiced(150.0, 1.0));
        (harmonic(), vec![1.0; N / 2 + 1], mag, Vec::new())
    }

    #[test]
    fn a_known_pitch_is_kept_and_its_combs_salience_measured() {
        let (h, rel, mag, mut scratch) = voice_at_150_hz();
        let known = |f0, voicing| VoicePitch { f0, voicing };
        let right = h.known_pitch(&mag, &rel, known(150.0, 0.8), &mut scratch);
        assert_eq!((right.f0, right.voicing), (150.0, 0.8));
        // The comb measured at the known F0 is the one the search would find; at a pitch the
        // spectrum does not carry it is far weaker.
        let searched = h.pitch(&mag, &rel, &Register::default(), None, &mut scratch);
        assert!(
            (right.salience / searched.salience - 1.0).abs() < 0.05,
            "{right:?} {searched:?}"
        );
        let wrong = h.known_pitch(&mag, &rel, known(190.0, 1.0), &mut scratch);
        assert!(wrong.salience < 0.2 * right.salience, "{wrong:?} {right:?}");
        // Unvoiced (or nonsense) known pitches give no comb.
        for k in [known(150.0, 0.0), known(0.0, 1.0), known(f64::NAN, 1.0)] {
            assert_eq!(h.known_pitch(&mag, &rel, k, &mut scratch), Pitch::default());
        }
    }

    #[test]
    fn a_known_f0_is_read_with_the_combs_own_voicing_there() {
        let (h, rel, mag, mut scratch) = voice_at_150_hz();
        // At the voice's F0 the comb is what the search finds, voicing and salience alike.
        let right = h.pitch_at(&mag, &rel, 150.0, &mut scratch);
        let searched = h.pitch(&mag, &rel, &Register::default(), None, &mut scratch);
        assert_eq!(right.f0, 150.0);
        assert!(
            (right.voicing - searched.voicing).abs() < 0.05
                && (right.salience / searched.salience - 1.0).abs() < 0.05,
            "{right:?} {searched:?}"
        );
        // At an F0 the spectrum does not carry, the comb reads as unvoiced.
        let wrong = h.pitch_at(&mag, &rel, 190.0, &mut scratch);
        assert_eq!(wrong.f0, 190.0);
        assert!(wrong.voicing < 0.5 * right.voicing, "{wrong:?} {right:?}");
        // A silent or nonsense F0 gives no comb.
        for f0 in [0.0, -150.0, f64::NAN] {
            assert_eq!(h.pitch_at(&mag, &rel, f0, &mut scratch), Pitch::default());
        }
    }

    #[test]
    fn of_two_combs_the_one_at_the_frames_periodic_lag_wins() {
        // Two voices equally strong in the comb's spectrum; the autocorrelation (here read from
        // each voice alone, to make the point) decides between them, and without a weight or
        // without a frame read the search is the comb's alone.
        let h = harmonic();
        let rel = vec![1.0; N / 2 + 1];
        let (a, b) = (voiced(150.0, 1.0), voiced(200.0, 1.0));
        let both: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + y).collect();
        let mag = spectrum(&both);
        let mut per = Periodicity::new(N, FS, 70.0, 400.0);
        let search = |h: &Harmonic, per: Option<&Periodicity>| {
            h.pitch(&mag, &rel, &Register::default(), per, &mut Vec::new())
                .f0
        };
        let alone = search(&h, None);
        for f0 in [150.0, 200.0] {
            let own = spectrum(&voiced(f0, 1.0));
            let _ = per.peak(|k| own[k], 1, own.len());
            let got = search(&h, Some(&per));
            assert!(
                (got / f0 - 1.0).abs() < 0.01,
                "{f0} Hz periodic: read {got}"
            );
        }
        let cfg = HarmonicConfig {
            periodicity_weight: 0.0,
            ..HarmonicConfig::default()
        };
        let off = harmonic_with(&cfg);
        assert_eq!(search(&off, Some(&per)), alone);
    }
}
