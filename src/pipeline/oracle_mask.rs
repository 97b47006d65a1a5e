//! The ideal ratio mask (`--oracle-mask`): each true source's image recovered from the
//! reference microphone by the time-frequency gain its share of the power there would give,
//! read from the truth. It is the ceiling of any single-channel mask on that microphone, the
//! figure a separator's post-filter is measured against; the separator's own framing is used,
//! so the two differ only in where the gains come from.

use crate::dsp::{Complex, FrameGeometry, Istft, StreamingStft};

/// Each image's estimate from `mixture` (the reference microphone) by the ideal ratio mask
/// |S_i|² / (Σ_j |S_j|² + |N|²), N being what the images do not explain (the noise), in the
/// STFT `geometry`; sample-aligned with the mixture and as long as it. Images shorter than the
/// mixture are silent past their end.
pub fn ideal_ratio_mask(
    mixture: &[f64],
    images: &[&[f64]],
    geometry: FrameGeometry,
) -> Vec<Vec<f64>> {
    let (hop, delay, bins) = (geometry.hop, geometry.delay(), geometry.bins());
    let len = mixture.len();
    let mut stft = StreamingStft::new(geometry, images.len() + 1);
    let mut istft: Vec<Istft> = images.iter().map(|_| Istft::new(geometry)).collect();
    let mut out = vec![vec![0.0; len]; images.len()];
    let mut hop_in = vec![vec![0.0; hop]; images.len() + 1];
    let (mut masked, mut hop_out) = (vec![Complex::new(0.0, 0.0); bins], vec![0.0; hop]);
    let mut gains = vec![vec![0.0; bins]; images.len()];
    // The inverse lags by `delay` samples: push zeros past the end until the last sample is out.
    let mut start = 0;
    while start < len + delay {
        let read = |x: &[f64], buf: &mut Vec<f64>| {
            for (t, b) in buf.iter_mut().enumerate() {
                *b = x.get(start + t).copied().unwrap_or(0.0);
            }
        };
        read(mixture, &mut hop_in[0]);
        for (x, buf) in images.iter().zip(&mut hop_in[1..]) {
            read(x, buf);
        }
        let refs: Vec<&[f64]> = hop_in.iter().map(Vec::as_slice).collect();
        let spectra = stft.push(&refs);
        let x = spectra.channel(0);
        for (k, xk) in x.iter().enumerate() {
            let mut explained = Complex::new(0.0, 0.0);
            let mut total = 0.0;
            for (j, g) in gains.iter_mut().enumerate() {
                let s = spectra.channel(j + 1)[k];
                g[k] = s.norm_sqr();
                explained += s;
                total += g[k];
            }
            total += (xk - explained).norm_sqr();
            for g in gains.iter_mut() {
                g[k] = if total > 0.0 { g[k] / total } else { 0.0 };
            }
        }
        for ((inv, y), gain) in istft.iter_mut().zip(&mut out).zip(&gains) {
            for ((m, xk), g) in masked.iter_mut().zip(x).zip(gain) {
                *m = xk * g;
            }
            inv.push(&masked, &mut hop_out);
            // Output sample n of this hop is input sample start + n - delay.
            for (n, v) in hop_out.iter().enumerate() {
                if let Some(t) = (start + n).checked_sub(delay).filter(|&t| t < len) {
                    y[t] = *v;
                }
            }
        }
        start += hop;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tone(f: f64, fs: f64, n: usize, amp: f64) -> Vec<f64> {
        (0..n)
            .map(|t| amp * (2.0 * std::f64::consts::PI * f * t as f64 / fs).sin())
            .collect()
    }

    fn energy(x: &[f64]) -> f64 {
        x.iter().map(|v| v * v).sum()
    }

    #[test]
    fn two_tones_far_apart_come_back_each_on_its_own_and_aligned() {
        let (fs, n) = (16_000.0, 16_000);
        let g = FrameGeometry {
            frame: 1024,
            hop: 512,
        };
        let (a, b) = (tone(300.0, fs, n, 1.0), tone(2_000.0, fs, n, 0.3));
        let mix: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + y).collect();
        let est = ideal_ratio_mask(&mix, &[&a, &b], g);
        assert_eq!(est.len(), 2);
        assert!(est.iter().all(|y| y.len() == n));
        // Away from the edges each estimate is its image, in time (no delay left over).
        let mid = 2048..n - 2048;
        for (y, s) in est.iter().zip([&a, &b]) {
            let err: Vec<f64> = mid.clone().map(|t| y[t] - s[t]).collect();
            let ratio = energy(&err) / energy(&s[mid.clone()]);
            assert!(ratio < 1e-3, "residual {ratio}");
        }
    }

    #[test]
    fn the_noise_no_image_explains_is_left_out() {
        let (fs, n) = (16_000.0, 8_000);
        let g = FrameGeometry {
            frame: 512,
            hop: 256,
        };
        let a = tone(440.0, fs, n, 1.0);
        let noise = tone(3_000.0, fs, n, 1.0);
        let mix: Vec<f64> = a.iter().zip(&noise).map(|(x, y)| x + y).collect();
        let est = ideal_ratio_mask(&mix, &[&a], g);
        let mid = 1024..n - 1024;
        let leak: f64 = mid.clone().map(|t| (est[0][t] - a[t]).powi(2)).sum::<f64>()
            / energy(&noise[mid.clone()]);
        assert!(leak < 1e-2, "noise kept {leak}");
    }

    #[test]
    fn silence_gives_silence() {
        let g = FrameGeometry {
            frame: 256,
            hop: 128,
        };
        let zeros = vec![0.0; 1000];
        let est = ideal_ratio_mask(&zeros, &[&zeros, &zeros], g);
        assert!(est.iter().flatten().all(|v| *v == 0.0));
    }
}
