//! Test-only signals for the separator: an image-source shoebox room and speech-like sources.
//! (The project's own simulator lives in `scene::sim`; this one only has to make echoic
//! mixtures with known per-source images for the separator's tests.)

use std::f64::consts::PI;

use avsep::geometry::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use realfft::RealFftPlanner;

/// A shoebox room with uniformly absorbing walls.
pub struct Room {
    pub dims: Vec3,
    pub beta: f64,
    pub fs: f64,
    pub c: f64,
}

impl Room {
    /// Wall reflection coefficient from Sabine's formula for the given RT60 (s); `rt60 <= 0` is
    /// an anechoic room.
    pub fn with_rt60(dims: Vec3, rt60: f64, fs: f64, c: f64) -> Self {
        let beta = if rt60 <= 0.0 {
            0.0
        } else {
            let v = dims.x * dims.y * dims.z;
            let s = 2.0 * (dims.x * dims.y + dims.x * dims.z + dims.y * dims.z);
            let alpha = (0.161 * v / (s * rt60)).min(1.0);
            (1.0 - alpha).sqrt()
        };
        Self { dims, beta, fs, c }
    }

    /// Room impulse response from `src` to `mic`, `len` samples (image-source method, Allen and
    /// Berkley, with windowed-sinc fractional delays).
    pub fn rir(&self, src: &Vec3, mic: &Vec3, len: usize) -> Vec<f64> {
        const HALF: i64 = 16;
        let mut h = vec![0.0; len];
        let reach = len as f64 / self.fs * self.c;
        let n = |l: f64| (reach / (2.0 * l)).ceil() as i64 + 1;
        let (nx, ny, nz) = if self.beta > 0.0 {
            (n(self.dims.x), n(self.dims.y), n(self.dims.z))
        } else {
            (0, 0, 0)
        };
        for ix in -nx..=nx {
            for iy in -ny..=ny {
                for iz in -nz..=nz {
                    for q in 0..8u32 {
                        let (qx, qy, qz) =
                            ((q & 1) as i64, ((q >> 1) & 1) as i64, ((q >> 2) & 1) as i64);
                        let refl = (ix - qx).abs()
                            + ix.abs()
                            + (iy - qy).abs()
                            + iy.abs()
                            + (iz - qz).abs()
                            + iz.abs();
                        if self.beta == 0.0 && refl > 0 {
                            continue;
                        }
                        let img = Vec3::new(
                            (1 - 2 * qx) as f64 * src.x + 2.0 * ix as f64 * self.dims.x,
                            (1 - 2 * qy) as f64 * src.y + 2.0 * iy as f64 * self.dims.y,
                            (1 - 2 * qz) as f64 * src.z + 2.0 * iz as f64 * self.dims.z,
                        );
                        let d = (img - mic).norm();
                        let delay = d / self.c * self.fs;
                        if delay >= (len as i64 - HALF - 1) as f64 {
                            continue;
                        }
                        let amp = self.beta.powi(refl as i32) / (4.0 * PI * d.max(0.01));
                        let n0 = delay.floor() as i64;
                        for i in (n0 - HALF + 1).max(0)..=(n0 + HALF) {
                            let t = i as f64 - delay;
                            let sinc = if t.abs() < 1e-12 {
                                1.0
                            } else {
                                (PI * t).sin() / (PI * t)
                            };
                            let w = 0.5 + 0.5 * (PI * t / HALF as f64).cos();
                            h[i as usize] += amp * sinc * w;
                        }
                    }
                }
            }
        }
        h
    }
}

/// Linear convolution of `x` with `h`, truncated to `x.len()` samples (FFT based).
pub fn convolve(x: &[f64], h: &[f64]) -> Vec<f64> {
    let n = (x.len() + h.len()).next_power_of_two();
    let mut planner = RealFftPlanner::<f64>::new();
    let f = planner.plan_fft_forward(n);
    let inv = planner.plan_fft_inverse(n);
    let mut a = vec![0.0; n];
    a[..x.len()].copy_from_slice(x);
    let mut b = vec![0.0; n];
    b[..h.len()].copy_from_slice(h);
    let mut fa = f.make_output_vec();
    let mut fb = f.make_output_vec();
    f.process(&mut a, &mut fa).unwrap();
    f.process(&mut b, &mut fb).unwrap();
    for (x, y) in fa.iter_mut().zip(&fb) {
        *x *= y / n as f64;
    }
    let mut out = vec![0.0; n];
    inv.process(&mut fa, &mut out).unwrap();
    out.truncate(x.len());
    out
}

/// A speech-like signal: syllables of voiced (glottal pulses through formant resonators, with a
/// moving pitch) or unvoiced (resonant noise) sound, separated by short gaps and longer pauses.
/// Returns the signal and its talk spurts (s).
pub fn speech(seconds: f64, fs: f64, f0: f64, seed: u64) -> (Vec<f64>, Vec<(f64, f64)>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = (seconds * fs) as usize;
    let mut x = vec![0.0; n];
    let mut spurts: Vec<(f64, f64)> = Vec::new();
    let mut t = rng.random_range(0.0..0.3);
    let mut phase = 0.0;
    while t < seconds {
        // A talk spurt of a few syllables, then a pause.
        let syllables = rng.random_range(3..9);
        let spurt_start = t;
        for _ in 0..syllables {
            let dur = rng.random_range(0.12..0.3);
            let voiced = rng.random::<f64>() < 0.8;
            let level = 10f64.powf(rng.random_range(-6.0..3.0) / 20.0);
            let formants = [
                rng.random_range(300.0..800.0),
                rng.random_range(900.0..2300.0),
                rng.random_range(2400.0..3200.0),
            ];
            let pitch0 = f0 * rng.random_range(0.85..1.15);
            let pitch1 = f0 * rng.random_range(0.85..1.15);
            let fric = rng.random_range(2500.0..6000.0);
            let i0 = (t * fs) as usize;
            let len = (dur * fs) as usize;
            let mut src = vec![0.0; len];
            let mut lp = 0.0;
            for (i, s) in src.iter_mut().enumerate() {
                let u = i as f64 / len as f64;
                let e = if voiced {
                    let f = pitch0 + (pitch1 - pitch0) * u;
                    phase += f / fs;
                    let pulse = if phase >= 1.0 {
                        phase -= 1.0;
                        1.0
                    } else {
                        0.0
                    };
                    // Glottal tilt: a one-pole low-pass of the pulse train.
                    lp = 0.9 * lp + pulse;
                    lp + 0.02 * (rng.random::<f64>() - 0.5)
                } else {
                    rng.random::<f64>() - 0.5
                };
                *s = e;
            }
            let mut y = if voiced {
                let mut acc = vec![0.0; len];
                for (j, f) in formants.iter().enumerate() {
                    let r = resonate(&src, *f, 80.0 + 40.0 * j as f64, fs);
                    let g = [1.0, 0.6, 0.3][j];
                    for (a, v) in acc.iter_mut().zip(&r) {
                        *a += g * v;
                    }
                }
                acc
            } else {
                resonate(&src, fric, 1500.0, fs)
            };
            let peak = y.iter().fold(1e-12, |m: f64, v| m.max(v.abs()));
            for (i, v) in y.iter_mut().enumerate() {
                let u = i as f64 / len as f64;
                let env = (PI * u).sin().powf(0.6);
                *v *= level * env / peak * 0.3;
            }
            for (i, v) in y.iter().enumerate() {
                if i0 + i < n {
                    x[i0 + i] += v;
                }
            }
            t += dur + rng.random_range(0.0..0.08);
        }
        spurts.push((spurt_start, t.min(seconds)));
        t += rng.random_range(0.2..0.9);
    }
    // Speech has no energy below ~80 Hz.
    dc_block(&mut x, 0.97);
    (x, spurts)
}

/// Two-pole band-pass resonator at `f` Hz with bandwidth `bw` Hz (zeros at DC and Nyquist, about
/// unit gain at resonance).
fn resonate(x: &[f64], f: f64, bw: f64, fs: f64) -> Vec<f64> {
    let r = (-PI * bw / fs).exp();
    let th = 2.0 * PI * f / fs;
    let (a1, a2) = (2.0 * r * th.cos(), -r * r);
    let g = (1.0 - r * r) / 2.0;
    let (mut x1, mut x2, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0);
    x.iter()
        .map(|&v| {
            let y = g * (v - x2) + a1 * y1 + a2 * y2;
            x2 = x1;
            x1 = v;
            y2 = y1;
            y1 = y;
            y
        })
        .collect()
}

/// First-order DC blocker (high-pass, corner about fs (1 - p) / 2 pi).
fn dc_block(x: &mut [f64], p: f64) {
    let (mut x1, mut y1) = (0.0, 0.0);
    for v in x.iter_mut() {
        let y = *v - x1 + p * y1;
        x1 = *v;
        y1 = y;
        *v = y;
    }
}

/// White Gaussian-ish noise (sum of uniforms) of unit variance.
pub fn white(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let s: f64 = (0..4).map(|_| rng.random::<f64>() - 0.5).sum();
            s * (3.0f64).sqrt()
        })
        .collect()
}
