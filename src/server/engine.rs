//! What a session's worker drives: the pipeline, behind a trait so the worker's failure handling
//! can be shown with an engine that breaks on purpose.

use crate::geometry::Layout;
use crate::pipeline::{ConfigError, InputError, Pipeline, PipelineConfig, PipelineEvent};
use crate::scene::{AudioMeasurementFrame, DetectionFrame};

/// One session's processing, as the worker thread sees it.
pub trait Engine: Send + 'static {
    /// Accepts interleaved audio starting at sample frame `first_sample`.
    fn push_audio(
        &mut self,
        first_sample: u64,
        channels: usize,
        samples: &[f32],
    ) -> Result<Vec<PipelineEvent>, InputError>;
    /// Accepts one camera frame.
    fn push_detections(&mut self, frame: DetectionFrame) -> Result<Vec<PipelineEvent>, InputError>;
    /// Accepts one device measurement frame.
    fn push_device_measurements(
        &mut self,
        frame: AudioMeasurementFrame,
    ) -> Result<Vec<PipelineEvent>, InputError>;
    /// Recalibration: new sensor positions, tracks kept.
    fn set_layout(&mut self, layout: Layout) -> Result<(), ConfigError>;
    /// New settings, where they can change live.
    fn update_config(&mut self, cfg: PipelineConfig) -> Result<(), ConfigError>;
    /// End of input: everything held is processed and flushed.
    fn finish(&mut self) -> Vec<PipelineEvent>;
}

impl Engine for Pipeline {
    fn push_audio(
        &mut self,
        first_sample: u64,
        channels: usize,
        samples: &[f32],
    ) -> Result<Vec<PipelineEvent>, InputError> {
        Pipeline::push_audio(self, first_sample, channels, samples)
    }

    fn push_detections(&mut self, frame: DetectionFrame) -> Result<Vec<PipelineEvent>, InputError> {
        Pipeline::push_detections(self, frame)
    }

    fn push_device_measurements(
        &mut self,
        frame: AudioMeasurementFrame,
    ) -> Result<Vec<PipelineEvent>, InputError> {
        Pipeline::push_device_measurements(self, frame)
    }

    fn set_layout(&mut self, layout: Layout) -> Result<(), ConfigError> {
        Pipeline::set_layout(self, layout)
    }

    fn update_config(&mut self, cfg: PipelineConfig) -> Result<(), ConfigError> {
        Pipeline::update_config(self, cfg)
    }

    fn finish(&mut self) -> Vec<PipelineEvent> {
        Pipeline::finish(self)
    }
}
