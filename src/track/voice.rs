//! The talking/silent mode of a track (see [`VoiceConfig`]): a two-state Markov chain whose
//! state sets the audio detection probability.

use super::config::VoiceConfig;

/// Transition rates of the talking/silent mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct VoiceModel {
    enabled: bool,
    /// Rate (1/s) at which talking stops.
    stop_per_s: f64,
    /// Rate (1/s) at which silence ends.
    start_per_s: f64,
    initial: f64,
}

impl VoiceModel {
    /// The model of the configuration.
    pub fn new(cfg: &VoiceConfig) -> Self {
        Self {
            enabled: cfg.enabled,
            stop_per_s: 1.0 / cfg.mean_talk_s,
            start_per_s: 1.0 / cfg.mean_pause_s,
            initial: cfg.initial_talking,
        }
    }

    /// Talking probability of a new track (1 when the mode is not modelled).
    pub fn initial(&self) -> f64 {
        if self.enabled { self.initial } else { 1.0 }
    }

    /// Talking probability after `dt` seconds.
    pub fn predict(&self, p: f64, dt: f64) -> f64 {
        if !self.enabled {
            return 1.0;
        }
        let dt = dt.max(0.0);
        let stop = -(-self.stop_per_s * dt).exp_m1();
        let start = -(-self.start_per_s * dt).exp_m1();
        (p * (1.0 - stop) + (1.0 - p) * start).clamp(0.0, 1.0)
    }
}

/// Probability of an audio sensor's outcome (detected or missed) for a track that talks with
/// probability `p`, and the talking probability after it.
pub(crate) fn audio_outcome(p: f64, pd_talk: f64, pd_silent: f64, detected: bool) -> (f64, f64) {
    let (a, b) = if detected {
        (p * pd_talk, (1.0 - p) * pd_silent)
    } else {
        (p * (1.0 - pd_talk), (1.0 - p) * (1.0 - pd_silent))
    };
    let f = a + b;
    if f > 0.0 { (f, a / f) } else { (0.0, p) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pause_lowers_the_talking_probability_and_the_miss_penalty() {
        let m = VoiceModel::new(&VoiceConfig::default());
        let mut p = 0.95;
        let mut penalty = 1.0;
        let mut first = 0.0;
        for k in 0..16 {
            p = m.predict(p, 0.128);
            let (f, q) = audio_outcome(p, 0.6, 0.02, false);
            if k == 0 {
                first = f;
            }
            penalty *= f;
            p = q;
        }
        // The first miss costs about 1 - 0.6; later ones little: a 2 s pause costs far less
        // than 0.4^16 = 4e-7.
        assert!(first < 0.5, "{first}");
        assert!(p < 0.1, "{p}");
        assert!(penalty > 1e-3, "{penalty}");
        // A detection brings the mode back to talking.
        let (_, q) = audio_outcome(m.predict(p, 0.128), 0.6, 0.02, true);
        assert!(q > 0.5, "{q}");
        // Disabled: always talking, plain P_D.
        let off = VoiceModel::new(&VoiceConfig {
            enabled: false,
            ..VoiceConfig::default()
        });
        assert_eq!(off.predict(0.3, 1.0), 1.0);
        assert_eq!(audio_outcome(1.0, 0.6, 0.02, false).0, 0.4);
    }
}
