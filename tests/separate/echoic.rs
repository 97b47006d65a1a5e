//! Separation of talkers in an echoic room with oracle tracks, and the ignored quality survey.

use avsep::geometry::Vec3;
use avsep::separate::SeparatorConfig;

use crate::fixtures::{FS, Mixture, Signal, oracle, room_mixture, run, uca};
use crate::scores::Scores;
use crate::sim;

fn three_talkers(seconds: f64, seed: u64) -> Mixture {
    let centre = Vec3::new(3.1, 2.4, 1.2);
    let positions = vec![
        centre + Vec3::new(1.4, 0.2, 0.4),
        centre + Vec3::new(-0.9, 1.2, 0.3),
        centre + Vec3::new(-0.6, -1.3, 0.45),
    ];
    let signals = [120.0, 210.0, 160.0]
        .iter()
        .enumerate()
        .map(|(i, f0)| sim::speech(seconds, FS, *f0, 1 + i as u64 + 10 * seed))
        .collect();
    room_mixture(
        uca(8, 0.05, centre),
        positions,
        signals,
        0.3,
        25.0,
        7 + seed,
    )
}

/// The separation target of the task on our own echoic mixtures (until the project's simulator
/// and pipeline provide `avsep process --oracle-tracks`): an 8-microphone circular array (10 cm
/// across), three talkers in a 6 x 5 x 3 m room with RT60 0.3 s and 25 dB SNR, oracle positions
/// and talk spurts.
#[test]
fn separates_three_talkers_in_an_echoic_room_with_oracle_tracks() {
    let mixture = three_talkers(8.0, 0);
    let baseline: SeparatorConfig =
        serde_json::from_str(r#"{"beamformer": "delay_and_sum", "post_filter": {"kind": "none"}}"#)
            .unwrap();
    let das = Scores::of(
        &mixture,
        &run(&mixture, &baseline, true, |_, t| oracle(&mixture, t)),
        1.0,
    );
    println!("{}", das.line("delay_and_sum (baseline)"));
    let r = run(&mixture, &SeparatorConfig::default(), true, |_, t| {
        oracle(&mixture, t)
    });
    let s = Scores::of(&mixture, &r, 1.0);
    println!("{}", s.line("default"));
    assert!(
        s.si_sdr_improvement() >= 6.0,
        "SI-SDR improvement {:.2} dB",
        s.si_sdr_improvement()
    );
    assert!(
        s.sir_improvement() >= 12.0,
        "SIR improvement {:.2} dB",
        s.sir_improvement()
    );
    assert!(s.si_sdr_improvement() > das.si_sdr_improvement() + 6.0);
}

#[test]
fn a_single_talker_comes_through_nearly_untouched() {
    let centre = Vec3::new(3.1, 2.4, 1.2);
    let p = centre + Vec3::new(1.4, 0.2, 0.4);
    let mixture = room_mixture(
        uca(8, 0.05, centre),
        vec![p],
        vec![sim::speech(6.0, FS, 140.0, 5)],
        0.3,
        30.0,
        3,
    );
    let r = run(&mixture, &SeparatorConfig::default(), false, |_, t| {
        oracle(&mixture, t)
    });
    let s = Scores::of(&mixture, &r, 1.0);
    println!("{}", s.line("single talker"));
    assert!(s.si_sdr_out[0] >= 20.0, "SI-SDR {:.2} dB", s.si_sdr_out[0]);
}

/// A far talker in a reverberant room (RT60 0.4 s, 2.6 m from a 6-microphone line) and a silent
/// label nearer the array: the talker's reverberation reaches the silent label's beamformer
/// strongly enough that the label reads the talker's pitch. The harmonic grouping's activity
/// gate (the direct-path power fit) keeps more of the talker out of the silent label's stream.
#[test]
fn a_silent_label_beside_a_far_reverberant_talker_keeps_out_of_its_harmonics() {
    let mics: Vec<Vec3> = (0..6)
        .map(|i| Vec3::new(2.9 + 0.04 * f64::from(i), 0.8, 1.5))
        .collect();
    let centre = Vec3::new(3.0, 0.8, 1.5);
    let at = |deg: f64, r: f64| {
        let a = deg.to_radians();
        centre + Vec3::new(r * a.cos(), r * a.sin(), 0.0)
    };
    let (talker, silent) = (at(62.0, 2.6), at(110.0, 1.3));
    let speech = sim::speech(6.0, FS, 190.0, 3);
    let nothing = (vec![0.0; speech.0.len()], vec![]);
    let mixture = room_mixture(
        mics,
        vec![talker, silent],
        vec![speech, nothing],
        0.4,
        30.0,
        5,
    );
    let targets = |_: usize, t: f64| oracle(&mixture, t);
    let gate_off: SeparatorConfig =
        serde_json::from_str(r#"{"post_filter": {"harmonic": {"activity_gate": false}}}"#).unwrap();
    let skip = FS as usize;
    let leak = |cfg: &SeparatorConfig| {
        let r = run(&mixture, cfg, false, targets);
        let own = crate::scores::energy(&r.out[0][skip..]);
        let stolen = crate::scores::energy(&r.out[1][skip..]);
        crate::scores::db(stolen / own)
    };
    let (on, off) = (leak(&SeparatorConfig::default()), leak(&gate_off));
    println!("silent label's stream against the talker's: gate on {on:.1} dB, off {off:.1} dB");
    // About -11.7 against -8.1 dB. Most of what the silent label keeps is the reverberation
    // its spatial gain passes, which no pitch rule removes. The bound also guards the low
    // band's rule (`direct_power::LOW_BAND_MAX_COSINE`): counting the bins where the line
    // cannot tell the silent label from the diffuse field, the gate left -6.1 dB, worse than
    // none.
    assert!(on < off - 2.0, "gate on {on:.1} dB, off {off:.1} dB");
}

/// Two talkers far beyond the critical distance of a reverberant, noisy room (RT60 0.9 s, SNR
/// 10 dB, 2.2-2.4 m from an 8-microphone circle 20 cm across): a talker's direct path dominates
/// few bins, so the activity gate at the thresholds set for the small arrays' rooms keeps its
/// voicing shut much of the time it talks. Calibrated to the room's level it opens more, and
/// still not on a label that is silent.
#[test]
fn far_talkers_in_a_reverberant_room_are_heard_voiced_with_the_gate_calibrated_to_it() {
    let centre = Vec3::new(3.0, 2.5, 0.75);
    let at = |deg: f64, r: f64, z: f64| {
        let a = deg.to_radians();
        centre + Vec3::new(r * a.cos(), r * a.sin(), z)
    };
    let signals = [115.0, 200.0]
        .iter()
        .enumerate()
        .map(|(i, f0)| sim::speech(10.0, FS, *f0, 31 + i as u64))
        .collect();
    let mixture = room_mixture(
        uca(8, 0.1, centre),
        vec![at(20.0, 2.4, 0.85), at(150.0, 2.2, 0.8)],
        signals,
        0.9,
        10.0,
        11,
    );
    // Per configuration: the share of frames read as voiced (0.5 or more) inside the talkers'
    // spurts and outside them, after the room has been heard for 4 s.
    let voiced = |cfg: &SeparatorConfig| {
        let r = run(&mixture, cfg, false, |_, t| oracle(&mixture, t));
        let (mut inside, mut outside) = ((0, 0), (0, 0));
        for (t, v) in r.voicing.iter().filter(|(t, _)| *t >= 4.0) {
            for (i, spurts) in mixture.spurts.iter().enumerate() {
                let talking = spurts.iter().any(|&(a, b)| a <= *t && *t <= b);
                let silent = spurts.iter().all(|&(a, b)| *t < a - 0.3 || *t > b + 0.3);
                let tally = if talking {
                    &mut inside
                } else if silent {
                    &mut outside
                } else {
                    continue;
                };
                tally.0 += usize::from(v[i] >= 0.5);
                tally.1 += 1;
            }
        }
        let share = |(n, of): (usize, usize)| n as f64 / of.max(1) as f64;
        (share(inside), share(outside))
    };
    let fixed: SeparatorConfig =
        serde_json::from_str(r#"{"post_filter": {"harmonic": {"activity_room_level": 0}}}"#)
            .unwrap();
    let (calibrated, set) = (voiced(&SeparatorConfig::default()), voiced(&fixed));
    println!(
        "voiced while talking / while silent: calibrated {:.3} / {:.3}, as set {:.3} / {:.3}",
        calibrated.0, calibrated.1, set.0, set.1
    );
    // About 0.32 against 0.27 (the spurts hold unvoiced sounds and pauses too), 0 both.
    assert!(
        calibrated.0 > set.0 + 0.03,
        "{calibrated:?} against {set:?}"
    );
    assert!(calibrated.1 < 0.05, "{calibrated:?}");
}

/// Scene knobs of the survey from `AVSEP_SCENE` ("radius=0.05,rt60=0.3,snr=25,seconds=10,seed=1").
fn survey_scene() -> Mixture {
    let spec = std::env::var("AVSEP_SCENE").unwrap_or_default();
    let get = |k: &str, d: f64| -> f64 {
        spec.split(',')
            .filter_map(|kv| kv.split_once('='))
            .find(|(a, _)| a.trim() == k)
            .map(|(_, v)| v.trim().parse().unwrap())
            .unwrap_or(d)
    };
    let seed = get("seed", 0.0) as u64;
    let centre = Vec3::new(3.1, 2.4, 1.2);
    let talkers = get("talkers", 3.0) as usize;
    let seconds = get("seconds", 10.0);
    let all = [
        centre + Vec3::new(1.4, 0.2, 0.4),
        centre + Vec3::new(-0.9, 1.2, 0.3),
        centre + Vec3::new(-0.6, -1.3, 0.45),
        centre + Vec3::new(0.8, -1.0, 0.35),
    ];
    let f0 = [120.0, 210.0, 160.0, 100.0];
    let positions = all[..talkers].to_vec();
    let signals = (0..talkers)
        .map(|i| sim::speech(seconds, FS, f0[i], 1 + i as u64 + 10 * seed))
        .collect();
    room_mixture(
        uca(8, get("radius", 0.05), centre),
        positions,
        signals,
        get("rt60", 0.3),
        get("snr", 25.0),
        7 + seed,
    )
}

/// Prints SI-SDR and SIR of configuration variants on an echoic mixture. Variants come from
/// `AVSEP_VARIANTS` as `name|{json patch of SeparatorConfig}` separated by `;`.
#[test]
#[ignore = "quality survey: cargo test --test separate survey -- --ignored --nocapture"]
fn survey() {
    let mixture = survey_scene();
    let spec = std::env::var("AVSEP_VARIANTS").unwrap_or_else(|_| {
        concat!(
            r#"das|{"beamformer":"delay_and_sum","post_filter":{"kind":"none"}};"#,
            r#"null|{"beamformer":"null_steering","post_filter":{"kind":"none"}};"#,
            r#"gsc|{"post_filter":{"kind":"none"}};"#,
            r#"mvdr|{"beamformer":"mvdr","post_filter":{"kind":"none"}};"#,
            r#"gsc+mask@bf|{"post_filter":{"kind":"mask","apply_to":"beamformer_output"}};"#,
            r#"gsc+mask@ref|{"post_filter":{"kind":"mask","apply_to":"reference_mic"}};"#,
            r#"gsc+wiener@bf|{"post_filter":{"kind":"wiener","apply_to":"beamformer_output"}};"#,
            r#"gsc+wiener@ref|{"post_filter":{"kind":"wiener","apply_to":"reference_mic"}}"#
        )
        .to_string()
    });
    // Speaking probabilities: the truth's talk spurts, or no information at all.
    let speaking: Option<f64> = std::env::var("AVSEP_SPEAKING")
        .ok()
        .map(|v| v.parse().unwrap());
    let tracked: usize = std::env::var("AVSEP_TRACKED")
        .ok()
        .map_or(mixture.sources(), |v| v.parse().unwrap());
    for variant in spec.split(';').filter(|v| !v.trim().is_empty()) {
        let (name, json) = variant.split_once('|').unwrap();
        let cfg: SeparatorConfig = serde_json::from_str(json).unwrap();
        let r = run(&mixture, &cfg, true, |_, t| {
            let mut ts = oracle(&mixture, t);
            if let Some(p) = speaking {
                ts.iter_mut().for_each(|x| x.speaking = p);
            }
            ts.truncate(tracked);
            ts
        });
        println!(
            "{}",
            Scores::of_tracked(&mixture, &r, 1.0, tracked).line(name.trim())
        );
    }
}

/// Six microphones on a 20 cm line along x, centred at (3.0, 0.8, 1.5), as paper-linear6's.
fn line_20cm() -> Vec<Vec3> {
    (0..6)
        .map(|i| Vec3::new(2.9 + 0.04 * f64::from(i), 0.8, 1.5))
        .collect()
}

/// Two talkers 25 degrees apart (at 75 and 100 degrees), 1.5 m from a 6-microphone line 20 cm
/// long, in a room with RT60 0.3 s and 30 dB SNR: below 1 kHz the array cannot tell them apart.
fn unresolved_pair(signals: Vec<Signal>, seed: u64) -> Mixture {
    let mics = line_20cm();
    let centre = Vec3::new(3.0, 0.8, 1.5);
    let at = |deg: f64| {
        let a = f64::to_radians(deg);
        centre + Vec3::new(1.5 * a.cos(), 1.5 * a.sin(), 0.1)
    };
    room_mixture(mics, vec![at(75.0), at(100.0)], signals, 0.3, 30.0, seed)
}

/// Two talkers the 20 cm line cannot resolve below 1 kHz (`unresolved_pair`): there the
/// harmonic amplitude fit divides each bin by the power each voice has in it rather than
/// handing it whole to the stronger comb.
#[test]
fn the_harmonic_fit_separates_two_voices_the_array_cannot_resolve() {
    let signals = vec![
        sim::speech(6.0, FS, 120.0, 11),
        sim::speech(6.0, FS, 205.0, 12),
    ];
    let mixture = unresolved_pair(signals, 9);
    let targets = |_: usize, t: f64| oracle(&mixture, t);
    let fit_off: SeparatorConfig =
        serde_json::from_str(r#"{"post_filter": {"harmonic": {"fit_below_hz": 0.0}}}"#).unwrap();
    let score =
        |cfg: &SeparatorConfig| Scores::of(&mixture, &run(&mixture, cfg, true, targets), 1.0);
    let (on, off) = (score(&SeparatorConfig::default()), score(&fit_off));
    println!("{}\n{}", on.line("fit"), off.line("no fit"));
    // Measured: SI-SDR +8.9 against +7.3 dB, SIR +11.6 against +10.4 dB.
    assert!(
        on.sir_improvement() > off.sir_improvement() + 0.8,
        "SIR improvement {:.2} dB with the fit, {:.2} dB without",
        on.sir_improvement(),
        off.sir_improvement()
    );
    assert!(on.si_sdr_improvement() > off.si_sdr_improvement() + 1.0);
}

/// A voice on the harmonics of `f0(t)` (Hz) from `start` (s) on, harmonic h weighted
/// `amp(h f0)`; `phase` offsets each harmonic's phase so two voices on one F0 differ in form.
fn harmonic_voice(
    seconds: f64,
    start: f64,
    f0: impl Fn(f64) -> f64,
    amp: impl Fn(f64) -> f64,
    phase: f64,
) -> Vec<f64> {
    let n = (seconds * FS) as usize;
    let mut cycles = 0.0;
    (0..n)
        .map(|i| {
            let t = i as f64 / FS;
            let f = f0(t);
            cycles += f / FS;
            if t < start {
                return 0.0;
            }
            // A 50 ms fade-in, so the onset is not a click.
            let fade = ((t - start) / 0.05).min(1.0);
            let mut v = 0.0;
            let mut h = 1.0;
            while h * f < 4000.0 {
                v += amp(h * f) * (std::f64::consts::TAU * h * cycles + phase * h).cos();
                h += 1.0;
            }
            fade * v
        })
        .collect()
}

/// Two talkers the 20 cm line cannot tell apart below 1 kHz, in unison: the first holds a
/// vowel 20 dB weaker above 1 kHz than below, the second joins on the same gliding F0 with a
/// flat spectrum. The activity gate, measured above 1 kHz, closes on the first; the voiced
/// segment it started while alone holds it open, and the fit divides the low harmonics by what
/// each label had in them before, so the first keeps its voice instead of losing it to the
/// louder comb.
#[test]
fn a_vowel_without_upper_harmonics_keeps_its_voice_when_a_neighbour_joins_in_unison() {
    // One long vowel: 1.5 s alone, then 0.45 s in unison.
    let (seconds, joins) = (1.95, 1.5);
    let f0 = |t: f64| 120.0 * (1.0 + 0.03 * (std::f64::consts::TAU * 0.7 * t).sin());
    let dark = harmonic_voice(seconds, 0.0, f0, |f| if f < 900.0 { 1.0 } else { 0.1 }, 0.3);
    let bright = harmonic_voice(seconds, joins, f0, |_| 0.3, 1.9);
    let signals = vec![
        (dark, vec![(0.0, seconds)]),
        (bright, vec![(joins, seconds)]),
    ];
    let mixture = unresolved_pair(signals, 5);
    let targets = |_: usize, t: f64| oracle(&mixture, t);
    let no_hold: SeparatorConfig =
        serde_json::from_str(r#"{"post_filter": {"harmonic": {"activity_hold": 0.0}}}"#).unwrap();
    let score = |cfg: &SeparatorConfig| {
        let r = run(&mixture, cfg, true, targets);
        Scores::of(&mixture, &r, joins + 0.05)
    };
    let (on, off) = (score(&SeparatorConfig::default()), score(&no_hold));
    println!("{}\n{}", on.line("hold"), off.line("no hold"));
    let dark = |s: &Scores| s.si_sdr_out[0];
    println!(
        "dark voice SI-SDR {:.2} against {:.2}",
        dark(&on),
        dark(&off)
    );
    // Measured: dark voice +4.3 against +1.1 dB; SIR improvement +3.1 against +1.7 dB.
    assert!(dark(&on) > dark(&off) + 2.0);
    assert!(on.sir_improvement() > off.sir_improvement() + 1.0);
}

/// A talker who starts just after his neighbour stops, on the 20 cm line that cannot tell
/// them apart below 1 kHz, with a third, silent label close by, while the tracker still reads
/// him silent (his label's `speaking` lags his onset by 0.4 s, as the tracker's talk/pause
/// chain can): his label's activity gate, which measures him talking, keeps his own canceller
/// from learning his voice meanwhile.
#[test]
fn a_talker_whose_onset_the_tracker_misses_is_not_cancelled_by_his_own_canceller() {
    let (seconds, stops, starts) = (3.0, 1.4, 1.5);
    let within = |x: Vec<f64>, a: f64, b: f64| -> Vec<f64> {
        x.into_iter()
            .enumerate()
            .map(|(i, v)| {
                let t = i as f64 / FS;
                if t >= a && t < b { v } else { 0.0 }
            })
            .collect()
    };
    let first = within(sim::speech(seconds, FS, 120.0, 21).0, 0.0, stops);
    let second = within(sim::speech(seconds, FS, 205.0, 22).0, starts, seconds);
    let silent = vec![0.0; second.len()];
    let signals = vec![
        (first, vec![(0.0, stops)]),
        (second, vec![(starts, seconds)]),
        (silent, vec![]),
    ];
    // The newcomer far out at 70 degrees, the neighbour who stops at 95 and a silent label
    // close by at 125, as on paper-linear6 seed 16.
    let at = |deg: f64, r: f64| {
        let a = f64::to_radians(deg);
        Vec3::new(3.0 + r * a.cos(), 0.8 + r * a.sin(), 1.6)
    };
    let positions = vec![at(95.0, 2.0), at(70.0, 2.6), at(125.0, 1.3)];
    let mixture = room_mixture(line_20cm(), positions, signals, 0.3, 30.0, 7);
    let lagging = |_: usize, t: f64| {
        let mut targets = oracle(&mixture, t);
        if t < starts + 0.4 {
            targets[1].speaking = 0.0;
        }
        targets
    };
    let off: SeparatorConfig =
        serde_json::from_str(r#"{"adaptation": {"activity_presence": false}}"#).unwrap();
    // The second talker's first second, in his own stream.
    let (a, b) = ((starts * FS) as usize, ((starts + 1.0) * FS) as usize);
    // Per stream, the energy of the talker it carries there (as `avsep eval`'s continuity
    // reads a block: <y, s>^2 / |s|^2), relative to the talker's.
    let onset = |cfg: &SeparatorConfig| {
        let r = run(&mixture, cfg, false, lagging);
        let s = &mixture.truth(1)[a..b];
        let ss: f64 = s.iter().map(|v| v * v).sum();
        let carried: Vec<f64> = r
            .out
            .iter()
            .map(|y| {
                let ys: f64 = y[a..b].iter().zip(s).map(|(p, q)| p * q).sum();
                ys * ys / (ss * ss)
            })
            .collect();
        (crate::scores::si_sdr(&r.out[1][a..b], s), carried)
    };
    let (on, without) = (onset(&SeparatorConfig::default()), onset(&off));
    println!("onset: with the gate {on:.3?}, without {without:.3?}");
    // Measured: SI-SDR 17.2 against 16.6 dB; his stream carries 0.81 of his energy against
    // 0.74, the others 0.01 and 0.004 either way. Asserted: half of each gain.
    assert!(on.0 > without.0 + 0.25, "{on:.2?} against {without:.2?}");
    assert!(
        on.1[1] > without.1[1] + 0.03,
        "{on:.3?} against {without:.3?}"
    );
    assert!(on.1[1] > 10.0 * on.1[0].max(on.1[2]), "{on:.3?}");
}
