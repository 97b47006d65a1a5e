//! Per-frame voice activity of one array: in-band power against a noise floor tracked by
//! minimum statistics, combined with the spatial coherence of the strongest SRP peak.
//!
//! Localisation frames are long (128 ms) and average hundreds of bins over every microphone, so
//! the frame power of stationary noise fluctuates little and its running minimum is an almost
//! unbiased floor: no bias correction is applied. The minimum runs over a window longer than the
//! pauses-free stretches of speech, so speech frames stand out against it. Stationary noise, even
//! when directional, sits at the floor; diffuse or uncorrelated noise also has a low SRP peak.

use super::config::ActivityConfig;

/// Noise-floor tracker and activity score of one array.
#[derive(Debug, Clone)]
pub(crate) struct ActivityTracker {
    history: Vec<f64>,
    next: usize,
    filled: usize,
}

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

impl ActivityTracker {
    /// A tracker with a minimum window of `cfg.noise_window_frames` frames.
    pub fn new(cfg: &ActivityConfig) -> Self {
        Self {
            history: vec![0.0; cfg.noise_window_frames],
            next: 0,
            filled: 0,
        }
    }

    /// Whether `power` (mean in-band power per sample) is digital silence for this configuration.
    pub fn is_silent(cfg: &ActivityConfig, power: f64) -> bool {
        !(power.is_finite() && power > cfg.min_power)
    }

    /// Adds a non-silent frame's power and returns its ratio to the noise floor in dB (>= 0).
    pub fn update(&mut self, power: f64) -> f64 {
        self.history[self.next] = power;
        self.next = (self.next + 1) % self.history.len();
        self.filled = (self.filled + 1).min(self.history.len());
        let floor = self.history[..self.filled]
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        let ratio = power / floor;
        if ratio.is_finite() && ratio > 0.0 {
            10.0 * ratio.log10()
        } else {
            0.0
        }
    }

    /// Activity in [0, 1]: the energy score times the coherence score (`coherence` = the frame's
    /// largest normalised SRP, `None` when the array cannot localise).
    pub fn score(cfg: &ActivityConfig, snr_db: f64, coherence: Option<f64>) -> f64 {
        let energy = sigmoid((snr_db - cfg.snr_midpoint_db) / cfg.snr_scale_db);
        let spatial = coherence.map_or(1.0, |c| {
            sigmoid((c - cfg.coherence_midpoint) / cfg.coherence_scale)
        });
        let a = energy * spatial;
        if a.is_finite() {
            a.clamp(0.0, 1.0)
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_follows_the_minimum_and_speech_stands_out() {
        let cfg = ActivityConfig::default();
        let mut t = ActivityTracker::new(&cfg);
        for i in 0..30 {
            let noise = 1e-4 * (1.0 + 0.05 * ((i * 7 % 5) as f64 - 2.0) / 2.0);
            let snr = t.update(noise);
            assert!(snr < 1.0, "{snr}");
            assert!(ActivityTracker::score(&cfg, snr, Some(0.02)) < 0.05);
        }
        let snr = t.update(1e-2);
        assert!((snr - 20.0).abs() < 0.5, "{snr}");
        assert!(ActivityTracker::score(&cfg, snr, Some(0.4)) > 0.95);
        // A louder stationary noise becomes the floor once the window has forgotten the quiet one.
        for _ in 0..cfg.noise_window_frames {
            t.update(1e-2);
        }
        assert!(t.update(1e-2) < 0.1);
    }

    #[test]
    fn silence_and_garbage_are_silent() {
        let cfg = ActivityConfig::default();
        assert!(ActivityTracker::is_silent(&cfg, 0.0));
        assert!(ActivityTracker::is_silent(&cfg, f64::NAN));
        assert!(!ActivityTracker::is_silent(&cfg, 1e-6));
        assert_eq!(ActivityTracker::score(&cfg, f64::NAN, None), 0.0);
    }
}
