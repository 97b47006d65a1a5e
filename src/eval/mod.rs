//! Evaluation: scores an output folder against its scene's truth.
//!
//! The metrics are pure functions, each in its own module: optimal [`assignment`], [`ospa`] and
//! OSPA(2), [`gospa`], [`clear_mot`], [`identity`] (IDF1) and [`hota`], [`si_sdr`] and BSS Eval v3
//! ([`bss_eval`]). The report ([`evaluate`]) has one optional section per part of the output
//! folder: the localiser's `measurements.jsonl` ([`measurements`]), the tracker's `tracks.jsonl`
//! ([`tracks`]) and the separated `audio/<label>.wav` ([`audio`]); [`plots`] draws SVG figures of
//! it.

pub mod assignment;
pub mod audio;
pub mod bss_eval;
mod cholesky;
pub mod clear_mot;
mod config;
pub mod gospa;
pub mod hota;
pub mod identity;
pub mod measurements;
pub mod ospa;
pub mod pitch;
pub mod plots;
pub mod sample_set;
pub mod si_sdr;
mod source_tracking;
mod stats;
mod table;
mod track_grid;
pub mod tracks;

use serde::{Deserialize, Serialize};

use crate::scene::output::Output;
use crate::scene::{Scene, SceneError};

pub use config::{EvalConfig, FrameAnchor};
pub use stats::Summary;

use audio::{AudioInputs, AudioReport, SourceAudio, score_audio};
use measurements::{MeasurementsReport, score_measurements};
use pitch::{PitchReport, score_pitch};
use tracks::{TracksReport, score_tracks};

/// Why an evaluation could not be made.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A scene or output file is missing or invalid (names the file).
    #[error("{0}")]
    Scene(#[from] SceneError),
    /// The scene has no ground truth.
    #[error(
        "scene {0} has no truth (scene.json names no `truth` file), so there is nothing to score against"
    )]
    NoTruth(String),
    /// An invalid setting.
    #[error("evaluation setting `{field}`: {message}")]
    Config {
        /// The field.
        field: String,
        /// What is wrong with it.
        message: String,
    },
    /// Inputs that do not fit together (e.g. streams of the wrong length).
    #[error("{0}")]
    Input(String),
    /// Writing a result failed.
    #[error("{0}")]
    Write(String),
}

impl EvalError {
    /// Whether the error is about the inputs (exit code 2) rather than a failure to write.
    pub fn is_input(&self) -> bool {
        !matches!(self, EvalError::Write(_))
    }
}

/// The evaluation of one output folder; sections are absent when the folder lacks that part.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalReport {
    /// The scene folder.
    pub scene: String,
    /// The output folder.
    pub output: String,
    /// Scene duration (s).
    pub duration_s: f64,
    /// Number of true sources.
    pub sources: usize,
    /// The settings used.
    pub config: EvalConfig,
    /// Localiser scores (`measurements.jsonl`).
    pub measurements: Option<MeasurementsReport>,
    /// Tracking scores (`tracks.jsonl`).
    pub tracks: Option<TracksReport>,
    /// Separation scores (`audio/`).
    pub audio: Option<AudioReport>,
    /// The separator's pitch against each source's (`pitch.jsonl`, scored for the sources the
    /// separation section mapped to a label).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pitch: Option<PitchReport>,
    /// Why a section is missing, and other remarks.
    pub notes: Vec<String>,
}

/// Scores `out` against the truth of `scene`.
pub fn evaluate(scene: &Scene, out: &Output, cfg: &EvalConfig) -> Result<EvalReport, EvalError> {
    cfg.validate()?;
    let truth = scene
        .truth
        .as_ref()
        .ok_or_else(|| EvalError::NoTruth(scene.dir.display().to_string()))?;
    let mut notes = Vec::new();
    let measurements = match &out.measurements {
        Some(m) => Some(score_measurements(scene, &truth.sources, m, cfg)),
        None => {
            notes.push("no measurements.jsonl: localiser not scored".to_string());
            None
        }
    };
    let tracks = match &out.tracks {
        Some(lines) => Some(score_tracks(&scene.layout, &truth.sources, lines, cfg)),
        None => {
            notes.push("no tracks.jsonl: tracking not scored".to_string());
            None
        }
    };
    let with_signal: Vec<_> = truth
        .sources
        .iter()
        .filter(|s| s.signal.is_some())
        .collect();
    let audio = if out.audio.is_empty() {
        notes.push("no audio/<label>.wav streams: separation not scored".to_string());
        None
    } else if with_signal.is_empty() {
        notes.push("no true source has a signal: separation not scored".to_string());
        None
    } else {
        let mixture = match (&scene.audio, scene.layout.reference_channel()) {
            (Some(a), Some(ch)) => Some(a.channel(ch)),
            _ => {
                notes.push("the scene has no audio: no reference-microphone baseline".into());
                None
            }
        };
        let inputs = AudioInputs {
            sample_rate: f64::from(scene.layout.sample_rate),
            sources: with_signal.clone(),
            streams: &out.audio,
            mixture,
            tracks: tracks.as_ref(),
        };
        Some(score_audio(&inputs, cfg)?)
    };
    let pitch = match (&out.pitch, &audio) {
        (None, _) => None,
        (Some(_), None) => {
            notes.push("pitch.jsonl without scored streams: pitch not scored".to_string());
            None
        }
        (Some(lines), Some(a)) => {
            // The audio section scored `with_signal`, in order.
            let labels: Vec<_> = a.sources.iter().map(|s| s.label).collect();
            let fs = f64::from(scene.layout.sample_rate);
            let off = off_stream_blocks(a);
            Some(score_pitch(lines, &with_signal, &labels, &off, fs, cfg))
        }
    };
    Ok(EvalReport {
        scene: scene.dir.display().to_string(),
        output: out.dir.display().to_string(),
        duration_s: scene.duration(),
        sources: truth.sources.len(),
        config: cfg.clone(),
        measurements,
        tracks,
        audio,
        pitch,
        notes,
    })
}

/// Per scored source, the (start, end) times (s) of the blocks its own stream does not carry.
fn off_stream_blocks(a: &AudioReport) -> Vec<Vec<(f64, f64)>> {
    let span = |s: &SourceAudio| -> Vec<(f64, f64)> {
        let strays = &s.continuity.strays;
        strays.iter().map(|b| (b.start_s, b.end_s)).collect()
    };
    a.sources.iter().map(span).collect()
}
