//! avsep: online audio-visual multi-speaker tracking and separation.
//!
//! The pipeline is detection (SRP-PHAT localisation and camera detections) -> tracking (a labelled
//! random finite set tracker, multi-sensor GLMB) -> spatial filtering (a bank of track-steered
//! beamformers). See docs/architecture.md for the layers and how data flows between them.

pub mod cli;
pub mod dsp;
pub mod eval;
pub mod field_error;
pub mod geometry;
pub mod label;
pub mod localize;
pub mod pipeline;
pub mod protocol;
pub mod scene;
pub mod separate;
pub mod server;
pub mod track;
