//! The separator's pitch (`pitch.jsonl`) scored against each true source's voice.
//!
//! The harmonic grouping divides the bins a small array cannot resolve by each label's F0 and
//! voicing, so how well it reads them bounds the separation (`--oracle-pitch` measures the
//! bound). Each true source's signal is read by YIN at the frame times of `pitch.jsonl`, and the
//! label the audio section mapped to the source is compared with it frame by frame: how many of
//! the source's voiced frames the label reads as voiced, how many of its silent or unvoiced ones
//! it reads as voiced anyway (a neighbour's leak), and how close its F0 is where both are voiced.
//! The same figures over the frames of the blocks the source's own stream does not carry (the
//! audio section's stray blocks) say how much of a lost block the pitch explains.

use serde::{Deserialize, Serialize};

use super::EvalConfig;
use super::stats::mean_of;
use crate::dsp::{VoicePitch, Yin};
use crate::label::Label;
use crate::scene::TruthSource;
use crate::scene::format::PitchLine;

/// An F0 more than this fraction away from the true one is a gross error (the usual 20 %).
pub const GROSS_ERROR: f64 = 0.2;

/// Pitch scores of the separator.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PitchReport {
    /// Relative F0 deviation within which a label's F0 counts as right.
    pub tolerance: f64,
    /// Per true source with a signal and a mapped label.
    pub sources: Vec<SourcePitch>,
    /// Means over the sources that have each figure.
    pub mean: PitchFigures,
    /// Every source's frames in the blocks its own stream does not carry, pooled; absent when
    /// no source has such a frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub off_stream: Option<FrameFigures>,
}

/// Pitch figures over a set of frames, with their counts.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct FrameFigures {
    /// Frames counted.
    pub frames: usize,
    /// Of those, frames in which the source is voiced.
    pub voiced_frames: usize,
    /// The figures.
    #[serde(flatten)]
    pub figures: PitchFigures,
}

/// One source's pitch scores.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SourcePitch {
    /// Source id.
    pub id: String,
    /// The label the audio section mapped to it.
    pub label: Label,
    /// Over the frames in which the label had a stream.
    #[serde(flatten)]
    pub whole: FrameFigures,
    /// The same over its frames in the blocks its own stream does not carry (a frame there
    /// without the label's stream counts as read unvoiced); absent without such a frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub off_stream: Option<FrameFigures>,
}

/// Shares of frames; absent when their frames are none.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PitchFigures {
    /// Of the source's voiced frames, the share its label reads as voiced.
    pub voiced_recall: Option<f64>,
    /// Of its silent or unvoiced frames, the share its label reads as voiced.
    pub false_voicing: Option<f64>,
    /// Of the frames both voiced, the share with the label's F0 within `tolerance`.
    pub f0_within_tolerance: Option<f64>,
    /// Of the frames both voiced, the share with the label's F0 off by more than 20 %.
    pub gross_error: Option<f64>,
}

/// Frame counts of one source.
#[derive(Default)]
struct Counts {
    frames: usize,
    voiced: usize,
    voiced_read: usize,
    unvoiced_read: usize,
    within: usize,
    gross: usize,
}

impl Counts {
    fn add(&mut self, truth: VoicePitch, f0: f64, voicing: f64, cfg: &EvalConfig) {
        self.frames += 1;
        let read = voicing >= cfg.pitch_voiced && f0 > 0.0;
        if !(truth.voicing >= cfg.pitch_voiced && truth.f0 > 0.0) {
            self.unvoiced_read += usize::from(read);
            return;
        }
        self.voiced += 1;
        if read {
            self.voiced_read += 1;
            let off = (f0 / truth.f0 - 1.0).abs();
            self.within += usize::from(off <= cfg.pitch_tolerance);
            self.gross += usize::from(off > GROSS_ERROR);
        }
    }

    fn figures(&self) -> PitchFigures {
        let share = |n: usize, of: usize| (of > 0).then(|| n as f64 / of as f64);
        PitchFigures {
            voiced_recall: share(self.voiced_read, self.voiced),
            false_voicing: share(self.unvoiced_read, self.frames - self.voiced),
            f0_within_tolerance: share(self.within, self.voiced_read),
            gross_error: share(self.gross, self.voiced_read),
        }
    }

    /// The counts with their figures.
    fn frame_figures(&self) -> FrameFigures {
        FrameFigures {
            frames: self.frames,
            voiced_frames: self.voiced,
            figures: self.figures(),
        }
    }

    /// [`Counts::frame_figures`], `None` without a frame.
    fn any_frame_figures(&self) -> Option<FrameFigures> {
        (self.frames > 0).then(|| self.frame_figures())
    }

    fn merge(&mut self, o: &Counts) {
        self.frames += o.frames;
        self.voiced += o.voiced;
        self.voiced_read += o.voiced_read;
        self.unvoiced_read += o.unvoiced_read;
        self.within += o.within;
        self.gross += o.gross;
    }
}

/// Scores `lines` against `sources`, each compared with its mapped label (`labels[i]`, none:
/// not scored), their signals at `sample_rate` Hz; `off_stream[i]` holds the (start, end)
/// times (s) of the blocks source i's own stream does not carry (missing: none).
pub fn score_pitch(
    lines: &[PitchLine],
    sources: &[&TruthSource],
    labels: &[Option<Label>],
    off_stream: &[Vec<(f64, f64)>],
    sample_rate: f64,
    cfg: &EvalConfig,
) -> PitchReport {
    let frame = (cfg.pitch_frame_s * sample_rate).round().max(2.0) as usize;
    let yin = Yin::new(sample_rate, cfg.pitch_f0_min_hz, cfg.pitch_f0_max_hz, frame);
    let centres: Vec<usize> = lines
        .iter()
        .map(|l| (l.t * sample_rate).round().max(0.0) as usize)
        .collect();
    let mut scored = Vec::new();
    let mut pooled = Counts::default();
    for (i, (src, label)) in sources.iter().zip(labels).enumerate() {
        let (Some(signal), Some(label)) = (src.signal.as_deref(), *label) else {
            continue;
        };
        let blocks = off_stream.get(i).map_or(&[][..], Vec::as_slice);
        let truth = yin.track_at(signal, &centres);
        let (mut c, mut off) = (Counts::default(), Counts::default());
        for (line, t) in lines.iter().zip(&truth) {
            let read = line.labels.iter().find(|p| p.label == label);
            if let Some(p) = read {
                c.add(*t, p.f0, p.voicing, cfg);
            }
            // In a lost block a frame without the label's stream (not yet born, say) is a frame
            // it did not read, not one to leave out.
            if blocks.iter().any(|&(a, b)| (a..b).contains(&line.t)) {
                let (f0, voicing) = read.map_or((0.0, 0.0), |p| (p.f0, p.voicing));
                off.add(*t, f0, voicing, cfg);
            }
        }
        pooled.merge(&off);
        scored.push(SourcePitch {
            id: src.id.clone(),
            label,
            whole: c.frame_figures(),
            off_stream: off.any_frame_figures(),
        });
    }
    let mean =
        |f: fn(&PitchFigures) -> Option<f64>| mean_of(scored.iter().map(|s| f(&s.whole.figures)));
    let mean = PitchFigures {
        voiced_recall: mean(|f| f.voiced_recall),
        false_voicing: mean(|f| f.false_voicing),
        f0_within_tolerance: mean(|f| f.f0_within_tolerance),
        gross_error: mean(|f| f.gross_error),
    };
    PitchReport {
        tolerance: cfg.pitch_tolerance,
        sources: scored,
        mean,
        off_stream: pooled.any_frame_figures(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::format::LabelPitch;

    const FS: f64 = 16_000.0;

    /// A 150 Hz voice with five harmonics during [start, end) s of a 2 s signal.
    fn voice(start: f64, end: f64) -> Vec<f32> {
        (0..(2.0 * FS) as usize)
            .map(|i| {
                let t = i as f64 / FS;
                if t < start || t >= end {
                    return 0.0;
                }
                (1..=5)
                    .map(|h| (std::f64::consts::TAU * 150.0 * h as f64 * t).sin() / h as f64)
                    .sum::<f64>() as f32
            })
            .collect()
    }

    fn source(signal: Vec<f32>) -> TruthSource {
        TruthSource {
            id: "s1".into(),
            signal: Some(signal),
            trajectory: Vec::new(),
            active: vec![(0.5, 1.5)],
        }
    }

    /// Lines every 32 ms with `read(t)` as the label's (F0, voicing).
    fn lines(label: Label, read: impl Fn(f64) -> (f64, f64)) -> Vec<PitchLine> {
        (0..62)
            .map(|j| {
                let t = j as f64 * 0.032;
                let (f0, voicing) = read(t);
                PitchLine {
                    t,
                    labels: vec![LabelPitch { label, f0, voicing }],
                }
            })
            .collect()
    }

    #[test]
    fn a_label_that_reads_its_voice_scores_full_marks_and_errors_are_counted() {
        let src = source(voice(0.5, 1.5));
        let l = Label::new(3, 0);
        let cfg = EvalConfig::default();
        let right = lines(l, |t| {
            if (0.5..1.5).contains(&t) {
                (151.0, 1.0)
            } else {
                (0.0, 0.0)
            }
        });
        let r = score_pitch(&right, &[&src], &[Some(l)], &[], FS, &cfg);
        let f = r.sources[0].whole.figures;
        assert!(r.sources[0].whole.voiced_frames >= 28, "{:?}", r.sources[0]);
        // A frame straddling an edge of the voice may count as voiced for YIN and not for
        // the label, or the other way round.
        assert!(f.voiced_recall.unwrap() >= 0.9, "{f:?}");
        assert!(f.false_voicing.unwrap() <= 0.1, "{f:?}");
        assert_eq!(
            (f.f0_within_tolerance, f.gross_error),
            (Some(1.0), Some(0.0))
        );

        // Reading the subharmonic throughout, and voicing in the silence before the voice.
        let wrong = lines(l, |t| if t < 1.5 { (75.0, 1.0) } else { (0.0, 0.0) });
        let r = score_pitch(&wrong, &[&src], &[Some(l)], &[], FS, &cfg);
        let f = r.sources[0].whole.figures;
        assert_eq!(
            (f.f0_within_tolerance, f.gross_error),
            (Some(0.0), Some(1.0))
        );
        assert!(f.false_voicing.unwrap() > 0.4, "{f:?}");
        assert_eq!(r.mean, f);
        assert!(r.sources[0].off_stream.is_none() && r.off_stream.is_none());
    }

    #[test]
    fn the_blocks_off_the_own_stream_are_scored_on_their_own() {
        // The label reads the voice right in its first half and not at all in its second,
        // and the second half is the block its own stream lost.
        let src = source(voice(0.5, 1.5));
        let l = Label::new(3, 0);
        let cfg = EvalConfig::default();
        let read = lines(l, |t| {
            if (0.5..1.0).contains(&t) {
                (151.0, 1.0)
            } else {
                (0.0, 0.0)
            }
        });
        let lost = vec![vec![(1.0, 1.5)]];
        let r = score_pitch(&read, &[&src], &[Some(l)], &lost, FS, &cfg);
        let whole = r.sources[0].whole.figures.voiced_recall.unwrap();
        let off = r.sources[0].off_stream.expect("frames in the lost block");
        assert!((0.4..0.6).contains(&whole), "{whole}");
        assert!(off.voiced_frames >= 14, "{off:?}");
        assert_eq!(off.figures.voiced_recall, Some(0.0));
        assert_eq!(off.figures.f0_within_tolerance, None);
        // One source: the pooled figures are its own.
        assert_eq!(r.off_stream, Some(off));
    }

    #[test]
    fn lost_blocks_follow_their_source_and_pool_every_count() {
        // An unmapped source first: the blocks are the sources', not the scored ones'.
        let (quiet, talker) = (source(voice(0.5, 1.5)), source(voice(0.5, 1.5)));
        let l = Label::new(3, 0);
        let cfg = EvalConfig::default();
        // Right up to 1.0 s, then the subharmonic (a gross error), over two adjacent blocks.
        let read = lines(l, |t| if t < 1.0 { (151.0, 1.0) } else { (75.0, 1.0) });
        let lost = vec![Vec::new(), vec![(0.768, 1.28), (1.28, 1.5)]];
        let r = score_pitch(&read, &[&quiet, &talker], &[None, Some(l)], &lost, FS, &cfg);
        assert_eq!(r.sources.len(), 1);
        let off = r.sources[0].off_stream.expect("frames in the lost blocks");
        // Frames at 0.768-0.992 s read right, 1.024-1.472 s wrong: 8 against 15.
        assert_eq!(off.frames, 23, "{off:?}");
        let f = off.figures;
        assert!(f.voiced_recall.unwrap() > 0.9, "{f:?}");
        let (within, gross) = (f.f0_within_tolerance.unwrap(), f.gross_error.unwrap());
        assert!((within - 8.0 / 23.0).abs() < 0.05 && (gross - 15.0 / 23.0).abs() < 0.05);
        assert_eq!(r.off_stream, Some(off));
        // A label without a stream in a lost block read nothing there.
        let absent = lines(Label::new(4, 0), |_| (151.0, 1.0));
        let r = score_pitch(&absent, &[&talker], &[Some(l)], &lost[1..], FS, &cfg);
        let off = r.sources[0].off_stream.expect("the block's frames");
        assert_eq!((r.sources[0].whole.frames, off.frames), (0, 23));
        assert_eq!(off.figures.voiced_recall, Some(0.0));
    }

    #[test]
    fn an_unmapped_source_or_a_label_without_a_stream_is_not_scored() {
        let src = source(voice(0.5, 1.5));
        let cfg = EvalConfig::default();
        let l = lines(Label::new(3, 0), |_| (150.0, 1.0));
        let r = score_pitch(&l, &[&src], &[None], &[], FS, &cfg);
        assert!(r.sources.is_empty() && r.mean == PitchFigures::default());
        let r = score_pitch(&l, &[&src], &[Some(Label::new(4, 0))], &[], FS, &cfg);
        assert_eq!(r.sources[0].whole.frames, 0);
        assert_eq!(r.sources[0].whole.figures, PitchFigures::default());
    }
}
