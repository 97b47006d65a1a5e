//! The separator: a bank of per-label beamformers keyed by label, run one STFT frame at a time.

use super::blocking::Blocking;
use super::config::{BeamformerKind, ConfigError, MicSelection, PostFilterTarget, SeparatorConfig};
use super::lifecycle::Timing;
use super::null_steering::NullSteering;
use super::postfilter::{PostFilter, PostState};
use super::rls::{self, RlsStep};
use super::steering::Steering;
use super::stream::Stream;
use super::{Target, mvdr};
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
    ur: Vec<f64>,
    ui: Vec<f64>,
    scratch: Vec<f64>,
    mat: Vec<Complex>,
    w: Vec<Complex>,
    w2: Vec<Complex>,
    post: Vec<PostState>,
    /// Per stream: prior weight in the post-filter's competition for the bins.
    priors: Vec<f64>,
    gains: Vec<f64>,
    energy: Vec<f64>,
    present: Vec<bool>,
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
    domega: f64,
    timing: Timing,
    post: PostFilter,
    psd: Vec<f64>,
    psd_ready: bool,
    /// Smoothed power of the reference microphone per bin (post-filter).
    ref_power: Vec<f64>,
    streams: Vec<Stream>,
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
            domega: 0.0,
            timing: Timing {
                fade_in: 0,
                grace: 0,
                fade_out: 1,
            },
            post: PostFilter::new(&cfg.post_filter, 1.0),
            psd: Vec::new(),
            psd_ready: false,
            ref_power: Vec::new(),
            streams: Vec::new(),
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

    /// Labels that currently have a stream, in birth order.
    pub fn labels(&self) -> Vec<Label> {
        self.streams.iter().map(|s| s.label).collect()
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
            for s in &mut self.streams {
                s.needs_reset = true;
            }
        }
        self.rebuild_groups();
        self.apply_config();
        Ok(())
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
        resize_outputs(out, self.streams.len(), bins);
        for (s, (label, o)) in self.streams.iter().zip(out.iter_mut()) {
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
        resize_outputs(out, self.streams.len(), self.bins);
        for (s, (label, o)) in self.streams.iter().zip(out.iter_mut()) {
            *label = s.label;
            o[..self.k_lo].fill(Complex::new(0.0, 0.0));
            o[self.k_hi..].fill(Complex::new(0.0, 0.0));
        }
        self.run_bins(out);
        let t = self.timing;
        self.streams.retain(|s| !s.envelope.is_dead(&t));
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
        for s in &mut self.streams {
            s.steering_changed = true;
            s.constraints_changed = true;
            s.steering
                .iter_mut()
                .for_each(|st| *st = Steering::default());
        }
        for s in &mut self.streams {
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
            for s in &mut self.streams {
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
        let frames_per_s = self.fs / geom.hop as f64;
        self.timing = Timing::new(&self.cfg.lifecycle, frames_per_s);
        self.post = PostFilter::new(&self.cfg.post_filter, frames_per_s);
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
        w.scratch.resize(2 * lp, 0.0);
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
        y.fill(Complex::new(0.0, 0.0));
        let nb = bins.min(spectra.bins());
        for c in 0..ch.min(spectra.channels()) {
            for (k, v) in spectra.channel(c)[..nb].iter().enumerate() {
                y[k * ch + c] = sanitise(*v);
            }
        }
        let a = if self.psd_ready { PSD_SMOOTHING } else { 0.0 };
        for (k, p) in self.psd.iter_mut().enumerate() {
            let e: f64 = y[k * ch..(k + 1) * ch].iter().map(|v| v.norm_sqr()).sum();
            let e = e / ch.max(1) as f64;
            *p = if e.is_finite() {
                a * *p + (1.0 - a) * e
            } else {
                *p
            };
        }
        self.psd_ready = true;
    }

    /// Births, updates and absences from this frame's targets.
    fn update_bank(&mut self, targets: &[Target]) {
        let present = &mut self.work.present;
        present.clear();
        present.resize(self.streams.len(), false);
        for (i, t) in targets.iter().enumerate() {
            if targets[..i].iter().any(|u| u.label == t.label) {
                continue;
            }
            let finite = t.position.iter().all(|v| v.is_finite());
            let presence = presence_of(t);
            match self.streams.iter().position(|s| s.label == t.label) {
                Some(j) => {
                    if finite {
                        self.streams[j].position = t.position;
                        self.streams[j].direction_only = t.direction_only;
                    }
                    self.streams[j].presence = presence;
                    present[j] = true;
                }
                None if finite => {
                    let mut s =
                        Stream::new(t.label, t.position, t.direction_only, self.groups.len());
                    s.presence = presence;
                    self.streams.push(s);
                    present.push(true);
                }
                None => {}
            }
        }
        for (s, &p) in self.streams.iter_mut().zip(present.iter()) {
            s.envelope.step(p, &self.timing);
            s.gain = s.envelope.gain();
            if !p {
                // Steering at a stale position: do not learn.
                s.presence = 1.0;
            }
        }
    }

    /// Chooses each stream's group, sizes and resets its state, computes its steering and the
    /// null constraints, and starts the walks over the bins.
    fn prepare_streams(&mut self) {
        let kind = self.cfg.beamformer;
        let ngroups = self.groups.len();
        let (bins, k_lo) = (self.bins, self.k_lo);
        for s in &mut self.streams {
            let g = match self.cfg.mics {
                MicSelection::All => 0,
                MicSelection::NearestArray => nearest_group(&self.groups, s),
            };
            if g != s.group {
                s.group = g;
                s.needs_reset = true;
            }
            let m = self.groups[g].channels.len();
            s.fit(kind, bins, m, ngroups);
            if s.needs_reset {
                s.reset_adaptive(kind, m, self.cfg.rls.init_regularisation, &self.psd);
                s.steering_changed = true;
                s.steering
                    .iter_mut()
                    .for_each(|st| *st = Steering::default());
            }
            if s.blocking.len() != bins || s.blocking.first().is_some_and(|b| b.mics() != m) {
                s.blocking = vec![Blocking::new(m); bins];
                s.steering_changed = true;
            }
        }
        let n = self.streams.len();
        // The fixed beamformers and blocking matrices depend only on the steering: they are
        // rebuilt when a label's steering moves beyond the tolerance or the bank changes, and
        // the steering in use stays put in between (a stale steering errs by at most the
        // tolerance in phase at the top bin).
        let omega_max = self.domega * self.k_hi.saturating_sub(1) as f64;
        let tol = self.cfg.steering_tolerance_rad;
        let bank_changed = self.last_bank.len() != n
            || self
                .last_bank
                .iter()
                .zip(&self.streams)
                .any(|(&(l, g), s)| l != s.label || g != s.group);
        self.last_bank.clear();
        self.last_bank
            .extend(self.streams.iter().map(|s| (s.label, s.group)));
        let w = &mut self.work;
        w.active.fill(false);
        w.rebuild.fill(false);
        for s in &self.streams {
            w.active[s.group] = true;
        }
        for (g, grp) in self.groups.iter().enumerate() {
            if !w.active[g] {
                continue;
            }
            let m = grp.channels.len();
            w.walk[g].resize(n * m, Complex::new(0.0, 0.0));
            w.step[g].resize(n * m, Complex::new(0.0, 0.0));
            w.shared[g] = n <= m;
            if w.ns_bins[g].len() != bins {
                w.ns_bins[g] = vec![NullSteering::default(); bins];
                w.rebuild[g] = true;
            }
            w.rebuild[g] |= bank_changed;
            for (i, s) in self.streams.iter_mut().enumerate() {
                let st = &mut w.candidate;
                if s.direction_only {
                    let dir = s.position - grp.centroid;
                    st.set_far_field(&grp.mics, &self.reference_pos, &dir, self.c);
                } else {
                    st.set_near_field(&grp.mics, &self.reference_pos, &s.position, self.c);
                }
                if s.steering[g].differs(st, omega_max, tol) {
                    std::mem::swap(&mut s.steering[g], st);
                    w.rebuild[g] = true;
                    if s.group == g {
                        s.steering_changed = true;
                    }
                }
                let st = &s.steering[g];
                let omega0 = self.domega * k_lo as f64;
                st.start_walk(
                    omega0,
                    self.domega,
                    &mut w.walk[g][i * m..(i + 1) * m],
                    &mut w.step[g][i * m..(i + 1) * m],
                );
            }
        }
        // Capped null constraints: the loudest other labels get the M - 1 nulls.
        for i in 0..n {
            let g = self.streams[i].group;
            let m = self.groups[g].channels.len();
            if n <= m {
                self.streams[i].constraints.clear();
                self.streams[i].constraints_changed = true;
                continue;
            }
            let mut order: Vec<usize> = (0..n).filter(|&j| j != i).collect();
            order.sort_by(|&a, &b| {
                self.streams[b]
                    .power
                    .total_cmp(&self.streams[a].power)
                    .then(a.cmp(&b))
            });
            order.truncate(m - 1);
            order.insert(0, i);
            // Any steering moved on the group: its columns may be among this stream's.
            let moved = w.rebuild[g];
            let s = &mut self.streams[i];
            s.constraints_changed |= bank_changed || moved || s.constraints != order;
            s.constraints = order;
            if s.null_steering.len() != bins {
                s.null_steering = vec![NullSteering::default(); bins];
                s.constraints_changed = true;
            }
        }
        w.fixed.resize(n, Complex::new(0.0, 0.0));
        w.bf.resize(n, Complex::new(0.0, 0.0));
        w.ns_out.resize(n, Complex::new(0.0, 0.0));
        w.beta.resize(n, 0.0);
        w.post.resize(n, PostState::default());
        w.gains.resize(n, 1.0);
        w.priors.clear();
        for st in &self.streams {
            w.priors.push(self.post.prior(st.gain, st.presence));
        }
        w.energy.clear();
        w.energy.resize(n, 0.0);
        let rec = self.record;
        let ch = self.channels;
        for s in &mut self.streams {
            if rec {
                s.filters.resize(bins * ch, Complex::new(0.0, 0.0));
                s.filters.fill(Complex::new(0.0, 0.0));
            } else {
                s.filters.clear();
            }
        }
    }

    /// The per-bin work: fixed beamformers, adaptation control, adaptive stage, post-filter.
    fn run_bins(&mut self, out: &mut [(Label, Vec<Complex>)]) {
        let n = self.streams.len();
        if n == 0 {
            return;
        }
        for k in self.k_lo..self.k_hi {
            self.fixed_outputs(k);
            self.adaptation_weights(k);
            for i in 0..n {
                self.beamform(k, i);
            }
            self.post_filter(k, out);
            if k + 1 < self.k_hi {
                let w = &mut self.work;
                for g in 0..self.groups.len() {
                    if w.active[g] {
                        for (a, z) in w.walk[g].iter_mut().zip(&w.step[g]) {
                            *a *= z;
                        }
                    }
                }
            }
        }
        for (s, e) in self.streams.iter_mut().zip(&self.work.energy) {
            s.power = POWER_SMOOTHING * s.power + (1.0 - POWER_SMOOTHING) * e;
            s.steering_changed = false;
            s.constraints_changed = false;
        }
    }

    /// Null-steering outputs of every stream at bin `k` (delay-and-sum for that beamformer).
    fn fixed_outputs(&mut self, k: usize) {
        let ch = self.channels;
        let loading = self.cfg.null_loading;
        let das = self.cfg.beamformer == BeamformerKind::DelayAndSum;
        let w = &mut self.work;
        for (g, grp) in self.groups.iter().enumerate() {
            if !w.active[g] {
                continue;
            }
            let y = &w.y[k * ch..(k + 1) * ch];
            for (o, &c) in w.yg[g].iter_mut().zip(&grp.channels) {
                *o = y[c];
            }
            let m = grp.channels.len();
            if das {
                for (i, s) in self.streams.iter().enumerate() {
                    if s.group == g {
                        w.fixed[i] = delay_and_sum(&w.walk[g][i * m..(i + 1) * m], &w.yg[g]);
                    }
                }
            } else if w.shared[g] {
                let n = self.streams.len();
                let ns = &mut w.ns_bins[g][k];
                if w.rebuild[g] {
                    ns.prepare(&w.walk[g], n, m, loading);
                }
                ns.outputs(&w.walk[g], m, &w.yg[g], &mut w.ns_out);
                for (i, s) in self.streams.iter().enumerate() {
                    if s.group == g {
                        w.fixed[i] = w.ns_out[i];
                    }
                }
            } else {
                for (i, s) in self.streams.iter_mut().enumerate() {
                    if s.group != g {
                        continue;
                    }
                    let nc = s.constraints.len();
                    w.dsub.resize(nc * m, Complex::new(0.0, 0.0));
                    for (j, &c) in s.constraints.iter().enumerate() {
                        w.dsub[j * m..(j + 1) * m].copy_from_slice(&w.walk[g][c * m..(c + 1) * m]);
                    }
                    let ns = &mut s.null_steering[k];
                    if s.constraints_changed {
                        ns.prepare(&w.dsub, nc, m, loading);
                    }
                    ns.outputs(&w.dsub, m, &w.yg[g], &mut w.ns_out);
                    w.fixed[i] = w.ns_out[0];
                }
            }
        }
    }

    /// Adaptation weight per stream at bin `k`: 1 adapts fully, 0 freezes.
    fn adaptation_weights(&mut self, k: usize) {
        let a = &self.cfg.adaptation;
        let w = &mut self.work;
        let mut total = 0.0;
        for (s, f) in self.streams.iter_mut().zip(&w.fixed) {
            let p = &mut s.fixed_power[k];
            *p = a.power_smoothing * *p + (1.0 - a.power_smoothing) * f.norm_sqr();
            total += *p;
        }
        for (s, b) in self.streams.iter().zip(w.beta.iter_mut()) {
            let mut presence = s.presence;
            if a.per_bin && total > 0.0 {
                presence *= s.fixed_power[k] / total;
            }
            *b =
                ((a.presence_high - presence) / (a.presence_high - a.presence_low)).clamp(0.0, 1.0);
        }
    }

    /// The beamformer output of stream `i` at bin `k`, with its adaptive step.
    fn beamform(&mut self, k: usize, i: usize) {
        let kind = self.cfg.beamformer;
        let s = &mut self.streams[i];
        let g = s.group;
        let m = self.groups[g].channels.len();
        let w = &mut self.work;
        let a = &w.walk[g][i * m..(i + 1) * m];
        let y = &w.yg[g];
        let d = w.fixed[i];
        let power = self.psd[k];
        let out = match kind {
            BeamformerKind::DelayAndSum | BeamformerKind::NullSteering => d,
            BeamformerKind::Gsc => {
                let dims = s.rls_dims;
                let l = dims.l;
                let blocking = &mut s.blocking[k];
                if s.steering_changed {
                    blocking.set(a);
                }
                // The padding must be zero (another group may have left values there).
                w.ur[l..dims.lp].iter_mut().for_each(|x| *x = 0.0);
                w.ui[l..dims.lp].iter_mut().for_each(|x| *x = 0.0);
                blocking.apply_split(y, &mut w.ur[..l], &mut w.ui[..l]);
                let stride = dims.stride();
                let st = &mut s.rls[k * stride..(k + 1) * stride];
                let e = rls::output(st, dims, &w.ur, &w.ui, d);
                if self.record {
                    // Effective weights W - B V with the weights that made this output.
                    rls::weights(st, dims, &mut w.u[..l]);
                    s.blocking[k].combine(&w.u[..l], &mut w.w2[..m]);
                }
                let an: f64 = a.iter().map(|x| x.norm_sqr()).sum();
                let step = RlsStep {
                    forgetting: self.cfg.rls.forgetting,
                    leakage: self.cfg.rls.leakage,
                    max_norm2: self.cfg.rls.max_norm_ratio.powi(2) / an.max(1e-300),
                };
                let ok = rls::adapt(
                    st,
                    dims,
                    &w.ur,
                    &w.ui,
                    e,
                    w.beta[i],
                    power,
                    s.leak_index.wrapping_add(k),
                    &step,
                    &mut w.scratch,
                );
                if !ok {
                    s.reset_bin(kind, m, k, self.cfg.rls.init_regularisation, power);
                }
                e
            }
            BeamformerKind::Mvdr => {
                let st = &mut s.adaptive[k * s.stride..(k + 1) * s.stride];
                mvdr::update(st, m, y, w.beta[i], self.cfg.mvdr.forgetting);
                mvdr::weights(st, m, a, self.cfg.mvdr.loading, &mut w.mat, &mut w.w[..m]);
                let mut e = Complex::new(0.0, 0.0);
                for (wv, yv) in w.w[..m].iter().zip(y) {
                    e += wv.conj() * yv;
                }
                e
            }
        };
        let out = if out.is_finite() {
            out
        } else {
            s.reset_bin(kind, m, k, self.cfg.rls.init_regularisation, power);
            if d.is_finite() {
                d
            } else {
                Complex::new(0.0, 0.0)
            }
        };
        if k + 1 == self.k_hi {
            s.leak_index = s.leak_index.wrapping_add(1);
        }
        w.bf[i] = out;
        w.energy[i] += out.norm_sqr();
        if self.record {
            self.record_filter(k, i);
        }
    }

    /// Stores stream `i`'s beamformer weights at bin `k` (before the post-filter gain).
    fn record_filter(&mut self, k: usize, i: usize) {
        let ch = self.channels;
        let kind = self.cfg.beamformer;
        let s = &mut self.streams[i];
        let grp = &self.groups[s.group];
        let m = grp.channels.len();
        let w = &mut self.work;
        let a = &w.walk[s.group][i * m..(i + 1) * m];
        let weights = &mut w.w[..m];
        match kind {
            BeamformerKind::DelayAndSum => {
                let an: f64 = a.iter().map(|x| x.norm_sqr()).sum();
                for (o, a) in weights.iter_mut().zip(a) {
                    *o = a / an.max(1e-300);
                }
            }
            BeamformerKind::Mvdr => {}
            BeamformerKind::NullSteering | BeamformerKind::Gsc => {
                if w.shared[s.group] {
                    w.ns_bins[s.group][k].weights(&w.walk[s.group], m, i, weights);
                } else {
                    for (j, &c) in s.constraints.iter().enumerate() {
                        w.dsub[j * m..(j + 1) * m]
                            .copy_from_slice(&w.walk[s.group][c * m..(c + 1) * m]);
                    }
                    s.null_steering[k].weights(&w.dsub, m, 0, weights);
                }
                if kind == BeamformerKind::Gsc {
                    for (o, bv) in weights.iter_mut().zip(&w.w2[..m]) {
                        *o -= bv;
                    }
                }
            }
        }
        let f = &mut s.filters[k * ch..(k + 1) * ch];
        for (&c, x) in grp.channels.iter().zip(weights.iter()) {
            f[c] = *x;
        }
    }

    /// Post-filter gains at bin `k`; writes every stream's output bin into `out`.
    fn post_filter(&mut self, k: usize, out: &mut [(Label, Vec<Complex>)]) {
        let w = &mut self.work;
        for (p, s) in w.post.iter_mut().zip(&self.streams) {
            *p = s.post[k];
        }
        let yref = w.y[k * self.channels + self.reference];
        self.post.gains(
            &w.bf,
            &w.priors,
            &mut w.post,
            (yref, &mut self.ref_power[k]),
            &mut w.gains,
        );
        let to_ref =
            self.cfg.post_filter.apply_to == PostFilterTarget::ReferenceMic && self.post.enabled();
        let ch = self.channels;
        for (((s, p), (g, b)), (_, o)) in self
            .streams
            .iter_mut()
            .zip(&w.post)
            .zip(w.gains.iter().zip(&w.bf))
            .zip(out.iter_mut())
        {
            s.post[k] = *p;
            let scale = g * s.gain;
            o[k] = if to_ref { yref * scale } else { b * scale };
            if self.record {
                let f = &mut s.filters[k * ch..(k + 1) * ch];
                if to_ref {
                    f.fill(Complex::new(0.0, 0.0));
                    f[self.reference] = Complex::new(1.0, 0.0);
                }
                for x in f.iter_mut() {
                    *x *= scale;
                }
            }
        }
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

/// The array group (index >= 1) nearest to the stream, keeping the current one unless another is
/// clearly nearer.
fn nearest_group(groups: &[MicGroup], s: &Stream) -> usize {
    let dist = |g: usize| (groups[g].centroid - s.position).norm();
    let mut best = 1;
    for g in 2..groups.len() {
        if dist(g) < dist(best) {
            best = g;
        }
    }
    if s.group >= 1 && s.group < groups.len() && dist(best) > SWITCH_RATIO * dist(s.group) {
        s.group
    } else {
        best
    }
}

/// Presence of a target's speech this frame; unknown (NaN) counts as talking, so nothing is
/// learnt from it.
fn presence_of(t: &Target) -> f64 {
    let p = t.speaking * t.activity;
    if p.is_finite() {
        p.clamp(0.0, 1.0)
    } else {
        1.0
    }
}

fn sanitise(v: Complex) -> Complex {
    if v.is_finite() {
        v
    } else {
        Complex::new(0.0, 0.0)
    }
}

fn delay_and_sum(a: &[Complex], y: &[Complex]) -> Complex {
    let mut num = Complex::new(0.0, 0.0);
    let mut den = 0.0;
    for (a, y) in a.iter().zip(y) {
        num += a.conj() * y;
        den += a.norm_sqr();
    }
    if den > 1e-300 {
        num / den
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
