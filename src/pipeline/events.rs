//! What a pipeline emits: measurements, track estimates, separated audio and events.

use crate::label::Label;
use crate::scene::format::{AudioMeasurementLine, LabelPitch, TracksLine};

/// Where a pipeline hands its events, one by one as they are produced (a step's tracks before
/// its separated audio, so a live session can send them before the separation runs).
pub type EventSink<'a> = dyn FnMut(PipelineEvent) + 'a;

/// One output of a pipeline, in the order produced.
#[derive(Debug, Clone, PartialEq)]
pub enum PipelineEvent {
    /// The localiser's (or a device's) audio measurements of one array for one step.
    Measurements(AudioMeasurementLine),
    /// The tracker's estimate after step `step`.
    Tracks {
        /// Tracker step index.
        step: u64,
        /// The estimate, in the `tracks.jsonl` form.
        line: TracksLine,
    },
    /// A chunk of separated audio of one label, aligned with the input's sample indices.
    Audio {
        /// The track whose voice this is.
        label: Label,
        /// Input sample index of the first sample.
        first_sample: u64,
        /// Mono samples.
        samples: Vec<f32>,
    },
    /// Each label's pitch as the separator's harmonic grouping read it in one STFT frame (only
    /// when the pipeline records it, see [`crate::pipeline::Pipeline::record_pitch`]).
    Pitch {
        /// Input sample index of the frame's centre.
        centre_sample: u64,
        /// One entry per label with a stream.
        labels: Vec<LabelPitch>,
    },
    /// A label appeared for the first time.
    TrackBorn {
        /// Estimate time (s).
        t: f64,
        /// The new label.
        label: Label,
    },
    /// A label disappeared; it will not be reused.
    TrackEnded {
        /// Time of the last estimate that held it (s).
        t: f64,
        /// The ended label.
        label: Label,
    },
    /// Something worth telling the client (input dropped, gap bridged, ...).
    Warning {
        /// Machine-readable reason.
        code: &'static str,
        /// Explanation.
        message: String,
    },
}
