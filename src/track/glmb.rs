//! The multi-sensor GLMB tracker: joint prediction-update, estimator, measurement-driven birth.

use std::collections::HashMap;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::birth::{BirthContext, BirthScan, BirthTerm, births_from_measurements};
use super::config::{ConfigError, TrackerConfig};
use super::estimator::Reporter;
use super::filter::Transition;
use super::gaussian::Gaussian;
use super::joint_update::{Entry, JointUpdate, Posterior, StepModel};
use super::motion::{MotionModel, position_of, velocity_of};
use super::scan::{SensorScan, StepClock, collect};
use super::sensor::{Sensor, SensorModel};
use super::voice::VoiceModel;
use super::{StepInput, TrackEstimate, Tracker, TrackerStats, covariance6};
use crate::geometry::{Aabb, Vec3};
use crate::label::Label;

/// Margin (m) by which the region is grown before track means are clamped into it.
const CLAMP_MARGIN_M: f64 = 0.5;

/// Multi-sensor GLMB tracker over the state `[position; velocity]` of dimension N.
#[derive(Debug, Clone)]
pub struct GlmbTracker<const N: usize> {
    cfg: TrackerConfig,
    motion: MotionModel<N>,
    sensors: Vec<Sensor<N>>,
    region: Option<Aabb>,
    fixed_births: Vec<BirthTerm<N>>,
    seed: u64,
    rng: ChaCha8Rng,
    posterior: Posterior<N>,
    pending: Vec<BirthTerm<N>>,
    clock: StepClock,
    reporter: Reporter,
    stats: TrackerStats,
    work: JointUpdate<N>,
}

/// Per-label marginals of the posterior.
#[derive(Debug, Clone, Copy)]
struct LabelInfo {
    existence: f64,
    audio: f64,
    best_entry: usize,
    best_weight: f64,
}

pub(crate) fn compile_sensors<const N: usize>(
    models: &[SensorModel],
    cfg: &TrackerConfig,
) -> Result<Vec<Sensor<N>>, ConfigError> {
    models
        .iter()
        .enumerate()
        .map(|(i, m)| Sensor::compile(m, i, cfg))
        .collect()
}

/// The region grown by the clamp margin, when clamping is configured.
pub(crate) fn clamp_region(cfg: &TrackerConfig, region: Option<&Aabb>) -> Option<Aabb> {
    let r = region.filter(|_| cfg.clamp_to_region)?;
    let m = Vec3::repeat(CLAMP_MARGIN_M);
    Some(Aabb {
        min: r.min - m,
        max: r.max + m,
    })
}

impl<const N: usize> GlmbTracker<N> {
    /// A tracker with an explicit motion model and fixed birth terms (any state dimension).
    pub fn new(
        cfg: &TrackerConfig,
        motion: MotionModel<N>,
        sensors: Vec<SensorModel>,
        region: Option<Aabb>,
        fixed_births: Vec<BirthTerm<N>>,
        seed: u64,
    ) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let motion = motion.validated()?;
        for (i, b) in fixed_births.iter().enumerate() {
            let ok = b.existence > 0.0
                && b.existence < 1.0
                && b.density.mean.iter().all(|v| v.is_finite())
                && b.density.cov.cholesky().is_some();
            if !ok {
                return Err(ConfigError::new(
                    format!("fixed_births[{i}]"),
                    "needs 0 < existence < 1, a finite mean and a positive definite covariance",
                ));
            }
        }
        Ok(Self {
            cfg: cfg.clone(),
            motion,
            sensors: compile_sensors(&sensors, cfg)?,
            region,
            fixed_births,
            seed,
            rng: ChaCha8Rng::seed_from_u64(seed),
            posterior: Posterior::empty(),
            pending: Vec::new(),
            clock: StepClock::default(),
            reporter: Reporter::new(&cfg.estimator, cfg.speaking_smoothing),
            stats: TrackerStats::default(),
            work: JointUpdate::default(),
        })
    }

    /// Cardinality distribution rho(n) of the posterior.
    pub fn cardinality(&self) -> Vec<f64> {
        let mut rho = Vec::new();
        for h in 0..self.posterior.hyps.len() {
            let n = self.posterior.tracks(h).len();
            if rho.len() <= n {
                rho.resize(n + 1, 0.0);
            }
            rho[n] += self.posterior.weight(h);
        }
        rho
    }

    /// Number of hypotheses held.
    pub fn hypothesis_count(&self) -> usize {
        self.posterior.hyps.len()
    }

    /// Existence probability of every label in the posterior.
    pub fn existence(&self) -> Vec<(Label, f64)> {
        let (_, labels) = self.marginals(&[]);
        let mut v: Vec<_> = labels.iter().map(|(l, i)| (*l, i.existence)).collect();
        v.sort_by_key(|p| p.0);
        v
    }

    /// Entry weights, label marginals and (when scans are given) r_U per measurement.
    fn marginals(&self, scans: &[SensorScan]) -> (Vec<Vec<f64>>, HashMap<Label, LabelInfo>) {
        let post = &self.posterior;
        let mut entry_w = vec![0.0; post.entries.len()];
        for h in 0..post.hyps.len() {
            let w = post.weight(h);
            for &e in post.tracks(h) {
                entry_w[e as usize] += w;
            }
        }
        let mut r_u: Vec<Vec<f64>> = scans.iter().map(|s| vec![0.0; s.z.len()]).collect();
        let mut labels: HashMap<Label, LabelInfo> = HashMap::new();
        for (e, entry) in post.entries.iter().enumerate() {
            let w = entry_w[e];
            let info = labels.entry(entry.label).or_insert(LabelInfo {
                existence: 0.0,
                audio: 0.0,
                best_entry: e,
                best_weight: -1.0,
            });
            info.existence += w;
            if entry.audio {
                info.audio += w;
            }
            if w > info.best_weight {
                info.best_weight = w;
                info.best_entry = e;
            }
            for &(s, j) in &entry.assoc {
                if let Some(v) = r_u.get_mut(s as usize).and_then(|r| r.get_mut(j as usize)) {
                    *v += w;
                }
            }
        }
        (r_u, labels)
    }

    fn estimate_of(&self, entry: &Entry<N>, info: &LabelInfo) -> TrackEstimate {
        let existence = info.existence.clamp(0.0, 1.0);
        TrackEstimate {
            label: entry.label,
            position: position_of(&entry.density.mean),
            velocity: velocity_of(&entry.density.mean),
            covariance: covariance6(&entry.density.cov),
            existence,
            speaking: if existence > 0.0 {
                (info.audio / info.existence).clamp(0.0, 1.0)
            } else {
                0.0
            },
        }
    }

    /// The standard GLMB estimator (MAP cardinality, best hypothesis of that cardinality),
    /// followed by the reporting hysteresis.
    fn report(&mut self, labels: &HashMap<Label, LabelInfo>, audio: bool) -> Vec<TrackEstimate> {
        let post = &self.posterior;
        let rho = self.cardinality();
        let n_hat = rho
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map_or(0, |(n, _)| n);
        // Hypotheses are sorted by decreasing weight.
        let best = (0..post.hyps.len()).find(|&h| post.tracks(h).len() == n_hat);
        let mut estimated = Vec::new();
        if let Some(h) = best {
            for &e in post.tracks(h) {
                let entry = &post.entries[e as usize];
                if let Some(info) = labels.get(&entry.label) {
                    estimated.push(self.estimate_of(entry, info));
                }
            }
        }
        let fallback: HashMap<Label, TrackEstimate> = labels
            .iter()
            .map(|(l, info)| (*l, self.estimate_of(&post.entries[info.best_entry], info)))
            .collect();
        self.reporter.report(estimated, &fallback, audio)
    }
}

impl<const N: usize> Tracker for GlmbTracker<N> {
    fn step(&mut self, input: &StepInput) -> Vec<TrackEstimate> {
        let (k, dt) = self.clock.advance(input, &mut self.stats);
        let scans = collect(input, &self.sensors, &mut self.stats);
        let (f, q) = self.motion.transition(dt);
        let mut births = self.fixed_births.clone();
        births.append(&mut self.pending);
        let model = StepModel {
            k,
            dt,
            transition: Transition::new(f, q),
            voice: VoiceModel::new(&self.cfg.voice),
            survival: self.cfg.survival_probability,
            sensors: &self.sensors,
            scans: &scans,
            births: &births,
            glmb: &self.cfg.glmb,
            ukf: &self.cfg.ukf,
            camera: &self.cfg.camera,
            clamp: clamp_region(&self.cfg, self.region.as_ref()),
        };
        self.posterior = self.work.run(&self.posterior, &model, &mut self.rng);
        let (r_u, labels) = self.marginals(&scans);
        let audio = scans.iter().any(|s| self.sensors[s.sensor].audio);
        let out = self.report(&labels, audio);
        if self.cfg.birth.from_measurements {
            // Births are suppressed near every track that is reasonably likely to exist.
            let confirmed: Vec<Gaussian<N>> = labels
                .values()
                .filter(|i| i.existence >= self.cfg.birth.suppress_existence)
                .map(|i| self.posterior.entries[i.best_entry].density.clone())
                .collect();
            let ctx = BirthContext {
                cfg: &self.cfg.birth,
                ukf: &self.cfg.ukf,
                region: self.region.as_ref(),
                sensors: &self.sensors,
            };
            let birth_scans: Vec<BirthScan> = scans
                .iter()
                .zip(&r_u)
                .map(|(s, a)| BirthScan {
                    sensor: s.sensor,
                    z: &s.z,
                    assoc: a,
                })
                .collect();
            self.pending = births_from_measurements(&ctx, &birth_scans, &confirmed);
        }
        out
    }

    fn set_sensors(&mut self, sensors: Vec<SensorModel>) -> Result<(), ConfigError> {
        self.sensors = compile_sensors(&sensors, &self.cfg)?;
        // Pending births refer to measurements of the old calibration.
        self.pending.clear();
        Ok(())
    }

    fn reset(&mut self) {
        self.posterior = Posterior::empty();
        self.pending.clear();
        self.clock = StepClock::default();
        self.reporter.reset();
        self.rng = ChaCha8Rng::seed_from_u64(self.seed);
    }

    fn stats(&self) -> TrackerStats {
        self.stats
    }
}
