//! Behaviour of the localiser on synthetic sources at known places.

use super::synth::{self, Room};
use super::*;
use crate::geometry::{angle_diff, deg, direction_from_angles, rad};

mod stopping;

const FS: f64 = 16000.0;
const C: f64 = 343.0;

fn settings(smoothing: f64) -> gcc::GccSettings {
    gcc::GccSettings {
        interpolation: 10,
        beta: 1.0,
        smoothing,
        subband_bins: 8,
    }
}

fn angle_between(a: &Vec3, b: &Vec3) -> f64 {
    deg(a.normalize().dot(&b.normalize()).clamp(-1.0, 1.0).acos())
}

/// Runs the localiser over every frame of `signals` and returns the observations of array 0.
fn run(loc: &mut Localizer, signals: &[Vec<f64>]) -> Vec<ArrayObservation> {
    let frame = loc.frame_size();
    let mut out = Vec::new();
    let mut start = 0;
    while start + frame <= signals[0].len() {
        let spectra = synth::spectra_at(signals, start, frame);
        out.push(loc.process(&spectra).remove(0));
        start += frame;
    }
    out
}

#[test]
fn gcc_peaks_at_tau_a_minus_tau_b() {
    // Mic 0 at the origin, mic 1 20 cm along +x; a source on the +x side reaches mic 1 first, so
    // tau_0 - tau_1 > 0 and the GCC of pair (0, 1) must peak at that positive lag.
    let array = MicArray::new(
        "a",
        vec![Vec3::zeros(), Vec3::new(0.2, 0.0, 0.0)],
        vec![0, 1],
    )
    .unwrap();
    for src in [Vec3::new(3.0, 1.0, 0.5), Vec3::new(-2.0, 2.5, 0.0)] {
        let expect = array.tdoa(&src, 0, 1, C);
        let sig = synth::white(8192, 3);
        let x = synth::render(&array.mics, &[(src, &sig)], FS, C, None, 0.0, 1);
        let spectra = synth::spectra_at(&x, 2048, 2048);
        let mut bank = gcc::GccBank::new(&array, 2048, (128, 256), settings(0.0), FS, C);
        bank.whiten(&spectra);
        bank.compute();
        let p = bank.pairs[0];
        let table = &bank.table[p.offset..p.offset + 2 * p.half + 1];
        let argmax = (0..table.len())
            .max_by(|&i, &j| table[i].total_cmp(&table[j]))
            .unwrap();
        let lag = (argmax as f64 - p.half as f64) / bank.steps_per_second;
        assert!(
            (lag - expect).abs() < 0.15 / FS,
            "peak at {lag} s, expected {expect} s"
        );
        assert!(table[argmax] > 0.9, "coherent pair peak {}", table[argmax]);
    }
}

#[test]
fn smoothed_cross_spectra_weigh_past_frames_and_forget_them() {
    // Frame 1 has a source at one lag, frame 2 one at another: with decay 0.5 the GCC of
    // frame 2 is 2/3 of a coherent peak at the new lag and 1/3 at the old one; after forget()
    // only the new lag remains.
    let array = MicArray::new(
        "a",
        vec![Vec3::zeros(), Vec3::new(0.2, 0.0, 0.0)],
        vec![0, 1],
    )
    .unwrap();
    let (s1, s2) = (Vec3::new(3.0, 0.5, 0.0), Vec3::new(-3.0, 0.8, 0.0));
    let sig = synth::white(4096, 5);
    let frame = |src: &Vec3| {
        let x = synth::render(&array.mics, &[(*src, &sig)], FS, C, None, 0.0, 1);
        synth::spectra_at(&x, 2048, 2048)
    };
    let (f1, f2) = (frame(&s1), frame(&s2));
    let at = |bank: &gcc::GccBank, src: &Vec3| {
        let p = bank.pairs[0];
        let pos =
            p.offset as f64 + p.half as f64 + array.tdoa(src, 0, 1, C) * bank.steps_per_second;
        gcc::lerp(&bank.table, pos)
    };
    let mut bank = gcc::GccBank::new(&array, 2048, (128, 640), settings(0.5), FS, C);
    bank.whiten(&f1);
    bank.compute();
    assert!(at(&bank, &s1) > 0.95);
    bank.whiten(&f2);
    bank.compute();
    let (old, new) = (at(&bank, &s1), at(&bank, &s2));
    assert!((new - 2.0 / 3.0).abs() < 0.05, "new lag {new}");
    assert!((old - 1.0 / 3.0).abs() < 0.05, "old lag {old}");
    bank.forget();
    bank.whiten(&f2);
    bank.compute();
    assert!(at(&bank, &s2) > 0.95 && at(&bank, &s1).abs() < 0.1);
}

#[test]
fn interpolated_gcc_matches_the_exact_band_sum() {
    let array = MicArray::new(
        "a",
        vec![Vec3::zeros(), Vec3::new(0.1, 0.03, 0.0)],
        vec![0, 1],
    )
    .unwrap();
    let sig = synth::white(8192, 5);
    let x = synth::render(
        &array.mics,
        &[(Vec3::new(1.0, 2.0, 0.3), &sig)],
        FS,
        C,
        None,
        0.05,
        2,
    );
    let spectra = synth::spectra_at(&x, 1024, 2048);
    let band = (128, 320);
    let mut bank = gcc::GccBank::new(&array, 2048, band, settings(0.0), FS, C);
    bank.whiten(&spectra);
    bank.compute();
    let white = |ch: usize| -> Vec<crate::dsp::Complex> {
        spectra.channel(ch)[band.0..=band.1]
            .iter()
            .map(|y| y / y.norm())
            .collect()
    };
    let (wa, wb) = (white(0), white(1));
    let p = bank.pairs[0];
    for j in (0..=2 * p.half).step_by(7) {
        let tau = (j as f64 - p.half as f64) / 10.0;
        let exact = gcc::direct_gcc(&wa, &wb, band, 2048, tau);
        let got = bank.table[p.offset + j];
        assert!((got - exact).abs() < 2e-3, "lag {tau}: {got} vs {exact}");
    }
}

fn uca_layout() -> Layout {
    synth::layout(
        vec![synth::uca(8, 0.05, Vec3::new(3.0, 2.5, 1.0), 0, "uca8")],
        Some(synth::room_box()),
    )
}

#[test]
fn uca8_finds_sources_at_known_directions() {
    let layout = uca_layout();
    let centre = layout.arrays[0].centroid();
    let cfg = LocalizerConfig {
        search: SearchMode::Directions,
        ..LocalizerConfig::default()
    };
    let mut worst: f64 = 0.0;
    for (i, &(az, el)) in [
        (10.0, 20.0),
        (75.0, 5.0),
        (160.0, 35.0),
        (-100.0, 15.0),
        (-30.0, 60.0),
    ]
    .iter()
    .enumerate()
    {
        let src = centre + direction_from_angles(rad(az), rad(el)) * 2.0;
        let sig = synth::white(6144, 10 + i as u64);
        let x = synth::render(&layout.arrays[0].mics, &[(src, &sig)], FS, C, None, 0.01, 7);
        let mut loc = Localizer::new(&layout, &cfg, 1).unwrap();
        for obs in run(&mut loc, &x) {
            let best = &obs.doas[0];
            let err = angle_between(&best.direction, &(src - centre));
            worst = worst.max(err);
            assert!(
                err < 2.0,
                "az {az} el {el}: found az {} el {} ({err} deg off)",
                deg(best.azimuth),
                deg(best.elevation)
            );
            assert!(angle_diff(best.azimuth, rad(az)).abs() < rad(1.5));
            assert!(best.power > 0.5 && best.power <= 1.0);
        }
    }
    eprintln!("uca8 worst direction error {worst:.2} deg");
}

#[test]
fn uca8_finds_a_speech_like_source_in_a_reverberant_room() {
    let layout = uca_layout();
    let centre = layout.arrays[0].centroid();
    let cfg = LocalizerConfig {
        search: SearchMode::Directions,
        ..LocalizerConfig::default()
    };
    let room = Room {
        bounds: synth::room_box(),
        reflection: 0.7,
    };
    let src = Vec3::new(4.2, 4.0, 1.6);
    let sig = synth::harmonic(16384, 140.0, FS, 2);
    let x = synth::render(
        &layout.arrays[0].mics,
        &[(src, &sig)],
        FS,
        C,
        Some(&room),
        0.005,
        3,
    );
    let mut loc = Localizer::new(&layout, &cfg, 1).unwrap();
    for obs in run(&mut loc, &x) {
        let az = azimuth_of(&(src - centre));
        assert!(
            obs.doas
                .iter()
                .any(|d| angle_diff(d.azimuth, az).abs() < rad(3.0)),
            "{:?}",
            obs.doas
        );
        assert!(angle_diff(obs.doas[0].azimuth, az).abs() < rad(3.0));
    }
}

#[test]
fn uca8_finds_two_simultaneous_sources() {
    let layout = uca_layout();
    let centre = layout.arrays[0].centroid();
    let cfg = LocalizerConfig {
        search: SearchMode::Directions,
        ..LocalizerConfig::default()
    };
    let truths = [(40.0, 15.0), (-80.0, 25.0)];
    let sources: Vec<(Vec3, Vec<f64>)> = truths
        .iter()
        .enumerate()
        .map(|(i, &(az, el))| {
            (
                centre + direction_from_angles(rad(az), rad(el)) * 1.8,
                synth::white(10240, 30 + i as u64),
            )
        })
        .collect();
    let refs: Vec<(Vec3, &[f64])> = sources.iter().map(|(p, s)| (*p, s.as_slice())).collect();
    let x = synth::render(&layout.arrays[0].mics, &refs, FS, C, None, 0.01, 8);
    let mut loc = Localizer::new(&layout, &cfg, 1).unwrap();
    for obs in run(&mut loc, &x) {
        for (p, _) in &sources {
            let az = azimuth_of(&(p - centre));
            assert!(
                obs.doas
                    .iter()
                    .any(|d| angle_diff(d.azimuth, az).abs() < rad(3.0)),
                "source at az {} missing from {:?}",
                deg(az),
                obs.doas.iter().map(|d| deg(d.azimuth)).collect::<Vec<_>>()
            );
        }
    }
}

/// Eight microphones on the corners of a 40 cm cube: a compact volumetric array.
fn cube_layout() -> Layout {
    let c = Vec3::new(3.0, 2.5, 1.2);
    let mics = (0..8)
        .map(|i| {
            let s = |bit: usize| if i & bit == 0 { -0.2 } else { 0.2 };
            c + Vec3::new(s(1), s(2), s(4))
        })
        .collect();
    synth::layout(
        vec![MicArray::new("cube", mics, (0..8).collect()).unwrap()],
        Some(synth::room_box()),
    )
}

#[test]
fn src_finds_a_source_at_its_position() {
    let layout = cube_layout();
    let centre = layout.arrays[0].centroid();
    let cfg = LocalizerConfig {
        search: SearchMode::Positions,
        ..LocalizerConfig::default()
    };
    for (i, src) in [Vec3::new(2.2, 1.9, 1.6), Vec3::new(4.1, 3.2, 0.9)]
        .iter()
        .enumerate()
    {
        let sig = synth::white(8192, 50 + i as u64);
        let x = synth::render(
            &layout.arrays[0].mics,
            &[(*src, &sig)],
            FS,
            C,
            None,
            0.002,
            9,
        );
        let mut loc = Localizer::new(&layout, &cfg, 7).unwrap();
        for obs in run(&mut loc, &x) {
            let p = obs.points[0].position;
            let ray = (src - centre).normalize();
            let across = ((p - centre) - ray * (p - centre).dot(&ray)).norm();
            let along = (p - src).dot(&ray);
            eprintln!("cube: across {across:.3} m, along {along:.3} m");
            assert!(
                across < 0.03,
                "found {p:?}, {across} m off the source direction"
            );
            assert!(along.abs() < 0.25, "found {p:?}, {along} m off in range");
        }
    }
}

#[test]
fn auto_search_finds_positions_only_for_the_arrays_that_want_them() {
    let a0 = synth::uca(8, 0.05, Vec3::new(1.0, 1.0, 0.8), 0, "a0");
    let a1 = synth::uca(8, 0.05, Vec3::new(5.0, 1.5, 0.9), 8, "a1");
    let layout = synth::layout(vec![a0, a1], Some(synth::room_box()));
    let sig = synth::white(4096, 61);
    let mics: Vec<Vec3> = layout.arrays.iter().flat_map(|a| a.mics.clone()).collect();
    let x = synth::render(
        &mics,
        &[(Vec3::new(3.0, 3.5, 1.7), &sig)],
        FS,
        C,
        None,
        0.002,
        11,
    );
    let spectra = synth::spectra_at(&x, 2048, 2048);
    let auto = LocalizerConfig::default();
    assert_eq!(auto.search, SearchMode::Auto);
    let both = LocalizerConfig {
        search: SearchMode::Both,
        ..LocalizerConfig::default()
    };
    let mut loc_auto = Localizer::new(&layout, &auto, 3).unwrap();
    loc_auto.use_positions(&[false, true]);
    let mut loc_both = Localizer::new(&layout, &both, 3).unwrap();
    let (oa, ob) = (loc_auto.process(&spectra), loc_both.process(&spectra));
    assert!(oa[0].points.is_empty() && !oa[1].points.is_empty());
    // Directions do not depend on whether positions were searched.
    for (a, b) in oa.iter().zip(&ob) {
        assert!(!a.doas.is_empty());
        assert_eq!(a.doas, b.doas);
    }
}

#[test]
fn two_arrays_each_find_the_source_direction_in_3d() {
    // Two UCAs: each array localises on its own (no pairs across arrays); the position candidate
    // of each must lie on the ray from its centroid to the source (a 10 cm array hardly observes
    // range).
    let a0 = synth::uca(8, 0.05, Vec3::new(1.0, 1.0, 0.8), 0, "a0");
    let a1 = synth::uca(8, 0.05, Vec3::new(5.0, 1.5, 0.9), 8, "a1");
    let layout = synth::layout(vec![a0, a1], Some(synth::room_box()));
    let cfg = LocalizerConfig {
        search: SearchMode::Both,
        ..LocalizerConfig::default()
    };
    let src = Vec3::new(3.0, 3.5, 1.7);
    let sig = synth::white(6144, 60);
    let mics: Vec<Vec3> = layout.arrays.iter().flat_map(|a| a.mics.clone()).collect();
    let x = synth::render(&mics, &[(src, &sig)], FS, C, None, 0.002, 10);
    let mut loc = Localizer::new(&layout, &cfg, 3).unwrap();
    let mut start = 0;
    while start + 2048 <= x[0].len() {
        let obs = loc.process(&synth::spectra_at(&x, start, 2048));
        assert_eq!(obs.len(), 2);
        for o in &obs {
            let c = layout.arrays[o.array].centroid();
            let ray = (src - c).normalize();
            let p = o.points[0].position - c;
            // The direction of the point is what a 10 cm array observes; 1 degree is 5 cm at
            // the source's 3 m range.
            let err = angle_between(&p, &ray);
            eprintln!(
                "two arrays: array {} point direction off by {err:.2} deg, range {:.2} m (true {:.2})",
                o.array,
                p.norm(),
                (src - c).norm()
            );
            assert!(
                err < 1.5,
                "array {} point {:?} off the source direction by {err} deg",
                o.array,
                o.points[0].position
            );
            assert!(angle_between(&o.doas[0].direction, &ray) < 2.0);
        }
        start += 2048;
    }
}

#[test]
fn linear_array_reports_the_cone_angle() {
    let mics: Vec<Vec3> = (0..6)
        .map(|i| Vec3::new(2.5 + 0.05 * i as f64, 4.9, 2.0))
        .collect();
    let array = MicArray::new("lin", mics, (0..6).collect()).unwrap();
    let layout = synth::layout(vec![array.clone()], Some(synth::room_box()));
    let centre = array.centroid();
    let cfg = LocalizerConfig {
        search: SearchMode::Directions,
        ..LocalizerConfig::default()
    };
    let src = Vec3::new(4.0, 2.0, 1.5);
    let sig = synth::white(4096, 70);
    let x = synth::render(&array.mics, &[(src, &sig)], FS, C, None, 0.005, 11);
    let mut loc = Localizer::new(&layout, &cfg, 1).unwrap();
    let truth_cone = deg((src - centre).normalize().x.acos());
    for obs in run(&mut loc, &x) {
        let d = obs.doas[0].direction;
        let cone = deg(d.x.acos());
        assert!(
            (cone - truth_cone).abs() < 2.0,
            "cone {cone} vs {truth_cone}"
        );
        // The representative points from the array towards the room's centre side (-y, down).
        let towards = synth::room_box().center() - centre;
        assert!(d.dot(&towards) > 0.0);
    }
}

#[test]
fn silence_gives_nothing_and_noise_gives_low_activity() {
    let layout = uca_layout();
    let mut loc = Localizer::new(&layout, &LocalizerConfig::default(), 1).unwrap();
    let silent = MultiSpectrum::zeros(8, 1025);
    for _ in 0..3 {
        let obs = loc.process(&silent);
        assert_eq!(obs.len(), 1);
        assert!(obs[0].doas.is_empty() && obs[0].points.is_empty());
        assert_eq!(obs[0].activity, 0.0);
    }
    // Uncorrelated sensor noise, then a source switching on over the same noise.
    let centre = layout.arrays[0].centroid();
    let n = 2048 * 12;
    let mut sig = vec![0.0; n];
    let speech = synth::harmonic(n / 2, 120.0, FS, 4);
    sig[n / 2..].copy_from_slice(&speech);
    let src = centre + direction_from_angles(rad(30.0), rad(20.0)) * 1.5;
    let x = synth::render(
        &layout.arrays[0].mics,
        &[(src, &sig)],
        FS,
        C,
        None,
        0.002,
        13,
    );
    let obs = run(&mut loc, &x);
    for o in &obs[..5] {
        assert!(o.activity < 0.1, "noise activity {}", o.activity);
    }
    for o in &obs[7..] {
        assert!(o.activity > 0.8, "speech activity {}", o.activity);
        assert!(!o.doas.is_empty());
    }
}

#[test]
fn non_finite_and_clipped_input_never_produce_nan() {
    let layout = uca_layout();
    let mut loc = Localizer::new(&layout, &LocalizerConfig::default(), 1).unwrap();
    let mut nan = MultiSpectrum::zeros(8, 1025);
    for ch in 0..8 {
        for (k, v) in nan.channel_mut(ch).iter_mut().enumerate() {
            *v = match k % 3 {
                0 => crate::dsp::Complex::new(f64::NAN, 1.0),
                1 => crate::dsp::Complex::new(f64::INFINITY, 0.0),
                _ => crate::dsp::Complex::new(0.0, f64::NEG_INFINITY),
            };
        }
    }
    let obs = loc.process(&nan);
    assert!(obs[0].doas.is_empty() && obs[0].points.is_empty());
    assert_eq!(obs[0].activity, 0.0);
    // Hard-clipped loud source: candidates stay finite.
    let centre = layout.arrays[0].centroid();
    let sig: Vec<f64> = synth::white(4096, 14).iter().map(|v| v * 50.0).collect();
    let src = centre + direction_from_angles(rad(-60.0), rad(10.0)) * 2.0;
    let x: Vec<Vec<f64>> =
        synth::render(&layout.arrays[0].mics, &[(src, &sig)], FS, C, None, 0.0, 1)
            .into_iter()
            .map(|ch| ch.into_iter().map(|v| v.clamp(-1.0, 1.0)).collect())
            .collect();
    for o in run(&mut loc, &x) {
        assert!(o.activity.is_finite());
        for d in &o.doas {
            assert!(d.direction.iter().all(|v| v.is_finite()) && d.power.is_finite());
        }
        for p in &o.points {
            assert!(p.position.iter().all(|v| v.is_finite()) && p.power.is_finite());
        }
        assert!(angle_diff(o.doas[0].azimuth, rad(-60.0)).abs() < rad(3.0));
    }
    // Mixed: some finite bins, some NaN.
    let mut mixed = synth::spectra_at(&x, 0, 2048);
    mixed.channel_mut(3)[200] = crate::dsp::Complex::new(f64::NAN, f64::NAN);
    let obs = loc.process(&mixed);
    assert!(obs[0].activity.is_finite());
    assert!(obs[0].doas.iter().all(|d| d.power.is_finite()));
}

#[test]
fn single_microphone_arrays_report_activity_only() {
    let a0 = MicArray::new("mono", vec![Vec3::new(1.0, 1.0, 1.0)], vec![0]).unwrap();
    let layout = synth::layout(vec![a0], None);
    let mut loc = Localizer::new(&layout, &LocalizerConfig::default(), 1).unwrap();
    let x = vec![synth::white(4096, 2)];
    for o in run(&mut loc, &x) {
        assert!(o.doas.is_empty() && o.points.is_empty());
        assert!(o.activity.is_finite());
    }
    // Nothing can be probed either: the pipeline then keeps the tracker's `speaking`.
    assert_eq!(loc.probe(&[Vec3::new(2.0, 1.0, 1.5)]), None);
}

#[test]
fn recalibration_moves_the_answer_with_the_array() {
    // The recording comes from an array rotated by 90 degrees about z; until the layout says so
    // the direction is off by 90 degrees, after set_layout it is right.
    let layout = uca_layout();
    let centre = layout.arrays[0].centroid();
    let rotated: Vec<Vec3> = layout.arrays[0]
        .mics
        .iter()
        .map(|m| {
            let d = m - centre;
            centre + Vec3::new(-d.y, d.x, d.z)
        })
        .collect();
    let true_layout = synth::layout(
        vec![MicArray::new("uca8", rotated.clone(), (0..8).collect()).unwrap()],
        Some(synth::room_box()),
    );
    let src = centre + direction_from_angles(rad(20.0), rad(10.0)) * 2.0;
    let sig = synth::white(4096, 15);
    let x = synth::render(&rotated, &[(src, &sig)], FS, C, None, 0.005, 16);
    let cfg = LocalizerConfig {
        search: SearchMode::Directions,
        ..LocalizerConfig::default()
    };
    let mut loc = Localizer::new(&layout, &cfg, 1).unwrap();
    let before = loc.process(&synth::spectra_at(&x, 0, 2048)).remove(0);
    assert!(angle_diff(before.doas[0].azimuth, rad(-70.0)).abs() < rad(3.0));
    loc.set_layout(&true_layout).unwrap();
    let after = loc.process(&synth::spectra_at(&x, 2048, 2048)).remove(0);
    assert!(angle_diff(after.doas[0].azimuth, rad(20.0)).abs() < rad(2.0));
}

#[test]
fn planar_array_searches_the_half_space_facing_the_region() {
    let layout = uca_layout();
    let a = &layout.arrays[0];
    let bank = gcc::GccBank::new(a, 2048, (128, 256), settings(0.0), FS, C);
    let cfg = DirectionConfig::default();
    let up = directions::DirectionSearch::new(
        a,
        &bank,
        Some(synth::room_box()),
        &cfg.levels,
        0.002,
        1.0,
        C,
    );
    // About half of level 2's 162 points (plus those on the plane) face up.
    let sizes = up.level_sizes();
    assert!(sizes[0] >= 81 && sizes[0] < 100, "{sizes:?}");
    // A ceiling array looks down.
    let ceiling = synth::uca(8, 0.05, Vec3::new(3.0, 2.5, 2.9), 0, "c");
    let layout2 = synth::layout(vec![ceiling.clone()], Some(synth::room_box()));
    let src = Vec3::new(4.0, 3.0, 1.2);
    let sig = synth::white(4096, 17);
    let x = synth::render(&ceiling.mics, &[(src, &sig)], FS, C, None, 0.005, 18);
    let dcfg = LocalizerConfig {
        search: SearchMode::Directions,
        ..LocalizerConfig::default()
    };
    let mut loc = Localizer::new(&layout2, &dcfg, 1).unwrap();
    for o in run(&mut loc, &x) {
        assert!(angle_between(&o.doas[0].direction, &(src - ceiling.centroid())) < 2.0);
    }
}
