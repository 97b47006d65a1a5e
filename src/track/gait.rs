//! A track's gait: standing or walking, two motion modes that a two-state Markov chain switches.
//!
//! One Langevin velocity decay cannot serve both. A fast decay (`beta_per_s`) keeps a
//! standing talker's track still against noisy measurements, but lets a walker's track lag
//! him and forget his velocity as soon as a camera loses him; a slow one
//! (`walking_beta_per_s`) carries a walker through such gaps and overshoots a talker who
//! stops. Each track entry carries an interacting multiple model (Blom & Bar-Shalom): the
//! probability that it walks and its density conditioned on each mode. A step mixes the two
//! mode densities by the chain's switching, predicts each with its own decay, and hands the
//! GLMB their moment-matched merge to score associations with; the update then updates each
//! mode's density by the associated measurements and weighs the modes by their likelihoods,
//! so a track whose measurements keep running ahead of the standing prediction comes to
//! walk (0.78 after 5 s measured at 0.6 m/s, in this module's tests), and one that stops
//! reads as walking less within a few seconds (0.42), as a still one does (0.41). The
//! standing mode is the single-mode default, whose velocity is mostly redrawn every half
//! second, so a still track's steady nil velocity suits either mode about as well: it is the
//! walker's persistent velocity that only the walking mode predicts.

use nalgebra::Vector3;

use super::config::UkfConfig;
use super::filter::{Transition, update as kalman_update};
use super::gaussian::{Gaussian, mixture_moments};
use super::modes::ModeModel;
use super::motion::clamp_position;
use super::sensor::Sensor;
use crate::geometry::Aabb;

/// One step's gait model: the walking mode's transition for the step's dt and the chain. The
/// standing mode's transition is the step's single-mode one, which the caller holds anyway.
#[derive(Debug, Clone)]
pub(crate) struct Gait<const N: usize> {
    walking: Transition<N>,
    /// "On" is walking.
    chain: ModeModel,
    dt: f64,
    /// How long after its last camera detection a track keeps its gait (s).
    camera_memory_s: f64,
}

/// A track's prediction under its gait.
#[derive(Debug, Clone)]
pub(crate) struct GaitPrediction<const N: usize> {
    /// The two modes' predictions merged: what the GLMB scores associations with.
    pub merged: Gaussian<N>,
    /// Each mode's own prediction (standing, walking).
    pub modes: [Gaussian<N>; 2],
    /// Probability of walking after the step, before its measurements.
    pub walking: f64,
}

impl<const N: usize> Gait<N> {
    /// The gait of a step of `dt` seconds with the walking mode's transition, for tracks a
    /// camera saw within the last `camera_memory_s`.
    pub fn new(walking: Transition<N>, chain: ModeModel, dt: f64, camera_memory_s: f64) -> Self {
        Self {
            walking,
            chain,
            dt,
            camera_memory_s,
        }
    }

    /// Whether a track last seen by a camera (or any sensor that is not audio) `unseen_s`
    /// seconds before the step (infinite when never) has a gait; one that has none stands.
    pub fn applies(&self, unseen_s: f64) -> bool {
        unseen_s < self.camera_memory_s
    }

    /// The probability that a new track walks.
    pub fn initial(&self) -> f64 {
        self.chain.initial()
    }

    /// Predicts a track that walks with probability `walking`, with density `modes[0]` if it
    /// stands (moved by `standing`) and `modes[1]` if it walks. None when a prediction is not
    /// finite.
    pub fn predict(
        &self,
        standing: &Transition<N>,
        modes: [&Gaussian<N>; 2],
        walking: f64,
    ) -> Option<GaitPrediction<N>> {
        let (stop, start) = self.chain.switches(self.dt);
        let w = self.chain.predict(walking, self.dt);
        // Mixing: each mode's density after the switch is the mixture of the modes it can
        // come from, weighed by how likely it came from each.
        let stand_from_walk = if w < 1.0 {
            walking * stop / (1.0 - w)
        } else {
            0.0
        };
        let walk_from_stand = if w > 0.0 {
            (1.0 - walking) * start / w
        } else {
            0.0
        };
        let stand0 = merge(1.0 - stand_from_walk, modes[0], stand_from_walk, modes[1])?;
        let walk0 = merge(walk_from_stand, modes[0], 1.0 - walk_from_stand, modes[1])?;
        let standing = standing.predict(&stand0)?;
        let moving = self.walking.predict(&walk0)?;
        let merged = merge(1.0 - w, &standing, w, &moving)?;
        Some(GaitPrediction {
            merged,
            modes: [standing, moving],
            walking: w,
        })
    }
}

/// A track's gait after an update.
#[derive(Debug, Clone)]
pub(crate) struct GaitUpdate<const N: usize> {
    /// Probability of walking.
    pub walking: f64,
    /// The density conditioned on standing and on walking.
    pub modes: [Gaussian<N>; 2],
    /// Their moment-matched merge, the interacting multiple model's estimate (None when not
    /// finite).
    pub merged: Option<Gaussian<N>>,
}

/// Updates each mode's prediction (`modes`: standing, walking) by the `measured` sensors'
/// measurements in turn and weighs the modes by their likelihoods (`walking` the probability
/// of walking before the update); every mean is clamped into `clamp`. None when an update
/// fails.
pub(crate) fn update<'a, const N: usize>(
    modes: &[Gaussian<N>; 2],
    walking: f64,
    measured: impl Iterator<Item = (&'a Sensor<N>, &'a Vector3<f64>)> + Clone,
    ukf: &UkfConfig,
    clamp: Option<&Aabb>,
) -> Option<GaitUpdate<N>> {
    let mut ll = [0.0; 2];
    let mut out = modes.clone();
    for (mode, density) in out.iter_mut().enumerate() {
        for (sensor, z) in measured.clone() {
            let (next, l) = kalman_update(sensor, density, z, ukf)?;
            *density = next;
            ll[mode] += l;
        }
        if let Some(region) = clamp {
            clamp_position(&mut density.mean, region);
        }
    }
    let walking = walking_after(walking, ll[0], ll[1]);
    let mut merged = merge(1.0 - walking, &out[0], walking, &out[1]);
    if let (Some(g), Some(region)) = (&mut merged, clamp) {
        clamp_position(&mut g.mean, region);
    }
    Some(GaitUpdate {
        walking,
        modes: out,
        merged,
    })
}

/// The probability of walking after an update whose measurements have log likelihoods
/// `log_standing` and `log_walking` under the two modes' predictions; `walking` before it.
pub(crate) fn walking_after(walking: f64, log_standing: f64, log_walking: f64) -> f64 {
    if !(log_standing.is_finite() && log_walking.is_finite()) {
        return walking;
    }
    // w L_w / (w L_w + (1 - w) L_s), in logs so that far measurements do not underflow.
    let d = ((1.0 - walking).ln() + log_standing) - (walking.ln() + log_walking);
    let p = 1.0 / (1.0 + d.exp());
    if p.is_finite() {
        p.clamp(0.0, 1.0)
    } else {
        walking
    }
}

/// The moment-matched Gaussian of the mixture wa N(a) + wb N(b) (weights summing to 1).
pub(crate) fn merge<const N: usize>(
    wa: f64,
    a: &Gaussian<N>,
    wb: f64,
    b: &Gaussian<N>,
) -> Option<Gaussian<N>> {
    let Gaussian { mean, cov } = mixture_moments([(wa, a), (wb, b)].into_iter());
    let cov = (cov + cov.transpose()) * 0.5;
    (mean.iter().all(|v| v.is_finite()) && cov.iter().all(|v| v.is_finite()))
        .then_some(Gaussian { mean, cov })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use crate::track::config::TrackerConfig;
    use crate::track::motion::{MotionModel, position_of, state_of};
    use crate::track::sensor::SensorModel;
    use nalgebra::{DMatrix, SMatrix};

    fn langevin(beta_per_s: f64) -> MotionModel<6> {
        MotionModel::Langevin {
            beta_per_s,
            nu_m_per_s: 1.0,
            sigma_m_per_s: [0.27, 0.27, 0.05],
        }
    }

    /// The tests' gait with its standing transition, as the joint update holds them.
    struct Stepped {
        gait: Gait<6>,
        standing: Transition<6>,
    }

    impl Stepped {
        fn predict(&self, modes: [&Gaussian<6>; 2], w: f64) -> Option<GaitPrediction<6>> {
            self.gait.predict(&self.standing, modes, w)
        }

        fn applies(&self, unseen_s: f64) -> bool {
            self.gait.applies(unseen_s)
        }
    }

    fn gait(dt: f64) -> Stepped {
        let t = |m: MotionModel<6>| {
            let (f, q) = m.transition(dt);
            Transition::new(f, q)
        };
        let chain = ModeModel::new(3.0, 10.0, 0.2);
        Stepped {
            gait: Gait::new(t(langevin(0.5)), chain, dt, 5.0),
            standing: t(langevin(2.0)),
        }
    }

    fn walker() -> Gaussian<6> {
        Gaussian {
            mean: state_of(&Vec3::new(1.0, 2.0, 1.6), &Vec3::new(0.6, 0.0, 0.0)),
            cov: SMatrix::<f64, 6, 6>::identity() * 0.01,
        }
    }

    #[test]
    fn the_merged_prediction_lies_between_the_modes_and_holds_their_spread() {
        let g = gait(0.128);
        let p = g.predict([&walker(), &walker()], 0.5).unwrap();
        let (vs, vw, vm) = (p.modes[0].mean[3], p.modes[1].mean[3], p.merged.mean[3]);
        // Standing forgets the velocity faster than walking.
        assert!(vs < vw, "{vs} {vw}");
        let w = p.walking;
        assert!((vm - ((1.0 - w) * vs + w * vw)).abs() < 1e-12);
        // The merged variance exceeds each mode's weighted variance by their means' spread.
        let spread = w * (1.0 - w) * (vw - vs) * (vw - vs);
        let weighted = (1.0 - w) * p.modes[0].cov[(3, 3)] + w * p.modes[1].cov[(3, 3)];
        assert!((p.merged.cov[(3, 3)] - weighted - spread).abs() < 1e-12);
        // A track certain to stand predicts as the standing mode would, up to the chain's
        // switch within the step.
        let still = g.predict([&walker(), &walker()], 0.0).unwrap();
        assert!(still.walking < 0.02);
        assert!((still.merged.mean[3] - vs).abs() < 0.02 * (vw - vs) + 1e-12);
    }

    #[test]
    fn each_mode_starts_from_the_modes_it_may_have_come_from() {
        let dt = 0.128;
        let g = gait(dt);
        let mut standing = walker();
        standing.mean[3] = 0.0;
        let moving = walker();
        let p = g.predict([&standing, &moving], 0.4).unwrap();
        // Mixing by hand: the share of each mode's start that comes from the other mode.
        let (stop, start) = ModeModel::new(3.0, 10.0, 0.2).switches(dt);
        let w = 0.4 * (1.0 - stop) + 0.6 * start;
        assert!((p.walking - w).abs() < 1e-12);
        let stand_from_walk = 0.4 * stop / (1.0 - w);
        let walk_from_stand = 0.6 * start / w;
        let v_stand = (-2.0 * dt).exp() * stand_from_walk * 0.6;
        let v_walk = (-0.5 * dt).exp() * (1.0 - walk_from_stand) * 0.6;
        assert!(
            (p.modes[0].mean[3] - v_stand).abs() < 1e-12,
            "{}",
            p.modes[0].mean[3]
        );
        assert!(
            (p.modes[1].mean[3] - v_walk).abs() < 1e-12,
            "{}",
            p.modes[1].mean[3]
        );
        // A walker mostly keeps his velocity, a stander mostly has none.
        assert!(v_walk > 0.5 && v_stand < 0.05);
    }

    /// A sensor that measures the position with 0.1 m noise.
    fn position_sensor() -> Sensor<6> {
        let mut h = DMatrix::zeros(3, 6);
        for i in 0..3 {
            h[(i, i)] = 1.0;
        }
        let model = SensorModel::GenericPoint {
            h,
            r: DMatrix::from_diagonal_element(3, 3, 0.01),
            p_detect: 0.9,
            clutter_rate: 1.0,
            clutter_density: 0.01,
        };
        Sensor::compile(&model, 0, &TrackerConfig::default()).unwrap()
    }

    /// The probability of walking after `steps` of the gait's predict-update loop on a track
    /// measured at `at(t)` each step, starting from `walking` with modes `start`.
    fn run(
        at: impl Fn(f64) -> Vec3,
        steps: usize,
        walking: f64,
        start: &Gaussian<6>,
    ) -> (f64, [Gaussian<6>; 2]) {
        let dt = 0.128;
        let g = gait(dt);
        let sensor = position_sensor();
        let ukf = UkfConfig::default();
        let mut state = (walking, [start.clone(), start.clone()]);
        for k in 1..=steps {
            let p = g.predict([&state.1[0], &state.1[1]], state.0).unwrap();
            let z = at(k as f64 * dt);
            let u = update(
                &p.modes,
                p.walking,
                std::iter::once((&sensor, &z)),
                &ukf,
                None,
            );
            let u = u.unwrap();
            state = (u.walking, u.modes);
        }
        state
    }

    #[test]
    fn a_track_measured_walking_reads_as_walking_and_one_measured_still_less() {
        let mut still = walker();
        still.mean[3] = 0.0;
        let origin = Vec3::new(1.0, 2.0, 1.6);
        let (standing, stand_modes) = run(|_| origin, 40, 0.5, &still);
        let walk = |t: f64| origin + Vec3::new(0.6 * t, 0.0, 0.0);
        let (walking, modes) = run(walk, 40, 0.5, &still);
        // The standing mode's velocity is the default model's, which at 2/s re-draws most of
        // it every half second: a still track's walking mode, which keeps its (nil) velocity,
        // predicts it about as well, so "standing" reads as the lower probability, not a low
        // one. A walker's persistent velocity is what the walking mode alone predicts.
        assert!(walking > 0.7, "{walking}");
        assert!(standing < walking - 0.25, "{standing} {walking}");
        assert!(modes[1].mean[3] > 0.4, "{}", modes[1].mean[3]);
        assert!(modes[0].mean[3] < modes[1].mean[3]);
        assert!(stand_modes[1].mean[3].abs() < 0.01);
        // A walker who stops reads as walking less within a few seconds.
        let stops = |t: f64| walk(t.min(40.0 * 0.128));
        let (stopped, _) = run(stops, 70, 0.5, &still);
        println!("standing {standing:.3} walking {walking:.3} stopped {stopped:.3}");
        assert!(stopped < walking - 0.2, "{stopped} {walking}");
    }

    #[test]
    fn the_modes_move_towards_their_measurements_and_stay_in_the_region() {
        let g = gait(0.128);
        let p = g.predict([&walker(), &walker()], 0.5).unwrap();
        let sensor = position_sensor();
        let ukf = UkfConfig::default();
        let z = position_of(&p.merged.mean) + Vec3::new(0.4, 0.0, 0.0);
        let once = || std::iter::once((&sensor, &z));
        let u = update(&p.modes, p.walking, once(), &ukf, None).unwrap();
        for (post, prior) in u.modes.iter().zip(&p.modes) {
            assert!(post.mean[0] > prior.mean[0] + 0.1);
        }
        // The estimate is the modes' merge.
        let (w, merged) = (u.walking, u.merged.unwrap());
        let expected = (1.0 - w) * u.modes[0].mean[0] + w * u.modes[1].mean[0];
        assert!((merged.mean[0] - expected).abs() < 1e-12);
        let region = Aabb::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.05, 3.0, 2.0)).unwrap();
        let clamped = update(&p.modes, p.walking, once(), &ukf, Some(&region)).unwrap();
        assert!(clamped.modes.iter().all(|g| g.mean[0] <= 1.05));
        assert!(clamped.merged.unwrap().mean[0] <= 1.05);
    }

    #[test]
    fn only_a_track_a_camera_saw_lately_has_a_gait() {
        let g = gait(0.128);
        assert!(g.applies(0.0));
        assert!(g.applies(4.9));
        assert!(!g.applies(5.0));
        // Never seen: an audio-only track, whose range no measurement fixes, stands.
        assert!(!g.applies(f64::INFINITY));
    }

    #[test]
    fn measurements_that_run_ahead_make_a_track_walk_and_a_stop_makes_it_stand() {
        // Measurement log likelihoods as a walking track's mode predictions would give them.
        assert!(walking_after(0.2, -5.0, -1.0) > 0.9);
        assert!(walking_after(0.8, -1.0, -5.0) < 0.1);
        // Equal likelihoods leave the prior; non-finite ones are ignored.
        assert!((walking_after(0.3, -2.0, -2.0) - 0.3).abs() < 1e-12);
        assert_eq!(walking_after(0.3, f64::NEG_INFINITY, -2.0), 0.3);
        assert_eq!(walking_after(0.3, -2.0, f64::NAN), 0.3);
        // Far measurements do not underflow to NaN.
        let p = walking_after(0.5, -1e4, -1.0);
        assert!(p.is_finite() && p > 0.99);
        // A certain mode stays certain.
        assert_eq!(walking_after(0.0, -1e4, -1.0), 0.0);
        assert_eq!(walking_after(1.0, -1.0, -1e4), 1.0);
    }
}
