//! Detectability modes of a track: two-state Markov chains ("on" / "off") whose state sets a
//! sensor's detection probability (see [`VoiceConfig`] and [`FaceConfig`]).
//!
//! Slot 0 is the voice (talking / silent), shared by every audio sensor, since talking is a
//! property of the person; each camera has its own slot (face towards / turned away from it),
//! since a face turned to one camera may be seen by another. A mode leaves the kinematic density
//! untouched and each sensor's outcome (detected or missed) updates the mode exactly, so the
//! augmented single-object density stays "Gaussian times a distribution over the modes" and the
//! GLMB update stays exact.

use super::config::{FaceConfig, VoiceConfig};
use super::sensor::Sensor;

/// Transition rates of one mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ModeModel {
    /// Rate (1/s) at which "on" ends.
    stop_per_s: f64,
    /// Rate (1/s) at which "off" ends.
    start_per_s: f64,
    /// Probability that a new track is "on".
    initial: f64,
}

impl ModeModel {
    /// A chain whose "on" and "off" last `mean_on_s` and `mean_off_s` on average, "on" with
    /// probability `initial` at the start.
    pub fn new(mean_on_s: f64, mean_off_s: f64, initial: f64) -> Self {
        Self {
            stop_per_s: 1.0 / mean_on_s,
            start_per_s: 1.0 / mean_off_s,
            initial,
        }
    }

    /// The probability that a new track is "on".
    pub fn initial(&self) -> f64 {
        self.initial
    }

    /// The probability of "on" that one step of `dt` seconds leaves unchanged (at `dt` 0, where
    /// every one is, the start probability).
    pub fn stationary(&self, dt: f64) -> f64 {
        let (stop, start) = self.switches(dt);
        if stop + start > 0.0 {
            start / (stop + start)
        } else {
            self.initial
        }
    }

    /// Probabilities that "on" ends and that "off" ends within `dt` seconds.
    pub fn switches(&self, dt: f64) -> (f64, f64) {
        let dt = dt.max(0.0);
        (
            -(-self.stop_per_s * dt).exp_m1(),
            -(-self.start_per_s * dt).exp_m1(),
        )
    }

    /// Probability of "on" after `dt` seconds.
    pub fn predict(&self, p: f64, dt: f64) -> f64 {
        let (stop, start) = self.switches(dt);
        (p * (1.0 - stop) + (1.0 - p) * start).clamp(0.0, 1.0)
    }
}

/// The modes of the configured sensors, one per slot.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Modes {
    models: Vec<ModeModel>,
}

impl Modes {
    /// Assigns every sensor its mode slot (audio: the voice, cameras: a face slot each) and
    /// returns the slots' models. Disabled modes leave the sensors' P_D plain.
    pub fn assign<const N: usize>(
        sensors: &mut [Sensor<N>],
        voice: &VoiceConfig,
        face: &FaceConfig,
    ) -> Self {
        let mut models = Vec::new();
        let voice_slot = voice.enabled.then(|| {
            models.push(ModeModel::new(
                voice.mean_talk_s,
                voice.mean_pause_s,
                voice.initial_talking,
            ));
            0
        });
        for s in sensors.iter_mut() {
            s.mode = if s.audio {
                voice_slot
            } else if s.camera().is_some() && face.enabled {
                models.push(ModeModel::new(
                    face.mean_towards_s,
                    face.mean_away_s,
                    face.initial_towards,
                ));
                Some(models.len() - 1)
            } else {
                None
            };
        }
        Self { models }
    }

    /// Mode probabilities of a new track.
    pub fn initial(&self) -> Vec<f64> {
        self.models.iter().map(|m| m.initial).collect()
    }

    /// Mode probabilities `dt` seconds after `p`; slots that `p` lacks (cameras added by a
    /// recalibration) start from their initial probability.
    pub fn predict(&self, p: &[f64], dt: f64) -> Vec<f64> {
        self.models
            .iter()
            .enumerate()
            .map(|(i, m)| m.predict(p.get(i).copied().unwrap_or(m.initial), dt))
            .collect()
    }
}

/// Probability of a sensor's outcome (detected or missed) for a track whose mode is "on" with
/// probability `p`, detected with `pd_on` when on and `pd_off` when off; and the probability of
/// "on" after the outcome.
pub(crate) fn mode_outcome(p: f64, pd_on: f64, pd_off: f64, detected: bool) -> (f64, f64) {
    let (a, b) = if detected {
        (p * pd_on, (1.0 - p) * pd_off)
    } else {
        (p * (1.0 - pd_on), (1.0 - p) * (1.0 - pd_off))
    };
    let f = a + b;
    if f > 0.0 { (f, a / f) } else { (0.0, p) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pause_lowers_the_talking_probability_and_the_miss_penalty() {
        let cfg = VoiceConfig::default();
        let m = ModeModel::new(cfg.mean_talk_s, cfg.mean_pause_s, cfg.initial_talking);
        let mut p = 0.95;
        let mut penalty = 1.0;
        let mut first = 0.0;
        for k in 0..16 {
            p = m.predict(p, 0.128);
            let (f, q) = mode_outcome(p, 0.6, 0.02, false);
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
        let (_, q) = mode_outcome(m.predict(p, 0.128), 0.6, 0.02, true);
        assert!(q > 0.5, "{q}");
        assert_eq!(mode_outcome(1.0, 0.6, 0.02, false).0, 0.4);
    }

    #[test]
    fn a_face_turned_away_for_two_seconds_costs_little_after_the_first_misses() {
        let cfg = FaceConfig::default();
        let m = ModeModel::new(cfg.mean_towards_s, cfg.mean_away_s, cfg.initial_towards);
        let (mut p, mut penalty) = (0.99, 1.0);
        for _ in 0..16 {
            p = m.predict(p, 0.128);
            let (f, q) = mode_outcome(p, 0.9, cfg.away_p_detect, false);
            penalty *= f;
            p = q;
        }
        // A plain P_D of 0.9 would cost 0.1^16.
        assert!(penalty > 1e-3, "{penalty}");
        assert!(p < 0.1, "{p}");
        let (_, q) = mode_outcome(m.predict(p, 0.128), 0.9, cfg.away_p_detect, true);
        assert!(q > 0.5, "{q}");
    }
}
