//! Each track's `speaking`: a two-state (talking / pause) Markov chain per label, filtered step
//! by step with the likelihood ratio of the localiser's probe reading at the track.
//!
//! The probe ([`crate::localize::Localizer::probe`]) reads one frame alone, so a talker's reading
//! dips between syllables and in overlaps. Thresholding it (at `peaks.sounding_sigmas`) made the
//! reported `speaking` change 3.2 times for each true change (about two changes a second per
//! track). The chain's prior on spurts and pauses bridges those dips, and the strength of the
//! reading decides how far one step moves the belief: a reading of 30 sigma settles it, one of
//! 5 barely moves it.

use std::collections::HashMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::stages::Estimate;
use crate::field_error::FieldError;
use crate::label::Label;
use crate::track::ModeModel;

/// How the pipeline turns the probe's readings into `speaking`. (The tracker's own talking mode,
/// `track.voice`, is a chain of the same kind that only scales the audio detection probability;
/// its 2 s means suit that job, where a mode that lingers costs little.)
///
/// The likelihood ratio of a reading of s null standard deviations is
/// `exp(slope_per_sigma x (s - even_sigmas))`, bounded to [`min_ratio`, `max_ratio`]. Measured
/// ratios P(s | talking) / P(s | silent) at the tracks matched to true sources (full pipeline,
/// `paper-linear6` seeds 1-12, `uca8` three talkers seeds 1-6 and six real-speech scenes):
/// 0.23 below 1 sigma, 0.48 at 2-3, 1.1 at 4-5, 2.9 at 6-8, 9.8 at 10-15, 40 at 20-30 and 190
/// above 30; 14 % of the talking steps read below 1 sigma (mostly the quieter talker of an
/// overlap).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct SpeakingConfig {
    /// Mean length of a talk spurt (s): how long the chain expects talking to go on. Both
    /// means at 1 s against 2 s (a prototype with the ratio bounded to 0.25-20, on the scenes
    /// above): 14 % against 18 % of silent steps read as speaking, 1.58 against 1.34 changes
    /// per true change, 84 % of steps read right either way.
    pub mean_talk_s: f64,
    /// Mean length of a pause (s).
    pub mean_pause_s: f64,
    /// Reading (null standard deviations) as likely from a talker as from silence.
    pub even_sigmas: f64,
    /// Growth of the natural log of the likelihood ratio per null standard deviation.
    pub slope_per_sigma: f64,
    /// Lower bound of a reading's likelihood ratio. Readings are never negative, so at the
    /// default slope no reading comes near it (0 reads 0.27, near the measured 0.23); it keeps
    /// a steeper slope from letting one silent step undo a talk spurt.
    pub min_ratio: f64,
    /// Upper bound of a reading's likelihood ratio: one strong reading moves a settled silence
    /// (about 0.05) to about 0.9, short of certainty.
    pub max_ratio: f64,
}

impl Default for SpeakingConfig {
    fn default() -> Self {
        Self {
            mean_talk_s: 1.0,
            mean_pause_s: 1.0,
            even_sigmas: 4.3,
            slope_per_sigma: 0.3,
            min_ratio: 0.1,
            max_ratio: 50.0,
        }
    }
}

impl SpeakingConfig {
    /// Checks the ranges; the error names the field.
    pub fn validate(&self) -> Result<(), FieldError> {
        let positive = |v: f64, field: &str, max: f64| {
            FieldError::check(
                v.is_finite() && v > 0.0 && v <= max,
                field,
                &format!("must be in (0, {max}]"),
            )
        };
        positive(self.mean_talk_s, "mean_talk_s", 60.0)?;
        positive(self.mean_pause_s, "mean_pause_s", 60.0)?;
        positive(self.slope_per_sigma, "slope_per_sigma", 10.0)?;
        FieldError::check(
            self.even_sigmas.is_finite() && (0.0..=100.0).contains(&self.even_sigmas),
            "even_sigmas",
            "must be in [0, 100]",
        )?;
        FieldError::check(
            self.min_ratio.is_finite() && self.min_ratio > 0.0 && self.min_ratio <= 1.0,
            "min_ratio",
            "must be in (0, 1]",
        )?;
        // At 1 no reading could ever raise the belief above the chain's own prior.
        FieldError::check(
            self.max_ratio.is_finite() && self.max_ratio > 1.0 && self.max_ratio <= 1e6,
            "max_ratio",
            "must be in (1, 1e6]",
        )
    }
}

/// Per-label belief that the track talks, updated once per tracker step.
#[derive(Debug, Clone)]
pub struct SpeakingFilter {
    cfg: SpeakingConfig,
    chain: ModeModel,
    step_s: f64,
    /// Where a new label starts: the stepped chain's stationary probability of talking.
    stationary: f64,
    beliefs: HashMap<Label, f64>,
}

impl SpeakingFilter {
    /// A filter for steps of `step_s` seconds.
    pub fn new(cfg: &SpeakingConfig, step_s: f64) -> Self {
        // The chain's own start probability is not used: new labels start at `stationary`.
        let chain = ModeModel::new(cfg.mean_talk_s, cfg.mean_pause_s, 0.5);
        Self {
            cfg: cfg.clone(),
            stationary: chain.stationary(step_s),
            chain,
            step_s,
            beliefs: HashMap::new(),
        }
    }

    /// The likelihood ratio (talking against silent) of a probe reading of `sigmas`; 1 (no
    /// evidence) for a reading that is not a number.
    pub fn likelihood_ratio(&self, sigmas: f64) -> f64 {
        if sigmas.is_nan() {
            return 1.0;
        }
        let c = &self.cfg;
        (c.slope_per_sigma * (sigmas - c.even_sigmas))
            .exp()
            .clamp(c.min_ratio, c.max_ratio)
    }

    /// One step: sets each estimate's `speaking` from its belief after `readings` (the probe at
    /// each estimate, in order). Labels no longer estimated are forgotten; a new label starts
    /// from the chain's stationary belief.
    pub fn update(&mut self, estimates: &mut [Estimate], readings: &[f64]) {
        debug_assert_eq!(estimates.len(), readings.len(), "one reading per estimate");
        self.beliefs
            .retain(|label, _| estimates.iter().any(|e| e.label == *label));
        for (e, &r) in estimates.iter_mut().zip(readings) {
            let prior = match self.beliefs.get(&e.label) {
                Some(&p) => self.chain.predict(p, self.step_s),
                None => self.stationary,
            };
            // The prior is in [0, 1] and the ratio finite and positive, so this is too.
            let lr = self.likelihood_ratio(r);
            let p = (prior * lr / (prior * lr + 1.0 - prior)).clamp(0.0, 1.0);
            self.beliefs.insert(e.label, p);
            e.speaking = p;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;

    const STEP: f64 = 0.128;

    fn estimate(label: Label) -> Estimate {
        Estimate {
            label,
            position: Vec3::new(1.0, 2.0, 1.6),
            velocity: Vec3::zeros(),
            existence: 1.0,
            speaking: 0.0,
            covariance: None,
        }
    }

    /// Runs one label through `readings`, returning its `speaking` after each step.
    fn run(f: &mut SpeakingFilter, readings: &[f64]) -> Vec<f64> {
        let mut e = [estimate(Label::new(1, 0))];
        readings
            .iter()
            .map(|&r| {
                f.update(&mut e, &[r]);
                e[0].speaking
            })
            .collect()
    }

    #[test]
    fn a_talker_reads_speaking_through_the_dips_between_syllables() {
        let mut f = SpeakingFilter::new(&SpeakingConfig::default(), STEP);
        // Silent, then talking with a missed step every third one.
        let mut readings = vec![0.5; 10];
        for k in 0..24 {
            readings.push(if k % 3 == 2 { 0.5 } else { 25.0 });
        }
        let s = run(&mut f, &readings);
        // A new label starts undecided (0.5) and settles within two steps of silence.
        assert!(s[..10].iter().all(|&p| p < 0.5), "{s:?}");
        assert!(s[2..10].iter().all(|&p| p < 0.1), "{s:?}");
        // Speaking from the first strong reading on, including every dip.
        assert!(s[10..].iter().all(|&p| p >= 0.5), "{s:?}");
    }

    #[test]
    fn a_talker_who_stops_reads_silent_within_a_few_steps() {
        let mut f = SpeakingFilter::new(&SpeakingConfig::default(), STEP);
        let mut readings = vec![30.0; 15];
        readings.extend([0.5; 10]);
        let s = run(&mut f, &readings);
        assert!(s[14] > 0.95);
        let off = s[15..].iter().position(|&p| p < 0.5).map(|k| k + 1);
        assert!(off.is_some_and(|n| n <= 3), "{s:?}");
        assert!(s[24] < 0.1, "{s:?}");
    }

    #[test]
    fn a_weak_stray_reading_in_silence_does_not_make_speech() {
        let mut f = SpeakingFilter::new(&SpeakingConfig::default(), STEP);
        let mut readings = vec![0.5; 10];
        readings.push(6.0);
        readings.extend([0.5; 3]);
        let s = run(&mut f, &readings);
        assert!(s.iter().all(|&p| p < 0.5), "{s:?}");
        // A strong one does, short of certainty.
        let s = run(&mut f, &[40.0]);
        assert!(s[0] > 0.8 && s[0] < 0.95, "{s:?}");
    }

    #[test]
    fn labels_keep_their_own_beliefs_and_are_forgotten_when_gone() {
        let mut f = SpeakingFilter::new(&SpeakingConfig::default(), STEP);
        let (a, b) = (Label::new(1, 0), Label::new(2, 0));
        let mut both = [estimate(a), estimate(b)];
        for _ in 0..8 {
            f.update(&mut both, &[30.0, 0.0]);
        }
        assert!(both[0].speaking > 0.95 && both[1].speaking < 0.1);
        let mut only_b = [estimate(b)];
        f.update(&mut only_b, &[0.0]);
        assert!(!f.beliefs.contains_key(&a));
        // A label seen again starts over from the stationary belief, not its old one.
        let mut a_again = [estimate(a)];
        f.update(&mut a_again, &[f64::NAN]);
        assert!((a_again[0].speaking - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_step_without_a_reading_only_lets_the_belief_drift_toward_undecided() {
        let mut f = SpeakingFilter::new(&SpeakingConfig::default(), STEP);
        let s = run(&mut f, &[30.0, 30.0, 30.0, f64::NAN, f64::NAN]);
        // The chain's prediction alone: a little less sure each step, not dropped.
        assert!(s[3] < s[2] && s[4] < s[3] && s[4] > 0.7, "{s:?}");
    }

    #[test]
    fn a_reading_that_is_not_a_number_leaves_only_the_prior() {
        let f = SpeakingFilter::new(&SpeakingConfig::default(), STEP);
        assert_eq!(f.likelihood_ratio(f64::NAN), 1.0);
        assert_eq!(f.likelihood_ratio(1e9), 50.0);
        assert_eq!(f.likelihood_ratio(-1e9), 0.1);
        assert!((f.likelihood_ratio(4.3) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn out_of_range_settings_are_named() {
        let cfg = SpeakingConfig {
            mean_pause_s: 0.0,
            ..SpeakingConfig::default()
        };
        assert_eq!(cfg.validate().unwrap_err().field, "mean_pause_s");
        let cfg = SpeakingConfig {
            min_ratio: 2.0,
            ..SpeakingConfig::default()
        };
        assert_eq!(cfg.validate().unwrap_err().field, "min_ratio");
        let cfg = SpeakingConfig {
            max_ratio: 1.0,
            ..SpeakingConfig::default()
        };
        assert_eq!(cfg.validate().unwrap_err().field, "max_ratio");
        assert!(SpeakingConfig::default().validate().is_ok());
        // In a pipeline configuration the field is named under its section.
        let err = crate::pipeline::PipelineConfig::parse("[speaking]\nmin_ratio = 2").unwrap_err();
        assert_eq!(err.field, "speaking.min_ratio");
    }
}
