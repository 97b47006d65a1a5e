//! Integration tests of the separator: whole frames through `Separator::process` with the
//! project's STFT and inverse, on free-field and echoic (image-source) mixtures.

#[path = "separate/sim.rs"]
mod sim;

use avsep::dsp::{Complex, Istft, StreamingStft};
use avsep::geometry::{Layout, MicArray, Vec3};
use avsep::label::Label;
use avsep::separate::{
    BeamformerKind, PostFilterKind, PostFilterTarget, Separator, SeparatorConfig, Target,
};

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

/// Sources with the given signals at `positions` in a shoebox room, plus white sensor noise at
/// `snr_db` below the mean source image power at the reference microphone.
fn room_mixture(
    mics: Vec<Vec3>,
    positions: Vec<Vec3>,
    signals: Vec<(Vec<f64>, Vec<(f64, f64)>)>,
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
        let from = (skip_s * FS) as usize;
        let ns = mixture.sources();
        let mut s = Scores {
            si_sdr_in: vec![],
            si_sdr_out: vec![],
            sir_in: vec![],
            sir_out: vec![],
        };
        let ref_parts: Vec<Vec<f64>> = mixture.parts.iter().map(|p| p[0].clone()).collect();
        for i in 0..ns {
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
        })
        .collect()
}

fn three_talkers(radius: f64, rt60: f64, snr_db: f64, seconds: f64) -> Mixture {
    let centre = Vec3::new(3.1, 2.4, 1.2);
    let positions = vec![
        centre + Vec3::new(1.4, 0.2, 0.4),
        centre + Vec3::new(-0.9, 1.2, 0.3),
        centre + Vec3::new(-0.6, -1.3, 0.45),
    ];
    let signals = vec![
        sim::speech(seconds, FS, 120.0, 1),
        sim::speech(seconds, FS, 210.0, 2),
        sim::speech(seconds, FS, 160.0, 3),
    ];
    room_mixture(uca(8, radius, centre), positions, signals, rt60, snr_db, 7)
}

#[test]
#[ignore = "quality survey: prints a table (cargo test --test separate survey -- --ignored --nocapture)"]
fn survey() {
    let mixture = three_talkers(0.05, 0.3, 25.0, 10.0);
    let base = SeparatorConfig::default();
    let mut configs: Vec<(&str, SeparatorConfig)> = vec![];
    let mut c = base.clone();
    c.beamformer = BeamformerKind::DelayAndSum;
    c.post_filter.kind = PostFilterKind::None;
    configs.push(("delay_and_sum", c));
    let mut c = base.clone();
    c.beamformer = BeamformerKind::NullSteering;
    c.post_filter.kind = PostFilterKind::None;
    configs.push(("null_steering", c));
    let mut c = base.clone();
    c.post_filter.kind = PostFilterKind::None;
    configs.push(("gsc", c));
    let mut c = base.clone();
    c.beamformer = BeamformerKind::Mvdr;
    c.post_filter.kind = PostFilterKind::None;
    configs.push(("mvdr", c));
    for (kind, kn) in [
        (PostFilterKind::Mask, "mask"),
        (PostFilterKind::Wiener, "wiener"),
    ] {
        for (to, tn) in [
            (PostFilterTarget::BeamformerOutput, "bf"),
            (PostFilterTarget::ReferenceMic, "ref"),
        ] {
            let mut c = base.clone();
            c.post_filter.kind = kind;
            c.post_filter.apply_to = to;
            configs.push((Box::leak(format!("gsc+{kn}@{tn}").into_boxed_str()), c));
        }
    }
    for (name, cfg) in &configs {
        let r = run(&mixture, cfg, true, |_, t| oracle(&mixture, t));
        println!("{}", Scores::of(&mixture, &r, 1.0).line(name));
    }
}
