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
    band: (bool, f64),
) -> Vec<f64> {
    let (mics, cosine) = (line6(), LOW_BAND_MAX_COSINE);
    mean_dominances_counting(&mics, (positions, powers), diffuse, frames, band, cosine)
}

/// Eight microphones on a circle of 10 cm radius round the line's centre (a `two-arrays` array).
fn circle8() -> Vec<Vec3> {
    (0..8)
        .map(|i| {
            let a = std::f64::consts::TAU * f64::from(i) / 8.0;
            Vec3::new(3.0 + 0.1 * a.cos(), 3.25 + 0.1 * a.sin(), 1.95)
        })
        .collect()
}

/// [`mean_dominances_with`] on microphones `mics`, the low band counting a label's bin below
/// `max_cosine`.
fn mean_dominances_counting(
    mics: &[Vec3],
    (positions, powers): (&[Vec3], &[f64]),
    diffuse: f64,
    frames: usize,
    (low_band, top_hz): (bool, f64),
    max_cosine: f64,
) -> Vec<f64> {
    let (c, hz_per_bin, bins) = (343.0, 15.625, 513);
    let mut fit = DirectPowerFit::new(mics, c, hz_per_bin, bins, low_band);
    fit.low_band_max_cosine = max_cosine;
    let reference = mics[0];
    let steer: Vec<Steering> = positions
        .iter()
        .map(|p| Steering::near_field(mics, &reference, p, c))
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
    // diffuse field: above 1 kHz there is nothing of the talker to measure. A 10 cm circle of
    // eight resolves both labels and the diffuse field from about 400 Hz.
    let (mics, cosine) = (circle8(), LOW_BAND_MAX_COSINE);
    let labels = [at(110.0, 1.5), at(62.0, 1.5)];
    let dominances = |low_band: bool, top_hz: f64| {
        let scene = (&labels[..], &[1.0, 0.0][..]);
        mean_dominances_counting(&mics, scene, 0.1, 60, (low_band, top_hz), cosine)
    };
    let (off, on) = (dominances(false, 1000.0), dominances(true, 1000.0));
    // Without it neither label dominates what the diffuse field leaves above 1 kHz (each by
    // chance in under 1 % of the bins).
    assert!(off[0] < 0.1 && off[1] < 0.1, "{off:?}");
    // With it the talker dominates the low band's bins and the silent label hardly any (about
    // 0.49 and 0.001).
    assert!(on[0] > 0.3 && on[1] < 0.25 * on[0], "{on:?}");
    // A talker with power in both bands dominates in both.
    let (both_off, both_on) = (
        dominances(false, f64::INFINITY),
        dominances(true, f64::INFINITY),
    );
    assert!(
        both_on[0] > 0.5 * both_off[0] && both_on[1] < 0.25 * both_on[0],
        "{both_on:?} against {both_off:?}"
    );
}

#[test]
fn the_low_band_counts_a_label_only_where_the_array_tells_it_from_the_others() {
    // A talker with nothing above 1 kHz at 62 degrees and a silent label 10 degrees from it,
    // in a weak diffuse field: a 20 cm line tells neither label from the other, nor from the
    // diffuse field, below about 750 Hz.
    let labels = [at(62.0, 1.5), at(72.0, 1.5)];
    let band = (true, 1000.0);
    let scene = (&labels[..], &[1.0, 0.0][..]);
    let all = mean_dominances_counting(&line6(), scene, 0.1, 60, band, 1.0);
    let resolved = mean_dominances_with(&labels, &[1.0, 0.0], 0.1, 60, band);
    // Counting every bin, the silent label takes a share of the talker's bins (about 0.07
    // against the talker's 0.40). Counted only where resolved, the low band says little about
    // either: each keeps about the main band's chance share, 0.02.
    assert!(all[1] > 0.05 && all[0] > 0.3, "{all:?}");
    assert!(resolved[1] < 0.5 * all[1], "{resolved:?}");
    // On the circle a label far from the talker keeps its low band (about 0.49 against 0.001).
    let apart = [at(62.0, 1.5), at(120.0, 1.5)];
    let scene = (&apart[..], &[1.0, 0.0][..]);
    let far = mean_dominances_counting(&circle8(), scene, 0.1, 60, band, LOW_BAND_MAX_COSINE);
    assert!(far[0] > 0.3 && far[1] < 0.25 * far[0], "{far:?}");
}

#[test]
fn resolved_labels_reads_the_cosines_of_the_gram_matrix() {
    // Three labels and the diffuse term, each of norm 2: labels 0 and 1 nearly collinear
    // (cosine 0.9), label 2 apart from both, every label at cosine 0.3 from the diffuse term.
    let (n, nn) = (3, 4);
    let mut gram = vec![0.0; nn * nn];
    let set = |g: &mut [f64], i: usize, j: usize, v: f64| {
        g[i * nn + j] = v;
        g[j * nn + i] = v;
    };
    for i in 0..nn {
        set(&mut gram, i, i, 4.0);
    }
    set(&mut gram, 0, 1, 3.6);
    set(&mut gram, 0, 2, 0.4);
    for i in 0..n {
        set(&mut gram, i, n, 1.2);
    }
    assert_eq!(resolved_labels(&gram, n, 0.8), 0b100);
    assert_eq!(resolved_labels(&gram, n, 0.95), 0b111);
    // A label alike with the diffuse field (a small array's low bins) is not resolved either.
    set(&mut gram, 2, n, 3.6);
    assert_eq!(resolved_labels(&gram, n, 0.8), 0b000);
    assert_eq!(resolved_labels(&gram, n, 0.95), 0b111);
    // A zero column (no steering) is never counted, and its NaN cosines do not stop the others.
    set(&mut gram, 2, 2, 0.0);
    set(&mut gram, 0, 2, 0.0);
    set(&mut gram, 2, n, 0.0);
    assert_eq!(resolved_labels(&gram, n, 0.95), 0b011);
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
