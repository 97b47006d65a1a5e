//! Integration tests of the separator: whole frames through `Separator::process` with the
//! project's STFT and inverse, on free-field and echoic (image-source) mixtures.

#[path = "separate/sim.rs"]
mod sim;

use avsep::dsp::{Complex, Istft, StreamingStft};
use avsep::geometry::{Layout, MicArray, Vec3};
use avsep::label::Label;
use avsep::separate::{Separator, SeparatorConfig, Target};

const FS: f64 = 16000.0;
const C: f64 = 343.0;

fn uca(n: usize, radius: f64, centre: Vec3) -> Vec<Vec3> {
    (0..n)
        .map(|i| {
            let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
            centre + Vec3::new(radius * a.cos(), radius * a.sin(), 0.0)
        })
        .collect()
}

fn layout_of(mics: &[Vec3]) -> Layout {
    let arr = MicArray::new("a0", mics.to_vec(), (0..mics.len()).collect()).unwrap();
    Layout::new(FS as u32, C, vec![arr], vec![], None).unwrap()
}

/// A multichannel recording with its parts: each source's image and the sensor noise.
struct Mixture {
    mics: Vec<Vec3>,
    /// Per channel.
    mix: Vec<Vec<f64>>,
    /// Per part (sources in order, then noise), per channel.
    parts: Vec<Vec<Vec<f64>>>,
    positions: Vec<Vec3>,
    spurts: Vec<Vec<(f64, f64)>>,
}

impl Mixture {
    fn len(&self) -> usize {
        self.mix[0].len()
    }

    fn sources(&self) -> usize {
        self.positions.len()
    }

    /// Source `i`'s image at the reference microphone (channel 0): the truth.
    fn truth(&self, i: usize) -> &[f64] {
        &self.parts[i][0]
    }

    fn talking(&self, i: usize, t: f64) -> bool {
        self.spurts[i].iter().any(|&(a, b)| t >= a && t < b)
    }
}

/// A source signal and its talk spurts (s).
type Signal = (Vec<f64>, Vec<(f64, f64)>);

/// Sources with the given signals at `positions` in a shoebox room, plus white sensor noise at
/// `snr_db` below the mean source image power at the reference microphone.
fn room_mixture(
    mics: Vec<Vec3>,
    positions: Vec<Vec3>,
    signals: Vec<Signal>,
    rt60: f64,
    snr_db: f64,
    seed: u64,
) -> Mixture {
    let room = sim::Room::with_rt60(Vec3::new(6.0, 5.0, 3.0), rt60, FS, C);
    let rir_len = ((rt60.max(0.05) * FS) as usize).max(1024);
    let n = signals[0].0.len();
    let mut parts: Vec<Vec<Vec<f64>>> = positions
        .iter()
        .zip(&signals)
        .map(|(p, (x, _))| {
            mics.iter()
                .map(|m| sim::convolve(x, &room.rir(p, m, rir_len)))
                .collect()
        })
        .collect();
    let src_power: f64 = parts
        .iter()
        .map(|p| p[0].iter().map(|v| v * v).sum::<f64>() / n as f64)
        .sum::<f64>()
        / parts.len() as f64;
    let sigma = (src_power / 10f64.powf(snr_db / 10.0)).sqrt();
    parts.push(
        (0..mics.len())
            .map(|m| {
                sim::white(n, seed * 1000 + m as u64)
                    .iter()
                    .map(|v| v * sigma)
                    .collect()
            })
            .collect(),
    );
    let mix = (0..mics.len())
        .map(|m| {
            (0..n)
                .map(|t| parts.iter().map(|p| p[m][t]).sum())
                .collect()
        })
        .collect();
    Mixture {
        mics,
        mix,
        parts,
        positions,
        spurts: signals.into_iter().map(|(_, s)| s).collect(),
    }
}

/// Time-domain outputs of a run, aligned with the input: per label index, the output and the
/// output's parts (one per mixture part, from the recorded per-frame filters).
struct Run {
    out: Vec<Vec<f64>>,
    parts: Vec<Vec<Vec<f64>>>,
}

/// Runs the separator over the mixture with targets from `targets(frame_index, time)`; source
/// `i` is label `0.i`.
fn run(
    mixture: &Mixture,
    cfg: &SeparatorConfig,
    with_parts: bool,
    mut targets: impl FnMut(usize, f64) -> Vec<Target>,
) -> Run {
    let layout = layout_of(&mixture.mics);
    let mut sep = Separator::new(&layout, cfg).unwrap();
    sep.record_filters(with_parts);
    let g = sep.frame_geometry();
    let m = mixture.mics.len();
    let nparts = if with_parts { mixture.parts.len() } else { 0 };
    let mut stft = StreamingStft::new(g, m);
    let mut part_stft: Vec<StreamingStft> = (0..nparts).map(|_| StreamingStft::new(g, m)).collect();
    let ns = mixture.sources();
    let mut istft: Vec<Istft> = (0..ns).map(|_| Istft::new(g)).collect();
    let mut part_istft: Vec<Vec<Istft>> = (0..ns)
        .map(|_| (0..nparts).map(|_| Istft::new(g)).collect())
        .collect();
    let mut out = vec![Vec::new(); ns];
    let mut parts = vec![vec![Vec::new(); nparts]; ns];
    let mut frame_out = Vec::new();
    let mut part_out = Vec::new();
    let mut hop = vec![0.0; g.hop];
    let zeros = vec![Complex::new(0.0, 0.0); g.bins()];
    let total = mixture.len() + g.delay();
    let frames = total.div_ceil(g.hop);
    let padded = |x: &[f64], a: usize| -> Vec<f64> {
        (a..a + g.hop)
            .map(|i| x.get(i).copied().unwrap_or(0.0))
            .collect()
    };
    for f in 0..frames {
        let a = f * g.hop;
        let chunk: Vec<Vec<f64>> = mixture.mix.iter().map(|x| padded(x, a)).collect();
        let refs: Vec<&[f64]> = chunk.iter().map(|v| v.as_slice()).collect();
        let spec = stft.push(&refs).clone();
        // The frame ends at sample a + hop; its centre is half a frame earlier.
        let t = (a + g.hop) as f64 / FS - g.frame as f64 / (2.0 * FS);
        sep.process_into(&spec, &targets(f, t), &mut frame_out);
        for (i, ist) in istft.iter_mut().enumerate() {
            let bins = frame_out
                .iter()
                .find(|(l, _)| l.index as usize == i)
                .map(|(_, b)| b.as_slice())
                .unwrap_or(&zeros);
            ist.push(bins, &mut hop);
            out[i].extend_from_slice(&hop);
        }
        for (p, ps) in part_stft.iter_mut().enumerate() {
            let chunk: Vec<Vec<f64>> = mixture.parts[p].iter().map(|x| padded(x, a)).collect();
            let refs: Vec<&[f64]> = chunk.iter().map(|v| v.as_slice()).collect();
            sep.apply_last_filters(ps.push(&refs), &mut part_out);
            for i in 0..ns {
                let bins = part_out
                    .iter()
                    .find(|(l, _)| l.index as usize == i)
                    .map(|(_, b)| b.as_slice())
                    .unwrap_or(&zeros);
                part_istft[i][p].push(bins, &mut hop);
                parts[i][p].extend_from_slice(&hop);
            }
        }
    }
    let align = |x: &mut Vec<f64>| {
        x.drain(..g.delay());
        x.truncate(mixture.len());
    };
    out.iter_mut().for_each(align);
    parts.iter_mut().flatten().for_each(align);
    Run { out, parts }
}

fn energy(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum()
}

fn db(x: f64) -> f64 {
    10.0 * x.max(1e-300).log10()
}

/// Scale-invariant SDR (dB) of `est` against `truth`.
fn si_sdr(est: &[f64], truth: &[f64]) -> f64 {
    let dot: f64 = est.iter().zip(truth).map(|(a, b)| a * b).sum();
    let alpha = dot / energy(truth).max(1e-300);
    let target: f64 = truth.iter().map(|t| (alpha * t).powi(2)).sum();
    let noise: f64 = est
        .iter()
        .zip(truth)
        .map(|(e, t)| (e - alpha * t).powi(2))
        .sum();
    db(target / noise.max(1e-300))
}

/// Signal-to-interference ratio (dB) of label `i` from its output's parts.
fn sir(parts: &[Vec<f64>], i: usize, sources: usize, from: usize) -> f64 {
    let n = parts[i].len();
    let interf: Vec<f64> = (from..n)
        .map(|t| (0..sources).filter(|&j| j != i).map(|j| parts[j][t]).sum())
        .collect();
    db(energy(&parts[i][from..]) / energy(&interf).max(1e-300))
}

/// Per-source SI-SDR and SIR, unprocessed (reference microphone) and processed, from `skip_s`.
struct Scores {
    si_sdr_in: Vec<f64>,
    si_sdr_out: Vec<f64>,
    sir_in: Vec<f64>,
    sir_out: Vec<f64>,
}

impl Scores {
    fn of(mixture: &Mixture, run: &Run, skip_s: f64) -> Self {
        Self::of_tracked(mixture, run, skip_s, mixture.sources())
    }

    /// Scores of the first `tracked` sources (the others are interferers nobody tracks).
    fn of_tracked(mixture: &Mixture, run: &Run, skip_s: f64, tracked: usize) -> Self {
        let from = (skip_s * FS) as usize;
        let ns = mixture.sources();
        let mut s = Scores {
            si_sdr_in: vec![],
            si_sdr_out: vec![],
            sir_in: vec![],
            sir_out: vec![],
        };
        let ref_parts: Vec<Vec<f64>> = mixture.parts.iter().map(|p| p[0].clone()).collect();
        for i in 0..tracked {
            let truth = &mixture.truth(i)[from..];
            s.si_sdr_in.push(si_sdr(&mixture.mix[0][from..], truth));
            s.si_sdr_out.push(si_sdr(&run.out[i][from..], truth));
            if ns > 1 {
                s.sir_in.push(sir(&ref_parts, i, ns, from));
                if !run.parts[i].is_empty() {
                    s.sir_out.push(sir(&run.parts[i], i, ns, from));
                }
            }
        }
        s
    }

    fn mean(v: &[f64]) -> f64 {
        v.iter().sum::<f64>() / v.len().max(1) as f64
    }

    fn si_sdr_improvement(&self) -> f64 {
        Self::mean(&self.si_sdr_out) - Self::mean(&self.si_sdr_in)
    }

    fn sir_improvement(&self) -> f64 {
        Self::mean(&self.sir_out) - Self::mean(&self.sir_in)
    }

    fn line(&self, name: &str) -> String {
        format!(
            "{name:<28} SI-SDR in {:6.2} out {:6.2} (+{:5.2})  SIR in {:6.2} out {:6.2} (+{:5.2})",
            Self::mean(&self.si_sdr_in),
            Self::mean(&self.si_sdr_out),
            self.si_sdr_improvement(),
            Self::mean(&self.sir_in),
            Self::mean(&self.sir_out),
            self.sir_improvement()
        )
    }
}

/// Oracle targets: every source at its true position, speaking from its true talk spurts.
fn oracle(mixture: &Mixture, t: f64) -> Vec<Target> {
    (0..mixture.sources())
        .map(|i| Target {
            label: Label::new(0, i as u32),
            position: mixture.positions[i],
            direction_only: false,
            speaking: if mixture.talking(i, t) { 1.0 } else { 0.0 },
            activity: 1.0,
            pitch: None,
        })
        .collect()
}

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

/// The null-steering fixed beamformer alone, without post-filter.
fn fixed_only() -> SeparatorConfig {
    serde_json::from_str(r#"{"beamformer": "null_steering", "post_filter": {"kind": "none"}}"#)
        .unwrap()
}

fn static_targets(positions: &[Vec3], speaking: f64) -> Vec<Target> {
    positions
        .iter()
        .enumerate()
        .map(|(i, p)| Target {
            label: Label::new(0, i as u32),
            position: *p,
            direction_only: false,
            speaking,
            activity: 1.0,
            pitch: None,
        })
        .collect()
}

fn free_field(mics: Vec<Vec3>, positions: Vec<Vec3>, signals: Vec<Vec<f64>>) -> Mixture {
    let signals = signals.into_iter().map(|s| (s, vec![])).collect();
    room_mixture(mics, positions, signals, 0.0, 80.0, 11)
}

/// Band-limited noise (speech band, 300 Hz - 6 kHz) of unit-ish power.
fn band_noise(n: usize, seed: u64) -> Vec<f64> {
    let x = sim::white(n, seed);
    let g = avsep::dsp::FrameGeometry {
        frame: 512,
        hop: 128,
    };
    let mut a = StreamingStft::new(g, 1);
    let mut s = Istft::new(g);
    let mut out = Vec::new();
    let mut hop = vec![0.0; g.hop];
    for i in 0..(n + g.delay()).div_ceil(g.hop) {
        let chunk: Vec<f64> = (i * g.hop..(i + 1) * g.hop)
            .map(|t| x.get(t).copied().unwrap_or(0.0))
            .collect();
        let mut spec = a.push(&[&chunk]).channel(0).to_vec();
        for (k, v) in spec.iter_mut().enumerate() {
            let f = k as f64 * FS / g.frame as f64;
            if !(300.0..=6000.0).contains(&f) {
                *v = Complex::new(0.0, 0.0);
            }
        }
        s.push(&spec, &mut hop);
        out.extend_from_slice(&hop);
    }
    out.drain(..g.delay());
    out.truncate(n);
    out
}

#[test]
fn fixed_beamformer_is_distortionless_with_deep_nulls_in_free_field() {
    let centre = Vec3::new(3.0, 2.5, 1.2);
    let positions = vec![
        centre + Vec3::new(1.5, 0.3, 0.3),
        centre + Vec3::new(-0.8, 1.2, 0.4),
        centre + Vec3::new(-0.5, -1.5, 0.2),
    ];
    let n = (2.0 * FS) as usize;
    let signals = (0..3).map(|i| band_noise(n, 20 + i)).collect();
    let mixture = free_field(uca(8, 0.05, centre), positions.clone(), signals);
    let cfg = fixed_only();
    let r = run(&mixture, &cfg, true, |_, _| static_targets(&positions, 1.0));
    let from = (0.2 * FS) as usize;
    for i in 0..3 {
        let truth = &mixture.truth(i)[from..];
        let own = &r.parts[i][i][from..];
        let err: Vec<f64> = own.iter().zip(truth).map(|(a, b)| a - b).collect();
        let distortion = db(energy(&err) / energy(truth));
        assert!(
            distortion < -30.0,
            "label {i}: target distorted at {distortion:.1} dB"
        );
        for j in (0..3).filter(|&j| j != i) {
            let leak = db(energy(&r.parts[i][j][from..]) / energy(&mixture.truth(j)[from..]));
            println!("label {i}: source {j} at {leak:.1} dB");
            assert!(leak < -30.0, "label {i}: source {j} only {leak:.1} dB down");
        }
    }
}

#[test]
fn rls_cancels_a_stationary_interferer_and_then_passes_the_target() {
    cancels_a_stationary_interferer(1);
}

#[test]
fn rls_with_partial_updates_cancels_a_stationary_interferer_too() {
    // Each bin adapts on every other frame: the same cancellation, half the work.
    cancels_a_stationary_interferer(2);
}

fn cancels_a_stationary_interferer(update_every: usize) {
    // One tracked talker, quiet for the first 4 s; an untracked stationary noise source (a fan)
    // that the fixed branch (delay-and-sum toward the talker) barely attenuates.
    let centre = Vec3::new(3.0, 2.5, 1.2);
    let talker = centre + Vec3::new(1.2, 0.5, 0.3);
    let fan = centre + Vec3::new(-1.0, -1.4, -0.6);
    let n = (7.0 * FS) as usize;
    let quiet = (4.0 * FS) as usize;
    let mut voice = band_noise(n, 31);
    voice[..quiet].iter_mut().for_each(|v| *v = 0.0);
    let mixture = free_field(
        uca(8, 0.05, centre),
        vec![talker, fan],
        vec![voice, band_noise(n, 32)],
    );
    let mut cfg = SeparatorConfig::default();
    cfg.post_filter.kind = avsep::separate::PostFilterKind::None;
    cfg.rls.update_every = update_every;
    let targets = |_, t: f64| static_targets(&[talker], if t >= 4.0 { 1.0 } else { 0.0 });
    let r = run(&mixture, &cfg, true, targets);
    // The same frames through the fixed branch alone: what the canceller starts from.
    cfg.beamformer = avsep::separate::BeamformerKind::NullSteering;
    let fixed = run(&mixture, &cfg, true, targets);
    let seg = |x: &[f64], a: f64, b: f64| energy(&x[(a * FS) as usize..(b * FS) as usize]);
    let (fan_gsc, fan_fixed) = (&r.parts[0][1], &fixed.parts[0][1]);
    let fixed_rejection = db(seg(&mixture.parts[1][0], 3.0, 4.0) / seg(fan_fixed, 3.0, 4.0));
    println!("fixed branch alone: fan {fixed_rejection:.1} dB below the reference mic");
    for (a, b) in [
        (0.0, 0.1),
        (0.1, 0.5),
        (0.5, 1.0),
        (1.0, 2.0),
        (3.0, 4.0),
        (4.5, 6.5),
    ] {
        let drop = db(seg(fan_fixed, a, b) / seg(fan_gsc, a, b));
        println!("{a:.1}-{b:.1} s: canceller removes {drop:.1} dB of the fan");
    }
    let drop = db(seg(fan_fixed, 3.0, 4.0) / seg(fan_gsc, 3.0, 4.0));
    assert!(drop > 20.0, "interference only {drop:.1} dB down after 3 s");
    // Frozen while the target talks: the fan stays cancelled and the target is undistorted.
    let held = db(seg(fan_fixed, 4.5, 6.5) / seg(fan_gsc, 4.5, 6.5));
    assert!(
        held > 20.0,
        "cancellation lost while the target talks: {held:.1} dB"
    );
    let from = (4.5 * FS) as usize;
    let truth = &mixture.truth(0)[from..];
    let own = &r.parts[0][0][from..];
    let err: Vec<f64> = own.iter().zip(truth).map(|(a, b)| a - b).collect();
    let distortion = db(energy(&err) / energy(truth));
    println!("target distortion while talking: {distortion:.1} dB");
    assert!(distortion < -25.0, "target distorted at {distortion:.1} dB");
}

fn tones(n: usize, freqs: &[f64], amp: f64) -> Vec<f64> {
    (0..n)
        .map(|t| {
            freqs
                .iter()
                .enumerate()
                .map(|(i, f)| {
                    amp * (2.0 * std::f64::consts::PI * f * t as f64 / FS + i as f64).sin()
                })
                .sum()
        })
        .collect()
}

fn energy_c(x: &[Complex]) -> f64 {
    x.iter().map(|v| v.norm_sqr()).sum()
}

fn max_step(x: &[f64]) -> f64 {
    x.windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0, f64::max)
}

#[test]
fn no_clicks_when_positions_step_and_labels_come_and_go() {
    let centre = Vec3::new(3.0, 2.5, 1.2);
    let p0 = centre + Vec3::new(1.3, 0.4, 0.3);
    let p1 = centre + Vec3::new(-0.7, 1.3, 0.2);
    let n = (4.0 * FS) as usize;
    let mixture = free_field(
        uca(8, 0.05, centre),
        vec![p0, p1],
        vec![
            tones(n, &[220.0, 330.0], 20.0),
            tones(n, &[180.0, 410.0], 20.0),
        ],
    );
    let cfg = SeparatorConfig::default();
    let (birth, death) = (1.0, 2.5);
    let r = run(&mixture, &cfg, false, |f, t| {
        // Tracker steps every 4 frames; the estimate jumps by up to 8 cm at each step.
        let jitter = Vec3::new(0.08, -0.05, 0.03) * if (f / 4) % 2 == 0 { 1.0 } else { -1.0 };
        let mut ts = static_targets(&[p0 + jitter, p1], 1.0);
        if !(birth..death).contains(&t) {
            ts.truncate(1);
        }
        ts
    });
    let input_step = max_step(&mixture.mix[0]);
    for (i, out) in r.out.iter().enumerate() {
        let step = max_step(out);
        println!("label {i}: largest sample step {step:.4} (reference mic {input_step:.4})");
        assert!(
            step.is_finite() && step <= 1.5 * input_step,
            "label {i}: click of {step}"
        );
    }
    // No flutter either: while both labels exist the first one's output stays on its source's
    // image although its estimate jumps every step; alone, its mask is 1 and it is the reference
    // microphone (the documented behaviour of a lone label with `reference_mic`).
    let both = |a: usize, b: usize| -> Vec<f64> { mixture.truth(0)[a..b].to_vec() };
    let alone = |a: usize, b: usize| -> Vec<f64> { mixture.mix[0][a..b].to_vec() };
    type Expect<'a> = &'a dyn Fn(usize, usize) -> Vec<f64>;
    let windows: [(f64, f64, Expect); 3] =
        [(0.2, 0.9, &alone), (1.3, 2.4, &both), (3.2, 3.9, &alone)];
    for (a, b, expect) in windows {
        let (a, b) = ((a * FS) as usize, (b * FS) as usize);
        let want = expect(a, b);
        let err: Vec<f64> = r.out[0][a..b]
            .iter()
            .zip(&want)
            .map(|(x, y)| x - y)
            .collect();
        let e = db(energy(&err) / energy(&want));
        println!("label 0, samples {a}..{b}: error {e:.1} dB");
        assert!(e < -20.0, "label 0 deviates by {e:.1} dB in {a}..{b}");
    }
    // The second label is silent before its birth and after its fade-out, present in between.
    let born = &r.out[1];
    let frame = cfg.frame as f64 / FS;
    assert!(
        born[..((birth - frame) * FS) as usize]
            .iter()
            .all(|v| *v == 0.0)
    );
    let gone =
        ((death + cfg.lifecycle.grace_s + cfg.lifecycle.fade_out_s + 2.0 * frame) * FS) as usize;
    assert!(born[gone..].iter().all(|v| *v == 0.0));
    assert!(energy(&born[(1.5 * FS) as usize..(2.0 * FS) as usize]) > 0.0);
}

#[test]
fn a_label_missing_for_a_step_keeps_its_stream_then_fades_out() {
    let mics = uca(4, 0.05, Vec3::new(0.0, 0.0, 1.0));
    let layout = layout_of(&mics);
    let mut sep = Separator::new(&layout, &SeparatorConfig::default()).unwrap();
    let g = sep.frame_geometry();
    let mut spec = avsep::dsp::MultiSpectrum::zeros(4, g.bins());
    for c in 0..4 {
        for (k, v) in spec.channel_mut(c).iter_mut().enumerate() {
            *v = Complex::from_polar(1.0, 0.3 * (k * (c + 1)) as f64);
        }
    }
    let a = static_targets(&[Vec3::new(1.0, 1.0, 1.5)], 1.0);
    for _ in 0..10 {
        assert_eq!(sep.process(&spec, &a).len(), 1);
    }
    // Gone for less than the grace period: the stream continues at full gain.
    let full = sep.process(&spec, &a)[0].1.clone();
    for _ in 0..3 {
        let out = sep.process(&spec, &[]);
        assert_eq!(out.len(), 1);
        assert_eq!(
            out[0].1, full,
            "stream changed while the label was briefly missing"
        );
    }
    assert_eq!(sep.process(&spec, &a)[0].1, full);
    // Gone for good: grace period, fade-out, then the label is dropped.
    let mut frames = 0usize;
    let mut gains = Vec::new();
    loop {
        let out = sep.process(&spec, &[]);
        if out.is_empty() {
            break;
        }
        gains.push(energy_c(&out[0].1) / energy_c(&full));
        frames += 1;
        assert!(frames < 100, "label never dropped");
    }
    // Full gain through the grace period, then decreasing to silence.
    assert!(gains.windows(2).all(|w| w[1] <= w[0] + 1e-12), "{gains:?}");
    assert_eq!(*gains.last().unwrap(), 0.0);
    let t = SeparatorConfig::default().lifecycle;
    let rate = FS / g.hop as f64;
    let expected = ((t.grace_s + t.fade_out_s) * rate).round() as usize;
    assert!(
        frames.abs_diff(expected) <= 1,
        "dropped after {frames} frames"
    );
    assert!(sep.labels().is_empty());
}

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
        let cfg: SeparatorConfig =
            serde_json::from_str(&format!(r#"{{"beamformer": "{kind}"}}"#)).unwrap();
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

#[test]
fn direction_only_targets_steer_in_the_far_field() {
    let centre = Vec3::new(3.0, 2.5, 1.2);
    let positions = vec![
        centre + Vec3::new(2.0, 0.5, 0.3),
        centre + Vec3::new(-1.0, 1.8, 0.2),
    ];
    let n = (1.5 * FS) as usize;
    let mixture = free_field(
        uca(8, 0.05, centre),
        positions.clone(),
        (0..2).map(|i| band_noise(n, 70 + i)).collect(),
    );
    let cfg = fixed_only();
    // Directions only: points 5 m away along the true directions from the array centre.
    let far: Vec<Vec3> = positions
        .iter()
        .map(|p| centre + (p - centre).normalize() * 5.0)
        .collect();
    let r = run(&mixture, &cfg, true, |_, _| {
        let mut ts = static_targets(&far, 1.0);
        ts.iter_mut().for_each(|t| t.direction_only = true);
        ts
    });
    let from = (0.2 * FS) as usize;
    for i in 0..2 {
        let j = 1 - i;
        let own = si_sdr(&r.parts[i][i][from..], &mixture.truth(i)[from..]);
        let leak = db(energy(&r.parts[i][j][from..]) / energy(&mixture.truth(j)[from..]));
        println!("direction-only label {i}: own SI-SDR {own:.1} dB, other source {leak:.1} dB");
        // The plane-wave model misses the wavefront curvature and the 1/r gains across a 10 cm
        // array, which costs little at 2 m.
        assert!(own > 25.0, "label {i}: own source distorted ({own:.1} dB)");
        assert!(
            leak < -25.0,
            "label {i}: other source only {leak:.1} dB down"
        );
    }
}

/// Runs two separators frame by frame on the same input and targets; returns, per frame, the
/// energy of the difference of their outputs relative to the energy of the first's.
fn relative_differences(
    a: &mut Separator,
    b: &mut Separator,
    channels: &[Vec<f64>],
    targets: impl Fn(usize) -> Vec<Target>,
) -> Vec<f64> {
    let g = a.frame_geometry();
    let mut stft = StreamingStft::new(g, channels.len());
    let mut diffs = Vec::new();
    for (f, at) in (0..channels[0].len() - g.hop).step_by(g.hop).enumerate() {
        let chunk: Vec<&[f64]> = channels.iter().map(|c| &c[at..at + g.hop]).collect();
        let spec = stft.push(&chunk).clone();
        let t = targets(f);
        let (oa, ob) = (a.process(&spec, &t), b.process(&spec, &t));
        let (mut d, mut e) = (0.0, 0.0);
        for ((la, xa), (lb, xb)) in oa.iter().zip(&ob) {
            assert_eq!(la, lb);
            d += xa
                .iter()
                .zip(xb)
                .map(|(p, q)| (p - q).norm_sqr())
                .sum::<f64>();
            e += energy_c(xa);
        }
        diffs.push(d / e.max(1e-300));
    }
    diffs
}

#[test]
fn steering_tolerance_reuses_beamformers_without_changing_the_output() {
    let centre = Vec3::new(3.1, 2.4, 1.2);
    let start = [
        centre + Vec3::new(1.4, 0.2, 0.4),
        centre + Vec3::new(-0.9, 1.2, 0.3),
        centre + Vec3::new(-0.6, -1.3, 0.45),
    ];
    let signals = (0..3)
        .map(|i| (band_noise((1.5 * FS) as usize, 40 + i), vec![]))
        .collect();
    let mixture = room_mixture(uca(8, 0.05, centre), start.to_vec(), signals, 0.3, 25.0, 5);
    // Talkers sway by a millimetre per frame; at frame 20 the first jumps 40 degrees around the
    // array, which must be followed at once.
    let targets = |f: usize| -> Vec<Target> {
        let sway = Vec3::new(0.001, -0.001, 0.0) * (f % 7) as f64;
        let mut p: Vec<Vec3> = start.iter().map(|p| p + sway).collect();
        if f >= 20 {
            p[0] = centre + Vec3::new(0.9, 1.1, 0.4);
        }
        let mut t = static_targets(&p, 0.0);
        // The third talks from frame 25: its canceller freezes, the others keep adapting.
        t[2].speaking = if f >= 25 { 1.0 } else { 0.0 };
        t
    };
    // The harmonic grouping picks each frame's F0 by an argmax, which a change far below the
    // signal may flip: it is off here so that the beamformers' cache is what is compared.
    let no_f0 = r#"{"post_filter": {"harmonic": {"boost": 0}}}"#;
    for json in [no_f0, r#"{"post_filter": {"kind": "none"}}"#] {
        let mut cached: SeparatorConfig = serde_json::from_str(json).unwrap();
        // The bound below is that of this tolerance (the default is looser, chosen on the
        // evaluation scenes).
        cached.steering_tolerance_rad = 0.05;
        let mut exact = cached.clone();
        exact.steering_tolerance_rad = 0.0;
        let layout = layout_of(&mixture.mics);
        let mut a = Separator::new(&layout, &exact).unwrap();
        let mut b = Separator::new(&layout, &cached).unwrap();
        let diffs = relative_differences(&mut a, &mut b, &mixture.mix, targets);
        let worst = diffs.iter().copied().fold(0.0, f64::max);
        // The stale steering errs by at most 0.05 rad at 8 kHz: far below the signal. Frame 20
        // is among them: a jump that was not followed at once would differ by the whole output.
        assert!(
            db(worst) < -30.0,
            "{json}: output changed by {:.1} dB",
            db(worst)
        );
        assert!(diffs.len() > 40);
    }
}
