//! The shared fixtures: microphone arrays, mixtures with known per-source images, targets,
//! and a run of the separator over a whole mixture through the project's STFT and inverse.

use avsep::dsp::{Complex, Istft, StreamingStft};
use avsep::geometry::{Layout, MicArray, Vec3};
use avsep::label::Label;
use avsep::separate::{Separator, SeparatorConfig, Target};

use crate::sim;

/// Sample rate (Hz) of every mixture.
pub const FS: f64 = 16000.0;
const C: f64 = 343.0;

/// `n` microphones evenly on a horizontal circle of `radius` about `centre`.
pub fn uca(n: usize, radius: f64, centre: Vec3) -> Vec<Vec3> {
    (0..n)
        .map(|i| {
            let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
            centre + Vec3::new(radius * a.cos(), radius * a.sin(), 0.0)
        })
        .collect()
}

/// A layout with the microphones as one array, in channel order, and no cameras.
pub fn layout_of(mics: &[Vec3]) -> Layout {
    let arr = MicArray::new("a0", mics.to_vec(), (0..mics.len()).collect()).unwrap();
    Layout::new(FS as u32, C, vec![arr], vec![], None).unwrap()
}

/// A multichannel recording with its parts: each source's image and the sensor noise.
pub struct Mixture {
    /// Microphone positions, in channel order.
    pub mics: Vec<Vec3>,
    /// Per channel.
    pub mix: Vec<Vec<f64>>,
    /// Per part (sources in order, then noise), per channel.
    pub parts: Vec<Vec<Vec<f64>>>,
    /// Source positions, in order.
    pub positions: Vec<Vec3>,
    /// Per source, its talk spurts (s).
    pub spurts: Vec<Vec<(f64, f64)>>,
}

impl Mixture {
    /// Samples per channel.
    pub fn len(&self) -> usize {
        self.mix[0].len()
    }

    /// Number of sources (the noise is not one).
    pub fn sources(&self) -> usize {
        self.positions.len()
    }

    /// Source `i`'s image at the reference microphone (channel 0): the truth.
    pub fn truth(&self, i: usize) -> &[f64] {
        &self.parts[i][0]
    }

    /// Whether source `i` talks at `t` (s).
    pub fn talking(&self, i: usize, t: f64) -> bool {
        self.spurts[i].iter().any(|&(a, b)| t >= a && t < b)
    }
}

/// A source signal and its talk spurts (s).
pub type Signal = (Vec<f64>, Vec<(f64, f64)>);

/// Sources with the given signals at `positions` in a shoebox room, plus white sensor noise at
/// `snr_db` below the mean source image power at the reference microphone.
pub fn room_mixture(
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
pub struct Run {
    pub out: Vec<Vec<f64>>,
    pub parts: Vec<Vec<Vec<f64>>>,
    /// Per frame: its centre's time (s) and each label index's voicing as the harmonic
    /// grouping read it (0 where the label has none).
    pub voicing: Vec<(f64, Vec<f64>)>,
}

/// Runs the separator over the mixture with targets from `targets(frame_index, time)`; source
/// `i` is label `0.i`.
pub fn run(
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
    let mut voicing = Vec::new();
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
        let mut v = vec![0.0; ns];
        for (label, p) in sep.pitches() {
            if let Some(x) = v.get_mut(label.index as usize) {
                *x = p.voicing;
            }
        }
        voicing.push((t, v));
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
    Run {
        out,
        parts,
        voicing,
    }
}

/// Oracle targets: every source at its true position, speaking from its true talk spurts.
pub fn oracle(mixture: &Mixture, t: f64) -> Vec<Target> {
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

/// The null-steering fixed beamformer alone, without post-filter.
pub fn fixed_only() -> SeparatorConfig {
    serde_json::from_str(r#"{"beamformer": "null_steering", "post_filter": {"kind": "none"}}"#)
        .unwrap()
}

/// Targets at `positions`, source `i` as label `0.i`, all with the same `speaking`.
pub fn static_targets(positions: &[Vec3], speaking: f64) -> Vec<Target> {
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

/// An anechoic mixture of the signals (no talk spurts) with sensor noise 80 dB down.
pub fn free_field(mics: Vec<Vec3>, positions: Vec<Vec3>, signals: Vec<Vec<f64>>) -> Mixture {
    let signals = signals.into_iter().map(|s| (s, vec![])).collect();
    room_mixture(mics, positions, signals, 0.0, 80.0, 11)
}

/// Band-limited noise (speech band, 300 Hz - 6 kHz) of unit-ish power.
pub fn band_noise(n: usize, seed: u64) -> Vec<f64> {
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

/// Silent input fed hop by hop, for tests of the bank's bookkeeping (which labels have streams).
pub struct Quiet {
    stft: StreamingStft,
    hop: Vec<Vec<f64>>,
    out: Vec<(Label, Vec<Complex>)>,
}

impl Quiet {
    /// Silent hops for `sep`'s framing on `mics` channels.
    pub fn new(sep: &Separator, mics: usize) -> Self {
        let g = sep.frame_geometry();
        Self {
            stft: StreamingStft::new(g, mics),
            hop: vec![vec![0.0; g.hop]; mics],
            out: Vec::new(),
        }
    }

    /// Feeds `hops` silent hops with `targets`; returns the labels of the last hop's outputs.
    pub fn feed(&mut self, sep: &mut Separator, targets: &[Target], hops: usize) -> Vec<Label> {
        let refs: Vec<&[f64]> = self.hop.iter().map(|v| v.as_slice()).collect();
        for _ in 0..hops {
            sep.process_into(self.stft.push(&refs), targets, &mut self.out);
        }
        self.out.iter().map(|(l, _)| *l).collect()
    }
}
