//! The wire contract of live sessions: binary audio frames and JSON messages, and the checks
//! applied to them before they reach a pipeline. Nothing here touches sockets.

pub mod audio_frame;

pub use audio_frame::{AudioFrame, FrameError, LabelAudioFrame, SampleEncoding};
