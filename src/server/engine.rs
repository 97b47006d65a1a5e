//! What a session's worker drives: the pipeline, behind a trait so the worker's failure handling
//! can be shown with an engine that breaks on purpose.

use crate::geometry::Layout;
use crate::pipeline::{
    ConfigError, EventSink, InputError, Pipeline, PipelineConfig, SensorClutter, SeparationDriver,
    SeparationHandoff,
};
use crate::scene::{AudioMeasurementFrame, DetectionFrame};

/// One session's processing, as the worker thread sees it. Every input hands what it produces
/// to `sink` as soon as it exists, so a step's tracks are sent before its separation runs.
pub trait Engine: Send + 'static {
    /// Accepts interleaved audio starting at sample frame `first_sample`.
    fn push_audio(
        &mut self,
        first_sample: u64,
        channels: usize,
        samples: &[f32],
        sink: &mut EventSink<'_>,
    ) -> Result<(), InputError>;
    /// Accepts one camera frame.
    fn push_detections(
        &mut self,
        frame: DetectionFrame,
        sink: &mut EventSink<'_>,
    ) -> Result<(), InputError>;
    /// Accepts one device measurement frame.
    fn push_device_measurements(
        &mut self,
        frame: AudioMeasurementFrame,
        sink: &mut EventSink<'_>,
    ) -> Result<(), InputError>;
    /// Recalibration: new sensor positions, tracks kept.
    fn set_layout(&mut self, layout: Layout) -> Result<(), ConfigError>;
    /// New settings, where they can change live.
    fn update_config(&mut self, cfg: PipelineConfig) -> Result<(), ConfigError>;
    /// Each tracker sensor's clutter rate, configured and estimated (none by default).
    fn clutter_rates(&self) -> Vec<SensorClutter> {
        Vec::new()
    }
    /// End of input: everything held is processed and flushed.
    fn finish(&mut self, sink: &mut EventSink<'_>);
    /// Hands the separation work to `handoff` from now on and returns what applies it
    /// ([`Pipeline::detach_separation`]); an engine that separates nothing returns None.
    fn detach_separation(&mut self, _handoff: SeparationHandoff) -> Option<SeparationDriver> {
        None
    }
}

impl Engine for Pipeline {
    fn push_audio(
        &mut self,
        first_sample: u64,
        channels: usize,
        samples: &[f32],
        sink: &mut EventSink<'_>,
    ) -> Result<(), InputError> {
        self.push_audio_to(first_sample, channels, samples, sink)
    }

    fn push_detections(
        &mut self,
        frame: DetectionFrame,
        sink: &mut EventSink<'_>,
    ) -> Result<(), InputError> {
        self.push_detections_to(frame, sink)
    }

    fn push_device_measurements(
        &mut self,
        frame: AudioMeasurementFrame,
        sink: &mut EventSink<'_>,
    ) -> Result<(), InputError> {
        self.push_device_measurements_to(frame, sink)
    }

    fn set_layout(&mut self, layout: Layout) -> Result<(), ConfigError> {
        Pipeline::set_layout(self, layout)
    }

    fn update_config(&mut self, cfg: PipelineConfig) -> Result<(), ConfigError> {
        Pipeline::update_config(self, cfg)
    }

    fn clutter_rates(&self) -> Vec<SensorClutter> {
        Pipeline::clutter_rates(self)
    }

    fn finish(&mut self, sink: &mut EventSink<'_>) {
        self.finish_to(sink)
    }

    fn detach_separation(&mut self, handoff: SeparationHandoff) -> Option<SeparationDriver> {
        Pipeline::detach_separation(self, handoff)
    }
}
