//! The syllable plan of a synthetic phrase: timing, consonants, vowel targets, stress and pitch
//! accents, and what the source-filter model should do at each sample.
//!
//! A syllable is an optional onset consonant (fricative, stop, aspirate or nasal), a vowel
//! nucleus with a rise-fall amplitude envelope, and an optional fricative coda.

use std::f64::consts::PI;

use rand::Rng;
use rand_distr::StandardNormal;

use super::config::VoiceConfig;

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

/// A noise band (frication or a stop burst) with its level relative to the vowels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Band {
    /// Centre frequency (Hz).
    pub centre: f64,
    /// Quality factor.
    pub q: f64,
    /// Amplitude relative to the RMS of the phrase's vowels.
    pub level: f64,
    /// RMS gain of white noise through the band-pass, divided out so that `level` holds.
    pub gain: f64,
}

impl Band {
    fn new(centre: f64, q: f64, level_db: f64, fs: f64) -> Self {
        Self {
            centre,
            q,
            level: 10f64.powf(level_db / 20.0),
            gain: BandPass::noise_gain(centre, q, fs),
        }
    }
}

/// How a syllable starts.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Onset {
    /// Straight into the vowel.
    Vowel,
    /// Band-pass noise (s, sh, f, th); `voiced` adds a weak voice source (z, zh, v).
    Fricative { band: Band, voiced: bool },
    /// Glottal noise through the vocal tract (h).
    Aspirate,
    /// Closure (silence, `closure` samples), a burst, then aspiration if `aspirated`.
    Stop {
        closure: usize,
        band: Band,
        aspirated: bool,
    },
    /// Voiced nasal murmur.
    Nasal,
}

/// One syllable, in samples from the phrase start: onset [start, nucleus), vowel
/// [nucleus, coda), coda [coda, end).
#[derive(Debug, Clone, Copy)]
pub struct Syllable {
    start: usize,
    nucleus: usize,
    coda: usize,
    /// First sample after the syllable.
    pub end: usize,
    onset: Onset,
    coda_band: Option<Band>,
    /// Formant targets F1-F4 of the vowel (Hz, scaled to the voice).
    pub vowel: [f64; 4],
    stress: f64,
    /// Pitch accent (semitones).
    pub accent_st: f64,
}

/// What the source-filter model aims at for one sample.
#[derive(Debug, Clone, Copy)]
pub struct Targets {
    /// Amplitude of the voice source.
    pub voicing: f64,
    /// Amplitude of band-pass frication.
    pub frication: f64,
    /// Amplitude of glottal noise through the tract.
    pub aspiration: f64,
    /// Formant targets F1-F4 (Hz).
    pub formants: [f64; 4],
    /// The frication band, when frication is wanted.
    pub band: Option<Band>,
    /// A nasal murmur (wider first formant).
    pub nasal: bool,
    /// Inside the vowel (where the phrase's vowel level is measured).
    pub vowel: bool,
}

impl Syllable {
    /// Targets at sample `n` of the phrase (which lies in this syllable).
    pub fn targets(&self, n: usize, formant_scale: f64, fs: f64) -> Targets {
        let mut t = Targets {
            voicing: 0.0,
            frication: 0.0,
            aspiration: 0.0,
            formants: self.vowel,
            band: None,
            nasal: false,
            vowel: false,
        };
        let pos = |a: usize, b: usize| (n - a) as f64 / (b - a).max(1) as f64;
        let bell = |x: f64| (PI * x).sin().powf(0.5);
        if n >= self.coda {
            t.frication = self.stress * bell(pos(self.coda, self.end));
            t.band = self.coda_band;
            return t;
        }
        if n >= self.nucleus {
            let x = pos(self.nucleus, self.coda);
            t.voicing = self.stress * (0.12 + 0.88 * (PI * x).sin().powf(0.7));
            t.vowel = true;
            return t;
        }
        let x = pos(self.start, self.nucleus);
        match self.onset {
            Onset::Vowel => {}
            Onset::Fricative { band, voiced } => {
                t.frication = self.stress * bell(x);
                t.band = Some(band);
                if voiced {
                    t.voicing = 0.25 * self.stress;
                }
            }
            Onset::Aspirate => t.aspiration = 0.6 * self.stress * bell(x),
            Onset::Stop {
                closure,
                band,
                aspirated,
            } => {
                let since = (n - self.start) as f64 - closure as f64;
                if since >= 0.0 && since < 0.012 * fs {
                    t.frication = self.stress * (-since / (0.004 * fs)).exp();
                    t.band = Some(band);
                } else if since >= 0.0 && aspirated {
                    t.aspiration = 0.5 * self.stress;
                }
            }
            Onset::Nasal => {
                t.voicing = 0.3 * self.stress;
                t.formants = NASAL.map(|f| f * formant_scale);
                t.nasal = true;
            }
        }
        t
    }
}

/// Plans the syllables of a phrase of `len` samples.
pub fn plan_phrase<R: Rng + ?Sized>(
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
        let onset_s = match onset {
            Onset::Vowel => 0.0,
            Onset::Fricative { .. } => rng.random_range(0.06..0.13),
            Onset::Aspirate => rng.random_range(0.04..0.08),
            Onset::Stop {
                closure, aspirated, ..
            } => closure as f64 / fs + 0.012 + if aspirated { 0.03 } else { 0.0 },
            Onset::Nasal => rng.random_range(0.05..0.08),
        };
        let nucleus = start + ((onset_s * fs) as usize).min(dur * 45 / 100);
        let (coda, coda_band) = if rng.random_range(0.0..1.0) < 0.3 {
            let coda_len = ((rng.random_range(0.05..0.1) * fs) as usize).min(dur * 3 / 10);
            (end - coda_len, Some(fricative(voice, fs, rng)))
        } else {
            (end, None)
        };
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
            coda: coda.max(nucleus),
            end,
            onset,
            coda_band,
            vowel,
            stress,
            accent_st,
        });
        start = end;
    }
    out
}

/// An unvoiced fricative band: s, sh, f or th.
fn fricative<R: Rng + ?Sized>(voice: &VoiceConfig, fs: f64, rng: &mut R) -> Band {
    let sqrt_scale = voice.formant_scale.sqrt();
    let cap = |f: f64| f.min(0.42 * fs);
    match rng.random_range(0..4) {
        0 => Band::new(cap(5500.0 * sqrt_scale), 3.0, -6.0, fs),
        1 => Band::new(cap(3000.0 * sqrt_scale), 2.5, -6.0, fs),
        2 => Band::new(cap(4500.0), 0.6, -16.0, fs),
        _ => Band::new(cap(5000.0), 0.7, -18.0, fs),
    }
}

fn draw_onset<R: Rng + ?Sized>(voice: &VoiceConfig, first: bool, fs: f64, rng: &mut R) -> Onset {
    let sqrt_scale = voice.formant_scale.sqrt();
    let u: f64 = rng.random_range(0.0..1.0);
    // Phrases begin with sound, so the first syllable never starts with a silent closure.
    let u = if first && (0.55..0.75).contains(&u) {
        u - 0.2
    } else {
        u
    };
    match u {
        u if u < 0.35 => Onset::Vowel,
        u if u < 0.55 => Onset::Fricative {
            band: fricative(voice, fs, rng),
            voiced: rng.random_range(0.0..1.0) < 0.25,
        },
        u if u < 0.75 => {
            let voiced = rng.random_range(0.0..1.0) < 0.4;
            let burst_hz = match rng.random_range(0..3) {
                0 => 1000.0,
                1 => (4000.0 * sqrt_scale).min(0.42 * fs),
                _ => 2200.0 * sqrt_scale,
            };
            Onset::Stop {
                closure: (rng.random_range(0.03..0.06) * fs) as usize,
                band: Band::new(burst_hz, 1.2, if voiced { -6.0 } else { 0.0 }, fs),
                aspirated: !voiced,
            }
        }
        u if u < 0.85 => Onset::Aspirate,
        _ => Onset::Nasal,
    }
}

/// A band-pass biquad with 0 dB peak gain (RBJ), for frication and bursts.
#[derive(Debug, Clone, Copy, Default)]
pub struct BandPass {
    x1: f64,
    x2: f64,
    y1: f64,
    y2: f64,
}

impl BandPass {
    /// One sample through the band `centre`, `q`.
    pub fn step(&mut self, x: f64, centre: f64, q: f64, fs: f64) -> f64 {
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

    /// RMS gain of white noise through the filter (the root energy of its impulse response).
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

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn syllables_tile_the_phrase_at_the_speaking_rate() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let voice = VoiceConfig {
            syllable_rate_hz: 5.0,
            ..VoiceConfig::default()
        };
        let plan = plan_phrase(&voice, 48000, 16000.0, &mut rng);
        assert_eq!(plan.last().unwrap().end, 48000);
        assert!(plan.windows(2).all(|w| w[0].end == w[1].start));
        assert!(
            (12..=18).contains(&plan.len()),
            "{} syllables in 3 s",
            plan.len()
        );
        for s in &plan {
            assert!(s.start <= s.nucleus && s.nucleus <= s.coda && s.coda <= s.end);
        }
        // The first syllable never opens with silence.
        assert!(!matches!(plan[0].onset, Onset::Stop { .. }));
    }
}
