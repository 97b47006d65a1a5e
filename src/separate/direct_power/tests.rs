//! Tests of the direct-path power fit: the shares of a silent label beside a reverberant talker.

use super::*;
use crate::separate::steering::Steering;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

/// Six microphones 4 cm apart on a line (the paper-linear6 array).
fn line6() -> Vec<Vec3> {
    (0..6)
        .map(|i| Vec3::new(2.9 + 0.04 * f64::from(i), 3.25, 1.95))
        .collect()
}

/// A complex Gaussian of unit power.
fn cgauss(rng: &mut StdRng) -> Complex {
    let s = std::f64::consts::FRAC_1_SQRT_2;
    Complex::new(
        s * rng.sample::<f64, _>(StandardNormal),
        s * rng.sample::<f64, _>(StandardNormal),
    )
}

/// Mean dominance of each label over `frames` snapshots: label j talks with power `powers[j]`
/// from `positions[j]`, in a diffuse field of power `diffuse` and white noise 30 dB under it.
fn mean_dominances(positions: &[Vec3], powers: &[f64], diffuse: f64, frames: usize) -> Vec<f64> {
    mean_dominances_with(positions, powers, diffuse, frames, (false, f64::INFINITY))
}

/// [`mean_dominances`] with the fit's low band on or off, the labels talking only below `top_hz`.
fn mean_dominances_with(
    positions: &[Vec3],
    powers: &[f64],
    diffuse: f64,
    frames: usize,
    (low_band, top_hz): (bool, f64),
) -> Vec<f64> {
    let mics = line6();
    let (c, hz_per_bin, bins) = (343.0, 15.625, 513);
    let mut fit = DirectPowerFit::new(&mics, c, hz_per_bin, bins, low_band);
    let reference = mics[0];
    let steer: Vec<Steering> = positions
        .iter()
        .map(|p| Steering::near_field(&mics, &reference, p, c))
        .collect();
    let n = positions.len();
    let m = mics.len();
    let mut rng = StdRng::seed_from_u64(3);
    let mut sums = vec![0.0; n];
    let mut a = vec![Complex::new(0.0, 0.0); n * m];
    let level = diffuse * 1.001 + powers.iter().sum::<f64>();
    for frame in 0..frames {
        fit.begin(n, level);
        for k in (fit.k0..fit.k1).step_by(BIN_STRIDE) {
            let omega = std::f64::consts::TAU * hz_per_bin * k as f64;
            for (j, s) in steer.iter().enumerate() {
                s.at(omega, &mut a[j * m..(j + 1) * m]);
            }
            // Diffuse field: L w with Gamma = L L^T (a small ridge keeps it positive definite).
            let b = (k - fit.k0) / BIN_STRIDE;
            let gamma = &fit.coherence[b * m * m..(b + 1) * m * m];
            let l = cholesky_real(gamma, m, 1e-6);
            let w: Vec<Complex> = (0..m).map(|_| cgauss(&mut rng)).collect();
            let mut y: Vec<Complex> = (0..m)
                .map(|i| (0..=i).map(|q| w[q] * l[i * m + q]).sum::<Complex>() * diffuse.sqrt())
                .collect();
            let talking = if hz_per_bin * (k as f64) < top_hz {
                1.0
            } else {
                0.0
            };
            for (j, &p) in powers.iter().enumerate() {
                let s = cgauss(&mut rng) * (talking * p).sqrt();
                for (yi, ai) in y.iter_mut().zip(&a[j * m..(j + 1) * m]) {
                    *yi += ai * s;
                }
            }
            for yi in &mut y {
                *yi += cgauss(&mut rng) * (1e-3 * diffuse).sqrt();
            }
            fit.observe(k, &y, &a, frame == 0);
        }
        for (acc, j) in sums.iter_mut().zip(0..n) {
            *acc += fit.dominance(j).expect("every bin holds the diffuse field");
        }
    }
    sums.iter().map(|s| s / frames as f64).collect()
}

/// Lower Cholesky factor of the real symmetric `m x m` matrix `g` plus `ridge` on the diagonal
/// (the upper triangle left as it was, unread).
fn cholesky_real(g: &[f64], m: usize, ridge: f64) -> Vec<f64> {
    let mut l = g.to_vec();
    for j in 0..m {
        l[j * m + j] += ridge;
    }
    assert!(crate::separate::cholesky::factor(&mut l, m));
    l
}

/// A point `r` m from the line's centre, `deg` degrees from its axis, at the line's height.
fn at(deg: f64, r: f64) -> Vec3 {
    let a = deg.to_radians();
    Vec3::new(3.0, 3.25, 1.95) + Vec3::new(r * a.cos(), r * a.sin(), 0.0)
}

#[test]
fn a_silent_label_beside_a_reverberant_talker_rarely_dominates_a_bin() {
    // A talker 2.5 m away at 62 degrees whose reverberation carries as much power as its
    // direct path, and a silent label 1.3 m away at 85 degrees.
    let talker = at(62.0, 2.5);
    let silent = at(85.0, 1.3);
    let alone = mean_dominances(&[silent, talker], &[0.0, 1.0], 1.0, 100);
    assert!(alone[0] < 0.02, "{alone:?}");
    assert!(alone[1] > 0.3, "{alone:?}");
    // The same label talking 5 dB below the far talker dominates the few bins where its voice
    // is the stronger, several times as many as the silent label's chance ones (about 0.06
    // against 0.017; its power share was 0.15 against 0.09).
    let quiet = mean_dominances(&[silent, talker], &[0.3, 1.0], 1.0, 100);
    assert!(quiet[0] > 2.5 * alone[0], "{quiet:?} against {alone:?}");
}

#[test]
fn a_talker_silent_above_1_khz_dominates_only_with_the_low_band() {
    // A dark vowel 1.5 m away at 110 degrees and a silent label at 62 degrees, in a weak
    // diffuse field: above 1 kHz there is nothing of the talker to measure.
    let labels = [at(110.0, 1.5), at(62.0, 1.5)];
    let off = mean_dominances_with(&labels, &[1.0, 0.0], 0.1, 60, (false, 1000.0));
    let on = mean_dominances_with(&labels, &[1.0, 0.0], 0.1, 60, (true, 1000.0));
    // Without it neither label dominates what the diffuse field leaves above 1 kHz (each by
    // chance in about 6 % of the bins).
    assert!(off[0] < 0.1 && off[1] < 0.1, "{off:?}");
    // With it the talker dominates the low band's bins and the silent label hardly any (about
    // 0.53 and 0.03).
    assert!(on[0] > 0.3 && on[1] < 0.25 * on[0], "{on:?}");
    // A talker with power in both bands dominates in both.
    let both_off = mean_dominances_with(&labels, &[1.0, 0.0], 0.1, 60, (false, f64::INFINITY));
    let both_on = mean_dominances_with(&labels, &[1.0, 0.0], 0.1, 60, (true, f64::INFINITY));
    assert!(
        both_on[0] > 0.5 * both_off[0] && both_on[1] < 0.25 * both_on[0],
        "{both_on:?} against {both_off:?}"
    );
}

/// One frame of two labels on every bin of the fit, each microphone reading `value`, in a frame
/// whose mean power per bin is `level`.
fn uniform_frame(fit: &mut DirectPowerFit, level: f64, value: f64, rebuild: bool) {
    let m = fit.m;
    let a = vec![Complex::new(1.0, 0.0); 2 * m];
    fit.begin(2, level);
    for k in fit.k0..fit.k1 {
        fit.observe(k, &vec![Complex::new(value, 0.0); m], &a, rebuild);
    }
}

#[test]
fn a_band_with_nothing_in_it_is_no_measurement() {
    let mut fit = DirectPowerFit::new(&line6(), 343.0, 15.625, 513, false);
    // A frame whose power is all below 1 kHz leaves numerical residue in the band.
    uniform_frame(&mut fit, 1.0, 1e-5, true);
    assert_eq!((fit.dominance(0), fit.dominance(1)), (None, None));
    // The same residue in a frame as quiet as it is a measurement.
    uniform_frame(&mut fit, 1e-10, 1e-5, false);
    assert!(fit.dominance(0).is_some());
}

#[test]
fn degenerate_input_gives_no_dominance_not_nan() {
    let mut fit = DirectPowerFit::new(&line6(), 343.0, 15.625, 513, true);
    uniform_frame(&mut fit, 0.0, 0.0, true);
    assert_eq!(
        (fit.dominance(0), fit.dominance(1), fit.dominance(5)),
        (None, None, None)
    );
    uniform_frame(&mut fit, f64::NAN, f64::NAN, false);
    assert_eq!((fit.dominance(0), fit.dominance(1)), (None, None));
}
