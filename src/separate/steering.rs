//! Free-field steering vectors as relative transfer functions (RTFs) to the reference microphone.
//!
//! The direct path from a source at p to microphone m is a delay tau_m = |p - u_m| / c and a gain
//! 1 / |p - u_m|. Dividing by the reference microphone's path gives the RTF
//! a_m(omega) = (r_ref / r_m) e^{-j omega (tau_m - tau_ref)}, with a_ref = 1. A beamformer with
//! w^H a = 1 then reproduces the source's direct path *at the reference microphone* instead of
//! removing the absolute propagation delay (which would be a non-causal shift that wraps within
//! the frame; spec 000 section 4.2). Forward FFT convention: a delay tau multiplies bin k by
//! e^{-j omega_k tau}.

use crate::dsp::Complex;
use crate::geometry::Vec3;

/// Closest distance from a microphone that the near-field model accepts (m); keeps the 1/r gain
/// finite for a position estimate on top of a microphone.
const MIN_RANGE_M: f64 = 0.01;

/// Per-microphone gains and delays of a source relative to the reference microphone.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Steering {
    /// Amplitude of the direct path at each microphone relative to the reference (r_ref / r_m).
    pub gains: Vec<f64>,
    /// Arrival time at each microphone minus that at the reference (s).
    pub delays_s: Vec<f64>,
}

impl Steering {
    /// Near-field (spherical wave) steering from a 3-D source position.
    pub fn near_field(mics: &[Vec3], reference: &Vec3, position: &Vec3, c: f64) -> Self {
        let mut s = Self::default();
        s.set_near_field(mics, reference, position, c);
        s
    }

    /// Far-field (plane wave) steering for a wave arriving from the unit vector `direction`
    /// (pointing from the array toward the source).
    pub fn far_field(mics: &[Vec3], reference: &Vec3, direction: &Vec3, c: f64) -> Self {
        let mut s = Self::default();
        s.set_far_field(mics, reference, direction, c);
        s
    }

    /// In-place [`Steering::near_field`], reusing the buffers.
    pub fn set_near_field(&mut self, mics: &[Vec3], reference: &Vec3, position: &Vec3, c: f64) {
        let r_ref = (position - reference).norm().max(MIN_RANGE_M);
        self.gains.clear();
        self.delays_s.clear();
        for m in mics {
            let r = (position - m).norm().max(MIN_RANGE_M);
            self.gains.push(r_ref / r);
            self.delays_s.push((r - r_ref) / c);
        }
    }

    /// In-place [`Steering::far_field`], reusing the buffers.
    pub fn set_far_field(&mut self, mics: &[Vec3], reference: &Vec3, direction: &Vec3, c: f64) {
        let n = direction.norm();
        let dir = if n > 1e-12 && n.is_finite() {
            direction / n
        } else {
            Vec3::x()
        };
        self.gains.clear();
        self.delays_s.clear();
        for m in mics {
            // A microphone displaced toward the source hears the wave earlier.
            self.gains.push(1.0);
            self.delays_s.push(-(m - reference).dot(&dir) / c);
        }
    }

    /// Whether `other` departs from this steering by more than `tolerance_rad` of phase at angular
    /// frequency `omega_max` on any microphone, or by more than `tolerance_rad` in relative gain:
    /// the error a beamformer built for one makes when the source is at the other.
    pub fn differs(&self, other: &Steering, omega_max: f64, tolerance_rad: f64) -> bool {
        if self.gains.len() != other.gains.len() || self.delays_s.len() != other.delays_s.len() {
            return true;
        }
        // Written as "not within" so that a NaN counts as a change and forces a rebuild.
        let within = |x: f64, limit: f64| x <= limit;
        let phase = self
            .delays_s
            .iter()
            .zip(&other.delays_s)
            .any(|(a, b)| !within((a - b).abs() * omega_max, tolerance_rad));
        let gain = self
            .gains
            .iter()
            .zip(&other.gains)
            .any(|(a, b)| !within((a - b).abs(), tolerance_rad * a.abs().max(b.abs())));
        phase || gain
    }

    /// The steering vector at angular frequency `omega` (rad/s).
    pub fn at(&self, omega: f64, out: &mut [Complex]) {
        for ((o, g), d) in out.iter_mut().zip(&self.gains).zip(&self.delays_s) {
            *o = Complex::from_polar(*g, -omega * d);
        }
    }

    /// Starts a walk over equally spaced bins: `a` gets the vector at `omega0` and `step` the
    /// per-bin factor, so that `a[m] *= step[m]` moves to the next bin (one multiply per
    /// microphone instead of a complex exponential).
    pub fn start_walk(&self, omega0: f64, domega: f64, a: &mut [Complex], step: &mut [Complex]) {
        self.at(omega0, a);
        for (s, d) in step.iter_mut().zip(&self.delays_s) {
            *s = Complex::from_polar(1.0, -domega * d);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dsp::{FrameGeometry, StreamingStft};
    use rand::{Rng, SeedableRng};

    /// Windowed-sinc fractional delay of `x` by `d` samples (non-circular).
    fn fractional_delay(x: &[f64], d: f64) -> Vec<f64> {
        let half = 64i64;
        (0..x.len() as i64)
            .map(|n| {
                let c = n as f64 - d;
                let n0 = c.floor() as i64;
                let mut s = 0.0;
                for i in n0 - half..=n0 + half {
                    if i < 0 || i >= x.len() as i64 {
                        continue;
                    }
                    let t = c - i as f64;
                    let sinc = if t.abs() < 1e-12 {
                        1.0
                    } else {
                        (std::f64::consts::PI * t).sin() / (std::f64::consts::PI * t)
                    };
                    let w = 0.5 + 0.5 * (std::f64::consts::PI * t / (half as f64 + 1.0)).cos();
                    s += x[i as usize] * sinc * w;
                }
                s
            })
            .collect()
    }

    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n).map(|_| rng.random_range(-0.5..0.5)).collect()
    }

    /// Simulates the direct path to each microphone in the time domain and checks the averaged
    /// STFT ratio Y_m / Y_ref against the steering vector, bin by bin.
    fn check_against_direct_path(mics: &[Vec3], source: Vec3, far: bool) {
        let (fs, c) = (16000.0, 343.0);
        let x = noise(16000, 3);
        let r_ref = (source - mics[0]).norm();
        let chans: Vec<Vec<f64>> = mics
            .iter()
            .map(|m| {
                let r = (source - m).norm();
                let (delay, gain) = if far {
                    let dir = (source - mics[0]).normalize();
                    (-(m - mics[0]).dot(&dir) / c, 1.0)
                } else {
                    ((r - r_ref) / c, r_ref / r)
                };
                // A common 40-sample delay keeps every channel causal.
                fractional_delay(&x, 40.0 + delay * fs)
                    .iter()
                    .map(|v| v * gain)
                    .collect()
            })
            .collect();
        let g = FrameGeometry {
            frame: 512,
            hop: 256,
        };
        let mut stft = StreamingStft::new(g, mics.len());
        let bins = g.bins();
        // Cross-spectra with the reference, averaged over frames.
        let mut cross = vec![vec![Complex::new(0.0, 0.0); bins]; mics.len()];
        let mut auto = vec![0.0; bins];
        for start in (0..x.len() - g.hop).step_by(g.hop) {
            let hop: Vec<&[f64]> = chans.iter().map(|ch| &ch[start..start + g.hop]).collect();
            let spec = stft.push(&hop);
            if start < g.frame {
                continue;
            }
            for k in 0..bins {
                let r = spec.at(0, k);
                auto[k] += r.norm_sqr();
                for (m, cr) in cross.iter_mut().enumerate() {
                    cr[k] += spec.at(m, k) * r.conj();
                }
            }
        }
        let steer = if far {
            Steering::far_field(mics, &mics[0], &(source - mics[0]).normalize(), c)
        } else {
            Steering::near_field(mics, &mics[0], &source, c)
        };
        let mut a = vec![Complex::new(0.0, 0.0); mics.len()];
        let mut walk = a.clone();
        let mut step = a.clone();
        let domega = 2.0 * std::f64::consts::PI * fs / g.frame as f64;
        steer.start_walk(domega * 10.0, domega, &mut walk, &mut step);
        for k in 10..200 {
            let omega = domega * k as f64;
            steer.at(omega, &mut a);
            for m in 0..mics.len() {
                let measured = cross[m][k] / auto[k];
                assert!(
                    (measured - a[m]).norm() < 0.02,
                    "bin {k} mic {m}: measured {measured}, model {}",
                    a[m]
                );
                assert!((walk[m] - a[m]).norm() < 1e-9, "walk drifted at bin {k}");
                walk[m] *= step[m];
            }
        }
    }

    fn uca(n: usize, r: f64) -> Vec<Vec3> {
        (0..n)
            .map(|i| {
                let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                Vec3::new(2.0 + r * a.cos(), 1.5 + r * a.sin(), 1.2)
            })
            .collect()
    }

    #[test]
    fn near_field_rtf_matches_a_simulated_direct_path() {
        check_against_direct_path(&uca(8, 0.1), Vec3::new(2.6, 2.3, 1.6), false);
    }

    #[test]
    fn far_field_rtf_matches_a_distant_plane_wave() {
        check_against_direct_path(&uca(6, 0.08), Vec3::new(-40.0, 60.0, 10.0), true);
    }

    #[test]
    fn differs_measures_phase_at_the_top_frequency_and_relative_gain() {
        let mics = uca(8, 0.05);
        let c = 343.0;
        let a = Steering::near_field(&mics, &mics[0], &Vec3::new(3.5, 2.0, 1.5), c);
        assert!(!a.differs(&a, 2.0 * std::f64::consts::PI * 8000.0, 0.0));
        // A 1 mm step of a source 2.2 m away moves the relative delays by nanoseconds: within a
        // 0.01 rad tolerance at 8 kHz, but not within zero tolerance.
        let b = Steering::near_field(&mics, &mics[0], &Vec3::new(3.5, 2.001, 1.5), c);
        let omega = 2.0 * std::f64::consts::PI * 8000.0;
        assert!(!a.differs(&b, omega, 0.01));
        assert!(a.differs(&b, omega, 0.0));
        // A 10 degree turn is far outside it.
        let d = Steering::near_field(&mics, &mics[0], &Vec3::new(3.3, 2.6, 1.5), c);
        assert!(a.differs(&d, omega, 0.01));
        let mut nan = a.clone();
        nan.delays_s[3] = f64::NAN;
        assert!(a.differs(&nan, omega, 0.01));
        assert!(a.differs(&Steering::default(), omega, 0.01));
    }

    #[test]
    fn reference_entry_is_one_and_sign_is_delay_negative() {
        let mics = uca(4, 0.1);
        // Source on the +x side: mic 0 (at +x) hears it first, mic 2 (at -x) last.
        let s = Steering::near_field(&mics, &mics[0], &Vec3::new(4.0, 1.5, 1.2), 343.0);
        let mut a = vec![Complex::new(0.0, 0.0); 4];
        let omega = 2.0 * std::f64::consts::PI * 1000.0;
        s.at(omega, &mut a);
        assert!((a[0] - Complex::new(1.0, 0.0)).norm() < 1e-12);
        assert!(s.delays_s[2] > 0.0);
        // A later arrival lags in phase: e^{-j omega tau} with tau > 0.
        let expect = Complex::from_polar(1.0, -omega * s.delays_s[2]);
        assert!((a[2] / a[2].norm() - expect).norm() < 1e-9);
        assert!(a[2].norm() < 1.0);
    }
}
