//! A session's clock against frames from a wrong clock.

use super::*;
use crate::geometry::MicArray;
use crate::pipeline::sensor_queue::Timed;
use crate::scene::{DetectionFrame, FaceBox};

/// The protocol tests' four-microphone array and camera; without audio, the array only
/// measures (no channels).
fn layout(audio: bool) -> Layout {
    let l = crate::protocol::inbound::tests::layout();
    if audio {
        return l;
    }
    let array = MicArray::new("a0", l.arrays[0].mics.clone(), Vec::new()).unwrap();
    Layout::new(
        l.sample_rate,
        l.speed_of_sound,
        vec![array],
        l.cameras.clone(),
        None,
    )
    .unwrap()
}

fn frame(t: f64) -> DetectionFrame {
    DetectionFrame {
        t,
        camera: 0,
        boxes: vec![FaceBox {
            x: 300.0,
            y: 200.0,
            w: 40.0,
            h: 50.0,
            score: None,
            point: None,
        }],
    }
}

#[test]
fn a_frame_from_far_ahead_is_refused_and_the_camera_goes_on() {
    // Without audio the cameras are the clock: a frame a billion seconds ahead would have the
    // session step through 30 years of empty time, and lock the camera out after it.
    let mut p = Pipeline::new(layout(false), PipelineConfig::default(), 1).unwrap();
    for i in 0..10 {
        p.push_detections(frame(0.125 * f64::from(i))).unwrap();
    }
    let steps = p.stats().steps;
    let e = p.push_detections(frame(1e9)).unwrap_err();
    assert_eq!((e.code, e.field.as_str()), ("too_early", "t"));
    assert!(e.message.contains("max_lead_s"), "{e}");
    assert_eq!(p.stats().steps, steps, "no step ran for the refused frame");
    // The camera's next frame in time is taken, and frames walk the clock on as before.
    p.push_detections(frame(1.25)).unwrap();
    p.push_detections(frame(1.25 + 9.0)).unwrap();
    assert!(p.stats().steps > steps);
    assert_eq!(
        p.push_detections(frame(40.0)).unwrap_err().code,
        "too_early"
    );
}

#[test]
fn with_audio_the_lead_is_measured_from_the_audio_received() {
    let cfg = PipelineConfig {
        max_lead_s: 2.0,
        ..PipelineConfig::default()
    };
    let mut p = Pipeline::new(layout(true), cfg, 1).unwrap();
    p.push_audio(0, 4, &vec![0.0; 4 * 16_000]).unwrap();
    // One second of audio received: frames up to 3 s are held for it, later ones refused.
    p.push_detections(frame(2.9)).unwrap();
    let e = p.push_detections(frame(3.1)).unwrap_err();
    assert_eq!((e.code, e.field.as_str()), ("too_early", "t"));
    // Frames accepted ahead do not move the present: audio does.
    let e = p.push_detections(frame(4.5)).unwrap_err();
    assert_eq!(e.code, "too_early");
    p.push_audio(16_000, 4, &vec![0.0; 4 * 48_000]).unwrap();
    p.push_detections(frame(4.5)).unwrap();
}

#[test]
fn frames_past_the_backlog_are_refused_until_the_audio_takes_them() {
    // A client that sets a long lead and floods frames within it holds only the backlog.
    let cfg = PipelineConfig {
        max_lead_s: 3600.0,
        ..PipelineConfig::default()
    };
    let mut p = Pipeline::new(layout(true), cfg, 1).unwrap();
    let held = frame(0.0).held_bytes();
    p.limit_backlog(10 * held);
    p.push_audio(0, 4, &vec![0.0; 4 * 4_096]).unwrap();
    for i in 0..10 {
        p.push_detections(frame(1.0 + 0.01 * f64::from(i))).unwrap();
    }
    let e = p.push_detections(frame(1.2)).unwrap_err();
    assert_eq!((e.code, e.field.as_str()), ("backlog_full", "t"));
    assert!(e.message.contains("limits.sensor_backlog_bytes"), "{e}");
    let rejected = p.stats().rejected;
    // Once the audio passes them, their steps take the frames and new ones are accepted.
    p.push_audio(4_096, 4, &vec![0.0; 4 * 32_000]).unwrap();
    p.push_detections(frame(3.0)).unwrap();
    assert_eq!(p.stats().rejected, rejected);
    assert_eq!(p.stats().detection_frames_in, 11);
}

/// The tracks of two seconds of one face and silence, after `change` (refused or not).
fn tracks_after(change: Option<(PipelineConfig, bool)>) -> String {
    let mut p = Pipeline::new(layout(true), PipelineConfig::default(), 1).unwrap();
    if let Some((cfg, accepted)) = change {
        let r = p.update_config(cfg);
        assert_eq!(r.is_ok(), accepted, "{r:?}");
        if let Err(e) = r {
            assert_eq!(e.field, "separate.null_loading");
        }
    }
    let mut events = Vec::new();
    for i in 0..16u32 {
        events.extend(p.push_detections(frame(0.125 * f64::from(i))).unwrap());
        let first = u64::from(i) * 2000;
        events.extend(p.push_audio(first, 4, &vec![0.0; 4 * 2000]).unwrap());
    }
    events.extend(p.finish());
    let tracks: Vec<_> = events
        .iter()
        .filter(|e| matches!(e, PipelineEvent::Tracks { .. }))
        .collect();
    assert!(!tracks.is_empty());
    format!("{tracks:?}")
}

#[test]
fn a_refused_settings_change_changes_nothing() {
    // The camera's noise alone changes the tracks; refused with an invalid separator setting,
    // it must not reach the tracker either.
    let mut noisier = PipelineConfig::default();
    noisier.track.camera.noise_std_px = 77.0;
    let untouched = tracks_after(None);
    assert_ne!(tracks_after(Some((noisier.clone(), true))), untouched);
    let mut refused = noisier;
    refused.separate.null_loading = -1.0;
    assert_eq!(tracks_after(Some((refused, false))), untouched);
}

/// A camera frame at `t` with `n` face-sized boxes scattered over the 640 x 480 image, none in
/// the same place twice (the frame index `i` moves them).
fn scattered_frame(t: f64, i: u32, n: u32) -> DetectionFrame {
    let boxes = (0..n)
        .map(|b| {
            let k = f64::from(i * n + b);
            FaceBox {
                x: (k * 173.3) % 580.0,
                y: (k * 97.1) % 400.0,
                w: 40.0,
                h: 50.0,
                score: None,
                point: None,
            }
        })
        .collect();
    DetectionFrame {
        t,
        camera: 0,
        boxes,
    }
}

/// The camera's clutter rate, configured and estimated.
fn camera_clutter(p: &Pipeline) -> (f64, f64) {
    let c = p.clutter_rates().into_iter().find(|c| c.sensor == "cam0");
    c.map(|c| (c.configured, c.estimated)).unwrap()
}

#[test]
fn clutter_estimation_changes_on_a_live_session() {
    let mut p = Pipeline::new(layout(false), PipelineConfig::default(), 1).unwrap();
    let feed = |p: &mut Pipeline, from: u32, to: u32| {
        for i in from..to {
            p.push_detections(scattered_frame(0.125 * f64::from(i), i, 12))
                .unwrap();
        }
    };
    feed(&mut p, 0, 40);
    let (configured, noisy) = camera_clutter(&p);
    assert!(noisy > 5.0 * configured, "{noisy} against {configured}");

    // A new time constant keeps the running estimate.
    let mut cfg = p.config().clone();
    cfg.track.clutter.time_constant_s = 1.0;
    p.update_config(cfg.clone()).unwrap();
    assert_eq!(camera_clutter(&p).1, noisy);

    // Turned off, the camera is back on its configured rate and stays there.
    cfg.track.clutter.estimate = false;
    p.update_config(cfg.clone()).unwrap();
    assert_eq!(camera_clutter(&p), (configured, configured));
    feed(&mut p, 40, 60);
    assert_eq!(camera_clutter(&p), (configured, configured));

    // Turned on again, it learns the noisy detector anew.
    cfg.track.clutter.estimate = true;
    p.update_config(cfg).unwrap();
    feed(&mut p, 60, 100);
    assert!(camera_clutter(&p).1 > 5.0 * configured);
}

#[test]
fn a_message_longer_than_the_history_is_processed_whole() {
    // Three seconds in one message, against the same audio in 1,024-sample blocks: the history
    // holds a few steps, so the intake must run each step before the next one's audio comes.
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let samples: Vec<f32> = (0..4 * 48_000)
        .map(|_| rng.random_range(-0.5..0.5))
        .collect();
    let run = |blocks: &[&[f32]]| {
        let mut p = Pipeline::new(layout(true), PipelineConfig::default(), 1).unwrap();
        let mut events = Vec::new();
        let mut at = 0;
        for b in blocks {
            events.extend(p.push_audio(at, 4, b).unwrap());
            at += (b.len() / 4) as u64;
        }
        (events, p.stats().steps)
    };
    let (whole, steps) = run(&[&samples]);
    let blocks: Vec<&[f32]> = samples.chunks(4 * 1024).collect();
    let (pieces, _) = run(&blocks);
    // Every step of the three seconds but the last, which waits for the camera.
    assert_eq!(steps, 22);
    let warned = |e: &PipelineEvent| matches!(e, PipelineEvent::Warning { .. });
    assert!(!whole.iter().any(warned), "{whole:?}");
    assert_eq!(whole, pieces);
}

#[test]
fn a_long_camera_wait_keeps_the_audio_its_steps_wait_with() {
    // A second of camera wait is eight steps: the history grows to hold their audio, also when
    // the wait is raised on a running session.
    let samples = vec![0.01f32; 4 * 48_000];
    for live in [false, true] {
        let wait = PipelineConfig {
            camera_wait_s: 1.0,
            ..PipelineConfig::default()
        };
        let first = if live {
            PipelineConfig::default()
        } else {
            wait.clone()
        };
        let mut p = Pipeline::new(layout(true), first, 1).unwrap();
        if live {
            p.update_config(wait).unwrap();
        }
        let mut events = Vec::new();
        for (i, b) in samples.chunks(4 * 1024).enumerate() {
            events.extend(p.push_audio(1024 * i as u64, 4, b).unwrap());
        }
        // The camera never reports: steps ending by 2 s have waited their second.
        assert_eq!(p.stats().steps, 15);
        let warned = |e: &PipelineEvent| matches!(e, PipelineEvent::Warning { .. });
        assert!(!events.iter().any(warned), "{events:?}");
    }
}
