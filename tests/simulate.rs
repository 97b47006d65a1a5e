//! Behaviour of the room simulator: the truth identity and SNR, determinism, speech timing and
//! the talkers' choreography here; detections and the command line in the submodules.

#[path = "simulate/cli.rs"]
mod cli;
#[path = "simulate/detections.rs"]
mod detections;

use avsep::geometry::Vec3;
use avsep::scene::Scene;
use avsep::scene::sim::{self, PresetOptions, SimConfig};

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

pub fn active_mask(len: usize, active: &[(f64, f64)], fs: f64) -> Vec<bool> {
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
