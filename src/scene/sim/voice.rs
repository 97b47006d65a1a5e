//! Synthetic speech: a source-filter model made by the project itself.
//!
//! Voiced sounds are a Rosenberg glottal-flow pulse train, differentiated (lip radiation), with a
//! wandering F0 (phrase declination, syllable accents, per-period jitter and shimmer) and pulsed
//! aspiration noise, filtered by a cascade of second-order formant resonators: F1-F4 glide
//! between vowel targets, F5 and F6 stay fixed (they keep the upper spectrum from falling off).
//! Syllables (3-6 per second, see `syllables`) carry the amplitude envelope and may
//! start with a fricative (band-pass noise), a stop (closure, burst, aspiration), an aspirate or
//! a nasal murmur, and may end with a fricative. Phrases are the intervals given; outside them
//! the signal is exactly zero, so the phrases are where the talker is active.

use std::f64::consts::PI;

use rand::Rng;
use rand_distr::StandardNormal;

use super::config::VoiceConfig;
use super::syllables::{Band, BandPass, Syllable, Targets, plan_phrase};

/// Nominal RMS of speech at 0 dB `level_db`, over the samples where the talker speaks.
pub const NOMINAL_RMS: f64 = 0.1;

/// Bandwidths (Hz) of F1-F6 before scaling with the voice.
const BANDWIDTHS: [f64; 6] = [60.0, 90.0, 150.0, 200.0, 300.0, 450.0];
/// The fixed upper formants F5, F6 of an adult male (Hz).
const UPPER_FORMANTS: [f64; 2] = [4500.0, 5500.0];

/// Synthesises `len` samples of speech by `voice`, talking during `phrases` (s).
pub fn synthesize<R: Rng + ?Sized>(
    voice: &VoiceConfig,
    phrases: &[(f64, f64)],
    sample_rate: f64,
    len: usize,
    rng: &mut R,
) -> Vec<f64> {
    let mut out = vec![0.0; len];
    let span = |t0: f64, t1: f64| {
        let a = ((t0 * sample_rate).round().max(0.0) as usize).min(len);
        let b = ((t1 * sample_rate).round().max(0.0) as usize).min(len);
        (a, b.max(a))
    };
    for &(t0, t1) in phrases {
        let (a, b) = span(t0, t1);
        if b <= a + 16 {
            continue;
        }
        let gain_db: f64 = rng.sample::<f64, _>(StandardNormal) * 1.5;
        let phrase = render_phrase(voice, b - a, sample_rate, rng);
        let g = 10f64.powf(gain_db / 20.0);
        for (o, v) in out[a..b].iter_mut().zip(&phrase) {
            *o = g * v;
        }
    }
    // Normalise the level over the speaking samples.
    let (mut energy, mut count) = (0.0, 0usize);
    for &(t0, t1) in phrases {
        let (a, b) = span(t0, t1);
        energy += out[a..b].iter().map(|v| v * v).sum::<f64>();
        count += b - a;
    }
    if count > 0 && energy > 0.0 {
        let rms = (energy / count as f64).sqrt();
        let g = NOMINAL_RMS * 10f64.powf(voice.level_db / 20.0) / rms;
        out.iter_mut().for_each(|v| *v *= g);
    }
    out
}

/// The glottal source: a Rosenberg flow pulse per period, with jitter and shimmer drawn per
/// period; its output is the flow's derivative (which includes lip radiation).
#[derive(Debug, Clone, Copy)]
struct Glottis {
    phase: f64,
    prev_flow: f64,
    jitter: f64,
    shimmer: f64,
}

impl Glottis {
    fn new() -> Self {
        Self {
            phase: 0.0,
            prev_flow: 0.0,
            jitter: 1.0,
            shimmer: 1.0,
        }
    }

    /// One sample at fundamental `f0`: (flow derivative, flow).
    fn step<R: Rng + ?Sized>(&mut self, f0: f64, oq: f64, fs: f64, rng: &mut R) -> (f64, f64) {
        self.phase += f0 / (fs * self.jitter);
        if self.phase >= 1.0 {
            self.phase -= 1.0;
            self.jitter = 1.0 + 0.008 * rng.sample::<f64, _>(StandardNormal);
            self.shimmer = 1.0 + 0.04 * rng.sample::<f64, _>(StandardNormal);
        }
        let flow = glottal_flow(self.phase, oq);
        // Scaled so that the derivative's size does not depend on the pitch.
        let pulse = (flow - self.prev_flow) * self.shimmer * fs / (100.0 * f0);
        self.prev_flow = flow;
        (pulse, flow)
    }
}

/// Rosenberg glottal flow at phase `p` in [0, 1) with open quotient `oq`.
fn glottal_flow(p: f64, oq: f64) -> f64 {
    let tp = 0.65 * oq;
    let tn = 0.35 * oq;
    if p < tp {
        0.5 * (1.0 - (PI * p / tp).cos())
    } else if p < tp + tn {
        (0.5 * PI * (p - tp) / tn).cos()
    } else {
        0.0
    }
}

/// A Klatt resonator: unity gain at DC, peak at the formant.
#[derive(Debug, Clone, Copy, Default)]
struct Resonator {
    y1: f64,
    y2: f64,
}

impl Resonator {
    fn step(&mut self, x: f64, freq: f64, bw: f64, fs: f64) -> f64 {
        let r = (-PI * bw / fs).exp();
        let b = 2.0 * r * (2.0 * PI * freq / fs).cos();
        let c = -r * r;
        let y = (1.0 - b - c) * x + b * self.y1 + c * self.y2;
        self.y2 = self.y1;
        self.y1 = y;
        y
    }
}

/// Pitch target (semitones from the voice's F0) at `progress` through the phrase: declination,
/// the syllable's accent, and a final fall on the last syllable.
fn pitch_target(voice: &VoiceConfig, syl: &Syllable, progress: f64, last: bool) -> f64 {
    let fall = if last { 0.3 * voice.f0_range_st } else { 0.0 };
    voice.f0_range_st * (0.4 - 0.8 * progress) + syl.accent_st - fall
}

/// Renders one phrase of `len` samples.
fn render_phrase<R: Rng + ?Sized>(
    voice: &VoiceConfig,
    len: usize,
    fs: f64,
    rng: &mut R,
) -> Vec<f64> {
    let syllables = plan_phrase(voice, len, fs, rng);
    let base_f0 = voice.f0_hz * 2f64.powf(rng.sample::<f64, _>(StandardNormal) * 0.08);
    let first_vowel = syllables
        .first()
        .map_or([500.0, 1500.0, 2500.0, 3500.0], |s| s.vowel);
    let mut tract = Tract::new(voice, fs, base_f0, first_vowel);
    let (mut voiced, mut noise) = (vec![0.0; len], vec![0.0; len]);
    let (mut vowel_energy, mut vowel_count) = (0.0, 0usize);
    let mut s_idx = 0;
    for n in 0..len {
        while s_idx + 1 < syllables.len() && n >= syllables[s_idx].end {
            s_idx += 1;
        }
        let syl = &syllables[s_idx];
        let t = syl.targets(n, voice.formant_scale, fs);
        let last = s_idx + 1 == syllables.len();
        tract.glide(&t, pitch_target(voice, syl, n as f64 / len as f64, last));
        voiced[n] = tract.voiced(t.nasal, rng);
        if t.vowel {
            vowel_energy += voiced[n] * voiced[n];
            vowel_count += 1;
        }
        noise[n] = tract.frication(rng);
    }
    // Frication levels are relative to the RMS of the vowels of this phrase.
    let vowel_rms = (vowel_energy / vowel_count.max(1) as f64).sqrt();
    faded_mix(&voiced, &noise, vowel_rms, fs)
}

/// The voice's state while it renders a phrase: the glottis, the formant resonators and the
/// frication filter, with the formants, pitch and amplitudes gliding toward each sample's
/// targets.
struct Tract<'a> {
    voice: &'a VoiceConfig,
    fs: f64,
    base_f0: f64,
    /// Fixed upper formants (Hz) below the Nyquist margin.
    upper: Vec<f64>,
    bw_scale: f64,
    /// One-pole glide coefficients per sample of the formants, the pitch and the amplitudes.
    k_formant: f64,
    k_pitch: f64,
    k_amp: f64,
    resonators: [Resonator; 6],
    glottis: Glottis,
    band_filter: BandPass,
    band: Option<Band>,
    formants: [f64; 4],
    /// Pitch in semitones from `base_f0`.
    pitch_st: f64,
    /// Voicing, frication and aspiration amplitudes.
    av: f64,
    an: f64,
    ah: f64,
}

impl<'a> Tract<'a> {
    fn new(voice: &'a VoiceConfig, fs: f64, base_f0: f64, formants: [f64; 4]) -> Self {
        let k = |tau: f64| 1.0 - (-1.0 / (tau * fs)).exp();
        Self {
            voice,
            fs,
            base_f0,
            upper: UPPER_FORMANTS
                .iter()
                .map(|f| f * voice.formant_scale)
                .filter(|f| *f < 0.42 * fs)
                .collect(),
            bw_scale: voice.formant_scale.sqrt(),
            k_formant: k(0.025),
            k_pitch: k(0.04),
            k_amp: k(0.005),
            resonators: [Resonator::default(); 6],
            glottis: Glottis::new(),
            band_filter: BandPass::default(),
            band: None,
            formants,
            pitch_st: voice.f0_range_st * 0.4,
            av: 0.0,
            an: 0.0,
            ah: 0.0,
        }
    }

    /// Smooth glides of formants, pitch (toward `pitch_st`) and amplitudes toward the
    /// targets `t`; frication attacks at once.
    fn glide(&mut self, t: &Targets, pitch_st: f64) {
        for (f, target) in self.formants.iter_mut().zip(t.formants) {
            *f += self.k_formant * (target - *f);
        }
        self.pitch_st += self.k_pitch * (pitch_st - self.pitch_st);
        self.av += self.k_amp * (t.voicing - self.av);
        self.an += if t.frication > self.an {
            t.frication - self.an
        } else {
            self.k_amp * (t.frication - self.an)
        };
        self.ah += self.k_amp * (t.aspiration - self.ah);
        if t.band.is_some() {
            self.band = t.band;
        }
    }

    /// One sample of the glottal source with breath and aspiration noise through the formant
    /// cascade (F1 widened when `nasal`).
    fn voiced<R: Rng + ?Sized>(&mut self, nasal: bool, rng: &mut R) -> f64 {
        let fs = self.fs;
        let f0 = (self.base_f0 * 2f64.powf(self.pitch_st / 12.0)).clamp(50.0, 500.0);
        let (pulse, flow) = self.glottis.step(f0, self.voice.open_quotient, fs, rng);
        let white: f64 = rng.sample(StandardNormal);
        let breath = self.voice.breathiness * 0.02 * white * (0.3 + flow);
        let mut y = self.av * (pulse + breath) + self.ah * 0.03 * white;
        let freqs = self.formants.iter().chain(&self.upper);
        for (i, (r, f)) in self.resonators.iter_mut().zip(freqs).enumerate() {
            let bw = if nasal && i == 0 {
                150.0
            } else {
                BANDWIDTHS[i] * self.bw_scale
            };
            y = r.step(y, *f, bw, fs);
        }
        y
    }

    /// One sample of band-pass frication noise (relative to the vowels' RMS), 0 without any.
    fn frication<R: Rng + ?Sized>(&mut self, rng: &mut R) -> f64 {
        match self.band {
            Some(b) if self.an > 1e-6 => {
                let white: f64 = rng.sample(StandardNormal);
                self.an * b.level * self.band_filter.step(white, b.centre, b.q, self.fs) / b.gain
            }
            _ => {
                self.band_filter = BandPass::default();
                0.0
            }
        }
    }
}

/// `voiced` plus `vowel_rms` times `noise`, faded in and out over 10 ms so that the phrase
/// starts and ends at zero.
fn faded_mix(voiced: &[f64], noise: &[f64], vowel_rms: f64, fs: f64) -> Vec<f64> {
    let len = voiced.len();
    let ramp = (0.01 * fs) as usize;
    (0..len)
        .map(|n| {
            let edge = n.min(len - 1 - n);
            let w = if edge < ramp {
                0.5 - 0.5 * (PI * edge as f64 / ramp as f64).cos()
            } else {
                1.0
            };
            w * (voiced[n] + vowel_rms * noise[n])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn voice(f0: f64, scale: f64) -> VoiceConfig {
        VoiceConfig {
            f0_hz: f0,
            formant_scale: scale,
            ..VoiceConfig::default()
        }
    }

    #[test]
    fn silent_outside_phrases_and_at_the_nominal_level_inside() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let fs = 16000.0;
        let phrases = [(0.5, 2.0), (2.6, 4.0)];
        let x = synthesize(&voice(120.0, 1.0), &phrases, fs, 64000, &mut rng);
        assert!(x.iter().all(|v| v.is_finite()));
        let inside = |n: usize| {
            phrases
                .iter()
                .any(|&(a, b)| n >= (a * fs) as usize && n < (b * fs) as usize)
        };
        assert!((0..x.len()).filter(|&n| !inside(n)).all(|n| x[n] == 0.0));
        let (e, c) = (0..x.len())
            .filter(|&n| inside(n))
            .fold((0.0, 0), |(e, c), n| (e + x[n] * x[n], c + 1));
        assert!(((e / c as f64).sqrt() - NOMINAL_RMS).abs() < 1e-9);
        // Syllables: the 50 ms energy envelope inside a phrase rises and falls several times.
        let frames: Vec<f64> = (8..32)
            .map(|i| x[i * 800..(i + 1) * 800].iter().map(|v| v * v).sum::<f64>())
            .collect();
        let dips = frames
            .windows(3)
            .filter(|w| w[1] < 0.5 * w[0].min(w[2]))
            .count();
        assert!(dips >= 2, "no syllable modulation: {frames:?}");
    }

    /// Median F0 (Hz) of the voiced 40 ms frames of `x`, by normalised autocorrelation.
    pub(crate) fn median_f0(x: &[f64], fs: f64) -> f64 {
        let frame = (0.04 * fs) as usize;
        let energies: Vec<f64> = x
            .chunks(frame)
            .map(|c| c.iter().map(|v| v * v).sum())
            .collect();
        let loud = energies.iter().fold(0.0f64, |m, v| m.max(*v));
        let (min_lag, max_lag) = ((fs / 400.0) as usize, (fs / 60.0) as usize);
        let mut f0s = Vec::new();
        for (i, c) in x.chunks_exact(frame).enumerate() {
            if energies[i] < 0.05 * loud {
                continue;
            }
            let r0: f64 = c.iter().map(|v| v * v).sum();
            let (mut best, mut lag) = (0.0, 0);
            for l in min_lag..=max_lag.min(frame - 1) {
                let r: f64 = (0..frame - l).map(|n| c[n] * c[n + l]).sum::<f64>() / r0;
                if r > best {
                    (best, lag) = (r, l);
                }
            }
            // Voiced frames are strongly periodic.
            if best > 0.5 {
                f0s.push(fs / lag as f64);
            }
        }
        f0s.sort_by(f64::total_cmp);
        f0s[f0s.len() / 2]
    }

    #[test]
    fn voices_have_distinct_pitch_near_their_configured_f0() {
        let fs = 16000.0;
        let mut medians = Vec::new();
        for (k, (f0, scale)) in [(105.0, 1.0), (150.0, 1.05), (215.0, 1.17)]
            .into_iter()
            .enumerate()
        {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(10 + k as u64);
            let x = synthesize(
                &voice(f0, scale),
                &[(0.0, 3.0), (3.5, 6.0)],
                fs,
                96000,
                &mut rng,
            );
            let m = median_f0(&x, fs);
            assert!(
                (m / f0 - 1.0).abs() < 0.15,
                "median F0 {m} for a {f0} Hz voice"
            );
            println!("F0 {f0} Hz: median {m:.1} Hz");
            medians.push(m);
        }
        assert!(
            medians[1] / medians[0] > 1.2 && medians[2] / medians[1] > 1.2,
            "{medians:?}"
        );
    }
}
