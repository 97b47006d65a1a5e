//! The kernels that tabulate a pair's GCC on the fine lag grid: the Kaiser-windowed sinc that
//! interpolates between integer lags, and the band's own response to a lag offset.

use std::f64::consts::PI;

/// Sinc taps on each side of the interpolation point.
pub(super) const SINC_TAPS: usize = 8;
/// Kaiser window shape of the interpolation kernel.
const KAISER_BETA: f64 = 8.0;

/// Zeroth-order modified Bessel function of the first kind (power series).
fn bessel_i0(x: f64) -> f64 {
    let mut sum = 1.0;
    let mut term = 1.0;
    let q = x * x / 4.0;
    for k in 1..64 {
        term *= q / (k * k) as f64;
        sum += term;
        if term < sum * 1e-16 {
            break;
        }
    }
    sum
}

/// Kaiser-windowed sinc evaluated at `x` samples from the interpolation point.
pub(super) fn sinc_kernel(x: f64) -> f64 {
    let k = SINC_TAPS as f64;
    if x.abs() >= k {
        return 0.0;
    }
    let sinc = if x.abs() < 1e-12 {
        1.0
    } else {
        (PI * x).sin() / (PI * x)
    };
    let r = x / k;
    sinc * bessel_i0(KAISER_BETA * (1.0 - r * r).sqrt()) / bessel_i0(KAISER_BETA)
}

/// Mean over bins k in `band` of cos(2 pi k d / frame), for a lag of `d` samples (closed form of
/// the sum of cosines in arithmetic progression).
pub(super) fn band_kernel(band: (usize, usize), frame: usize, d: f64) -> f64 {
    let n = (band.1 + 1 - band.0) as f64;
    let b = 2.0 * PI * d / frame as f64;
    let half = (b / 2.0).sin();
    if half.abs() < 1e-12 {
        return 1.0;
    }
    let a = b * band.0 as f64;
    (n * b / 2.0).sin() / half * (a + (n - 1.0) * b / 2.0).cos() / n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sinc_interpolates_integer_lags_exactly_and_vanishes_beyond_its_taps() {
        assert!((sinc_kernel(0.0) - 1.0).abs() < 1e-12);
        for n in 1..SINC_TAPS + 2 {
            assert!(sinc_kernel(n as f64).abs() < 1e-12, "lag {n}");
            assert_eq!(sinc_kernel(-(n as f64)), sinc_kernel(n as f64));
        }
        assert_eq!(sinc_kernel(SINC_TAPS as f64 + 0.5), 0.0);
        // Half-way between lags the sinc is 2 / pi; the window, below 1 off its centre, takes
        // a little of it.
        let half = sinc_kernel(0.5);
        assert!(half < 2.0 / PI && half > 2.0 / PI - 0.03, "{half}");
    }

    #[test]
    fn the_band_kernel_is_the_mean_cosine_over_the_band() {
        let (band, frame) = ((12usize, 200usize), 1024usize);
        for d in [0.0, 0.3, 1.0, 2.7, -4.2, 17.0] {
            let n = (band.1 + 1 - band.0) as f64;
            let direct: f64 = (band.0..=band.1)
                .map(|k| (2.0 * PI * k as f64 * d / frame as f64).cos())
                .sum::<f64>()
                / n;
            assert!(
                (band_kernel(band, frame, d) - direct).abs() < 1e-9,
                "lag {d}"
            );
        }
    }
}
