//! Separation: a time-varying bank of track-steered beamformers, one per label (seed paper
//! section 6; thesis section 4 and algorithms A7, A8), with a time-frequency post-filter.
//!
//! Per STFT frame and bin, for each label i among the current labels:
//! * steering: free-field relative transfer functions to the reference microphone, near-field
//!   from a 3-D position or far-field from a direction ([`steering`]);
//! * fixed branch: unit response toward i, nulls toward the other labels (loaded pseudo-inverse,
//!   at most M - 1 nulls) ([`null_steering`]);
//! * blocking matrix: an orthonormal basis of the complement of i's steering vector ([`blocking`]);
//! * adaptive canceller: complex RLS with forgetting, leakage and a norm bound, learning mainly
//!   while i is quiet (per-frame presence from the tracker, refined per bin) ([`rls`]);
//!   or an MVDR ([`mvdr`]), or plain delay-and-sum as the baseline;
//! * post-filter: a binary or soft mask from all labels' outputs, applied to the beamformer output
//!   or to the reference microphone ([`postfilter`]), then in the bins the array cannot resolve
//!   between labels, regrouped by each label's harmonic comb ([`harmonic`]);
//! * lifecycle: fade-in at birth, grace period when missing, fade-out at death ([`lifecycle`]).
//!
//! The caller does the STFT (`dsp::StreamingStft` with [`Separator::frame_geometry`]) and one
//! inverse per label (`dsp::Istft`); each output estimates the label's source image at the
//! reference microphone `layout.reference_channel()`.

pub mod blocking;
pub mod cholesky;
mod config;
pub mod demix;
pub mod direct_power;
mod footprint;
pub mod harmonic;
pub mod lifecycle;
pub mod mvdr;
pub mod nnls;
pub mod null_steering;
pub mod postfilter;
pub mod rls;
mod separator;
pub mod steering;
mod stream;

pub use config::{
    AdaptationConfig, BeamformerKind, ConfigError, HarmonicConfig, LifecycleConfig, MicSelection,
    MvdrConfig, PostFilterConfig, PostFilterKind, PostFilterTarget, RlsConfig, SeparatorConfig,
};
pub use footprint::footprint;
pub use separator::Separator;
pub use steering::Steering;

use crate::dsp::VoicePitch;
use crate::geometry::Vec3;
use crate::label::Label;

/// One label to separate at the current frame (the pipeline converts track estimates to these,
/// positions interpolated to the frame's time).
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    /// The track's label; keys the output stream.
    pub label: Label,
    /// Position (m, world frame); for `direction_only` any point along the direction.
    pub position: Vec3,
    /// Steer by direction only (far field from the array centroid toward `position`), for tracks
    /// whose range is unknown.
    pub direction_only: bool,
    /// The probability that this target is speaking, in [0, 1] (the pipeline's `speaking`).
    pub speaking: f64,
    /// This frame's voice-activity score, in [0, 1].
    pub activity: f64,
    /// The target's true pitch at this frame, used instead of (part of) the harmonic grouping's
    /// estimate (offline `--oracle-pitch` runs, which measure the grouping with the right pitch);
    /// `None` estimates it.
    pub pitch: Option<KnownPitch>,
}

/// Which part of a true pitch an oracle run hands the harmonic grouping.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PitchPart {
    /// F0 and voicing.
    #[default]
    Both,
    /// The F0 only; the voicing is the label's comb's at that F0, through the activity gate.
    F0,
    /// The voicing only; the grouping reads the F0 itself, and the true voicing replaces its
    /// comb's voicing and activity gate.
    Voicing,
}

/// A target's known pitch this frame: the part of its true pitch an oracle run hands over.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum KnownPitch {
    /// F0 and voicing.
    Both(VoicePitch),
    /// The F0 (Hz); 0 when the frame is silent.
    F0(f64),
    /// The voicing in [0, 1].
    Voicing(f64),
}

impl KnownPitch {
    /// `part` of `pitch`.
    pub fn new(part: PitchPart, pitch: VoicePitch) -> Self {
        match part {
            PitchPart::Both => Self::Both(pitch),
            PitchPart::F0 => Self::F0(pitch.f0),
            PitchPart::Voicing => Self::Voicing(pitch.voicing),
        }
    }
}
