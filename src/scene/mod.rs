//! Scene folders (../shared/scene-format.md, version 1): the strict reader, the writer, the output
//! folder, and the room simulator that makes scenes with known truth.

pub mod convert;
mod error;
pub mod format;
mod model;
pub mod output;
mod reader;
pub mod schema;
pub mod sim;
mod wav;
mod writer;

pub use error::SceneError;
pub use model::{
    AudioMeasurementFrame, DetectionFrame, Doa, FaceBox, Scene, Truth, TruthSource, box_problem,
};
pub use reader::{parse_json, read_jsonl};
pub use wav::{Audio, SampleFormat};
pub use writer::{JsonlWriter, measurement_to_line, write_json};

#[cfg(test)]
mod tests;
