//! The separator: a bank of per-label beamformers keyed by label, run one STFT frame at a time.

mod bank;
mod bins;
mod grouping;

use super::Target;
use super::config::{ConfigError, SeparatorConfig};
use super::direct_power::DirectPowerFit;
use super::harmonic::RoomLevel;
use super::harmonic::{Harmonic, HarmonicFit, Periodicity, Pitch};
use super::lifecycle::Timing;
use super::nnls::Nnls;
use super::null_steering::NullSteering;
use super::postfilter::{PostFilter, PostState};
use super::rls;
use super::steering::Steering;
use super::stream::Stream;
use crate::dsp::{Complex, FrameGeometry, MultiSpectrum};
use crate::geometry::{Layout, Vec3};
use crate::label::Label;

/// Smoothing per frame of the input power spectrum that scales the regularisation.
const PSD_SMOOTHING: f64 = 0.9;
/// Smoothing per frame of each stream's broadband power (ranks capped null constraints).
const POWER_SMOOTHING: f64 = 0.8;
/// In `nearest_array` mode a label moves to another array only when that one is nearer by this
/// factor, so a label between two arrays does not flip back and forth.
const SWITCH_RATIO: f64 = 0.8;

/// Microphones one beamformer runs on.
#[derive(Debug, Clone)]
struct MicGroup {
    /// Layout columns, in the order of the steering vectors.
    channels: Vec<usize>,
    /// Positions of those microphones.
    mics: Vec<Vec3>,
    /// Origin of far-field directions.
    centroid: Vec3,
}

/// Per-frame scratch, kept between frames so `process` does not allocate.
#[derive(Debug, Default)]
struct Work {
    /// Sanitised input, bin-major: `channels` values per bin.
    y: Vec<Complex>,
    /// The input's mean power per processed bin and microphone this frame.
    frame_level: f64,
    /// Snapshot of each group's microphones at the current bin.
    yg: Vec<Vec<Complex>>,
    /// Per group: steering of every stream at the current bin, stream after stream.
    walk: Vec<Vec<Complex>>,
    /// Per group: per-bin phase step of every stream's steering.
    step: Vec<Vec<Complex>>,
    /// Whether any stream runs on the group this frame.
    active: Vec<bool>,
    /// Whether the group's streams share one constraint set (all labels as columns).
    shared: Vec<bool>,
    /// Per group and bin: the shared fixed beamformers, kept while no steering moves.
    ns_bins: Vec<Vec<NullSteering>>,
    /// Per group: rebuild `ns_bins` this frame.
    rebuild: Vec<bool>,
    /// Candidate steering, compared with the one in use.
    candidate: Steering,
    dsub: Vec<Complex>,
    ns_out: Vec<Complex>,
    fixed: Vec<Complex>,
    bf: Vec<Complex>,
    beta: Vec<f64>,
    u: Vec<Complex>,
    ur: Vec<rls::Real>,
    ui: Vec<rls::Real>,
    scratch: Vec<rls::Real>,
    mat: Vec<Complex>,
    w: Vec<Complex>,
    w2: Vec<Complex>,
    post: Vec<PostState>,
    /// Per bin, stream and competitor: how unresolved the stream's claim is against that
    /// competitor (harmonic grouping); recomputed only when the steering on the stream's group
    /// moved (`rebuild`).
    pair_unresolved: Vec<f64>,
    /// Per bin below the demixing's top, stream and label: the power response of the stream's
    /// fixed beamformer toward the label's steering; recomputed with the beamformers
    /// (`rebuild`).
    cross: Vec<f64>,
    /// Per bin below the demixing's top: the labels whose demixed power was positive in the
    /// last frame (bit per label), where the next frame's solve starts.
    demix_support: Vec<u32>,
    /// The demixing's solver.
    nnls: Nnls,
    /// The canceller's forgetting per update this frame.
    rls_forgetting: f64,
    /// Per stream: the bound on the canceller's squared norm this frame.
    max_norm2: Vec<f64>,
    /// Per stream: how likely its target talks this frame, for the adaptation control (the
    /// tracker's presence, or the activity gate's where that is larger).
    presence: Vec<f64>,
    /// Per stream: prior weight in the post-filter's competition for the bins.
    priors: Vec<f64>,
    gains: Vec<f64>,
    /// This frame's post-filter gains, bin-major (`streams` values per bin), written out once the
    /// harmonic grouping has seen the whole frame.
    frame_gains: Vec<f64>,
    /// This frame's beamformer outputs, bin-major.
    frame_bf: Vec<Complex>,
    /// How unresolved each stream's claim is per bin (harmonic grouping), bin-major.
    frame_unresolved: Vec<f64>,
    /// Per stream: how much it counts as a competitor where another stream reads its F0.
    audibility: Vec<f64>,
    /// Per-bin scratch of the F0 analysis: a stream's magnitude (over every processed bin when
    /// the periodicity reads the voicing, else up to the F0 analysis's top) and the bins'
    /// reliability (up to that top).
    mag: Vec<f64>,
    reliability: Vec<f64>,
    /// Interpolation table of the F0 analysis.
    pitch_table: Vec<[f64; 4]>,
    /// Per bin: the mixture's local level that divides contest saliences, and a stream's
    /// magnitudes divided by it.
    level: Vec<f64>,
    whitened: Vec<f64>,
    /// Per stream: this frame's pitch, how much of it is the stream's own, and (per bin) its
    /// harmonic evidence.
    pitch: Vec<Pitch>,
    ownership: Vec<f64>,
    evidence: Vec<f64>,
    /// Per stream: its weight in the current bin's regrouping.
    shares: Vec<f64>,
    /// The harmonic amplitude fit's F0s (per stream), fitted power (per stream and bin) and
    /// residual (per bin).
    fit_f0s: Vec<f64>,
    /// The reference microphone's bins below the fit's top.
    fit_x: Vec<Complex>,
    fit_power: Vec<f64>,
    fit_residual: Vec<f64>,
    /// Per stream and bin: the weight of its memory in its claims on the fit's harmonics.
    fit_weight: Vec<f64>,
    energy: Vec<f64>,
    present: Vec<bool>,
    /// Per resting stream: whether its label is among this frame's targets.
    resting_present: Vec<bool>,
}

/// A bank of per-label beamformers with a time-frequency post-filter.
///
/// Each call to [`Separator::process`] takes one STFT frame of every layout channel and the
/// current targets and returns, for every label that has a stream, an estimate of that source's
/// image at the reference microphone `layout.reference_channel()` (its direct path through the
/// distortionless beamformer, or the reference microphone itself under the post-filter's gain
/// with `post_filter.apply_to = reference_mic`).
pub struct Separator {
    cfg: SeparatorConfig,
    fs: f64,
    c: f64,
    channels: usize,
    reference: usize,
    reference_pos: Vec3,
    groups: Vec<MicGroup>,
    bins: usize,
    k_lo: usize,
    k_hi: usize,
    /// One past the last bin whose post-filter demixes the beamformers' cross-responses.
    k_demix: usize,
    domega: f64,
    timing: Timing,
    /// The rest envelope's timing (`None`: labels never rest).
    rest_timing: Option<Timing>,
    post: PostFilter,
    harmonic: Harmonic,
    /// The harmonic grouping's amplitude fit of the low bins (fits nothing when off).
    harmonic_fit: HarmonicFit,
    /// The labels' periodicity reader (one for all, as it keeps only scratch between calls).
    periodicity: Periodicity,
    /// Per microphone group: the direct-path power fit of the harmonic grouping's activity gate
    /// (empty when the gate is off).
    direct: Vec<DirectPowerFit>,
    /// Per microphone group: the room level that scales the activity gate's thresholds (empty
    /// when the gate is off).
    levels: Vec<RoomLevel>,
    psd: Vec<f64>,
    psd_ready: bool,
    /// Smoothed power of the reference microphone per bin (post-filter).
    ref_power: Vec<f64>,
    streams: Vec<Stream>,
    /// Streams whose labels have not been heard for `rest_after_s`: silent, not processed, in
    /// the order they came to rest.
    resting: Vec<Stream>,
    /// Labels and groups of the bank at the last frame (a change rebuilds the fixed beamformers).
    last_bank: Vec<(Label, usize)>,
    record: bool,
    work: Work,
}

impl Separator {
    /// A separator for `layout` with configuration `cfg` (validated).
    pub fn new(layout: &Layout, cfg: &SeparatorConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let mut s = Self {
            cfg: cfg.clone(),
            fs: 0.0,
            c: 0.0,
            channels: 0,
            reference: 0,
            reference_pos: Vec3::zeros(),
            groups: Vec::new(),
            bins: 0,
            k_lo: 0,
            k_hi: 0,
            k_demix: 0,
            domega: 0.0,
            timing: Timing {
                fade_in: 0,
                grace: 0,
                fade_out: 1,
            },
            rest_timing: None,
            post: PostFilter::new(&cfg.post_filter, 1.0),
            harmonic: Harmonic::new(&cfg.post_filter.harmonic, 1.0, 1.0),
            harmonic_fit: HarmonicFit::default(),
            periodicity: Periodicity::new(4, 16000.0, 70.0, 400.0),
            direct: Vec::new(),
            levels: Vec::new(),
            psd: Vec::new(),
            psd_ready: false,
            ref_power: Vec::new(),
            streams: Vec::new(),
            resting: Vec::new(),
            last_bank: Vec::new(),
            record: false,
            work: Work::default(),
        };
        s.apply_layout(layout)?;
        s.apply_config();
        Ok(s)
    }

    /// The STFT frame and hop the separator expects (the caller's STFT and inverse use it).
    pub fn frame_geometry(&self) -> FrameGeometry {
        self.cfg.frame_geometry()
    }

    /// The configuration in use.
    pub fn config(&self) -> &SeparatorConfig {
        &self.cfg
    }

    /// Labels that currently have a stream: the running ones, then the resting ones.
    pub fn labels(&self) -> Vec<Label> {
        self.streams
            .iter()
            .chain(&self.resting)
            .map(|s| s.label)
            .collect()
    }

    /// Labels whose streams rest (silent, not processed) until they are heard again.
    pub fn resting_labels(&self) -> Vec<Label> {
        self.resting.iter().map(|s| s.label).collect()
    }

    /// Recalibration: new microphone or reference positions. The bank and its labels are kept; a
    /// label's adaptive state survives when its microphone group keeps its size.
    pub fn set_layout(&mut self, layout: &Layout) -> Result<(), ConfigError> {
        self.apply_layout(layout)?;
        self.apply_config();
        Ok(())
    }

    /// New settings. Labels are kept; per-bin state is reset when the framing, the beamformer or
    /// the microphone selection changes (the caller must then rebuild its STFT and inverse from
    /// [`Separator::frame_geometry`]).
    pub fn set_config(&mut self, cfg: &SeparatorConfig) -> Result<(), ConfigError> {
        cfg.validate()?;
        let reset = cfg.beamformer != self.cfg.beamformer || cfg.mics != self.cfg.mics;
        self.cfg = cfg.clone();
        if reset {
            for s in self.streams.iter_mut().chain(&mut self.resting) {
                s.needs_reset = true;
            }
        }
        self.rebuild_groups();
        self.apply_config();
        Ok(())
    }

    /// The last frame's pitch of each label as the harmonic grouping read it: its F0 (Hz, 0 for
    /// none) and voicing in [0, 1] with the activity gate and hold folded in. Empty when the
    /// grouping is off.
    pub fn pitches(&self) -> impl Iterator<Item = (Label, &Pitch)> + '_ {
        self.streams
            .iter()
            .zip(&self.work.pitch)
            .map(|(s, p)| (s.label, p))
    }

    /// Records each frame's effective linear filter per label (for evaluation: running
    /// [`Separator::apply_last_filters`] on parts of the input splits the output into parts).
    pub fn record_filters(&mut self, on: bool) {
        self.record = on;
    }

    /// Applies the filters of the last processed frame to other spectra (e.g. one source's image
    /// alone): the output each label would have given for that input, post-filter gain and fade
    /// included. Requires [`Separator::record_filters`].
    pub fn apply_last_filters(
        &self,
        spectra: &MultiSpectrum,
        out: &mut Vec<(Label, Vec<Complex>)>,
    ) {
        let (bins, ch) = (self.bins, self.channels);
        resize_outputs(out, self.streams.len() + self.resting.len(), bins);
        for (s, (label, o)) in self.streams.iter().chain(&self.resting).zip(out.iter_mut()) {
            *label = s.label;
            o.fill(Complex::new(0.0, 0.0));
            if s.filters.len() != bins * ch {
                continue;
            }
            for (k, ok) in o.iter_mut().enumerate().take(bins.min(spectra.bins())) {
                let h = &s.filters[k * ch..(k + 1) * ch];
                let mut acc = Complex::new(0.0, 0.0);
                for (c, hc) in h.iter().enumerate().take(spectra.channels()) {
                    acc += hc.conj() * sanitise(spectra.at(c, k));
                }
                *ok = acc;
            }
        }
    }

    /// Processes one STFT frame: `spectra` holds every layout channel (column order), `targets`
    /// the labels to separate at this frame's time. Returns one spectrum (`bins` values) per label
    /// with a stream, including labels within their grace period or fading out.
    pub fn process(
        &mut self,
        spectra: &MultiSpectrum,
        targets: &[Target],
    ) -> Vec<(Label, Vec<Complex>)> {
        let mut out = Vec::new();
        self.process_into(spectra, targets, &mut out);
        out
    }

    /// [`Separator::process`] writing into `out`, whose buffers are reused (no allocation once
    /// the number of labels is stable).
    pub fn process_into(
        &mut self,
        spectra: &MultiSpectrum,
        targets: &[Target],
        out: &mut Vec<(Label, Vec<Complex>)>,
    ) {
        self.load_input(spectra);
        self.update_bank(targets);
        self.prepare_streams();
        let n = self.streams.len();
        resize_outputs(out, n + self.resting.len(), self.bins);
        for (s, (label, o)) in self.streams.iter().zip(out.iter_mut()) {
            *label = s.label;
            o[..self.k_lo].fill(Complex::new(0.0, 0.0));
            o[self.k_hi..].fill(Complex::new(0.0, 0.0));
        }
        // A resting stream carries silence, so its label's output stays continuous.
        for (s, (label, o)) in self.resting.iter().zip(out[n..].iter_mut()) {
            *label = s.label;
            o.fill(Complex::new(0.0, 0.0));
        }
        self.run_bins(&mut out[..n]);
        let t = self.timing;
        self.streams.retain(|s| !s.envelope.is_dead(&t));
        self.resting.retain(|s| !s.envelope.is_dead(&t));
    }

    fn apply_layout(&mut self, layout: &Layout) -> Result<(), ConfigError> {
        let channels = layout.channel_count();
        let reference = layout
            .reference_channel()
            .ok_or_else(|| ConfigError::new("layout.arrays", "carry no audio channels"))?;
        let mut pos = vec![Vec3::zeros(); channels];
        for a in &layout.arrays {
            for (m, &ch) in a.mics.iter().zip(&a.channels) {
                if ch < channels {
                    pos[ch] = *m;
                }
            }
        }
        self.fs = f64::from(layout.sample_rate);
        self.c = layout.speed_of_sound;
        self.channels = channels;
        self.reference = reference;
        self.reference_pos = pos[reference];
        let mut groups = Vec::new();
        let mut all: Vec<usize> = std::iter::once(reference)
            .chain((0..channels).filter(|&c| c != reference))
            .collect();
        all.dedup();
        groups.push(make_group(all, &pos));
        for a in &layout.arrays {
            if !a.channels.is_empty() {
                groups.push(make_group(a.channels.clone(), &pos));
            }
        }
        self.groups = groups;
        self.rebuild_groups();
        Ok(())
    }

    /// Which groups exist for the microphone selection: group 0 is all microphones, groups 1..
    /// the single arrays.
    fn rebuild_groups(&mut self) {
        let n = self.groups.len();
        self.work.walk.resize(n, Vec::new());
        self.work.step.resize(n, Vec::new());
        self.work.yg.resize(n, Vec::new());
        for (g, grp) in self.groups.iter().enumerate() {
            self.work.yg[g].resize(grp.channels.len(), Complex::new(0.0, 0.0));
        }
        self.work.active.resize(n, false);
        self.work.shared.resize(n, true);
        self.work.ns_bins.resize(n, Vec::new());
        self.work.rebuild.resize(n, true);
        // New microphone positions or settings: nothing cached holds.
        self.last_bank.clear();
        for s in self.streams.iter_mut().chain(&mut self.resting) {
            s.forget_steering();
            s.steering.resize(n, Default::default());
        }
    }

    fn apply_config(&mut self) {
        let geom = self.cfg.frame_geometry();
        let bins = geom.bins();
        if bins != self.bins {
            self.psd = vec![0.0; bins];
            self.ref_power = vec![0.0; bins];
            self.psd_ready = false;
            for s in self.streams.iter_mut().chain(&mut self.resting) {
                s.needs_reset = true;
            }
        }
        self.bins = bins;
        let nyquist = self.fs / 2.0;
        let hz_per_bin = self.fs / geom.frame as f64;
        let hi = self.cfg.max_frequency_hz.unwrap_or(nyquist).min(nyquist);
        self.k_lo = ((self.cfg.min_frequency_hz / hz_per_bin).ceil() as usize).min(bins);
        self.k_hi = ((hi / hz_per_bin).floor() as usize + 1).clamp(self.k_lo, bins);
        self.domega = 2.0 * std::f64::consts::PI * hz_per_bin;
        self.k_demix =
            ((self.cfg.post_filter.demix_below_hz / hz_per_bin).ceil() as usize).min(self.k_hi);
        let frames_per_s = self.fs / geom.hop as f64;
        self.timing = Timing::new(&self.cfg.lifecycle, frames_per_s);
        self.rest_timing = Timing::rest(&self.cfg.lifecycle, frames_per_s);
        self.post = PostFilter::new(&self.cfg.post_filter, frames_per_s);
        self.harmonic = Harmonic::new(&self.cfg.post_filter.harmonic, hz_per_bin, frames_per_s);
        let hcfg = &self.cfg.post_filter.harmonic;
        let fit_top = ((hcfg.fit_below_hz / hz_per_bin).ceil() as usize).min(self.k_hi);
        self.harmonic_fit = HarmonicFit::new(geom.frame, hz_per_bin, fit_top, hcfg.fit_loading);
        self.periodicity = Periodicity::new(geom.frame, self.fs, hcfg.f0_min_hz, hcfg.f0_max_hz);
        self.direct = if self.harmonic.gates_activity() {
            let low_band = hcfg.activity_low_band;
            self.groups
                .iter()
                .map(|g| DirectPowerFit::new(&g.mics, self.c, hz_per_bin, bins, low_band))
                .collect()
        } else {
            Vec::new()
        };
        self.levels = self
            .direct
            .iter()
            .map(|_| self.harmonic.room_level())
            .collect();
        let maxm = self
            .groups
            .iter()
            .map(|g| g.channels.len())
            .max()
            .unwrap_or(1);
        let w = &mut self.work;
        w.y.resize(bins * self.channels, Complex::new(0.0, 0.0));
        w.u.resize(maxm, Complex::new(0.0, 0.0));
        let lp = rls::Dims::new(maxm).lp;
        w.ur.resize(lp, 0.0);
        w.ui.resize(lp, 0.0);
        w.scratch.resize(rls::SCRATCH_PER_LANE * lp, 0.0);
        w.mat.resize(maxm * maxm, Complex::new(0.0, 0.0));
        w.w.resize(maxm, Complex::new(0.0, 0.0));
        w.w2.resize(maxm, Complex::new(0.0, 0.0));
        let kind = self.cfg.beamformer;
        let groups = self.groups.len();
        for s in &mut self.streams {
            let m = self.groups[s.group].channels.len();
            s.fit(kind, bins, m, groups);
        }
    }

    /// Copies the frame bin-major, non-finite values as zero, and updates the input PSD.
    fn load_input(&mut self, spectra: &MultiSpectrum) {
        let (bins, ch) = (self.bins, self.channels);
        let y = &mut self.work.y;
        let nb = bins.min(spectra.bins());
        let nc = ch.min(spectra.channels());
        if nb < bins || nc < ch {
            y.fill(Complex::new(0.0, 0.0));
        }
        for c in 0..nc {
            for (k, v) in spectra.channel(c)[..nb].iter().enumerate() {
                y[k * ch + c] = sanitise(*v);
            }
        }
        let a = if self.psd_ready { PSD_SMOOTHING } else { 0.0 };
        let mut processed = 0.0;
        for (k, p) in self.psd.iter_mut().enumerate() {
            let e: f64 = y[k * ch..(k + 1) * ch].iter().map(|v| v.norm_sqr()).sum();
            let e = e / ch.max(1) as f64;
            if (self.k_lo..self.k_hi).contains(&k) {
                processed += e;
            }
            *p = if e.is_finite() {
                a * *p + (1.0 - a) * e
            } else {
                *p
            };
        }
        self.work.frame_level = processed / (self.k_hi - self.k_lo).max(1) as f64;
        self.psd_ready = true;
    }
}

fn make_group(channels: Vec<usize>, pos: &[Vec3]) -> MicGroup {
    let mics: Vec<Vec3> = channels.iter().map(|&c| pos[c]).collect();
    let centroid = mics.iter().sum::<Vec3>() / mics.len().max(1) as f64;
    MicGroup {
        channels,
        mics,
        centroid,
    }
}

fn sanitise(v: Complex) -> Complex {
    if v.is_finite() {
        v
    } else {
        Complex::new(0.0, 0.0)
    }
}

fn resize_outputs(out: &mut Vec<(Label, Vec<Complex>)>, n: usize, bins: usize) {
    out.truncate(n);
    while out.len() < n {
        out.push((Label::new(0, 0), Vec::new()));
    }
    for (_, o) in out.iter_mut() {
        o.resize(bins, Complex::new(0.0, 0.0));
    }
}
