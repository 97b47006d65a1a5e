//! Binary audio frames on the wire (WebSocket binary messages and Zenoh payloads).
//!
//! All integers are little-endian. Inbound (client to server) multichannel audio:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `AVSA` |
//! | 4 | 1 | version (1) |
//! | 5 | 1 | sample format: 1 = i16, 2 = f32 |
//! | 6 | 2 | channel count |
//! | 8 | 8 | index of the first sample frame (session time = index / sample rate) |
//! | 16 | 4 | frame count (samples per channel) |
//! | 20 | 4 | reserved, 0 |
//! | 24 | … | interleaved samples |
//!
//! Outbound (server to client) separated audio of one label:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `AVSO` |
//! | 4 | 1 | version (1) |
//! | 5 | 1 | sample format: 1 = i16, 2 = f32 |
//! | 6 | 2 | reserved, 0 |
//! | 8 | 8 | label birth step |
//! | 16 | 4 | label index |
//! | 20 | 4 | frame count |
//! | 24 | 8 | index of the first sample, aligned with the input's sample indices |
//! | 32 | … | mono samples |

use serde::{Deserialize, Serialize};

use crate::label::Label;

/// Magic of inbound multichannel audio frames.
pub const AUDIO_IN_MAGIC: [u8; 4] = *b"AVSA";
/// Magic of outbound separated audio frames.
pub const AUDIO_OUT_MAGIC: [u8; 4] = *b"AVSO";
/// The frame layout version this code writes and reads.
pub const FRAME_VERSION: u8 = 1;
/// Header length of inbound frames.
pub const AUDIO_IN_HEADER: usize = 24;
/// Header length of outbound frames.
pub const AUDIO_OUT_HEADER: usize = 32;

/// Sample encoding of a binary audio frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SampleEncoding {
    /// Signed 16-bit PCM, full scale 32768.
    I16,
    /// IEEE 754 32-bit float in [-1, 1].
    #[default]
    F32,
}

impl SampleEncoding {
    fn code(self) -> u8 {
        match self {
            Self::I16 => 1,
            Self::F32 => 2,
        }
    }

    fn from_code(c: u8) -> Option<Self> {
        match c {
            1 => Some(Self::I16),
            2 => Some(Self::F32),
            _ => None,
        }
    }

    /// Bytes per sample.
    pub fn width(self) -> usize {
        match self {
            Self::I16 => 2,
            Self::F32 => 4,
        }
    }
}

/// Why a binary frame was refused; `field` names the header field or part.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{field}: {message}")]
pub struct FrameError {
    /// Machine-readable reason.
    pub code: &'static str,
    /// The header field or part at fault.
    pub field: &'static str,
    /// Explanation.
    pub message: String,
}

fn err(code: &'static str, field: &'static str, message: impl Into<String>) -> FrameError {
    FrameError {
        code,
        field,
        message: message.into(),
    }
}

/// A decoded inbound audio frame.
#[derive(Debug, Clone, PartialEq)]
pub struct AudioFrame {
    /// Index of the first sample frame.
    pub first_sample: u64,
    /// Channel count.
    pub channels: usize,
    /// Interleaved samples as f32 in [-1, 1] (i16 is scaled by 1/32768).
    pub samples: Vec<f32>,
    /// Encoding the frame arrived in.
    pub encoding: SampleEncoding,
}

impl AudioFrame {
    /// Number of sample frames.
    pub fn frames(&self) -> usize {
        self.samples.len().checked_div(self.channels).unwrap_or(0)
    }

    /// Decodes an inbound frame, refusing more than `max_samples` samples in total.
    pub fn decode(bytes: &[u8], max_samples: usize) -> Result<Self, FrameError> {
        if bytes.len() < AUDIO_IN_HEADER {
            return Err(err(
                "truncated",
                "header",
                format!("{} bytes is shorter than the 24-byte header", bytes.len()),
            ));
        }
        if bytes[0..4] != AUDIO_IN_MAGIC {
            return Err(err(
                "bad_magic",
                "magic",
                "an audio frame must start with the bytes \"AVSA\"",
            ));
        }
        if bytes[4] != FRAME_VERSION {
            return Err(err(
                "bad_version",
                "version",
                format!("version {} is not supported (expected 1)", bytes[4]),
            ));
        }
        let encoding = SampleEncoding::from_code(bytes[5]).ok_or_else(|| {
            err(
                "bad_format",
                "sample_format",
                format!("code {} is not 1 (i16) or 2 (f32)", bytes[5]),
            )
        })?;
        let channels = u16::from_le_bytes([bytes[6], bytes[7]]) as usize;
        if channels == 0 {
            return Err(err(
                "bad_channels",
                "channels",
                "channel count must be at least 1",
            ));
        }
        let first_sample = u64::from_le_bytes(bytes[8..16].try_into().unwrap_or_default());
        let frames = u32::from_le_bytes(bytes[16..20].try_into().unwrap_or_default()) as usize;
        let total = frames.saturating_mul(channels);
        if total > max_samples {
            return Err(err(
                "oversized",
                "frame_count",
                format!(
                    "{frames} frames x {channels} channels exceeds the limit of {max_samples} samples per message"
                ),
            ));
        }
        let payload = &bytes[AUDIO_IN_HEADER..];
        let expect = total * encoding.width();
        if payload.len() != expect {
            return Err(err(
                "truncated",
                "samples",
                format!(
                    "header announces {expect} bytes of samples but {} follow",
                    payload.len()
                ),
            ));
        }
        let samples = decode_samples(payload, encoding);
        Ok(Self {
            first_sample,
            channels,
            samples,
            encoding,
        })
    }

    /// Encodes the frame in its `encoding`.
    pub fn encode(&self) -> Vec<u8> {
        let mut out =
            Vec::with_capacity(AUDIO_IN_HEADER + self.samples.len() * self.encoding.width());
        out.extend_from_slice(&AUDIO_IN_MAGIC);
        out.push(FRAME_VERSION);
        out.push(self.encoding.code());
        out.extend_from_slice(&(self.channels as u16).to_le_bytes());
        out.extend_from_slice(&self.first_sample.to_le_bytes());
        out.extend_from_slice(&(self.frames() as u32).to_le_bytes());
        out.extend_from_slice(&[0; 4]);
        encode_samples(&mut out, &self.samples, self.encoding);
        out
    }
}

/// A decoded outbound separated-audio frame.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelAudioFrame {
    /// The track whose voice this is.
    pub label: Label,
    /// Index of the first sample, aligned with the input.
    pub first_sample: u64,
    /// Mono samples.
    pub samples: Vec<f32>,
    /// Wire encoding.
    pub encoding: SampleEncoding,
}

impl LabelAudioFrame {
    /// Encodes the frame.
    pub fn encode(&self) -> Vec<u8> {
        let mut out =
            Vec::with_capacity(AUDIO_OUT_HEADER + self.samples.len() * self.encoding.width());
        out.extend_from_slice(&AUDIO_OUT_MAGIC);
        out.push(FRAME_VERSION);
        out.push(self.encoding.code());
        out.extend_from_slice(&[0; 2]);
        out.extend_from_slice(&self.label.birth_step.to_le_bytes());
        out.extend_from_slice(&self.label.index.to_le_bytes());
        out.extend_from_slice(&(self.samples.len() as u32).to_le_bytes());
        out.extend_from_slice(&self.first_sample.to_le_bytes());
        encode_samples(&mut out, &self.samples, self.encoding);
        out
    }

    /// Decodes a frame (used by clients and tests).
    pub fn decode(bytes: &[u8]) -> Result<Self, FrameError> {
        if bytes.len() < AUDIO_OUT_HEADER {
            return Err(err(
                "truncated",
                "header",
                "shorter than the 32-byte header",
            ));
        }
        if bytes[0..4] != AUDIO_OUT_MAGIC {
            return Err(err(
                "bad_magic",
                "magic",
                "a separated-audio frame starts with \"AVSO\"",
            ));
        }
        if bytes[4] != FRAME_VERSION {
            return Err(err(
                "bad_version",
                "version",
                format!("version {} is not supported", bytes[4]),
            ));
        }
        let encoding = SampleEncoding::from_code(bytes[5])
            .ok_or_else(|| err("bad_format", "sample_format", "unknown code"))?;
        let birth_step = u64::from_le_bytes(bytes[8..16].try_into().unwrap_or_default());
        let index = u32::from_le_bytes(bytes[16..20].try_into().unwrap_or_default());
        let frames = u32::from_le_bytes(bytes[20..24].try_into().unwrap_or_default()) as usize;
        let first_sample = u64::from_le_bytes(bytes[24..32].try_into().unwrap_or_default());
        let payload = &bytes[AUDIO_OUT_HEADER..];
        if payload.len() != frames * encoding.width() {
            return Err(err(
                "truncated",
                "samples",
                "payload length does not match the frame count",
            ));
        }
        Ok(Self {
            label: Label::new(birth_step, index),
            first_sample,
            samples: decode_samples(payload, encoding),
            encoding,
        })
    }
}

fn decode_samples(payload: &[u8], encoding: SampleEncoding) -> Vec<f32> {
    match encoding {
        SampleEncoding::I16 => payload
            .chunks_exact(2)
            .map(|b| f32::from(i16::from_le_bytes([b[0], b[1]])) / 32768.0)
            .collect(),
        SampleEncoding::F32 => payload
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect(),
    }
}

fn encode_samples(out: &mut Vec<u8>, samples: &[f32], encoding: SampleEncoding) {
    match encoding {
        SampleEncoding::I16 => {
            for &s in samples {
                let v = if s.is_finite() {
                    (s * 32768.0).round().clamp(-32768.0, 32767.0) as i16
                } else {
                    0
                };
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        SampleEncoding::F32 => {
            for &s in samples {
                out.extend_from_slice(&s.to_le_bytes());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(encoding: SampleEncoding) -> AudioFrame {
        AudioFrame {
            first_sample: 48_000,
            channels: 2,
            samples: vec![0.5, -0.25, 0.0, 0.75],
            encoding,
        }
    }

    #[test]
    fn inbound_frames_round_trip() {
        for enc in [SampleEncoding::F32, SampleEncoding::I16] {
            let f = frame(enc);
            let bytes = f.encode();
            assert_eq!(bytes.len(), 24 + 4 * enc.width());
            assert_eq!(AudioFrame::decode(&bytes, 1 << 20).unwrap(), f);
        }
    }

    #[test]
    fn outbound_frames_round_trip() {
        let f = LabelAudioFrame {
            label: Label::new(12, 1),
            first_sample: 1024,
            samples: vec![0.1, 0.2, -0.3],
            encoding: SampleEncoding::F32,
        };
        assert_eq!(LabelAudioFrame::decode(&f.encode()).unwrap(), f);
    }

    #[test]
    fn malformed_frames_name_the_field() {
        let good = frame(SampleEncoding::F32).encode();
        assert_eq!(
            AudioFrame::decode(&good[..10], 1 << 20).unwrap_err().field,
            "header"
        );
        assert_eq!(
            AudioFrame::decode(&good[..good.len() - 1], 1 << 20)
                .unwrap_err()
                .field,
            "samples"
        );
        let mut bad = good.clone();
        bad[0] = b'X';
        assert_eq!(
            AudioFrame::decode(&bad, 1 << 20).unwrap_err().field,
            "magic"
        );
        let mut bad = good.clone();
        bad[5] = 9;
        assert_eq!(
            AudioFrame::decode(&bad, 1 << 20).unwrap_err().field,
            "sample_format"
        );
        let mut bad = good.clone();
        bad[6] = 0;
        assert_eq!(
            AudioFrame::decode(&bad, 1 << 20).unwrap_err().field,
            "channels"
        );
        let e = AudioFrame::decode(&good, 3).unwrap_err();
        assert_eq!((e.code, e.field), ("oversized", "frame_count"));
    }
}
