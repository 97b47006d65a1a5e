//! YIN pitch estimation (de Cheveigné and Kawahara, 2002) of a clean, single-voice signal.
//!
//! The separator estimates each label's pitch from a mixture; this estimator reads one voice
//! alone (a scene's true source image), which makes it the reference for `--oracle-pitch` runs
//! that measure the harmonic grouping with the right pitch.

/// Cumulative-mean-normalised difference below which the first dip is taken as the period
/// (the paper's absolute threshold).
const THRESHOLD: f64 = 0.2;
/// Aperiodicity (the normalised difference at the period) at or below which a frame counts as
/// fully voiced (voicing 1); voicing falls linearly from there to 0 at `UNVOICED_ABOVE`.
const VOICED_BELOW: f64 = 0.2;
/// Aperiodicity at or above which a frame counts as unvoiced.
const UNVOICED_ABOVE: f64 = 0.6;
/// A frame whose energy is this far below the signal's loudest frame counts as silent.
const SILENCE_BELOW_MAX: f64 = 1e-4;

/// One frame's pitch of a single voice.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct VoicePitch {
    /// F0 (Hz); 0 when the frame is silent.
    pub f0: f64,
    /// Voicing in [0, 1] from the aperiodicity at the period (0 in silence).
    pub voicing: f64,
}

/// A YIN estimator for F0s in `[f0_min, f0_max]` Hz over `frame`-sample frames.
#[derive(Debug, Clone)]
pub struct Yin {
    tau_min: usize,
    tau_max: usize,
    frame: usize,
    sample_rate: f64,
}

impl Yin {
    /// An estimator at `sample_rate` Hz; `frame` must exceed the longest period by the
    /// integration window (it is raised to twice the longest period when shorter).
    pub fn new(sample_rate: f64, f0_min: f64, f0_max: f64, frame: usize) -> Self {
        let tau_min = (sample_rate / f0_max.max(1.0)).floor().max(2.0) as usize;
        let tau_max = ((sample_rate / f0_min.max(1.0)).ceil() as usize).max(tau_min + 2);
        Self {
            tau_min,
            tau_max,
            frame: frame.max(2 * tau_max + 2),
            sample_rate,
        }
    }

    /// F0 and aperiodicity of the frame centred on sample `centre` of `x` (zero outside it).
    /// The aperiodicity is the normalised difference at the period: 0 for a perfectly periodic
    /// frame, about 1 for noise.
    pub fn analyse(&self, x: &[f32], centre: usize) -> (f64, f64) {
        let start = centre as i64 - (self.frame / 2) as i64;
        let at = |i: usize| -> f64 {
            let j = start + i as i64;
            if j >= 0 && (j as usize) < x.len() {
                f64::from(x[j as usize])
            } else {
                0.0
            }
        };
        let seg: Vec<f64> = (0..self.frame).map(at).collect();
        let window = self.frame - self.tau_max - 1;
        // d(tau) and its cumulative-mean normalisation d'(tau) (YIN steps 2 and 3).
        let mut norm = vec![1.0; self.tau_max + 2];
        let mut running = 0.0;
        for (tau, n) in norm.iter_mut().enumerate().skip(1) {
            let d: f64 = (0..window).map(|i| (seg[i] - seg[i + tau]).powi(2)).sum();
            running += d;
            *n = if running > 0.0 {
                d * tau as f64 / running
            } else {
                1.0
            };
        }
        // Step 4: the first dip below the threshold, else the global minimum.
        let range = self.tau_min..=self.tau_max;
        let tau = range
            .clone()
            .find(|&t| norm[t] < THRESHOLD && norm[t] <= norm[t - 1] && norm[t] <= norm[t + 1])
            .or_else(|| range.min_by(|&a, &b| norm[a].total_cmp(&norm[b])))
            .unwrap_or(self.tau_min);
        // Step 5: parabolic interpolation of the dip.
        let (a, b, c) = (norm[tau - 1], norm[tau], norm[tau + 1]);
        let den = a - 2.0 * b + c;
        let shift = if den.abs() > 1e-12 {
            (0.5 * (a - c) / den).clamp(-1.0, 1.0)
        } else {
            0.0
        };
        (self.sample_rate / (tau as f64 + shift), b)
    }

    /// The pitch of `x` every `hop` samples (frame `j` centred on sample `j * hop`), silent
    /// frames (far below the loudest) unvoiced.
    pub fn track(&self, x: &[f32], hop: usize) -> Vec<VoicePitch> {
        let hop = hop.max(1);
        let count = x.len().div_ceil(hop) + 1;
        let centres: Vec<usize> = (0..count).map(|j| j * hop).collect();
        self.track_at(x, &centres)
    }

    /// The pitch of `x` in the frames centred on the samples `centres`, frames far below the
    /// loudest of them unvoiced.
    pub fn track_at(&self, x: &[f32], centres: &[usize]) -> Vec<VoicePitch> {
        let half = self.frame / 2;
        let energy = |centre: usize| -> f64 {
            let lo = centre.saturating_sub(half);
            let hi = (centre + half).min(x.len());
            x.get(lo..hi)
                .map_or(0.0, |s| s.iter().map(|&v| f64::from(v).powi(2)).sum())
        };
        let energies: Vec<f64> = centres.iter().map(|&c| energy(c)).collect();
        let loudest = energies.iter().copied().fold(0.0, f64::max);
        energies
            .iter()
            .zip(centres)
            .map(|(&e, &centre)| {
                if !(loudest > 0.0 && e > SILENCE_BELOW_MAX * loudest) {
                    return VoicePitch::default();
                }
                let (f0, aperiodicity) = self.analyse(x, centre);
                let voicing = ((UNVOICED_ABOVE - aperiodicity) / (UNVOICED_ABOVE - VOICED_BELOW))
                    .clamp(0.0, 1.0);
                VoicePitch { f0, voicing }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn voice(f0: f64, fs: f64, n: usize) -> Vec<f32> {
        (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                (1..=12)
                    .map(|h| (2.0 * std::f64::consts::PI * f0 * h as f64 * t).sin() / h as f64)
                    .sum::<f64>() as f32
            })
            .collect()
    }

    #[test]
    fn a_harmonic_voice_is_read_at_its_f0_not_an_octave_off() {
        let fs = 16000.0;
        let yin = Yin::new(fs, 70.0, 400.0, 1024);
        for f0 in [82.0, 117.0, 196.5, 310.0] {
            let x = voice(f0, fs, 8000);
            let (est, aperiodicity) = yin.analyse(&x, 4000);
            assert!((est / f0 - 1.0).abs() < 0.005, "{f0}: {est}");
            assert!(aperiodicity < 0.05, "{f0}: {aperiodicity}");
        }
    }

    #[test]
    fn noise_and_silence_are_unvoiced() {
        let fs = 16000.0;
        let yin = Yin::new(fs, 70.0, 400.0, 1024);
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut noise: Vec<f32> = (0..16000)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state as f64 / u64::MAX as f64 - 0.5) as f32
            })
            .collect();
        // Silence in the second half.
        noise[8000..].iter_mut().for_each(|v| *v = 0.0);
        let track = yin.track(&noise, 512);
        assert!(track[4..12].iter().all(|p| p.voicing == 0.0), "{track:?}");
        assert!(track[20..].iter().all(|p| *p == VoicePitch::default()));
    }

    #[test]
    fn a_track_follows_a_voice_that_starts_late() {
        let fs = 16000.0;
        let yin = Yin::new(fs, 70.0, 400.0, 1024);
        let mut x = vec![0.0f32; 4000];
        x.extend(voice(150.0, fs, 8000));
        let track = yin.track(&x, 512);
        assert_eq!(track[2], VoicePitch::default());
        for p in &track[10..22] {
            assert!(
                (p.f0 / 150.0 - 1.0).abs() < 0.005 && p.voicing == 1.0,
                "{p:?}"
            );
        }
    }
}
