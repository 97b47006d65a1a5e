//! Session time: tracker steps on the audio clock.
//!
//! Audio is the clock: sample n is at t = n / sample_rate. Step k covers [k T, (k + 1) T) with
//! T = `step_samples` / sample_rate, and its estimate refers to the middle of that interval.

/// Step timing of one session.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepClock {
    /// Sample rate (Hz).
    pub sample_rate: u32,
    /// Step length in samples.
    pub step_samples: u64,
}

impl StepClock {
    /// A clock with the step period rounded to whole samples (at least one).
    pub fn new(sample_rate: u32, step_s: f64) -> Self {
        let step_samples = ((step_s * sample_rate as f64).round() as u64).max(1);
        Self {
            sample_rate,
            step_samples,
        }
    }

    /// Step period in seconds.
    pub fn step_s(&self) -> f64 {
        self.step_samples as f64 / self.sample_rate as f64
    }

    /// Time of sample `n`.
    pub fn time_of(&self, n: u64) -> f64 {
        n as f64 / self.sample_rate as f64
    }

    /// Samples a session's audio history must hold: its longest analysis `frame`, four steps,
    /// and the camera wait, since a step that waits for its cameras still needs its own audio
    /// when it runs. The pipeline hands the audio in at most a step at a time, so nothing it
    /// was sent leaves the history before its step has run.
    pub fn history_samples(&self, frame: usize, camera_wait_s: f64) -> usize {
        let wait = (camera_wait_s.max(0.0) * f64::from(self.sample_rate)).ceil() as usize;
        frame + 4 * self.step_samples as usize + wait
    }

    /// First sample of step `k`.
    pub fn step_start_sample(&self, k: u64) -> u64 {
        k * self.step_samples
    }

    /// One past the last sample of step `k`.
    pub fn step_end_sample(&self, k: u64) -> u64 {
        (k + 1) * self.step_samples
    }

    /// `[start, end)` of step `k` in seconds.
    pub fn step_bounds(&self, k: u64) -> (f64, f64) {
        (
            self.time_of(self.step_start_sample(k)),
            self.time_of(self.step_end_sample(k)),
        )
    }

    /// The time step `k`'s estimate refers to: the middle of its interval.
    pub fn estimate_time(&self, k: u64) -> f64 {
        let (a, b) = self.step_bounds(k);
        0.5 * (a + b)
    }

    /// The step whose interval contains time `t` (t >= 0).
    pub fn step_of(&self, t: f64) -> u64 {
        ((t * self.sample_rate as f64) as u64) / self.step_samples
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_follow_the_audio_clock() {
        let c = StepClock::new(16000, 0.128);
        assert_eq!(c.step_samples, 2048);
        assert_eq!(c.step_bounds(2), (0.256, 0.384));
        assert!((c.estimate_time(0) - 0.064).abs() < 1e-12);
        assert_eq!(c.step_of(0.2559), 1);
        assert_eq!(c.step_of(0.256), 2);
    }
}
