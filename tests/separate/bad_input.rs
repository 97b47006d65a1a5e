//! Degenerate input: silence, clipping, NaN samples, no targets and more targets than mics.

use avsep::dsp::{Complex, StreamingStft};
use avsep::geometry::Vec3;
use avsep::label::Label;
use avsep::separate::{Separator, SeparatorConfig, Target};

use crate::fixtures::{FS, band_noise, free_field, layout_of, run, static_targets, uca};
use crate::scores::{db, energy, energy_c};
use crate::sim;

/// Feeds raw multichannel samples through the STFT and the separator, returning the outputs.
fn feed(
    sep: &mut Separator,
    channels: &[Vec<f64>],
    targets: &[Target],
) -> Vec<Vec<(Label, Vec<Complex>)>> {
    let g = sep.frame_geometry();
    let mut stft = StreamingStft::new(g, channels.len());
    let mut outs = Vec::new();
    for a in (0..channels[0].len()).step_by(g.hop) {
        let chunk: Vec<&[f64]> = channels.iter().map(|c| &c[a..a + g.hop]).collect();
        outs.push(sep.process(stft.push(&chunk), targets));
    }
    outs
}

fn all_finite(outs: &[Vec<(Label, Vec<Complex>)>]) -> bool {
    outs.iter()
        .flatten()
        .all(|(_, b)| b.iter().all(|v| v.is_finite()))
}

#[test]
fn silent_clipped_and_nan_input_give_finite_output() {
    let centre = Vec3::new(3.0, 2.5, 1.2);
    let positions = vec![
        centre + Vec3::new(1.3, 0.4, 0.3),
        centre + Vec3::new(-0.7, 1.3, 0.2),
        centre + Vec3::new(-0.6, -1.2, 0.1),
    ];
    let mics = uca(8, 0.05, centre);
    let layout = layout_of(&mics);
    let targets = static_targets(&positions, 0.0);
    let n = 512 * 60;
    for kind in ["gsc", "mvdr", "null_steering", "delay_and_sum"] {
        // The targets read silent, so the cancellers adapt on every frame; they must not
        // rest meanwhile.
        let cfg: SeparatorConfig = serde_json::from_str(&format!(
            r#"{{"beamformer": "{kind}", "lifecycle": {{"rest_after_s": 0}}}}"#
        ))
        .unwrap();
        // Silence: exactly silent output.
        let mut sep = Separator::new(&layout, &cfg).unwrap();
        let outs = feed(&mut sep, &vec![vec![0.0; n]; 8], &targets);
        assert!(outs.iter().all(|o| o.len() == 3));
        assert!(
            outs.iter()
                .flatten()
                .all(|(_, b)| b.iter().all(|v| v.norm() == 0.0))
        );
        // Then loud, clipped speech-band noise after the silence (state built on silence).
        let mixture = free_field(
            mics.clone(),
            positions.clone(),
            (0..3)
                .map(|i| band_noise(n, 50 + i).iter().map(|v| v * 400.0).collect())
                .collect(),
        );
        let clipped: Vec<Vec<f64>> = mixture
            .mix
            .iter()
            .map(|c| c.iter().map(|v| v.clamp(-1.0, 1.0)).collect())
            .collect();
        assert!(clipped[0].iter().filter(|v| v.abs() == 1.0).count() > n / 10);
        let outs = feed(&mut sep, &clipped, &targets);
        assert!(
            all_finite(&outs),
            "{kind}: non-finite output on clipped input"
        );
        // NaN and infinite samples in some channels, then whole NaN frames.
        let mut bad = clipped.clone();
        for (c, ch) in bad.iter_mut().enumerate() {
            for (t, v) in ch.iter_mut().enumerate() {
                if (t + c) % 97 == 0 {
                    *v = f64::NAN;
                } else if (t * 3 + c) % 1013 == 0 {
                    *v = f64::INFINITY;
                } else if t > n / 2 && c < 3 {
                    *v = f64::NAN;
                }
            }
        }
        let outs = feed(&mut sep, &bad, &targets);
        assert!(all_finite(&outs), "{kind}: non-finite output on NaN input");
        // And it recovers on clean input.
        let outs = feed(&mut sep, &clipped, &targets);
        assert!(all_finite(&outs));
        let e: f64 = outs.last().unwrap().iter().map(|(_, b)| energy_c(b)).sum();
        assert!(
            e > 0.0 && e.is_finite(),
            "{kind}: no output after recovering"
        );
    }
}

#[test]
fn no_targets_no_output_and_more_targets_than_mics_caps_the_nulls() {
    let centre = Vec3::new(3.0, 2.5, 1.2);
    let mics = uca(4, 0.05, centre);
    let layout = layout_of(&mics);
    let mut sep = Separator::new(&layout, &SeparatorConfig::default()).unwrap();
    let noise: Vec<Vec<f64>> = (0..4).map(|c| sim::white(512 * 10, c)).collect();
    assert!(feed(&mut sep, &noise, &[]).iter().all(|o| o.is_empty()));
    // Six talkers on a four-microphone array: every label still gets a distortionless stream.
    let positions: Vec<Vec3> = (0..6)
        .map(|i| {
            let a = i as f64 * std::f64::consts::PI / 3.0 + 0.2;
            centre + Vec3::new(1.5 * a.cos(), 1.5 * a.sin(), 0.2 + 0.05 * i as f64)
        })
        .collect();
    let n = (1.5 * FS) as usize;
    let mixture = free_field(
        mics,
        positions.clone(),
        (0..6).map(|i| band_noise(n, 60 + i)).collect(),
    );
    for kind in ["gsc", "null_steering"] {
        let mut cfg: SeparatorConfig =
            serde_json::from_str(&format!(r#"{{"beamformer": "{kind}"}}"#)).unwrap();
        cfg.post_filter.kind = avsep::separate::PostFilterKind::None;
        let r = run(&mixture, &cfg, true, |_, _| static_targets(&positions, 1.0));
        let from = (0.2 * FS) as usize;
        for i in 0..6 {
            let truth = &mixture.truth(i)[from..];
            let err: Vec<f64> = r.parts[i][i][from..]
                .iter()
                .zip(truth)
                .map(|(a, b)| a - b)
                .collect();
            let distortion = db(energy(&err) / energy(truth));
            assert!(
                distortion < -30.0,
                "{kind} label {i}: target distorted at {distortion:.1} dB"
            );
            assert!(r.out[i].iter().all(|v| v.is_finite()));
        }
    }
}
