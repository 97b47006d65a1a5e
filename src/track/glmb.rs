//! The multi-sensor GLMB tracker: joint prediction-update, estimator, measurement-driven birth.

use std::collections::HashMap;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::birth::{Birth, BirthContext, BirthScan, BirthTerm, births_from_measurements};
use super::clutter;
use super::config::{ClutterConfig, ConfigError, TrackerConfig};
use super::estimator::Reporter;
use super::filter::Transition;
use super::gait::Gait;
use super::gaussian::Gaussian;
use super::joint_update::{Entry, JointUpdate, Posterior, StepModel};
use super::modes::{ModeModel, Modes};
use super::motion::{MotionModel, position_of, velocity_of};
use super::scan::{SensorScan, StepClock, collect};
use super::sensor::{Sensor, SensorModel};
use super::{ClutterRateReport, StepInput, TrackEstimate, Tracker, TrackerStats, covariance6};
use crate::geometry::{Aabb, Vec3};
use crate::label::Label;

/// Margin (m) by which the region is grown before track means are clamped into it.
const CLAMP_MARGIN_M: f64 = 0.5;

/// Multi-sensor GLMB tracker over the state `[position; velocity]` of dimension N.
#[derive(Debug, Clone)]
pub struct GlmbTracker<const N: usize> {
    cfg: TrackerConfig,
    motion: MotionModel<N>,
    /// The walking mode's motion (`MotionConfig::walking_beta_per_s`) and the gait's chain;
    /// None without a gait (turned off, or a motion model without a velocity decay).
    gait: Option<(MotionModel<N>, ModeModel)>,
    sensors: Vec<Sensor<N>>,
    modes: Modes,
    region: Option<Aabb>,
    fixed_births: Vec<BirthTerm<N>>,
    seed: u64,
    rng: ChaCha8Rng,
    posterior: Posterior<N>,
    pending: Vec<Birth<N>>,
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

/// Compiles the sensor models and assigns their detectability mode slots.
pub(crate) fn compile_sensors<const N: usize>(
    models: &[SensorModel],
    cfg: &TrackerConfig,
) -> Result<(Vec<Sensor<N>>, Modes), ConfigError> {
    let mut sensors = models
        .iter()
        .enumerate()
        .map(|(i, m)| Sensor::compile(m, i, cfg))
        .collect::<Result<Vec<_>, _>>()?;
    let modes = Modes::assign(&mut sensors, &cfg.voice, &cfg.face);
    Ok((sensors, modes))
}

/// The walking mode's motion and the gait's chain, when the settings ask for a gait and the
/// motion has a velocity decay.
fn gait_of<const N: usize>(
    cfg: &TrackerConfig,
    motion: &MotionModel<N>,
) -> Option<(MotionModel<N>, ModeModel)> {
    let m = &cfg.motion;
    if !(m.gait && matches!(motion, MotionModel::Langevin { .. })) {
        return None;
    }
    let walking = motion.with_decay(m.walking_beta_per_s, m.walking_sigma_m_per_s);
    // A new track walks as often as tracks do in the long run.
    let initial = m.mean_walk_s / (m.mean_walk_s + m.mean_stand_s);
    Some((
        walking,
        ModeModel::new(m.mean_walk_s, m.mean_stand_s, initial),
    ))
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
        let (sensors, modes) = compile_sensors(&sensors, cfg)?;
        Ok(Self {
            cfg: cfg.clone(),
            gait: gait_of(cfg, &motion),
            motion,
            sensors,
            modes,
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
        let (_, _, labels) = self.marginals(&[]);
        let mut v: Vec<_> = labels.iter().map(|(l, i)| (*l, i.existence)).collect();
        v.sort_by_key(|p| p.0);
        v
    }

    /// Entry weights, label marginals and (when scans are given) r_U per measurement.
    fn marginals(
        &self,
        scans: &[SensorScan],
    ) -> (Vec<f64>, Vec<Vec<f64>>, HashMap<Label, LabelInfo>) {
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
        (entry_w, r_u, labels)
    }

    /// The step's gait model, when the tracker has a gait.
    fn gait(&self, dt: f64) -> Option<Gait<N>> {
        let (walking, chain) = self.gait.as_ref()?;
        let (f, q) = walking.transition(dt);
        let memory_s = self.cfg.motion.gait_camera_memory_s;
        Some(Gait::new(Transition::new(f, q), *chain, dt, memory_s))
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

    /// The track densities that suppress births: every entry of weight at least
    /// `birth.suppress_existence`, except those within `SAME_DENSITY_M` of a heavier entry of
    /// the same label (the association histories of a label mostly differ by one measurement
    /// and give nearly the same density; gating against each would cost a filter preparation
    /// per entry and sensor for nothing).
    fn suppressing_densities(&self, entry_w: &[f64]) -> Vec<Gaussian<N>> {
        const SAME_DENSITY_M: f64 = 0.1;
        let entries = &self.posterior.entries;
        let mut order: Vec<usize> = (0..entries.len())
            .filter(|&e| entry_w[e] >= self.cfg.birth.suppress_existence)
            .collect();
        order.sort_by(|&a, &b| entry_w[b].total_cmp(&entry_w[a]));
        let mut kept: Vec<usize> = Vec::new();
        for e in order {
            let p = position_of(&entries[e].density.mean);
            let near = kept.iter().any(|&k| {
                entries[k].label == entries[e].label
                    && (position_of(&entries[k].density.mean) - p).norm() < SAME_DENSITY_M
            });
            if !near {
                kept.push(e);
            }
        }
        kept.iter().map(|&e| entries[e].density.clone()).collect()
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
        let gait = self.gait(dt);
        let mut births = self.fixed_births.clone();
        let mut birth_modes = vec![self.modes.initial(); births.len()];
        for b in self.pending.drain(..) {
            births.push(b.term);
            birth_modes.push(b.modes);
        }
        let model = StepModel {
            k,
            dt,
            transition: Transition::new(f, q),
            gait,
            modes: &self.modes,
            survival: self.cfg.survival_probability,
            sensors: &self.sensors,
            scans: &scans,
            births: &births,
            birth_modes: &birth_modes,
            glmb: &self.cfg.glmb,
            ukf: &self.cfg.ukf,
            camera: &self.cfg.camera,
            clamp: clamp_region(&self.cfg, self.region.as_ref()),
        };
        self.posterior = self.work.run(&self.posterior, &model, &mut self.rng);
        let (entry_w, r_u, labels) = self.marginals(&scans);
        clutter::observe_step(&self.cfg.clutter, &mut self.sensors, &scans, &r_u, dt);
        let audio = scans.iter().any(|s| self.sensors[s.sensor].audio);
        let out = self.report(&labels, audio);
        if self.cfg.birth.from_measurements {
            // Births are suppressed near every track density that is reasonably likely: a
            // second label born from measurements a track already explains could only share
            // that track's existence (the data cannot tell the two apart) and take over its
            // identity later.
            let confirmed = self.suppressing_densities(&entry_w);
            let ctx =
                BirthContext::new(&self.cfg, self.region.as_ref(), &self.sensors, &self.modes);
            let birth_scans = BirthScan::of_step(&scans, &r_u);
            self.pending = births_from_measurements(&ctx, &birth_scans, &confirmed);
        }
        out
    }

    fn set_sensors(&mut self, sensors: Vec<SensorModel>) -> Result<(), ConfigError> {
        let (mut compiled, modes) = compile_sensors(&sensors, &self.cfg)?;
        clutter::carry_over(&self.sensors, &mut compiled);
        (self.sensors, self.modes) = (compiled, modes);
        // Pending births refer to measurements of the old calibration.
        self.pending.clear();
        Ok(())
    }

    fn set_clutter(&mut self, cfg: &ClutterConfig) {
        clutter::reconfigure(&mut self.cfg.clutter, cfg, &mut self.sensors);
    }

    fn reset(&mut self) {
        self.posterior = Posterior::empty();
        clutter::reset(&mut self.sensors);
        self.pending.clear();
        self.clock = StepClock::default();
        self.reporter.reset();
        self.rng = ChaCha8Rng::seed_from_u64(self.seed);
    }

    fn stats(&self) -> TrackerStats {
        self.stats
    }

    fn clutter_rates(&self) -> Vec<ClutterRateReport> {
        self.sensors.iter().map(|s| s.clutter.report()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track::config::FilterKind;
    use crate::track::{Measurement, Scan};

    /// A tracker with one array's direction-only sensor at (3, 2.5, 0.8) m in a
    /// 6 x 5 x 2.5 m room.
    fn direction_tracker(cfg: &TrackerConfig, p_detect: f64, clutter_rate: f64) -> GlmbTracker<6> {
        let sensor = SensorModel::AudioDirection {
            origin: Vec3::new(3.0, 2.5, 0.8),
            noise_std_rad: 5f64.to_radians(),
            uses_elevation: false,
            cone_axis: None,
            p_detect,
            min_p_detect: 0.02,
            clutter_rate,
            filter: FilterKind::Ekf,
        };
        let region = Aabb::new(Vec3::zeros(), Vec3::new(6.0, 5.0, 2.5)).unwrap();
        let motion = MotionModel::<6>::from_config(&cfg.motion).unwrap();
        GlmbTracker::new(cfg, motion, vec![sensor], Some(region), vec![], 1).unwrap()
    }

    /// Step `k` (128 ms apart) in which the array hears one voice at `azimuth` (rad).
    fn heard(k: u64, azimuth: f64) -> StepInput {
        StepInput {
            k,
            t: k as f64 * 0.128,
            scans: vec![Scan {
                sensor: 0,
                measurements: vec![Measurement::Direction {
                    azimuth,
                    elevation: None,
                }],
                activity: Some(0.9),
                sounding: Vec::new(),
            }],
        }
    }

    /// The existence of a direction-only track after 40 steps of evidence at one bearing and
    /// `silent` steps in which the array hears a voice elsewhere, with the cap at three
    /// hypotheses.
    fn existence_after_silence(keep_deaths: bool, silent: u64) -> f64 {
        let mut cfg = TrackerConfig::default();
        cfg.glmb.max_hypotheses = 3;
        cfg.glmb.keep_deaths = keep_deaths;
        let mut tracker = direction_tracker(&cfg, 0.9, 0.5);
        for k in 0..40 + silent {
            tracker.step(&heard(k, if k < 40 { 0.7 } else { -2.0 }));
        }
        // The labels born while the bearing was held (one track, whatever its birth step).
        tracker
            .existence()
            .iter()
            .filter(|(l, _)| l.birth_step < 40)
            .map(|(_, r)| *r)
            .sum()
    }

    /// Under a tight cap the hypotheses kept all hold the track alive and missed: its death
    /// never carries forward. Keeping the best hypothesis without each label lets it die.
    #[test]
    fn a_track_without_evidence_dies_only_if_its_death_survives_the_cap() {
        let before = existence_after_silence(true, 0);
        assert!(before > 0.99, "confirmed: {before}");
        // A voice that may pause explains the misses, so the existence falls slowly; with the
        // deaths cut it does not fall at all.
        let kept = existence_after_silence(true, 40);
        let cut = existence_after_silence(false, 40);
        assert!(kept < 0.9, "with its death kept: {kept}");
        assert!(cut > 0.999, "with its death cut: {cut}");
    }

    /// A tentative track (existence far below a confirmed one's) already explains the
    /// measurements at its bearing: they seed no second birth beside it, which could only share
    /// its existence and later take over its identity.
    #[test]
    fn a_tentative_track_suppresses_births_from_its_own_measurements() {
        let cfg = TrackerConfig::default();
        let mut tracker = direction_tracker(&cfg, 0.6, 2.0);
        let step = |tracker: &mut GlmbTracker<6>, k: u64, az: f64| tracker.step(&heard(k, az));
        step(&mut tracker, 0, 0.7);
        assert_eq!(
            tracker.pending.len(),
            1,
            "the first measurement seeds a birth"
        );
        step(&mut tracker, 1, 0.71);
        let existence = tracker.existence();
        assert_eq!(existence.len(), 1);
        let r = existence[0].1;
        assert!(
            r > cfg.birth.suppress_existence && r < 0.1,
            "tentative: {r}"
        );
        assert!(tracker.pending.is_empty(), "{:?}", tracker.pending);
        // A measurement far from the track still seeds one.
        step(&mut tracker, 2, -1.5);
        assert_eq!(tracker.pending.len(), 1);
    }

    /// The clutter estimate survives a recalibration (the same sensors, moved; a refused one
    /// changes nothing) and a reset returns it to the configured rate.
    #[test]
    fn the_clutter_estimate_survives_recalibration_and_not_reset() {
        let cfg = TrackerConfig::default();
        let mut tracker = direction_tracker(&cfg, 0.9, 0.5);
        // 12 directions a step spread over the circle, never twice at the same bearing.
        for k in 0..60u64 {
            let measurements = (0..12)
                .map(|j| Measurement::Direction {
                    azimuth: ((k * 12 + j) as f64 * 2.39996).rem_euclid(std::f64::consts::TAU)
                        - std::f64::consts::PI,
                    elevation: None,
                })
                .collect();
            tracker.step(&StepInput {
                k,
                t: k as f64 * 0.128,
                scans: vec![Scan {
                    sensor: 0,
                    measurements,
                    activity: Some(0.9),
                    sounding: Vec::new(),
                }],
            });
        }
        let learnt = tracker.clutter_rates()[0];
        assert_eq!(learnt.configured, 0.5);
        assert!(learnt.estimated > 9.0, "{learnt:?}");
        let sensors = vec![SensorModel::AudioDirection {
            origin: Vec3::new(3.1, 2.5, 0.8),
            noise_std_rad: 5f64.to_radians(),
            uses_elevation: false,
            cone_axis: None,
            p_detect: 0.9,
            min_p_detect: 0.02,
            clutter_rate: 1.0,
            filter: FilterKind::Ekf,
        }];
        let mut bad = sensors.clone();
        if let SensorModel::AudioDirection { p_detect, .. } = &mut bad[0] {
            *p_detect = 1.5;
        }
        assert!(tracker.set_sensors(bad).is_err());
        assert_eq!(
            tracker.clutter_rates(),
            vec![learnt],
            "a refused change keeps the sensors"
        );
        tracker.set_sensors(sensors).unwrap();
        let moved = tracker.clutter_rates()[0];
        assert_eq!(moved.configured, 1.0);
        assert_eq!(
            (moved.estimated, moved.scans),
            (learnt.estimated, learnt.scans)
        );
        // The filters use the carried estimate over the new floor (azimuth: uniform on 2 pi).
        let expected = moved.estimated.max(1.0).ln() - std::f64::consts::TAU.ln();
        assert!((tracker.sensors[0].clutter.log_intensity() - expected).abs() < 1e-12);
        tracker.reset();
        let reset = tracker.clutter_rates()[0];
        assert_eq!((reset.estimated, reset.scans), (1.0, 0));
    }
}
