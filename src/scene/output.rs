//! The output folder written by `avsep process` (and by live clients), read back for evaluation.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::geometry::Layout;
use crate::label::Label;

use super::format::{PitchLine, TracksLine};
use super::reader::{load_audio_measurements, parse_json, read_jsonl};
use super::{Audio, AudioMeasurementFrame, SceneError};

/// File names inside an output folder.
pub mod files {
    /// Tracker estimates, one line per tracker step.
    pub const TRACKS: &str = "tracks.jsonl";
    /// Localiser output, one line per array and frame.
    pub const MEASUREMENTS: &str = "measurements.jsonl";
    /// The separator's pitch per label and STFT frame (an avsep extension).
    pub const PITCH: &str = "pitch.jsonl";
    /// Who spoke when.
    pub const DIARIZATION: &str = "diarization.rttm";
    /// Run figures.
    pub const SUMMARY: &str = "summary.json";
    /// Folder of separated streams, `<label>.wav`.
    pub const AUDIO_DIR: &str = "audio";
}

/// Makes `dir` ready for a new run's output: creates it and its `audio/` folder, and removes
/// what an earlier run wrote there that this run might not overwrite (its `audio/<label>.wav`
/// streams, whose labels differ from run to run, and `pitch.jsonl`), so an evaluation never
/// scores one run's streams against another's. Other files are left alone.
pub fn prepare_dir(dir: &Path) -> Result<(), SceneError> {
    let audio = dir.join(files::AUDIO_DIR);
    std::fs::create_dir_all(&audio)
        .map_err(|e| SceneError::new(dir, format!("cannot create output folder: {e}")))?;
    let entries = std::fs::read_dir(&audio)
        .map_err(|e| SceneError::new(&audio, format!("cannot list: {e}")))?;
    let mut stale: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.extension().and_then(|e| e.to_str()) == Some("wav")
                && p.file_stem()
                    .and_then(|s| s.to_str())
                    .is_some_and(|s| s.parse::<Label>().is_ok())
        })
        .collect();
    let pitch = dir.join(files::PITCH);
    if pitch.exists() {
        stale.push(pitch);
    }
    for p in stale {
        std::fs::remove_file(&p).map_err(|e| {
            SceneError::new(&p, format!("cannot remove the earlier run's file: {e}"))
        })?;
    }
    Ok(())
}

/// What an output folder holds; every part is optional.
#[derive(Debug, Clone, Default)]
pub struct Output {
    /// The folder.
    pub dir: PathBuf,
    /// Tracker estimates in time order.
    pub tracks: Option<Vec<TracksLine>>,
    /// Localiser output.
    pub measurements: Option<Vec<AudioMeasurementFrame>>,
    /// Separated streams by label.
    pub audio: BTreeMap<Label, Vec<f32>>,
    /// The separator's pitch per label and frame, in time order.
    pub pitch: Option<Vec<PitchLine>>,
    /// The run summary.
    pub summary: Option<serde_json::Value>,
}

impl Output {
    /// Reads whatever the folder holds, validating it against the scene's layout.
    pub fn load(dir: &Path, layout: &Layout) -> Result<Self, SceneError> {
        if !dir.is_dir() {
            return Err(SceneError::new(dir, "is not a folder"));
        }
        let mut out = Output {
            dir: dir.to_path_buf(),
            ..Default::default()
        };
        let tracks_path = dir.join(files::TRACKS);
        if tracks_path.exists() {
            let mut lines = Vec::new();
            let mut last = f64::NEG_INFINITY;
            read_jsonl(&tracks_path, |line, l: TracksLine| {
                let err =
                    |f: String, m: String| SceneError::new(&tracks_path, m).at_line(line).field(f);
                if !l.t.is_finite() || l.t < last {
                    return Err(err(
                        "t".into(),
                        format!("time {} is not finite or goes backwards", l.t),
                    ));
                }
                last = l.t;
                for (i, tr) in l.tracks.iter().enumerate() {
                    if !tr
                        .position
                        .iter()
                        .chain(&tr.velocity)
                        .all(|v| v.is_finite())
                    {
                        return Err(err(
                            format!("tracks[{i}].position"),
                            "must be finite".into(),
                        ));
                    }
                }
                lines.push(l);
                Ok(())
            })?;
            out.tracks = Some(lines);
        }
        let pitch_path = dir.join(files::PITCH);
        if pitch_path.exists() {
            out.pitch = Some(load_pitch(&pitch_path)?);
        }
        let meas_path = dir.join(files::MEASUREMENTS);
        if meas_path.exists() {
            out.measurements = Some(load_audio_measurements(&meas_path, layout)?);
        }
        let audio_dir = dir.join(files::AUDIO_DIR);
        if audio_dir.is_dir() {
            let entries = std::fs::read_dir(&audio_dir)
                .map_err(|e| SceneError::new(&audio_dir, format!("cannot list: {e}")))?;
            for entry in entries.flatten() {
                let path = entry.path();
                if path.extension().and_then(|e| e.to_str()) != Some("wav") {
                    continue;
                }
                let stem = path
                    .file_stem()
                    .and_then(|s| s.to_str())
                    .unwrap_or_default();
                let label: Label = stem.parse().map_err(|e| {
                    SceneError::new(&path, format!("file name is not a track label: {e}"))
                })?;
                let a = Audio::read(&path)?;
                if a.channels != 1 {
                    return Err(
                        SceneError::new(&path, "separated audio must be mono").field("channels")
                    );
                }
                out.audio.insert(label, a.samples);
            }
        }
        let summary_path = dir.join(files::SUMMARY);
        if summary_path.exists() {
            let text = std::fs::read_to_string(&summary_path)
                .map_err(|e| SceneError::new(&summary_path, format!("cannot read: {e}")))?;
            out.summary = Some(parse_json(&summary_path, &text, None)?);
        }
        Ok(out)
    }
}

/// Reads `pitch.jsonl`: times finite and in order, F0s finite and not negative, voicings in
/// [0, 1].
fn load_pitch(path: &Path) -> Result<Vec<PitchLine>, SceneError> {
    let mut lines = Vec::new();
    let mut last = f64::NEG_INFINITY;
    read_jsonl(path, |line, l: PitchLine| {
        let err = |f: String, m: &str| SceneError::new(path, m).at_line(line).field(f);
        if !l.t.is_finite() || l.t < last {
            return Err(err("t".into(), "time is not finite or goes backwards"));
        }
        last = l.t;
        for (i, p) in l.labels.iter().enumerate() {
            if !(p.f0.is_finite() && p.f0 >= 0.0) {
                return Err(err(format!("labels[{i}].f0"), "must be finite, 0 or more"));
            }
            if !(0.0..=1.0).contains(&p.voicing) {
                return Err(err(format!("labels[{i}].voicing"), "must be in [0, 1]"));
            }
        }
        lines.push(l);
        Ok(())
    })?;
    Ok(lines)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preparing_a_folder_removes_an_earlier_runs_streams_and_pitch_only() {
        let dir = tempfile::tempdir().expect("temp dir");
        let d = dir.path().join("out");
        prepare_dir(&d).expect("creates");
        let audio = d.join(files::AUDIO_DIR);
        for f in ["12.0.wav", "3.1.wav", "mix.wav"] {
            std::fs::write(audio.join(f), b"x").expect("writes");
        }
        for f in [files::PITCH, files::TRACKS, "notes.txt"] {
            std::fs::write(d.join(f), b"x").expect("writes");
        }
        prepare_dir(&d).expect("prepares");
        let left = |p: &Path| p.exists();
        assert!(!left(&audio.join("12.0.wav")) && !left(&audio.join("3.1.wav")));
        assert!(!left(&d.join(files::PITCH)));
        // Not a stream, or overwritten by every run anyway: kept.
        assert!(left(&audio.join("mix.wav")) && left(&d.join("notes.txt")));
        assert!(left(&d.join(files::TRACKS)));
    }

    #[test]
    fn a_pitch_file_is_read_and_a_bad_line_names_its_field() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join(files::PITCH);
        let good = r#"{"t":0.032,"labels":[{"label":"3.0","f0":150.0,"voicing":1.0}]}
{"t":0.064,"labels":[]}
"#;
        std::fs::write(&path, good).expect("writes");
        let lines = load_pitch(&path).expect("reads");
        assert_eq!(lines.len(), 2);
        assert_eq!(lines[0].labels[0].label, Label::new(3, 0));
        let bad = good.replace("\"voicing\":1.0", "\"voicing\":1.5");
        std::fs::write(&path, bad).expect("writes");
        let e = load_pitch(&path)
            .expect_err("voicing out of range")
            .to_string();
        assert!(
            e.contains("labels[0].voicing") && e.contains("pitch.jsonl:1:"),
            "{e}"
        );
        let backwards = good.replace("0.064", "0.01");
        std::fs::write(&path, backwards).expect("writes");
        let e = load_pitch(&path).expect_err("time goes back").to_string();
        assert!(
            e.contains("pitch.jsonl:2:") && e.contains("backwards"),
            "{e}"
        );
    }
}
