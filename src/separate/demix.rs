//! Demixing of the labels' output powers through their fixed beamformers' known power
//! cross-responses, for the post-filter's low band.
//!
//! Label i's beamformer passes label j's talker with power response R_ij = |w_i^H a_j|^2. The
//! smoothed output powers p are then about R phi, with phi >= 0 the talkers' own powers. Where R
//! is far from the identity (closely spaced labels at low frequencies, where one label's loaded
//! null-steering beamformer passes its neighbours whole), comparing p favours that label; phi
//! does not.
//!
//! phi solves min |R phi - p|^2 + lambda |phi - p|^2 over phi >= 0. The second term is a ridge
//! toward the output powers themselves: in the directions R cannot tell apart (every label's
//! beamformer alike, at the lowest bins) the answer stays with the powers as measured instead of
//! an arbitrary split. lambda = `ridge` * trace(R^T R) / n, so the ridge is relative.
//!
//! The problem is a small strictly convex quadratic programme, solved exactly by the active-set
//! method ([`Nnls`]) on its normal equations, started from the bin's support in the last frame
//! (one Cholesky solve when that support still holds).

use super::nnls::Nnls;

/// Most labels demixed at a bin (more leave the powers as they are).
pub const MAX_DEMIXED: usize = 16;

/// The ridge toward the measured powers, relative to the mean eigenvalue of R^T R. 1e-4 and 1e-2
/// gave the same within 0.04 dB (full pipeline, paper-linear6 and uca8).
pub const DEMIX_RIDGE: f64 = 1e-3;

/// A bin is demixed only where some label's beamformer passes another label's talker at this
/// fraction of that label's own response or more ([`Demixing::powers`]). Against demixing every
/// bin below the top (full pipeline, SI-SDRi / streams / lost blocks): uca8 three talkers seeds
/// 1-18 +9.07 / 1.167 / 61 against +9.03 / 1.167 / 63, recorded seeds 1-12 +6.29 / 1.250 / 40
/// against +6.26 / 1.250 / 41 (the whole cost of the demixing there); paper-linear6, whose
/// middle label passes both outer talkers at 0.9-1.1 below 300 Hz, unchanged to the printed
/// digit on seeds 1-48, recorded 1-36 and held-out 49-72, recorded 37-52 +6.61 against +6.59
/// dB. 0.5 changed nothing; 1.0 cost paper-linear6's held-out seeds 2 blocks (1.236 against
/// 1.208). On uca8 seeds not used to choose it (19-30, recorded 13-20) it is the same within
/// noise: +9.80 and +7.66 dB against +9.83 and +7.64 demixing every bin (+9.77 and +7.65
/// without the demixing). It also spares the solve in the bins it skips.
pub const DEMIX_MIN_LEAK: f64 = 0.9;

/// Power cross-responses of loaded null-steering beamformers at 100 Hz on paper-linear6's 20 cm
/// array, labels at -25, 3 and 25 degrees: the middle label passes both outer talkers.
#[cfg(test)]
pub(crate) const CROSS_100_HZ: [f64; 9] = [1.0, 0.36, 0.09, 0.90, 1.0, 1.08, 0.10, 0.49, 1.0];

/// What the post-filter needs to demix one bin: the beamformers' power cross-responses
/// (row-major n x n: row i is label i's beamformer's response toward each label), the solver's
/// scratch, and the bin's last support (which labels had power; the next solve starts there).
pub struct Demixing<'a> {
    /// The power cross-responses.
    pub cross: &'a [f64],
    /// The solver, reused across bins.
    pub solver: &'a mut Nnls,
    /// The bin's support from the last frame (bit j: label j's power was positive).
    pub support: &'a mut u32,
}

impl Demixing<'_> {
    /// The labels' own powers phi >= 0 (module doc) from their output powers `powers`, with
    /// the ridge `ridge`. `None`, leaving the raw powers to the caller, where no beamformer
    /// passes another label's talker at [`DEMIX_MIN_LEAK`] of its own response, or when
    /// `cross` is too short, there are more than [`MAX_DEMIXED`] labels, R is zero or the
    /// numbers are not finite.
    pub fn powers(&mut self, powers: &[f64], ridge: f64) -> Option<&[f64]> {
        let (cross, n) = (self.cross, powers.len());
        if n == 0 || n > MAX_DEMIXED || cross.len() < n * n {
            return None;
        }
        if !powers.iter().chain(&cross[..n * n]).all(|v| v.is_finite()) {
            return None;
        }
        if !biased(cross, n) {
            return None;
        }
        let mut a = [0.0; MAX_DEMIXED * MAX_DEMIXED];
        let mut b = [0.0; MAX_DEMIXED];
        let mut trace = 0.0;
        for i in 0..n {
            for j in i..n {
                let v: f64 = (0..n).map(|q| cross[q * n + i] * cross[q * n + j]).sum();
                a[i * n + j] = v;
                a[j * n + i] = v;
            }
            trace += a[i * n + i];
        }
        let lambda = ridge * trace / n as f64;
        if !(trace > 0.0 && lambda.is_finite()) {
            return None;
        }
        for i in 0..n {
            a[i * n + i] += lambda;
            b[i] = (0..n).map(|q| cross[q * n + i] * powers[q]).sum::<f64>() + lambda * powers[i];
        }
        let phi = self.solver.solve(&a[..n * n], &b[..n], n, self.support);
        phi.iter().all(|v| v.is_finite()).then_some(phi)
    }
}

/// Whether some label's beamformer passes another label's talker at [`DEMIX_MIN_LEAK`] or more of
/// that label's own response, which is where comparing raw output powers can hand the talker's
/// bin to the wrong label. Elsewhere the raw comparison is kept: the model p = R phi leaves out
/// the room's reverberation and noise, and demixing there only adds its error.
fn biased(cross: &[f64], n: usize) -> bool {
    (0..n).any(|j| {
        let own = cross[j * n + j];
        (0..n).any(|i| i != j && cross[i * n + j] >= DEMIX_MIN_LEAK * own)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Demixes `p` from a cold start into `out`; false when refused.
    fn demix(cross: &[f64], p: &[f64], ridge: f64, out: &mut [f64]) -> bool {
        demix_from(cross, p, ridge, 0, out)
    }

    fn demix_from(cross: &[f64], p: &[f64], ridge: f64, mut support: u32, out: &mut [f64]) -> bool {
        let mut solver = Nnls::default();
        let mut d = Demixing {
            cross,
            solver: &mut solver,
            support: &mut support,
        };
        match d.powers(p, ridge) {
            Some(phi) => {
                out[..phi.len()].copy_from_slice(phi);
                true
            }
            None => false,
        }
    }

    fn mix(cross: &[f64], phi: &[f64]) -> Vec<f64> {
        let n = phi.len();
        (0..n)
            .map(|i| (0..n).map(|j| cross[i * n + j] * phi[j]).sum())
            .collect()
    }

    #[test]
    fn an_outer_talkers_power_comes_back_from_the_middle_label() {
        let phi = [0.0, 0.0, 1.0];
        let p = mix(&CROSS_100_HZ, &phi);
        // The middle label's output is the loudest.
        assert!(p[1] > p[2]);
        let mut out = [0.0; 3];
        assert!(demix(&CROSS_100_HZ, &p, DEMIX_RIDGE, &mut out));
        // The ridge pulls it 1 % toward the measured powers.
        for (o, t) in out.iter().zip(phi) {
            assert!((o - t).abs() < 0.02, "{out:?}");
        }
        // Without the ridge the recovery is exact but for the solver's own 1e-6 one.
        assert!(demix(&CROSS_100_HZ, &p, 0.0, &mut out));
        for (o, t) in out.iter().zip(phi) {
            assert!((o - t).abs() < 1e-5, "{out:?}");
        }
    }

    #[test]
    fn where_the_beamformers_are_alike_the_measured_powers_stay() {
        // Every beamformer passes every talker whole: nothing can be undone.
        let cross = [1.0; 9];
        let p = [0.2, 1.0, 0.5];
        let mut out = [0.0; 3];
        assert!(demix(&cross, &p, DEMIX_RIDGE, &mut out));
        // The part R sees (the sum, which every output carries) is fitted to the mean output;
        // the differences R cannot see stay as measured. The quietest label takes the bound.
        let mean = p.iter().sum::<f64>() / 3.0;
        assert!((out.iter().sum::<f64>() - mean).abs() < 0.01, "{out:?}");
        assert!(((out[1] - out[2]) - (p[1] - p[2])).abs() < 0.01, "{out:?}");
        assert_eq!(out[0], 0.0);
    }

    #[test]
    fn only_beamformers_that_pass_a_neighbour_whole_are_undone_and_bad_input_is_refused() {
        let eye = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let p = [0.3, 0.0, 2.0];
        let mut kept = [7.0; 3];
        // Nulls, or a neighbour passed at half its own response: the raw powers stay.
        assert!(!demix(&eye, &p, DEMIX_RIDGE, &mut kept));
        let half = [1.0, 0.5, 0.1, 0.5, 1.0, 0.5, 0.1, 0.5, 1.0];
        assert!(!demix(&half, &p, DEMIX_RIDGE, &mut kept));
        // One beamformer passing a neighbour at 0.9 of its own response is enough.
        let mut leaky = half;
        leaky[2] = 0.9;
        assert!(demix(&leaky, &p, DEMIX_RIDGE, &mut [0.0; 3]));
        assert!(!demix(&CROSS_100_HZ[..4], &p, DEMIX_RIDGE, &mut kept));
        assert!(!demix(&[0.0; 9], &p, DEMIX_RIDGE, &mut kept));
        assert!(!demix(
            &CROSS_100_HZ,
            &[f64::NAN, 1.0, 1.0],
            DEMIX_RIDGE,
            &mut kept
        ));
        assert_eq!(kept, [7.0; 3]);
    }

    proptest! {
        /// The answer meets the bound problem's optimality conditions (phi >= 0, the gradient
        /// A phi - b zero on the positive powers and not negative on those at the bound), from
        /// any warm start.
        #[test]
        fn the_answer_is_the_constrained_optimum(
            n in 1usize..6,
            cross in prop::collection::vec(0.0f64..1.5, 36),
            powers in prop::collection::vec(0.0f64..10.0, 6),
            ridge in prop::sample::select(vec![0.0, 1e-3, 1e-1]),
            support in 0u32..64,
        ) {
            let cross = &cross[..n * n];
            let p = &powers[..n];
            let mut out = [0.0; 6];
            let trace: f64 = cross.iter().map(|r| r * r).sum();
            prop_assume!(trace > 1e-6);
            let solved = demix_from(cross, p, ridge, support, &mut out[..n]);
            prop_assert_eq!(solved, biased(cross, n));
            if !solved {
                return Ok(());
            }
            let lambda = ridge * trace / n as f64;
            let rphi = mix(cross, &out[..n]);
            for i in 0..n {
                prop_assert!(out[i] >= 0.0);
                let col2: f64 = (0..n).map(|q| cross[q * n + i].powi(2)).sum();
                let grad: f64 = (0..n).map(|q| cross[q * n + i] * (rphi[q] - p[q])).sum::<f64>()
                    + lambda * (out[i] - p[i]);
                // The solver's own ridge (1e-6 of the diagonal) moves the optimum that much.
                let tol = 1e-5 * (col2 + lambda) * (1.0 + out[i]) + 1e-9 * (1.0 + trace);
                if out[i] > 0.0 {
                    prop_assert!(grad.abs() < tol, "label {i}: gradient {grad}");
                } else {
                    prop_assert!(grad > -tol, "label {i}: gradient {grad}");
                }
            }
        }
    }
}
