//! `cargo run --example zenoh-edge -- --calibration scene.json --wav audio.wav
//! --detections detections.jsonl`: an edge device that speaks only Zenoh (see README.md here).

#[path = "edge.rs"]
mod edge;

fn main() -> std::process::ExitCode {
    edge::main(std::env::args_os())
}
