//! Synthetic speech: a source-filter model made by the project itself.
//!
//! Voiced sounds are a Rosenberg glottal-flow pulse train, differentiated (lip radiation), with a
//! wandering F0 (phrase declination, syllable accents, per-period jitter and shimmer) and pulsed
//! aspiration noise, filtered by a cascade of four second-order formant resonators whose
//! frequencies glide between vowel targets. Syllables (3-6 per second) carry the amplitude
//! envelope and may start with a consonant: a fricative (band-pass noise), a stop (silent closure,
//! burst, aspiration) or a nasal murmur. Phrases are the intervals given; outside them the signal
//! is exactly zero, so the phrases are where the talker is active.

use std::f64::consts::PI;

use rand::Rng;
use rand_distr::StandardNormal;

use super::config::VoiceConfig;

/// Nominal RMS of speech at 0 dB `level_db`, over the samples where the talker speaks.
pub const NOMINAL_RMS: f64 = 0.1;

/// Vowel formant targets F1-F4 (Hz) of an adult male (Peterson & Barney averages).
const VOWELS: [[f64; 4]; 10] = [
    [270.0, 2290.0, 3010.0, 3500.0], // i
    [390.0, 1990.0, 2550.0, 3500.0], // I
    [530.0, 1840.0, 2480.0, 3500.0], // E
    [660.0, 1720.0, 2410.0, 3500.0], // ae
    [730.0, 1090.0, 2440.0, 3500.0], // a
    [570.0, 840.0, 2410.0, 3500.0],  // O
    [440.0, 1020.0, 2240.0, 3500.0], // U
    [300.0, 870.0, 2240.0, 3500.0],  // u
    [640.0, 1190.0, 2390.0, 3500.0], // V
    [490.0, 1350.0, 1690.0, 3500.0], // 3r
];
/// Formants of a nasal murmur.
const NASAL: [f64; 4] = [250.0, 1100.0, 2400.0, 3400.0];
/// Formant bandwidths (Hz) before scaling.
const BANDWIDTHS: [f64; 4] = [60.0, 90.0, 150.0, 200.0];

/// How a syllable starts.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Onset {
    /// Straight into the vowel.
    Vowel,
    /// Band-pass noise (s, sh, f, th); `voiced` adds a weak voice source (z, zh, v).
    Fricative {
        centre_hz: f64,
        q: f64,
        level: f64,
        voiced: bool,
    },
    /// Glottal noise through the vocal tract (h).
    Aspirate,
    /// Closure (silence), burst, then aspiration if `aspirated`.
    Stop {
        closure: usize,
        burst_hz: f64,
        level: f64,
        aspirated: bool,
    },
    /// Voiced nasal murmur.
    Nasal,
}

/// One syllable of a phrase, in samples relative to the phrase start.
#[derive(Debug, Clone, Copy)]
struct Syllable {
    start: usize,
    nucleus: usize,
    end: usize,
    onset: Onset,
    vowel: [f64; 4],
    stress: f64,
    accent_st: f64,
}

/// Synthesises `len` samples of speech by `voice`, talking during `phrases` (s).
pub fn synthesize<R: Rng + ?Sized>(
    voice: &VoiceConfig,
    phrases: &[(f64, f64)],
    sample_rate: f64,
    len: usize,
    rng: &mut R,
) -> Vec<f64> {
    let mut out = vec![0.0; len];
    for &(t0, t1) in phrases {
        let a = ((t0 * sample_rate).round() as usize).min(len);
        let b = ((t1 * sample_rate).round() as usize).min(len);
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
    let mut energy = 0.0;
    let mut count = 0usize;
    for &(t0, t1) in phrases {
        let a = ((t0 * sample_rate).round() as usize).min(len);
        let b = ((t1 * sample_rate).round() as usize).min(len);
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

/// Plans the syllables of a phrase of `len` samples.
fn plan_phrase<R: Rng + ?Sized>(
    voice: &VoiceConfig,
    len: usize,
    fs: f64,
    rng: &mut R,
) -> Vec<Syllable> {
    let nominal = fs / voice.syllable_rate_hz;
    let mut out: Vec<Syllable> = Vec::new();
    let mut start = 0usize;
    while start < len {
        let mut dur = (nominal * rng.random_range(0.7..1.3)) as usize;
        if len - start < (0.6 * nominal) as usize + dur {
            dur = len - start;
        }
        let end = start + dur;
        let onset = draw_onset(voice, start == 0, fs, rng);
        let onset_len = match onset {
            Onset::Vowel => 0.0,
            Onset::Fricative { .. } => rng.random_range(0.06..0.13),
            Onset::Aspirate => rng.random_range(0.04..0.08),
            Onset::Stop {
                closure, aspirated, ..
            } => closure as f64 / fs + 0.012 + if aspirated { 0.03 } else { 0.0 },
            Onset::Nasal => rng.random_range(0.05..0.08),
        };
        let nucleus = start + ((onset_len * fs) as usize).min(dur * 45 / 100);
        let stress = rng.random_range(0.55..1.0);
        // Stressed syllables (a third) rise, the others sit a little low: zero mean, so that
        // f0_hz stays the median pitch.
        let accent_st = voice.f0_range_st
            * if stress > 0.85 {
                rng.random_range(0.2..0.6)
            } else {
                -0.2 + 0.1 * rng.sample::<f64, _>(StandardNormal)
            };
        let mut vowel = VOWELS[rng.random_range(0..VOWELS.len())];
        for f in vowel.iter_mut() {
            *f = (*f * voice.formant_scale).min(0.45 * fs);
        }
        out.push(Syllable {
            start,
            nucleus,
            end,
            onset,
            vowel,
            stress,
            accent_st,
        });
        start = end;
    }
    out
}

fn draw_onset<R: Rng + ?Sized>(voice: &VoiceConfig, first: bool, fs: f64, rng: &mut R) -> Onset {
    let sqrt_scale = voice.formant_scale.sqrt();
    let cap = |f: f64| f.min(0.42 * fs);
    let u: f64 = rng.random_range(0.0..1.0);
    // Phrases begin with sound, so the first syllable never starts with a silent closure.
    let u = if first && (0.55..0.75).contains(&u) {
        u - 0.2
    } else {
        u
    };
    match u {
        u if u < 0.35 => Onset::Vowel,
        u if u < 0.55 => {
            let (centre_hz, q, level_db) = match rng.random_range(0..4) {
                0 => (cap(5500.0 * sqrt_scale), 3.0, -6.0),
                1 => (cap(3000.0 * sqrt_scale), 2.5, -6.0),
                2 => (cap(4500.0), 0.6, -16.0),
                _ => (cap(5000.0), 0.7, -18.0),
            };
            Onset::Fricative {
                centre_hz,
                q,
                level: 10f64.powf(level_db / 20.0),
                voiced: rng.random_range(0.0..1.0) < 0.25,
            }
        }
        u if u < 0.75 => {
            let voiced = rng.random_range(0.0..1.0) < 0.4;
            let burst_hz = match rng.random_range(0..3) {
                0 => 1000.0,
                1 => cap(4000.0 * sqrt_scale),
                _ => 2200.0 * sqrt_scale,
            };
            Onset::Stop {
                closure: (rng.random_range(0.03..0.06) * fs) as usize,
                burst_hz,
                level: if voiced { 0.5 } else { 1.0 },
                aspirated: !voiced,
            }
        }
        u if u < 0.85 => Onset::Aspirate,
        _ => Onset::Nasal,
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

/// A band-pass biquad with 0 dB peak gain (RBJ), for frication and bursts.
#[derive(Debug, Clone, Copy, Default)]
struct BandPass {
    x1: f64,
    x2: f64,
    y1: f64,
    y2: f64,
}

impl BandPass {
    fn step(&mut self, x: f64, centre: f64, q: f64, fs: f64) -> f64 {
        let w0 = 2.0 * PI * centre / fs;
        let alpha = w0.sin() / (2.0 * q);
        let a0 = 1.0 + alpha;
        let y =
            (alpha * x - alpha * self.x2 + 2.0 * w0.cos() * self.y1 - (1.0 - alpha) * self.y2) / a0;
        self.x2 = self.x1;
        self.x1 = x;
        self.y2 = self.y1;
        self.y1 = y;
        y
    }

    /// RMS gain of white noise through the filter (the root energy of its impulse response),
    /// so that frication levels are relative to the vowels whatever the band.
    fn noise_gain(centre: f64, q: f64, fs: f64) -> f64 {
        let mut f = Self::default();
        let mut energy = 0.0;
        for n in 0..4096 {
            let y = f.step(if n == 0 { 1.0 } else { 0.0 }, centre, q, fs);
            energy += y * y;
        }
        energy.sqrt().max(1e-9)
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

/// Renders one phrase of `len` samples.
fn render_phrase<R: Rng + ?Sized>(
    voice: &VoiceConfig,
    len: usize,
    fs: f64,
    rng: &mut R,
) -> Vec<f64> {
    let syllables = plan_phrase(voice, len, fs, rng);
    let base_f0 = voice.f0_hz * 2f64.powf(rng.sample::<f64, _>(StandardNormal) * 0.08);
    let bw_scale = voice.formant_scale.sqrt();
    let k = |tau: f64| 1.0 - (-1.0 / (tau * fs)).exp();
    let (k_formant, k_pitch, k_amp) = (k(0.025), k(0.04), k(0.005));

    let mut voiced = vec![0.0; len];
    let mut noise = vec![0.0; len];
    let mut tract = [Resonator::default(); 4];
    let mut band = BandPass::default();
    let mut formants = syllables.first().map_or(VOWELS[8], |s| s.vowel);
    let mut pitch_st = voice.f0_range_st * 0.4;
    let (mut av, mut an, mut ah) = (0.0, 0.0, 0.0);
    let mut phase = 0.0;
    let mut prev_flow = 0.0;
    let (mut jitter, mut shimmer) = (1.0, 1.0);
    let mut nucleus_energy = 0.0;
    let mut nucleus_count = 0usize;
    // Noise gain of each syllable's frication or burst band.
    let band_gains: Vec<f64> = syllables
        .iter()
        .map(|s| match s.onset {
            Onset::Fricative { centre_hz, q, .. } => BandPass::noise_gain(centre_hz, q, fs),
            Onset::Stop { burst_hz, .. } => BandPass::noise_gain(burst_hz, 1.2, fs),
            _ => 1.0,
        })
        .collect();
    let mut s_idx = 0;
    for n in 0..len {
        while s_idx + 1 < syllables.len() && n >= syllables[s_idx].end {
            s_idx += 1;
        }
        let syl = &syllables[s_idx];
        let last = s_idx + 1 == syllables.len();
        // Targets of this sample.
        let (mut av_t, mut an_t, mut ah_t) = (0.0, 0.0, 0.0);
        let mut f_target = syl.vowel;
        let (mut centre, mut q, mut level) = (3000.0, 1.0, 0.0);
        let in_nucleus = n >= syl.nucleus;
        if in_nucleus {
            let x = (n - syl.nucleus) as f64 / (syl.end - syl.nucleus).max(1) as f64;
            av_t = syl.stress * (0.12 + 0.88 * (PI * x).sin().powf(0.7));
        } else {
            let x = (n - syl.start) as f64 / (syl.nucleus - syl.start).max(1) as f64;
            let bell = (PI * x).sin().powf(0.5);
            match syl.onset {
                Onset::Vowel => {}
                Onset::Fricative {
                    centre_hz,
                    q: qq,
                    level: l,
                    voiced,
                } => {
                    (centre, q, level) = (centre_hz, qq, l);
                    an_t = syl.stress * bell;
                    if voiced {
                        av_t = 0.25 * syl.stress;
                    }
                }
                Onset::Aspirate => ah_t = 0.6 * syl.stress * bell,
                Onset::Stop {
                    closure,
                    burst_hz,
                    level: l,
                    aspirated,
                } => {
                    let since = (n - syl.start) as f64 - closure as f64;
                    if since >= 0.0 {
                        let burst = 0.012 * fs;
                        if since < burst {
                            (centre, q, level) = (burst_hz, 1.2, l);
                            an_t = syl.stress * (-since / (0.004 * fs)).exp();
                        } else if aspirated {
                            ah_t = 0.5 * syl.stress;
                        }
                    }
                }
                Onset::Nasal => {
                    av_t = 0.3 * syl.stress;
                    f_target = NASAL.map(|f| f * voice.formant_scale);
                }
            }
        }
        // Smooth glides of formants, pitch and amplitudes.
        for (f, t) in formants.iter_mut().zip(f_target) {
            *f += k_formant * (t - *f);
        }
        let progress = n as f64 / len as f64;
        let mut st_target = voice.f0_range_st * (0.4 - 0.8 * progress) + syl.accent_st;
        if last {
            st_target -= 0.3 * voice.f0_range_st;
        }
        pitch_st += k_pitch * (st_target - pitch_st);
        av += k_amp * (av_t - av);
        an += if an_t > an {
            an_t - an
        } else {
            k_amp * (an_t - an)
        };
        ah += k_amp * (ah_t - ah);

        // Glottal source: one period at a time, with jitter and shimmer drawn per period.
        let f0 = (base_f0 * 2f64.powf(pitch_st / 12.0)).clamp(50.0, 500.0);
        phase += f0 / (fs * jitter);
        if phase >= 1.0 {
            phase -= 1.0;
            jitter = 1.0 + 0.008 * rng.sample::<f64, _>(StandardNormal);
            shimmer = 1.0 + 0.04 * rng.sample::<f64, _>(StandardNormal);
        }
        let flow = glottal_flow(phase, voice.open_quotient);
        let pulse = (flow - prev_flow) * shimmer * fs / (100.0 * f0);
        prev_flow = flow;
        let white: f64 = rng.sample(StandardNormal);
        let aspiration = voice.breathiness * 0.02 * white * (0.3 + flow);
        let excitation = av * (pulse + aspiration) + ah * 0.03 * white;
        let mut y = excitation;
        for (i, r) in tract.iter_mut().enumerate() {
            let bw = if !in_nucleus && matches!(syl.onset, Onset::Nasal) && i == 0 {
                150.0
            } else {
                BANDWIDTHS[i] * bw_scale
            };
            y = r.step(y, formants[i], bw, fs);
        }
        voiced[n] = y;
        if in_nucleus {
            nucleus_energy += y * y;
            nucleus_count += 1;
        }
        if an > 1e-6 {
            let g = band_gains[s_idx];
            let white2: f64 = rng.sample(StandardNormal);
            noise[n] = an * level * band.step(white2, centre, q, fs) / g;
        } else {
            band = BandPass::default();
        }
    }
    // Frication levels are relative to the RMS of the vowels of this phrase.
    let vowel_rms = (nucleus_energy / nucleus_count.max(1) as f64).sqrt();
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
