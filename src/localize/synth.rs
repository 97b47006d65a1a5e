//! Synthetic multichannel signals for the localiser's tests: free-field fractional delays with
//! 1/r gain, optional first-order image sources of a shoebox room, and sensor noise.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use realfft::RealFftPlanner;

use crate::dsp::{Complex, MultiSpectrum, Stft};
use crate::geometry::{Aabb, Layout, MicArray, Vec3};

/// White Gaussian noise of unit variance.
pub fn white(len: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = Normal::new(0.0, 1.0).unwrap();
    (0..len).map(|_| n.sample(&mut rng)).collect()
}

/// A voiced, speech-like harmonic signal: fundamental `f0` with a slow vibrato, harmonics up to
/// 5 kHz with 1/h amplitudes and random phases, unit-ish power.
pub fn harmonic(len: usize, f0: f64, fs: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let phases: Vec<f64> = (0..64)
        .map(|_| rand::Rng::random::<f64>(&mut rng) * 2.0 * std::f64::consts::PI)
        .collect();
    let mut phase = 0.0;
    (0..len)
        .map(|t| {
            let f = f0 * (1.0 + 0.03 * (2.0 * std::f64::consts::PI * 3.0 * t as f64 / fs).sin());
            phase += 2.0 * std::f64::consts::PI * f / fs;
            let mut v = 0.0;
            let mut h = 1;
            while (h as f64) * f < 5000.0 && h < 64 {
                v += (h as f64 * phase + phases[h]).sin() / h as f64;
                h += 1;
            }
            v
        })
        .collect()
}

/// A shoebox room for first-order image sources.
pub struct Room {
    pub bounds: Aabb,
    /// Pressure reflection coefficient of every wall.
    pub reflection: f64,
}

/// Renders what `mics` record from `sources` (position, signal) in free field (plus the six
/// first-order images when `room` is given), each path delayed exactly (fractional, circular over
/// a padded length) with gain 1/r, plus white sensor noise of standard deviation `noise`.
pub fn render(
    mics: &[Vec3],
    sources: &[(Vec3, &[f64])],
    fs: f64,
    c: f64,
    room: Option<&Room>,
    noise: f64,
    seed: u64,
) -> Vec<Vec<f64>> {
    let len = sources.iter().map(|s| s.1.len()).max().unwrap_or(0);
    let n = (len + 4096).next_power_of_two();
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(n);
    let inv = planner.plan_fft_inverse(n);
    let mut acc = vec![vec![Complex::new(0.0, 0.0); n / 2 + 1]; mics.len()];
    for (pos, sig) in sources {
        let mut buf = vec![0.0; n];
        buf[..sig.len()].copy_from_slice(sig);
        let mut spec = vec![Complex::new(0.0, 0.0); n / 2 + 1];
        fwd.process(&mut buf, &mut spec).unwrap();
        let mut paths = vec![(*pos, 1.0)];
        if let Some(r) = room {
            for axis in 0..3 {
                for wall in [r.bounds.min[axis], r.bounds.max[axis]] {
                    let mut img = *pos;
                    img[axis] = 2.0 * wall - pos[axis];
                    paths.push((img, r.reflection));
                }
            }
        }
        for (m, mic) in mics.iter().enumerate() {
            for &(p, g) in &paths {
                let dist = (p - mic).norm();
                let delay = dist / c * fs;
                let gain = g / dist;
                for (k, (a, s)) in acc[m].iter_mut().zip(&spec).enumerate() {
                    let w = -2.0 * std::f64::consts::PI * k as f64 / n as f64 * delay;
                    *a += s * Complex::from_polar(gain, w);
                }
            }
        }
    }
    let mut out = Vec::with_capacity(mics.len());
    for (m, spec) in acc.iter_mut().enumerate() {
        spec[0].im = 0.0;
        spec[n / 2].im = 0.0;
        let mut x = vec![0.0; n];
        inv.process(spec, &mut x).unwrap();
        let z = white(len, seed.wrapping_add(1000 + m as u64));
        out.push(
            x[..len]
                .iter()
                .zip(&z)
                .map(|(v, e)| v / n as f64 + noise * e)
                .collect(),
        );
    }
    out
}

/// Spectra of the Hann-windowed frame starting at `start` of every channel.
pub fn spectra_at(signals: &[Vec<f64>], start: usize, frame: usize) -> MultiSpectrum {
    let mut stft = Stft::new(frame);
    let mut out = MultiSpectrum::zeros(signals.len(), frame / 2 + 1);
    for (ch, s) in signals.iter().enumerate() {
        stft.forward(&s[start..start + frame], out.channel_mut(ch));
    }
    out
}

/// A uniform circular array of `n` mics with radius `r` around `centre` in a horizontal plane.
pub fn uca(n: usize, r: f64, centre: Vec3, first_channel: usize, id: &str) -> MicArray {
    let mics = (0..n)
        .map(|i| {
            let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
            centre + Vec3::new(r * a.cos(), r * a.sin(), 0.0)
        })
        .collect();
    MicArray::new(id, mics, (first_channel..first_channel + n).collect()).unwrap()
}

/// A single-array layout at 16 kHz with c = 343 m/s.
pub fn layout(arrays: Vec<MicArray>, region: Option<Aabb>) -> Layout {
    Layout::new(16000, 343.0, arrays, vec![], region).unwrap()
}

/// The room used by most tests: 6 x 5 x 3 m.
pub fn room_box() -> Aabb {
    Aabb::new(Vec3::zeros(), Vec3::new(6.0, 5.0, 3.0)).unwrap()
}
