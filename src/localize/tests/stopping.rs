//! The localiser's activity when a talker stops: what the smoothing remembers and what the
//! probe of a tracked place still hears.

use super::*;

/// A place 1.8 m from the uca8 array at azimuth and elevation `az`, `el` (degrees).
fn talker_place(layout: &Layout, az: f64, el: f64) -> Vec3 {
    layout.arrays[0].centroid() + direction_from_angles(rad(az), rad(el)) * 1.8
}

/// 2 s of white noise from two talkers (place, seed) in free field: the first stops half-way,
/// the second, at amplitude `second_gain`, talks throughout; `noise_seed` drives the sensor noise.
fn one_stops_one_goes_on(
    layout: &Layout,
    first: (Vec3, u64),
    second: (Vec3, u64),
    second_gain: f64,
    noise_seed: u64,
) -> Vec<Vec<f64>> {
    let n = 16 * 2048;
    let mut s1 = synth::white(n, first.1);
    s1[n / 2..].iter_mut().for_each(|v| *v = 0.0);
    let s2: Vec<f64> = synth::white(n, second.1)
        .iter()
        .map(|v| second_gain * v)
        .collect();
    synth::render(
        &layout.arrays[0].mics,
        &[(first.0, &s1), (second.0, &s2)],
        FS,
        C,
        None,
        0.01,
        noise_seed,
    )
}

#[test]
fn a_talker_who_stops_is_no_longer_sounding_though_the_smoothing_remembers_him() {
    // Two talkers for 1 s, then only the second for 1 s. The smoothed maps keep the first in
    // view for a while after he stops (decay 0.9 per frame); his candidates are then no longer
    // sounding, while the second's are throughout.
    let layout = uca_layout();
    let centre = layout.arrays[0].centroid();
    let (p1, p2) = (
        talker_place(&layout, 30.0, 15.0),
        talker_place(&layout, -90.0, 20.0),
    );
    let x = one_stops_one_goes_on(&layout, (p1, 41), (p2, 42), 1.0, 9);
    let cfg = LocalizerConfig {
        search: SearchMode::Directions,
        ..LocalizerConfig::default()
    };
    let mut loc = Localizer::new(&layout, &cfg, 1).unwrap();
    let at = |obs: &ArrayObservation, p: &Vec3| {
        let az = azimuth_of(&(p - centre));
        obs.doas
            .iter()
            .find(|d| angle_diff(d.azimuth, az).abs() < rad(3.0))
            .cloned()
    };
    let mut remembered = 0;
    for (k, o) in run(&mut loc, &x).iter().enumerate() {
        let second =
            at(o, &p2).unwrap_or_else(|| panic!("frame {k}: the second talker is missing"));
        assert!(
            second.sounding,
            "frame {k}: the second talker, fresh {}",
            second.fresh
        );
        let first = at(o, &p1);
        if k < 7 {
            let first = first.unwrap_or_else(|| panic!("frame {k}: the first talker is missing"));
            assert!(
                first.sounding && first.fresh > 10.0,
                "frame {k}: fresh {}",
                first.fresh
            );
        } else if k >= 8
            && let Some(first) = first
        {
            // Frames that start after he stopped.
            remembered += 1;
            assert!(
                !first.sounding,
                "frame {k}: he stopped, fresh {}",
                first.fresh
            );
        }
    }
    assert!(
        remembered >= 2,
        "the smoothing should remember him: {remembered} frames"
    );
}

#[test]
fn the_probe_hears_a_tracked_talker_only_while_he_talks() {
    // The first talker stops half-way; the second talks throughout; nobody is at the third
    // place. Probed at the three places, each frame.
    let layout = uca_layout();
    let (p1, p2, p3) = (
        talker_place(&layout, 30.0, 15.0),
        talker_place(&layout, -90.0, 20.0),
        talker_place(&layout, 150.0, 10.0),
    );
    let x = one_stops_one_goes_on(&layout, (p1, 43), (p2, 44), 0.5, 10);
    let n = x[0].len();
    let cfg = LocalizerConfig {
        search: SearchMode::Directions,
        ..LocalizerConfig::default()
    };
    let min = cfg.peaks.sounding_sigmas;
    let mut loc = Localizer::new(&layout, &cfg, 1).unwrap();
    let frame = loc.frame_size();
    for k in 0..n / frame {
        let spectra = synth::spectra_at(&x, k * frame, frame);
        loc.process(&spectra);
        let f = loc.probe(&[p1, p2, p3]).expect("the circle searches");
        assert!(f[1] >= min, "frame {k}: the second talker reads {}", f[1]);
        assert!(f[2] < min, "frame {k}: the empty place reads {}", f[2]);
        if k < 7 {
            assert!(f[0] >= min, "frame {k}: the first talker reads {}", f[0]);
        } else if k >= 8 {
            assert!(
                f[0] < min,
                "frame {k}: the first talker stopped, reads {}",
                f[0]
            );
        }
    }
    assert_eq!(loc.probe(&[]), Some(Vec::new()));
}
