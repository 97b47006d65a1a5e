//! Short-time Fourier transform with a perfect-reconstruction inverse (realfft).
//!
//! Sign convention (rustfft/realfft forward): `X[k] = sum_n x[n] e^{-j 2 pi k n / N}`, so a
//! delay of tau seconds multiplies bin k by `e^{-j omega_k tau}`.
//!
//! Streaming framing: frame m covers input samples [m*hop - P, m*hop - P + frame) with the prepad
//! P = frame - hop (zeros before the first sample), so a frame is ready as soon as `hop` new samples
//! arrived, and the inverse emits samples with a fixed delay of P samples.

use std::sync::Arc;

use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use serde::{Deserialize, Serialize};

use super::{Complex, MultiSpectrum, hann_periodic};

/// Frame length and hop of an STFT, in samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameGeometry {
    /// Frame (window and FFT) length in samples.
    pub frame: usize,
    /// Advance between frames in samples.
    pub hop: usize,
}

impl FrameGeometry {
    /// Checks the geometry; `needs_inverse` also requires the overlap that reconstruction needs.
    pub fn validate(&self, needs_inverse: bool) -> Result<(), String> {
        if !(16..=1 << 16).contains(&self.frame) || !self.frame.is_multiple_of(2) {
            return Err(format!(
                "frame must be an even number of samples in 16..=65536, got {}",
                self.frame
            ));
        }
        if self.hop == 0 {
            return Err("hop must be at least 1 sample".into());
        }
        if needs_inverse && self.hop >= self.frame {
            return Err(format!(
                "hop ({}) must be shorter than the frame ({}) for reconstruction",
                self.hop, self.frame
            ));
        }
        Ok(())
    }

    /// Number of one-sided bins, frame / 2 + 1.
    pub fn bins(&self) -> usize {
        self.frame / 2 + 1
    }

    /// Samples of zero padding before the first input sample, and the synthesis delay.
    pub fn delay(&self) -> usize {
        self.frame.saturating_sub(self.hop)
    }
}

/// Forward transform of single windowed frames.
pub struct Stft {
    window: Vec<f64>,
    fft: Arc<dyn RealToComplex<f64>>,
    input: Vec<f64>,
    scratch: Vec<Complex>,
}

impl Stft {
    /// A forward transform of `frame` samples with a periodic Hann window.
    pub fn new(frame: usize) -> Self {
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(frame);
        let scratch = fft.make_scratch_vec();
        Self {
            window: hann_periodic(frame),
            input: vec![0.0; frame],
            fft,
            scratch,
        }
    }

    /// Frame length.
    pub fn frame(&self) -> usize {
        self.window.len()
    }

    /// Windows `samples` (length `frame`) and writes its `frame / 2 + 1` bins to `out`.
    pub fn forward(&mut self, samples: &[f64], out: &mut [Complex]) {
        for ((d, s), w) in self.input.iter_mut().zip(samples).zip(&self.window) {
            *d = s * w;
        }
        // Lengths are fixed at construction, so the transform cannot fail.
        let _ = self
            .fft
            .process_with_scratch(&mut self.input, out, &mut self.scratch);
    }
}

/// Streaming inverse STFT by least-squares weighted overlap-add.
///
/// The synthesis window is `w[t] / sum_k w^2[t + k hop]`, which reconstructs the input exactly for any
/// hop shorter than the frame.
pub struct Istft {
    geometry: FrameGeometry,
    synthesis: Vec<f64>,
    ifft: Arc<dyn ComplexToReal<f64>>,
    spectrum: Vec<Complex>,
    frame_out: Vec<f64>,
    acc: Vec<f64>,
    scratch: Vec<Complex>,
}

impl Istft {
    /// An inverse for the given geometry (validated by the caller).
    pub fn new(geometry: FrameGeometry) -> Self {
        let (n, h) = (geometry.frame, geometry.hop);
        let w = hann_periodic(n);
        let mut denom = vec![0.0; h];
        for (t, wt) in w.iter().enumerate() {
            denom[t % h] += wt * wt;
        }
        let synthesis = w
            .iter()
            .enumerate()
            .map(|(t, wt)| wt / denom[t % h].max(1e-12))
            .collect();
        let ifft = RealFftPlanner::<f64>::new().plan_fft_inverse(n);
        let scratch = ifft.make_scratch_vec();
        Self {
            geometry,
            synthesis,
            spectrum: vec![Complex::new(0.0, 0.0); n / 2 + 1],
            frame_out: vec![0.0; n],
            acc: vec![0.0; n],
            ifft,
            scratch,
        }
    }

    /// Adds the inverse of one frame's bins and writes the next `hop` finished samples to `out`.
    pub fn push(&mut self, bins: &[Complex], out: &mut [f64]) {
        let (n, h) = (self.geometry.frame, self.geometry.hop);
        self.spectrum.copy_from_slice(bins);
        // A real signal has real DC and Nyquist bins; drop any imaginary residue.
        self.spectrum[0].im = 0.0;
        self.spectrum[n / 2].im = 0.0;
        let _ = self.ifft.process_with_scratch(
            &mut self.spectrum,
            &mut self.frame_out,
            &mut self.scratch,
        );
        let scale = 1.0 / n as f64;
        for ((a, x), w) in self
            .acc
            .iter_mut()
            .zip(&self.frame_out)
            .zip(&self.synthesis)
        {
            *a += x * scale * w;
        }
        out[..h].copy_from_slice(&self.acc[..h]);
        self.acc.copy_within(h.., 0);
        self.acc[n - h..].fill(0.0);
    }

    /// Forgets all overlap state.
    pub fn reset(&mut self) {
        self.acc.fill(0.0);
    }
}

/// Multichannel streaming analysis: push `hop` samples per channel, get one frame of spectra.
pub struct StreamingStft {
    geometry: FrameGeometry,
    stft: Stft,
    history: Vec<Vec<f64>>,
    spectra: MultiSpectrum,
}

impl StreamingStft {
    /// Streaming analysis of `channels` channels; the history starts as the zero prepad.
    pub fn new(geometry: FrameGeometry, channels: usize) -> Self {
        Self {
            geometry,
            stft: Stft::new(geometry.frame),
            history: vec![vec![0.0; geometry.frame]; channels],
            spectra: MultiSpectrum::zeros(channels, geometry.bins()),
        }
    }

    /// The frame geometry.
    pub fn geometry(&self) -> FrameGeometry {
        self.geometry
    }

    /// Appends one hop of samples per channel (`hop[ch]` has `hop` samples) and returns the
    /// spectra of the frame that ends with them.
    pub fn push(&mut self, hop: &[&[f64]]) -> &MultiSpectrum {
        let n = self.geometry.frame;
        for (ch, samples) in hop.iter().enumerate() {
            let hist = &mut self.history[ch];
            if samples.len() >= n {
                hist.copy_from_slice(&samples[samples.len() - n..]);
            } else {
                hist.copy_within(samples.len().., 0);
                hist[n - samples.len()..].copy_from_slice(samples);
            }
            self.stft
                .forward(&self.history[ch], self.spectra.channel_mut(ch));
        }
        &self.spectra
    }

    /// Resets the history to silence.
    pub fn reset(&mut self) {
        for h in &mut self.history {
            h.fill(0.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n).map(|_| rng.random_range(-0.5..0.5)).collect()
    }

    fn round_trip(frame: usize, hop: usize) {
        let g = FrameGeometry { frame, hop };
        g.validate(true).unwrap();
        let x = noise(hop * 40, 7);
        let mut a = StreamingStft::new(g, 1);
        let mut s = Istft::new(g);
        let mut y = Vec::new();
        let mut out = vec![0.0; hop];
        for chunk in x.chunks(hop) {
            let spec = a.push(&[chunk]).channel(0).to_vec();
            s.push(&spec, &mut out);
            y.extend_from_slice(&out);
        }
        let d = g.delay();
        for i in 0..x.len() - d {
            assert!(
                (y[i + d] - x[i]).abs() < 1e-9,
                "frame {frame} hop {hop} sample {i}"
            );
        }
    }

    #[test]
    fn reconstructs_perfectly_with_fixed_delay() {
        round_trip(1024, 512);
        round_trip(2048, 1024);
        round_trip(512, 128);
        round_trip(400, 160);
    }

    #[test]
    fn delay_follows_forward_sign_convention() {
        // A pure (circular) delay of d samples multiplies bin k by exp(-j 2 pi k d / N).
        let (n, k, d) = (256usize, 5usize, 3.0);
        let tone = |shift: f64| -> Vec<f64> {
            (0..n)
                .map(|t| {
                    (2.0 * std::f64::consts::PI * k as f64 * (t as f64 - shift) / n as f64).cos()
                })
                .collect()
        };
        let mut stft = Stft::new(n);
        stft.window.fill(1.0);
        let mut a = vec![Complex::new(0.0, 0.0); n / 2 + 1];
        let mut b = a.clone();
        stft.forward(&tone(0.0), &mut a);
        stft.forward(&tone(d), &mut b);
        let expect = (-Complex::i() * 2.0 * std::f64::consts::PI * k as f64 * d / n as f64).exp();
        assert!((b[k] / a[k] - expect).norm() < 1e-9);
    }

    #[test]
    fn validates_geometry() {
        assert!(
            FrameGeometry {
                frame: 1024,
                hop: 1024
            }
            .validate(true)
            .is_err()
        );
        assert!(
            FrameGeometry {
                frame: 1024,
                hop: 1024
            }
            .validate(false)
            .is_ok()
        );
        assert!(
            FrameGeometry {
                frame: 1023,
                hop: 512
            }
            .validate(false)
            .is_err()
        );
        assert!(
            FrameGeometry {
                frame: 1024,
                hop: 0
            }
            .validate(false)
            .is_err()
        );
    }
}
