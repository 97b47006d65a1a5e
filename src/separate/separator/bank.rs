//! The bank's frame preparation: births, updates and absences from the targets, each stream's
//! microphone group, steering (kept while it moves less than the tolerance) and null constraints.

use super::{MicGroup, SWITCH_RATIO, Separator};
use crate::dsp::Complex;
use crate::separate::Target;
use crate::separate::blocking::BlockingBank;
use crate::separate::config::MicSelection;
use crate::separate::lifecycle::{Envelope, Timing};
use crate::separate::null_steering::NullSteering;
use crate::separate::postfilter::PostState;
use crate::separate::steering::Steering;
use crate::separate::stream::Stream;

/// A label outside a capped null set replaces one of its members only when its power exceeds
/// the quietest member's by this factor (3 dB).
const SWAP_RATIO: f64 = 2.0;

impl Separator {
    /// Births, updates and absences from this frame's targets; then streams rest or wake.
    pub(super) fn update_bank(&mut self, targets: &[Target]) {
        let present = &mut self.work.present;
        present.clear();
        present.resize(self.streams.len(), false);
        let resting_present = &mut self.work.resting_present;
        resting_present.clear();
        resting_present.resize(self.resting.len(), false);
        let wake = self.cfg.lifecycle.wake_speaking;
        for (i, t) in targets.iter().enumerate() {
            if targets[..i].iter().any(|u| u.label == t.label) {
                continue;
            }
            let finite = t.position.iter().all(|v| v.is_finite());
            if let Some(j) = self.streams.iter().position(|s| s.label == t.label) {
                follow(&mut self.streams[j], t, finite, wake);
                self.work.present[j] = true;
            } else if let Some(j) = self.resting.iter().position(|s| s.label == t.label) {
                follow(&mut self.resting[j], t, finite, wake);
                self.work.resting_present[j] = true;
            } else if finite && self.make_room() {
                // Past the cap a label waits, unseparated, for a stream to be dropped.
                let mut s = Stream::new(t.label, t.position, t.direction_only, self.groups.len());
                follow(&mut s, t, true, wake);
                self.streams.push(s);
                self.work.present.push(true);
            }
        }
        for (s, &p) in self.streams.iter_mut().zip(self.work.present.iter()) {
            s.envelope.step(p, &self.timing);
            if let (true, Some(rest)) = (p, &self.rest_timing) {
                s.rest.step(s.heard, rest);
            }
            s.gain = s.envelope.gain() * s.rest.gain();
            if !p {
                // Steering at a stale position: do not learn.
                s.presence = 1.0;
                s.known_pitch = None;
            }
        }
        self.rest_and_wake();
    }

    /// Moves the streams unheard for `rest_after_s` (faded to silence) to the resting set, and
    /// the resting ones heard again back to the bank (fading in), room permitting.
    fn rest_and_wake(&mut self) {
        let Some(rest) = self.rest_timing else {
            // Resting was turned off: every resting label is heard again.
            for s in &mut self.resting {
                s.rest = Envelope::open();
                s.heard = true;
            }
            return self.wake_resting(None);
        };
        self.wake_resting(Some(&rest));
        let mut i = 0;
        while i < self.streams.len() {
            if self.streams[i].rest.is_dead(&rest) {
                let s = self.streams.remove(i);
                self.work.present.remove(i);
                self.resting.push(s);
            } else {
                i += 1;
            }
        }
    }

    /// Moves the resting streams whose labels are heard back to the bank (fading in under
    /// `rest`; at full gain without one), room permitting.
    fn wake_resting(&mut self, rest: Option<&Timing>) {
        let mut i = 0;
        while i < self.resting.len() {
            let p = self.work.resting_present[i];
            let s = &mut self.resting[i];
            s.envelope.step(p, &self.timing);
            // A present label's envelope has just been reset, so it cannot be dead.
            let wakes = p && s.heard;
            let released = s.released;
            if wakes && (!released || self.make_room()) {
                let mut s = self.resting.remove(i);
                self.work.resting_present.remove(i);
                s.wake();
                if let Some(rest) = rest {
                    s.rest.step(true, rest);
                }
                s.gain = s.envelope.gain() * s.rest.gain();
                self.streams.push(s);
                self.work.present.push(true);
            } else {
                i += 1;
            }
        }
    }

    /// Whether one more stream may hold per-bin state. At the cap, the stream that has rested
    /// longest gives its state up (it stays, silent, as a label that may wake).
    fn make_room(&mut self) -> bool {
        let held = self.streams.len() + self.resting.iter().filter(|s| !s.released).count();
        if held < self.cfg.lifecycle.max_streams {
            return true;
        }
        match self.resting.iter_mut().find(|s| !s.released) {
            Some(s) => {
                s.release_state();
                true
            }
            None => false,
        }
    }

    /// Chooses each stream's group, sizes and resets its state, computes its steering and the
    /// null constraints, and starts the walks over the bins.
    pub(super) fn prepare_streams(&mut self) {
        self.fit_streams();
        let bank_changed = self.update_steering();
        self.select_constraints(bank_changed);
        self.size_work();
        let n = self.streams.len();
        self.work.pair_unresolved.resize(self.bins * n * n, 0.0);
        self.work.cross.resize(self.k_demix * n * n, 0.0);
        self.work.demix_support.resize(self.k_demix, 0);
    }

    /// Each stream's microphone group, with its adaptive state sized (and reset on a change).
    fn fit_streams(&mut self) {
        let kind = self.cfg.beamformer;
        let ngroups = self.groups.len();
        let bins = self.bins;
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
            if s.blocking.bins() != bins || s.blocking.mics() != m {
                s.blocking = BlockingBank::new(m, bins);
                s.steering_changed = true;
            }
        }
    }

    /// Steering of every stream on every active group, swapped in only when it moved beyond the
    /// tolerance; starts the walks over the bins. Returns whether the bank itself changed.
    fn update_steering(&mut self) -> bool {
        let (bins, k_lo) = (self.bins, self.k_lo);
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
        bank_changed
    }

    /// Capped null constraints: with more labels than microphones, the loudest other labels get
    /// the M - 1 nulls.
    fn select_constraints(&mut self, bank_changed: bool) {
        let n = self.streams.len();
        let bins = self.bins;
        let w = &self.work;
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
            // Keep the set while no other label is clearly louder than its quietest member:
            // near-silent labels reorder every frame, and each new set rebuilds the label's
            // fixed beamformers in every bin. Stream indices hold while the bank is unchanged.
            let current = &self.streams[i].constraints;
            if !bank_changed && current.len() == m && current[0] == i {
                let kept = &current[1..];
                let power = |j: usize| self.streams[j].power;
                let quietest = kept.iter().map(|&j| power(j)).fold(f64::INFINITY, f64::min);
                let louder = order
                    .iter()
                    .filter(|j| !kept.contains(j))
                    .any(|&j| power(j) > SWAP_RATIO * quietest);
                if !louder {
                    order.clear();
                    order.extend_from_slice(kept);
                }
            }
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
    }

    /// Per-frame scratch sized for the bank; post-filter priors and filter records reset.
    fn size_work(&mut self) {
        let n = self.streams.len();
        let bins = self.bins;
        let w = &mut self.work;
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

/// Takes a target's position (when finite), presence, pitch and whether it is heard.
fn follow(s: &mut Stream, t: &Target, finite: bool, wake: f64) {
    if finite {
        s.position = t.position;
        s.direction_only = t.direction_only;
    }
    s.presence = presence_of(t);
    s.known_pitch = t.pitch;
    // Unknown speaking (NaN) counts as heard: nothing rests on no evidence.
    s.heard = t.speaking.is_nan() || t.speaking >= wake;
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
