//! Multi-sensor Gibbs sampler with the factorised ("minimally Markovian") proposal of Vo, Vo &
//! Beard 2019 (spec 000 A4, spec 003 5.9).
//!
//! For each candidate track the proposal holds one birth/survival factor and, per sensor, a row
//! of association weights beta(j) (j = 0 for a miss). The alive mass is
//! `P_S * prod_s sum_{j allowed} beta_s(j)`: a single P_S factor, not one per sensor (the caveat
//! of spec 000 3.6, which would make births almost never sampled alive with several sensors).
//! Exclusions (a measurement taken by another track in the same sensor) are applied on the fly,
//! also in the death probability, so for a single sensor this is the exact Gibbs conditional.

use rand::Rng;

use super::slice_set::SliceSet;

/// Association value of a dead (or unborn) track.
pub(crate) const DEAD: u16 = u16::MAX;
const FREE: u32 = u32::MAX;

/// The proposal of every candidate track of a step: flat rows, computed lazily by the caller.
#[derive(Debug, Clone, Default)]
pub(crate) struct Proposal {
    sensors: usize,
    /// Start of each sensor's measurements in the sampler's table of taken measurements.
    offsets: Vec<u32>,
    /// Total number of measurements over the sensors.
    measurements: usize,
    /// (start, len) of row (candidate, sensor) in the entry arrays.
    spans: Vec<(u32, u32)>,
    /// log scale of each row: the weights in `ws` are exp(log w - scale).
    scales: Vec<f64>,
    /// Sum of the scaled weights of each row.
    totals: Vec<f64>,
    /// Row entries: measurement index (0 = miss), scaled weight, slot in the taken table.
    js: Vec<u16>,
    ws: Vec<f64>,
    slots: Vec<u32>,
    log_alive: Vec<f64>,
    log_dead: Vec<f64>,
    /// Death probability of each candidate when no measurement is taken by another track.
    p_dead_free: Vec<f64>,
}

impl Proposal {
    /// Empties the proposal for `candidates` tracks and sensors with `counts` measurements each.
    pub fn reset(&mut self, candidates: usize, counts: &[usize]) {
        let sensors = counts.len();
        self.sensors = sensors;
        self.offsets.clear();
        let mut total = 0u32;
        for &n in counts {
            self.offsets.push(total);
            total += n as u32;
        }
        self.measurements = total as usize;
        self.spans.clear();
        self.spans.resize(candidates * sensors, (0, 0));
        self.scales.clear();
        self.scales.resize(candidates * sensors, 0.0);
        self.totals.clear();
        self.totals.resize(candidates * sensors, 0.0);
        self.js.clear();
        self.ws.clear();
        self.slots.clear();
        self.log_alive.clear();
        self.log_alive.resize(candidates, 0.0);
        self.log_dead.clear();
        self.log_dead.resize(candidates, 0.0);
        self.p_dead_free.clear();
        self.p_dead_free.resize(candidates, 0.0);
    }

    /// Sets a candidate's survival (or birth) probability.
    pub fn set_existence(&mut self, cand: usize, p: f64) {
        self.log_alive[cand] = p.ln();
        self.log_dead[cand] = (-p).ln_1p();
    }

    /// Stores the row of (candidate, sensor): pairs (j, log beta(j)); j = 0 (miss) must be first.
    pub fn set_row(&mut self, cand: usize, sensor: usize, row: &[(u16, f64)]) {
        let scale = row.iter().map(|r| r.1).fold(f64::NEG_INFINITY, f64::max);
        let start = self.js.len() as u32;
        let mut total = 0.0;
        for &(j, lw) in row {
            let w = (lw - scale).exp();
            self.js.push(j);
            self.ws.push(w);
            self.slots.push(if j == 0 {
                FREE
            } else {
                self.offsets[sensor] + j as u32 - 1
            });
            total += w;
        }
        let k = cand * self.sensors + sensor;
        self.spans[k] = (start, row.len() as u32);
        self.scales[k] = scale;
        self.totals[k] = total;
    }

    /// log P_S (or log r_B) of a candidate.
    pub fn log_alive(&self, cand: usize) -> f64 {
        self.log_alive[cand]
    }

    /// log(1 - P_S) (or log(1 - r_B)) of a candidate.
    pub fn log_dead(&self, cand: usize) -> f64 {
        self.log_dead[cand]
    }

    /// Completes a candidate once its existence and rows are set.
    pub fn seal(&mut self, cand: usize) {
        let mut log_alive = self.log_alive[cand];
        for s in 0..self.sensors {
            let k = cand * self.sensors + s;
            log_alive += self.scales[k] + self.totals[k].ln();
        }
        self.p_dead_free[cand] = death_probability(log_alive, self.log_dead[cand]);
    }
}

/// P(dead) = 1 / (1 + alive / dead) from log masses.
fn death_probability(log_alive: f64, log_dead: f64) -> f64 {
    1.0 / (1.0 + (log_alive - log_dead).exp())
}

/// Reusable buffers of the sampler.
#[derive(Debug, Clone, Default)]
pub(crate) struct Sampler {
    gamma: Vec<u16>,
    previous: Vec<u16>,
    /// Per measurement (all sensors): the local track holding it, or FREE.
    taken: Vec<u32>,
    sums: Vec<f64>,
}

impl Sampler {
    /// Draws `samples` association maps for the tracks `cands` (indices into the proposal) and
    /// inserts the distinct ones into `out`. A map holds `sensors + 1` entries per track, track
    /// major: first the status (0 = alive, [`DEAD`] = dead or not born), then per sensor 0 =
    /// missed or j + 1 = measurement j (0 for a dead track).
    ///
    /// The chain starts from (and stores) the map in which the first `births` tracks are not born
    /// and the others are alive and missed. The reference code starts from all tracks alive,
    /// births included: equally valid (only the start of the chain differs and every map is
    /// weighted exactly), but it stores for every parent a child in which every birth exists
    /// undetected, which is negligible and costly in the next step.
    pub fn sample<R: Rng>(
        &mut self,
        prop: &Proposal,
        cands: &[u32],
        births: usize,
        samples: usize,
        rng: &mut R,
        out: &mut SliceSet<u16>,
    ) {
        let c = prop.sensors;
        let p = cands.len();
        self.gamma.clear();
        self.gamma.resize(p * (c + 1), 0);
        for i in 0..births.min(p) {
            self.gamma[i * (c + 1)] = DEAD;
        }
        out.insert(&self.gamma);
        if samples <= 1 {
            return;
        }
        self.taken.clear();
        self.taken.resize(prop.measurements, FREE);
        self.sums.resize(c, 0.0);
        self.previous.clear();
        self.previous.extend_from_slice(&self.gamma);
        for _ in 1..samples {
            for (i, &cand) in cands.iter().enumerate() {
                self.resample_track(prop, cand as usize, i, rng);
            }
            // A chain often stays put; only a changed map needs the set lookup.
            if self.gamma != self.previous {
                out.insert(&self.gamma);
                self.previous.copy_from_slice(&self.gamma);
            }
        }
    }

    fn resample_track<R: Rng>(&mut self, prop: &Proposal, cand: usize, i: usize, rng: &mut R) {
        let c = prop.sensors;
        let base = i * (c + 1);
        let Self {
            gamma, taken, sums, ..
        } = self;
        let g = &mut gamma[base..base + 1 + c];
        for s in 0..c {
            if g[1 + s] != 0 {
                taken[(prop.offsets[s] + g[1 + s] as u32 - 1) as usize] = FREE;
            }
        }
        let spans = &prop.spans[cand * c..(cand + 1) * c];
        // Sum the allowed weights of each row; summed in the order of the row total, so an
        // untouched row reproduces it exactly and the precomputed death probability applies.
        let mut untouched = true;
        for (s, &(start, len)) in spans.iter().enumerate() {
            let (a, b) = (start as usize, (start + len) as usize);
            let total = prop.totals[cand * c + s];
            if len > 1 {
                let mut sum = 0.0;
                for (w, &slot) in prop.ws[a..b].iter().zip(&prop.slots[a..b]) {
                    if slot == FREE || taken[slot as usize] == FREE {
                        sum += w;
                    }
                }
                untouched &= sum == total;
                sums[s] = sum;
            } else {
                sums[s] = total;
            }
        }
        let p_dead = if untouched {
            prop.p_dead_free[cand]
        } else {
            let mut alive = prop.log_alive[cand];
            for (s, sum) in sums.iter().enumerate() {
                alive += prop.scales[cand * c + s] + sum.ln();
            }
            death_probability(alive, prop.log_dead[cand])
        };
        let u0 = rng.random::<f64>();
        if u0 < p_dead {
            g.fill(0);
            g[0] = DEAD;
            return;
        }
        g[0] = 0;
        // The first sensor reuses the death draw, rescaled to a fresh uniform.
        let mut fresh = Some((u0 - p_dead) / (1.0 - p_dead));
        for (s, &(start, len)) in spans.iter().enumerate() {
            let (a, b) = (start as usize, (start + len) as usize);
            let u = fresh.take().unwrap_or_else(|| rng.random::<f64>());
            let mut left = u * sums[s];
            let mut pick = 0u16;
            for k in a..b {
                let slot = prop.slots[k];
                if slot != FREE && taken[slot as usize] != FREE {
                    continue;
                }
                pick = prop.js[k];
                left -= prop.ws[k];
                if left <= 0.0 {
                    break;
                }
            }
            g[1 + s] = pick;
            if pick != 0 {
                taken[(prop.offsets[s] + pick as u32 - 1) as usize] = i as u32;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// Two tracks, one sensor, two measurements: the sampled frequencies follow the exact
    /// conditionals, so the most likely joint association must be found and dominate.
    #[test]
    fn finds_the_best_joint_association_and_respects_exclusion() {
        let mut prop = Proposal::default();
        prop.reset(2, &[2]);
        prop.set_existence(0, 0.99);
        prop.set_existence(1, 0.99);
        // Track 0 likes measurement 1 (j = 1), track 1 likes both but measurement 1 more.
        prop.set_row(
            0,
            0,
            &[(0, 0.05f64.ln()), (1, 50f64.ln()), (2, 0.1f64.ln())],
        );
        prop.set_row(1, 0, &[(0, 0.05f64.ln()), (1, 40f64.ln()), (2, 30f64.ln())]);
        prop.seal(0);
        prop.seal(1);
        let mut out = SliceSet::default();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut sampler = Sampler::default();
        sampler.sample(&prop, &[0, 1], 0, 200, &mut rng, &mut out);
        let samples: Vec<Vec<u16>> = (0..out.len()).map(|i| out.get(i).to_vec()).collect();
        assert!(samples.contains(&vec![0, 0, 0, 0]));
        assert!(samples.contains(&vec![0, 1, 0, 2]), "{samples:?}");
        for s in &samples {
            assert!(!(s[1] == s[3] && s[1] != 0), "{s:?}");
        }
    }

    #[test]
    fn unlikely_births_die_and_likely_ones_live() {
        let mut prop = Proposal::default();
        prop.reset(2, &[1, 1]);
        // A birth with r_B = 0.001 and no support, and one with strong support in both sensors.
        prop.set_existence(0, 0.001);
        prop.set_existence(1, 0.01);
        for s in 0..2 {
            prop.set_row(0, s, &[(0, 0.4f64.ln())]);
            prop.set_row(1, s, &[(0, 0.4f64.ln()), (1, 1000f64.ln())]);
        }
        prop.seal(0);
        prop.seal(1);
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut counts = [0usize; 2];
        let mut sampler = Sampler::default();
        for _ in 0..200 {
            let mut out = SliceSet::default();
            sampler.sample(&prop, &[0, 1], 2, 2, &mut rng, &mut out);
            let last = out.get(out.len() - 1).to_vec();
            counts[0] += (last[0] != DEAD) as usize;
            counts[1] += (last[3] == 0 && last[4] == 1 && last[5] == 1) as usize;
        }
        assert!(counts[0] < 10, "{counts:?}");
        // P(alive) = 0.01*1000.4^2 / (0.99 + 0.01*1000.4^2) ~ 0.99990.
        assert!(counts[1] > 190, "{counts:?}");
    }
}
