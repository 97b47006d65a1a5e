//! 3-D position search by stochastic region contraction (Do, Silverman & Yu, ICASSP 2007; spec
//! 000 section 2.4 and algorithm A2) on the near-field SRP-PHAT of one array.

use rand::Rng;

use crate::geometry::{Aabb, MicArray, Vec3};

use super::config::PositionConfig;
use super::gcc::{GccBank, lerp};

/// Draws allowed per accepted point before giving up on a crowded box.
const MAX_DRAW_TRIES: usize = 32;
/// The final simplex ascent stops when the simplex is smaller than this (metres).
const POLISH_MIN_STEP_M: f64 = 0.005;
/// Cap on SRP evaluations of the final simplex ascent, bounding its cost.
const POLISH_MAX_EVALUATIONS: usize = 300;

/// The position search of one array, with its buffers.
pub(crate) struct PositionSearch {
    bounds: Aabb,
    mics: Vec<Vec3>,
    /// Planar arrays: only points with `normal . (x - centroid) >= 0` are searched.
    half_space: Option<(Vec3, Vec3)>,
    /// Microphones of each pair and the absolute table position of its zero lag.
    pairs: Vec<(usize, usize, f64)>,
    /// Fine table steps per metre of path difference.
    steps_per_metre: f64,
    min_range: f64,
    initial: usize,
    kept: usize,
    min_volume: f64,
    max_evaluations: usize,
    exclusion: f64,
    dist: Vec<f64>,
    points: Vec<(Vec3, f64)>,
    /// SRP traded per square metre of distance from the prior in the final ascent (this search).
    pull: f64,
    centroid: Vec3,
    /// Mean distance from the array centroid to the searchable points of the box.
    mean_range: f64,
}

impl PositionSearch {
    /// A search over `region` (or a cube of half-side `default_half_size_m` around the array).
    pub fn new(
        array: &MicArray,
        bank: &GccBank,
        region: Option<Aabb>,
        cfg: &PositionConfig,
        speed_of_sound: f64,
        half_space: Option<Vec3>,
    ) -> Self {
        let centroid = array.centroid();
        let mut bounds = region.unwrap_or_else(|| {
            let h = Vec3::repeat(cfg.default_half_size_m);
            Aabb {
                min: centroid - h,
                max: centroid + h,
            }
        });
        // A planar array cannot tell a point from its mirror image: search the side facing the
        // region only, and cut the box there when the plane is axis-aligned.
        if let Some(n) = half_space {
            for i in 0..3 {
                let (lo, hi) = (bounds.min[i], bounds.max[i]);
                if n[i] > 0.999 && centroid[i] < hi {
                    bounds.min[i] = lo.max(centroid[i]);
                } else if n[i] < -0.999 && centroid[i] > lo {
                    bounds.max[i] = hi.min(centroid[i]);
                }
            }
        }
        let mut search = Self {
            bounds,
            half_space: half_space.map(|n| (n, centroid)),
            mics: array.mics.clone(),
            pairs: bank
                .pairs
                .iter()
                .map(|p| (p.a, p.b, (p.offset + p.half) as f64))
                .collect(),
            steps_per_metre: bank.steps_per_second / speed_of_sound,
            min_range: cfg.min_range_m,
            initial: cfg.initial_points,
            kept: cfg.kept_points,
            min_volume: cfg.min_volume_m3,
            max_evaluations: cfg.max_evaluations,
            exclusion: cfg.exclusion_radius_m,
            dist: vec![0.0; array.len()],
            points: Vec::with_capacity(cfg.initial_points.max(cfg.kept_points)),
            pull: 0.0,
            centroid,
            mean_range: 0.0,
        };
        search.mean_range = search.mean_range_of_box();
        search
    }

    /// Mean distance from the array centroid over a regular 16^3 grid of the searchable box.
    fn mean_range_of_box(&self) -> f64 {
        const N: usize = 16;
        let (mut sum, mut n) = (0.0, 0usize);
        let size = self.bounds.size();
        for i in 0..N {
            for j in 0..N {
                for k in 0..N {
                    let f = |q: usize| (q as f64 + 0.5) / N as f64;
                    let x =
                        self.bounds.min + Vec3::new(size.x * f(i), size.y * f(j), size.z * f(k));
                    if self.valid(&x, &[]) {
                        sum += (x - self.centroid).norm();
                        n += 1;
                    }
                }
            }
        }
        if n == 0 {
            (self.bounds.center() - self.centroid).norm()
        } else {
            sum / n as f64
        }
    }

    /// Mean normalised near-field SRP at `x`.
    #[inline]
    fn srp(&mut self, table: &[f64], x: &Vec3) -> f64 {
        for (d, m) in self.dist.iter_mut().zip(&self.mics) {
            *d = (x - m).norm_squared().sqrt() * self.steps_per_metre;
        }
        // Four partial sums break the chain of dependent additions.
        let dist = &self.dist;
        let term = |&(a, b, zero): &(usize, usize, f64)| lerp(table, zero + dist[a] - dist[b]);
        let mut acc = [0.0; 4];
        let chunks = self.pairs.chunks_exact(4);
        let rest: f64 = chunks.remainder().iter().map(term).sum();
        for c in chunks {
            for (s, p) in acc.iter_mut().zip(c) {
                *s += term(p);
            }
        }
        let sum = acc[0] + acc[1] + acc[2] + acc[3] + rest;
        sum / self.pairs.len() as f64
    }

    fn valid(&self, x: &Vec3, accepted: &[Vec3]) -> bool {
        let (r2, e2) = (
            self.min_range * self.min_range,
            self.exclusion * self.exclusion,
        );
        self.half_space.is_none_or(|(n, c)| n.dot(&(x - c)) >= 0.0)
            && self.mics.iter().all(|m| (x - m).norm_squared() >= r2)
            && accepted.iter().all(|a| (x - a).norm_squared() >= e2)
    }

    /// A uniform point of `bx` that is far enough from the mics and the accepted candidates.
    fn draw<R: Rng + ?Sized>(&self, bx: &Aabb, accepted: &[Vec3], rng: &mut R) -> Option<Vec3> {
        (0..MAX_DRAW_TRIES)
            .map(|_| bx.sample(rng))
            .find(|x| self.valid(x, accepted))
    }

    /// Runs one contraction and returns the best point with its normalised SRP.
    pub fn search<R: Rng + ?Sized>(
        &mut self,
        bank: &GccBank,
        accepted: &[Vec3],
        rng: &mut R,
        pull: f64,
    ) -> Option<(Vec3, f64)> {
        let table = &bank.table;
        let bounds = self.bounds;
        let mut points = std::mem::take(&mut self.points);
        points.clear();
        let mut evaluations = 0;
        for _ in 0..self.initial {
            if let Some(x) = self.draw(&bounds, accepted, rng) {
                let v = self.srp(table, &x);
                points.push((x, v));
            }
            evaluations += 1;
        }
        if points.is_empty() {
            self.points = points;
            return None;
        }
        if points.len() > self.kept {
            points.select_nth_unstable_by(self.kept - 1, |a, b| b.1.total_cmp(&a.1));
            points.truncate(self.kept);
        }
        loop {
            let bx = bounding_box(&points);
            if volume(&bx) < self.min_volume || evaluations >= self.max_evaluations {
                break;
            }
            let threshold = points.iter().map(|p| p.1).sum::<f64>() / points.len() as f64;
            let before = points.len();
            points.retain(|p| p.1 > threshold);
            if points.is_empty() || points.len() == before {
                // Every point has the same SRP: the box cannot contract further.
                break;
            }
            let bx = bounding_box(&points);
            let mut misses = 0;
            while points.len() < self.kept && evaluations < self.max_evaluations {
                evaluations += 1;
                let Some(x) = self.draw(&bx, accepted, rng) else {
                    misses += 1;
                    if misses > MAX_DRAW_TRIES {
                        break;
                    }
                    continue;
                };
                let v = self.srp(table, &x);
                if v > threshold {
                    points.push((x, v));
                }
            }
        }
        let best = points.iter().copied().max_by(|a, b| a.1.total_cmp(&b.1));
        let start_step = (0.25 * max_side(&bounding_box(&points))).clamp(0.02, 0.2);
        self.points = points;
        self.pull = pull / (0.25 * self.bounds.size().norm_squared());
        best.map(|(x, _)| {
            let v = self.objective(table, &x, accepted);
            let (x, _) = self.polish(table, x, v, start_step, accepted);
            (x, self.srp(table, &x))
        })
    }

    /// What the final ascent maximises: the SRP minus the pull towards the box centre and towards
    /// the mean range of the box from the array, or minus infinity where no source may be.
    fn objective(&mut self, table: &[f64], x: &Vec3, accepted: &[Vec3]) -> f64 {
        if self.bounds.contains(x) && self.valid(x, accepted) {
            let range = (x - self.centroid).norm() - self.mean_range;
            let centre = (x - self.bounds.center()).norm_squared();
            self.srp(table, x) - self.pull * (centre + range * range)
        } else {
            f64::NEG_INFINITY
        }
    }

    /// Nelder-Mead ascent of the objective from the contraction's best point. The random points
    /// leave it a fraction of the final box away from the peak; along the ridges where the SRP is
    /// flat (range, the cone of a linear array) the pull slides it to the most central place at
    /// a typical range, instead of wherever noise put the maximum (often the box's far corners).
    /// The simplex follows ridges that axis-wise steps cannot.
    fn polish(
        &mut self,
        table: &[f64],
        x: Vec3,
        v: f64,
        step: f64,
        accepted: &[Vec3],
    ) -> (Vec3, f64) {
        let mut simplex = [(x, v); 4];
        for (axis, vertex) in simplex.iter_mut().enumerate().skip(1) {
            let mut p = x;
            p[axis - 1] += step;
            if !self.bounds.contains(&p) {
                p[axis - 1] -= 2.0 * step;
            }
            *vertex = (p, self.objective(table, &p, accepted));
        }
        let mut evaluations = 3;
        while evaluations < POLISH_MAX_EVALUATIONS {
            simplex.sort_by(|a, b| b.1.total_cmp(&a.1));
            let size = simplex[1..]
                .iter()
                .map(|(p, _)| (p - simplex[0].0).norm())
                .fold(0.0, f64::max);
            if size < POLISH_MIN_STEP_M {
                break;
            }
            let centroid = (simplex[0].0 + simplex[1].0 + simplex[2].0) / 3.0;
            let worst = simplex[3];
            let reflected = centroid + (centroid - worst.0);
            let vr = self.objective(table, &reflected, accepted);
            evaluations += 1;
            if vr > simplex[0].1 {
                let expanded = centroid + (centroid - worst.0) * 2.0;
                let ve = self.objective(table, &expanded, accepted);
                evaluations += 1;
                simplex[3] = if ve > vr {
                    (expanded, ve)
                } else {
                    (reflected, vr)
                };
            } else if vr > simplex[2].1 {
                simplex[3] = (reflected, vr);
            } else {
                let contracted = centroid + (worst.0 - centroid) * 0.5;
                let vc = self.objective(table, &contracted, accepted);
                evaluations += 1;
                if vc > worst.1 {
                    simplex[3] = (contracted, vc);
                } else {
                    let best = simplex[0].0;
                    for vertex in simplex.iter_mut().skip(1) {
                        let p = best + (vertex.0 - best) * 0.5;
                        *vertex = (p, self.objective(table, &p, accepted));
                    }
                    evaluations += 3;
                }
            }
        }
        simplex
            .into_iter()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((x, v))
    }

    /// Times of flight (seconds) from a source at `x` to every microphone.
    pub fn delays(&self, x: &Vec3, steps_per_second: f64, out: &mut [f64]) {
        let per_metre = self.steps_per_metre / steps_per_second;
        for (o, m) in out.iter_mut().zip(&self.mics) {
            *o = (x - m).norm() * per_metre;
        }
    }
}

fn bounding_box(points: &[(Vec3, f64)]) -> Aabb {
    let mut min = Vec3::repeat(f64::INFINITY);
    let mut max = Vec3::repeat(f64::NEG_INFINITY);
    for (p, _) in points {
        min = min.inf(p);
        max = max.sup(p);
    }
    Aabb { min, max }
}

fn max_side(b: &Aabb) -> f64 {
    let s = b.max - b.min;
    s.x.max(s.y).max(s.z)
}

fn volume(b: &Aabb) -> f64 {
    let s = b.max - b.min;
    s.x.max(0.0) * s.y.max(0.0) * s.z.max(0.0)
}
