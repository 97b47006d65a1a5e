//! Running the tracker steps: when a step's data is complete, and what one step does
//! (localise, track, emit the tracks, then separate the step's audio).

use std::collections::BTreeSet;

use super::{Pipeline, TrackSource};
use crate::label::Label;
use crate::localize::Localizer;
use crate::pipeline::oracle;
use crate::pipeline::sensor_queue::SensorQueue;
use crate::pipeline::speaking::SpeakingFilter;
use crate::pipeline::stages::{self, Estimate};
use crate::pipeline::{EventSink, PipelineEvent};
use crate::scene::format::TracksLine;
use crate::scene::{AudioMeasurementFrame, DetectionFrame};
use crate::track::{Scan, StepInput};

impl Pipeline {
    /// Whether the data of step `k` is complete (or waited for long enough).
    fn step_ready(&self, k: u64) -> bool {
        let (_, t1) = self.clock.step_bounds(k);
        if let Some(end) = self.end_sample
            && self.clock.step_start_sample(k) >= end
        {
            return false;
        }
        let mut waited: Vec<f64> = Vec::new();
        if self.cfg.cameras {
            waited.extend(self.cameras.iter().map(SensorQueue::last_time));
        }
        waited.extend(
            self.devices
                .iter()
                .filter(|d| d.has_reported())
                .map(SensorQueue::last_time),
        );
        let horizon = match &self.audio {
            Some(a) => self.clock.time_of(a.end()),
            None => waited.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        };
        if horizon < t1 {
            return false;
        }
        self.finishing || horizon >= t1 + self.cfg.camera_wait_s || waited.iter().all(|&t| t >= t1)
    }

    /// Runs every step whose data is complete; returns what they produced.
    pub fn poll(&mut self) -> Vec<PipelineEvent> {
        let mut events = Vec::new();
        self.poll_to(&mut |e| events.push(e));
        events
    }

    /// [`Pipeline::poll`] handing each event to `sink` as soon as it exists.
    pub fn poll_to(&mut self, sink: &mut EventSink<'_>) {
        while self.step_ready(self.next_step) {
            self.run_step(sink);
        }
    }

    /// Ends the input: pads the audio to whole steps and frames, runs the remaining steps and
    /// flushes the separated streams.
    pub fn finish(&mut self) -> Vec<PipelineEvent> {
        let mut events = Vec::new();
        self.finish_to(&mut |e| events.push(e));
        events
    }

    /// [`Pipeline::finish`] handing each event to `sink` as soon as it exists.
    pub fn finish_to(&mut self, sink: &mut EventSink<'_>) {
        self.finishing = true;
        let end = match &self.audio {
            Some(a) => a.end(),
            None => {
                let cams = self.cameras.iter().map(SensorQueue::last_time);
                let t_max = cams
                    .chain(self.devices.iter().map(SensorQueue::last_time))
                    .fold(0.0, f64::max);
                (t_max * self.clock.sample_rate as f64).ceil() as u64 + 1
            }
        };
        self.end_sample = Some(end);
        let steps = end.div_ceil(self.clock.step_samples);
        if let Some(audio) = self.audio.as_mut() {
            // Whole last step plus one separator frame of silence so every input sample is output.
            let pad = steps * self.clock.step_samples - end + self.frame_buf.len() as u64;
            audio.append_silence(pad as usize);
        }
        while self.next_step < steps && self.step_ready(self.next_step) {
            self.run_step(sink);
        }
        if let Some(sep) = self.separation.as_mut()
            && let Some(audio) = &self.audio
        {
            let timeline = &self.timeline;
            sep.advance(
                audio,
                audio.end(),
                &self.clock,
                |t| timeline.targets_at(t),
                sink,
            );
            sep.flush(sink);
        }
        for label in std::mem::take(&mut self.live) {
            let t = self.timeline.last_time().unwrap_or(0.0);
            sink(PipelineEvent::TrackEnded { t, label });
        }
    }

    fn run_step(&mut self, sink: &mut EventSink<'_>) {
        let k = self.next_step;
        self.next_step += 1;
        self.stats.steps += 1;
        let (_, t1) = self.clock.step_bounds(k);
        let t_est = self.clock.estimate_time(k);
        let end_sample = self.clock.step_end_sample(k);

        // Audio measurements: the localiser on the frame ending at the step's end (None when it
        // did not run: no localiser, or the frame's audio is not all there, as at the end).
        let localized = self.localize(end_sample);
        let frame_seen = localized.is_some();
        let observations = localized.unwrap_or_default();
        for obs in &observations {
            sink(PipelineEvent::Measurements(stages::measurement_line(
                &self.layout,
                obs,
                t1 - self.loc_stft.frame() as f64 / self.clock.sample_rate as f64,
            )));
        }
        let activity = observations.iter().map(|o| o.activity).fold(0.0, f64::max);

        let (camera_frames, device_frames) = self.take_sensor_frames(t1);
        let estimates = match &mut self.source {
            TrackSource::Tracker { tracker, routes } => {
                let mut scans: Vec<Scan> = Vec::new();
                routes.localized(
                    &observations,
                    self.cfg.localized_min_fresh_sigmas,
                    &mut scans,
                );
                routes.devices(&device_frames, &mut scans);
                if self.cfg.cameras {
                    routes.cameras(&camera_frames, &mut scans);
                }
                let out = tracker.step(&StepInput { k, t: t_est, scans });
                let mut est: Vec<Estimate> = out.into_iter().map(Estimate::from).collect();
                probe_speaking(
                    self.localizer.as_mut(),
                    &mut self.speaking,
                    &mut est,
                    frame_seen,
                );
                est
            }
            TrackSource::Oracle(truth, _) => oracle::estimates(truth, t_est),
        };
        self.timeline.push(t_est, estimates.clone(), activity);
        self.emit_tracks(k, t_est, &estimates, sink);

        // Separation of every STFT frame whose window ends within this step (here, or handed
        // to the separation's own thread).
        if let (Some(sep), Some(audio)) = (self.separation.as_mut(), self.audio.as_ref()) {
            let timeline = &self.timeline;
            let oracle = match &self.source {
                TrackSource::Oracle(truth, pitch) => Some((truth, pitch.as_ref())),
                TrackSource::Tracker { .. } => None,
            };
            sep.advance(
                audio,
                end_sample,
                &self.clock,
                |t| match oracle {
                    Some((truth, pitch)) => oracle::targets(truth, t, activity, pitch),
                    None => timeline.targets_at(t),
                },
                sink,
            );
        }
    }

    /// This step's camera frames (the latest per camera: the tracker models one look per step)
    /// and device measurement frames.
    fn take_sensor_frames(
        &mut self,
        t1: f64,
    ) -> (Vec<(usize, DetectionFrame)>, Vec<AudioMeasurementFrame>) {
        let mut camera_frames = Vec::new();
        for (j, q) in self.cameras.iter_mut().enumerate() {
            if let Some(f) = q.take_before(t1).pop() {
                camera_frames.push((j, f));
            }
        }
        if self.cfg.cameras && camera_frames.len() < self.cameras.len() {
            self.stats.steps_with_absent_camera += 1;
        }
        let mut device_frames = Vec::new();
        for q in &mut self.devices {
            device_frames.extend(q.take_before(t1));
        }
        (camera_frames, device_frames)
    }

    fn localize(&mut self, end_sample: u64) -> Option<Vec<crate::localize::ArrayObservation>> {
        let (Some(localizer), Some(audio)) = (self.localizer.as_mut(), self.audio.as_ref()) else {
            return None;
        };
        let n = self.loc_stft.frame();
        let from = end_sample as i64 - n as i64;
        for ch in 0..audio.channels() {
            audio.read(ch, from, &mut self.frame_buf[..n]).ok()?;
            self.loc_stft
                .forward(&self.frame_buf[..n], self.loc_spectra.channel_mut(ch));
        }
        Some(localizer.process(&self.loc_spectra))
    }

    fn emit_tracks(&mut self, k: u64, t: f64, estimates: &[Estimate], sink: &mut EventSink<'_>) {
        let now: BTreeSet<Label> = estimates.iter().map(|e| e.label).collect();
        for &label in now.difference(&self.live) {
            if self.seen.insert(label) {
                self.stats.labels += 1;
            }
            sink(PipelineEvent::TrackBorn { t, label });
        }
        let prev_t = self.timeline.previous_time().unwrap_or(t);
        for &label in self.live.difference(&now) {
            sink(PipelineEvent::TrackEnded { t: prev_t, label });
        }
        self.live = now;
        let line = TracksLine {
            t,
            tracks: estimates.iter().map(Estimate::to_file).collect(),
        };
        sink(PipelineEvent::Tracks { step: k, line });
    }
}

/// Where the localiser can probe, sets `speaking` to its filtered reading at each track: the
/// tracker's own counts only the candidates the search found, and in an overlap the search often
/// finds only the louder talkers. A step whose frame the localiser did not see (`frame_seen`
/// false; its state is the previous frame's) gives no evidence: the chain only predicts.
fn probe_speaking(
    localizer: Option<&mut Localizer>,
    speaking: &mut SpeakingFilter,
    estimates: &mut [Estimate],
    frame_seen: bool,
) {
    let Some(loc) = localizer else { return };
    let readings = if frame_seen {
        let positions: Vec<_> = estimates.iter().map(|e| e.position).collect();
        loc.probe(&positions)
    } else {
        loc.can_probe().then(|| vec![f64::NAN; estimates.len()])
    };
    if let Some(readings) = readings {
        speaking.update(estimates, &readings);
    }
}
