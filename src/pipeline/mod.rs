//! One session's processing: framing of audio in session time, synchronisation with camera
//! detections, the wiring of the localiser, tracker and separator, and the offline runner.

mod audio_history;
mod bounds;
mod clock;
pub mod config;
pub mod config_doc;
pub mod diarization;
mod events;
pub mod input;
pub mod offline;
mod oracle;
mod oracle_mask;
mod sensor_queue;
mod separation;
mod session;
pub mod speaking;
pub mod stages;

pub use audio_history::AudioHistory;
pub use bounds::{SizeBounds, footprint};
pub use clock::StepClock;
pub use config::{AudioMeasurementSource, ConfigError, LocalizedMeasurements, PipelineConfig};
pub use events::{EventSink, PipelineEvent};
pub use input::InputError;
pub use sensor_queue::{SensorQueue, largest_frame_bytes};
pub use separation::{SeparationChunk, SeparationDriver, SeparationHandoff, SeparationWork};
pub use session::{LIVE_SETTINGS, Pipeline, PipelineStats};
pub use speaking::{SpeakingConfig, SpeakingFilter};
pub use stages::SensorClutter;
