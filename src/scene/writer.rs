//! The scene writer, and the JSON/JSONL helpers shared with the output folder.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use serde::Serialize;

use crate::geometry::deg;

use super::convert::{box_to_file, layout_to_file};
use super::format::{AudioMeasurementLine, DetectionLine, DoaFile, TruthFile, TruthSourceFile};
use super::{Audio, AudioMeasurementFrame, SampleFormat, Scene, SceneError};

/// Writes `value` as pretty JSON.
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), SceneError> {
    let io = |e: std::io::Error| SceneError::new(path, format!("cannot write: {e}"));
    let mut w = BufWriter::new(File::create(path).map_err(io)?);
    serde_json::to_writer_pretty(&mut w, value)
        .map_err(|e| SceneError::new(path, e.to_string()))?;
    w.write_all(b"\n").map_err(io)?;
    w.flush().map_err(io)
}

/// A JSONL file written one value per line.
pub struct JsonlWriter {
    path: std::path::PathBuf,
    out: BufWriter<File>,
}

impl JsonlWriter {
    /// Creates (truncates) the file.
    pub fn create(path: &Path) -> Result<Self, SceneError> {
        let f =
            File::create(path).map_err(|e| SceneError::new(path, format!("cannot create: {e}")))?;
        Ok(Self {
            path: path.to_path_buf(),
            out: BufWriter::new(f),
        })
    }

    /// Appends one value as a line.
    pub fn write<T: Serialize>(&mut self, value: &T) -> Result<(), SceneError> {
        serde_json::to_writer(&mut self.out, value)
            .map_err(|e| SceneError::new(&self.path, e.to_string()))?;
        self.out
            .write_all(b"\n")
            .map_err(|e| SceneError::new(&self.path, format!("cannot write: {e}")))
    }

    /// Flushes buffered lines.
    pub fn finish(mut self) -> Result<(), SceneError> {
        self.out
            .flush()
            .map_err(|e| SceneError::new(&self.path, format!("cannot write: {e}")))
    }
}

/// The wire form of a localisation frame (degrees), as in `audio_measurements.jsonl`.
pub fn measurement_to_line(m: &AudioMeasurementFrame, array_id: &str) -> AudioMeasurementLine {
    AudioMeasurementLine {
        t: m.t,
        array: array_id.to_string(),
        doas: m
            .doas
            .iter()
            .map(|d| DoaFile {
                azimuth: deg(d.azimuth),
                elevation: d.elevation.map(deg),
                energy: d.energy,
            })
            .collect(),
        points: m.points.iter().map(|p| [p.x, p.y, p.z]).collect(),
        activity: m.activity,
    }
}

impl Scene {
    /// Writes the scene into `dir` (created if needed) with the standard file names. Audio is
    /// written as 32-bit float.
    pub fn save(&self, dir: &Path) -> Result<(), SceneError> {
        std::fs::create_dir_all(dir)
            .map_err(|e| SceneError::new(dir, format!("cannot create folder: {e}")))?;
        let l = &self.layout;
        let mut file = layout_to_file(l);
        if let Some(a) = &self.audio {
            a.write(&dir.join("audio.wav"), SampleFormat::F32)?;
            file.audio = Some("audio.wav".into());
        }
        if !self.detections.is_empty() || !l.cameras.is_empty() {
            let mut w = JsonlWriter::create(&dir.join("detections.jsonl"))?;
            for d in &self.detections {
                w.write(&DetectionLine {
                    t: d.t,
                    camera: l.cameras[d.camera].id.clone(),
                    boxes: d.boxes.iter().map(box_to_file).collect(),
                })?;
            }
            w.finish()?;
            file.detections = Some("detections.jsonl".into());
        }
        if !self.audio_measurements.is_empty() {
            let mut w = JsonlWriter::create(&dir.join("audio_measurements.jsonl"))?;
            for m in &self.audio_measurements {
                w.write(&measurement_to_line(m, &l.arrays[m.array].id))?;
            }
            w.finish()?;
            file.audio_measurements = Some("audio_measurements.jsonl".into());
        }
        if let Some(truth) = &self.truth {
            let tdir = dir.join("truth");
            std::fs::create_dir_all(&tdir)
                .map_err(|e| SceneError::new(&tdir, format!("cannot create folder: {e}")))?;
            let mut sources = Vec::new();
            for s in &truth.sources {
                let signal = match &s.signal {
                    Some(sig) => {
                        let rel = format!("truth/{}.wav", s.id);
                        Audio::mono(l.sample_rate, sig.clone())
                            .write(&dir.join(&rel), SampleFormat::F32)?;
                        Some(rel)
                    }
                    None => None,
                };
                sources.push(TruthSourceFile {
                    id: s.id.clone(),
                    signal,
                    trajectory: s
                        .trajectory
                        .iter()
                        .map(|(t, p)| [*t, p.x, p.y, p.z])
                        .collect(),
                    active: s.active.iter().map(|&(a, b)| [a, b]).collect(),
                });
            }
            write_json(&tdir.join("truth.json"), &TruthFile { sources })?;
            file.truth = Some("truth/truth.json".into());
        }
        write_json(&dir.join("scene.json"), &file)
    }
}
