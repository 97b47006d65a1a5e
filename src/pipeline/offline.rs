//! The offline runner: feeds a scene folder through a pipeline in time order, exactly as a live
//! client streaming it would, and writes the output folder.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use serde::Serialize;

use crate::dsp::FrameGeometry;
use crate::field_error::FieldError;
use crate::label::Label;
use crate::scene::format::PitchLine;
use crate::scene::output::{files, prepare_dir};
use crate::scene::{Audio, JsonlWriter, SampleFormat, Scene, SceneError, write_json};
use crate::separate::PitchPart;

use super::config::{ConfigError, PipelineConfig};
use super::diarization::{Diarizer, to_rttm};
use super::input::InputError;
use super::oracle;
use super::oracle_mask::ideal_ratio_mask;
use super::session::{Pipeline, PipelineStats};
use super::stages::SensorClutter;
use super::{PipelineEvent, SizeBounds};

/// Options of an offline run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OfflineOptions {
    /// Steer the separator with the scene's true trajectories instead of the tracker.
    pub oracle_tracks: bool,
    /// With `oracle_tracks`: the harmonic grouping takes this part of each true source's pitch,
    /// read from its truth signal, instead of estimating it.
    pub oracle_pitch: Option<PitchPart>,
    /// With `oracle_tracks`: each label's audio is the ideal ratio mask of its true source on
    /// the reference microphone (from the truth images) instead of the separator's output, the
    /// ceiling a separator is measured against.
    pub oracle_mask: bool,
    /// Audio is pushed in blocks of this many sample frames (as a client would stream it).
    pub block_samples: usize,
    /// The scene's layout and the settings are checked against these before anything is sized
    /// from them (the server's default limits unless lifted); `None` checks nothing.
    pub bounds: Option<SizeBounds>,
}

impl Default for OfflineOptions {
    fn default() -> Self {
        Self {
            oracle_tracks: false,
            oracle_pitch: None,
            oracle_mask: false,
            block_samples: 1024,
            bounds: Some(SizeBounds::default()),
        }
    }
}

/// What went wrong in an offline run.
#[derive(Debug, thiserror::Error)]
pub enum ProcessError {
    /// The configuration is invalid.
    #[error("configuration: {0}")]
    Config(#[from] ConfigError),
    /// Reading or writing files failed.
    #[error("{0}")]
    Files(#[from] SceneError),
    /// The scene lacks what the options need.
    #[error("{0}")]
    Scene(String),
    /// The scene's layout or the settings pass the size bounds (the field is named).
    #[error("{0}")]
    TooLarge(FieldError),
}

/// Figures of an offline run, written to `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct RunSummary {
    /// Scene folder.
    pub scene: String,
    /// Input duration (s).
    pub duration_s: f64,
    /// Wall-clock processing time (s).
    pub processing_s: f64,
    /// Processing time over input duration (below 1 is faster than real time).
    pub real_time_factor: f64,
    /// Whether the tracks were the scene's truth.
    pub oracle_tracks: bool,
    /// Whether the harmonic grouping was given the true sources' pitch (or part of it).
    pub oracle_pitch: bool,
    /// Which part of the true pitch it was given, when it was.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub oracle_pitch_part: Option<PitchPart>,
    /// Whether the audio is the truth's ideal ratio mask instead of the separator's output.
    pub oracle_mask: bool,
    /// Labels ever reported.
    pub tracks: Vec<String>,
    /// Number of speech segments in the diarization.
    pub speech_segments: usize,
    /// Warnings raised, by code.
    pub warnings: BTreeMap<String, u64>,
    /// Pipeline counters.
    pub stats: PipelineStats,
    /// Each tracker sensor's clutter rate at the end of the run, configured and estimated.
    pub clutter: Vec<SensorClutter>,
    /// Seed used.
    pub seed: u64,
    /// Settings used.
    pub settings: PipelineConfig,
}

/// Default seed of offline runs when the configuration gives none.
pub const DEFAULT_OFFLINE_SEED: u64 = 0x5eed;

/// What the sink wrote, for the summary.
struct Written {
    labels: Vec<Label>,
    speech_segments: usize,
    warnings: BTreeMap<String, u64>,
}

/// Everything an offline run writes, accumulated from the pipeline's events.
struct OutputSink {
    tracks: JsonlWriter,
    measurements: JsonlWriter,
    /// `pitch.jsonl`, when the pipeline records the separator's pitch.
    pitch: Option<JsonlWriter>,
    sample_rate: f64,
    audio: BTreeMap<Label, Vec<f32>>,
    frames: usize,
    diarizer: Diarizer,
    step_s: f64,
    warnings: BTreeMap<String, u64>,
    labels: Vec<Label>,
}

impl OutputSink {
    /// Creates the output folder and its streaming files (`pitch.jsonl` with `pitch`).
    fn create(
        out: &Path,
        frames: usize,
        step_s: f64,
        sample_rate: u32,
        pitch: bool,
    ) -> Result<Self, SceneError> {
        prepare_dir(out)?;
        Ok(Self {
            tracks: JsonlWriter::create(&out.join(files::TRACKS))?,
            measurements: JsonlWriter::create(&out.join(files::MEASUREMENTS))?,
            pitch: pitch
                .then(|| JsonlWriter::create(&out.join(files::PITCH)))
                .transpose()?,
            sample_rate: f64::from(sample_rate),
            audio: BTreeMap::new(),
            frames,
            diarizer: Diarizer::new(0.5, 0.3, 0.5),
            step_s,
            warnings: BTreeMap::new(),
            labels: Vec::new(),
        })
    }

    /// Takes the events of an accepted input, or counts a refused one as a warning (a live
    /// client would get the same error and go on).
    fn accept(&mut self, result: Result<Vec<PipelineEvent>, InputError>) -> Result<(), SceneError> {
        match result {
            Ok(events) => self.handle(events),
            Err(e) => self.handle(vec![PipelineEvent::Warning {
                code: e.code,
                message: e.to_string(),
            }]),
        }
    }

    /// Closes the streaming files and writes the audio and the diarization.
    fn finish(self, out: &Path, sample_rate: u32, file_id: &str) -> Result<Written, SceneError> {
        self.tracks.finish()?;
        self.measurements.finish()?;
        if let Some(p) = self.pitch {
            p.finish()?;
        }
        for (label, samples) in self.audio {
            Audio::mono(sample_rate, samples).write(
                &out.join(files::AUDIO_DIR).join(format!("{label}.wav")),
                SampleFormat::F32,
            )?;
        }
        let segments = self.diarizer.finish();
        let rttm = out.join(files::DIARIZATION);
        std::fs::write(&rttm, to_rttm(file_id, &segments))
            .map_err(|e| SceneError::new(&rttm, format!("cannot write: {e}")))?;
        Ok(Written {
            labels: self.labels,
            speech_segments: segments.len(),
            warnings: self.warnings,
        })
    }

    fn handle(&mut self, events: Vec<PipelineEvent>) -> Result<(), SceneError> {
        for e in events {
            match e {
                PipelineEvent::Measurements(line) => self.measurements.write(&line)?,
                PipelineEvent::Tracks { line, .. } => {
                    let speaking: Vec<(Label, f64)> =
                        line.tracks.iter().map(|t| (t.label, t.speaking)).collect();
                    let half = 0.5 * self.step_s;
                    self.diarizer.push(line.t - half, line.t + half, &speaking);
                    self.tracks.write(&line)?;
                }
                PipelineEvent::Audio {
                    label,
                    first_sample,
                    samples,
                } => {
                    let buf = self
                        .audio
                        .entry(label)
                        .or_insert_with(|| vec![0.0; self.frames]);
                    let start = first_sample as usize;
                    if start < buf.len() {
                        let n = samples.len().min(buf.len() - start);
                        buf[start..start + n].copy_from_slice(&samples[..n]);
                    }
                }
                PipelineEvent::Pitch {
                    centre_sample,
                    labels,
                } => {
                    if let Some(w) = self.pitch.as_mut() {
                        let t = centre_sample as f64 / self.sample_rate;
                        w.write(&PitchLine { t, labels })?;
                    }
                }
                PipelineEvent::TrackBorn { label, .. } => self.labels.push(label),
                PipelineEvent::TrackEnded { .. } => {}
                PipelineEvent::Warning { code, message } => {
                    tracing::warn!(code, "{message}");
                    *self.warnings.entry(code.to_string()).or_default() += 1;
                }
            }
        }
        Ok(())
    }
}

/// Runs the pipeline over `scene` and writes the output folder `out`. `progress` receives the
/// fraction of the input processed.
pub fn process_scene(
    scene: &Scene,
    cfg: PipelineConfig,
    out: &Path,
    opts: OfflineOptions,
    progress: &dyn Fn(f64),
) -> Result<RunSummary, ProcessError> {
    let started = Instant::now();
    let seed = cfg.seed.unwrap_or(DEFAULT_OFFLINE_SEED);
    let mut pipeline = build_pipeline(scene, &cfg, &opts, seed)?;
    let masked = if opts.oracle_mask {
        Some(oracle_mask_streams(scene, &cfg, opts.oracle_tracks)?)
    } else {
        None
    };
    let frames = scene.audio.as_ref().map_or(0, Audio::frames);
    // The oracle mask replaces the separator's streams, so its pitch would describe nothing.
    let pitch = !opts.oracle_mask && pipeline.record_pitch();
    let mut sink = OutputSink::create(
        out,
        frames,
        pipeline.clock().step_s(),
        scene.layout.sample_rate,
        pitch,
    )?;
    feed_scene(
        scene,
        &mut pipeline,
        &mut sink,
        opts.block_samples,
        progress,
    )?;
    if let Some(streams) = masked {
        sink.audio = streams;
    }
    let file_id = scene
        .dir
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or("scene");
    let written = sink.finish(out, scene.layout.sample_rate, file_id)?;

    let duration_s = scene.duration();
    let processing_s = started.elapsed().as_secs_f64();
    let summary = RunSummary {
        scene: scene.dir.display().to_string(),
        duration_s,
        processing_s,
        real_time_factor: if duration_s > 0.0 {
            processing_s / duration_s
        } else {
            0.0
        },
        oracle_tracks: opts.oracle_tracks,
        oracle_pitch: opts.oracle_pitch.is_some(),
        oracle_pitch_part: opts.oracle_pitch,
        oracle_mask: opts.oracle_mask,
        tracks: written.labels.iter().map(ToString::to_string).collect(),
        speech_segments: written.speech_segments,
        warnings: written.warnings,
        stats: pipeline.stats(),
        clutter: pipeline.clutter_rates(),
        seed,
        settings: cfg,
    };
    write_json(&out.join(files::SUMMARY), &summary)?;
    Ok(summary)
}

/// The pipeline for `scene` with `cfg`, checked against the size bounds `opts` asks for and
/// with the oracle inputs it names.
fn build_pipeline(
    scene: &Scene,
    cfg: &PipelineConfig,
    opts: &OfflineOptions,
    seed: u64,
) -> Result<Pipeline, ProcessError> {
    if let Some(bounds) = opts.bounds {
        bounds
            .check_layout(&scene.layout)
            .map_err(ProcessError::TooLarge)?;
        bounds.check_settings(cfg).map_err(ProcessError::TooLarge)?;
    }
    let mut pipeline = Pipeline::new(scene.layout.clone(), cfg.clone(), seed)?;
    if opts.oracle_tracks {
        let truth = scene.truth.clone().ok_or_else(|| {
            ProcessError::Scene(format!(
                "{}: --oracle-tracks needs a scene with truth",
                scene.dir.display()
            ))
        })?;
        pipeline.use_oracle_tracks(truth);
    }
    if let Some(part) = opts.oracle_pitch {
        pipeline.use_oracle_pitch(part).map_err(|e| {
            ProcessError::Scene(format!("{}: --oracle-pitch: {e}", scene.dir.display()))
        })?;
    }
    Ok(pipeline)
}

/// Each true source's stream by the ideal ratio mask on the reference microphone, under its
/// oracle label, with the separator's framing; the error says what the scene lacks.
fn oracle_mask_streams(
    scene: &Scene,
    cfg: &PipelineConfig,
    oracle_tracks: bool,
) -> Result<BTreeMap<Label, Vec<f32>>, ProcessError> {
    let lacks = |what: &str| {
        ProcessError::Scene(format!(
            "{}: --oracle-mask needs {what}",
            scene.dir.display()
        ))
    };
    if !oracle_tracks {
        return Err(lacks(
            "--oracle-tracks (its streams are the true sources' labels)",
        ));
    }
    let truth = scene
        .truth
        .as_ref()
        .ok_or_else(|| lacks("a scene with truth"))?;
    let audio = scene
        .audio
        .as_ref()
        .ok_or_else(|| lacks("a scene with audio"))?;
    let reference = scene
        .layout
        .reference_channel()
        .filter(|&c| c < audio.channels)
        .ok_or_else(|| lacks("a reference microphone in the audio"))?;
    let mixture: Vec<f64> = audio
        .channel(reference)
        .into_iter()
        .map(f64::from)
        .collect();
    let images = truth
        .sources
        .iter()
        .map(|s| {
            let signal = s.signal.as_ref().ok_or_else(|| {
                lacks(&format!(
                    "every truth source's signal (source {:?} has none)",
                    s.id
                ))
            })?;
            Ok(signal.iter().map(|&v| f64::from(v)).collect::<Vec<f64>>())
        })
        .collect::<Result<Vec<_>, ProcessError>>()?;
    let refs: Vec<&[f64]> = images.iter().map(Vec::as_slice).collect();
    let geometry = FrameGeometry {
        frame: cfg.separate.frame,
        hop: cfg.separate.hop,
    };
    Ok(ideal_ratio_mask(&mixture, &refs, geometry)
        .into_iter()
        .enumerate()
        .map(|(i, y)| {
            (
                oracle::source_label(i),
                y.into_iter().map(|v| v as f32).collect(),
            )
        })
        .collect())
}

/// Feeds the scene's audio in blocks of `block_samples`, and its camera frames and device
/// measurements in time order between the blocks, as a live client streaming it would.
fn feed_scene(
    scene: &Scene,
    pipeline: &mut Pipeline,
    sink: &mut OutputSink,
    block_samples: usize,
    progress: &dyn Fn(f64),
) -> Result<(), SceneError> {
    let mut feed: Vec<(f64, Feed)> = scene
        .detections
        .iter()
        .map(|d| (d.t, Feed::Detection(d)))
        .collect();
    feed.extend(
        scene
            .audio_measurements
            .iter()
            .map(|m| (m.t, Feed::Device(m))),
    );
    feed.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut next = 0;
    let mut push_feed_until =
        |pipeline: &mut Pipeline, sink: &mut OutputSink, t_end: f64| -> Result<(), SceneError> {
            while next < feed.len() && feed[next].0 < t_end {
                let result = match &feed[next].1 {
                    Feed::Detection(d) => pipeline.push_detections((*d).clone()),
                    Feed::Device(m) => pipeline.push_device_measurements((*m).clone()),
                };
                sink.accept(result)?;
                next += 1;
            }
            Ok(())
        };
    if let Some(audio) = &scene.audio {
        let frames = audio.frames();
        let sr = audio.sample_rate as f64;
        let block = block_samples.max(1);
        let mut start = 0;
        while start < frames {
            let end = (start + block).min(frames);
            push_feed_until(pipeline, sink, end as f64 / sr)?;
            let slice = &audio.samples[start * audio.channels..end * audio.channels];
            sink.accept(pipeline.push_audio(start as u64, audio.channels, slice))?;
            start = end;
            progress(start as f64 / frames as f64);
        }
    }
    push_feed_until(pipeline, sink, f64::INFINITY)?;
    sink.handle(pipeline.finish())?;
    progress(1.0);
    Ok(())
}

enum Feed<'a> {
    Detection(&'a crate::scene::DetectionFrame),
    Device(&'a crate::scene::AudioMeasurementFrame),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::sim::{PresetOptions, SimConfig, simulate};

    /// A scene past the size bounds is refused before anything is sized from it, naming the
    /// field; without bounds the same scene runs.
    #[test]
    fn a_scene_past_the_size_bounds_is_refused_naming_the_field() {
        let opts = PresetOptions {
            duration_s: Some(1.0),
            ..PresetOptions::default()
        };
        let scene = simulate(&SimConfig::preset("single", &opts, 1).unwrap(), 1).unwrap();
        let out = tempfile::tempdir().unwrap();
        let run = |bounds, cfg| {
            let opts = OfflineOptions {
                bounds,
                ..OfflineOptions::default()
            };
            process_scene(&scene, cfg, out.path(), opts, &|_| {})
        };
        let few = SizeBounds {
            max_microphones: 4,
            ..SizeBounds::default()
        };
        match run(Some(few), PipelineConfig::default()) {
            Err(ProcessError::TooLarge(e)) => {
                assert_eq!(e.field, "arrays[0].mics");
                assert!(e.message.contains("limits.max_microphones (4)"), "{e}");
            }
            other => panic!("expected a refusal, got {other:?}"),
        }
        assert!(!out.path().join("tracks.jsonl").exists());
        let mut big = PipelineConfig::default();
        big.localize.frame = 8192;
        match run(Some(SizeBounds::default()), big) {
            Err(ProcessError::TooLarge(e)) => assert_eq!(e.field, "localize.frame"),
            other => panic!("expected a refusal, got {other:?}"),
        }
        let summary = run(None, PipelineConfig::default()).unwrap();
        assert!(summary.duration_s > 0.9, "{summary:?}");
        run(Some(SizeBounds::default()), PipelineConfig::default()).unwrap();
    }
}
