//! One session's pipeline: audio and detections in session time go in; measurements, tracks,
//! separated audio and events come out.
//!
//! The pipeline is a plain struct driven by its caller (the offline runner or a server worker):
//! `push_*` accepts input (validated, never panicking), `poll` runs every tracker step whose data
//! is complete, `finish` flushes everything at the end of the input. It has no clock of its own:
//! the camera wait is measured in audio time, so a live session fed in time order produces exactly
//! what the offline run produces.

mod sensors;
mod step;
#[cfg(test)]
mod tests;

use std::collections::BTreeSet;

use crate::dsp::{MultiSpectrum, Stft};
use crate::geometry::Layout;
use crate::label::Label;
use crate::localize::Localizer;
use crate::scene::{AudioMeasurementFrame, DetectionFrame, Truth};
use crate::separate::PitchPart;
use crate::track::{Tracker, build_tracker, sensors_from_layout};

use super::config::{ConfigError, PipelineConfig};
use super::input::{self, InputError};
use super::oracle::OraclePitch;
use super::sensor_queue::SensorQueue;
use super::separation::{SeparationDriver, SeparationFeed, SeparationHandoff};
use super::speaking::SpeakingFilter;
use super::stages::{SensorClutter, SensorRoutes, Timeline};
use super::{AudioHistory, EventSink, PipelineEvent, StepClock};

/// Counters of a pipeline's life, for summaries and metrics.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct PipelineStats {
    /// Tracker steps run.
    pub steps: u64,
    /// Audio sample frames accepted.
    pub samples_in: u64,
    /// Audio sample frames of silence inserted to bridge gaps.
    pub samples_bridged: u64,
    /// Camera frames accepted.
    pub detection_frames_in: u64,
    /// Device measurement frames accepted.
    pub device_frames_in: u64,
    /// Messages refused (invalid or late).
    pub rejected: u64,
    /// Camera frames that arrived after their step had run.
    pub late_frames: u64,
    /// Steps in which at least one camera was absent.
    pub steps_with_absent_camera: u64,
    /// Distinct labels ever reported.
    pub labels: u64,
}

/// Where track estimates come from.
enum TrackSource {
    /// The configured tracker, with the routes from inputs to its sensors.
    Tracker {
        tracker: Box<dyn Tracker>,
        routes: SensorRoutes,
    },
    /// The scene's true trajectories (for measuring separation alone), and the true sources'
    /// pitch when the harmonic grouping is to use it.
    Oracle(Truth, Option<OraclePitch>),
}

/// One session's processing chain.
pub struct Pipeline {
    layout: Layout,
    cfg: PipelineConfig,
    clock: StepClock,
    seed: u64,
    audio: Option<AudioHistory>,
    localizer: Option<Localizer>,
    loc_stft: Stft,
    loc_spectra: MultiSpectrum,
    frame_buf: Vec<f64>,
    cameras: Vec<SensorQueue<DetectionFrame>>,
    devices: Vec<SensorQueue<AudioMeasurementFrame>>,
    next_step: u64,
    source: TrackSource,
    timeline: Timeline,
    live: BTreeSet<Label>,
    /// Each track's `speaking` from the localiser's probe.
    speaking: SpeakingFilter,
    seen: BTreeSet<Label>,
    separation: Option<SeparationFeed>,
    stats: PipelineStats,
    finishing: bool,
    /// Where the (zero-padded) input ends once finishing; steps past it are not run.
    end_sample: Option<u64>,
    /// Bytes the sensor frames waiting for their step may hold together (`None`: no bound).
    backlog_limit: Option<usize>,
}

impl Pipeline {
    /// Builds the pipeline of a session with the given layout and settings.
    pub fn new(layout: Layout, cfg: PipelineConfig, seed: u64) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let clock = StepClock::new(layout.sample_rate, cfg.step_s);
        let has_audio = layout.channel_count() > 0;
        let localizer = if has_audio && cfg.audio_measurements.uses_localizer() {
            Some(Localizer::new(&layout, &cfg.localize, seed).map_err(|e| e.within("localize"))?)
        } else {
            None
        };
        let loc_frame = localizer
            .as_ref()
            .map_or(cfg.localize.frame, Localizer::frame_size);
        let separation = if has_audio && cfg.separation {
            Some(SeparationFeed::new(&layout, &cfg.separate)?)
        } else {
            None
        };
        let sep_frame = separation.as_ref().map_or(0, |s| s.frame_len());
        let history = clock.history_samples(loc_frame.max(sep_frame), cfg.camera_wait_s);
        let keyed = sensors_from_layout(&layout, &cfg.track);
        let routes = SensorRoutes::new(&layout, &cfg, keyed.iter().map(|(k, _)| *k).collect());
        let mut localizer = localizer;
        if let Some(l) = localizer.as_mut() {
            l.use_positions(routes.localized_positions());
        }
        let tracker = build_tracker(
            &cfg.track,
            keyed.into_iter().map(|(_, m)| m).collect(),
            layout.region,
            seed,
        )
        .map_err(|e| e.within("track"))?;
        Ok(Self {
            clock,
            seed,
            audio: has_audio.then(|| AudioHistory::new(layout.channel_count(), history)),
            localizer,
            loc_stft: Stft::new(loc_frame),
            loc_spectra: MultiSpectrum::zeros(layout.channel_count(), loc_frame / 2 + 1),
            frame_buf: vec![0.0; loc_frame.max(sep_frame)],
            cameras: (0..layout.cameras.len())
                .map(|_| SensorQueue::default())
                .collect(),
            devices: (0..layout.arrays.len())
                .map(|_| SensorQueue::default())
                .collect(),
            next_step: 0,
            source: TrackSource::Tracker { tracker, routes },
            timeline: Timeline::default(),
            live: BTreeSet::new(),
            speaking: SpeakingFilter::new(&cfg.speaking, clock.step_s()),
            seen: BTreeSet::new(),
            separation,
            stats: PipelineStats::default(),
            finishing: false,
            end_sample: None,
            backlog_limit: None,
            layout,
            cfg,
        })
    }

    /// Replaces the tracker by the scene's true trajectories (labels `0.i` for source i).
    pub fn use_oracle_tracks(&mut self, truth: Truth) {
        self.source = TrackSource::Oracle(truth, None);
    }

    /// With oracle tracks, hands the separator `part` of each true source's pitch (read from its
    /// signal) instead of the harmonic grouping's estimate, to measure the grouping alone. The
    /// error says why it cannot (no oracle tracks, or a source without a signal).
    pub fn use_oracle_pitch(&mut self, part: PitchPart) -> Result<(), String> {
        let rate = self.layout.sample_rate;
        match &mut self.source {
            TrackSource::Oracle(truth, pitch) => {
                *pitch = Some(OraclePitch::new(truth, rate, &self.cfg.separate, part)?);
                Ok(())
            }
            TrackSource::Tracker { .. } => {
                Err("oracle pitch needs oracle tracks (the pitch is per true source)".into())
            }
        }
    }

    /// The session's layout.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// The settings in force.
    pub fn config(&self) -> &PipelineConfig {
        &self.cfg
    }

    /// The step clock.
    pub fn clock(&self) -> StepClock {
        self.clock
    }

    /// The seed of the session's random numbers.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Counters so far.
    pub fn stats(&self) -> PipelineStats {
        self.stats
    }

    /// Index of the next audio sample frame expected.
    pub fn next_sample(&self) -> u64 {
        self.audio.as_ref().map_or(0, AudioHistory::end)
    }

    /// Labels currently reported.
    pub fn live_labels(&self) -> Vec<Label> {
        self.live.iter().copied().collect()
    }

    /// Separated-audio latency: samples between the end of the input a step needs and the last
    /// separated sample it releases (frame minus hop of the separator's STFT).
    pub fn audio_delay_samples(&self) -> u64 {
        self.separation.as_ref().map_or(0, |s| s.delay_samples())
    }

    /// Makes the separation emit each STFT frame's pitch per label ([`PipelineEvent::Pitch`],
    /// for `pitch.jsonl`); false when the pipeline separates nothing or its separation has
    /// been moved out.
    pub fn record_pitch(&mut self) -> bool {
        self.separation.as_mut().is_some_and(|s| s.record_pitch())
    }

    /// Moves the separation out of the pipeline: from now on each step's separation work goes to
    /// `handoff`, in order, and whoever holds the returned driver applies it (a live session runs
    /// it on a thread of its own, so the next step's tracks never wait for this step's audio).
    /// None when the pipeline separates nothing or has handed its driver out already.
    pub fn detach_separation(&mut self, handoff: SeparationHandoff) -> Option<SeparationDriver> {
        self.separation.as_mut()?.detach(handoff)
    }

    fn reject<T>(&mut self, e: InputError) -> Result<T, InputError> {
        self.stats.rejected += 1;
        Err(e)
    }

    /// Accepts a block of interleaved audio starting at sample frame `first_sample`; returns what
    /// the steps it completed produced.
    ///
    /// A block that starts after the expected sample is preceded by silence (up to `max_gap_s`);
    /// one that starts before it (overlap or time going backwards) is refused.
    pub fn push_audio(
        &mut self,
        first_sample: u64,
        channels: usize,
        samples: &[f32],
    ) -> Result<Vec<PipelineEvent>, InputError> {
        collected(|sink| self.push_audio_to(first_sample, channels, samples, sink))
    }

    /// [`Pipeline::push_audio`] handing each event to `sink` as soon as it exists: a step's
    /// tracks go out before its separation runs.
    pub fn push_audio_to(
        &mut self,
        first_sample: u64,
        channels: usize,
        samples: &[f32],
        sink: &mut EventSink<'_>,
    ) -> Result<(), InputError> {
        if let Err(e) = input::check_audio(&self.layout, channels, samples) {
            return self.reject(e);
        }
        if self.finishing {
            return self.reject(InputError::new(
                "finished",
                "first_sample",
                "the session's input has ended",
            ));
        }
        let max_gap = (self.cfg.max_gap_s * self.clock.sample_rate as f64) as u64;
        let sr = self.clock.sample_rate as f64;
        let step = self.clock.step_samples as usize;
        let Some(audio) = self.audio.as_mut() else {
            return self.reject(InputError::new(
                "no_audio",
                "channels",
                "this session has no audio channels",
            ));
        };
        let expected = audio.end();
        if first_sample < expected {
            let msg = format!(
                "block starts at sample {first_sample} but sample {expected} is next (time goes backwards or overlaps)"
            );
            return self.reject(InputError::new("time_backwards", "first_sample", msg));
        }
        if first_sample > expected {
            let gap = first_sample - expected;
            if gap > max_gap {
                let msg = format!(
                    "gap of {:.3} s before this block exceeds max_gap_s; send from sample {expected}",
                    gap as f64 / sr
                );
                return self.reject(InputError::new("gap_too_long", "first_sample", msg));
            }
            self.stats.samples_bridged += gap;
            sink(PipelineEvent::Warning {
                code: "gap_bridged",
                message: format!(
                    "{gap} missing samples before sample {first_sample} replaced by silence"
                ),
            });
            // A step at a time, as the audio below, so the history holds each step's audio
            // when it runs.
            let mut left = gap as usize;
            while left > 0 {
                let n = left.min(step);
                if let Some(a) = self.audio.as_mut() {
                    a.append_silence(n);
                }
                self.poll_to(sink);
                left -= n;
            }
        }
        for piece in samples.chunks(step * channels) {
            if let Some(a) = self.audio.as_mut() {
                a.append_interleaved(piece);
            }
            self.poll_to(sink);
        }
        self.stats.samples_in += (samples.len() / channels) as u64;
        Ok(())
    }

    /// Replaces the layout (live recalibration): stages keep their tracks and adaptive state.
    pub fn set_layout(&mut self, layout: Layout) -> Result<(), ConfigError> {
        if layout.channel_count() != self.layout.channel_count()
            || layout.cameras.len() != self.layout.cameras.len()
            || layout.arrays.len() != self.layout.arrays.len()
        {
            return Err(ConfigError::new(
                "layout",
                "recalibration may move microphones and cameras but not add or remove them",
            ));
        }
        // Every check before any change, so a refused layout leaves the session as it was: the
        // localiser's check is pure, the tracker's change all or nothing, and what follows
        // cannot fail.
        if let Some(l) = &self.localizer {
            l.check_layout(&layout).map_err(|e| e.within("localize"))?;
        }
        if let TrackSource::Tracker { tracker, .. } = &mut self.source {
            let models = sensors_from_layout(&layout, &self.cfg.track)
                .into_iter()
                .map(|(_, m)| m)
                .collect();
            tracker.set_sensors(models).map_err(|e| e.within("track"))?;
        }
        if let Some(l) = self.localizer.as_mut() {
            l.set_layout(&layout).map_err(|e| e.within("localize"))?;
        }
        if let Some(s) = self.separation.as_mut() {
            s.set_layout(&layout);
        }
        self.layout = layout;
        Ok(())
    }

    /// Applies new settings to a running pipeline, keeping its tracks. Only what tunes a stage
    /// can change ([`LIVE_SETTINGS`]: the camera wait, box score threshold, gap bridging, use of
    /// cameras, the tracker's sensor models and clutter estimation, and the separator except its
    /// framing); anything else shapes a stage when it is built and is refused, naming the first
    /// such field.
    pub fn update_config(&mut self, cfg: PipelineConfig) -> Result<(), ConfigError> {
        cfg.validate()?;
        let as_value = |c: &PipelineConfig| {
            serde_json::to_value(c).map_err(|e| ConfigError::new("", e.to_string()))
        };
        let mut changed = Vec::new();
        changed_fields(&as_value(&self.cfg)?, &as_value(&cfg)?, "", &mut changed);
        let live = |f: &str| {
            !matches!(f, "separate.frame" | "separate.hop")
                && LIVE_SETTINGS
                    .iter()
                    .any(|p| f == *p || f.strip_prefix(p).is_some_and(|r| r.starts_with('.')))
        };
        if let Some(f) = changed.iter().find(|f| !live(f)) {
            return Err(ConfigError::new(
                f.clone(),
                "cannot change on a running session (it shapes a stage when the session is created)",
            ));
        }
        // As in `set_layout`: the separator's check first, then the tracker's all-or-nothing
        // change, then the separator's, which cannot fail after its check.
        let separate = changed.iter().any(|f| f.starts_with("separate."));
        if separate && let Some(sep) = &self.separation {
            sep.check_config(&cfg.separate)?;
        }
        if changed.iter().any(|f| f.starts_with("track.")) {
            cfg.track.validate().map_err(|e| e.within("track"))?;
            if let TrackSource::Tracker { tracker, .. } = &mut self.source {
                let models = sensors_from_layout(&self.layout, &cfg.track)
                    .into_iter()
                    .map(|(_, m)| m)
                    .collect();
                tracker.set_sensors(models).map_err(|e| e.within("track"))?;
                if changed.iter().any(|f| f.starts_with("track.clutter.")) {
                    tracker.set_clutter(&cfg.track.clutter);
                }
            }
        }
        if separate && let Some(sep) = self.separation.as_mut() {
            sep.set_config(&cfg.separate)?;
        }
        if let Some(a) = self.audio.as_mut() {
            // The camera wait sizes the history.
            let loc = (self.localizer.as_ref()).map_or(cfg.localize.frame, Localizer::frame_size);
            let sep = self.separation.as_ref().map_or(0, |s| s.frame_len());
            a.set_capacity(self.clock.history_samples(loc.max(sep), cfg.camera_wait_s));
        }
        self.cfg = cfg;
        Ok(())
    }

    /// The tracker sensors' clutter rates, configured and estimated (none with oracle tracks).
    pub fn clutter_rates(&self) -> Vec<SensorClutter> {
        let TrackSource::Tracker { tracker, routes } = &self.source else {
            return Vec::new();
        };
        routes
            .keys()
            .iter()
            .zip(tracker.clutter_rates())
            .map(|(key, rate)| SensorClutter {
                sensor: key.name(&self.layout),
                configured: rate.configured,
                estimated: rate.estimated,
                scans: rate.scans,
            })
            .collect()
    }
}

/// Settings (dotted paths, with everything below them) that [`Pipeline::update_config`] can change
/// on a running pipeline; `separate.frame` and `separate.hop` are excluded.
pub const LIVE_SETTINGS: &[&str] = &[
    "camera_wait_s",
    "min_box_score",
    "localized_min_fresh_sigmas",
    "max_gap_s",
    "max_lead_s",
    "cameras",
    "track.audio_position",
    "track.audio_direction",
    "track.camera.noise_std_px",
    "track.camera.reference_height_px",
    "track.camera.p_detect",
    "track.camera.clutter_rate",
    "track.camera.filter",
    "track.clutter",
    "separate",
];

/// Dotted paths of the leaves where two settings documents differ.
fn changed_fields(
    old: &serde_json::Value,
    new: &serde_json::Value,
    path: &str,
    out: &mut Vec<String>,
) {
    match (old, new) {
        (serde_json::Value::Object(a), serde_json::Value::Object(b)) => {
            for (key, va) in a {
                let p = if path.is_empty() {
                    key.clone()
                } else {
                    format!("{path}.{key}")
                };
                match b.get(key) {
                    Some(vb) => changed_fields(va, vb, &p, out),
                    None => out.push(p),
                }
            }
            for key in b.keys().filter(|k| !a.contains_key(*k)) {
                out.push(if path.is_empty() {
                    key.clone()
                } else {
                    format!("{path}.{key}")
                });
            }
        }
        (a, b) if a != b => out.push(path.to_string()),
        _ => {}
    }
}

/// Runs `push` with a sink that collects its events.
fn collected(
    push: impl FnOnce(&mut EventSink<'_>) -> Result<(), InputError>,
) -> Result<Vec<PipelineEvent>, InputError> {
    let mut events = Vec::new();
    push(&mut |e| events.push(e))?;
    Ok(events)
}
