//! Scores of the separated streams (`audio/<label>.wav`) against the true source images.
//!
//! Each true source with a signal is mapped to the label whose stream carries it: the label
//! matched to it most often (in 3-D, else in azimuth) during its speaking steps, else the best
//! SI-SDR assignment among the remaining labels. Everything is computed over the source's active
//! samples (the union of its `active` intervals): SI-SDR and BSS Eval v3 SDR/SIR/SAR (references:
//! every source's truth signal) of the stream and of the unprocessed reference microphone, and
//! their differences (improvements).
//!
//! Stream continuity: the active samples are cut into blocks; a block is carried by the stream
//! holding the most of the source's energy (largest `<y, s>^2 / |s|^2`) provided that stream
//! correlates with the source at least `continuity_min_correlation`; the report gives each label's
//! share of the blocks and how many labels carry at least `continuity_share` (the target is 1).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::label::Label;
use crate::scene::TruthSource;

use super::EvalError;
use super::assignment::{CostMatrix, assign};
use super::bss_eval::{BssFigures, BssSystem};
use super::config::EvalConfig;
use super::sample_set::SampleSet;
use super::si_sdr::si_sdr;
use super::stats::mean_of;
use super::tracks::{LabelShare, TracksReport};

/// Separation scores.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AudioReport {
    /// Taps of the BSS Eval distortion filter.
    pub filter_taps: usize,
    /// Per true source with a signal.
    pub sources: Vec<SourceAudio>,
    /// Means over the sources that have each figure.
    pub mean: AudioMeans,
}

/// How a source was mapped to a stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MappedBy {
    /// The label matched to it most often in 3-D during its speech.
    Tracks,
    /// The label matched to it most often in azimuth during its speech.
    DirectionTracks,
    /// The best SI-SDR assignment of the remaining labels.
    SiSdr,
}

/// Separation scores of one source.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SourceAudio {
    /// Source id.
    pub id: String,
    /// The stream it was mapped to.
    pub label: Option<Label>,
    /// How.
    pub mapped_by: Option<MappedBy>,
    /// Active (scored) time (s).
    pub active_s: f64,
    /// SI-SDR of the stream (dB).
    pub si_sdr_db: Option<f64>,
    /// SI-SDR of the reference microphone (dB).
    pub si_sdr_mixture_db: Option<f64>,
    /// Stream minus reference microphone (dB).
    pub si_sdr_improvement_db: Option<f64>,
    /// BSS Eval v3 figures of the stream.
    pub bss: Option<BssFigures>,
    /// BSS Eval v3 figures of the reference microphone.
    pub bss_mixture: Option<BssFigures>,
    /// Stream minus reference microphone.
    pub bss_improvement: Option<BssFigures>,
    /// How its active time splits across streams.
    pub continuity: StreamContinuity,
}

/// How a source's active blocks split across the streams.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct StreamContinuity {
    /// Blocks of active samples.
    pub blocks: usize,
    /// Share of the blocks carried by each label, largest first.
    pub shares: Vec<LabelShare>,
    /// Share of the blocks no stream carries.
    pub unassigned_share: f64,
    /// Labels with at least `continuity_share` of the blocks.
    pub stream_labels: usize,
    /// The blocks the source's own stream does not carry, in time order: where its speech
    /// went instead.
    #[serde(default)]
    pub strays: Vec<StrayBlock>,
}

/// A block of a source's active samples that its own stream does not carry.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct StrayBlock {
    /// Start of the block (s).
    pub start_s: f64,
    /// End of the block (s).
    pub end_s: f64,
    /// The stream that carries it; none when no stream correlates with the source enough.
    pub label: Option<Label>,
    /// Share of the source's energy in the block that the carrying stream projects onto the
    /// source (`<y, s>^2 / |s|^4`); none when no stream carries it.
    pub carried: Option<f64>,
    /// The same share for the source's own stream; none when the source has no stream.
    pub own: Option<f64>,
}

/// Means over sources.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct AudioMeans {
    /// SI-SDR of the streams (dB).
    pub si_sdr_db: Option<f64>,
    /// SI-SDR of the reference microphone (dB).
    pub si_sdr_mixture_db: Option<f64>,
    /// SI-SDR improvement (dB).
    pub si_sdr_improvement_db: Option<f64>,
    /// BSS Eval v3 of the streams.
    pub bss: Option<BssFigures>,
    /// BSS Eval v3 of the reference microphone.
    pub bss_mixture: Option<BssFigures>,
    /// BSS Eval v3 improvement.
    pub bss_improvement: Option<BssFigures>,
    /// Mean number of labels carrying each source (the target is 1).
    pub stream_labels: Option<f64>,
}

/// Inputs of the audio scores.
pub struct AudioInputs<'a> {
    /// Sample rate (Hz).
    pub sample_rate: f64,
    /// The true sources with a signal.
    pub sources: Vec<&'a TruthSource>,
    /// Separated streams by label.
    pub streams: &'a BTreeMap<Label, Vec<f32>>,
    /// The reference microphone of the scene audio, when the scene has audio.
    pub mixture: Option<Vec<f32>>,
    /// The tracking scores, used to map sources to labels.
    pub tracks: Option<&'a TracksReport>,
}

fn to_f64(x: &[f32]) -> Vec<f64> {
    x.iter().map(|&v| f64::from(v)).collect()
}

/// Scores the separated streams.
pub fn score_audio(inputs: &AudioInputs, cfg: &EvalConfig) -> Result<AudioReport, EvalError> {
    let refs: Vec<Vec<f64>> = inputs
        .sources
        .iter()
        .map(|s| to_f64(s.signal.as_deref().unwrap_or(&[])))
        .collect();
    let len = refs.iter().map(Vec::len).max().unwrap_or(0);
    let labels: Vec<Label> = inputs.streams.keys().copied().collect();
    let mut streams = Vec::with_capacity(labels.len());
    for (label, s) in inputs.streams {
        if s.len() != len {
            return Err(EvalError::Input(format!(
                "audio/{label}.wav has {} samples but the scene audio has {len}: separated \
                 streams must be exactly as long as audio.wav and sample-aligned with it",
                s.len()
            )));
        }
        streams.push(to_f64(s));
    }
    let mixture = inputs.mixture.as_deref().map(to_f64);
    let sets: Vec<SampleSet> = inputs
        .sources
        .iter()
        .map(|s| SampleSet::from_intervals(&s.active, inputs.sample_rate, len))
        .collect();
    let mapping = map_sources(inputs, &labels, &streams, &refs, &sets);
    let ref_slices: Vec<&[f64]> = refs.iter().map(Vec::as_slice).collect();
    // A source that never sounds (a person who stays silent) spans nothing: leaving it out of
    // the BSS projections gives the same scores, and a scene with many silent people stays
    // quick to score (the projection's cost grows with the cube of the sources).
    let audible: Vec<bool> = refs.iter().map(|r| r.iter().any(|v| *v != 0.0)).collect();
    let block = ((cfg.continuity_block_s * inputs.sample_rate).round() as usize).max(1);
    let mut sources = Vec::new();
    for (i, src) in inputs.sources.iter().enumerate() {
        let set = &sets[i];
        let (label, mapped_by) = match mapping[i] {
            Some((j, how)) => (Some(j), Some(how)),
            None => (None, None),
        };
        let est = label.map(|j| &streams[j]);
        let members: Vec<&[f64]> = (0..refs.len())
            .filter(|&j| j == i || audible[j])
            .map(|j| ref_slices[j])
            .collect();
        let target = (0..i).filter(|&j| audible[j]).count();
        let system = BssSystem::new(&members, target, set, cfg.bss_filter_taps);
        let score = |x: &[f64]| system.as_ref().map(|s| s.score(x));
        let si = |x: &[f64]| (!set.is_empty()).then(|| si_sdr(x, &refs[i], set));
        let si_est = est.and_then(|e| si(e));
        let si_mix = mixture.as_deref().and_then(si);
        let bss = est.and_then(|e| score(e));
        let bss_mix = mixture.as_deref().and_then(score);
        sources.push(SourceAudio {
            id: src.id.clone(),
            label: label.map(|j| labels[j]),
            mapped_by,
            active_s: set.len() as f64 / inputs.sample_rate,
            si_sdr_db: si_est,
            si_sdr_mixture_db: si_mix,
            si_sdr_improvement_db: si_est.zip(si_mix).map(|(a, b)| a - b),
            bss,
            bss_mixture: bss_mix,
            bss_improvement: bss.zip(bss_mix).map(|(a, b)| a.minus(&b)),
            continuity: continuity(
                &refs[i],
                set,
                (&labels, &streams, label),
                (block, inputs.sample_rate),
                cfg,
            ),
        });
    }
    let mean = means(&sources);
    Ok(AudioReport {
        filter_taps: cfg.bss_filter_taps,
        sources,
        mean,
    })
}

/// The means over the sources that have each figure.
fn means(sources: &[SourceAudio]) -> AudioMeans {
    let mean_bss = |f: fn(&SourceAudio) -> Option<BssFigures>| -> Option<BssFigures> {
        let v: Vec<BssFigures> = sources.iter().filter_map(f).collect();
        Some(BssFigures {
            sdr_db: mean_of(v.iter().map(|b| Some(b.sdr_db)))?,
            sir_db: mean_of(v.iter().map(|b| Some(b.sir_db)))?,
            sar_db: mean_of(v.iter().map(|b| Some(b.sar_db)))?,
        })
    };
    AudioMeans {
        si_sdr_db: mean_of(sources.iter().map(|s| s.si_sdr_db)),
        si_sdr_mixture_db: mean_of(sources.iter().map(|s| s.si_sdr_mixture_db)),
        si_sdr_improvement_db: mean_of(sources.iter().map(|s| s.si_sdr_improvement_db)),
        bss: mean_bss(|s| s.bss),
        bss_mixture: mean_bss(|s| s.bss_mixture),
        bss_improvement: mean_bss(|s| s.bss_improvement),
        stream_labels: mean_of(
            sources
                .iter()
                .filter(|s| s.continuity.blocks > 0)
                .map(|s| Some(s.continuity.stream_labels as f64)),
        ),
    }
}

/// For each source, the index of its stream and how it was chosen.
fn map_sources(
    inputs: &AudioInputs,
    labels: &[Label],
    streams: &[Vec<f64>],
    refs: &[Vec<f64>],
    sets: &[SampleSet],
) -> Vec<Option<(usize, MappedBy)>> {
    let index_of = |l: &Label| labels.iter().position(|x| x == l);
    let mut mapping: Vec<Option<(usize, MappedBy)>> = inputs
        .sources
        .iter()
        .map(|s| {
            let t = inputs.tracks?.all.sources.iter().find(|x| x.id == s.id)?;
            let pick = |shares: &[LabelShare]| shares.iter().find_map(|l| index_of(&l.label));
            pick(&t.active_labels)
                .map(|j| (j, MappedBy::Tracks))
                .or_else(|| {
                    pick(&t.direction_active_labels).map(|j| (j, MappedBy::DirectionTracks))
                })
        })
        .collect();
    let free_sources: Vec<usize> = (0..mapping.len())
        .filter(|&i| mapping[i].is_none() && !sets[i].is_empty())
        .collect();
    let free_labels: Vec<usize> = (0..labels.len())
        .filter(|j| !mapping.iter().flatten().any(|(k, _)| k == j))
        .collect();
    let costs = CostMatrix::from_fn(free_sources.len(), free_labels.len(), |a, b| {
        let i = free_sources[a];
        -si_sdr(&streams[free_labels[b]], &refs[i], &sets[i])
    });
    for (a, b) in assign(&costs).pairs {
        mapping[free_sources[a]] = Some((free_labels[b], MappedBy::SiSdr));
    }
    mapping
}

/// How the source's active blocks split across the streams (`labels` and their `streams`;
/// `own` indexes the source's own stream) in blocks of `block` samples at `sample_rate`.
fn continuity(
    reference: &[f64],
    set: &SampleSet,
    (labels, streams, own): (&[Label], &[Vec<f64>], Option<usize>),
    (block, sample_rate): (usize, f64),
    cfg: &EvalConfig,
) -> StreamContinuity {
    let blocks = cut_blocks(set, block);
    let mut counts: BTreeMap<usize, usize> = BTreeMap::new();
    let mut unassigned = 0usize;
    let mut strays = Vec::new();
    for &(a, b) in &blocks {
        let s = &reference[a..b];
        let ss: f64 = s.iter().map(|v| v * v).sum();
        // Per stream: its projected energy onto the source and its correlation with it.
        let carry = |y: &[f64]| -> (f64, f64) {
            let y = &y[a..b];
            let ys: f64 = y.iter().zip(s).map(|(p, q)| p * q).sum();
            let yy: f64 = y.iter().map(|v| v * v).sum();
            let rho = if ss > 0.0 && yy > 0.0 {
                ys / (ss * yy).sqrt()
            } else {
                0.0
            };
            (ys * ys, rho)
        };
        let best = streams
            .iter()
            .enumerate()
            .map(|(j, y)| (j, carry(y)))
            .max_by(|x, y| x.1.0.total_cmp(&y.1.0));
        // The carrying stream and its projected energy.
        let carrier = match best {
            Some((j, (energy, rho))) if rho >= cfg.continuity_min_correlation => {
                *counts.entry(j).or_default() += 1;
                Some((j, energy))
            }
            _ => {
                unassigned += 1;
                None
            }
        };
        let carrier_index = carrier.map(|(j, _)| j);
        if carrier_index.is_none() || carrier_index != own {
            let share = |energy: f64| (ss > 0.0).then(|| energy / (ss * ss));
            strays.push(StrayBlock {
                start_s: a as f64 / sample_rate,
                end_s: b as f64 / sample_rate,
                label: carrier_index.map(|j| labels[j]),
                carried: carrier.and_then(|(_, energy)| share(energy)),
                own: own.and_then(|j| share(carry(&streams[j]).0)),
            });
        }
    }
    let n = blocks.len().max(1) as f64;
    let mut shares: Vec<LabelShare> = counts
        .into_iter()
        .map(|(j, c)| LabelShare {
            label: labels[j],
            share: c as f64 / n,
        })
        .collect();
    shares.sort_by(|a, b| b.share.total_cmp(&a.share).then(a.label.cmp(&b.label)));
    StreamContinuity {
        blocks: blocks.len(),
        stream_labels: shares
            .iter()
            .filter(|l| l.share >= cfg.continuity_share)
            .count(),
        shares,
        unassigned_share: if blocks.is_empty() {
            0.0
        } else {
            unassigned as f64 / n
        },
        strays,
    }
}

/// The active samples cut into blocks of `block` samples; a remainder shorter than half a
/// block is too short to judge on its own and is left out.
fn cut_blocks(set: &SampleSet, block: usize) -> Vec<(usize, usize)> {
    let mut blocks = Vec::new();
    for &(a, b) in set.ranges() {
        let mut s = a;
        while s < b {
            let e = (s + block).min(b);
            if e - s >= block.div_ceil(2) {
                blocks.push((s, e));
            }
            s = e;
        }
    }
    blocks
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn noise(n: usize, seed: u64) -> Vec<f32> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let d = Normal::new(0.0, 0.1).unwrap();
        (0..n).map(|_| d.sample(&mut rng) as f32).collect()
    }

    fn source(id: &str, signal: Vec<f32>, active: Vec<(f64, f64)>) -> TruthSource {
        TruthSource {
            id: id.into(),
            signal: Some(signal),
            trajectory: vec![(0.0, Vec3::zeros())],
            active,
        }
    }

    #[test]
    fn maps_by_si_sdr_and_scores_a_perfect_stream() {
        let fs = 1000.0;
        let n = 4000;
        let a = source("a", noise(n, 1), vec![(0.0, 4.0)]);
        // b speaks from 1 s to 3 s and is silent otherwise.
        let mut nb = noise(n, 2);
        nb[..1000].fill(0.0);
        nb[3000..].fill(0.0);
        let b = source("b", nb, vec![(1.0, 3.0)]);
        let sa = a.signal.clone().unwrap();
        let sb = b.signal.clone().unwrap();
        let mix: Vec<f32> = sa.iter().zip(&sb).map(|(x, y)| x + y).collect();
        let mut streams = BTreeMap::new();
        // Label 3.0 is exactly b; 1.0 is a with half of b leaking in.
        streams.insert(Label::new(3, 0), sb.clone());
        streams.insert(
            Label::new(1, 0),
            sa.iter().zip(&sb).map(|(x, y)| x + 0.5 * y).collect(),
        );
        let cfg = EvalConfig {
            bss_filter_taps: 16,
            ..Default::default()
        };
        let inputs = AudioInputs {
            sample_rate: fs,
            sources: vec![&a, &b],
            streams: &streams,
            mixture: Some(mix),
            tracks: None,
        };
        let r = score_audio(&inputs, &cfg).unwrap();
        let (ra, rb) = (&r.sources[0], &r.sources[1]);
        assert_eq!(ra.label, Some(Label::new(1, 0)));
        assert_eq!(rb.label, Some(Label::new(3, 0)));
        assert_eq!(rb.mapped_by, Some(MappedBy::SiSdr));
        assert!(rb.si_sdr_db.unwrap() > 100.0);
        assert!(rb.si_sdr_improvement_db.unwrap() > 90.0);
        assert!(rb.bss.unwrap().sdr_db > 60.0);
        // Source a over its 4 s: b is active half the time at half amplitude, so the leak
        // carries 1/4 * 1/2 of a's energy (equal powers): SIR ~ 10 log10(8) = 9 dB.
        let sir = ra.bss.unwrap().sir_db;
        assert!((sir - 10.0 * 8f64.log10()).abs() < 0.6, "{sir}");
        assert_eq!(rb.continuity.stream_labels, 1);
        assert_eq!(rb.continuity.shares[0].label, Label::new(3, 0));
        assert_eq!(rb.continuity.blocks, 4);
        assert!(r.mean.si_sdr_improvement_db.is_some());
    }

    #[test]
    fn a_silent_source_leaves_the_others_scores_unchanged() {
        let fs = 1000.0;
        let n = 3000;
        let a = source("a", noise(n, 4), vec![(0.0, 3.0)]);
        let b = source("b", noise(n, 5), vec![(0.0, 3.0)]);
        let quiet = source("quiet", vec![0.0; n], vec![]);
        let (sa, sb) = (a.signal.clone().unwrap(), b.signal.clone().unwrap());
        let mix: Vec<f32> = sa.iter().zip(&sb).map(|(x, y)| x + y).collect();
        let streams = BTreeMap::from([
            (
                Label::new(1, 0),
                sa.iter().zip(&sb).map(|(x, y)| x + 0.3 * y).collect(),
            ),
            (
                Label::new(2, 0),
                sb.iter().zip(&sa).map(|(x, y)| x + 0.2 * y).collect(),
            ),
        ]);
        let cfg = EvalConfig {
            bss_filter_taps: 16,
            ..Default::default()
        };
        let score = |sources: Vec<&TruthSource>| {
            let inputs = AudioInputs {
                sample_rate: fs,
                sources,
                streams: &streams,
                mixture: Some(mix.clone()),
                tracks: None,
            };
            score_audio(&inputs, &cfg).unwrap()
        };
        let (with, without) = (score(vec![&a, &quiet, &b]), score(vec![&a, &b]));
        for (x, y) in [
            (&with.sources[0], &without.sources[0]),
            (&with.sources[2], &without.sources[1]),
        ] {
            let (bx, by) = (x.bss.unwrap(), y.bss.unwrap());
            assert!((bx.sdr_db - by.sdr_db).abs() < 1e-9 && (bx.sir_db - by.sir_db).abs() < 1e-9);
            assert_eq!(x.si_sdr_db, y.si_sdr_db);
        }
        assert!(with.sources[1].bss.is_none());
    }

    #[test]
    fn lists_the_blocks_another_stream_carries() {
        let fs = 1000.0;
        let sa = noise(4000, 3);
        let a = source("a", sa.clone(), vec![(0.0, 4.0)]);
        // Label 1.0 carries a except in 1.0-1.5 s, which label 2.0 carries, and in 3.5-4 s,
        // which no stream carries.
        let mut own = sa.clone();
        own[1000..1500].fill(0.0);
        own[3500..].fill(0.0);
        let mut other = vec![0.0f32; 4000];
        other[1000..1500].copy_from_slice(&sa[1000..1500]);
        let streams = BTreeMap::from([(Label::new(1, 0), own), (Label::new(2, 0), other)]);
        let inputs = AudioInputs {
            sample_rate: fs,
            sources: vec![&a],
            streams: &streams,
            mixture: None,
            tracks: None,
        };
        let cfg = EvalConfig {
            bss_filter_taps: 16,
            ..Default::default()
        };
        let r = score_audio(&inputs, &cfg).unwrap();
        let c = &r.sources[0].continuity;
        assert_eq!(r.sources[0].label, Some(Label::new(1, 0)));
        assert_eq!((c.blocks, c.stream_labels), (8, 2));
        assert_eq!(c.strays.len(), 2, "{:?}", c.strays);
        let (moved, lost) = (&c.strays[0], &c.strays[1]);
        assert_eq!((moved.start_s, moved.end_s), (1.0, 1.5));
        assert_eq!(moved.label, Some(Label::new(2, 0)));
        assert!((moved.carried.unwrap() - 1.0).abs() < 1e-9);
        assert_eq!(moved.own, Some(0.0));
        assert_eq!((lost.start_s, lost.end_s, lost.label), (3.5, 4.0, None));
        assert_eq!((lost.carried, lost.own), (None, Some(0.0)));
    }

    #[test]
    fn rejects_streams_of_the_wrong_length() {
        let a = source("a", noise(100, 1), vec![(0.0, 0.1)]);
        let mut streams = BTreeMap::new();
        streams.insert(Label::new(0, 0), vec![0.0f32; 99]);
        let inputs = AudioInputs {
            sample_rate: 1000.0,
            sources: vec![&a],
            streams: &streams,
            mixture: None,
            tracks: None,
        };
        let e = score_audio(&inputs, &EvalConfig::default()).unwrap_err();
        assert!(e.to_string().contains("audio/0.0.wav"), "{e}");
    }
}
