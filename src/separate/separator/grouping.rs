//! The separator's harmonic grouping of a frame: each stream's pitch from its resolved bins,
//! the regrouping of the unresolved bins by harmonic evidence, and the harmonic amplitude fit
//! of the low bins.

use super::Separator;
use crate::separate::harmonic::Pitch;

impl Separator {
    /// Estimates each stream's F0 from its resolved bins and regroups the unresolved ones.
    pub(super) fn regroup_harmonic(&mut self, to_ref: bool) {
        let n = self.streams.len();
        let (ch, rf) = (self.channels, self.reference);
        let w = &mut self.work;
        w.pitch.clear();
        // The F0 analysis reads bins up to its top frequency only; those below k_lo stay zero.
        let top = self.harmonic.top_bin().min(self.k_hi);
        let len = top.max(self.k_lo);
        w.mag.clear();
        w.mag.resize(len, 0.0);
        w.reliability.clear();
        w.reliability.resize(len, 0.0);
        let y = &w.y;
        self.harmonic
            .whitening(|k| y[k * ch + rf].norm_sqr(), self.k_lo, top, &mut w.level);
        for i in 0..n {
            let p = self.stream_pitch(i, to_ref, top);
            self.work.pitch.push(p);
        }
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
        let min_voicing = self.cfg.post_filter.harmonic.fit_min_voicing;
        let fitted = self.harmonic_fit.fit(
            &w.fit_x,
            &w.fit_f0s,
            |i, kf| {
                // Voicing is clamped to 1 when whole; the margin keeps rounding from losing it.
                match pitch.get(i) {
                    Some(p) if p.voicing + 1e-9 >= min_voicing => harmonic.claim(pitch, i, kf),
                    _ => 0.0,
                }
            },
            &mut w.fit_power,
            &mut w.fit_residual,
        );
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

    /// Stream `i`'s pitch this frame, read from its post-filtered magnitudes (of the reference
    /// microphone with `to_ref`, else of its beamformer) up to bin `top`, with its activity
    /// gate folded in and its contest salience measured against the mixture's local level.
    fn stream_pitch(&mut self, i: usize, to_ref: bool, top: usize) -> Pitch {
        let n = self.streams.len();
        let (ch, rf) = (self.channels, self.reference);
        let w = &mut self.work;
        if w.priors[i] <= 0.0 {
            return Pitch::default();
        }
        for k in self.k_lo..top {
            let g = w.frame_gains[k * n + i];
            let v = if to_ref {
                w.y[k * ch + rf]
            } else {
                w.frame_bf[k * n + i]
            };
            w.mag[k] = g * v.norm_sqr().sqrt();
            let r = 1.0 - w.frame_unresolved[k * n + i];
            w.reliability[k] = r * r;
        }
        let s = &mut self.streams[i];
        // The gate's smoothing runs whether or not the pitch is known, so its state does not
        // depend on where the pitch comes from.
        let gate = match self.direct.get(s.group) {
            Some(fit) => self.harmonic.activity_gate(&mut s.activity, fit.share(i)),
            None => 1.0,
        };
        let mut p = match s.known_pitch {
            Some(known) => {
                self.harmonic
                    .known_pitch(&w.mag, &w.reliability, known, &mut w.pitch_table)
            }
            None => {
                let mut p =
                    self.harmonic
                        .pitch(&w.mag, &w.reliability, &s.register, &mut w.pitch_table);
                p.voicing *= gate;
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
