//! The `avsep simulate` command line: scenes that load back, configuration files, recorded
//! speech, and bad arguments.

use std::path::Path;
use std::process::Command;

use avsep::scene::sim;
use avsep::scene::{Audio, SampleFormat, Scene};

use super::{active_mask, preset};

fn avsep() -> Command {
    Command::new(env!("CARGO_BIN_EXE_avsep"))
}

#[test]
fn the_command_line_writes_a_scene_that_loads_back() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene");
    let status = avsep()
        .args([
            "simulate",
            "--preset",
            "paper-linear6",
            "--seed",
            "2",
            "--duration",
            "1.5",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let scene = Scene::load(&out).unwrap();
    assert_eq!(scene.layout.channel_count(), 6);
    assert_eq!(scene.layout.cameras.len(), 1);
    assert_eq!(scene.detections.len(), 12, "8 fps for 1.5 s");
    let truth = scene.truth.as_ref().unwrap();
    assert_eq!(truth.sources.len(), 3);
    assert!((scene.duration() - 1.5).abs() < 1e-9);
    // The paper's camera matrix is kept exactly.
    assert_eq!(scene.layout.cameras[0].projection()[(0, 3)], 7071.5);
    let again = sim::simulate(&preset("paper-linear6", 1.5, 2), 2).unwrap();
    assert_eq!(scene.audio, again.audio);

    let list = avsep()
        .args(["simulate", "--list-presets"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&list.stdout);
    for name in ["paper-linear6", "uca8", "two-arrays", "single"] {
        assert!(text.contains(name), "{text}");
    }
}

fn expect_input_error(args: &[&str], mention: &str) {
    let out = avsep().args(args).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{args:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(mention), "{args:?}: {err}");
}

#[test]
fn bad_arguments_exit_with_code_2_and_say_why() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x");
    let out = out.to_str().unwrap();
    expect_input_error(
        &["simulate", "--preset", "nope", "--out", out],
        "unknown preset",
    );
    expect_input_error(
        &[
            "simulate",
            "--preset",
            "uca8",
            "--duration",
            "-1",
            "--out",
            out,
        ],
        "--duration",
    );
    expect_input_error(
        &[
            "simulate",
            "--preset",
            "single",
            "--speakers",
            "2",
            "--out",
            out,
        ],
        "--speakers",
    );
    expect_input_error(
        &[
            "simulate", "--preset", "uca8", "--rt60", "0.01", "--out", out,
        ],
        "rt60",
    );
    expect_input_error(&["simulate", "--preset", "uca8"], "--out");
    expect_input_error(&["simulate", "--out", out], "--preset");
    let cfg = dir.path().join("bad.json");
    std::fs::write(&cfg, r#"{"duration_s": 2.0, "rooom": {}}"#).unwrap();
    expect_input_error(
        &["simulate", "--config", cfg.to_str().unwrap(), "--out", out],
        "rooom",
    );
}

#[test]
fn a_configuration_file_reproduces_the_preset() {
    let dir = tempfile::tempdir().unwrap();
    let printed = avsep()
        .args([
            "simulate",
            "--preset",
            "single",
            "--seed",
            "4",
            "--duration",
            "1",
            "--print-config",
        ])
        .output()
        .unwrap();
    assert!(printed.status.success());
    let cfg_path = dir.path().join("single.json");
    std::fs::write(&cfg_path, &printed.stdout).unwrap();
    let out = dir.path().join("scene");
    let run = avsep()
        .args([
            "simulate",
            "--seed",
            "4",
            "--config",
            cfg_path.to_str().unwrap(),
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let from_file = Scene::load(&out).unwrap();
    let direct = sim::simulate(&preset("single", 1.0, 4), 4).unwrap();
    assert_eq!(from_file.audio, direct.audio);
}

/// Writes a WAV of noise bursts (speech-like on/off) at `rate` with `channels`.
fn write_bursts(path: &Path, rate: u32, channels: usize, seconds: f64) {
    let frames = (seconds * rate as f64) as usize;
    let mut samples = Vec::with_capacity(frames * channels);
    let mut state = 12345u32;
    for n in 0..frames {
        let t = n as f64 / rate as f64;
        let on = (t % 1.0) < 0.6;
        for _ in 0..channels {
            state = state.wrapping_mul(1664525).wrapping_add(1013904223);
            let noise = (state >> 8) as f32 / (1 << 24) as f32 - 0.5;
            samples.push(if on { 0.3 * noise } else { 0.0 });
        }
    }
    Audio {
        sample_rate: rate,
        channels,
        samples,
    }
    .write(path, SampleFormat::I16)
    .unwrap();
}

#[test]
fn recorded_speech_from_a_folder_replaces_the_synthetic_voices() {
    let dir = tempfile::tempdir().unwrap();
    let speech = dir.path().join("speech");
    std::fs::create_dir(&speech).unwrap();
    write_bursts(&speech.join("a.wav"), 44100, 2, 3.0);
    write_bursts(&speech.join("b.wav"), 16000, 1, 3.0);
    std::fs::write(speech.join("notes.txt"), "ignored").unwrap();
    let out = dir.path().join("scene");
    let run = avsep()
        .args([
            "simulate",
            "--preset",
            "uca8",
            "--speakers",
            "2",
            "--duration",
            "2.5",
        ])
        .arg("--speech")
        .arg(&speech)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_voices_follow_the_bursts(&Scene::load(&out).unwrap());

    // A missing folder, a folder without enough files, a broken WAV: exit 2 naming the path.
    expect_speech_error(&dir.path().join("missing"), &out, "missing");
    expect_speech_error(&speech, &out, "speech");
    std::fs::write(speech.join("c.wav"), "this is not audio").unwrap();
    expect_speech_error(&speech, &out, "c.wav");
}

/// Every source of the 2.5 s `scene` pauses where its recording does and has its energy inside
/// its active intervals.
fn assert_voices_follow_the_bursts(scene: &Scene) {
    let fs = scene.layout.sample_rate as f64;
    for s in &scene.truth.as_ref().unwrap().sources {
        // The bursts' gaps show up as pauses inside the phrases.
        assert!(!s.active.is_empty());
        let talk: f64 = s.active.iter().map(|(a, b)| b - a).sum();
        assert!(talk < 0.8 * 2.5, "{}: active {talk} s", s.id);
        let sig = s.signal.as_ref().unwrap();
        let mask = active_mask(
            sig.len(),
            &s.active
                .iter()
                .map(|&(a, b)| (a, b + 0.3))
                .collect::<Vec<_>>(),
            fs,
        );
        let total: f64 = sig.iter().map(|v| (*v as f64).powi(2)).sum();
        let inside: f64 = sig
            .iter()
            .zip(&mask)
            .filter(|p| *p.1)
            .map(|p| (*p.0 as f64).powi(2))
            .sum();
        assert!(total > 0.0 && inside > 0.99 * total);
    }
}

/// Simulating a 1 s uca8 scene with the recordings in `speech` into `out` exits 2 mentioning
/// `mention`.
fn expect_speech_error(speech: &Path, out: &Path, mention: &str) {
    expect_input_error(
        &[
            "simulate",
            "--preset",
            "uca8",
            "--duration",
            "1",
            "--speech",
            speech.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        mention,
    );
}
