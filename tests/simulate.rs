//! Behaviour of the room simulator: the truth identity and SNR, determinism, speech timing,
//! detections, and the `avsep simulate` command line.

use std::path::Path;
use std::process::Command;

use avsep::geometry::{Vec3, angle_diff};
use avsep::scene::sim::{
    self, CameraConfig, DetectorConfig, FacingConfig, PresetOptions, SimConfig, SpeakerConfig,
    SpeechConfig,
};
use avsep::scene::{Audio, SampleFormat, Scene};

fn preset(name: &str, seconds: f64, seed: u64) -> SimConfig {
    let opts = PresetOptions {
        duration_s: Some(seconds),
        ..Default::default()
    };
    SimConfig::preset(name, &opts, seed).unwrap()
}

fn power(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>() / x.len().max(1) as f64
}

/// The reference channel, the sum of the truth signals, and the union of active intervals.
fn reference_and_truth(scene: &Scene) -> (Vec<f64>, Vec<f64>, Vec<(f64, f64)>) {
    let audio = scene.audio.as_ref().unwrap();
    let reference: Vec<f64> = audio
        .channel(scene.layout.reference_channel().unwrap())
        .iter()
        .map(|v| *v as f64)
        .collect();
    let truth = scene.truth.as_ref().unwrap();
    let mut sum = vec![0.0; reference.len()];
    let mut active = Vec::new();
    for s in &truth.sources {
        let sig = s.signal.as_ref().unwrap();
        assert_eq!(sig.len(), reference.len());
        sum.iter_mut().zip(sig).for_each(|(a, b)| *a += *b as f64);
        active.extend(s.active.iter().copied());
    }
    (reference, sum, active)
}

fn active_mask(len: usize, active: &[(f64, f64)], fs: f64) -> Vec<bool> {
    let mut mask = vec![false; len];
    for &(a, b) in active {
        let (a, b) = ((a * fs) as usize, ((b * fs) as usize).min(len));
        mask[a..b.max(a)].iter_mut().for_each(|m| *m = true);
    }
    mask
}

/// Speech power while anyone talks over the power of (mixture - speech), in dB.
fn measured_snr(scene: &Scene) -> f64 {
    let (reference, speech, active) = reference_and_truth(scene);
    let mask = active_mask(reference.len(), &active, scene.layout.sample_rate as f64);
    let on: Vec<f64> = speech
        .iter()
        .zip(&mask)
        .filter(|p| *p.1)
        .map(|p| *p.0)
        .collect();
    let residual: Vec<f64> = reference.iter().zip(&speech).map(|(a, b)| a - b).collect();
    10.0 * (power(&on) / power(&residual)).log10()
}

#[test]
fn reference_channel_is_the_sum_of_the_truth_signals_plus_noise() {
    // Without noise the identity is exact up to the f32 rounding of the files.
    let mut cfg = preset("uca8", 2.0, 3);
    cfg.noise.snr_db = 120.0;
    let scene = sim::simulate(&cfg, 3).unwrap();
    let (reference, speech, _) = reference_and_truth(&scene);
    let samples = &scene.audio.as_ref().unwrap().samples;
    let peak = samples.iter().fold(0.0f64, |m, v| m.max(v.abs() as f64));
    assert!((peak - cfg.peak_level).abs() < 1e-6, "peak {peak}");
    let err = reference
        .iter()
        .zip(&speech)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-5 * peak, "max |ref - sum(truth)| = {err}");

    // With noise, the residual is the noise at the requested SNR.
    for (name, snr) in [("uca8", 25.0), ("single", 10.0)] {
        let mut cfg = preset(name, 2.0, 4);
        cfg.noise.snr_db = snr;
        let got = measured_snr(&sim::simulate(&cfg, 4).unwrap());
        assert!(
            (got - snr).abs() < 0.5,
            "{name}: SNR {got} dB, asked {snr} dB"
        );
    }
    // The fan of two-arrays adds its own 20 dB: 25 dB sensor noise and 20 dB fan give 18.8 dB.
    let cfg = preset("two-arrays", 1.5, 5);
    let got = measured_snr(&sim::simulate(&cfg, 5).unwrap());
    let want = -10.0 * (10f64.powf(-2.5) + 10f64.powf(-2.0)).log10();
    assert!(
        (got - want).abs() < 0.5,
        "two-arrays: SNR {got} dB, expected {want} dB"
    );
}

#[test]
fn same_seed_same_scene_and_different_seeds_differ() {
    let cfg = preset("paper-linear6", 1.5, 11);
    let a = sim::simulate(&cfg, 11).unwrap();
    let b = sim::simulate(&cfg, 11).unwrap();
    let bits = |s: &Scene| -> Vec<u32> {
        s.audio
            .as_ref()
            .unwrap()
            .samples
            .iter()
            .map(|v| v.to_bits())
            .collect()
    };
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(a.detections, b.detections);
    assert_eq!(a.truth, b.truth);
    let c = sim::simulate(&cfg, 12).unwrap();
    assert_ne!(bits(&a), bits(&c));
    let other = preset("paper-linear6", 1.5, 12);
    assert_ne!(cfg.speakers[0].path, other.speakers[0].path);
}

#[test]
fn speech_energy_lies_inside_the_active_intervals() {
    let cfg = preset("uca8", 3.0, 21);
    let scene = sim::simulate(&cfg, 21).unwrap();
    let fs = scene.layout.sample_rate as f64;
    for s in &scene.truth.as_ref().unwrap().sources {
        assert!(!s.active.is_empty(), "{} never talks", s.id);
        let sig: Vec<f64> = s
            .signal
            .as_ref()
            .unwrap()
            .iter()
            .map(|v| *v as f64)
            .collect();
        // Allow the reverberation to ring out for 0.3 s (the RT60) after each phrase.
        let tail: Vec<(f64, f64)> = s.active.iter().map(|&(a, b)| (a, b + 0.3)).collect();
        let mask = active_mask(sig.len(), &tail, fs);
        let total: f64 = sig.iter().map(|v| v * v).sum();
        let inside: f64 = sig
            .iter()
            .zip(&mask)
            .filter(|p| *p.1)
            .map(|p| p.0 * p.0)
            .sum();
        assert!(
            inside > 0.999 * total,
            "{}: {:.5} of the energy inside",
            s.id,
            inside / total
        );
        // Pauses longer than the response are silent once the reverberation has died out.
        for w in s.active.windows(2) {
            let (quiet, next) = (((w[0].1 + 0.4) * fs) as usize, (w[1].0 * fs) as usize);
            if quiet < next {
                assert!(
                    sig[quiet..next].iter().all(|v| *v == 0.0),
                    "{} in a pause",
                    s.id
                );
            }
        }
        // Before the first phrase the talker is silent.
        let first = (s.active[0].0 * fs) as usize;
        let nz = sig.iter().position(|v| *v != 0.0).unwrap();
        assert!(
            nz >= first,
            "{} speaks early: {nz} < {first}, {:?}",
            s.id,
            &sig[nz..nz + 5]
        );
    }
}

#[test]
fn paper_preset_follows_the_papers_choreography() {
    let cfg = SimConfig::preset("paper-linear6", &PresetOptions::default(), 9).unwrap();
    let entries = [[2.0, 0.7], [3.0, 0.5], [4.0, 0.6]];
    let mut enters = Vec::new();
    for (s, e) in cfg.speakers.iter().zip(entries) {
        let (first, last) = (s.path[0], s.path[s.path.len() - 1]);
        assert!(
            (first[1] - e[0]).hypot(first[2] - e[1]) < 0.25,
            "{first:?} vs {e:?}"
        );
        assert!(
            (1.8..=2.2).contains(&last[2]),
            "walks towards the sensors: {last:?}"
        );
        assert!((1.6..=1.75).contains(&s.mouth_height_m));
        enters.push(s.enter_s);
    }
    assert!(
        enters[0] < 1.0 && enters[1] > 2.0 && enters[2] > 5.0,
        "{enters:?}"
    );
    let turned: Vec<_> = cfg
        .speakers
        .iter()
        .filter(|s| !s.facing.away_s.is_empty())
        .collect();
    assert_eq!(turned.len(), 1);
    let away = turned[0].facing.away_s[0][0];
    assert!(away > 8.0 && turned[0].speech.phrases.iter().all(|p| p[1] < away));

    // Everybody is seen by the paper's camera at some point, and nobody while turned away.
    let scene = sim::simulate(&cfg, 9).unwrap();
    let cam = &scene.layout.cameras[0];
    let sources = &scene.truth.as_ref().unwrap().sources;
    let sigma = cfg.detector.point_sigma_px;
    for (s, c) in sources.iter().zip(&cfg.speakers) {
        let hits = scene
            .detections
            .iter()
            .filter(|f| {
                s.position_at(f.t).is_some_and(|p| {
                    let m = cam.project(&p).unwrap();
                    f.boxes
                        .iter()
                        .any(|b| (b.point.unwrap() - m).norm() < 4.0 * sigma)
                })
            })
            .count();
        let present = scene.detections.iter().filter(|f| s.exists_at(f.t)).count();
        assert!(
            hits as f64 > 0.5 * present as f64,
            "{}: {hits} of {present}",
            s.id
        );
        if let Some(a) = c.facing.away_s.first() {
            let late = scene.detections.iter().filter(|f| f.t > a[0] + 0.6);
            for f in late {
                let m = cam.project(&s.position_at(f.t).unwrap()).unwrap();
                assert!(
                    f.boxes
                        .iter()
                        .all(|b| (b.point.unwrap() - m).norm() > 4.0 * sigma)
                );
            }
        }
    }
}

#[test]
fn talkers_move_slowly_stay_apart_and_inside_the_region() {
    for (name, seed) in [("paper-linear6", 1), ("uca8", 2), ("two-arrays", 3)] {
        let mut cfg = SimConfig::preset(name, &PresetOptions::default(), seed).unwrap();
        // The whole choreography matters here, not the audio: keep the rendering cheap.
        cfg.sample_rate = 8000;
        for s in &mut cfg.speakers {
            s.speech.phrases = vec![[s.enter_s + 0.1, s.enter_s + 0.3]];
        }
        let scene = sim::simulate(&cfg, seed).unwrap();
        let region = scene.layout.region.unwrap();
        let sources = &scene.truth.as_ref().unwrap().sources;
        for s in sources {
            for w in s.trajectory.windows(2) {
                assert!(w[1].0 - w[0].0 <= 0.0201);
                let v = (w[1].1 - w[0].1).norm() / (w[1].0 - w[0].0);
                assert!(v <= 1.1, "{name} {}: {v} m/s at {}", s.id, w[0].0);
                assert!(
                    region.contains(&w[0].1),
                    "{name} {} leaves the region",
                    s.id
                );
            }
        }
        let mut t = 0.0;
        while t < cfg.duration_s {
            let here: Vec<Vec3> = sources.iter().filter_map(|s| s.position_at(t)).collect();
            for i in 0..here.len() {
                for j in i + 1..here.len() {
                    let d = (here[i] - here[j]).xy().norm();
                    assert!(d > 0.5, "{name}: talkers {d} m apart at {t}");
                }
            }
            t += 0.1;
        }
    }
}

/// A talker standing at `xy` facing `look_at`, turned away during `away`, silent.
fn still_talker(
    xy: [f64; 2],
    look_at: [f64; 2],
    away: Vec<[f64; 2]>,
    phrases: Vec<[f64; 2]>,
) -> SpeakerConfig {
    SpeakerConfig {
        path: vec![[0.0, xy[0], xy[1]]],
        mouth_height_m: 1.6,
        sway_m: 0.0,
        facing: FacingConfig {
            look_at: Some(look_at),
            follow_motion: false,
            away_s: away,
            jitter_deg: 0.0,
        },
        speech: SpeechConfig {
            phrases,
            ..Default::default()
        },
        ..Default::default()
    }
}

#[test]
fn detections_follow_visibility_and_facing() {
    let camera = CameraConfig::default();
    let cam_xy = [camera.position.unwrap()[0], camera.position.unwrap()[1]];
    let mut cfg = SimConfig {
        duration_s: 3.0,
        cameras: vec![camera],
        detector: DetectorConfig {
            detection_probability: 1.0,
            clutter_per_frame: 0.0,
            point_sigma_px: 6.0,
            ..Default::default()
        },
        speakers: vec![
            // In view and facing the camera until it turns away at 1.5 s.
            still_talker([3.4, 3.5], cam_xy, vec![[1.5, 10.0]], vec![[0.2, 1.2]]),
            // Facing the camera but outside the field of view (far left, near the camera wall).
            still_talker([0.4, 0.5], cam_xy, vec![], vec![[0.5, 1.5]]),
        ],
        ..Default::default()
    };
    let scene = sim::simulate(&cfg, 7).unwrap();
    let cam = &scene.layout.cameras[0];
    let truth = &scene.truth.as_ref().unwrap().sources;
    let sigma = 6.0 * cam.height / 1080.0;
    assert_eq!(
        scene.detections.len(),
        45,
        "one frame per 1/15 s, also when empty"
    );
    let hidden = truth[1].position_at(0.5).unwrap();
    assert!(
        !cam.in_view(&hidden),
        "the second talker must be out of view"
    );
    let mut seen = 0;
    for f in &scene.detections {
        if f.t < 1.5 {
            // Exactly the first talker, with its point near the projected mouth.
            assert_eq!(f.boxes.len(), 1, "frame at {}", f.t);
            let mouth = cam.project(&truth[0].position_at(f.t).unwrap()).unwrap();
            let b = f.boxes[0];
            let p = b.point.unwrap();
            assert!(
                (p - mouth).norm() < 4.0 * sigma,
                "point {p:?} vs mouth {mouth:?}"
            );
            assert!(p.x >= b.x && p.x <= b.x + b.w && p.y >= b.y && p.y <= b.y + b.h);
            assert!(b.h > b.w, "a face box is taller than wide");
            assert!((0.5..=1.0).contains(&b.score.unwrap()));
            seen += 1;
        } else if f.t > 2.2 {
            // Turned away (the turn takes about half a second): nobody is detected.
            assert!(f.boxes.is_empty(), "frame at {}: {:?}", f.t, f.boxes);
        }
    }
    assert!(seen >= 22);

    // Missed detections and clutter at the configured rates.
    cfg.duration_s = 6.0;
    cfg.detector.detection_probability = 0.7;
    cfg.detector.clutter_per_frame = 2.0;
    cfg.speakers[0].facing.away_s.clear();
    let scene = sim::simulate(&cfg, 8).unwrap();
    let truth = &scene.truth.as_ref().unwrap().sources;
    let frames = scene.detections.len() as f64;
    let (mut true_hits, mut clutter) = (0.0, 0.0);
    for f in &scene.detections {
        let mouth = cam.project(&truth[0].position_at(f.t).unwrap()).unwrap();
        for b in &f.boxes {
            let p = b.point.unwrap();
            assert!(cam.contains_pixel(&p));
            if (p - mouth).norm() < 5.0 * sigma && b.score.unwrap() > 0.78 {
                true_hits += 1.0;
            } else {
                clutter += 1.0;
            }
        }
    }
    let (pd, rate) = (true_hits / frames, clutter / frames);
    assert!((pd - 0.7).abs() < 0.15, "detection rate {pd}");
    assert!((rate - 2.0).abs() < 0.4, "clutter rate {rate}");
}

#[test]
fn the_facing_direction_decides_detection() {
    // Facing at most max_yaw from the camera is detectable; beyond it is not.
    let cfg = SimConfig {
        duration_s: 1.0,
        detector: DetectorConfig {
            detection_probability: 1.0,
            clutter_per_frame: 0.0,
            ..Default::default()
        },
        speakers: vec![still_talker(
            [3.0, 3.5],
            [0.0, 3.5],
            vec![],
            vec![[0.2, 0.8]],
        )],
        ..Default::default()
    };
    let scene = sim::simulate(&cfg, 1).unwrap();
    let cam = &scene.layout.cameras[0];
    let mouth = scene.truth.as_ref().unwrap().sources[0]
        .position_at(0.5)
        .unwrap();
    let to_cam = cam.centre() - mouth;
    // Looking along -x while the camera is towards -y: about 90 degrees off, beyond 75.
    let yaw = angle_diff(to_cam.y.atan2(to_cam.x), std::f64::consts::PI).abs();
    assert!(yaw.to_degrees() > 80.0);
    assert!(scene.detections.iter().all(|f| f.boxes.is_empty()));
}

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
    let scene = Scene::load(&out).unwrap();
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

    // A missing folder, a folder without enough files, a broken WAV: exit 2 naming the path.
    let missing = dir.path().join("missing");
    expect_input_error(
        &[
            "simulate",
            "--preset",
            "uca8",
            "--duration",
            "1",
            "--speech",
            missing.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        "missing",
    );
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
        "speech",
    );
    std::fs::write(speech.join("c.wav"), "this is not audio").unwrap();
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
        "c.wav",
    );
}
