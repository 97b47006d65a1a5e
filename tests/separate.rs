//! Integration tests of the separator: whole frames through `Separator::process` with the
//! project's STFT and inverse, on free-field and echoic (image-source) mixtures.

#[path = "separate/bad_input.rs"]
mod bad_input;
#[path = "separate/beamformers.rs"]
mod beamformers;
#[path = "separate/echoic.rs"]
mod echoic;
#[path = "separate/fixtures.rs"]
mod fixtures;
#[path = "separate/lifecycle.rs"]
mod lifecycle;
#[path = "separate/resting.rs"]
mod resting;
#[path = "separate/scores.rs"]
mod scores;
#[path = "separate/sim.rs"]
mod sim;
