//! Drives the separator: STFT framing of the audio history, one inverse STFT per label, and the
//! separated audio as chunks aligned with the input's sample indices.

use std::collections::BTreeMap;

use crate::dsp::{Complex, FrameGeometry, Istft, MultiSpectrum, Stft};
use crate::geometry::Layout;
use crate::label::Label;
use crate::separate::{Separator, SeparatorConfig, Target};

use super::config::ConfigError;
use super::{AudioHistory, PipelineEvent, StepClock};

/// The separator with its framing state.
pub struct SeparationDriver {
    separator: Separator,
    geometry: FrameGeometry,
    stft: Stft,
    spectra: MultiSpectrum,
    frame: Vec<f64>,
    /// Index m of the next STFT frame; frame m covers input samples [(m+1) hop - N, (m+1) hop).
    next_frame: u64,
    streams: BTreeMap<Label, Istft>,
    out: Vec<(Label, Vec<Complex>)>,
    hop_out: Vec<f64>,
}

fn sep_err(e: crate::separate::ConfigError) -> ConfigError {
    ConfigError::new(format!("separate.{}", e.field), e.message)
}

impl SeparationDriver {
    /// A driver for the layout's channels.
    pub fn new(layout: &Layout, cfg: &SeparatorConfig) -> Result<Self, ConfigError> {
        let separator = Separator::new(layout, cfg).map_err(sep_err)?;
        let geometry = separator.frame_geometry();
        Ok(Self {
            separator,
            geometry,
            stft: Stft::new(geometry.frame),
            spectra: MultiSpectrum::zeros(layout.channel_count(), geometry.bins()),
            frame: vec![0.0; geometry.frame],
            next_frame: 0,
            streams: BTreeMap::new(),
            out: Vec::new(),
            hop_out: vec![0.0; geometry.hop],
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

    /// Recalibration: the separator keeps its bank.
    pub fn set_layout(&mut self, layout: &Layout) -> Result<(), ConfigError> {
        self.separator.set_layout(layout).map_err(sep_err)
    }

    /// New separator settings with the same framing (labels and streams are kept).
    pub fn set_config(&mut self, cfg: &SeparatorConfig) -> Result<(), ConfigError> {
        if cfg.frame_geometry() != self.geometry {
            return Err(ConfigError::new(
                "separate.frame",
                "the STFT framing cannot change on a running session",
            ));
        }
        self.separator.set_config(cfg).map_err(sep_err)
    }

    /// Processes every frame whose window ends at or before `end_sample`, with targets at each
    /// frame's centre time.
    pub fn run_until(
        &mut self,
        audio: &AudioHistory,
        end_sample: u64,
        clock: &StepClock,
        targets_at: impl Fn(f64) -> Vec<Target>,
    ) -> Vec<PipelineEvent> {
        let (n, hop) = (self.geometry.frame as u64, self.geometry.hop as u64);
        let mut events = Vec::new();
        while (self.next_frame + 1) * hop <= end_sample {
            let end = (self.next_frame + 1) * hop;
            let from = end as i64 - n as i64;
            let mut ok = true;
            for ch in 0..audio.channels() {
                if audio.read(ch, from, &mut self.frame).is_err() {
                    ok = false;
                    break;
                }
                self.stft.forward(&self.frame, self.spectra.channel_mut(ch));
            }
            if !ok {
                // The history no longer holds this frame (cannot happen with the pipeline's
                // sizing); skip it rather than emit garbage.
                self.next_frame += 1;
                continue;
            }
            let centre = clock.time_of(end) - 0.5 * n as f64 / clock.sample_rate as f64;
            let targets = targets_at(centre);
            self.separator
                .process_into(&self.spectra, &targets, &mut self.out);
            for (label, bins) in &self.out {
                let istft = self
                    .streams
                    .entry(*label)
                    .or_insert_with(|| Istft::new(self.geometry));
                istft.push(bins, &mut self.hop_out);
                push_chunk(&mut events, *label, from, &self.hop_out);
            }
            let finished: Vec<Label> = self
                .streams
                .keys()
                .filter(|l| !self.out.iter().any(|(o, _)| o == *l))
                .copied()
                .collect();
            for label in finished {
                if let Some(istft) = self.streams.remove(&label) {
                    flush_stream(
                        &mut events,
                        label,
                        istft,
                        from - hop as i64,
                        self.geometry,
                        &mut self.hop_out,
                    );
                }
            }
            self.next_frame += 1;
        }
        events
    }

    /// Emits the overlap tails of every open stream (end of input).
    pub fn flush(&mut self) -> Vec<PipelineEvent> {
        let mut events = Vec::new();
        let last_from =
            (self.next_frame * self.geometry.hop as u64) as i64 - self.geometry.frame as i64;
        for (label, istft) in std::mem::take(&mut self.streams) {
            flush_stream(
                &mut events,
                label,
                istft,
                last_from,
                self.geometry,
                &mut self.hop_out,
            );
        }
        events
    }
}

/// Pushes silence through an inverse STFT to release the tail of its last frames; `last_from` is
/// the first sample of the chunk the last pushed frame released.
fn flush_stream(
    events: &mut Vec<PipelineEvent>,
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
            events,
            label,
            last_from + ((i + 1) * geometry.hop) as i64,
            hop_out,
        );
    }
}

/// Emits a chunk that starts at input sample `from`, dropping any part before sample 0.
fn push_chunk(events: &mut Vec<PipelineEvent>, label: Label, from: i64, samples: &[f64]) {
    let skip = (-from).max(0) as usize;
    if skip >= samples.len() {
        return;
    }
    events.push(PipelineEvent::Audio {
        label,
        first_sample: (from + skip as i64) as u64,
        samples: samples[skip..].iter().map(|&s| s as f32).collect(),
    });
}
