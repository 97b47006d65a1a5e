//! Noise: white sensor noise at a given SNR, and the dry signal of a fan-like point source.
//!
//! SNR definition (used by both `noise.snr_db` and `noise.point.snr_db`): the reference power is
//! the mean power of the speech mixture (the sum of every talker's image) at the reference
//! microphone over the samples where at least one talker is active; the noise power is the mean
//! power of the noise over the whole scene (per microphone for sensor noise, at the reference
//! microphone for the point source). Generated noise is scaled to meet the definition exactly.

use std::f64::consts::PI;

use rand::Rng;
use rand_distr::StandardNormal;

/// Mean power of `x` over the samples inside `intervals` (s); over all samples when no interval
/// covers any sample.
pub fn active_power(x: &[f64], intervals: &[(f64, f64)], sample_rate: f64) -> f64 {
    let mut mask = vec![false; x.len()];
    for &(a, b) in intervals {
        let a = ((a * sample_rate).round().max(0.0) as usize).min(x.len());
        let b = ((b * sample_rate).round().max(0.0) as usize).min(x.len());
        mask[a..b.max(a)].iter_mut().for_each(|m| *m = true);
    }
    let (e, n) = x
        .iter()
        .zip(&mask)
        .filter(|(_, m)| **m)
        .fold((0.0, 0usize), |(e, n), (v, _)| (e + v * v, n + 1));
    if n == 0 { mean_power(x) } else { e / n as f64 }
}

/// Mean power of `x` (0 when empty).
pub fn mean_power(x: &[f64]) -> f64 {
    if x.is_empty() {
        0.0
    } else {
        x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64
    }
}

/// Scales `x` so that its mean power becomes `power` (no change to a silent signal).
pub fn set_power(x: &mut [f64], power: f64) {
    let p = mean_power(x);
    if p > 0.0 && power.is_finite() && power >= 0.0 {
        let g = (power / p).sqrt();
        x.iter_mut().for_each(|v| *v *= g);
    }
}

/// `len` samples of white Gaussian noise with mean power exactly `power`.
pub fn white<R: Rng + ?Sized>(len: usize, power: f64, rng: &mut R) -> Vec<f64> {
    let mut x: Vec<f64> = (0..len).map(|_| rng.sample(StandardNormal)).collect();
    set_power(&mut x, power);
    x
}

/// A fan: low-passed (coloured) broadband noise plus a blade-pass hum with decaying harmonics
/// and a slow amplitude wobble; unit mean power.
pub fn fan<R: Rng + ?Sized>(
    len: usize,
    sample_rate: f64,
    hum_hz: f64,
    corner_hz: f64,
    rng: &mut R,
) -> Vec<f64> {
    // One-pole low-pass for the colour, one-pole high-pass at 40 Hz against rumble.
    let lp = (-2.0 * PI * corner_hz / sample_rate).exp();
    let hp = (-2.0 * PI * 40.0 / sample_rate).exp();
    let (mut y, mut hx, mut hy) = (0.0, 0.0, 0.0);
    let mut x: Vec<f64> = (0..len)
        .map(|_| {
            let w: f64 = rng.sample(StandardNormal);
            y = (1.0 - lp) * w + lp * y;
            let out = hp * (hy + y - hx);
            hx = y;
            hy = out;
            out
        })
        .collect();
    set_power(&mut x, 1.0);
    if hum_hz > 0.0 {
        let phases: Vec<f64> = (0..6).map(|_| rng.random_range(0.0..2.0 * PI)).collect();
        let wobble_hz = rng.random_range(0.2..0.6);
        let mut hum: Vec<f64> = (0..len)
            .map(|n| {
                let t = n as f64 / sample_rate;
                let wob = 1.0 + 0.2 * (2.0 * PI * wobble_hz * t).sin();
                (1..=6)
                    .filter(|h| (*h as f64) * hum_hz < 0.45 * sample_rate)
                    .map(|h| {
                        wob * (2.0 * PI * h as f64 * hum_hz * t + phases[h - 1]).sin() / h as f64
                    })
                    .sum()
            })
            .collect();
        // Hum 6 dB below the broadband part.
        set_power(&mut hum, 0.25);
        x.iter_mut().zip(&hum).for_each(|(a, b)| *a += b);
        set_power(&mut x, 1.0);
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn white_noise_has_the_requested_power_and_fan_is_coloured() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let w = white(16000, 0.01, &mut rng);
        assert!((mean_power(&w) - 0.01).abs() < 1e-12);
        let f = fan(32000, 16000.0, 100.0, 300.0, &mut rng);
        assert!((mean_power(&f) - 1.0).abs() < 1e-9);
        // Coloured: neighbouring samples are strongly correlated (white noise would give ~0).
        let r1: f64 = f.windows(2).map(|p| p[0] * p[1]).sum::<f64>() / f.len() as f64;
        assert!(r1 > 0.5, "{r1}");
    }

    #[test]
    fn active_power_counts_only_active_samples() {
        let mut x = vec![0.0; 1000];
        x[100..200].iter_mut().for_each(|v| *v = 2.0);
        assert!((active_power(&x, &[(0.1, 0.2)], 1000.0) - 4.0).abs() < 1e-12);
        assert!((active_power(&x, &[], 1000.0) - 0.4).abs() < 1e-12);
    }
}
