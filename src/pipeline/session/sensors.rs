//! A session's camera and device frames: their timing against the session's present and
//! its tracker steps, and what the frames waiting for their step may hold.

use super::{Pipeline, collected};
use crate::pipeline::input::{self, InputError};
use crate::pipeline::sensor_queue::{SensorQueue, Timed};
use crate::pipeline::{EventSink, PipelineEvent};
use crate::scene::{AudioMeasurementFrame, DetectionFrame};

impl Pipeline {
    /// The refusal of a sensor frame at time `t` whose tracker step has already run, if it is.
    fn late(&self, what: &str, t: f64) -> Option<InputError> {
        let step_start = self.clock.step_bounds(self.next_step).0;
        (t < step_start).then(|| {
            let msg = format!(
                "{what} at {t} s arrived after its tracker step ran (now at {step_start} s)"
            );
            InputError::new("late", "t", msg)
        })
    }

    /// The session's present (s): the end of the audio received or, in a session without
    /// audio, its sensors' newest time (at least the start of the step the tracker is at).
    fn present(&self) -> f64 {
        match &self.audio {
            Some(a) => self.clock.time_of(a.end()),
            None => self
                .cameras
                .iter()
                .map(SensorQueue::last_time)
                .chain(self.devices.iter().map(SensorQueue::last_time))
                .fold(self.clock.step_bounds(self.next_step).0, f64::max),
        }
    }

    /// The refusal of a sensor frame at time `t` further than `max_lead_s` ahead of the
    /// session's present, if it is.
    fn too_early(&self, t: f64) -> Option<InputError> {
        let present = self.present();
        (t > present + self.cfg.max_lead_s).then(|| {
            let msg = format!(
                "frame at {t} s is more than max_lead_s ({} s) ahead of the session's present ({present:.3} s)",
                self.cfg.max_lead_s
            );
            InputError::new("too_early", "t", msg)
        })
    }

    /// Why a sensor frame (`what`) at time `t` holding `bytes` cannot wait for its step, if it
    /// cannot: too far ahead of the present, after its step ran, or past the backlog.
    fn untimely(&self, what: &str, t: f64, bytes: usize) -> Option<InputError> {
        self.too_early(t)
            .or_else(|| self.late(what, t))
            .or_else(|| self.over_backlog(bytes))
    }

    /// Bounds what the camera and device frames waiting for their tracker step may hold
    /// together: a frame that would take them past `bytes` is refused (`backlog_full`). A
    /// server sets it, since `max_lead_s` bounds how far ahead frames may run but not how
    /// many a client sends in that time.
    pub fn limit_backlog(&mut self, bytes: usize) {
        self.backlog_limit = Some(bytes);
    }

    /// The refusal of a frame holding `bytes` that would take the waiting frames past the
    /// backlog limit, if it would.
    fn over_backlog(&self, bytes: usize) -> Option<InputError> {
        let limit = self.backlog_limit?;
        let cams = self.cameras.iter().map(SensorQueue::held_bytes);
        let held: usize = cams
            .chain(self.devices.iter().map(SensorQueue::held_bytes))
            .sum();
        (held + bytes > limit).then(|| {
            let msg = format!(
                "the sensor frames waiting for the audio hold {held} bytes and this one \
                 {bytes} more, past limits.sensor_backlog_bytes ({limit}): frames may lead \
                 the audio by max_lead_s, but not by this much data"
            );
            InputError::new("backlog_full", "t", msg)
        })
    }

    /// Accepts one camera frame. Frames whose step already ran are refused as late.
    pub fn push_detections(
        &mut self,
        frame: DetectionFrame,
    ) -> Result<Vec<PipelineEvent>, InputError> {
        collected(|sink| self.push_detections_to(frame, sink))
    }

    /// [`Pipeline::push_detections`] handing each event to `sink` as soon as it exists.
    pub fn push_detections_to(
        &mut self,
        mut frame: DetectionFrame,
        sink: &mut EventSink<'_>,
    ) -> Result<(), InputError> {
        let last = self
            .cameras
            .get(frame.camera)
            .map_or(f64::NEG_INFINITY, SensorQueue::last_time);
        if let Err(e) = input::check_detections(&self.layout, &frame, last) {
            return self.reject(e);
        }
        let min_score = self.cfg.min_box_score;
        frame
            .boxes
            .retain(|b| b.score.is_none_or(|s| s >= min_score));
        if let Some(e) = self.untimely("camera frame", frame.t, frame.held_bytes()) {
            if e.code == "late" {
                self.stats.late_frames += 1;
            }
            return self.reject(e);
        }
        self.stats.detection_frames_in += 1;
        self.cameras[frame.camera].push(frame);
        self.poll_to(sink);
        Ok(())
    }

    /// Accepts one frame of directions/positions from a device that localises itself.
    pub fn push_device_measurements(
        &mut self,
        frame: AudioMeasurementFrame,
    ) -> Result<Vec<PipelineEvent>, InputError> {
        collected(|sink| self.push_device_measurements_to(frame, sink))
    }

    /// [`Pipeline::push_device_measurements`] handing each event to `sink` as soon as it exists.
    pub fn push_device_measurements_to(
        &mut self,
        frame: AudioMeasurementFrame,
        sink: &mut EventSink<'_>,
    ) -> Result<(), InputError> {
        let last = self
            .devices
            .get(frame.array)
            .map_or(f64::NEG_INFINITY, SensorQueue::last_time);
        if let Err(e) = input::check_device_measurements(&self.layout, &frame, last) {
            return self.reject(e);
        }
        if let Some(e) = self.untimely("measurement frame", frame.t, frame.held_bytes()) {
            return self.reject(e);
        }
        self.stats.device_frames_in += 1;
        self.devices[frame.array].push(frame);
        self.poll_to(sink);
        Ok(())
    }
}
