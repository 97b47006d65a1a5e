//! The per-bin work of a frame: fixed beamformers, adaptation control, the adaptive stage and
//! the post-filter.

use super::grouping::room_scale;
use super::{POWER_SMOOTHING, Separator, Work};
use crate::dsp::Complex;
use crate::label::Label;
use crate::separate::config::{
    AdaptationConfig, BeamformerKind, PostFilterTarget, SeparatorConfig,
};
use crate::separate::demix::Demixing;
use crate::separate::harmonic;
use crate::separate::mvdr;
use crate::separate::rls::{self, RlsStep};
use crate::separate::stream::Stream;

impl Separator {
    /// The per-bin work: fixed beamformers, adaptation control, adaptive stage, post-filter.
    pub(super) fn run_bins(&mut self, out: &mut [(Label, Vec<Complex>)]) {
        let n = self.streams.len();
        if n == 0 {
            return;
        }
        self.rls_constants();
        for (g, fit) in self.direct.iter_mut().enumerate() {
            if self.work.active[g] {
                fit.begin(n, self.work.frame_level);
            }
        }
        for k in self.k_lo..self.k_hi {
            self.fixed_outputs(k);
            self.fit_direct_power(k);
            self.adaptation_weights(k);
            for i in 0..n {
                self.beamform(k, i);
            }
            self.post_filter(k);
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
        self.write_bins(out);
        for (s, e) in self.streams.iter_mut().zip(&self.work.energy) {
            s.power = POWER_SMOOTHING * s.power + (1.0 - POWER_SMOOTHING) * e;
            s.steering_changed = false;
            s.constraints_changed = false;
        }
    }

    /// The adaptive stage's per-frame constants: the canceller's forgetting per update, each
    /// stream's norm bound (its steering's norm is the same in every bin: the walk only turns
    /// phases) and each stream's target presence for the adaptation control.
    fn rls_constants(&mut self) {
        let r = &self.cfg.rls;
        let w = &mut self.work;
        w.rls_forgetting = r.forgetting.powi(r.update_every.max(1) as i32);
        w.max_norm2.clear();
        for (i, s) in self.streams.iter().enumerate() {
            let m = self.groups[s.group].channels.len();
            let a = w.walk[s.group].get(i * m..(i + 1) * m).unwrap_or(&[]);
            let an: f64 = a.iter().map(|x| x.norm_sqr()).sum();
            w.max_norm2.push(r.max_norm_ratio.powi(2) / an.max(1e-300));
        }
        // The gate is measured only where the harmonic grouping runs.
        let gated = self.cfg.adaptation.activity_presence
            && self.harmonic.gates_activity()
            && self.post.enabled();
        w.presence.clear();
        w.presence.extend(self.streams.iter().map(|s| {
            let scale = room_scale(&self.levels, s.group);
            let gate = gated.then(|| self.harmonic.gate_of(s.activity, scale));
            target_presence(s.presence, gate)
        }));
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
                if w.rebuild[g] && k < self.k_demix {
                    let cross = &mut w.cross[k * n * n..(k + 1) * n * n];
                    for (i, s) in self.streams.iter().enumerate() {
                        if s.group == g {
                            ns.cross_powers(i, &mut cross[i * n..(i + 1) * n]);
                        }
                    }
                }
            } else {
                for (i, s) in self.streams.iter_mut().enumerate() {
                    if s.group != g {
                        continue;
                    }
                    let ns = &mut s.null_steering[k];
                    if s.constraints_changed {
                        let nc = s.constraints.len();
                        w.dsub.resize(nc * m, Complex::new(0.0, 0.0));
                        for (j, &c) in s.constraints.iter().enumerate() {
                            w.dsub[j * m..(j + 1) * m]
                                .copy_from_slice(&w.walk[g][c * m..(c + 1) * m]);
                        }
                        ns.prepare_first(&w.dsub, nc, m, loading);
                    }
                    w.fixed[i] = ns.first_output(&w.yg[g]);
                }
            }
        }
    }

    /// Feeds bin `k`'s group snapshots (after [`Separator::fixed_outputs`] gathered them) to the
    /// direct-path power fits of the activity gate.
    fn fit_direct_power(&mut self, k: usize) {
        let w = &self.work;
        for (g, fit) in self.direct.iter_mut().enumerate() {
            if w.active[g] && fit.covers(k) {
                fit.observe(k, &w.yg[g], &w.walk[g], w.rebuild[g]);
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
        let n = self.streams.len();
        for ((s, b), &presence) in self.streams.iter().zip(w.beta.iter_mut()).zip(&w.presence) {
            let share = (a.per_bin && total > 0.0).then(|| s.fixed_power[k] / total);
            *b = adaptation_weight(a, presence, share, n);
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
                let gsc = GscBin {
                    cfg: &self.cfg,
                    record: self.record,
                    k,
                    i,
                    m,
                    power,
                };
                gsc.output(s, w, g, d)
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
                    weights.copy_from_slice(s.null_steering[k].first_weights());
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

    /// Post-filter gains at bin `k`, kept with the beamformer outputs for [`Self::write_bins`].
    fn post_filter(&mut self, k: usize) {
        let n = self.streams.len();
        let w = &mut self.work;
        if k == self.k_lo {
            let len = self.bins * n;
            w.frame_gains.resize(len, 0.0);
            w.frame_bf.resize(len, Complex::new(0.0, 0.0));
            w.frame_unresolved.resize(len, 0.0);
        }
        for (p, s) in w.post.iter_mut().zip(&self.streams) {
            *p = s.post[k];
        }
        let yref = w.y[k * self.channels + self.reference];
        // The cross-responses are the fixed branch's, computed where every label shares its
        // group's beamformers.
        let fixed_branch = matches!(
            self.cfg.beamformer,
            BeamformerKind::Gsc | BeamformerKind::NullSteering
        );
        let demix_by = (k < self.k_demix
            && fixed_branch
            && (0..self.groups.len()).all(|g| !w.active[g] || w.shared[g]))
        .then(|| Demixing {
            cross: &w.cross[k * n * n..(k + 1) * n * n],
            solver: &mut w.nnls,
            support: &mut w.demix_support[k],
        });
        self.post.gains(
            &w.bf,
            &w.priors,
            &mut w.post,
            (yref, &mut self.ref_power[k]),
            demix_by,
            &mut w.gains,
        );
        for (s, p) in self.streams.iter_mut().zip(&w.post) {
            s.post[k] = *p;
        }
        w.frame_gains[k * n..(k + 1) * n].copy_from_slice(&w.gains[..n]);
        w.frame_bf[k * n..(k + 1) * n].copy_from_slice(&w.bf[..n]);
        if self.harmonic.enabled() && self.post.enabled() {
            self.unresolved_pairs(k);
        }
    }

    /// How unresolved each pair of streams is at bin `k` (recomputed where a group's steering
    /// moved), and each stream's least resolved audible competitor's value.
    fn unresolved_pairs(&mut self, k: usize) {
        let n = self.streams.len();
        let w = &mut self.work;
        // Each stream's claim is as ambiguous as its least resolved audible competitor; the
        // same measure weighs the bins its F0 is read from.
        let loading = self.cfg.null_loading;
        let pairs = &mut w.pair_unresolved[k * n * n..(k + 1) * n * n];
        // A pair's value is read on the first stream's group and depends only on the
        // steering there: it is recomputed with that group's fixed beamformers.
        let unresolved = |g: usize, a: usize, b: usize| {
            let m = self.groups[g].channels.len();
            let va = &w.walk[g][a * m..(a + 1) * m];
            let vb = &w.walk[g][b * m..(b + 1) * m];
            self.harmonic.unresolved(harmonic::leakage(va, vb, loading))
        };
        for i in 0..n {
            for j in i + 1..n {
                let (gi, gj) = (self.streams[i].group, self.streams[j].group);
                // The leakage is symmetric in the two steering vectors on one group.
                if gi == gj {
                    if w.rebuild[gi] {
                        let u = unresolved(gi, i, j);
                        pairs[i * n + j] = u;
                        pairs[j * n + i] = u;
                    }
                    continue;
                }
                if w.rebuild[gi] {
                    pairs[i * n + j] = unresolved(gi, i, j);
                }
                if w.rebuild[gj] {
                    pairs[j * n + i] = unresolved(gj, j, i);
                }
            }
        }
        // unresolved() is monotone, so the least resolved audible competitor's value is
        // the largest of the pairs'.
        let floor = self.harmonic.unresolved_floor();
        for i in 0..n {
            w.frame_unresolved[k * n + i] = if w.priors[i] > 0.0 {
                least_resolved(pairs, i, &w.priors, floor, |_| 1.0)
            } else {
                floor
            };
        }
    }

    /// After the frame's bins: regroups the unresolved bins by harmonic evidence, then writes
    /// every stream's output bins into `out` (and scales the recorded filters).
    fn write_bins(&mut self, out: &mut [(Label, Vec<Complex>)]) {
        let n = self.streams.len();
        let to_ref =
            self.cfg.post_filter.apply_to == PostFilterTarget::ReferenceMic && self.post.enabled();
        if self.harmonic.enabled() && self.post.enabled() {
            self.regroup_harmonic(to_ref);
        } else {
            self.work.pitch.clear();
        }
        let (ch, rf) = (self.channels, self.reference);
        let w = &self.work;
        for k in self.k_lo..self.k_hi {
            let yref = w.y[k * ch + rf];
            for (i, (s, (_, o))) in self.streams.iter_mut().zip(out.iter_mut()).enumerate() {
                let scale = w.frame_gains[k * n + i] * s.gain;
                o[k] = if to_ref {
                    yref * scale
                } else {
                    w.frame_bf[k * n + i] * scale
                };
                if self.record {
                    let f = &mut s.filters[k * ch..(k + 1) * ch];
                    if to_ref {
                        f.fill(Complex::new(0.0, 0.0));
                        f[rf] = Complex::new(1.0, 0.0);
                    }
                    for x in f.iter_mut() {
                        *x *= scale;
                    }
                }
            }
        }
    }
}

/// One bin of one stream's generalised sidelobe canceller.
struct GscBin<'a> {
    cfg: &'a SeparatorConfig,
    record: bool,
    k: usize,
    i: usize,
    /// Microphones in the stream's group.
    m: usize,
    /// The bin's input power (the canceller's regularisation scale).
    power: f64,
}

impl GscBin<'_> {
    /// The canceller's output for the fixed beamformer's output `d` on microphone group `g`:
    /// the blocking matrix's outputs are filtered and subtracted, then the canceller adapts
    /// (every `update_every` frames per bin, weighted by the adaptation weight).
    fn output(&self, s: &mut Stream, w: &mut Work, g: usize, d: Complex) -> Complex {
        let (k, i, m, power) = (self.k, self.i, self.m, self.power);
        let a = &w.walk[g][i * m..(i + 1) * m];
        let y = &w.yg[g];
        let dims = s.rls_dims;
        let l = dims.l;
        if s.steering_changed {
            s.blocking.set(k, a);
        }
        // The padding must be zero (another group may have left values there).
        w.ur[l..dims.lp].iter_mut().for_each(|x| *x = 0.0);
        w.ui[l..dims.lp].iter_mut().for_each(|x| *x = 0.0);
        s.blocking.apply_split(k, y, &mut w.ur[..l], &mut w.ui[..l]);
        let stride = dims.stride();
        let st = &mut s.rls[k * stride..(k + 1) * stride];
        let e = rls::output(st, dims, &w.ur, &w.ui, d);
        if self.record {
            // Effective weights W - B V with the weights that made this output.
            rls::weights(st, dims, &mut w.u[..l]);
            s.blocking.combine(k, &w.u[..l], &mut w.w2[..m]);
        }
        // Partial update: bin k adapts when (frame + k) is a multiple of `every`; its own update
        // counter then is (frame + k) / every.
        let every = self.cfg.rls.update_every.max(1);
        let phase = s.leak_index.wrapping_add(k);
        if every == 1 || phase.is_multiple_of(every) {
            let step = RlsStep {
                forgetting: w.rls_forgetting,
                leakage: self.cfg.rls.leakage,
                max_norm2: w.max_norm2[i],
            };
            let ok = rls::adapt(
                st,
                dims,
                &w.ur,
                &w.ui,
                e,
                w.beta[i],
                power,
                phase / every,
                &step,
                &mut w.scratch,
            );
            if !ok {
                let kind = self.cfg.beamformer;
                s.reset_bin(kind, m, k, self.cfg.rls.init_regularisation, power);
            }
        }
        e
    }
}

/// How likely a label's target talks, for its adaptation: the tracker's `presence`, or the
/// label's activity `gate` where that says more (a NaN gate says nothing).
fn target_presence(presence: f64, gate: Option<f64>) -> f64 {
    // f64::max returns the other argument when one is NaN.
    gate.map_or(presence, |g| presence.max(g))
}

/// How fast a label's adaptive stage learns in one bin (1 fully, 0 frozen), from its target's
/// `presence` and, per bin, its share of the `labels`' fixed-beamformer power: the share scales
/// the presence down where interferers dominate, and with the dominance guard a bin the
/// label's own beamformer dominates counts as its target talking.
fn adaptation_weight(
    a: &AdaptationConfig,
    presence: f64,
    share: Option<f64>,
    labels: usize,
) -> f64 {
    let mut presence = presence;
    if let Some(share) = share {
        presence *= share;
        // One label always has the whole share: that says nothing about its target.
        if a.dominance_guard && labels >= 2 {
            let guard = (share - a.dominance_low) / (a.dominance_high - a.dominance_low);
            presence = presence.max(guard.clamp(0.0, 1.0));
        }
    }
    ((a.presence_high - presence) / (a.presence_high - a.presence_low)).clamp(0.0, 1.0)
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

/// How unresolved stream `i`'s claim on a bin is: its least resolved competitor's value
/// (`pairs`: the bin's stream x competitor values), counting only competitors with a prior,
/// each weighed by `weight(j)`, and at least `floor`.
pub(super) fn least_resolved(
    pairs: &[f64],
    i: usize,
    priors: &[f64],
    floor: f64,
    weight: impl Fn(usize) -> f64,
) -> f64 {
    let n = priors.len();
    (0..n)
        .filter(|&j| j != i && priors[j] > 0.0)
        .map(|j| pairs[i * n + j] * weight(j))
        .fold(floor, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_label_whose_gate_measures_its_talker_is_not_adapted_while_the_tracker_lags() {
        let a = AdaptationConfig::default();
        let weight =
            |presence, gate| adaptation_weight(&a, target_presence(presence, gate), None, 3);
        // The tracker says silent, the gate says talking: frozen.
        assert_eq!(weight(0.05, Some(1.0)), 0.0);
        // Both say silent: learns at full speed; without a gate the tracker decides.
        assert_eq!(weight(0.05, Some(0.0)), 1.0);
        assert_eq!(weight(0.05, None), 1.0);
        // The tracker says talking and the gate closed: still frozen (the larger counts).
        assert_eq!(weight(1.0, Some(0.0)), 0.0);
        // A gate that is no number says nothing.
        assert_eq!(weight(0.05, Some(f64::NAN)), 1.0);
    }

    #[test]
    fn a_label_its_own_beamformer_dominates_is_not_adapted_even_when_the_tracker_says_silent() {
        let a = AdaptationConfig::default();
        // Silent by the tracker, the bin carried by an interferer: learn it.
        assert_eq!(adaptation_weight(&a, 0.0, Some(0.2), 3), 1.0);
        // Silent by the tracker, yet its own output carries the bin: its target talks there.
        assert_eq!(adaptation_weight(&a, 0.0, Some(0.9), 3), 0.0);
        // In between, the step is weighted.
        let mid = adaptation_weight(&a, 0.0, Some(0.6), 3);
        assert!(mid > 0.0 && mid < 1.0, "{mid}");
        // Talking by the tracker in a bin it dominates: frozen as before.
        assert_eq!(adaptation_weight(&a, 1.0, Some(0.9), 3), 0.0);
        // A lone label has the whole share: the guard says nothing, the tracker decides.
        assert_eq!(adaptation_weight(&a, 0.0, Some(1.0), 1), 1.0);
        // Guard off: the previous rule.
        let off = AdaptationConfig {
            dominance_guard: false,
            ..AdaptationConfig::default()
        };
        assert_eq!(adaptation_weight(&off, 0.0, Some(0.9), 3), 1.0);
        // Without per-bin shares the presence alone decides.
        assert_eq!(adaptation_weight(&a, 0.0, None, 3), 1.0);
    }
}
