//! WAV input and output (hound): interleaved multichannel audio as f32 in [-1, 1].

use std::path::Path;

use super::SceneError;

/// Interleaved multichannel audio.
#[derive(Debug, Clone, PartialEq)]
pub struct Audio {
    /// Sample rate (Hz).
    pub sample_rate: u32,
    /// Number of channels.
    pub channels: usize,
    /// Interleaved samples, `frames() * channels` long.
    pub samples: Vec<f32>,
}

/// How to store samples in a written WAV file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleFormat {
    /// 16-bit PCM.
    I16,
    /// 32-bit IEEE float.
    F32,
}

impl Audio {
    /// Silence of the given shape.
    pub fn silence(sample_rate: u32, channels: usize, frames: usize) -> Self {
        Self {
            sample_rate,
            channels,
            samples: vec![0.0; frames * channels],
        }
    }

    /// Mono audio from one channel of samples.
    pub fn mono(sample_rate: u32, samples: Vec<f32>) -> Self {
        Self {
            sample_rate,
            channels: 1,
            samples,
        }
    }

    /// Number of sample frames (samples per channel).
    pub fn frames(&self) -> usize {
        self.samples.len().checked_div(self.channels).unwrap_or(0)
    }

    /// Duration in seconds.
    pub fn duration(&self) -> f64 {
        self.frames() as f64 / self.sample_rate as f64
    }

    /// The samples of one channel.
    pub fn channel(&self, ch: usize) -> Vec<f32> {
        self.samples
            .iter()
            .skip(ch)
            .step_by(self.channels)
            .copied()
            .collect()
    }

    /// Reads a PCM (8/16/24/32-bit) or IEEE-float WAV file.
    pub fn read(path: &Path) -> Result<Self, SceneError> {
        let reader = hound::WavReader::open(path)
            .map_err(|e| SceneError::new(path, format!("cannot read WAV: {e}")))?;
        let spec = reader.spec();
        let bad = |e: hound::Error| SceneError::new(path, format!("corrupt WAV data: {e}"));
        let samples: Vec<f32> = match spec.sample_format {
            hound::SampleFormat::Float => {
                if spec.bits_per_sample != 32 {
                    return Err(
                        SceneError::new(path, "float WAV must be 32-bit").field("bits_per_sample")
                    );
                }
                reader
                    .into_samples::<f32>()
                    .collect::<Result<_, _>>()
                    .map_err(bad)?
            }
            hound::SampleFormat::Int => {
                let bits = spec.bits_per_sample;
                if !(8..=32).contains(&bits) {
                    return Err(
                        SceneError::new(path, format!("unsupported PCM width {bits}"))
                            .field("bits_per_sample"),
                    );
                }
                let scale = 1.0 / (1u64 << (bits - 1)) as f64;
                reader
                    .into_samples::<i32>()
                    .map(|s| s.map(|v| (v as f64 * scale) as f32))
                    .collect::<Result<_, _>>()
                    .map_err(bad)?
            }
        };
        let channels = spec.channels as usize;
        if channels == 0 {
            return Err(SceneError::new(path, "WAV has no channels").field("channels"));
        }
        if let Some(i) = samples.iter().position(|s| !s.is_finite()) {
            return Err(SceneError::new(
                path,
                format!(
                    "sample {} of channel {} is not a finite number",
                    i / channels,
                    i % channels
                ),
            )
            .field("samples"));
        }
        Ok(Self {
            sample_rate: spec.sample_rate,
            channels,
            samples,
        })
    }

    /// Writes the audio; 16-bit output is clipped to [-1, 1) (full scale is 32768).
    pub fn write(&self, path: &Path, format: SampleFormat) -> Result<(), SceneError> {
        let spec = hound::WavSpec {
            channels: self.channels as u16,
            sample_rate: self.sample_rate,
            bits_per_sample: match format {
                SampleFormat::I16 => 16,
                SampleFormat::F32 => 32,
            },
            sample_format: match format {
                SampleFormat::I16 => hound::SampleFormat::Int,
                SampleFormat::F32 => hound::SampleFormat::Float,
            },
        };
        let io = |e: hound::Error| SceneError::new(path, format!("cannot write WAV: {e}"));
        let mut w = hound::WavWriter::create(path, spec).map_err(io)?;
        match format {
            SampleFormat::F32 => {
                for &s in &self.samples {
                    w.write_sample(s).map_err(io)?;
                }
            }
            SampleFormat::I16 => {
                for &s in &self.samples {
                    w.write_sample((s * 32768.0).round().clamp(-32768.0, 32767.0) as i16)
                        .map_err(io)?;
                }
            }
        }
        w.finalize().map_err(io)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_both_formats() {
        let dir = tempfile::tempdir().unwrap();
        let a = Audio {
            sample_rate: 16000,
            channels: 2,
            samples: vec![0.0, 0.5, -0.25, 0.125, 0.99, -1.0],
        };
        for (fmt, tol) in [(SampleFormat::F32, 0.0), (SampleFormat::I16, 1.0 / 32767.0)] {
            let p = dir.path().join("a.wav");
            a.write(&p, fmt).unwrap();
            let b = Audio::read(&p).unwrap();
            assert_eq!((b.sample_rate, b.channels, b.frames()), (16000, 2, 3));
            for (x, y) in a.samples.iter().zip(&b.samples) {
                assert!((x - y).abs() <= tol as f32 + 1e-6, "{fmt:?}: {x} vs {y}");
            }
        }
        assert_eq!(a.channel(1), vec![0.5, 0.125, -1.0]);
    }

    #[test]
    fn rejects_non_finite_samples() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("nan.wav");
        Audio {
            sample_rate: 16000,
            channels: 2,
            samples: vec![0.0, 0.1, f32::NAN, 0.0],
        }
        .write(&p, SampleFormat::F32)
        .unwrap();
        let e = Audio::read(&p).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("samples"));
        assert!(e.message.contains("sample 1 of channel 0"), "{e}");
    }
}
