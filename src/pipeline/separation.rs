//! The separator's side of a pipeline, split in two so the separation can run on a thread of its
//! own. The pipeline keeps a [`SeparationFeed`]: after each step it hands over the step's new audio
//! with the targets of every STFT frame that audio completes. A [`SeparationDriver`] applies that
//! work in order (STFT framing, the separator, one inverse STFT per label) and emits the separated
//! audio as chunks aligned with the input's sample indices. The driver runs inline (offline) or
//! wherever the pipeline's owner puts it (a live session's separation thread); the same work in the
//! same order gives the same audio, sample for sample.

use std::collections::BTreeMap;

use crate::dsp::{Complex, FrameGeometry, Istft, MultiSpectrum, Stft};
use crate::geometry::Layout;
use crate::label::Label;
use crate::scene::format::LabelPitch;
use crate::separate::{Separator, SeparatorConfig, Target};

use super::config::ConfigError;
use super::{AudioHistory, EventSink, PipelineEvent, StepClock};

/// One unit of the separator's work, applied in the order the pipeline hands it out.
#[derive(Debug, Clone)]
pub enum SeparationWork {
    /// New audio and the targets of the frames it completes.
    Audio(SeparationChunk),
    /// Recalibration (same channels): the bank is kept.
    Layout(Box<Layout>),
    /// New separator settings, already validated, with the same framing.
    Config(Box<SeparatorConfig>),
    /// End of input: release the tails of every open stream.
    Flush,
}

/// Audio samples `[first_sample, first_sample + frames)` of every channel, and the separator's
/// targets for each STFT frame whose window ends within them.
#[derive(Debug, Clone)]
pub struct SeparationChunk {
    /// Input sample index of the first sample frame.
    pub first_sample: u64,
    /// Interleaved samples, all channels.
    pub samples: Vec<f32>,
    /// Targets of each completed frame, in frame order, at the frame's centre time.
    pub frames: Vec<Vec<Target>>,
}

/// Where a pipeline sends the separation work it does not apply itself.
pub type SeparationHandoff = Box<dyn FnMut(SeparationWork) + Send>;

/// Who applies the work.
enum Run {
    Inline(Box<SeparationDriver>),
    HandedOff(SeparationHandoff),
}

/// The pipeline's side: which frames are due and which audio has been handed over.
pub(super) struct SeparationFeed {
    geometry: FrameGeometry,
    /// Index m of the next STFT frame; frame m covers input samples [(m+1) hop - N, (m+1) hop).
    next_frame: u64,
    /// Samples before this index have been handed over.
    sent: u64,
    run: Run,
}

fn sep_err(e: crate::separate::ConfigError) -> ConfigError {
    e.within("separate")
}

impl SeparationFeed {
    /// A feed with its driver inline, for the layout's channels.
    pub fn new(layout: &Layout, cfg: &SeparatorConfig) -> Result<Self, ConfigError> {
        let driver = SeparationDriver::new(layout, cfg)?;
        Ok(Self {
            geometry: driver.geometry,
            next_frame: 0,
            sent: 0,
            run: Run::Inline(Box::new(driver)),
        })
    }

    /// STFT frame length (samples).
    pub fn frame_len(&self) -> usize {
        self.geometry.frame
    }

    /// Samples between the newest input a frame needs and the newest output it completes.
    pub fn delay_samples(&self) -> u64 {
        self.geometry.delay() as u64
    }

    /// From now on hands the work to `handoff`; returns the driver that applies it (None if it
    /// was handed off already).
    pub fn detach(&mut self, handoff: SeparationHandoff) -> Option<SeparationDriver> {
        match std::mem::replace(&mut self.run, Run::HandedOff(handoff)) {
            Run::Inline(driver) => Some(*driver),
            Run::HandedOff(previous) => {
                self.run = Run::HandedOff(previous);
                None
            }
        }
    }

    /// Hands over the audio up to the end of the last frame that ends by `end_sample`, with each
    /// frame's targets from `targets_at` (session time of the frame's centre).
    pub fn advance(
        &mut self,
        audio: &AudioHistory,
        end_sample: u64,
        clock: &StepClock,
        targets_at: impl Fn(f64) -> Vec<Target>,
        sink: &mut EventSink<'_>,
    ) {
        let (n, hop) = (self.geometry.frame as u64, self.geometry.hop as u64);
        let mut frames = Vec::new();
        while (self.next_frame + 1) * hop <= end_sample {
            let end = (self.next_frame + 1) * hop;
            let centre = clock.time_of(end) - 0.5 * n as f64 / clock.sample_rate as f64;
            frames.push(targets_at(centre));
            self.next_frame += 1;
        }
        let until = self.next_frame * hop;
        if frames.is_empty() || until <= self.sent {
            return;
        }
        let mut samples = Vec::new();
        if let Err(e) = audio.read_interleaved(self.sent, until, &mut samples) {
            // Cannot happen with the pipeline's history sizing; say so rather than emit garbage.
            sink(PipelineEvent::Warning {
                code: "separation_skipped",
                message: format!("separation skipped samples {}..{until}: {e}", self.sent),
            });
            samples = vec![0.0; (until - self.sent) as usize * audio.channels()];
        }
        let chunk = SeparationChunk {
            first_sample: self.sent,
            samples,
            frames,
        };
        self.sent = until;
        self.submit(SeparationWork::Audio(chunk), sink);
    }

    /// Recalibration: the separator keeps its bank.
    pub fn set_layout(&mut self, layout: &Layout) {
        self.submit(
            SeparationWork::Layout(Box::new(layout.clone())),
            &mut |_| {},
        );
    }

    /// Whether [`SeparationFeed::set_config`] would take `cfg`, without changing anything.
    pub fn check_config(&self, cfg: &SeparatorConfig) -> Result<(), ConfigError> {
        if cfg.frame_geometry() != self.geometry {
            return Err(ConfigError::new(
                "separate.frame",
                "the STFT framing cannot change on a running session",
            ));
        }
        cfg.validate().map_err(sep_err)
    }

    /// New separator settings with the same framing (labels and streams are kept); checked here,
    /// so a refusal reaches the caller wherever the driver runs.
    pub fn set_config(&mut self, cfg: &SeparatorConfig) -> Result<(), ConfigError> {
        self.check_config(cfg)?;
        self.submit(SeparationWork::Config(Box::new(cfg.clone())), &mut |_| {});
        Ok(())
    }

    /// Makes the inline driver emit each frame's pitches ([`PipelineEvent::Pitch`]); false
    /// when the driver has been handed off.
    pub fn record_pitch(&mut self) -> bool {
        match &mut self.run {
            Run::Inline(driver) => {
                driver.record_pitch = true;
                true
            }
            Run::HandedOff(_) => false,
        }
    }

    /// End of input: the driver releases every stream's tail.
    pub fn flush(&mut self, sink: &mut EventSink<'_>) {
        self.submit(SeparationWork::Flush, sink);
    }

    fn submit(&mut self, work: SeparationWork, sink: &mut EventSink<'_>) {
        match &mut self.run {
            Run::Inline(driver) => driver.apply(work, sink),
            Run::HandedOff(handoff) => handoff(work),
        }
    }
}

/// The separator with its framing state: applies [`SeparationWork`] in order.
pub struct SeparationDriver {
    separator: Separator,
    geometry: FrameGeometry,
    stft: Stft,
    spectra: MultiSpectrum,
    frame: Vec<f64>,
    /// The last frame's worth of input (and the chunk being consumed).
    history: AudioHistory,
    /// Index of the next frame, as in [`SeparationFeed`].
    next_frame: u64,
    streams: BTreeMap<Label, Istft>,
    out: Vec<(Label, Vec<Complex>)>,
    hop_out: Vec<f64>,
    /// Emit each frame's pitches ([`PipelineEvent::Pitch`]).
    record_pitch: bool,
}

impl SeparationDriver {
    /// A driver for the layout's channels.
    fn new(layout: &Layout, cfg: &SeparatorConfig) -> Result<Self, ConfigError> {
        let separator = Separator::new(layout, cfg).map_err(sep_err)?;
        let geometry = separator.frame_geometry();
        Ok(Self {
            separator,
            geometry,
            stft: Stft::new(geometry.frame),
            spectra: MultiSpectrum::zeros(layout.channel_count(), geometry.bins()),
            frame: vec![0.0; geometry.frame],
            history: AudioHistory::new(layout.channel_count(), geometry.frame + geometry.hop),
            next_frame: 0,
            streams: BTreeMap::new(),
            out: Vec::new(),
            hop_out: vec![0.0; geometry.hop],
            record_pitch: false,
        })
    }

    /// Applies one unit of work, handing the separated audio it completes to `sink`.
    pub fn apply(&mut self, work: SeparationWork, sink: &mut EventSink<'_>) {
        let refused = match work {
            SeparationWork::Audio(chunk) => {
                self.run_chunk(&chunk, sink);
                None
            }
            SeparationWork::Layout(layout) => self.separator.set_layout(&layout).err(),
            SeparationWork::Config(cfg) => self.separator.set_config(&cfg).err(),
            SeparationWork::Flush => {
                self.flush(sink);
                None
            }
        };
        // The feed checks what it hands over, so this is a bug, not bad input: keep separating.
        if let Some(e) = refused {
            sink(PipelineEvent::Warning {
                code: "separation_setting_refused",
                message: format!("separate.{}: {}", e.field, e.message),
            });
        }
    }

    fn run_chunk(&mut self, chunk: &SeparationChunk, sink: &mut EventSink<'_>) {
        let channels = self.history.channels().max(1);
        let frames_in = (chunk.samples.len() / channels) as u64;
        let (n, hop) = (self.geometry.frame as u64, self.geometry.hop as u64);
        let chunk_end = chunk.first_sample + frames_in;
        if chunk.first_sample > self.history.end() {
            self.history
                .append_silence((chunk.first_sample - self.history.end()) as usize);
        }
        let mut frames = chunk.frames.iter();
        loop {
            let end = (self.next_frame + 1) * hop;
            if end > chunk_end {
                break;
            }
            let Some(targets) = frames.next() else { break };
            self.append_until(chunk, end);
            let from = end as i64 - n as i64;
            if self.transform(from) {
                self.separator
                    .process_into(&self.spectra, targets, &mut self.out);
                if self.record_pitch {
                    self.emit_pitch(end - n / 2, sink);
                }
                self.emit_frame(from, sink);
            }
            self.next_frame += 1;
        }
        self.append_until(chunk, chunk_end);
    }

    /// Emits the separator's pitch of each label in the frame centred at `centre_sample`.
    fn emit_pitch(&self, centre_sample: u64, sink: &mut EventSink<'_>) {
        let labels: Vec<LabelPitch> = self
            .separator
            .pitches()
            .map(|(label, p)| LabelPitch {
                label,
                f0: p.f0,
                voicing: p.voicing,
            })
            .collect();
        if !labels.is_empty() {
            sink(PipelineEvent::Pitch {
                centre_sample,
                labels,
            });
        }
    }

    /// Appends the chunk's samples from the history's end up to sample index `until`.
    fn append_until(&mut self, chunk: &SeparationChunk, until: u64) {
        let channels = self.history.channels();
        let have = self.history.end().max(chunk.first_sample);
        if until <= have {
            return;
        }
        let a = (have - chunk.first_sample) as usize * channels;
        let b = (until - chunk.first_sample) as usize * channels;
        self.history.append_interleaved(&chunk.samples[a..b]);
    }

    /// The STFT of the frame starting at `from`; false when the history does not hold it.
    fn transform(&mut self, from: i64) -> bool {
        for ch in 0..self.history.channels() {
            if self.history.read(ch, from, &mut self.frame).is_err() {
                return false;
            }
            self.stft.forward(&self.frame, self.spectra.channel_mut(ch));
        }
        true
    }

    /// Pushes the separator's output of the frame at `from` through each label's inverse STFT;
    /// streams whose label has gone are flushed.
    fn emit_frame(&mut self, from: i64, sink: &mut EventSink<'_>) {
        for (label, bins) in &self.out {
            let istft = self
                .streams
                .entry(*label)
                .or_insert_with(|| Istft::new(self.geometry));
            istft.push(bins, &mut self.hop_out);
            push_chunk(sink, *label, from, &self.hop_out);
        }
        let finished: Vec<Label> = self
            .streams
            .keys()
            .filter(|l| !self.out.iter().any(|(o, _)| o == *l))
            .copied()
            .collect();
        for label in finished {
            if let Some(istft) = self.streams.remove(&label) {
                let last_from = from - self.geometry.hop as i64;
                flush_stream(
                    sink,
                    label,
                    istft,
                    last_from,
                    self.geometry,
                    &mut self.hop_out,
                );
            }
        }
    }

    /// Emits the overlap tails of every open stream (end of input).
    fn flush(&mut self, sink: &mut EventSink<'_>) {
        let last_from =
            (self.next_frame * self.geometry.hop as u64) as i64 - self.geometry.frame as i64;
        for (label, istft) in std::mem::take(&mut self.streams) {
            flush_stream(
                sink,
                label,
                istft,
                last_from,
                self.geometry,
                &mut self.hop_out,
            );
        }
    }
}

/// Pushes silence through an inverse STFT to release the tail of its last frames; `last_from` is
/// the first sample of the chunk the last pushed frame released.
fn flush_stream(
    sink: &mut EventSink<'_>,
    label: Label,
    mut istft: Istft,
    last_from: i64,
    geometry: FrameGeometry,
    hop_out: &mut [f64],
) {
    let zeros = vec![Complex::new(0.0, 0.0); geometry.bins()];
    let tail_hops = geometry.frame.div_ceil(geometry.hop).saturating_sub(1);
    for i in 0..tail_hops {
        istft.push(&zeros, hop_out);
        push_chunk(
            sink,
            label,
            last_from + ((i + 1) * geometry.hop) as i64,
            hop_out,
        );
    }
}

/// Emits a chunk that starts at input sample `from`, dropping any part before sample 0.
fn push_chunk(sink: &mut EventSink<'_>, label: Label, from: i64, samples: &[f64]) {
    let skip = (-from).max(0) as usize;
    if skip >= samples.len() {
        return;
    }
    sink(PipelineEvent::Audio {
        label,
        first_sample: (from + skip as i64) as u64,
        samples: samples[skip..].iter().map(|&s| s as f32).collect(),
    });
}
