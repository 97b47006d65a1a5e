//! The wire contract of live sessions: binary audio frames and JSON messages, and the checks
//! applied to them before they reach a pipeline. Nothing here touches sockets.

pub mod audio_frame;
pub mod inbound;
pub mod messages;
pub mod parse;
pub mod rest;
pub mod schema;
pub mod zenoh_keys;

pub use audio_frame::{AudioFrame, FrameError, LabelAudioFrame, SampleEncoding};
pub use messages::{
    AudioSelection, ClientMessage, ErrorBody, OutputSelection, ServerMessage, SessionEvent,
};
