//! Labels that are never heard (a poster's faces, false detections) rest: their streams fall
//! silent and stop competing with the talkers; a resting label that speaks wakes.

use avsep::geometry::Vec3;
use avsep::separate::{Separator, SeparatorConfig, Target};

use crate::fixtures::{FS, Quiet, band_noise, free_field, layout_of, run, static_targets, uca};
use crate::scores::{db, energy};

fn max_step(x: &[f64]) -> f64 {
    x.windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0, f64::max)
}

fn error_db(x: &[f64], want: &[f64]) -> f64 {
    let err: Vec<f64> = x.iter().zip(want).map(|(x, y)| x - y).collect();
    db(energy(&err) / energy(want))
}

/// One talker and ten silent faces around an 8-microphone array; at 2 s one face starts to
/// talk. With resting, the silent faces' streams fall silent, the talker keeps his whole
/// signal instead of sharing his bins with eleven labels, and the face that talks wakes
/// without a click and carries its own voice as if the other faces were not there.
#[test]
fn silent_labels_rest_and_a_label_that_speaks_wakes() {
    let centre = Vec3::new(3.0, 2.5, 1.2);
    let n = (3.5 * FS) as usize;
    let wake_at = 2.0;
    let (talker, waker) = (0, 4);
    let positions: Vec<Vec3> = (0..11)
        .map(|i| {
            let a = 2.0 * std::f64::consts::PI * f64::from(i) / 11.0;
            centre + Vec3::new(1.5 * a.cos(), 1.5 * a.sin(), 0.3)
        })
        .collect();
    let signals: Vec<Vec<f64>> = (0..11)
        .map(|i| match i {
            i if i == talker => band_noise(n, 3),
            i if i == waker => {
                let mut x = band_noise(n, 5);
                x[..(wake_at * FS) as usize].fill(0.0);
                x
            }
            _ => vec![0.0; n],
        })
        .collect();
    let mixture = free_field(uca(8, 0.05, centre), positions.clone(), signals);
    let targets = |t: f64| -> Vec<Target> {
        let mut ts = static_targets(&positions, 0.0);
        ts[talker].speaking = 1.0;
        ts[waker].speaking = if t >= wake_at { 1.0 } else { 0.0 };
        ts
    };
    let mut cfg = SeparatorConfig::default();
    cfg.lifecycle.rest_after_s = 0.5;
    let frame = cfg.frame as f64 / FS;
    let rested = run(&mixture, &cfg, false, |_, t| targets(t));
    cfg.lifecycle.rest_after_s = 0.0;
    let awake = run(&mixture, &cfg, false, |_, t| targets(t));

    // Unheard for 0.5 s, then a 64 ms fade: from 0.7 s to the wake's frame (64 ms long) the
    // faces are silent.
    let (a, b) = ((0.7 * FS) as usize, ((wake_at - frame) * FS) as usize);
    for (i, out) in rested.out.iter().enumerate() {
        if i != talker {
            assert!(
                out[a..b].iter().all(|v| *v == 0.0),
                "label {i} is not silent while resting"
            );
        }
    }
    let silent_awake = (0..11)
        .filter(|&i| i != talker)
        .map(|i| energy(&awake.out[i][a..b]))
        .sum::<f64>();
    assert!(silent_awake > 0.0, "without resting the faces carry sound");

    // The talker's output against his image at the reference microphone, between the rest
    // and the wake: with eleven labels each face's claim takes part of his bins.
    let truth = mixture.truth(talker);
    let with = error_db(&rested.out[talker][a..b], &truth[a..b]);
    let without = error_db(&awake.out[talker][a..b], &truth[a..b]);
    println!("talker's error: {with:.1} dB resting, {without:.1} dB without");
    assert!(with < -20.0, "talker's error {with:.1} dB with resting");
    assert!(
        with < without - 6.0,
        "resting gained only {:.1} dB",
        without - with
    );

    // The face that talks wakes: its stream fades in without a click and carries its voice.
    let woken = &rested.out[waker];
    let step = max_step(woken);
    let input_step = max_step(&mixture.mix[0]);
    assert!(step <= 1.5 * input_step, "click of {step} at the wake");
    let (c, d) = (((wake_at + 0.5) * FS) as usize, n);
    // As well as in a room with the two talkers alone (two noises 131 degrees apart, which a
    // 10 cm array separates only partly below 1 kHz).
    let pair = run(&mixture, &cfg, false, |_, t| {
        let ts = targets(t);
        vec![ts[talker].clone(), ts[waker].clone()]
    });
    let truth = mixture.truth(waker);
    let e = error_db(&woken[c..d], &truth[c..d]);
    let alone = error_db(&pair.out[waker][c..d], &truth[c..d]);
    println!("woken label's error: {e:.1} dB, {alone:.1} dB with the two talkers alone");
    assert!(e < alone + 1.0, "woken label's error {e:.1} dB");
    assert!(e < -3.0, "woken label's error {e:.1} dB");
}

/// With `max_streams` 2: a resting label gives its state up to a new label, cannot wake while
/// two running labels hold the streams, and takes the state of the next one that rests.
#[test]
fn at_the_stream_cap_a_new_label_takes_a_resting_labels_state() {
    let centre = Vec3::new(3.0, 2.5, 1.2);
    let mics = uca(8, 0.05, centre);
    let mut cfg = SeparatorConfig::default();
    cfg.lifecycle.max_streams = 2;
    cfg.lifecycle.rest_after_s = 0.3;
    let mut sep = Separator::new(&layout_of(&mics), &cfg).unwrap();
    let hop = sep.frame_geometry().hop as f64;
    let mut quiet = Quiet::new(&sep, mics.len());
    let mut run_for = |sep: &mut Separator, targets: &[Target], s: f64| {
        quiet.feed(sep, targets, (s * FS / hop).round() as usize);
    };
    let spots: Vec<Vec3> = (0..3)
        .map(|i| centre + Vec3::new(1.5, -1.0 + 0.8 * f64::from(i), 0.2))
        .collect();
    let all = static_targets(&spots, 0.0);
    let (a, b, c) = (all[0].label, all[1].label, all[2].label);
    let mut heard = all.clone();
    heard[0].speaking = 1.0;
    // B is never heard: after 0.3 s and its fade it rests, keeping its state.
    run_for(&mut sep, &heard[..2], 0.5);
    assert_eq!(sep.resting_labels(), [b]);
    // C is born at the cap: it takes B's state; B stays, resting.
    run_for(&mut sep, &heard, 0.1);
    assert_eq!(sep.labels(), [a, c, b]);
    assert_eq!(sep.resting_labels(), [b]);
    // B speaks, but A and C hold both streams: it waits until C, unheard, rests too.
    heard[1].speaking = 1.0;
    run_for(&mut sep, &heard, 0.1);
    assert_eq!(sep.resting_labels(), [b]);
    run_for(&mut sep, &heard, 0.4);
    assert_eq!(sep.labels(), [a, b, c]);
    assert_eq!(sep.resting_labels(), [c]);
}
