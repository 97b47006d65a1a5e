//! Reporting: hysteresis on the instantaneous estimate and smoothing of `speaking`.
//!
//! The GLMB estimator is instantaneous and can drop a label for a single step (spec 000 3.7
//! caveat); labels key the separated streams downstream, so a label reported in the previous step
//! keeps being reported for a few steps while its existence stays above a lower threshold.

use std::collections::HashMap;

use super::TrackEstimate;
use super::config::EstimatorConfig;
use crate::label::Label;

#[derive(Debug, Clone, Copy)]
struct LabelState {
    missing: u32,
    speaking: f64,
}

/// Per-label reporting state.
#[derive(Debug, Clone)]
pub(crate) struct Reporter {
    cfg: EstimatorConfig,
    smoothing: f64,
    states: HashMap<Label, LabelState>,
}

impl Reporter {
    /// A reporter with the given hysteresis and speaking smoothing weight.
    pub fn new(cfg: &EstimatorConfig, smoothing: f64) -> Self {
        Self {
            cfg: cfg.clone(),
            smoothing,
            states: HashMap::new(),
        }
    }

    /// Forgets every label.
    pub fn reset(&mut self) {
        self.states.clear();
    }

    /// The step's report. `estimated` is the estimator's set (with the raw speaking
    /// probability); `fallback` holds the best estimate of every label still in the posterior,
    /// used for labels kept by the hysteresis. `audio` says whether an audio sensor reported
    /// (without one the speaking values are left as they were).
    pub fn report(
        &mut self,
        estimated: Vec<TrackEstimate>,
        fallback: &HashMap<Label, TrackEstimate>,
        audio: bool,
    ) -> Vec<TrackEstimate> {
        let alpha = self.smoothing;
        let smooth = |st: &mut LabelState, raw: f64| {
            if audio {
                st.speaking += alpha * (raw - st.speaking);
            }
        };
        let mut out = Vec::with_capacity(estimated.len());
        for mut e in estimated {
            match self.states.get_mut(&e.label) {
                Some(st) => {
                    st.missing = 0;
                    smooth(st, e.speaking);
                    e.speaking = st.speaking;
                }
                None => {
                    let speaking = if audio { e.speaking } else { 0.0 };
                    self.states.insert(
                        e.label,
                        LabelState {
                            missing: 0,
                            speaking,
                        },
                    );
                    e.speaking = speaking;
                }
            }
            out.push(e);
        }
        let reported: Vec<Label> = out.iter().map(|e| e.label).collect();
        let (steps, min_existence) = (self.cfg.hysteresis_steps, self.cfg.hysteresis_existence);
        self.states.retain(|label, st| {
            if reported.contains(label) {
                return true;
            }
            match fallback.get(label) {
                Some(e) if st.missing < steps && e.existence >= min_existence => {
                    st.missing += 1;
                    smooth(st, e.speaking);
                    let mut e = e.clone();
                    e.speaking = st.speaking;
                    out.push(e);
                    true
                }
                _ => false,
            }
        });
        out.sort_by_key(|e| e.label);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use nalgebra::Matrix6;

    fn est(label: Label, existence: f64, speaking: f64) -> TrackEstimate {
        TrackEstimate {
            label,
            position: Vec3::zeros(),
            velocity: Vec3::zeros(),
            covariance: Matrix6::identity(),
            existence,
            speaking,
        }
    }

    #[test]
    fn keeps_a_briefly_missing_label_then_ends_it() {
        let cfg = EstimatorConfig {
            hysteresis_steps: 2,
            hysteresis_existence: 0.2,
        };
        let mut r = Reporter::new(&cfg, 0.5);
        let l = Label::new(1, 0);
        let out = r.report(vec![est(l, 0.9, 1.0)], &HashMap::new(), true);
        assert_eq!(out[0].speaking, 1.0);
        let mut fb = HashMap::new();
        fb.insert(l, est(l, 0.4, 0.0));
        // Missing from the estimate for two steps: still reported, speaking decays.
        let out = r.report(vec![], &fb, true);
        assert_eq!(out.len(), 1);
        assert!((out[0].speaking - 0.5).abs() < 1e-12);
        assert_eq!(r.report(vec![], &fb, true).len(), 1);
        // Third step: the hysteresis is exhausted.
        assert!(r.report(vec![], &fb, true).is_empty());
        // Low existence ends a label at once.
        let l2 = Label::new(2, 0);
        r.report(vec![est(l2, 0.9, 0.0)], &HashMap::new(), false);
        fb.insert(l2, est(l2, 0.05, 0.0));
        assert!(r.report(vec![], &fb, false).is_empty());
    }
}
