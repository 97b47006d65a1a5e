//! The MS-GLMB joint prediction and update (spec 000 3.4-3.6 and A3; spec 003 5.9-5.10).
//!
//! For every parent hypothesis the Gibbs sampler draws T_h ~ H_upd sqrt(w_h) association maps
//! over the candidate tracks (all births plus the parent's tracks). Each distinct map is then
//! weighted exactly, with the sequential multi-sensor update of every live track. Single-object
//! updates live in one table keyed by (candidate track, measurement index per sensor), shared
//! by all parents, so no update is computed twice; identical child hypotheses are merged.

use nalgebra::{SMatrix, Vector3};
use rand::Rng;

use super::birth::BirthTerm;
use super::config::{CameraConfig, GlmbConfig, UkfConfig};
use super::filter::{Prepared, predict, prepare, update};
use super::gaussian::{Gaussian, log_add, log_sum_exp};
use super::gibbs::{DEAD, Proposal, Sampler};
use super::motion::position_of;
use super::occlusion::occludes;
use super::scan::SensorScan;
use super::sensor::Sensor;
use super::slice_set::SliceSet;
use crate::geometry::{Aabb, Vec3};
use crate::label::Label;

/// One track density of the posterior: a label with one association history.
#[derive(Debug, Clone)]
pub(crate) struct Entry<const N: usize> {
    pub label: Label,
    pub density: Gaussian<N>,
    /// Whether the last update associated an audio measurement.
    pub audio: bool,
    /// (scan, measurement) pairs used by the last update.
    pub assoc: Vec<(u16, u16)>,
}

/// A GLMB density: weighted hypotheses over shared track entries, sorted by decreasing weight.
#[derive(Debug, Clone)]
pub(crate) struct Posterior<const N: usize> {
    pub entries: Vec<Entry<N>>,
    /// (log weight, start, len) of each hypothesis in `ids`.
    pub hyps: Vec<(f64, u32, u32)>,
    pub ids: Vec<u32>,
}

impl<const N: usize> Posterior<N> {
    /// The density with no track (certainly).
    pub fn empty() -> Self {
        Self {
            entries: Vec::new(),
            hyps: vec![(0.0, 0, 0)],
            ids: Vec::new(),
        }
    }

    /// Entry indices of hypothesis `h`.
    pub fn tracks(&self, h: usize) -> &[u32] {
        let (_, s, l) = self.hyps[h];
        &self.ids[s as usize..(s + l) as usize]
    }

    /// Normalised weight of hypothesis `h`.
    pub fn weight(&self, h: usize) -> f64 {
        self.hyps[h].0.exp()
    }
}

/// Everything one joint update needs besides the prior.
pub(crate) struct StepModel<'a, const N: usize> {
    pub k: u64,
    pub f: SMatrix<f64, N, N>,
    pub q: SMatrix<f64, N, N>,
    pub survival: f64,
    pub sensors: &'a [Sensor<N>],
    pub scans: &'a [SensorScan],
    pub births: &'a [BirthTerm<N>],
    pub glmb: &'a GlmbConfig,
    pub ukf: &'a UkfConfig,
    pub camera: &'a CameraConfig,
    /// Region (already grown) that track means are clamped into.
    pub clamp: Option<Aabb>,
}

#[derive(Debug, Clone)]
struct Candidate<const N: usize> {
    label: Label,
    pred: Gaussian<N>,
    existence: f64,
    ready: bool,
}

/// Reusable workspace of the joint update.
#[derive(Debug, Clone, Default)]
pub(crate) struct JointUpdate<const N: usize> {
    cands: Vec<Candidate<N>>,
    pd: Vec<f64>,
    prepared: Vec<Option<Prepared<N>>>,
    proposal: Proposal,
    sampler: Sampler,
    samples: SliceSet<u16>,
    keys: SliceSet<u32>,
    children: SliceSet<u32>,
    child_logw: Vec<f64>,
    new_entries: Vec<Entry<N>>,
    new_terms: Vec<f64>,
    local: Vec<u32>,
    gamma: Vec<u16>,
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
        let counts: Vec<usize> = m.scans.iter().map(|s| s.z.len()).collect();
        let half: Vec<f64> = prior.hyps.iter().map(|h| (0.5 * h.0).exp()).collect();
        let total: f64 = half.iter().sum();
        let mut budget: Vec<usize> = half
            .iter()
            .map(|w| (m.glmb.requested_hypotheses as f64 * w / total).round() as usize)
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
            self.samples.clear();
            self.sampler.sample(
                &self.proposal,
                &self.local,
                &counts,
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
        self.finish(m.glmb)
    }

    fn start(&mut self, prior: &Posterior<N>, m: &StepModel<N>) {
        let c = m.scans.len();
        self.cands.clear();
        for (b, birth) in m.births.iter().enumerate() {
            self.cands.push(Candidate {
                label: Label::new(m.k, b as u32),
                pred: birth.density.clone(),
                existence: birth.existence,
                ready: false,
            });
        }
        for e in &prior.entries {
            self.cands.push(Candidate {
                label: e.label,
                pred: e.density.clone(),
                existence: m.survival,
                ready: false,
            });
        }
        let n = self.cands.len();
        self.pd.clear();
        self.pd.resize(n * c, 0.0);
        self.prepared.clear();
        self.prepared.resize(n * c, None);
        self.proposal.reset(n, c);
        self.keys.clear();
        self.children.clear();
        self.child_logw.clear();
        self.new_entries.clear();
        self.new_terms.clear();
    }

    /// Predicts a candidate and computes its proposal rows, once per step.
    fn ensure(&mut self, c: usize, prior: &Posterior<N>, m: &StepModel<N>) {
        if self.cands[c].ready {
            return;
        }
        let births = m.births.len();
        if c >= births {
            if let Some(p) = predict(&prior.entries[c - births].density, &m.f, &m.q) {
                self.cands[c].pred = p;
            }
        }
        let cand = &self.cands[c];
        self.proposal.set_existence(c, cand.existence);
        let sc = m.scans.len();
        for (s, scan) in m.scans.iter().enumerate() {
            let sensor = &m.sensors[scan.sensor];
            let mut pd = sensor.p_detect_at(&cand.pred.mean, scan.activity);
            let prep = if pd > 0.0 {
                prepare(sensor, &cand.pred, m.ukf)
            } else {
                None
            };
            if prep.is_none() {
                pd = 0.0;
            }
            self.row.clear();
            self.row.push((0, (-pd).ln_1p()));
            if let Some(p) = &prep {
                let log_pd = pd.ln() - sensor.log_clutter;
                for (j, z) in scan.z.iter().enumerate() {
                    let d2 = p.mahalanobis(&p.innovation(sensor, z));
                    if d2 <= sensor.gate {
                        self.row.push((j as u16 + 1, log_pd + p.log_likelihood(d2)));
                    }
                }
            }
            self.proposal.set_row(c, s, &self.row);
            self.pd[c * sc + s] = pd;
            self.prepared[c * sc + s] = prep;
        }
        self.cands[c].ready = true;
    }

    /// Exact weight of the association map in `self.gamma`; adds the child hypothesis.
    fn score(&mut self, parent_logw: f64, m: &StepModel<N>) {
        let sc = m.scans.len();
        let stride = sc + 1;
        let mut logw = parent_logw;
        self.ids.clear();
        for i in 0..self.local.len() {
            let c = self.local[i] as usize;
            let g = &self.gamma[i * stride..(i + 1) * stride];
            if g[0] == DEAD {
                logw += (-self.cands[c].existence).ln_1p();
                continue;
            }
            self.key.clear();
            self.key.push(c as u32);
            self.key.extend(g[1..].iter().map(|&j| j as u32));
            let (id, new) = self.keys.insert(&self.key);
            if new {
                let (entry, term) = self.child_entry(c, m);
                self.new_entries.push(entry);
                self.new_terms.push(term);
            }
            logw += self.new_terms[id];
            self.ids.push(id as u32);
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
    fn child_entry(&self, c: usize, m: &StepModel<N>) -> (Entry<N>, f64) {
        let sc = m.scans.len();
        let cand = &self.cands[c];
        let mut term = cand.existence.ln();
        let mut density = cand.pred.clone();
        let mut first = true;
        let mut audio = false;
        let mut assoc = Vec::new();
        for (s, &j) in self.key[1..].iter().enumerate() {
            let pd = self.pd[c * sc + s];
            if j == 0 {
                term += (-pd).ln_1p();
                continue;
            }
            let scan = &m.scans[s];
            let sensor = &m.sensors[scan.sensor];
            let z: &Vector3<f64> = &scan.z[j as usize - 1];
            term += pd.ln() - sensor.log_clutter;
            let prep = if first {
                self.prepared[c * sc + s].as_ref()
            } else {
                None
            };
            match prep {
                Some(p) => {
                    let nu = p.innovation(sensor, z);
                    term += p.log_likelihood(p.mahalanobis(&nu));
                    density = Gaussian {
                        mean: p.mean(&nu),
                        cov: p.cov,
                    };
                }
                None => match update(sensor, &density, z, m.ukf) {
                    Some((g, ll)) => {
                        density = g;
                        term += ll;
                    }
                    None => term = f64::NEG_INFINITY,
                },
            }
            first = false;
            audio |= sensor.audio;
            assoc.push((s as u16, j as u16 - 1));
        }
        if let Some(region) = &m.clamp {
            clamp_position(&mut density.mean, region);
        }
        let entry = Entry {
            label: cand.label,
            density,
            audio,
            assoc,
        };
        (entry, term)
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

    /// Normalises, prunes, caps and compacts the children into the new posterior.
    fn finish(&mut self, cfg: &GlmbConfig) -> Posterior<N> {
        let lse = log_sum_exp(self.child_logw.iter().copied());
        if !lse.is_finite() {
            return Posterior::empty();
        }
        let floor = cfg.prune_threshold.ln();
        let mut order: Vec<usize> = (0..self.child_logw.len())
            .filter(|&h| self.child_logw[h] - lse >= floor)
            .collect();
        order.sort_unstable_by(|&a, &b| self.child_logw[b].total_cmp(&self.child_logw[a]));
        order.truncate(cfg.max_hypotheses);
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
                    out.entries.push(self.new_entries[e].clone());
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

/// Clamps the position part of a state into `region`.
pub(crate) fn clamp_position<const N: usize>(x: &mut nalgebra::SVector<f64, N>, region: &Aabb) {
    let p = region.clamp(&position_of(x));
    for i in 0..(N / 2).min(3) {
        x[i] = p[i];
    }
}
