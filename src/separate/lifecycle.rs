//! Birth, grace period and death of a label's stream, as a per-frame gain envelope.
//!
//! A new label fades in over a few frames. A label missing from the targets keeps its stream and
//! its adaptive state for a grace period (the tracker can drop a label for a step), then fades out
//! and is dropped; if it comes back meanwhile it resumes where it was. The gain changes once per
//! STFT frame with a raised-cosine shape, and the overlap-add of the inverse STFT interpolates
//! between frames, so births and deaths are click-free.

use super::config::LifecycleConfig;

/// Lengths of the envelope's phases in frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Timing {
    /// Frames to fade in (0: start at full gain).
    pub fade_in: usize,
    /// Frames a label may be missing before fading out.
    pub grace: usize,
    /// Frames to fade out (at least 1: the last frame is silent).
    pub fade_out: usize,
}

impl Timing {
    /// Frame counts for a frame rate of `frames_per_s`.
    pub fn new(cfg: &LifecycleConfig, frames_per_s: f64) -> Self {
        let frames = |s: f64| (s * frames_per_s).round() as usize;
        Self {
            fade_in: frames(cfg.fade_in_s),
            grace: frames(cfg.grace_s),
            fade_out: frames(cfg.fade_out_s).max(1),
        }
    }

    /// The rest envelope's timing: the same fades, with `rest_after_s` unheard as the grace.
    /// `None` when labels never rest.
    pub fn rest(cfg: &LifecycleConfig, frames_per_s: f64) -> Option<Self> {
        (cfg.rest_after_s > 0.0).then(|| Self {
            grace: (cfg.rest_after_s * frames_per_s).round().max(1.0) as usize,
            ..Self::new(cfg, frames_per_s)
        })
    }
}

/// Where a stream is in its life.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Envelope {
    /// Fade position in [0, 1]: 0 silent, 1 full gain.
    level: f64,
    /// Consecutive frames the label has been missing from the targets.
    missing: usize,
}

impl Envelope {
    /// A newly born stream (silent until its first frame).
    pub fn born() -> Self {
        Self {
            level: 0.0,
            missing: 0,
        }
    }

    /// A stream already at full gain (a new label counts as heard until it has been silent for
    /// the rest envelope's grace).
    pub fn open() -> Self {
        Self {
            level: 1.0,
            missing: 0,
        }
    }

    /// Advances one frame; `present` tells whether the label is among this frame's targets.
    pub fn step(&mut self, present: bool, t: &Timing) {
        if present {
            self.missing = 0;
            self.level = if t.fade_in == 0 {
                1.0
            } else {
                (self.level + 1.0 / t.fade_in as f64).min(1.0)
            };
        } else {
            self.missing += 1;
            if self.missing > t.grace {
                self.level = (self.level - 1.0 / t.fade_out as f64).max(0.0);
            }
        }
    }

    /// Gain to apply this frame (raised-cosine of the fade position).
    pub fn gain(&self) -> f64 {
        let s = (std::f64::consts::FRAC_PI_2 * self.level).sin();
        s * s
    }

    /// Whether the label is missing from the targets this frame.
    pub fn is_missing(&self) -> bool {
        self.missing > 0
    }

    /// Whether the stream has faded out completely and can be dropped after this frame.
    pub fn is_dead(&self, t: &Timing) -> bool {
        self.missing > t.grace && self.level <= 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fades_in_holds_through_gaps_and_fades_out() {
        let t = Timing {
            fade_in: 4,
            grace: 3,
            fade_out: 2,
        };
        let mut e = Envelope::born();
        let mut gains = vec![];
        for _ in 0..6 {
            e.step(true, &t);
            gains.push(e.gain());
        }
        assert!(gains.windows(2).all(|w| w[1] >= w[0]));
        assert!(gains[0] > 0.0 && gains[0] < 0.5);
        assert_eq!(gains[4], 1.0);
        // A two-frame gap is within the grace period: full gain throughout.
        e.step(false, &t);
        e.step(false, &t);
        assert_eq!(e.gain(), 1.0);
        e.step(true, &t);
        for _ in 0..3 {
            e.step(false, &t);
            assert_eq!(e.gain(), 1.0);
            assert!(!e.is_dead(&t));
        }
        e.step(false, &t);
        assert!((e.gain() - 0.5).abs() < 1e-12);
        e.step(false, &t);
        assert_eq!(e.gain(), 0.0);
        assert!(e.is_dead(&t));
    }

    #[test]
    fn an_open_envelope_stays_full_while_heard_and_fades_after_the_rest_time() {
        let mut cfg = LifecycleConfig::default();
        let rest = Timing::rest(&cfg, 31.25).unwrap();
        assert_eq!(rest.grace, 156);
        assert_eq!((rest.fade_in, rest.fade_out), (2, 2));
        let mut e = Envelope::open();
        assert_eq!(e.gain(), 1.0);
        for _ in 0..rest.grace {
            e.step(false, &rest);
            assert_eq!(e.gain(), 1.0);
        }
        e.step(false, &rest);
        e.step(false, &rest);
        assert!(e.is_dead(&rest));
        // Heard again: it fades back in.
        e.step(true, &rest);
        assert!(e.gain() > 0.0 && e.gain() < 1.0 && !e.is_dead(&rest));
        cfg.rest_after_s = 0.0;
        assert_eq!(Timing::rest(&cfg, 31.25), None);
    }

    #[test]
    fn frame_counts_from_seconds() {
        let t = Timing::new(&LifecycleConfig::default(), 31.25);
        assert_eq!(
            t,
            Timing {
                fade_in: 2,
                grace: 8,
                fade_out: 2
            }
        );
    }
}
