//! GM-PHD filter with label propagation (spec 002 sections 3, 5 and 6), for comparison.
//!
//! Multi-sensor by the sequential per-sensor update of Pham's Ch. 5 (prune and merge after each
//! sensor). Labels follow spec 002 5.3 with its fixes: components carry label masses through
//! update and merging; estimates (weight above 0.5) are matched to the previous estimates by a
//! minimum-cost assignment on the position distance, restricted to compatible labels and gated;
//! a duplicate or birth label gets a fresh one; a vanished label coasts for a while and an
//! unmatched estimate near its predicted position takes it back (spec 002 14).

use std::collections::HashMap;

use nalgebra::SVector;

use crate::eval::assignment::{CostMatrix, assign};

use super::birth::{BirthContext, BirthScan, BirthTerm, births_from_measurements};
use super::clutter;
use super::config::{ClutterConfig, ConfigError, TrackerConfig};
use super::estimator::Reporter;
use super::filter::{Transition, prepare};
use super::gaussian::{Gaussian, mixture_moments};
use super::glmb::{clamp_region, compile_sensors};
use super::modes::Modes;
use super::motion::{MotionModel, clamp_position, position_of, velocity_of};
use super::scan::{SensorScan, StepClock, collect};
use super::sensor::{Sensor, SensorModel};
use super::{ClutterRateReport, StepInput, TrackEstimate, Tracker, TrackerStats, covariance6};
use crate::geometry::Aabb;
use crate::label::Label;

/// Identity carried by a component: a track label, or a birth term of the current step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Tag {
    Label(Label),
    Birth(u32),
}

#[derive(Debug, Clone)]
struct Component<const N: usize> {
    w: f64,
    g: Gaussian<N>,
    /// Tags with the fraction of the weight each carries (fractions sum to 1).
    tags: Vec<(Tag, f64)>,
    /// Fraction of the weight that comes from an audio detection this step.
    audio: f64,
}

impl<const N: usize> Component<N> {
    fn dominant(&self) -> Option<Tag> {
        self.tags
            .iter()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|t| t.0)
    }
}

/// GM-PHD tracker over the state `[position; velocity]` of dimension N.
#[derive(Debug, Clone)]
pub struct GmphdTracker<const N: usize> {
    cfg: TrackerConfig,
    motion: MotionModel<N>,
    sensors: Vec<Sensor<N>>,
    /// Detectability modes of the sensors; used only to condition births (the PHD has no modes).
    modes: Modes,
    region: Option<Aabb>,
    fixed_births: Vec<BirthTerm<N>>,
    comps: Vec<Component<N>>,
    pending: Vec<BirthTerm<N>>,
    previous: Vec<(Label, SVector<f64, N>)>,
    coasting: Vec<(Label, SVector<f64, N>, u32)>,
    clock: StepClock,
    reporter: Reporter,
    stats: TrackerStats,
}

impl<const N: usize> GmphdTracker<N> {
    /// A tracker with an explicit motion model and fixed birth terms.
    pub fn new(
        cfg: &TrackerConfig,
        motion: MotionModel<N>,
        sensors: Vec<SensorModel>,
        region: Option<Aabb>,
        fixed_births: Vec<BirthTerm<N>>,
    ) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let (sensors, modes) = compile_sensors(&sensors, cfg)?;
        Ok(Self {
            cfg: cfg.clone(),
            motion: motion.validated()?,
            sensors,
            modes,
            region,
            fixed_births,
            comps: Vec::new(),
            pending: Vec::new(),
            previous: Vec::new(),
            coasting: Vec::new(),
            clock: StepClock::default(),
            reporter: Reporter::new(&cfg.estimator, cfg.speaking_smoothing),
            stats: TrackerStats::default(),
        })
    }

    /// Sum of the component weights: the expected number of targets.
    pub fn expected_count(&self) -> f64 {
        self.comps.iter().map(|c| c.w).sum()
    }

    /// One sensor's PHD update (spec 002 3.3); returns r_U per measurement.
    fn update_sensor(&mut self, scan: &SensorScan) -> Vec<f64> {
        let sensor = &self.sensors[scan.sensor];
        let mut out = Vec::with_capacity(self.comps.len() * (1 + scan.z.len()));
        let mut detections: Vec<Vec<Component<N>>> = vec![Vec::new(); scan.z.len()];
        let mut scores: Vec<Vec<f64>> = vec![Vec::new(); scan.z.len()];
        for c in &self.comps {
            let pd = sensor.p_detect_at(&c.g.mean, scan.activity);
            let prep = (pd > 0.0)
                .then(|| {
                    let p = prepare(sensor, &c.g, &self.cfg.ukf)?;
                    let g = p.complete(sensor, &c.g)?;
                    Some((p, g))
                })
                .flatten();
            let pd = if prep.is_some() { pd } else { 0.0 };
            let mut missed = c.clone();
            missed.w *= 1.0 - pd;
            out.push(missed);
            let Some((p, gain)) = prep else { continue };
            for (j, z) in scan.z.iter().enumerate() {
                let nu = p.innovation(sensor, z);
                let d2 = p.mahalanobis(&nu);
                if d2 > sensor.gate {
                    continue;
                }
                let score = pd.ln() + c.w.ln() + p.log_likelihood(d2);
                let mut d = c.clone();
                d.g = Gaussian {
                    mean: gain.mean(&c.g.mean, &nu),
                    cov: gain.cov,
                };
                if sensor.audio && scan.sounding.get(j).copied().unwrap_or(true) {
                    d.audio = 1.0;
                }
                detections[j].push(d);
                scores[j].push(score);
            }
        }
        let mut r_u = vec![0.0; scan.z.len()];
        for (j, (dets, sc)) in detections.into_iter().zip(scores).enumerate() {
            let denom = super::gaussian::log_add(
                sensor.clutter.log_intensity(),
                super::gaussian::log_sum_exp(sc.iter().copied()),
            );
            for (mut d, s) in dets.into_iter().zip(sc) {
                d.w = (s - denom).exp();
                r_u[j] += d.w;
                out.push(d);
            }
            r_u[j] = r_u[j].min(1.0);
        }
        self.comps = out;
        r_u
    }

    /// Pruning and merging (Vo & Ma 2006, spec 002 3.4), labels and audio carried along.
    ///
    /// Unlike the thesis (which merges regardless and keeps the union of labels), components
    /// whose dominant labels differ are not merged: the labelled GM-PHD of Panta, Clark & Vo
    /// (2009) does the same, and it keeps identities through crossings.
    fn prune_and_merge(&mut self) {
        let cfg = &self.cfg.gmphd;
        let mut rest: Vec<Component<N>> = std::mem::take(&mut self.comps)
            .into_iter()
            .filter(|c| c.w > cfg.prune_threshold && c.w.is_finite())
            .collect();
        rest.sort_by(|a, b| b.w.total_cmp(&a.w));
        let inverses: Vec<_> = rest.iter().map(|c| c.g.cov.cholesky()).collect();
        let mut used = vec![false; rest.len()];
        let mut merged = Vec::new();
        for j in 0..rest.len() {
            if used[j] {
                continue;
            }
            let mj = rest[j].g.mean;
            let leader = rest[j].dominant();
            let members: Vec<usize> = (j..rest.len())
                .filter(|&i| {
                    // Components of two different tracks never merge (a merged pair loses who is
                    // who when two people cross); births merge into anything.
                    let tag = rest[i].dominant();
                    let compatible =
                        i == j || tag == leader || matches!(tag, Some(Tag::Birth(_)) | None);
                    !used[i]
                        && compatible
                        && inverses[i].as_ref().is_none_or(|ch| {
                            let d = rest[i].g.mean - mj;
                            d.dot(&ch.solve(&d)) <= cfg.merge_threshold
                        })
                })
                .collect();
            let w: f64 = members.iter().map(|&i| rest[i].w).sum();
            let Gaussian { mean, mut cov } =
                mixture_moments(members.iter().map(|&i| (rest[i].w / w, &rest[i].g)));
            let mut tags: Vec<(Tag, f64)> = Vec::new();
            let mut audio = 0.0;
            for &i in &members {
                used[i] = true;
                let c = &rest[i];
                audio += c.audio * c.w / w;
                for &(t, f) in &c.tags {
                    match tags.iter_mut().find(|x| x.0 == t) {
                        Some(x) => x.1 += f * c.w / w,
                        None => tags.push((t, f * c.w / w)),
                    }
                }
            }
            if !super::gaussian::condition(&mut cov) {
                continue;
            }
            merged.push(Component {
                w,
                g: Gaussian { mean, cov },
                tags,
                audio,
            });
        }
        merged.sort_by(|a, b| b.w.total_cmp(&a.w));
        merged.truncate(cfg.max_components);
        self.comps = merged;
    }

    /// Predicts every component over `dt` (survival, motion) and adds this step's birth terms:
    /// the fixed ones, then the measurement births planned last step (taken from `pending`).
    /// Returns the transition matrix the label association predicts with.
    fn predict(&mut self, dt: f64) -> nalgebra::SMatrix<f64, N, N> {
        let (f, q) = self.motion.transition(dt);
        let ps = self.cfg.survival_probability;
        let transition = Transition::new(f, q);
        for c in &mut self.comps {
            if let Some(g) = transition.predict(&c.g) {
                c.g = g;
            }
            c.w *= ps;
            c.audio = 0.0;
        }
        let mut births = self.fixed_births.clone();
        births.append(&mut self.pending);
        for (b, t) in births.into_iter().enumerate() {
            self.comps.push(Component {
                w: t.existence,
                g: t.density,
                tags: vec![(Tag::Birth(b as u32), 1.0)],
                audio: 0.0,
            });
        }
        f
    }

    /// Next step's births from this step's measurements that no labelled component explains
    /// (`r_u`: each measurement's probability of having been assigned).
    fn measurement_births(&self, scans: &[SensorScan], r_u: &[Vec<f64>]) -> Vec<BirthTerm<N>> {
        let min_w = self.cfg.birth.suppress_existence;
        let confirmed: Vec<Gaussian<N>> = self
            .comps
            .iter()
            .filter(|c| c.w >= min_w && matches!(c.dominant(), Some(Tag::Label(_))))
            .map(|c| c.g.clone())
            .collect();
        let ctx = BirthContext::new(&self.cfg, self.region.as_ref(), &self.sensors, &self.modes);
        let birth_scans = BirthScan::of_step(scans, r_u);
        births_from_measurements(&ctx, &birth_scans, &confirmed)
            .into_iter()
            .map(|b| b.term)
            .collect()
    }

    /// Label association of the extracted estimates (spec 002 5.3 steps 4-8).
    fn label_estimates(&mut self, k: u64, f: &nalgebra::SMatrix<f64, N, N>) -> Vec<usize> {
        let cfg = &self.cfg.gmphd;
        let est: Vec<usize> = (0..self.comps.len())
            .filter(|&i| self.comps[i].w > cfg.extraction_threshold)
            .collect();
        let mut labels = self.match_previous(&est, f);
        for c in &mut self.coasting {
            c.1 = f * c.1;
            c.2 += 1;
        }
        self.label_unmatched(&est, &mut labels, k);
        let current: Vec<(Label, SVector<f64, N>)> = est
            .iter()
            .zip(&labels)
            .filter_map(|(&i, l)| l.map(|l| (l, self.comps[i].g.mean)))
            .collect();
        for (l, x) in &self.previous {
            if !current.iter().any(|c| c.0 == *l) {
                self.coasting.push((*l, *x, 0));
            }
        }
        self.coasting
            .retain(|c| c.2 <= cfg.label_coast_steps && !current.iter().any(|x| x.0 == c.0));
        for (&i, l) in est.iter().zip(&labels) {
            if let Some(l) = l {
                self.comps[i].tags = vec![(Tag::Label(*l), 1.0)];
            }
        }
        for (i, c) in self.comps.iter_mut().enumerate() {
            if !est.contains(&i)
                && let Some(t) = c.dominant()
            {
                c.tags = vec![(t, 1.0)];
            }
        }
        self.previous = current;
        est
    }

    /// Steps 4-5: the estimates `est` matched one to one with the previous step's labels
    /// (predicted by `f`), each pair within the gate and carrying that label among its tags.
    fn match_previous(
        &self,
        est: &[usize],
        f: &nalgebra::SMatrix<f64, N, N>,
    ) -> Vec<Option<Label>> {
        let cfg = &self.cfg.gmphd;
        let predicted: Vec<(Label, SVector<f64, N>)> =
            self.previous.iter().map(|(l, x)| (*l, f * x)).collect();
        // Infeasible pairs cost more than any feasible set of matches.
        let big = 1e6 * (1.0 + cfg.label_gate_m) * (est.len() + predicted.len()) as f64;
        let cost: Vec<Vec<f64>> = est
            .iter()
            .map(|&i| {
                let c = &self.comps[i];
                predicted
                    .iter()
                    .map(|(l, x)| {
                        let d = (position_of(&c.g.mean) - position_of(x)).norm();
                        let compatible = c.tags.iter().any(|t| t.0 == Tag::Label(*l));
                        if compatible && d <= cfg.label_gate_m {
                            d
                        } else {
                            big
                        }
                    })
                    .collect()
            })
            .collect();
        let matches = assign(&CostMatrix::from_fn(est.len(), predicted.len(), |i, j| {
            cost[i][j]
        }));
        let mut labels: Vec<Option<Label>> = vec![None; est.len()];
        for (i, j) in matches.pairs {
            if cost[i][j] < big {
                labels[i] = Some(predicted[j].0);
            }
        }
        labels
    }

    /// Steps 6-7: an unmatched estimate keeps its dominant label if no other took it, else
    /// takes the nearest coasting label within the gate, else a fresh label of step `k`.
    fn label_unmatched(&self, est: &[usize], labels: &mut [Option<Label>], k: u64) {
        let cfg = &self.cfg.gmphd;
        let mut fresh = 0u32;
        for i in 0..est.len() {
            if labels[i].is_some() {
                continue;
            }
            let c = &self.comps[est[i]];
            let taken = |l: &Label| labels.contains(&Some(*l));
            let label = match c.dominant() {
                Some(Tag::Label(l)) if !taken(&l) => l,
                _ => {
                    let p = position_of(&c.g.mean);
                    let nearest = self
                        .coasting
                        .iter()
                        .filter(|(l, x, _)| {
                            !taken(l) && (position_of(x) - p).norm() <= cfg.label_gate_m
                        })
                        .min_by(|a, b| {
                            let da = (position_of(&a.1) - p).norm();
                            let db = (position_of(&b.1) - p).norm();
                            da.total_cmp(&db)
                        })
                        .map(|c| c.0);
                    nearest.unwrap_or_else(|| {
                        fresh += 1;
                        Label::new(k, fresh - 1)
                    })
                }
            };
            labels[i] = Some(label);
        }
    }
}

impl<const N: usize> Tracker for GmphdTracker<N> {
    fn step(&mut self, input: &StepInput) -> Vec<TrackEstimate> {
        let (k, dt) = self.clock.advance(input, &mut self.stats);
        let scans = collect(input, &self.sensors, &mut self.stats);
        let f = self.predict(dt);
        let mut r_u = Vec::with_capacity(scans.len());
        for scan in &scans {
            r_u.push(self.update_sensor(scan));
            self.prune_and_merge();
        }
        if scans.is_empty() {
            self.prune_and_merge();
        }
        clutter::observe_step(&self.cfg.clutter, &mut self.sensors, &scans, &r_u, dt);
        if let Some(region) = clamp_region(&self.cfg, self.region.as_ref()) {
            for c in &mut self.comps {
                clamp_position(&mut c.g.mean, &region);
            }
        }
        let est = self.label_estimates(k, &f);
        let estimate = |c: &Component<N>, label: Label| TrackEstimate {
            label,
            position: position_of(&c.g.mean),
            velocity: velocity_of(&c.g.mean),
            covariance: covariance6(&c.g.cov),
            existence: c.w.min(1.0),
            speaking: c.audio.clamp(0.0, 1.0),
        };
        let mut estimates = Vec::with_capacity(est.len());
        for &i in &est {
            if let Some((Tag::Label(l), _)) = self.comps[i].tags.first() {
                estimates.push(estimate(&self.comps[i], *l));
            }
        }
        // A target missed by the sensors drops below the extraction threshold at once (spec 002
        // 6.4); its strongest component still feeds the reporting hysteresis.
        let mut fallback: HashMap<Label, TrackEstimate> = HashMap::new();
        for c in &self.comps {
            if let Some(Tag::Label(l)) = c.dominant()
                && fallback.get(&l).is_none_or(|e| e.existence < c.w.min(1.0))
            {
                fallback.insert(l, estimate(c, l));
            }
        }
        let audio = scans.iter().any(|s| self.sensors[s.sensor].audio);
        let out = self.reporter.report(estimates, &fallback, audio);
        if self.cfg.birth.from_measurements {
            self.pending = self.measurement_births(&scans, &r_u);
        }
        out
    }

    fn set_sensors(&mut self, sensors: Vec<SensorModel>) -> Result<(), ConfigError> {
        let (mut compiled, modes) = compile_sensors(&sensors, &self.cfg)?;
        clutter::carry_over(&self.sensors, &mut compiled);
        (self.sensors, self.modes) = (compiled, modes);
        self.pending.clear();
        Ok(())
    }

    fn set_clutter(&mut self, cfg: &ClutterConfig) {
        clutter::reconfigure(&mut self.cfg.clutter, cfg, &mut self.sensors);
    }

    fn reset(&mut self) {
        self.comps.clear();
        clutter::reset(&mut self.sensors);
        self.pending.clear();
        self.previous.clear();
        self.coasting.clear();
        self.clock = StepClock::default();
        self.reporter.reset();
    }

    fn stats(&self) -> TrackerStats {
        self.stats
    }

    fn clutter_rates(&self) -> Vec<ClutterRateReport> {
        self.sensors.iter().map(|s| s.clutter.report()).collect()
    }
}
