//! Tests of the harmonic grouping: F0 search, register, ownership, regrouping and leakage.

use super::*;
use crate::dsp::hann_periodic;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub(super) const FS: f64 = 16000.0;
pub(super) const N: usize = 1024;

pub(super) fn harmonic() -> Harmonic {
    harmonic_with(&HarmonicConfig::default())
}

/// The grouping with settings `cfg` at the tests' frame (`N` at `FS`, hop `N / 2`).
pub(super) fn harmonic_with(cfg: &HarmonicConfig) -> Harmonic {
    Harmonic::new(cfg, FS / N as f64, FS / (N / 2) as f64)
}

/// Magnitude spectrum of one Hann-windowed frame of `x`.
pub(super) fn spectrum(x: &[f64]) -> Vec<f64> {
    let w = hann_periodic(N);
    (0..=N / 2)
        .map(|k| {
            let mut acc = Complex::new(0.0, 0.0);
            for (t, (v, w)) in x.iter().zip(&w).enumerate() {
                let ph = -std::f64::consts::TAU * (k * t) as f64 / N as f64;
                acc += Complex::from_polar(v * w, ph);
            }
            acc.norm()
        })
        .collect()
}

/// A seeded generator for the tests' noise.
pub(super) fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// The next value of `rng`, uniform in [-0.5, 0.5).
pub(super) fn uniform(rng: &mut ChaCha8Rng) -> f64 {
    rng.random_range(-0.5..0.5)
}

pub(super) fn voiced(f0: f64, amp: f64) -> Vec<f64> {
    (0..N)
        .map(|t| {
            let t = t as f64 / FS;
            (1..40)
                .filter(|&h| f64::from(h) * f0 < 4000.0)
                .map(|h| {
                    let h = f64::from(h);
                    amp / h * (std::f64::consts::TAU * h * f0 * t + h).sin()
                })
                .sum()
        })
        .collect()
}

#[test]
fn coarse_to_fine_search_finds_the_exhaustive_searchs_pitch() {
    let h = harmonic();
    let rel: Vec<f64> = (0..=N / 2)
        .map(|k| (k as f64 * FS / N as f64 / 1000.0).clamp(0.0, 1.0))
        .collect();
    let (mut cases, mut same) = (0, 0);
    // Single talkers and two-talker mixtures over the F0 range, the second talker 0-12 dB
    // below the first, with noise.
    let mut s = rng(11);
    for i in 0..40 {
        let f1 = 75.0 * (1.0f64 + 0.043 * i as f64);
        let f2 = 310.0 / (1.0f64 + 0.031 * i as f64);
        let a2 = [0.0, 1.0, 0.5, 0.25][i % 4];
        let x: Vec<f64> = voiced(f1, 1.0)
            .iter()
            .zip(voiced(f2, a2))
            .map(|(a, b)| a + b + 0.05 * uniform(&mut s))
            .collect();
        let mag = spectrum(&x);
        let (p, q) = (
            h.pitch(&mag, &rel, &Register::default(), None, &mut Vec::new()),
            h.pitch_exhaustive(&mag, &rel),
        );
        cases += 1;
        same += usize::from(p == q);
        // Where they differ, the coarse search found a comb nearly as good.
        assert!(
            p.voicing >= q.voicing - 0.05,
            "{f1} {f2} {a2}: {p:?} vs {q:?}"
        );
    }
    assert!(same * 10 >= cases * 9, "{same} of {cases} the same");
}

#[test]
fn register_learns_a_labels_f0_and_keeps_it_through_a_neighbours_leak() {
    let h = harmonic();
    let rel = vec![1.0; N / 2 + 1];
    // Half a second of the label's own voice at 104 Hz; then its output carries a
    // neighbour's leak as strong as its own voice, whose comb a fresh search prefers.
    let own = spectrum(&voiced(104.0, 1.0));
    let mut reg = Register::default();
    for _ in 0..16 {
        let p = h.pitch(&own, &rel, &reg, None, &mut Vec::new());
        assert!((p.f0 / 104.0 - 1.0).abs() < 0.01, "{}", p.f0);
        h.observe(&mut reg, &p, 1.0);
    }
    assert!((reg.log_f0 - 104f64.ln()).abs() < 0.01, "{reg:?}");
    for neighbour in [131.0, 171.0, 250.0, 280.0] {
        let mixed: Vec<f64> = voiced(104.0, 1.0)
            .iter()
            .zip(voiced(neighbour, 1.0))
            .map(|(a, b)| a + b)
            .collect();
        let mag = spectrum(&mixed);
        let fresh = h.pitch(&mag, &rel, &Register::default(), None, &mut Vec::new());
        assert!((fresh.f0 / neighbour - 1.0).abs() < 0.01, "{}", fresh.f0);
        let held = h.pitch(&mag, &rel, &reg, None, &mut Vec::new());
        assert!((held.f0 / 104.0 - 1.0).abs() < 0.01, "{}", held.f0);
    }
    // Without evidence the register forgets: after its memory (5 s) it has lost most of
    // its weight, and unvoiced frames do not move its mean.
    let before = reg;
    for _ in 0..(5 * 31) {
        h.observe(&mut reg, &Pitch::default(), 0.0);
    }
    assert_eq!(reg.log_f0, before.log_f0);
    assert!(reg.weight < 0.4 * before.weight, "{reg:?} from {before:?}");
    // A talker who moves out of the register is still followed: a 150 Hz voice alone is
    // read as 150 Hz against a register at 104 Hz (an octave out, the search settles on
    // the subharmonic inside the register, whose comb still covers the talker's bins).
    let far = h.pitch(
        &spectrum(&voiced(150.0, 1.0)),
        &rel,
        &before,
        None,
        &mut Vec::new(),
    );
    assert!((far.f0 / 150.0 - 1.0).abs() < 0.01, "{}", far.f0);
}

/// A register that has learnt `f0` over two seconds of voiced, owned frames.
fn register_at(h: &Harmonic, f0: f64) -> Register {
    let mut reg = Register::default();
    let p = Pitch {
        f0,
        voicing: 1.0,
        salience: 1.0,
        register_fit: 1.0,
    };
    for _ in 0..64 {
        h.observe(&mut reg, &p, 1.0);
    }
    reg
}

#[test]
fn of_two_labels_reading_one_f0_the_one_whose_register_holds_it_keeps_its_harmonics() {
    let h = harmonic();
    let rel = vec![1.0; N / 2 + 1];
    // A far talker at 200 Hz (register 200 Hz) and a silent neighbour whose voice sits at
    // 150 Hz: the talker's reverberation reaches the neighbour's output as strongly as its
    // own, so both labels read 200 Hz with the same salience.
    let mag = spectrum(&voiced(200.0, 1.0));
    let talker = h.pitch(&mag, &rel, &register_at(&h, 200.0), None, &mut Vec::new());
    let silent = h.pitch(&mag, &rel, &register_at(&h, 150.0), None, &mut Vec::new());
    assert!((talker.f0 / 200.0 - 1.0).abs() < 0.01, "{}", talker.f0);
    assert!((silent.f0 / 200.0 - 1.0).abs() < 0.01, "{}", silent.f0);
    assert!(
        (talker.salience / silent.salience - 1.0).abs() < 0.1,
        "{talker:?} {silent:?}"
    );
    assert!(
        talker.register_fit > 0.95 && silent.register_fit < 0.7,
        "{talker:?} {silent:?}"
    );
    // The harmonics go to the talker (the claims are read on the low harmonics, where the two
    // slightly different F0 picks still share their bins).
    let claims = |h: &Harmonic, pitch: &[Pitch]| -> Vec<[f64; 2]> {
        [1.0, 2.0, 5.0]
            .iter()
            .map(|harm| {
                let mut e = [0.0; 2];
                h.evidence(
                    pitch,
                    (harm * 200.0 / h.hz_per_bin).round() as usize,
                    &mut e,
                );
                e
            })
            .collect()
    };
    for e in claims(&h, &[talker, silent]) {
        assert!(e[0] > 0.8 && e[1] < 0.15, "{e:?}");
    }
    // With the register left out of the contest the silent label keeps a third or more of
    // its claim.
    let cfg = HarmonicConfig {
        register_ownership: 0.0,
        ..HarmonicConfig::default()
    };
    let flat = harmonic_with(&cfg);
    let tied = [
        flat.pitch(
            &mag,
            &rel,
            &register_at(&flat, 200.0),
            None,
            &mut Vec::new(),
        ),
        flat.pitch(
            &mag,
            &rel,
            &register_at(&flat, 150.0),
            None,
            &mut Vec::new(),
        ),
    ];
    for e in claims(&flat, &tied) {
        assert!(e[0] > 0.8 && e[1] > 0.3, "{e:?}");
    }
}

#[test]
fn register_off_leaves_the_search_alone() {
    let cfg = HarmonicConfig {
        register_semitones: 0.0,
        ..HarmonicConfig::default()
    };
    let h = harmonic_with(&cfg);
    let rel = vec![1.0; N / 2 + 1];
    let mut reg = Register::default();
    for _ in 0..32 {
        h.observe(
            &mut reg,
            &Pitch {
                f0: 104.0,
                voicing: 1.0,
                salience: 1.0,
                register_fit: 1.0,
            },
            1.0,
        );
    }
    let mag = spectrum(&voiced(212.0, 1.0));
    let a = h.pitch(&mag, &rel, &reg, None, &mut Vec::new());
    let b = h.pitch(&mag, &rel, &Register::default(), None, &mut Vec::new());
    assert_eq!(a, b);
}

#[test]
fn f0_of_a_harmonic_signal_is_found_from_its_upper_band() {
    let h = harmonic();
    for f0 in [97.0, 133.0, 210.0, 287.0] {
        let mag = spectrum(&voiced(f0, 1.0));
        // Only 500 Hz and up are reliable: the fundamental and the low harmonics are not read.
        let rel: Vec<f64> = (0..mag.len())
            .map(|k| f64::from(u8::from(k as f64 * FS / N as f64 >= 500.0)))
            .collect();
        let p = h.pitch(&mag, &rel, &Register::default(), None, &mut Vec::new());
        assert!((p.f0 / f0 - 1.0).abs() < 0.01, "{f0}: {}", p.f0);
        assert!(p.voicing > 0.9, "{f0}: voicing {}", p.voicing);
        // The same harmonics leaking at a tenth into another label are not that label's.
        let leak: Vec<f64> = mag.iter().map(|m| 0.1 * m).collect();
        let q = h.pitch(&leak, &rel, &Register::default(), None, &mut Vec::new());
        let mut own = [0.0; 2];
        h.ownership(&[p, q], &mut own);
        assert!(own[0] > 0.9 && own[1] < 0.02, "{own:?}");
    }
    // Noise has no pitch: one frame in ten may pass a lucky comb, weakly.
    let mut s = rng(7);
    let mut voicing: Vec<f64> = (0..50)
        .map(|_| {
            let noise: Vec<f64> = (0..N).map(|_| uniform(&mut s)).collect();
            h.pitch(
                &spectrum(&noise),
                &vec![1.0; N / 2 + 1],
                &Register::default(),
                None,
                &mut Vec::new(),
            )
            .voicing
        })
        .collect();
    voicing.sort_by(f64::total_cmp);
    assert!(voicing[25] < 0.05, "median noise voicing {}", voicing[25]);
    assert!(
        voicing[45] < 0.25,
        "90th percentile noise voicing {}",
        voicing[45]
    );
}

#[test]
fn a_subharmonic_leak_does_not_own_the_louder_labels_harmonics() {
    let h = harmonic();
    // A talker at 220 Hz; its leak into a silent neighbour's output reads as 110 Hz, whose
    // comb passes through every harmonic of 220 Hz (and between them, where nothing is).
    let mag = spectrum(&voiced(220.0, 1.0));
    let all = vec![1.0; mag.len()];
    let p = h.pitch(&mag, &all, &Register::default(), None, &mut Vec::new());
    assert!((p.f0 / 220.0 - 1.0).abs() < 0.01, "{}", p.f0);
    let ghost = Pitch {
        f0: 110.0,
        voicing: 1.0,
        salience: 0.4 * p.salience,
        register_fit: 1.0,
    };
    let pitch = [p, ghost];
    let mut e = [0.0; 2];
    for harm in [1.0, 3.0, 7.0] {
        let k = (harm * 220.0 / h.hz_per_bin).round() as usize;
        h.evidence(&pitch, k, &mut e);
        assert!(e[0] > 0.8 && e[1] < 0.2, "harmonic {harm}: {e:?}");
    }
    // Between the talker's harmonics the subharmonic comb keeps its claim.
    let k = (330.0 / h.hz_per_bin).round() as usize;
    h.evidence(&pitch, k, &mut e);
    assert!(e[0] < 0.01 && e[1] > 0.8, "{e:?}");
    // Its pitch is its own at the odd teeth only (about 0.6; a same-F0 rule would give it
    // all, 1), so it weighs less in its register.
    let mut own = [0.0; 2];
    h.ownership(&pitch, &mut own);
    assert!(own[0] > 0.9 && own[1] < 0.7, "{own:?}");
}

#[test]
fn an_unresolved_bin_goes_to_the_label_whose_comb_passes_through_it() {
    let h = harmonic();
    let f0 = 120.0;
    let k = (2.0 * f0 / h.hz_per_bin).round() as usize;
    assert!(h.membership(f0, k as f64) > 0.8);
    assert_eq!(h.membership(f0, (k + 3) as f64), 0.0);
    // Labels 0 and 1 are collinear here, label 2 is resolved; the spatial split is even.
    let mut g = vec![0.45, 0.45, 0.1];
    let unresolved = [1.0, 1.0, 0.0];
    h.regroup(
        &mut g,
        &unresolved,
        &[h.membership(f0, k as f64), 0.0, 1.0],
        0.05,
        &mut Vec::new(),
    );
    assert!(g[0] > 0.8 && g[1] < 0.1, "{g:?}");
    assert_eq!(g[2], 0.1);
    assert!((g[0] + g[1] - 0.9).abs() < 0.05 + 1e-12);
    // No evidence in a bin the array cannot resolve at all: the gains there only say who is
    // louder, so the pool is split evenly; where it is mostly unresolved, the louder label keeps
    // part of its lead; with the discount off, the spatial split stays.
    let mut g = vec![0.6, 0.3];
    h.regroup(&mut g, &[1.0, 1.0], &[0.0, 0.0], 0.05, &mut Vec::new());
    assert!(
        (g[0] - 0.45).abs() < 1e-12 && (g[1] - 0.45).abs() < 1e-12,
        "{g:?}"
    );
    let mut g = vec![0.6, 0.3];
    h.regroup(&mut g, &[0.9, 0.9], &[0.0, 0.0], 0.05, &mut Vec::new());
    assert!(g[0] > 0.45 + 0.01 && g[0] < 0.6 - 0.01, "{g:?}");
    assert!((g[0] + g[1] - 0.9).abs() < 1e-12);
    let spatial = harmonic_with(&HarmonicConfig {
        spatial_discount: 0.0,
        ..HarmonicConfig::default()
    });
    let mut g = vec![0.6, 0.3];
    spatial.regroup(&mut g, &[1.0, 1.0], &[0.0, 0.0], 0.05, &mut Vec::new());
    assert!((g[0] - 0.6).abs() < 1e-12 && (g[1] - 0.3).abs() < 1e-12);
}

#[test]
fn a_quiet_talker_keeps_its_harmonic_in_a_bin_the_array_cannot_resolve() {
    let h = harmonic();
    // The loud label's gain leads 0.9 : 0.1 only because it is louder; the bin lies on the
    // quiet label's comb and between the loud label's harmonics.
    let mut g = vec![0.9, 0.1];
    h.regroup(&mut g, &[1.0, 1.0], &[0.0, 1.0], 0.05, &mut Vec::new());
    assert!(g[1] > 0.9 && g[0] < 0.1, "{g:?}");
    // On both combs the bin is shared evenly.
    let mut g = vec![0.9, 0.1];
    h.regroup(&mut g, &[1.0, 1.0], &[1.0, 1.0], 0.05, &mut Vec::new());
    assert!(
        (g[0] - 0.5).abs() < 1e-9 && (g[1] - 0.5).abs() < 1e-9,
        "{g:?}"
    );
}

#[test]
fn leakage_follows_the_steering_correlation_and_loading() {
    let a: Vec<Complex> = (0..6)
        .map(|m| Complex::from_polar(1.0, 0.1 * m as f64))
        .collect();
    let b: Vec<Complex> = (0..6)
        .map(|m| Complex::from_polar(1.0, -0.1 * m as f64))
        .collect();
    let one = vec![Complex::new(1.0, 0.0); 6];
    let o: Vec<Complex> = (0..6)
        .map(|m| Complex::from_polar(1.0, std::f64::consts::TAU * m as f64 / 6.0))
        .collect();
    assert!(leakage(&a, &a, 0.01) > 0.99);
    assert!(leakage(&one, &o, 0.01) < 1e-9);
    let l = leakage(&a, &b, 0.01);
    assert!(l > 0.0 && l < 1.0 && leakage(&a, &b, 0.1) > l);
}

#[test]
fn whitening_is_the_local_rms_magnitude_to_its_power() {
    let h = harmonic();
    let mut s = rng(5);
    let power: Vec<f64> = (0..300).map(|_| (uniform(&mut s) + 0.5).powi(2)).collect();
    let (lo, len) = (3, 260);
    let mut out = Vec::new();
    h.whitening(|k| power[k], lo, len, &mut out);
    assert_eq!(out.len(), len);
    let hw = h.whitening_half_width;
    assert_eq!(hw, 8, "250 Hz at 15.6 Hz per bin");
    for (k, v) in out.iter().enumerate() {
        let want = if k < lo {
            1.0
        } else {
            let (a, b) = (k.saturating_sub(hw).max(lo), (k + hw + 1).min(len));
            let mean = power[a..b].iter().sum::<f64>() / (b - a) as f64;
            mean.powf(0.5 * HarmonicConfig::default().salience_whitening)
        };
        assert!(
            (v - want).abs() < 1e-9 * want,
            "bin {k}: {v} against {want}"
        );
    }
    // Off: every divisor is 1.
    let off = harmonic_with(&HarmonicConfig {
        salience_whitening: 0.0,
        ..HarmonicConfig::default()
    });
    off.whitening(|k| power[k], lo, len, &mut out);
    assert!(out.iter().all(|&v| v == 1.0));
}

#[test]
fn of_two_labels_reading_one_f0_the_upper_harmonics_decide_whose_it_is() {
    // One talker at 200 Hz seen by two labels. The first label's spatial gains pass the loud
    // harmonics below 500 Hz fully (there a small array's gains follow the room, not the
    // talker) and the rest at 0.1; the second label's pass the low ones at 0.3 and the rest
    // fully: the talker is the second label's. Raw magnitudes let the two loud low harmonics
    // decide; measured against the mixture's local level, every harmonic counts.
    let h = harmonic();
    let rel = vec![1.0; N / 2 + 1];
    let hz = FS / N as f64;
    // Speech-like tilt: the harmonics fall as 1/h^2.
    let x: Vec<f64> = (0..N)
        .map(|t| {
            let t = t as f64 / FS;
            (1..20)
                .map(|h| {
                    let h = f64::from(h);
                    (std::f64::consts::TAU * h * 200.0 * t + h).sin() / (h * h)
                })
                .sum()
        })
        .collect();
    let mix = spectrum(&x);
    let apply = |low: f64, high: f64| -> Vec<f64> {
        mix.iter()
            .enumerate()
            .map(|(k, m)| m * if k as f64 * hz < 500.0 { low } else { high })
            .collect()
    };
    let (first, second) = (apply(1.0, 0.1), apply(0.3, 1.0));
    let reg = Register::default();
    let mut level = Vec::new();
    h.whitening(|k| mix[k] * mix[k], 0, h.top_bin(), &mut level);
    let (mut whitened, mut scratch) = (Vec::new(), Vec::new());
    let mut pitches = Vec::new();
    for mag in [&first, &second] {
        let mut p = h.pitch(mag, &rel, &reg, None, &mut scratch);
        assert!((p.f0 / 200.0 - 1.0).abs() < 0.02, "{p:?}");
        let raw = p.salience;
        h.whiten_salience(&mut p, mag, &level, &rel, &mut whitened, &mut scratch);
        pitches.push((raw, p));
    }
    let (raw, white) = (
        [pitches[0].0, pitches[1].0],
        [pitches[0].1.salience, pitches[1].1.salience],
    );
    assert!(raw[0] > raw[1], "raw saliences {raw:?}");
    assert!(white[1] > 1.3 * white[0], "whitened saliences {white:?}");
    // The unresolved bin of the second harmonic goes to the second label, where the raw
    // saliences gave it to the first.
    let bin = (400.0 / hz).round() as usize;
    let claims = |a: f64, b: f64| {
        let (mut p, mut q) = (pitches[0].1, pitches[1].1);
        (p.salience, q.salience) = (a, b);
        let mut e = [0.0; 2];
        h.evidence(&[p, q], bin, &mut e);
        e
    };
    let e = claims(white[0], white[1]);
    assert!(e[1] > 2.0 * e[0], "whitened contest {e:?}");
    let e = claims(raw[0], raw[1]);
    assert!(e[0] > 2.0 * e[1], "raw contest {e:?}");
}

/// A label's segment past its first frames, whose open gate is a presumption.
fn measured(h: &Harmonic) -> Segment {
    let mut segment = Segment::default();
    for _ in 0..10 {
        h.hold(&mut segment, &Pitch::default(), 0.0);
    }
    segment
}

fn voiced_pitch(f0: f64) -> Pitch {
    Pitch {
        f0,
        voicing: 1.0,
        salience: 1.0,
        register_fit: 1.0,
    }
}

#[test]
fn a_voiced_segment_is_held_through_a_closed_gate_while_its_f0_glides() {
    let h = harmonic();
    let mut held = measured(&h);
    // The segment starts with the gate open, then the gate closes while the F0 glides by
    // 1 % per frame: the segment stays whole.
    assert_eq!(h.hold(&mut held, &voiced_pitch(110.0), 0.8), 0.8);
    for f0 in [111.0, 112.1, 113.2, 114.3] {
        assert_eq!(h.hold(&mut held, &voiced_pitch(f0), 0.0), 1.0, "{f0}");
    }
    // A jump of a fifth is another voice: the closed gate applies, and stays applied.
    assert_eq!(h.hold(&mut held, &voiced_pitch(170.0), 0.0), 0.0);
    assert_eq!(h.hold(&mut held, &voiced_pitch(170.5), 0.1), 0.1);
    // An unvoiced frame ends a segment too.
    assert_eq!(h.hold(&mut held, &voiced_pitch(150.0), 0.9), 0.9);
    let unvoiced = Pitch {
        voicing: 0.2,
        ..voiced_pitch(150.0)
    };
    assert_eq!(h.hold(&mut held, &unvoiced, 0.0), 0.0);
    assert_eq!(h.hold(&mut held, &voiced_pitch(150.0), 0.0), 0.0);
}

#[test]
fn a_label_whose_gate_never_opened_has_nothing_to_hold() {
    let h = harmonic();
    let mut held = Segment::default();
    // A silent label reading a steady neighbour's pitch with its gate closed throughout.
    for _ in 0..10 {
        assert_eq!(h.hold(&mut held, &voiced_pitch(130.0), 0.1), 0.1);
    }
    // With the hold off a segment is never held.
    let cfg = HarmonicConfig {
        activity_hold: 0.0,
        ..HarmonicConfig::default()
    };
    let off = harmonic_with(&cfg);
    assert_eq!(off.hold(&mut held, &voiced_pitch(130.0), 1.0), 1.0);
    assert_eq!(off.hold(&mut held, &voiced_pitch(130.0), 0.0), 0.0);
}

#[test]
fn a_held_note_is_held_no_longer_than_a_long_vowel() {
    // 31.25 frames per second: 0.5 s is 16 frames.
    let h = harmonic();
    let mut held = measured(&h);
    assert_eq!(h.hold(&mut held, &voiced_pitch(110.0), 1.0), 1.0);
    let gates: Vec<f64> = (0..20)
        .map(|_| h.hold(&mut held, &voiced_pitch(110.0), 0.0))
        .collect();
    assert!(gates[..16].iter().all(|&g| g == 1.0), "{gates:?}");
    assert!(gates[16..].iter().all(|&g| g == 0.0), "{gates:?}");
    // The gate opening again starts a new segment, with a new allowance.
    assert_eq!(h.hold(&mut held, &voiced_pitch(110.0), 0.7), 0.7);
    assert_eq!(h.hold(&mut held, &voiced_pitch(110.0), 0.0), 1.0);
}

#[test]
fn a_newborn_labels_presumed_open_gate_starts_no_segment() {
    // The gate starts open on the presumption of talk; the label reads a neighbour's note.
    let h = harmonic();
    let mut held = Segment::default();
    let gates: Vec<f64> = [1.0, 0.8, 0.3, 0.0, 0.0, 0.0]
        .iter()
        .map(|&g| h.hold(&mut held, &voiced_pitch(110.0), g))
        .collect();
    assert_eq!(gates, vec![1.0, 0.8, 0.3, 0.0, 0.0, 0.0]);
}
