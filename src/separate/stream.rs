//! One label's stream in the bank: where it steers, its lifecycle and its per-bin adaptive state.

use super::KnownPitch;
use super::blocking::BlockingBank;
use super::config::BeamformerKind;
use super::harmonic::{PitchTrack, Register, Segment};
use super::lifecycle::Envelope;
use super::null_steering::NullSteering;
use super::postfilter::PostState;
use super::rls;
use super::steering::Steering;
use crate::dsp::Complex;
use crate::geometry::Vec3;
use crate::label::Label;

/// The state the bank keeps for one label.
#[derive(Debug, Clone)]
pub(super) struct Stream {
    pub label: Label,
    /// Last known position (or a point along the direction for direction-only targets).
    pub position: Vec3,
    pub direction_only: bool,
    /// Probability that the target talks this frame (speaking x activity); 1 while missing.
    pub presence: f64,
    pub envelope: Envelope,
    /// Whether the label is heard: open while it speaks, fading out once it has been unheard
    /// for `rest_after_s` (the stream then rests) and back in when it speaks again.
    pub rest: Envelope,
    /// The target's speaking probability reached `wake_speaking` this frame (or is unknown).
    pub heard: bool,
    /// Resting without its per-bin state (released for a new label under the stream cap).
    pub released: bool,
    /// This frame's gain: the lifecycle envelope's times the rest envelope's.
    pub gain: f64,
    /// Index of the microphone group the beamformer runs on.
    pub group: usize,
    /// Smoothed broadband output power; ranks the null constraints when they must be capped.
    pub power: f64,
    /// Steering toward this label on every microphone group (only active groups are current).
    pub steering: Vec<Steering>,
    /// MVDR covariance, `stride` values per bin.
    pub adaptive: Vec<Complex>,
    pub stride: usize,
    /// GSC canceller state, `rls_dims.stride()` values per bin.
    pub rls: Vec<rls::Real>,
    pub rls_dims: rls::Dims,
    /// The adaptive state must be (re)initialised before the next frame.
    pub needs_reset: bool,
    /// Smoothed fixed-beamformer power per bin (per-bin adaptation control).
    pub fixed_power: Vec<f64>,
    /// Post-filter state per bin.
    pub post: Vec<PostState>,
    /// Coordinate the RLS leakage visits next.
    pub leak_index: usize,
    /// Stream indices of the null-steering columns (itself first) when the nulls are capped.
    pub constraints: Vec<usize>,
    /// Effective filter of the last frame, bins x channels (only when recording).
    pub filters: Vec<Complex>,
    /// Blocking matrix per bin, built for `steering` (GSC).
    pub blocking: BlockingBank,
    /// Fixed beamformer per bin when the nulls are capped (this stream's own constraint set).
    pub null_steering: Vec<NullSteering>,
    /// The steering moved beyond the tolerance (or the stream is new): rebuild its blocking
    /// matrices this frame.
    pub steering_changed: bool,
    /// Rebuild this stream's capped fixed beamformers this frame.
    pub constraints_changed: bool,
    /// The label's pitch register (harmonic grouping).
    pub register: Register,
    /// The label's F0 track over frames (harmonic grouping).
    pub pitch_track: PitchTrack,
    /// The label's smoothed direct-path dominance (harmonic grouping's activity gate); a new
    /// label starts as talking.
    pub activity: f64,
    /// The label's voiced segment, as the activity hold follows it.
    pub segment: Segment,
    /// This frame the hold kept the gate open wider than the activity alone would.
    pub held: bool,
    /// The voicing the label's comb read last frame, before its activity gate (1 at birth: a
    /// new label counts as audible).
    pub comb_voicing: f64,
    /// Smoothed fitted power per bin below the harmonic fit's top (the fit's memory).
    pub fit_memory: Vec<f64>,
    /// This frame's known pitch from the target (oracle runs), used instead of (part of) the
    /// estimate.
    pub known_pitch: Option<KnownPitch>,
}

impl Stream {
    /// A new stream for `label`, born silent.
    pub fn new(label: Label, position: Vec3, direction_only: bool, groups: usize) -> Self {
        Self {
            label,
            position,
            direction_only,
            presence: 1.0,
            envelope: Envelope::born(),
            rest: Envelope::open(),
            released: false,
            heard: true,
            gain: 0.0,
            group: 0,
            power: 0.0,
            steering: vec![Steering::default(); groups],
            adaptive: Vec::new(),
            stride: 0,
            rls: Vec::new(),
            rls_dims: rls::Dims::new(0),
            needs_reset: true,
            fixed_power: Vec::new(),
            post: Vec::new(),
            leak_index: 0,
            constraints: Vec::new(),
            filters: Vec::new(),
            blocking: BlockingBank::default(),
            null_steering: Vec::new(),
            steering_changed: true,
            constraints_changed: true,
            register: Register::default(),
            pitch_track: PitchTrack::default(),
            activity: 1.0,
            segment: Segment::default(),
            held: false,
            comb_voicing: 1.0,
            fit_memory: Vec::new(),
            known_pitch: None,
        }
    }

    /// Sizes the per-bin state for `bins` bins and an `m`-microphone group; any change of shape
    /// (or an explicit request) resets it.
    pub fn fit(&mut self, kind: BeamformerKind, bins: usize, m: usize, groups: usize) {
        let stride = if kind == BeamformerKind::Mvdr {
            m * m
        } else {
            0
        };
        let dims = if kind == BeamformerKind::Gsc {
            rls::Dims::new(m - 1)
        } else {
            rls::Dims::new(0)
        };
        if self.stride != stride || self.rls_dims != dims || self.fixed_power.len() != bins {
            self.stride = stride;
            self.rls_dims = dims;
            self.needs_reset = true;
        }
        self.steering.resize(groups, Steering::default());
        if self.needs_reset {
            self.adaptive.clear();
            self.adaptive.resize(stride * bins, Complex::new(0.0, 0.0));
            self.rls.clear();
            if kind == BeamformerKind::Gsc {
                self.rls.resize(dims.stride() * bins, 0.0);
            }
            self.fixed_power.clear();
            self.fixed_power.resize(bins, 0.0);
            self.post.clear();
            self.post.resize(bins, PostState::default());
        }
    }

    /// Frees the per-bin state of a resting stream (its label, lifecycle and pitch history
    /// stay); the next [`Stream::fit`] after waking sizes and resets it again.
    pub fn release_state(&mut self) {
        self.adaptive = Vec::new();
        self.rls = Vec::new();
        self.fixed_power = Vec::new();
        self.post = Vec::new();
        self.filters = Vec::new();
        self.blocking = BlockingBank::default();
        self.null_steering = Vec::new();
        self.fit_memory = Vec::new();
        self.constraints = Vec::new();
        self.needs_reset = true;
        self.released = true;
    }

    /// Readies a resting stream to run again: its steering is recomputed and its fixed
    /// beamformers rebuilt, since the bank and the layout may have changed meanwhile.
    pub fn wake(&mut self) {
        self.released = false;
        self.forget_steering();
    }

    /// Drops the steering in use, so that the next frame computes it afresh and rebuilds the
    /// beamformers on it.
    pub fn forget_steering(&mut self) {
        self.steering
            .iter_mut()
            .for_each(|st| *st = Steering::default());
        self.steering_changed = true;
        self.constraints_changed = true;
    }

    /// Initialises the adaptive state of every bin from the input power per bin.
    pub fn reset_adaptive(&mut self, kind: BeamformerKind, m: usize, delta: f64, psd: &[f64]) {
        for (k, &power) in psd.iter().enumerate() {
            self.reset_bin(kind, m, k, delta, power);
        }
        self.needs_reset = false;
    }

    /// Initialises the adaptive state of bin `k`.
    pub fn reset_bin(&mut self, kind: BeamformerKind, m: usize, k: usize, delta: f64, power: f64) {
        match kind {
            BeamformerKind::Gsc => {
                let d = self.rls_dims;
                let st = d.stride();
                rls::reset(&mut self.rls[k * st..(k + 1) * st], d, delta, power);
            }
            BeamformerKind::Mvdr => {
                let s = self.stride;
                super::mvdr::reset(&mut self.adaptive[k * s..(k + 1) * s], m, power);
            }
            BeamformerKind::NullSteering | BeamformerKind::DelayAndSum => {}
        }
    }
}
