//! Direction search: hierarchical scan of geodesic spheres with far-field TDOAs from the array
//! centroid (ODAS SRP-PHAT-HSDA), then a local pattern search.
//!
//! Which directions are searched depends on what the array can resolve:
//! - planar arrays cannot tell a direction from its mirror image across their plane, so only the
//!   half-space facing the region centre is searched (the upper one, +normal, when the layout has
//!   no region or the centre lies in the plane);
//! - linear arrays only observe the angle to their axis (a cone); the best cone angle is reported
//!   as the direction on that cone that lies in the half-plane through the axis towards the region
//!   centre (towards +z, or +x for a vertical array, without a region), and azimuth/elevation are
//!   the angles of that representative direction;
//! - with a region, only directions whose ray from the centroid enters the region are searched.

use crate::geometry::{Aabb, ArrayShape, MicArray, Vec3};

use super::gcc::{GccBank, lerp};
use super::geodesic::GeodesicSphere;

/// Smallest chord (metres) a ray must travel inside the region to count as pointing into it.
const MIN_CHORD_M: f64 = 0.01;
/// Cap on pattern-search moves, bounding the refinement's cost.
const MAX_REFINE_MOVES: usize = 200;

/// How the array's ambiguity restricts and labels directions.
#[derive(Debug, Clone, Copy)]
enum Ambiguity {
    None,
    /// Planar array: directions are folded into the half-space `side * normal . d >= 0`.
    Mirror {
        normal: Vec3,
    },
    /// Linear array: directions are represented on the cone through `reference`.
    Cone {
        axis: Vec3,
        reference: Vec3,
    },
}

/// One level of the hierarchy restricted to the searchable directions.
struct Level {
    dirs: Vec<Vec3>,
    /// Fine-table position of every pair's far-field TDOA, point-major.
    idx: Vec<f32>,
    neighbours: Vec<Vec<usize>>,
    /// For every point, the points of the next level nearest to it (its cell).
    children: Vec<Vec<usize>>,
}

/// The direction search of one array, with all geometry-dependent tables precomputed.
pub(crate) struct DirectionSearch {
    centroid: Vec3,
    region: Option<Aabb>,
    ambiguity: Ambiguity,
    levels: Vec<Level>,
    /// Far-field TDOA of pair q in fine steps is `pair_steps[q] . d`.
    pair_steps: Vec<Vec3>,
    /// The band's PHAT kernel at fine lag offsets (see `GccBank`).
    kernel: Vec<f64>,
    /// Directions where an accepted candidate's main lobe exceeds this are excluded (1: off).
    lobe_limit: f64,
    /// Table positions of the accepted directions' lags, pair-minor (see `excluded`).
    accepted_at: Vec<f64>,
    /// Microphone offsets from the centroid divided by the speed of sound (seconds per unit
    /// direction).
    mic_offsets: Vec<Vec3>,
    /// Absolute table position of every pair's zero lag.
    zeros: Vec<f64>,
    /// Max-filter half-widths (fine steps) per coarse level and pair.
    widths: Vec<Vec<usize>>,
    filtered: Vec<Vec<f64>>,
    work: Vec<f64>,
    first_step: f64,
    min_step: f64,
}

/// SRP statistics of a frame over the coarse grid.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct GridStats {
    pub mean: f64,
    pub max: f64,
}

/// Sum of `f` over `items` with four partial sums (breaks the chain of dependent additions).
#[inline(always)]
fn sum4<T>(items: &[T], f: impl Fn(&T) -> f64) -> f64 {
    let chunks = items.chunks_exact(4);
    let rest: f64 = chunks.remainder().iter().map(&f).sum();
    let mut acc = [0.0; 4];
    for c in chunks {
        for (s, x) in acc.iter_mut().zip(c) {
            *s += f(x);
        }
    }
    acc[0] + acc[1] + acc[2] + acc[3] + rest
}

fn ray_enters(region: &Aabb, origin: &Vec3, d: &Vec3) -> bool {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for i in 0..3 {
        if d[i].abs() < 1e-12 {
            if origin[i] < region.min[i] || origin[i] > region.max[i] {
                return false;
            }
        } else {
            let ta = (region.min[i] - origin[i]) / d[i];
            let tb = (region.max[i] - origin[i]) / d[i];
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
    }
    t1 - t0 > MIN_CHORD_M
}

fn perpendicular(v: &Vec3, axis: &Vec3) -> Option<Vec3> {
    let p = v - axis * axis.dot(v);
    (p.norm() > 1e-6).then(|| p.normalize())
}

impl DirectionSearch {
    /// Precomputes grids and TDOA tables for `array` (which has at least two microphones).
    pub fn new(
        array: &MicArray,
        bank: &GccBank,
        region: Option<Aabb>,
        levels: &[u32],
        refine_step: f64,
        lobe_limit: f64,
        speed_of_sound: f64,
    ) -> Self {
        let centroid = array.centroid();
        let towards = region.map(|r| r.center() - centroid);
        let ambiguity = match array.shape() {
            ArrayShape::Planar { normal } => {
                let side = match towards {
                    Some(t) if normal.dot(&t).abs() > 1e-6 => normal.dot(&t).signum(),
                    _ => 1.0,
                };
                Ambiguity::Mirror {
                    normal: normal * side,
                }
            }
            ArrayShape::Linear { axis } => {
                let reference = towards
                    .and_then(|t| perpendicular(&t, &axis))
                    .or_else(|| perpendicular(&Vec3::z(), &axis))
                    .or_else(|| perpendicular(&Vec3::x(), &axis))
                    .unwrap_or_else(Vec3::y);
                Ambiguity::Cone { axis, reference }
            }
            _ => Ambiguity::None,
        };
        let pair_steps: Vec<Vec3> = bank
            .pairs
            .iter()
            .map(|p| (array.mics[p.b] - array.mics[p.a]) * (bank.steps_per_second / speed_of_sound))
            .collect();
        let zeros: Vec<f64> = bank
            .pairs
            .iter()
            .map(|p| (p.offset + p.half) as f64)
            .collect();
        let mut search = Self {
            centroid,
            region,
            ambiguity,
            levels: Vec::new(),
            pair_steps,
            kernel: bank.kernel().to_vec(),
            lobe_limit,
            accepted_at: Vec::new(),
            mic_offsets: array
                .mics
                .iter()
                .map(|m| (m - centroid) / speed_of_sound)
                .collect(),
            zeros,
            widths: Vec::new(),
            filtered: Vec::new(),
            work: vec![0.0; 2 * bank.longest_table()],
            first_step: 0.0,
            min_step: refine_step,
        };
        let spheres: Vec<GeodesicSphere> = levels.iter().map(|&l| GeodesicSphere::new(l)).collect();
        let maps: Vec<Vec<Option<usize>>> = spheres.iter().map(|s| search.add_level(s)).collect();
        for l in 0..spheres.len().saturating_sub(1) {
            search.link_levels(l, &spheres[l], &maps[l]);
        }
        search.first_step = spheres.last().map_or(0.05, |s| s.spacing() / 2.0);
        search.filtered = vec![vec![0.0; bank.table.len()]; search.widths.len()];
        search
    }

    /// The unit normal of a planar array's searched half-space (facing the region).
    pub fn mirror_normal(&self) -> Option<Vec3> {
        match self.ambiguity {
            Ambiguity::Mirror { normal } => Some(normal),
            _ => None,
        }
    }

    /// Whether the search may report `d` (before folding).
    fn allowed(&self, d: &Vec3) -> bool {
        if let Ambiguity::Mirror { normal } = self.ambiguity
            && normal.dot(d) < -1e-9
        {
            return false;
        }
        self.region
            .as_ref()
            .is_none_or(|r| ray_enters(r, &self.centroid, d))
    }

    /// Folds a planar array's direction into the searched half-space.
    fn fold(&self, d: Vec3) -> Vec3 {
        match self.ambiguity {
            Ambiguity::Mirror { normal } if normal.dot(&d) < 0.0 => {
                d - normal * (2.0 * normal.dot(&d))
            }
            _ => d,
        }
    }

    /// Appends the searchable points of `sphere` as a level; returns the map from sphere index to
    /// level index.
    fn add_level(&mut self, sphere: &GeodesicSphere) -> Vec<Option<usize>> {
        let mut map = vec![None; sphere.points.len()];
        let mut dirs = Vec::new();
        for (i, p) in sphere.points.iter().enumerate() {
            if self.allowed(p) {
                map[i] = Some(dirs.len());
                dirs.push(*p);
            }
        }
        let mut idx = Vec::with_capacity(dirs.len() * self.pair_steps.len());
        for d in &dirs {
            for (v, z) in self.pair_steps.iter().zip(&self.zeros) {
                idx.push((z + v.dot(d)) as f32);
            }
        }
        let neighbours = sphere
            .points
            .iter()
            .enumerate()
            .filter(|(i, _)| map[*i].is_some())
            .map(|(i, _)| {
                sphere.neighbours[i]
                    .iter()
                    .filter_map(|&j| map[j])
                    .collect()
            })
            .collect();
        let n = dirs.len();
        self.levels.push(Level {
            dirs,
            idx,
            neighbours,
            children: vec![Vec::new(); n],
        });
        map
    }

    /// Assigns every point of level `l + 1` to the nearest point of level `l` and sizes the
    /// max filter of level `l` to the TDOA spread of its cells.
    fn link_levels(&mut self, l: usize, coarse: &GeodesicSphere, map: &[Option<usize>]) {
        let np = self.pair_steps.len();
        let mut start = 0;
        let fine_dirs = self.levels[l + 1].dirs.clone();
        for (c, d) in fine_dirs.iter().enumerate() {
            start = coarse.nearest(d, start);
            let parent = map[start].or_else(|| {
                let dirs = &self.levels[l].dirs;
                (0..dirs.len()).max_by(|&i, &j| dirs[i].dot(d).total_cmp(&dirs[j].dot(d)))
            });
            if let Some(p) = parent {
                self.levels[l].children[p].push(c);
            }
        }
        let mut widths = vec![1usize; np];
        let (coarse_level, fine_level) = (&self.levels[l], &self.levels[l + 1]);
        for (p, kids) in coarse_level.children.iter().enumerate() {
            for &c in kids {
                for (q, w) in widths.iter_mut().enumerate() {
                    let dev = (coarse_level.idx[p * np + q] - fine_level.idx[c * np + q]).abs();
                    *w = (*w).max(dev.ceil() as usize + 1);
                }
            }
        }
        self.widths.push(widths);
    }

    /// Mean normalised SRP at point `p` of a level, from `table`.
    #[inline]
    fn srp_at(&self, table: &[f64], level: &Level, p: usize) -> f64 {
        let np = self.pair_steps.len();
        sum4(&level.idx[p * np..(p + 1) * np], |&x| {
            lerp(table, f64::from(x))
        }) / np as f64
    }

    /// Mean normalised SRP in direction `d` (any unit vector), from `table`.
    #[inline]
    fn srp_dir(&self, table: &[f64], d: &Vec3) -> f64 {
        let np = self.pair_steps.len();
        let sum: f64 = self
            .pair_steps
            .iter()
            .zip(&self.zeros)
            .map(|(v, z)| lerp(table, z + v.dot(d)))
            .sum();
        sum / np as f64
    }

    /// SRP mean and maximum over the coarsest level.
    pub fn grid_stats(&self, bank: &GccBank) -> GridStats {
        let level = &self.levels[0];
        let n = level.dirs.len();
        if n == 0 {
            return GridStats::default();
        }
        let (mut s, mut max) = (0.0, f64::NEG_INFINITY);
        for p in 0..n {
            let v = self.srp_at(&bank.table, level, p);
            s += v;
            max = max.max(v);
        }
        GridStats {
            mean: s / n as f64,
            max,
        }
    }

    /// Angular separation used for exclusion: the cone-angle difference for linear arrays.
    pub fn separation(&self, a: &Vec3, b: &Vec3) -> f64 {
        match self.ambiguity {
            Ambiguity::Cone { axis, .. } => {
                (axis.dot(a).clamp(-1.0, 1.0).acos() - axis.dot(b).clamp(-1.0, 1.0).acos()).abs()
            }
            _ => a.dot(b).clamp(-1.0, 1.0).acos(),
        }
    }

    /// Whether `d` is too near an accepted direction: within `exclusion` radians, or inside
    /// its main lobe. `at` holds the table positions of `d`'s lags when known (grid points);
    /// `self.accepted_at` must hold those of `accepted`.
    fn excluded(&self, d: &Vec3, at: Option<&[f32]>, accepted: &[Vec3], exclusion: f64) -> bool {
        let near = match self.ambiguity {
            Ambiguity::Cone { .. } => accepted.iter().any(|a| self.separation(d, a) < exclusion),
            // Same test as the angle, without an arc cosine per grid point.
            _ => {
                let cos = exclusion.cos();
                accepted.iter().any(|a| a.dot(d) > cos)
            }
        };
        if near || self.lobe_limit >= 1.0 || accepted.is_empty() {
            return near;
        }
        let np = self.pair_steps.len();
        let last = (self.kernel.len() - 2) as f64;
        // The normalised SRP a lone, coherent source at the accepted direction gives at `d`:
        // the mean over pairs of the band kernel at the difference of their lags.
        let lobe = |pos: &dyn Fn(usize) -> f64, a: &[f64]| -> f64 {
            let sum: f64 = (0..np)
                .map(|q| lerp(&self.kernel, (pos(q) - a[q]).abs().min(last)))
                .sum();
            sum / np as f64
        };
        let limit = self.lobe_limit;
        self.accepted_at.chunks_exact(np).any(|a| match at {
            Some(idx) => lobe(&|q| f64::from(idx[q]), a) > limit,
            None => lobe(&|q| self.zeros[q] + self.pair_steps[q].dot(d), a) > limit,
        })
    }

    /// Stores the table positions of the accepted directions' lags for `excluded`.
    fn locate_accepted(&mut self, accepted: &[Vec3]) {
        self.accepted_at.clear();
        for a in accepted {
            for (v, z) in self.pair_steps.iter().zip(&self.zeros) {
                self.accepted_at.push(z + v.dot(a));
            }
        }
    }

    /// Finds the strongest direction not within `exclusion` radians of an accepted one; returns
    /// it (representative direction for linear arrays) with its normalised SRP.
    pub fn search(
        &mut self,
        bank: &GccBank,
        accepted: &[Vec3],
        exclusion: f64,
    ) -> Option<(Vec3, f64)> {
        for (w, out) in self.widths.iter().zip(self.filtered.iter_mut()) {
            bank.max_filter(w, out, &mut self.work);
        }
        self.locate_accepted(accepted);
        let np = self.pair_steps.len();
        let last = self.levels.len() - 1;
        let table_of = |l: usize| -> &[f64] {
            if l < last {
                &self.filtered[l]
            } else {
                &bank.table
            }
        };
        let level0 = &self.levels[0];
        let mut best: Option<(usize, f64)> = None;
        for p in 0..level0.dirs.len() {
            // The exclusion test costs as much as the SRP: only run it on a new best.
            let v = self.srp_at(table_of(0), level0, p);
            let at = &level0.idx[p * np..(p + 1) * np];
            if best.is_none_or(|(_, b)| v > b)
                && !self.excluded(&level0.dirs[p], Some(at), accepted, exclusion)
            {
                best = Some((p, v));
            }
        }
        let (mut prev, _) = best?;
        let mut level_of_prev = 0;
        for l in 1..self.levels.len() {
            let (coarse, fine) = (&self.levels[l - 1], &self.levels[l]);
            let cells = std::iter::once(prev).chain(coarse.neighbours[prev].iter().copied());
            let mut best: Option<(usize, f64)> = None;
            for cell in cells {
                for &c in &coarse.children[cell] {
                    let v = self.srp_at(table_of(l), fine, c);
                    let at = &fine.idx[c * np..(c + 1) * np];
                    if best.is_none_or(|(_, b)| v > b)
                        && !self.excluded(&fine.dirs[c], Some(at), accepted, exclusion)
                    {
                        best = Some((c, v));
                    }
                }
            }
            match best {
                Some((c, _)) => {
                    prev = c;
                    level_of_prev = l;
                }
                None => break,
            }
        }
        let start = self.levels[level_of_prev].dirs[prev];
        let (d, power) = self.refine(&bank.table, start, accepted, exclusion);
        Some((self.representative(d), power))
    }

    /// Re-maximises the SRP from `start` by the local pattern search alone: a candidate
    /// re-estimated once the other candidates' bins are masked. Returns it (representative
    /// direction for linear arrays) with its normalised SRP.
    pub fn polish(
        &mut self,
        bank: &GccBank,
        start: Vec3,
        accepted: &[Vec3],
        exclusion: f64,
    ) -> (Vec3, f64) {
        self.locate_accepted(accepted);
        let (d, power) = self.refine(&bank.table, start, accepted, exclusion);
        (self.representative(d), power)
    }

    /// Pattern search on the tangent plane: try 8 neighbours at the current step, move to the
    /// best improvement, halve the step when none improves.
    fn refine(&self, table: &[f64], start: Vec3, accepted: &[Vec3], exclusion: f64) -> (Vec3, f64) {
        let mut d = start;
        let mut best = self.srp_dir(table, &d);
        let mut step = self.first_step;
        let mut moves = 0;
        const D: f64 = std::f64::consts::FRAC_1_SQRT_2;
        const OFFSETS: [(f64, f64); 8] = [
            (1.0, 0.0),
            (-1.0, 0.0),
            (0.0, 1.0),
            (0.0, -1.0),
            (D, D),
            (D, -D),
            (-D, D),
            (-D, -D),
        ];
        while step >= self.min_step && moves < MAX_REFINE_MOVES {
            let helper = if d.x.abs() < 0.9 {
                Vec3::x()
            } else {
                Vec3::y()
            };
            let e1 = d.cross(&helper).normalize();
            let e2 = d.cross(&e1);
            let mut next = None;
            for (u, v) in OFFSETS {
                let cand = self.fold((d + (e1 * u + e2 * v) * step).normalize());
                let val = self.srp_dir(table, &cand);
                if val > best
                    && self.allowed(&cand)
                    && !self.excluded(&cand, None, accepted, exclusion)
                {
                    best = val;
                    next = Some(cand);
                }
            }
            match next {
                Some(n) => {
                    d = n;
                    moves += 1;
                }
                None => step /= 2.0,
            }
        }
        (d, best)
    }

    /// The reported direction: a linear array's direction moved onto the reference half-plane
    /// of its cone.
    fn representative(&self, d: Vec3) -> Vec3 {
        match self.ambiguity {
            Ambiguity::Cone { axis, reference } => {
                let c = axis.dot(&d).clamp(-1.0, 1.0);
                axis * c + reference * (1.0 - c * c).sqrt()
            }
            _ => d,
        }
    }

    /// Far-field arrival times (seconds, relative to the centroid) at every microphone of a
    /// plane wave from direction `d`.
    pub fn delays(&self, d: &Vec3, out: &mut [f64]) {
        for (o, m) in out.iter_mut().zip(&self.mic_offsets) {
            *o = -m.dot(d);
        }
    }

    /// Number of searchable points per level (for tests and benchmarks).
    #[cfg(test)]
    pub fn level_sizes(&self) -> Vec<usize> {
        self.levels.iter().map(|l| l.dirs.len()).collect()
    }
}
