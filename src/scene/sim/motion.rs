//! Where each talker's mouth is and where the face points, as smooth functions of time.
//!
//! A path is a list of keyframes interpolated by a cubic Hermite spline (Catmull-Rom tangents,
//! at rest at the ends and wherever the talker stands still), plus a slow sway made of a few
//! random low-frequency sinusoids. The facing direction follows the walking direction while the
//! talker walks, otherwise a look-at point, with slow random head turns and turned-away intervals;
//! it is low-pass filtered so that turns take a few hundred milliseconds.

use std::f64::consts::PI;

use rand::Rng;

use crate::geometry::{Aabb, Vec3, angle_diff, wrap_angle};

/// Step (s) of the facing-direction grid.
const FACING_STEP_S: f64 = 0.02;
/// Walking faster than this (m/s) turns the face to the walking direction.
const WALKING_SPEED: f64 = 0.2;
/// Time constant (s) of the low-pass that smooths head turns.
const TURN_TAU_S: f64 = 0.15;

/// A smooth 2-D path through keyframes `(t, [x, y])`.
#[derive(Debug, Clone, PartialEq)]
pub struct Path {
    keys: Vec<(f64, [f64; 2])>,
    tangents: Vec<[f64; 2]>,
}

impl Path {
    /// A path through `keys` (times strictly increasing, at least one key).
    pub fn new(keys: Vec<(f64, [f64; 2])>) -> Self {
        let n = keys.len();
        let mut tangents = vec![[0.0; 2]; n];
        for i in 1..n.saturating_sub(1) {
            let (t0, p0) = keys[i - 1];
            let (_, p1) = keys[i];
            let (t2, p2) = keys[i + 1];
            let still = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]) < 1e-9;
            if still(p0, p1) || still(p1, p2) {
                continue;
            }
            for a in 0..2 {
                tangents[i][a] = (p2[a] - p0[a]) / (t2 - t0);
            }
        }
        Self { keys, tangents }
    }

    /// From configuration keyframes `[t, x, y]`.
    pub fn from_keyframes(keys: &[[f64; 3]]) -> Self {
        Self::new(keys.iter().map(|k| (k[0], [k[1], k[2]])).collect())
    }

    /// Position at `t` (held constant outside the keyframes).
    pub fn at(&self, t: f64) -> [f64; 2] {
        let Some(first) = self.keys.first() else {
            return [0.0, 0.0];
        };
        if t <= first.0 || self.keys.len() == 1 {
            return first.1;
        }
        let i = self.keys.partition_point(|k| k.0 <= t);
        if i >= self.keys.len() {
            return self.keys[self.keys.len() - 1].1;
        }
        let ((t0, p0), (t1, p1)) = (self.keys[i - 1], self.keys[i]);
        let (m0, m1) = (self.tangents[i - 1], self.tangents[i]);
        let h = t1 - t0;
        let s = (t - t0) / h;
        let (s2, s3) = (s * s, s * s * s);
        let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
        let h10 = s3 - 2.0 * s2 + s;
        let h01 = -2.0 * s3 + 3.0 * s2;
        let h11 = s3 - s2;
        let mut out = [0.0; 2];
        for a in 0..2 {
            out[a] = h00 * p0[a] + h10 * h * m0[a] + h01 * p1[a] + h11 * h * m1[a];
        }
        out
    }

    /// Largest speed (m/s) along the path, sampled every 10 ms, and when it occurs.
    pub fn max_speed(&self) -> (f64, f64) {
        let (Some(a), Some(b)) = (self.keys.first(), self.keys.last()) else {
            return (0.0, 0.0);
        };
        let dt = 0.01;
        let mut best = (0.0, a.0);
        let mut t = a.0;
        while t < b.0 {
            let (p, q) = (self.at(t), self.at(t + dt));
            let v = (q[0] - p[0]).hypot(q[1] - p[1]) / dt;
            if v > best.0 {
                best = (v, t);
            }
            t += dt;
        }
        best
    }
}

/// A slow random wobble: per axis a sum of sinusoids at 0.05-0.3 Hz with an RMS of one unit.
#[derive(Debug, Clone, PartialEq)]
pub struct Wobble {
    /// Per axis: (amplitude, angular frequency, phase).
    terms: Vec<Vec<(f64, f64, f64)>>,
}

impl Wobble {
    /// `axes` independent wobbles with unit RMS.
    pub fn new<R: Rng + ?Sized>(axes: usize, rng: &mut R) -> Self {
        let terms = (0..axes)
            .map(|_| {
                let raw: Vec<(f64, f64, f64)> = (0..4)
                    .map(|_| {
                        (
                            rng.random_range(0.5..1.0),
                            2.0 * PI * rng.random_range(0.05..0.3),
                            rng.random_range(0.0..2.0 * PI),
                        )
                    })
                    .collect();
                // Sum of sinusoids: power is half the sum of squared amplitudes.
                let rms = (raw.iter().map(|t| t.0 * t.0).sum::<f64>() / 2.0).sqrt();
                raw.into_iter().map(|(a, w, p)| (a / rms, w, p)).collect()
            })
            .collect();
        Self { terms }
    }

    /// Value of axis `axis` at `t`.
    pub fn at(&self, axis: usize, t: f64) -> f64 {
        self.terms.get(axis).map_or(0.0, |ts| {
            ts.iter().map(|(a, w, p)| a * (w * t + p).sin()).sum()
        })
    }
}

/// One talker's motion: presence, mouth position and facing direction.
#[derive(Debug, Clone)]
pub struct Motion {
    /// Entry time (s).
    pub enter_s: f64,
    /// Exit time (s).
    pub exit_s: f64,
    path: Path,
    height: f64,
    sway_m: f64,
    sway: Wobble,
    bounds: Aabb,
    facing: Vec<f64>,
}

/// Inputs of the facing model.
#[derive(Debug, Clone)]
pub struct FacingPlan {
    /// Point looked at when not walking.
    pub look_at: [f64; 2],
    /// Face the walking direction when walking.
    pub follow_motion: bool,
    /// Turned-away intervals (s).
    pub away: Vec<(f64, f64)>,
    /// Standard deviation of head turns (rad).
    pub jitter_rad: f64,
}

impl Motion {
    /// Builds a talker's motion. `bounds` is where the mouth may go (the room with a margin).
    #[allow(clippy::too_many_arguments)]
    pub fn new<R: Rng + ?Sized>(
        enter_s: f64,
        exit_s: f64,
        path: Path,
        height: f64,
        sway_m: f64,
        bounds: Aabb,
        facing: &FacingPlan,
        rng: &mut R,
    ) -> Self {
        let sway = Wobble::new(3, rng);
        let head = Wobble::new(1, rng);
        let mut m = Self {
            enter_s,
            exit_s,
            path,
            height,
            sway_m,
            sway,
            bounds,
            facing: Vec::new(),
        };
        m.facing = m.facing_grid(facing, &head);
        m
    }

    /// Mouth position at `t` (held at the ends outside the talker's presence).
    pub fn position(&self, t: f64) -> Vec3 {
        let t = t.clamp(self.enter_s, self.exit_s);
        let p = self.path.at(t);
        let s = self.sway_m;
        let v = Vec3::new(
            p[0] + s * self.sway.at(0, t),
            p[1] + s * self.sway.at(1, t),
            self.height + 0.3 * s * self.sway.at(2, t),
        );
        self.bounds.clamp(&v)
    }

    /// Whether the talker is in the scene at `t`.
    pub fn present(&self, t: f64) -> bool {
        t >= self.enter_s && t <= self.exit_s
    }

    /// Azimuth (rad) the face points to at `t`.
    pub fn facing(&self, t: f64) -> f64 {
        let x = ((t - self.enter_s) / FACING_STEP_S).clamp(0.0, (self.facing.len() - 1) as f64);
        let i = (x.floor() as usize).min(self.facing.len().saturating_sub(2));
        let a = x - i as f64;
        let (f0, f1) = (
            self.facing[i],
            *self.facing.get(i + 1).unwrap_or(&self.facing[i]),
        );
        wrap_angle(f0 + a * (f1 - f0))
    }

    /// Facing azimuths on a grid from entry to exit, unwrapped so that they interpolate.
    fn facing_grid(&self, plan: &FacingPlan, head: &Wobble) -> Vec<f64> {
        let steps = ((self.exit_s - self.enter_s) / FACING_STEP_S).ceil() as usize + 1;
        let k = 1.0 - (-FACING_STEP_S / TURN_TAU_S).exp();
        let mut out = Vec::with_capacity(steps);
        let mut dir: Option<f64> = None;
        let mut prev_unwrapped = 0.0;
        for j in 0..steps {
            let t = self.enter_s + j as f64 * FACING_STEP_S;
            let p = self.path.at(t);
            let q = self.path.at(t + FACING_STEP_S);
            let (vx, vy) = ((q[0] - p[0]) / FACING_STEP_S, (q[1] - p[1]) / FACING_STEP_S);
            let base = if plan.follow_motion && vx.hypot(vy) > WALKING_SPEED {
                vy.atan2(vx)
            } else {
                (plan.look_at[1] - p[1]).atan2(plan.look_at[0] - p[0])
            };
            let away: f64 = plan
                .away
                .iter()
                .map(|&(a, b)| smoothstep((t - a) / 0.5) * (1.0 - smoothstep((t - b) / 0.5)))
                .fold(0.0, f64::max);
            let target = base + plan.jitter_rad * head.at(0, t) + PI * away;
            // Low-pass on the circle: step a fraction of the shortest turn towards the target.
            let d = match dir {
                None => wrap_angle(target),
                Some(d) => d + k * angle_diff(target, d),
            };
            dir = Some(d);
            let unwrapped = if j == 0 {
                d
            } else {
                prev_unwrapped + angle_diff(d, prev_unwrapped)
            };
            prev_unwrapped = unwrapped;
            out.push(unwrapped);
        }
        out
    }
}

/// 0 below 0, 1 above 1, smooth in between.
fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn path_passes_through_keyframes_and_rests_at_the_ends() {
        let p = Path::new(vec![
            (1.0, [0.0, 0.0]),
            (3.0, [1.0, 0.0]),
            (5.0, [1.0, 1.0]),
            (6.0, [1.0, 1.0]),
        ]);
        assert_eq!(p.at(0.0), [0.0, 0.0]);
        assert_eq!(p.at(3.0), [1.0, 0.0]);
        assert_eq!(p.at(10.0), [1.0, 1.0]);
        // At rest at the first keyframe: tiny motion just after it.
        let q = p.at(1.01);
        assert!(q[0].hypot(q[1]) < 1e-3);
        // Peak speed of a rest-to-rest segment is 1.5 times its mean speed.
        let (v, _) = Path::new(vec![(0.0, [0.0, 0.0]), (2.0, [1.0, 0.0])]).max_speed();
        assert!((v - 0.75).abs() < 0.01, "{v}");
    }

    #[test]
    fn facing_follows_walking_then_look_at_and_turns_away() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let bounds = Aabb::new(Vec3::zeros(), Vec3::new(10.0, 10.0, 3.0)).unwrap();
        let path = Path::new(vec![(0.0, [1.0, 5.0]), (4.0, [4.0, 5.0])]);
        let plan = FacingPlan {
            look_at: [4.0, 9.0],
            follow_motion: true,
            away: vec![(7.0, 9.0)],
            jitter_rad: 0.0,
        };
        let m = Motion::new(0.0, 10.0, path, 1.6, 0.0, bounds, &plan, &mut rng);
        // Walking along +x at mid-path.
        assert!(
            angle_diff(m.facing(2.0), 0.0).abs() < 0.1,
            "{}",
            m.facing(2.0)
        );
        // Standing at (4, 5): looks at (4, 9), i.e. +y.
        assert!(angle_diff(m.facing(6.0), PI / 2.0).abs() < 0.05);
        // Turned away: -y.
        assert!(angle_diff(m.facing(8.5), -PI / 2.0).abs() < 0.05);
        assert_eq!(m.position(6.0), Vec3::new(4.0, 5.0, 1.6));
    }
}
