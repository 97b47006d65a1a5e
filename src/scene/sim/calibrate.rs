//! Wall absorption for a target reverberation time.
//!
//! Sabine's formula gives the absorption of a diffuse room, but a shoebox with uniform walls
//! simulated by the image-source method is not diffuse: images along the longest side meet the
//! fewest walls, so the energy decay bends upward and the T30 measured on its responses comes out
//! longer than the target (a 7.67 x 3.41 x 2.7 m room with Sabine's absorption for 0.5 s measures
//! about 0.8 s). Sabine's value is therefore only the starting point: the absorption is tuned by
//! bisection until the T30 of the image-source energy decay for a representative source and
//! receiver, measured exactly as ISO 3382 measures a response (Schroeder integration, line fit
//! between -5 and -35 dB), equals the target. The same energy decay gives the response length:
//! where the Schroeder curve reaches -60 dB.

use std::f64::consts::PI;

use crate::geometry::Vec3;

use super::room::{sabine_absorption, visit_images};

/// Width of the energy histogram bins (s).
const BIN_S: f64 = 0.0005;

/// The absorption and response length that make a room reverberate for a target time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reverberation {
    /// Energy absorption coefficient of every wall.
    pub absorption: f64,
    /// What Sabine's formula alone would give (for reports).
    pub sabine_absorption: f64,
    /// Length of the room responses (s): where the decay reaches -60 dB.
    pub response_s: f64,
}

/// Energy of the image-source response of one source-receiver pair, binned by time and by
/// reflection order, so that its decay can be evaluated for any wall reflection coefficient.
struct EnergyTable {
    /// `by_order[k][bin]`: summed 1 / (4 pi r)^2 of the images of order k arriving in `bin`.
    by_order: Vec<Vec<f64>>,
    bins: usize,
}

impl EnergyTable {
    fn new(size: &Vec3, source: &Vec3, receiver: &Vec3, length_s: f64, c: f64) -> Self {
        let bins = (length_s / BIN_S).ceil() as usize;
        let mut by_order: Vec<Vec<f64>> = Vec::new();
        visit_images(size, source, receiver, c * length_s, |p, k| {
            let r = (p - receiver).norm().max(0.01);
            let bin = ((r / c) / BIN_S) as usize;
            if bin < bins {
                let k = k as usize;
                if by_order.len() <= k {
                    by_order.resize_with(k + 1, || vec![0.0; bins]);
                }
                by_order[k][bin] += 1.0 / (16.0 * PI * PI * r * r);
            }
        });
        Self { by_order, bins }
    }

    /// Schroeder decay curve (dB, 0 at the start) for wall absorption `alpha`.
    fn decay_db(&self, alpha: f64) -> Vec<f64> {
        let beta2 = 1.0 - alpha;
        let mut energy = vec![0.0; self.bins];
        let mut g = 1.0;
        for row in &self.by_order {
            if g < 1e-300 {
                break;
            }
            for (e, v) in energy.iter_mut().zip(row) {
                *e += g * v;
            }
            g *= beta2;
        }
        let mut acc = 0.0;
        for e in energy.iter_mut().rev() {
            acc += *e;
            *e = acc;
        }
        let total = energy.first().copied().unwrap_or(0.0).max(1e-300);
        energy
            .iter()
            .map(|e| 10.0 * (e / total).max(1e-30).log10())
            .collect()
    }

    /// T30 (s) for absorption `alpha`, or `None` when the curve does not fall 35 dB.
    fn t30(&self, alpha: f64) -> Option<f64> {
        let curve = self.decay_db(alpha);
        let first = curve.iter().position(|&d| d <= -5.0)?;
        let last = curve.iter().position(|&d| d <= -35.0)?;
        let pts: Vec<(f64, f64)> = (first..=last)
            .map(|i| ((i as f64 + 0.5) * BIN_S, curve[i]))
            .collect();
        if pts.len() < 3 {
            // Falls 30 dB within a bin or two: far shorter than any target we accept.
            return Some(pts.len() as f64 * BIN_S * 2.0);
        }
        let n = pts.len() as f64;
        let (st, sd) = pts.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
        let (stt, std_) = pts
            .iter()
            .fold((0.0, 0.0), |a, p| (a.0 + p.0 * p.0, a.1 + p.0 * p.1));
        let slope = (n * std_ - st * sd) / (n * stt - st * st);
        (slope < 0.0).then(|| -60.0 / slope)
    }

    /// Time (s) where the decay curve for `alpha` reaches `level_db`, if it does.
    fn time_to(&self, alpha: f64, level_db: f64) -> Option<f64> {
        let curve = self.decay_db(alpha);
        curve
            .iter()
            .position(|&d| d <= level_db)
            .map(|i| i as f64 * BIN_S)
    }
}

/// The absorption that gives T30 = `rt60_s` for a source at `source` heard at `receiver` in a
/// shoebox of `size`, and the response length. Errors name what is impossible.
pub fn reverberation_for(
    size: &Vec3,
    rt60_s: f64,
    source: &Vec3,
    receiver: &Vec3,
    speed_of_sound: f64,
) -> Result<Reverberation, String> {
    if !(rt60_s.is_finite() && rt60_s > 0.0) {
        return Err(format!("RT60 {rt60_s} s must be positive"));
    }
    // Sabine's value may exceed 1 for short targets the image-source room still reaches, so it
    // is only reported, not enforced.
    let sabine = sabine_absorption(size, rt60_s, speed_of_sound).unwrap_or(1.0);
    let horizon = 2.0 * rt60_s;
    let table = EnergyTable::new(size, source, receiver, horizon, speed_of_sound);
    let t30 = |alpha: f64| table.t30(alpha).unwrap_or(f64::INFINITY);
    let (mut lo, mut hi) = (1e-3, 0.98);
    if t30(hi) > rt60_s {
        return Err(format!(
            "RT60 {rt60_s} s is shorter than this room can reverberate ({:.3} s with walls \
             absorbing {:.0} % of the energy)",
            t30(hi),
            hi * 100.0
        ));
    }
    if t30(lo) < rt60_s {
        return Err(format!(
            "RT60 {rt60_s} s is longer than this room can reverberate"
        ));
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if t30(mid) > rt60_s {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let absorption = 0.5 * (lo + hi);
    let response_s = table.time_to(absorption, -60.0).unwrap_or(horizon);
    Ok(Reverberation {
        absorption,
        sabine_absorption: sabine,
        response_s,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tuned_absorption_brackets_sabine_and_orders_with_the_target() {
        let size = Vec3::new(6.0, 5.0, 3.0);
        let (s, r) = (Vec3::new(2.0, 3.5, 1.2), Vec3::new(3.0, 2.5, 0.8));
        let short = reverberation_for(&size, 0.25, &s, &r, 343.0).unwrap();
        let long = reverberation_for(&size, 0.5, &s, &r, 343.0).unwrap();
        assert!(short.absorption > long.absorption);
        assert!(short.response_s < long.response_s);
        // The tuned value stays in Sabine's neighbourhood (within a factor of two).
        for v in [short, long] {
            let ratio = v.absorption / v.sabine_absorption;
            assert!((0.5..2.0).contains(&ratio), "{v:?}");
        }
        assert!(reverberation_for(&size, 0.01, &s, &r, 343.0).is_err());
    }
}
