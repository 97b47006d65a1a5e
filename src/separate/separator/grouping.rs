//! The separator's harmonic grouping of a frame: each stream's pitch from its resolved bins,
//! the regrouping of the unresolved bins by harmonic evidence, and the harmonic amplitude fit
//! of the low bins.

use super::Separator;
use super::bins::least_resolved;
use crate::separate::KnownPitch;
use crate::separate::harmonic::{Pitch, RoomLevel};
use crate::separate::stream::Stream;

impl Separator {
    /// Estimates each stream's F0 from its resolved bins and regroups the unresolved ones.
    pub(super) fn regroup_harmonic(&mut self, to_ref: bool) {
        let n = self.streams.len();
        let (ch, rf) = (self.channels, self.reference);
        let w = &mut self.work;
        w.pitch.clear();
        // The F0 analysis reads bins up to its top frequency only, the periodicity every bin
        // the separator processes; those below k_lo stay zero.
        let top = self.harmonic.top_bin().min(self.k_hi);
        let len = top.max(self.k_lo);
        let mag_len = if self.harmonic.reads_periodicity() {
            self.k_hi.max(len)
        } else {
            len
        };
        w.mag.clear();
        w.mag.resize(mag_len, 0.0);
        w.reliability.clear();
        w.reliability.resize(len, 0.0);
        let y = &w.y;
        self.harmonic
            .whitening(|k| y[k * ch + rf].norm_sqr(), self.k_lo, top, &mut w.level);
        w.audibility.clear();
        w.audibility.extend(self.streams.iter().map(|s| {
            let scale = room_scale(&self.levels, s.group);
            self.harmonic.audibility(s.activity, s.comb_voicing, scale)
        }));
        for i in 0..n {
            let p = self.stream_pitch(i, to_ref, top);
            self.work.pitch.push(p);
        }
        self.observe_rooms();
        let w = &mut self.work;
        w.ownership.resize(n, 0.0);
        w.evidence.resize(n, 0.0);
        self.harmonic.ownership(&w.pitch, &mut w.ownership);
        for ((s, p), o) in self.streams.iter_mut().zip(&w.pitch).zip(&w.ownership) {
            self.harmonic.observe(&mut s.register, p, *o);
        }
        let floor = self.post.floor();
        for k in self.k_lo..self.k_hi {
            let u = &w.frame_unresolved[k * n..(k + 1) * n];
            if u.iter().all(|&x| x <= 0.0) {
                continue;
            }
            self.harmonic.evidence(&w.pitch, k, &mut w.evidence);
            self.harmonic.regroup(
                &mut w.frame_gains[k * n..(k + 1) * n],
                u,
                &w.evidence,
                floor,
                &mut w.shares,
            );
        }
        self.fit_harmonics(floor);
    }

    /// Folds each microphone group's strongest label this frame into its room level.
    fn observe_rooms(&mut self) {
        for (g, level) in self.levels.iter_mut().enumerate() {
            let strongest = self
                .streams
                .iter()
                .filter(|s| s.group == g)
                .map(|s| s.activity)
                .reduce(f64::max);
            if let Some(a) = strongest {
                self.harmonic.observe_room(level, a);
            }
        }
    }

    /// Divides the low unresolved bins by the harmonic amplitude fit: as far as a stream's
    /// claim on a bin is unresolved, its gain becomes its fitted harmonics' share of the bin's
    /// power plus, of what no harmonic explains, the share the grouping gave it.
    fn fit_harmonics(&mut self, floor: f64) {
        let n = self.streams.len();
        let (ch, rf) = (self.channels, self.reference);
        let top = self.harmonic_fit.top();
        if top <= self.k_lo || n == 0 {
            return;
        }
        let w = &mut self.work;
        w.fit_f0s.clear();
        w.fit_f0s.extend(w.pitch.iter().map(|p| p.f0));
        w.fit_x.clear();
        w.fit_x.extend((0..top).map(|k| w.y[k * ch + rf]));
        let (harmonic, pitch) = (&self.harmonic, &w.pitch);
        let hcfg = &self.cfg.post_filter.harmonic;
        let min_voicing = hcfg.fit_min_voicing;
        memory_weights(
            &self.streams,
            top,
            hcfg.fit_memory_exponent,
            &mut w.fit_weight,
        );
        let (weight, streams) = (&w.fit_weight, &self.streams);
        let fitted = self.harmonic_fit.fit(
            &w.fit_x,
            &w.fit_f0s,
            |i, kf| {
                // Voicing is clamped to 1 when whole; the margin keeps rounding from losing it.
                match pitch.get(i) {
                    Some(p) if p.voicing + 1e-9 >= min_voicing => {
                        let k = (kf.round() as usize).min(top - 1);
                        let (w, claim) = (weight[i * top + k], harmonic.claim(pitch, i, kf));
                        // A held label's contest reads bins its vowel left empty; its memory
                        // of the harmonic says more.
                        let claim = if streams[i].held {
                            claim.max(p.voicing * w)
                        } else {
                            claim
                        };
                        claim * w
                    }
                    _ => 0.0,
                }
            },
            &mut w.fit_power,
            &mut w.fit_residual,
        );
        let power = fitted.then_some(w.fit_power.as_slice());
        remember_fit(&mut self.streams, top, hcfg.fit_memory, power);
        if !fitted {
            return;
        }
        for k in self.k_lo..top {
            let total = w.fit_residual[k] + (0..n).map(|i| w.fit_power[i * top + k]).sum::<f64>();
            if !(total > 0.0 && total.is_finite()) {
                continue;
            }
            let rest = w.fit_residual[k] / total;
            for i in 0..n {
                let u = w.frame_unresolved[k * n + i];
                let g = w.frame_gains[k * n + i];
                let fitted = w.fit_power[i * top + k] / total + g * rest;
                w.frame_gains[k * n + i] = ((1.0 - u) * g + u * fitted).max(floor);
            }
        }
    }

    /// Loads stream `i`'s post-filtered magnitudes (of the reference microphone with `to_ref`,
    /// else of its beamformer) and, up to bin `top`, how reliably each bin is its own: as far
    /// as no audible competitor's beamformer passes the same mixture there.
    fn load_spectrum(&mut self, i: usize, to_ref: bool, top: usize) {
        let n = self.streams.len();
        let (ch, rf) = (self.channels, self.reference);
        let floor = self.harmonic.unresolved_floor();
        let w = &mut self.work;
        for k in self.k_lo..w.mag.len() {
            let g = w.frame_gains[k * n + i];
            let v = if to_ref {
                w.y[k * ch + rf]
            } else {
                w.frame_bf[k * n + i]
            };
            w.mag[k] = g * v.norm_sqr().sqrt();
        }
        for k in self.k_lo..top {
            let pairs = &w.pair_unresolved[k * n * n..(k + 1) * n * n];
            // A competitor blinds the stream's F0 reading only as far as it is audible.
            let audibility = &w.audibility;
            let u = least_resolved(pairs, i, &w.priors, floor, |j| audibility[j]);
            let r = 1.0 - u;
            w.reliability[k] = r * r;
        }
    }

    /// Stream `i`'s pitch this frame, read from its post-filtered magnitudes (of the reference
    /// microphone with `to_ref`, else of its beamformer): the F0 from its comb up to bin `top`,
    /// each candidate weighed by the periodicity of all of them, the voicing from that
    /// periodicity, with its activity gate folded in and its contest salience measured
    /// against the mixture's local level (each part as far as the settings ask for it).
    fn stream_pitch(&mut self, i: usize, to_ref: bool, top: usize) -> Pitch {
        self.streams[i].held = false;
        if self.work.priors[i] <= 0.0 {
            return Pitch::default();
        }
        self.load_spectrum(i, to_ref, top);
        let scale = room_scale(&self.levels, self.streams[i].group);
        let w = &mut self.work;
        let s = &mut self.streams[i];
        // The gate's smoothing runs whether or not the pitch is known, so its state does not
        // depend on where the pitch comes from.
        let gate = match self.direct.get(s.group) {
            Some(fit) => self
                .harmonic
                .activity_gate(&mut s.activity, fit.dominance(i), scale),
            None => 1.0,
        };
        let mut p = match s.known_pitch {
            Some(KnownPitch::Both(known)) => {
                let p =
                    self.harmonic
                        .known_pitch(&w.mag, &w.reliability, known, &mut w.pitch_table);
                s.comb_voicing = p.voicing;
                p
            }
            known => {
                // The frame's periodicity weighs the F0 search's candidates and reads the voicing.
                let peak = self
                    .harmonic
                    .reads_periodicity()
                    .then(|| self.periodicity.peak(|k| w.mag[k], self.k_lo, w.mag.len()));
                let periodicity = peak.map(|_| &self.periodicity);
                let mut p = match known {
                    Some(KnownPitch::F0(f0)) => {
                        self.harmonic
                            .pitch_at(&w.mag, &w.reliability, f0, &mut w.pitch_table)
                    }
                    _ => self.harmonic.next_pitch(
                        &w.mag,
                        &w.reliability,
                        &s.register,
                        periodicity,
                        &mut s.pitch_track,
                        &mut w.pitch_table,
                    ),
                };
                s.comb_voicing = p.voicing;
                // A voicing without an F0 would mean nothing to the grouping.
                if let Some(peak) = peak.filter(|_| p.f0 > 0.0) {
                    p.voicing = self.harmonic.periodic_voicing(peak).unwrap_or(p.voicing);
                }
                let held = self.harmonic.hold(&mut s.segment, &p, gate);
                s.held = held > gate;
                p.voicing *= held;
                if let Some(KnownPitch::Voicing(v)) = known {
                    // The true voicing replaces the comb's and the gate's: nothing is held.
                    p.voicing = if p.f0 > 0.0 { v.clamp(0.0, 1.0) } else { 0.0 };
                    s.held = false;
                }
                p
            }
        };
        self.harmonic.whiten_salience(
            &mut p,
            &w.mag,
            &w.level,
            &w.reliability,
            &mut w.whitened,
            &mut w.pitch_table,
        );
        p
    }
}

/// The activity gate's scale on microphone group `g` (1 without a room level there).
pub(super) fn room_scale(levels: &[RoomLevel], g: usize) -> f64 {
    levels.get(g).map_or(1.0, RoomLevel::scale)
}

/// A stream's memory at a bin counts against the strongest stream's memory there plus this
/// fraction of it, so a stream that had nothing there keeps a small say (a tenth of the
/// strongest's at the default exponent 0.5).
const MEMORY_FLOOR: f64 = 0.01;

/// Each stream's weight per bin below `top` (stream-major in `out`): its fit memory (the
/// largest over the bin and its neighbours, as a harmonic drifts by a bin when its F0 moves)
/// over the strongest stream's there, to the power `exponent`. All 1 where no stream has any.
fn memory_weights(streams: &[Stream], top: usize, exponent: f64, out: &mut Vec<f64>) {
    out.clear();
    out.resize(streams.len() * top, 1.0);
    if exponent <= 0.0 {
        return;
    }
    let near = |m: &[f64], k: usize| -> f64 {
        m.get(k.saturating_sub(1)..(k + 2).min(m.len()))
            .map_or(0.0, |s| s.iter().copied().fold(0.0, f64::max))
    };
    for k in 0..top {
        let strongest = streams
            .iter()
            .map(|s| near(&s.fit_memory, k))
            .fold(0.0, f64::max);
        if !(strongest > 0.0 && strongest.is_finite()) {
            continue;
        }
        let floor = MEMORY_FLOOR * strongest;
        for (i, s) in streams.iter().enumerate() {
            let r = (near(&s.fit_memory, k) + floor) / (strongest + floor);
            out[i * top + k] = r.powf(exponent);
        }
    }
}

/// Folds this frame's fitted power (stream-major, `top` bins each; `None`: nothing fitted)
/// into each stream's memory with smoothing `a` per frame (0 keeps none).
fn remember_fit(streams: &mut [Stream], top: usize, a: f64, power: Option<&[f64]>) {
    for (i, s) in streams.iter_mut().enumerate() {
        if a <= 0.0 {
            s.fit_memory.clear();
            continue;
        }
        s.fit_memory.resize(top, 0.0);
        let fitted = power.and_then(|p| p.get(i * top..(i + 1) * top));
        for (k, m) in s.fit_memory.iter_mut().enumerate() {
            let p = fitted.map_or(0.0, |f| f[k]);
            *m = a * *m + (1.0 - a) * if p.is_finite() { p } else { 0.0 };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dsp::Complex;
    use crate::geometry::Vec3;
    use crate::label::Label;
    use crate::separate::harmonic::HarmonicFit;
    use crate::separate::harmonic::fit_signals::{FS, N, spectrum, voice};

    fn stream(id: u64) -> Stream {
        Stream::new(Label::new(id, 0), Vec3::new(1.0, 0.0, 0.0), false, 1)
    }

    #[test]
    fn a_silent_competitor_leaves_the_shared_bins_reliable() {
        // Three streams: 0 and 1 unresolved against each other (0.9), 2 resolved from both.
        let n = 3;
        let mut pairs = vec![0.0; n * n];
        pairs[1] = 0.9;
        pairs[n] = 0.9;
        pairs[2] = 0.1;
        let priors = [1.0, 1.0, 1.0];
        // Every competitor audible: the least resolved one counts whole.
        let all = [1.0, 1.0, 1.0];
        let audible = |a: &[f64], priors: &[f64], floor: f64| {
            least_resolved(&pairs, 0, priors, floor, |j| a[j])
        };
        assert_eq!(audible(&all, &priors, 0.0), 0.9);
        // Stream 1 silent: stream 0's bin is as unresolved as against stream 2 only.
        let silent = [1.0, 0.0, 1.0];
        assert_eq!(audible(&silent, &priors, 0.0), 0.1);
        // Stream 1 half audible, and the floor.
        let half = [1.0, 0.25, 0.0];
        assert!((audible(&half, &priors, 0.0) - 0.225).abs() < 1e-12);
        assert_eq!(audible(&silent, &priors, 0.3), 0.3);
        // A competitor without a prior (faded out) does not count at all.
        assert_eq!(audible(&all, &[1.0, 0.0, 1.0], 0.0), 0.1);
    }

    #[test]
    fn memory_weighs_a_bin_by_who_had_power_there() {
        let mut streams = vec![stream(1), stream(2)];
        let top = 30;
        let mut power = vec![0.0; 2 * top];
        power[10] = 4.0; // stream 1 at bin 10
        power[top + 20] = 1.0; // stream 2 at bin 20
        for _ in 0..50 {
            remember_fit(&mut streams, top, 0.9, Some(&power));
        }
        assert!((streams[0].fit_memory[10] - 4.0).abs() < 0.03);
        let mut w = Vec::new();
        memory_weights(&streams, top, 0.5, &mut w);
        // Each keeps its own bins and the neighbours a drifting harmonic moves to.
        for k in 9..=11 {
            assert!((w[k] - 1.0).abs() < 1e-12, "bin {k}");
            assert!(w[top + k] < 0.11, "bin {k}: {}", w[top + k]);
        }
        assert!((w[top + 20] - 1.0).abs() < 1e-12 && w[20] < 0.11);
        // Where nobody had power, nobody is weighed down.
        assert_eq!((w[5], w[top + 5]), (1.0, 1.0));
        // Frames without a fit let the memory fade; no memory keeps nothing.
        for _ in 0..50 {
            remember_fit(&mut streams, top, 0.9, None);
        }
        assert!(streams[0].fit_memory[10] < 0.03);
        remember_fit(&mut streams, top, 0.0, Some(&power));
        assert!(streams.iter().all(|s| s.fit_memory.is_empty()));
        memory_weights(&streams, top, 0.5, &mut w);
        assert!(w.iter().all(|&v| v == 1.0));
    }

    #[test]
    fn in_unison_the_voice_that_held_the_harmonics_keeps_them() {
        // Voice A (strong low harmonics) talks alone; then voice B joins on the same F0 with
        // weak low harmonics. The fit cannot tell their columns apart; the memory of who had
        // the power divides it.
        let f0 = 125.0;
        let a = voice(f0, &[1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4], 0.3);
        let b = voice(f0, &[0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1], 1.9);
        let hz = FS / N as f64;
        let top = (1000.0 / hz) as usize;
        let mut fit = HarmonicFit::new(N, hz, top, 1e-3);
        let mut streams = vec![stream(1), stream(2)];
        let (mut power, mut residual, mut w) = (Vec::new(), Vec::new(), Vec::new());
        let mut share_of_a = |x: &[Complex], f0s: &[f64], streams: &mut Vec<Stream>| {
            memory_weights(streams, top, 0.5, &mut w);
            let claims = |i: usize, kf: f64| w[i * top + (kf.round() as usize).min(top - 1)];
            assert!(fit.fit(x, f0s, claims, &mut power, &mut residual));
            remember_fit(streams, top, 0.9, Some(&power));
            let pa: f64 = power[..top].iter().sum();
            pa / (pa + power[top..].iter().sum::<f64>())
        };
        let sa = spectrum(&a);
        for _ in 0..20 {
            // Alone, A's label reads its F0; B's label reads nothing.
            assert!(share_of_a(&sa, &[f0, 0.0], &mut streams) > 0.999);
        }
        let mix: Vec<f64> = a.iter().zip(&b).map(|(p, q)| p + q).collect();
        let sx = spectrum(&mix);
        let share = share_of_a(&sx, &[f0, f0], &mut streams);
        assert!(share > 0.9, "A's share of the unison {share:.3}");
        // Without memory the two equal claims split the harmonics evenly.
        let mut fresh = vec![stream(1), stream(2)];
        let even = share_of_a(&sx, &[f0, f0], &mut fresh);
        assert!((even - 0.5).abs() < 0.05, "{even:.3}");
    }
}
