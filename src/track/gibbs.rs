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
    /// (start, len) of row (candidate, sensor) in `js`/`ws`; len 0 = not computed.
    spans: Vec<(u32, u32)>,
    /// log scale of each row: the weights in `ws` are exp(log w - scale).
    scales: Vec<f64>,
    js: Vec<u16>,
    ws: Vec<f64>,
    log_alive: Vec<f64>,
    log_dead: Vec<f64>,
}

impl Proposal {
    /// Empties the proposal for `candidates` tracks and `sensors` sensors.
    pub fn reset(&mut self, candidates: usize, sensors: usize) {
        self.sensors = sensors;
        self.spans.clear();
        self.spans.resize(candidates * sensors, (0, 0));
        self.scales.clear();
        self.scales.resize(candidates * sensors, 0.0);
        self.js.clear();
        self.ws.clear();
        self.log_alive.clear();
        self.log_alive.resize(candidates, 0.0);
        self.log_dead.clear();
        self.log_dead.resize(candidates, 0.0);
    }

    /// Sets a candidate's survival (or birth) probability.
    pub fn set_existence(&mut self, cand: usize, p: f64) {
        self.log_alive[cand] = p.ln();
        self.log_dead[cand] = (-p).ln_1p();
    }

    /// Stores the row of (candidate, sensor): pairs (j, log beta(j)); j = 0 (miss) must be first.
    pub fn set_row(&mut self, cand: usize, sensor: usize, row: &[(u16, f64)]) {
        let scale = row
            .iter()
            .map(|r| r.1)
            .fold(f64::NEG_INFINITY, f64::max);
        let start = self.js.len() as u32;
        for &(j, lw) in row {
            self.js.push(j);
            self.ws.push((lw - scale).exp());
        }
        let k = cand * self.sensors + sensor;
        self.spans[k] = (start, row.len() as u32);
        self.scales[k] = scale;
    }

    fn row(&self, cand: usize, sensor: usize) -> (&[u16], &[f64], f64) {
        let k = cand * self.sensors + sensor;
        let (s, l) = self.spans[k];
        let r = s as usize..(s + l) as usize;
        (&self.js[r.clone()], &self.ws[r], self.scales[k])
    }
}

/// Reusable buffers of the sampler.
#[derive(Debug, Clone, Default)]
pub(crate) struct Sampler {
    gamma: Vec<u16>,
    taken: Vec<u32>,
    offsets: Vec<usize>,
    sums: Vec<f64>,
}

impl Sampler {
    /// Draws `samples` association maps for the tracks `cands` (indices into the proposal) and
    /// inserts the distinct ones into `out`. A map holds `sensors + 1` entries per track, track
    /// major: first the status (0 = alive, [`DEAD`] = dead or not born), then per sensor 0 =
    /// missed or j + 1 = measurement j (0 for a dead track). The first sample is the all-alive,
    /// all-missed map.
    pub fn sample<R: Rng>(
        &mut self,
        prop: &Proposal,
        cands: &[u32],
        measurements: &[usize],
        samples: usize,
        rng: &mut R,
        out: &mut SliceSet<u16>,
    ) {
        let c = prop.sensors;
        let p = cands.len();
        self.gamma.clear();
        self.gamma.resize(p * (c + 1), 0);
        self.offsets.clear();
        let mut total = 0;
        for &m in measurements {
            self.offsets.push(total);
            total += m;
        }
        self.taken.clear();
        self.taken.resize(total, FREE);
        self.sums.resize(c, 0.0);
        out.insert(&self.gamma);
        for _ in 1..samples {
            for i in 0..p {
                self.resample_track(prop, cands, i, rng);
            }
            out.insert(&self.gamma);
        }
    }

    fn resample_track<R: Rng>(&mut self, prop: &Proposal, cands: &[u32], i: usize, rng: &mut R) {
        let c = prop.sensors;
        let base = i * (c + 1);
        let cand = cands[i] as usize;
        for s in 0..c {
            let g = self.gamma[base + 1 + s];
            if g != 0 {
                self.taken[self.offsets[s] + g as usize - 1] = FREE;
            }
        }
        let mut log_alive = prop.log_alive[cand];
        for s in 0..c {
            let (js, ws, scale) = prop.row(cand, s);
            let off = self.offsets[s];
            let sum: f64 = js
                .iter()
                .zip(ws)
                .filter(|(j, _)| **j == 0 || self.taken[off + **j as usize - 1] == FREE)
                .map(|(_, w)| w)
                .sum();
            self.sums[s] = sum;
            log_alive += scale + sum.ln();
        }
        let p_dead = 1.0 / (1.0 + (log_alive - prop.log_dead[cand]).exp());
        if rng.random::<f64>() < p_dead {
            self.gamma[base] = DEAD;
            self.gamma[base + 1..base + 1 + c].fill(0);
            return;
        }
        self.gamma[base] = 0;
        for s in 0..c {
            let (js, ws, _) = prop.row(cand, s);
            let off = self.offsets[s];
            let mut u = rng.random::<f64>() * self.sums[s];
            let mut pick = 0u16;
            for (j, w) in js.iter().zip(ws) {
                if *j != 0 && self.taken[off + *j as usize - 1] != FREE {
                    continue;
                }
                pick = *j;
                u -= w;
                if u <= 0.0 {
                    break;
                }
            }
            self.gamma[base + 1 + s] = pick;
            if pick != 0 {
                self.taken[off + pick as usize - 1] = i as u32;
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
        prop.reset(2, 1);
        prop.set_existence(0, 0.99);
        prop.set_existence(1, 0.99);
        // Track 0 likes measurement 1 (j = 1), track 1 likes both but measurement 1 more.
        prop.set_row(0, 0, &[(0, 0.05f64.ln()), (1, 50f64.ln()), (2, 0.1f64.ln())]);
        prop.set_row(1, 0, &[(0, 0.05f64.ln()), (1, 40f64.ln()), (2, 30f64.ln())]);
        let mut out = SliceSet::default();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut sampler = Sampler::default();
        sampler.sample(&prop, &[0, 1], &[2], 200, &mut rng, &mut out);
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
        prop.reset(2, 2);
        // A birth with r_B = 0.001 and no support, and one with strong support in both sensors.
        prop.set_existence(0, 0.001);
        prop.set_existence(1, 0.01);
        for s in 0..2 {
            prop.set_row(0, s, &[(0, 0.4f64.ln())]);
            prop.set_row(1, s, &[(0, 0.4f64.ln()), (1, 1000f64.ln())]);
        }
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut counts = [0usize; 2];
        let mut sampler = Sampler::default();
        for _ in 0..200 {
            let mut out = SliceSet::default();
            sampler.sample(&prop, &[0, 1], &[1, 1], 2, &mut rng, &mut out);
            let last = out.get(out.len() - 1).to_vec();
            counts[0] += (last[0] != DEAD) as usize;
            counts[1] += (last[3] == 0 && last[4] == 1 && last[5] == 1) as usize;
        }
        assert!(counts[0] < 10, "{counts:?}");
        // P(alive) = 0.01*1000.4^2 / (0.99 + 0.01*1000.4^2) ~ 0.99990.
        assert!(counts[1] > 190, "{counts:?}");
    }
}
