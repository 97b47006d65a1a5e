//! Recorded speech as source signals: WAV files from a folder, mixed to mono and resampled to
//! the scene rate, laid into a talker's phrases.
//!
//! Each phrase takes the next stretch of its file (wrapping to the start at the end), with 10 ms
//! fades at the cuts; the talker's active intervals are where the laid-out signal has speech
//! energy (20 ms frames within 35 dB of the loud frames, gaps under 0.2 s closed, bursts under
//! 0.1 s dropped), so pauses inside the recording count as silence.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use crate::scene::Audio;

use super::SimError;
use super::room::sinc;

/// A recorded speech signal at the scene rate.
#[derive(Debug, Clone, PartialEq)]
pub struct SpeechFile {
    /// Where it came from.
    pub path: PathBuf,
    /// Mono samples at the scene rate.
    pub samples: Vec<f64>,
}

/// Reads every `.wav` file of `dir` (name order; other files are ignored), or `dir` itself when
/// it is a WAV file. Stereo and multichannel files are mixed to mono; other rates resampled.
pub fn load_speech(dir: &Path, sample_rate: u32) -> Result<Vec<SpeechFile>, SimError> {
    let err = |path: &Path, message: String| SimError::Speech {
        path: path.to_path_buf(),
        message,
    };
    let meta = std::fs::metadata(dir).map_err(|e| err(dir, format!("cannot open: {e}")))?;
    let paths: Vec<PathBuf> = if meta.is_dir() {
        let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| err(dir, format!("cannot list folder: {e}")))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.is_file()
                    && p.extension()
                        .is_some_and(|x| x.to_string_lossy().eq_ignore_ascii_case("wav"))
            })
            .collect();
        v.sort();
        if v.is_empty() {
            return Err(err(dir, "holds no .wav files".into()));
        }
        v
    } else {
        vec![dir.to_path_buf()]
    };
    paths
        .into_iter()
        .map(|path| {
            let audio = Audio::read(&path).map_err(|e| err(&path, e.message))?;
            let mono = mix_to_mono(&audio);
            if mono.is_empty() || mono.iter().all(|v| *v == 0.0) {
                return Err(err(&path, "is empty or silent".into()));
            }
            let samples = if audio.sample_rate == sample_rate {
                mono
            } else {
                resample(&mono, audio.sample_rate as f64, sample_rate as f64)
            };
            Ok(SpeechFile { path, samples })
        })
        .collect()
}

fn mix_to_mono(audio: &Audio) -> Vec<f64> {
    let c = audio.channels.max(1);
    audio
        .samples
        .chunks_exact(c)
        .map(|f| f.iter().map(|v| *v as f64).sum::<f64>() / c as f64)
        .collect()
}

/// Band-limited resampling by windowed-sinc interpolation (16 zero crossings of the lower
/// rate's sinc each side, Hann window), with the cut-off at the lower Nyquist frequency.
pub fn resample(x: &[f64], from_hz: f64, to_hz: f64) -> Vec<f64> {
    let ratio = to_hz / from_hz;
    let cutoff = ratio.min(1.0);
    let half = (16.0 / cutoff).ceil() as isize;
    let out_len = (x.len() as f64 * ratio).round() as usize;
    (0..out_len)
        .map(|n| {
            let t = n as f64 / ratio;
            let k0 = t.floor() as isize;
            let mut acc = 0.0;
            for k in (k0 - half + 1)..=(k0 + half) {
                if k < 0 || k as usize >= x.len() {
                    continue;
                }
                let d = t - k as f64;
                let w = 0.5 + 0.5 * (PI * d / half as f64).cos();
                if d.abs() < half as f64 {
                    acc += x[k as usize] * cutoff * sinc(cutoff * d) * w;
                }
            }
            acc
        })
        .collect()
}

/// Lays `file` into `phrases` (s) of a signal of `len` samples: each phrase continues the file
/// where the previous one stopped, faded in and out over 10 ms.
pub fn lay_out(file: &[f64], phrases: &[(f64, f64)], sample_rate: f64, len: usize) -> Vec<f64> {
    let mut out = vec![0.0; len];
    if file.is_empty() {
        return out;
    }
    let ramp = (0.01 * sample_rate) as usize;
    let mut cursor = 0usize;
    for &(t0, t1) in phrases {
        let a = ((t0 * sample_rate).round() as usize).min(len);
        let b = ((t1 * sample_rate).round() as usize).min(len);
        let n = b.saturating_sub(a);
        for i in 0..n {
            let edge = i.min(n - 1 - i);
            let w = if edge < ramp {
                0.5 - 0.5 * (PI * edge as f64 / ramp as f64).cos()
            } else {
                1.0
            };
            out[a + i] = w * file[cursor % file.len()];
            cursor += 1;
        }
    }
    out
}

/// Intervals (s) where `x` carries speech energy.
pub fn speech_intervals(x: &[f64], sample_rate: f64) -> Vec<(f64, f64)> {
    let frame = ((0.02 * sample_rate) as usize).max(1);
    let energies: Vec<f64> = x
        .chunks(frame)
        .map(|c| c.iter().map(|v| v * v).sum::<f64>() / c.len() as f64)
        .collect();
    let mut sorted: Vec<f64> = energies.iter().copied().filter(|e| *e > 0.0).collect();
    if sorted.is_empty() {
        return Vec::new();
    }
    sorted.sort_by(f64::total_cmp);
    let loud = sorted[(sorted.len() * 95 / 100).min(sorted.len() - 1)];
    let threshold = loud * 10f64.powf(-35.0 / 10.0);
    let step = frame as f64 / sample_rate;
    let mut raw: Vec<(f64, f64)> = Vec::new();
    for (i, e) in energies.iter().enumerate() {
        if *e > threshold {
            let (a, b) = (
                i as f64 * step,
                ((i + 1) as f64 * step).min(x.len() as f64 / sample_rate),
            );
            match raw.last_mut() {
                Some(last) if a - last.1 < 0.2 => last.1 = b,
                _ => raw.push((a, b)),
            }
        }
    }
    raw.retain(|(a, b)| b - a >= 0.1);
    raw
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resampling_keeps_a_tone_in_band() {
        let tone: Vec<f64> = (0..44100)
            .map(|n| (2.0 * PI * 440.0 * n as f64 / 44100.0).sin())
            .collect();
        let y = resample(&tone, 44100.0, 16000.0);
        assert_eq!(y.len(), 16000);
        // Compare with the ideal tone away from the edges.
        let err = (1000..15000)
            .map(|n| (y[n] - (2.0 * PI * 440.0 * n as f64 / 16000.0).sin()).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-3, "{err}");
    }

    #[test]
    fn speech_intervals_find_bursts_and_skip_silence() {
        let fs = 1000.0;
        let mut x = vec![0.0; 3000];
        for (n, v) in x.iter_mut().enumerate() {
            *v = match n {
                500..1200 => (n as f64 * 0.3).sin(),
                2000..2600 => (n as f64 * 0.2).sin(),
                _ => 0.0,
            };
        }
        let iv = speech_intervals(&x, fs);
        assert_eq!(iv.len(), 2, "{iv:?}");
        assert!((iv[0].0 - 0.5).abs() < 0.021 && (iv[0].1 - 1.2).abs() < 0.021);
        assert!((iv[1].0 - 2.0).abs() < 0.021 && (iv[1].1 - 2.6).abs() < 0.021);
    }
}
