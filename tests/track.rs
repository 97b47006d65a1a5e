//! Integration tests of the tracker: Vo's standard linear-Gaussian scenario (OSPA), and
//! behaviour in a room with a camera and microphone arrays, one group of scenarios per module.

#[path = "track/arrays.rs"]
mod arrays;
#[path = "track/bad_input.rs"]
mod bad_input;
#[path = "track/clutter.rs"]
mod clutter;
#[path = "track/crossing.rs"]
mod crossing;
#[path = "track/gait.rs"]
mod gait;
#[path = "track/labels.rs"]
mod labels;
#[path = "track/paper_room.rs"]
mod paper_room;
#[path = "track/room.rs"]
mod room;
#[path = "track/silence.rs"]
mod silence;
#[path = "track/vo.rs"]
mod vo;
