//! Time-frequency post-filter: a gain per label and bin from all labels' beamformer outputs.
//!
//! Each label's beamformer is distortionless toward its own source at the reference microphone, so
//! the outputs share one scale and their powers can be compared directly:
//! * `mask` (thesis section 3.5.2 / algorithm A8): 1 where the label's smoothed power beats every
//!   other label's by the threshold, else the floor;
//! * `wiener`: G_i = xi_i^a / (sum_j xi_j^a + N_i^a) with xi the smoothed power above the label's
//!   stationary noise floor N (minimum tracking with a slow rise), floored against musical noise.

use super::config::{PostFilterConfig, PostFilterKind};
use super::demix::{DEMIX_RIDGE, Demixing, MAX_DEMIXED};
use crate::dsp::Complex;

/// Smoothing factor per frame of the power that the noise floor tracks.
const NOISE_SMOOTHING: f64 = 0.9;
/// The minimum of a smoothed periodogram sits below its mean; this factor undoes that bias.
const NOISE_BIAS: f64 = 1.5;

/// Per-bin state of one label's post-filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PostState {
    /// Smoothed output power.
    pub power: f64,
    /// Slowly smoothed output power, tracked by the noise floor.
    pub slow: f64,
    /// Tracked noise floor (infinite until the first frame).
    pub noise: f64,
}

impl Default for PostState {
    fn default() -> Self {
        Self {
            power: 0.0,
            slow: 0.0,
            noise: f64::INFINITY,
        }
    }
}

/// The post-filter's constants.
#[derive(Debug, Clone)]
pub struct PostFilter {
    kind: PostFilterKind,
    floor: f64,
    alpha: f64,
    exponent: f64,
    threshold: f64,
    use_noise: bool,
    untracked: f64,
    margin: f64,
    rise: f64,
    presence_floor: f64,
}

impl PostFilter {
    /// Constants from the configuration at a frame rate of `frames_per_s`.
    pub fn new(cfg: &PostFilterConfig, frames_per_s: f64) -> Self {
        Self {
            kind: cfg.kind,
            floor: cfg.gain_floor,
            alpha: cfg.power_smoothing,
            exponent: cfg.exponent,
            threshold: cfg.mask_threshold,
            use_noise: cfg.noise_floor,
            untracked: cfg.untracked_weight,
            margin: cfg.untracked_margin,
            rise: 10f64.powf(cfg.noise_rise_db_per_s / 10.0 / frames_per_s),
            presence_floor: cfg.presence_floor,
        }
    }

    /// A label's prior weight in the competition for the bins: its envelope gain (a label fading
    /// in or out has a partial claim) times `presence_floor + (1 - presence_floor) presence`,
    /// where presence is the target's speaking probability times the voice activity. A label
    /// believed silent thus takes a bin only where its beamformer output clearly
    /// dominates, so a silent or spurious label near a talker does not split that talker's energy.
    pub fn prior(&self, envelope_gain: f64, presence: f64) -> f64 {
        let p = if presence.is_finite() {
            presence.clamp(0.0, 1.0)
        } else {
            1.0
        };
        envelope_gain.clamp(0.0, 1.0) * (self.presence_floor + (1.0 - self.presence_floor) * p)
    }

    /// The smallest gain.
    pub fn floor(&self) -> f64 {
        self.floor
    }

    /// Whether any gain is applied at all.
    pub fn enabled(&self) -> bool {
        self.kind != PostFilterKind::None
    }

    /// Updates every label's state at one bin from its beamformer output and writes its gain.
    /// `priors` weighs each label's claim on the bin (its prior probability of talking, see
    /// [`PostFilter::prior`]); `reference` is the reference microphone's value and its smoothed
    /// power (state). With `demix_by` the Wiener gains compare the labels' powers with the
    /// beamformers' cross-responses undone ([`super::demix`]).
    pub fn gains(
        &self,
        outputs: &[Complex],
        priors: &[f64],
        state: &mut [PostState],
        reference: (Complex, &mut f64),
        demix_by: Option<Demixing<'_>>,
        gains: &mut [f64],
    ) {
        let n = outputs.len();
        let mut explained = 0.0;
        for (s, o) in state.iter_mut().zip(outputs) {
            let p = o.norm_sqr();
            s.power = self.alpha * s.power + (1.0 - self.alpha) * p;
            s.slow = NOISE_SMOOTHING * s.slow + (1.0 - NOISE_SMOOTHING) * p;
            s.noise = s.slow.min(s.noise * self.rise);
            explained += s.power;
        }
        let (yref, pref) = reference;
        *pref = self.alpha * *pref + (1.0 - self.alpha) * yref.norm_sqr();
        // Power at the reference microphone that no label accounts for.
        let residual = self.untracked * (*pref - self.margin * explained).max(0.0);
        match self.kind {
            PostFilterKind::None => gains[..n].fill(1.0),
            PostFilterKind::Mask => {
                for i in 0..n {
                    let pi = priors[i] * state[i].power;
                    let wins = (0..n)
                        .all(|j| j == i || pi >= self.threshold * priors[j] * state[j].power)
                        && pi >= self.threshold * residual;
                    gains[i] = if wins { 1.0 } else { self.floor };
                }
            }
            PostFilterKind::Wiener => {
                let mut powers = [0.0; MAX_DEMIXED];
                let mut demix_by = demix_by;
                let demixed = demix_by.as_mut().and_then(|d| {
                    // More labels than the demixing takes leave the raw powers.
                    let p = powers.get_mut(..n)?;
                    for (p, s) in p.iter_mut().zip(state.iter()) {
                        *p = s.power;
                    }
                    d.powers(p, DEMIX_RIDGE)
                });
                let a = self.exponent;
                let pow = |x: f64| {
                    if a == 1.0 {
                        x
                    } else if a == 2.0 {
                        x * x
                    } else {
                        x.powf(a)
                    }
                };
                let mut total = pow(residual);
                for (i, ((g, s), w)) in gains.iter_mut().zip(state.iter()).zip(priors).enumerate() {
                    let p = demixed.map_or(s.power, |d| d[i]);
                    let xi = if self.use_noise {
                        (p - NOISE_BIAS * s.noise).max(0.0)
                    } else {
                        p
                    };
                    *g = w * pow(xi);
                    total += *g;
                }
                for (g, s) in gains.iter_mut().zip(state.iter()) {
                    let noise = if self.use_noise {
                        pow(NOISE_BIAS * s.noise)
                    } else {
                        0.0
                    };
                    let den = total + noise;
                    let v = if den > 1e-300 { *g / den } else { 0.0 };
                    *g = if v.is_finite() {
                        v.max(self.floor)
                    } else {
                        1.0
                    };
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn pf(kind: PostFilterKind, smoothing: f64) -> PostFilter {
        PostFilter::new(
            &PostFilterConfig {
                kind,
                power_smoothing: smoothing,
                gain_floor: 0.1,
                exponent: 1.0,
                noise_floor: true,
                ..PostFilterConfig::default()
            },
            31.25,
        )
    }

    #[test]
    fn mask_keeps_the_loudest_label() {
        let f = pf(PostFilterKind::Mask, 0.0);
        let mut st = vec![PostState::default(); 3];
        let mut g = vec![0.0; 3];
        let out = [
            Complex::new(1.0, 0.0),
            Complex::new(0.0, 2.0),
            Complex::new(0.5, 0.0),
        ];
        f.gains(
            &out,
            &[1.0; 3],
            &mut st,
            (Complex::new(0.0, 0.0), &mut 0.0),
            None,
            &mut g,
        );
        assert_eq!(g, vec![0.1, 1.0, 0.1]);
        let mut one = vec![PostState::default()];
        f.gains(
            &out[..1],
            &[1.0],
            &mut one,
            (Complex::new(0.0, 0.0), &mut 0.0),
            None,
            &mut g[..1],
        );
        assert_eq!(g[0], 1.0);
    }

    #[test]
    fn wiener_gains_follow_power_shares_and_floor() {
        let mut f = pf(PostFilterKind::Wiener, 0.0);
        f.use_noise = false;
        let mut st = vec![PostState::default(); 2];
        let mut g = vec![0.0; 2];
        f.gains(
            &[Complex::new(3.0, 0.0), Complex::new(1.0, 0.0)],
            &[1.0; 2],
            &mut st,
            (Complex::new(0.0, 0.0), &mut 0.0),
            None,
            &mut g,
        );
        assert!((g[0] - 0.9).abs() < 1e-12 && (g[1] - 0.1).abs() < 1e-12);
        f.gains(
            &[Complex::new(10.0, 0.0), Complex::new(0.1, 0.0)],
            &[1.0; 2],
            &mut st,
            (Complex::new(0.0, 0.0), &mut 0.0),
            None,
            &mut g,
        );
        assert_eq!(g[1], 0.1);
        // Silence gives the floor, not NaN.
        f.gains(
            &[Complex::new(0.0, 0.0); 2],
            &[1.0; 2],
            &mut st,
            (Complex::new(0.0, 0.0), &mut 0.0),
            None,
            &mut g,
        );
        assert!(g.iter().all(|x| x.is_finite()));
    }

    #[test]
    fn priors_weigh_each_labels_claim() {
        let mut f = pf(PostFilterKind::Wiener, 0.0);
        f.use_noise = false;
        f.presence_floor = 0.25;
        // A label fading in at half gain and silent has a quarter of the claim of a full one
        // that talks; a label not yet audible (gain 0) has none.
        assert!((f.prior(0.5, 0.0) - 0.125).abs() < 1e-12);
        assert_eq!(f.prior(1.0, 1.0), 1.0);
        assert_eq!(f.prior(0.0, 1.0), 0.0);
        assert_eq!(f.prior(1.0, f64::NAN), 1.0);
        let out = [Complex::new(1.0, 0.0), Complex::new(1.0, 0.0)];
        let mut st = vec![PostState::default(); 2];
        let mut g = vec![0.0; 2];
        let r = (Complex::new(0.0, 0.0), &mut 0.0);
        f.gains(
            &out,
            &[f.prior(1.0, 1.0), f.prior(1.0, 0.0)],
            &mut st,
            r,
            None,
            &mut g,
        );
        // Equal outputs split by the priors: 1 : 0.25.
        assert!(
            (g[0] - 0.8).abs() < 1e-12 && (g[1] - 0.2).abs() < 1e-12,
            "{g:?}"
        );
        let r = (Complex::new(0.0, 0.0), &mut 0.0);
        f.gains(&out, &[1.0, 0.0], &mut st, r, None, &mut g);
        assert_eq!(g, vec![1.0, 0.1]);
    }

    #[test]
    fn noise_floor_suppresses_stationary_noise_and_passes_bursts() {
        let f = pf(PostFilterKind::Wiener, 0.3);
        let mut st = vec![PostState::default()];
        let mut g = vec![0.0];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let mut noise_gain = 0.0;
        for n in 0..300 {
            let ph = rng.random_range(0.0..std::f64::consts::TAU);
            let burst = if n % 50 == 49 { 30.0 } else { 1.0 };
            f.gains(
                &[Complex::from_polar(burst, ph)],
                &[1.0],
                &mut st,
                (Complex::new(0.0, 0.0), &mut 0.0),
                None,
                &mut g,
            );
            if n > 100 && n % 50 == 49 {
                assert!(g[0] > 0.9, "burst gain {}", g[0]);
            } else if n > 100 && n % 50 < 40 {
                noise_gain += g[0];
            }
        }
        assert!(noise_gain / 154.0 < 0.4, "{}", noise_gain / 154.0);
    }

    #[test]
    fn demixing_gives_an_outer_talkers_low_band_back_to_its_label() {
        use crate::separate::demix::CROSS_100_HZ;
        use crate::separate::nnls::Nnls;
        // Only the outer talker (label 2) is heard: the middle label's beamformer outputs more
        // of it than its own does.
        let phi = [0.0, 0.0, 1.0];
        let mut st = [PostState::default(); 3];
        for (i, s) in st.iter_mut().enumerate() {
            s.power = (0..3).map(|j| CROSS_100_HZ[i * 3 + j] * phi[j]).sum();
        }
        // The talker's label takes the bin with the demixing, the middle label without it.
        let f = PostFilter::new(
            &PostFilterConfig {
                kind: PostFilterKind::Wiener,
                power_smoothing: 0.0,
                gain_floor: 0.1,
                exponent: 1.0,
                noise_floor: false,
                ..PostFilterConfig::default()
            },
            31.25,
        );
        let outputs: Vec<Complex> = st
            .iter()
            .map(|s| Complex::new(s.power.sqrt(), 0.0))
            .collect();
        let gains_with = |cross: Option<&[f64]>| {
            let mut st = vec![PostState::default(); 3];
            let mut g = vec![0.0; 3];
            let (mut solver, mut support) = (Nnls::default(), 0);
            let demix_by = cross.map(|cross| Demixing {
                cross,
                solver: &mut solver,
                support: &mut support,
            });
            f.gains(
                &outputs,
                &[1.0; 3],
                &mut st,
                (Complex::new(0.0, 0.0), &mut 0.0),
                demix_by,
                &mut g,
            );
            g
        };
        let raw = gains_with(None);
        let demixed = gains_with(Some(&CROSS_100_HZ));
        assert!(raw[1] > raw[2], "{raw:?}");
        assert!(demixed[2] > 0.9 && demixed[1] < 0.2, "{demixed:?}");
        // Too short a matrix is refused and the gains use the raw powers.
        assert_eq!(gains_with(Some(&CROSS_100_HZ[..4])), raw);
    }
}
