//! One session's processing: framing of audio in session time, synchronisation with camera
//! detections, the wiring of the localiser, tracker and separator, and the offline runner.

mod audio_history;
mod clock;
pub mod config_doc;
pub mod diarization;
pub mod input;

pub use audio_history::AudioHistory;
pub use clock::StepClock;
pub use input::InputError;
