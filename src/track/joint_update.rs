//! The MS-GLMB joint prediction and update (spec 000 3.4-3.6 and A3; spec 003 5.9-5.10).
//!
//! For every parent hypothesis the Gibbs sampler draws T_h ~ H_upd sqrt(w_h) association maps
//! over the candidate tracks (all births plus the parent's tracks). Each distinct map is then
//! weighted exactly, with the sequential multi-sensor update of every live track. Single-object
//! updates live in one table keyed by (candidate track, measurement index per sensor), shared
//! by all parents, so no update is computed twice; identical child hypotheses are merged.

use nalgebra::Vector3;
use rand::Rng;

use super::birth::BirthTerm;
use super::config::{CameraConfig, GlmbConfig, UkfConfig};
use super::filter::{Gain, Prepared, Transition, prepare, update};
use super::gait::{self, Gait};
use super::gaussian::{Gaussian, log_add, log_sum_exp};
use super::gibbs::{DEAD, Proposal, Sampler};
use super::modes::{Modes, mode_outcome};
use super::motion::{clamp_position, position_of};
use super::occlusion::occludes;
pub(crate) use super::posterior::{Entry, Posterior};
use super::scan::SensorScan;
use super::sensor::Sensor;
use super::slice_set::SliceSet;
use crate::geometry::{Aabb, Vec3};
use crate::label::Label;

/// Everything one joint update needs besides the prior.
pub(crate) struct StepModel<'a, const N: usize> {
    pub k: u64,
    pub dt: f64,
    pub transition: Transition<N>,
    /// The two-mode motion (standing / walking), when the settings ask for it; it replaces
    /// `transition` for surviving tracks that a camera (or any sensor that is not audio) saw
    /// within `gait_camera_memory_s`.
    pub gait: Option<Gait<N>>,
    pub modes: &'a Modes,
    pub survival: f64,
    pub sensors: &'a [Sensor<N>],
    pub scans: &'a [SensorScan],
    pub births: &'a [BirthTerm<N>],
    /// Detectability modes of each birth (`births` order).
    pub birth_modes: &'a [Vec<f64>],
    pub glmb: &'a GlmbConfig,
    pub ukf: &'a UkfConfig,
    pub camera: &'a CameraConfig,
    /// Region (already grown) that track means are clamped into.
    pub clamp: Option<Aabb>,
}

const NONE: u32 = u32::MAX;

#[derive(Debug, Clone)]
struct Candidate<const N: usize> {
    label: Label,
    pred: Gaussian<N>,
    modes: Vec<f64>,
    existence: f64,
    /// The parent entry's `unseen_s` at the step's end (infinite for a birth).
    unseen_s: f64,
    /// Probability of walking, predicted over the step once `ready`.
    walking: f64,
    ready: bool,
}

/// Reusable workspace of the joint update.
#[derive(Debug, Clone, Default)]
pub(crate) struct JointUpdate<const N: usize> {
    cands: Vec<Candidate<N>>,
    pd: Vec<f64>,
    /// (P_D on, P_D off) of mode-following sensors per (candidate, scan).
    mode_pd: Vec<(f64, f64)>,
    /// (log(1 - P_D), log P_D - log kappa) per (candidate, scan), P_D marginal over the mode.
    log_pd: Vec<(f64, f64)>,
    /// Index into `preps` per (candidate, scan); NONE when the sensor cannot observe it.
    prep_idx: Vec<u32>,
    preps: Vec<Prepared<N>>,
    /// Gain and posterior covariance per prepared update, computed on first use.
    gains: Vec<Option<Gain<N>>>,
    proposal: Proposal,
    sampler: Sampler,
    samples: SliceSet<u16>,
    keys: SliceSet<u32>,
    children: SliceSet<u32>,
    child_logw: Vec<f64>,
    new_entries: Vec<Option<Entry<N>>>,
    /// The candidate of each new entry.
    new_cands: Vec<u32>,
    /// Per candidate, the standing and walking modes' own predictions when it has a gait:
    /// they weigh the gait at the update. Apart from the candidates, which stay small.
    gait_preds: Vec<Option<[Gaussian<N>; 2]>>,
    new_terms: Vec<f64>,
    local: Vec<u32>,
    gamma: Vec<u16>,
    /// Per local track of the current parent: the last association row scored, with its entry
    /// (NONE when dead) and log weight factor.
    memo_rows: Vec<u16>,
    memo_valid: Vec<bool>,
    memo_ids: Vec<u32>,
    memo_terms: Vec<f64>,
    key: Vec<u32>,
    ids: Vec<u32>,
    row: Vec<(u16, f64)>,
}

impl<const N: usize> JointUpdate<N> {
    /// The posterior of the next step.
    pub fn run<R: Rng>(
        &mut self,
        prior: &Posterior<N>,
        m: &StepModel<N>,
        rng: &mut R,
    ) -> Posterior<N> {
        self.start(prior, m);
        let half: Vec<f64> = prior.hyps.iter().map(|h| (0.5 * h.0).exp()).collect();
        let total: f64 = half.iter().sum();
        let least = m.glmb.min_parent_samples;
        let mut budget: Vec<usize> = half
            .iter()
            .map(|w| (m.glmb.requested_hypotheses as f64 * w / total).round() as usize)
            .map(|b| if b > 0 { b.max(least) } else { 0 })
            .collect();
        if budget.iter().all(|&b| b == 0) {
            budget[0] = 1;
        }
        let births = m.births.len() as u32;
        for (h, &t_h) in budget.iter().enumerate() {
            if t_h == 0 {
                continue;
            }
            self.local.clear();
            self.local.extend(0..births);
            self.local
                .extend(prior.tracks(h).iter().map(|&e| births + e));
            for i in 0..self.local.len() {
                let c = self.local[i] as usize;
                self.ensure(c, prior, m);
            }
            let p = self.local.len();
            self.memo_rows.clear();
            self.memo_rows.resize(p * (m.scans.len() + 1), 0);
            self.memo_valid.clear();
            self.memo_valid.resize(p, false);
            self.memo_ids.resize(p, NONE);
            self.memo_terms.resize(p, 0.0);
            self.samples.clear();
            self.sampler.sample(
                &self.proposal,
                &self.local,
                births as usize,
                t_h,
                rng,
                &mut self.samples,
            );
            for s in 0..self.samples.len() {
                self.gamma.clear();
                self.gamma.extend_from_slice(self.samples.get(s));
                self.score(prior.hyps[h].0, m);
            }
        }
        self.finish(m)
    }

    fn start(&mut self, prior: &Posterior<N>, m: &StepModel<N>) {
        let c = m.scans.len();
        self.cands.clear();
        for (b, birth) in m.births.iter().enumerate() {
            self.cands.push(Candidate {
                label: Label::new(m.k, b as u32),
                pred: birth.density.clone(),
                modes: m
                    .birth_modes
                    .get(b)
                    .cloned()
                    .unwrap_or_else(|| m.modes.initial()),
                existence: birth.existence,
                unseen_s: f64::INFINITY,
                walking: m.gait.as_ref().map_or(0.0, Gait::initial),
                ready: false,
            });
        }
        for e in &prior.entries {
            self.cands.push(Candidate {
                label: e.label,
                pred: e.density.clone(),
                modes: m.modes.predict(&e.modes, m.dt),
                existence: m.survival,
                unseen_s: e.unseen_s + m.dt.max(0.0),
                walking: e.walking,
                ready: false,
            });
        }
        let n = self.cands.len();
        self.gait_preds.clear();
        self.gait_preds.resize(n, None);
        self.pd.clear();
        self.pd.resize(n * c, 0.0);
        self.log_pd.clear();
        self.log_pd.resize(n * c, (0.0, f64::NEG_INFINITY));
        self.mode_pd.clear();
        self.mode_pd.resize(n * c, (0.0, 0.0));
        self.prep_idx.clear();
        self.prep_idx.resize(n * c, NONE);
        self.preps.clear();
        self.gains.clear();
        let counts: Vec<usize> = m.scans.iter().map(|s| s.z.len()).collect();
        self.proposal.reset(n, &counts);
        self.keys.clear();
        self.children.clear();
        self.child_logw.clear();
        self.new_entries.clear();
        self.new_cands.clear();
        self.new_terms.clear();
    }

    /// Predicts a candidate and computes its proposal rows, once per step.
    fn ensure(&mut self, c: usize, prior: &Posterior<N>, m: &StepModel<N>) {
        if self.cands[c].ready {
            return;
        }
        let births = m.births.len();
        if c >= births {
            self.predict(c, &prior.entries[c - births], m);
        }
        let cand = &self.cands[c];
        self.proposal.set_existence(c, cand.existence);
        let sc = m.scans.len();
        for (s, scan) in m.scans.iter().enumerate() {
            let sensor = &m.sensors[scan.sensor];
            let prep = prepare(sensor, &cand.pred, m.ukf);
            let mut pd = prep.as_ref().map_or(0.0, |p| {
                sensor.p_detect_of(&cand.pred.mean, p, scan.activity)
            });
            let prep = prep.filter(|_| pd > 0.0);
            if let Some(slot) = sensor.mode {
                // A track whose mode is off (silent, face turned away) is detected with the
                // sensor's off probability; the row uses the P_D marginal over the mode.
                let off = sensor.off_p_detect.min(pd);
                self.mode_pd[c * sc + s] = (pd, off);
                let on = cand.modes[slot];
                pd = on * pd + (1.0 - on) * off;
            }
            let log_miss = (-pd).ln_1p();
            let log_hit = pd.ln() - sensor.clutter.log_intensity();
            self.log_pd[c * sc + s] = (log_miss, log_hit);
            self.row.clear();
            self.row.push((0, log_miss));
            if let Some(p) = &prep {
                for (j, z) in scan.z.iter().enumerate() {
                    let d2 = p.mahalanobis(&p.innovation(sensor, z));
                    if d2 <= sensor.gate {
                        self.row
                            .push((j as u16 + 1, log_hit + p.log_likelihood(d2)));
                    }
                }
            }
            self.proposal.set_row(c, s, &self.row);
            self.pd[c * sc + s] = pd;
            if let Some(p) = prep {
                self.prep_idx[c * sc + s] = self.preps.len() as u32;
                self.preps.push(p);
                self.gains.push(None);
            }
        }
        self.proposal.seal(c);
        self.cands[c].ready = true;
    }

    /// Predicts survivor `c` from its parent entry, with its gait when the model has one.
    fn predict(&mut self, c: usize, parent: &Entry<N>, m: &StepModel<N>) {
        let cand = &mut self.cands[c];
        // Only a track a camera saw lately has a gait (`gait_camera_memory_s`).
        match m.gait.as_ref().filter(|g| g.applies(parent.unseen_s)) {
            Some(gait) => {
                let modes = match &parent.gait {
                    Some(g) => [&g[0], &g[1]],
                    None => [&parent.density, &parent.density],
                };
                if let Some(p) = gait.predict(&m.transition, modes, parent.walking) {
                    cand.pred = p.merged;
                    cand.walking = p.walking;
                    self.gait_preds[c] = Some(p.modes);
                }
            }
            None => {
                if let Some(p) = m.transition.predict(&parent.density) {
                    cand.pred = p;
                }
                cand.walking = 0.0;
            }
        }
    }

    /// Exact weight of the association map in `self.gamma`; adds the child hypothesis.
    fn score(&mut self, parent_logw: f64, m: &StepModel<N>) {
        let sc = m.scans.len();
        let stride = sc + 1;
        let mut logw = parent_logw;
        self.ids.clear();
        for i in 0..self.local.len() {
            let row = i * stride..(i + 1) * stride;
            // Consecutive samples of a chain differ in few tracks: reuse the last lookup.
            if self.memo_valid[i] && self.memo_rows[row.clone()] == self.gamma[row.clone()] {
                logw += self.memo_terms[i];
                if self.memo_ids[i] != NONE {
                    self.ids.push(self.memo_ids[i]);
                }
                continue;
            }
            let c = self.local[i] as usize;
            let (id, term) = if self.gamma[row.start] == DEAD {
                (NONE, self.proposal.log_dead(c))
            } else {
                self.key.clear();
                self.key.push(c as u32);
                self.key
                    .extend(self.gamma[row.start + 1..row.end].iter().map(|&j| j as u32));
                let (id, new) = self.keys.insert(&self.key);
                if new {
                    let (entry, term) = self.child_entry(c, m);
                    self.new_entries.push(Some(entry));
                    self.new_cands.push(c as u32);
                    self.new_terms.push(term);
                }
                (id as u32, self.new_terms[id])
            };
            self.memo_rows[row.clone()].copy_from_slice(&self.gamma[row]);
            self.memo_valid[i] = true;
            self.memo_ids[i] = id;
            self.memo_terms[i] = term;
            logw += term;
            if id != NONE {
                self.ids.push(id);
            }
        }
        if m.camera.occlusion {
            logw += self.occlusion_correction(m);
        }
        if logw == f64::NEG_INFINITY || logw.is_nan() {
            return;
        }
        self.ids.sort_unstable();
        let (h, new) = self.children.insert(&self.ids);
        if new {
            self.child_logw.push(logw);
        } else {
            self.child_logw[h] = log_add(self.child_logw[h], logw);
        }
    }

    /// The updated density of candidate `c` under the associations in `self.key[1..]`, and its
    /// log weight factor: log P_S (or r_B) + per-sensor miss/detection terms + log likelihood.
    ///
    /// The detecting sensors update in sequence (exact for linear-Gaussian sensors); the first
    /// uses the statistics cached at the prediction, the others are computed afresh.
    fn child_entry(&mut self, c: usize, m: &StepModel<N>) -> (Entry<N>, f64) {
        let sc = m.scans.len();
        let mut term = self.proposal.log_alive(c);
        let mut audio = false;
        let mut seen = false;
        let mut assoc = Vec::new();
        // Outcomes of mode-following sensors are scored jointly with their mode (sequentially,
        // which is exact for sensors independent given the modes).
        let mut modes = self.cands[c].modes.clone();
        for (s, &j) in self.key[1..].iter().enumerate() {
            let sensor = &m.sensors[m.scans[s].sensor];
            if let Some(slot) = sensor.mode {
                let (pd_on, pd_off) = self.mode_pd[c * sc + s];
                let (f, after) = mode_outcome(modes[slot], pd_on, pd_off, j != 0);
                modes[slot] = after;
                term += f.ln();
                if j != 0 {
                    term -= sensor.clutter.log_intensity();
                }
            } else {
                let (log_miss, log_hit) = self.log_pd[c * sc + s];
                term += if j == 0 { log_miss } else { log_hit };
            }
            if j != 0 {
                let sounding = m.scans[s].sounding.get(j as usize - 1).copied();
                audio |= sensor.audio && sounding.unwrap_or(true);
                seen |= !sensor.audio;
                assoc.push((s as u16, j as u16 - 1));
            }
        }
        let mut density: Option<Gaussian<N>> = None;
        for s in 0..sc {
            let j = self.key[1 + s];
            if j == 0 || term == f64::NEG_INFINITY {
                continue;
            }
            let sensor = &m.sensors[m.scans[s].sensor];
            let z = m.scans[s].z[j as usize - 1];
            let step = match &density {
                None => self.first_stage(c, s, &z, m),
                Some(prior) => update(sensor, prior, &z, m.ukf),
            };
            match step {
                Some((g, ll)) => {
                    density = Some(g);
                    term += ll;
                }
                None => term = f64::NEG_INFINITY,
            }
        }
        let cand = &self.cands[c];
        let mut density = density.unwrap_or_else(|| cand.pred.clone());
        if let Some(region) = &m.clamp {
            clamp_position(&mut density.mean, region);
        }
        let entry = Entry {
            label: cand.label,
            density,
            audio,
            modes,
            assoc,
            unseen_s: if seen { 0.0 } else { cand.unseen_s },
            // The gait's update waits for `finish`: most children are pruned.
            walking: cand.walking,
            gait: None,
        };
        (entry, term)
    }

    /// Updates kept child `entry` of candidate `c` under the candidate's gait: each mode's
    /// prediction by the entry's measurements, the modes weighed by their likelihoods, and
    /// the entry's density their merge (the interacting multiple model's estimate).
    fn update_gait(&self, entry: &mut Entry<N>, c: usize, m: &StepModel<N>) {
        let cand = &self.cands[c];
        let Some(modes) = &self.gait_preds[c] else {
            return;
        };
        let measured = entry.assoc.iter().map(|&(s, j)| {
            let scan = &m.scans[s as usize];
            (&m.sensors[scan.sensor], &scan.z[j as usize])
        });
        let Some(u) = gait::update(modes, cand.walking, measured, m.ukf, m.clamp.as_ref()) else {
            return;
        };
        if let Some(density) = u.merged {
            entry.density = density;
        }
        entry.walking = u.walking;
        entry.gait = Some(Box::new(u.modes));
    }

    /// Update of the prediction of candidate `c` by scan `s` with the cached statistics.
    fn first_stage(
        &mut self,
        c: usize,
        s: usize,
        z: &Vector3<f64>,
        m: &StepModel<N>,
    ) -> Option<(Gaussian<N>, f64)> {
        let i = self.prep_idx[c * m.scans.len() + s];
        if i == NONE {
            return None;
        }
        let i = i as usize;
        let sensor = &m.sensors[m.scans[s].sensor];
        if self.gains[i].is_none() {
            self.gains[i] = self.preps[i].complete(sensor, &self.cands[c].pred);
        }
        let (p, g) = (&self.preps[i], self.gains[i].as_ref()?);
        let nu = p.innovation(sensor, z);
        let ll = p.log_likelihood(p.mahalanobis(&nu));
        let mean = g.mean(&self.cands[c].pred.mean, &nu);
        Some((Gaussian { mean, cov: g.cov }, ll))
    }

    /// Importance correction for occlusion-aware camera detection (spec 000 A5): the proposal
    /// used the unoccluded P_D; the exact weight uses P_D reduced for tracks hidden behind another
    /// live track of this hypothesis (positions at the predicted means).
    fn occlusion_correction(&self, m: &StepModel<N>) -> f64 {
        let sc = m.scans.len();
        let stride = sc + 1;
        let half = Vec3::from(m.camera.occluder_half_size_m);
        let mu = m.camera.occluded_factor;
        let mut corr = 0.0;
        for (s, scan) in m.scans.iter().enumerate() {
            let Some(camera) = m.sensors[scan.sensor].camera() else {
                continue;
            };
            let eye = camera.centre();
            for i in 0..self.local.len() {
                let g = &self.gamma[i * stride..(i + 1) * stride];
                let c = self.local[i] as usize;
                let pd = self.pd[c * sc + s];
                if g[0] == DEAD || pd <= 0.0 {
                    continue;
                }
                let target = position_of(&self.cands[c].pred.mean);
                let hidden = (0..self.local.len()).any(|o| {
                    let go = self.gamma[o * stride];
                    o != i
                        && go != DEAD
                        && occludes(
                            &eye,
                            &target,
                            &position_of(&self.cands[self.local[o] as usize].pred.mean),
                            &half,
                        )
                });
                if hidden {
                    corr += if g[1 + s] == 0 {
                        (-mu * pd).ln_1p() - (-pd).ln_1p()
                    } else {
                        mu.ln()
                    };
                }
            }
        }
        corr
    }

    /// Truncates `order` (children by decreasing weight) to its first `max`, then appends, for
    /// each label of a kept child, the best child without that label where the cap cut it.
    fn keep_deaths(&self, order: &mut Vec<usize>, max: usize) {
        if order.len() <= max {
            return;
        }
        let label_of = |e: &u32| self.new_entries[*e as usize].as_ref().map(|x| x.label);
        let mut labels: Vec<Label> = order[..max]
            .iter()
            .flat_map(|&h| self.children.get(h).iter().filter_map(label_of))
            .collect();
        labels.sort_unstable();
        labels.dedup();
        // Positions in `order` of the cut children to keep: sorted, they stay by weight.
        let mut cut: Vec<usize> = labels
            .into_iter()
            .filter_map(|label| {
                order.iter().position(|&h| {
                    !self
                        .children
                        .get(h)
                        .iter()
                        .any(|e| label_of(e) == Some(label))
                })
            })
            .filter(|&i| i >= max)
            .collect();
        cut.sort_unstable();
        cut.dedup();
        let extra: Vec<usize> = cut.iter().map(|&i| order[i]).collect();
        order.truncate(max);
        order.extend(extra);
    }

    /// Normalises, prunes, caps and compacts the children into the new posterior.
    fn finish(&mut self, m: &StepModel<N>) -> Posterior<N> {
        let cfg = m.glmb;
        let lse = log_sum_exp(self.child_logw.iter().copied());
        if !lse.is_finite() {
            return Posterior::empty();
        }
        let floor = cfg.prune_threshold.ln();
        let mut order: Vec<usize> = (0..self.child_logw.len())
            .filter(|&h| self.child_logw[h] - lse >= floor)
            .collect();
        order.sort_unstable_by(|&a, &b| self.child_logw[b].total_cmp(&self.child_logw[a]));
        if cfg.keep_deaths {
            self.keep_deaths(&mut order, cfg.max_hypotheses);
        } else {
            order.truncate(cfg.max_hypotheses);
        }
        let kept = log_sum_exp(order.iter().map(|&h| self.child_logw[h]));
        let mut remap = vec![u32::MAX; self.new_entries.len()];
        let mut out = Posterior {
            entries: Vec::new(),
            hyps: Vec::with_capacity(order.len()),
            ids: Vec::new(),
        };
        for &h in &order {
            let start = out.ids.len() as u32;
            for &e in self.children.get(h) {
                let e = e as usize;
                if remap[e] == u32::MAX {
                    remap[e] = out.entries.len() as u32;
                    if let Some(mut entry) = self.new_entries[e].take() {
                        self.update_gait(&mut entry, self.new_cands[e] as usize, m);
                        out.entries.push(entry);
                    }
                }
                out.ids.push(remap[e]);
            }
            let len = out.ids.len() as u32 - start;
            out.hyps.push((self.child_logw[h] - kept, start, len));
        }
        if out.hyps.is_empty() {
            return Posterior::empty();
        }
        out
    }
}
