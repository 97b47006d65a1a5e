//! Each pair's GCC at the integer lags, decomposed over the sub-bands of the band.
//!
//! The GCC at lag n is linear in the cross-spectrum: r(n) = 2 Re sum_k X_k e^{j 2 pi k n / N}
//! (the band holds neither DC nor Nyquist). When the bins are weighted by a mask that is
//! constant over sub-bands of `width` bins, r(n) = sum_b g_b r_b(n) with r_b the sub-band's own
//! contribution. The localiser removes found sources by such masks several times per frame;
//! with the r_b computed once per frame, each removal costs one weighted sum per lag instead of
//! an inverse FFT per pair.
//!
//! r_b(n) = 2 Re(e^{j 2 pi k_b n / N} sum_i X_{k_b + i} e^{j 2 pi i n / N}): two small phasor
//! tables (sub-band starts by lags, in-band offsets by lags) serve every pair and frame.

use std::f64::consts::PI;

use crate::dsp::Complex;

/// Lags summed together in [`SubbandLags::rebuild`]: one AVX-512 register of f64 (two AVX2
/// ones), few enough that the sums stay in registers.
pub(super) const LAG_BLOCK: usize = 8;

/// Sub-band lag contributions of every pair, with their bin norms.
pub(crate) struct SubbandLags {
    /// Bins per sub-band (the last one may be shorter).
    pub width: usize,
    /// Sub-bands in the band.
    pub count: usize,
    /// Integer lags, from -span to +span.
    lags: usize,
    /// `lags` rounded up to whole [`LAG_BLOCK`]s (the padding lags are computed and ignored).
    stride: usize,
    /// Per in-band offset i < width and lag: e^{j 2 pi i n / N}, real and imaginary parts.
    offset_re: Vec<f64>,
    offset_im: Vec<f64>,
    /// Per sub-band and lag: e^{j 2 pi k_b n / N}.
    start_re: Vec<f64>,
    start_im: Vec<f64>,
    /// Per pair, sub-band and lag: r_b(n).
    values: Vec<f64>,
    /// Per pair and sub-band: the bin norms summed over the sub-band (first and second).
    norm1: Vec<f64>,
    norm2: Vec<f64>,
}

impl SubbandLags {
    /// Tables for sub-bands of `width` bins over `band` (inclusive bins of an N = `frame` FFT),
    /// `pairs` pairs and lags -`span`..=`span`.
    pub fn new(
        band: (usize, usize),
        width: usize,
        frame: usize,
        pairs: usize,
        span: usize,
    ) -> Self {
        let nb = band.1 + 1 - band.0;
        let width = width.clamp(1, nb.max(1));
        let count = nb.div_ceil(width);
        let lags = 2 * span + 1;
        let stride = lags.next_multiple_of(LAG_BLOCK);
        // Phases reduced modulo N before scaling, so large k n stay exact.
        let phasor = |k: usize, l: usize| {
            let n = l as i64 - span as i64;
            let kn = (k as i64 * n).rem_euclid(frame as i64);
            Complex::from_polar(1.0, 2.0 * PI * kn as f64 / frame as f64)
        };
        let (mut offset_re, mut offset_im) = (Vec::new(), Vec::new());
        for i in 0..width {
            for l in 0..stride {
                let z = phasor(i, l);
                offset_re.push(z.re);
                offset_im.push(z.im);
            }
        }
        let (mut start_re, mut start_im) = (Vec::new(), Vec::new());
        for b in 0..count {
            for l in 0..stride {
                let z = phasor(band.0 + b * width, l);
                start_re.push(z.re);
                start_im.push(z.im);
            }
        }
        Self {
            width,
            count,
            lags,
            stride,
            offset_re,
            offset_im,
            start_re,
            start_im,
            values: vec![0.0; pairs * count * stride],
            norm1: vec![0.0; pairs * count],
            norm2: vec![0.0; pairs * count],
        }
    }

    /// Recomputes pair `q`'s contributions from its band cross-spectrum and bin norms.
    pub fn rebuild(&mut self, q: usize, cross: &[Complex], norm1: &[f64], norm2: &[f64]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU supports AVX-512F, checked just above.
            unsafe { self.rebuild_avx512(q, cross) };
        } else if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            unsafe { self.rebuild_avx2(q, cross) };
        } else {
            self.rebuild_lags(q, cross);
        }
        #[cfg(not(target_arch = "x86_64"))]
        self.rebuild_lags(q, cross);
        let (w, count) = (self.width, self.count);
        for b in 0..count {
            let (k0, k1) = (b * w, ((b + 1) * w).min(cross.len()));
            self.norm1[q * count + b] = norm1[k0..k1].iter().sum();
            self.norm2[q * count + b] = norm2[k0..k1].iter().sum();
        }
    }

    /// [`SubbandLags::rebuild_lags`] compiled for AVX-512 (eight lanes; the same operations in
    /// the same order, so the same result).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn rebuild_avx512(&mut self, q: usize, cross: &[Complex]) {
        self.rebuild_lags(q, cross);
    }

    /// [`SubbandLags::rebuild_lags`] compiled for AVX2 (four lanes instead of two, the same
    /// operations in the same order, so the same result).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn rebuild_avx2(&mut self, q: usize, cross: &[Complex]) {
        self.rebuild_lags(q, cross);
    }

    #[inline(always)]
    fn rebuild_lags(&mut self, q: usize, cross: &[Complex]) {
        let (nl, w, count) = (self.stride, self.width, self.count);
        let Self {
            offset_re,
            offset_im,
            start_re,
            start_im,
            values,
            ..
        } = self;
        for b in 0..count {
            let k0 = b * w;
            let bins = &cross[k0..(k0 + w).min(cross.len())];
            let out = &mut values[(q * count + b) * nl..(q * count + b + 1) * nl];
            // One block of lags at a time, its sums kept in registers over the sub-band's bins
            // (each lag's sum still runs over the bins in order).
            for l0 in (0..nl).step_by(LAG_BLOCK) {
                let (mut acc_re, mut acc_im) = ([0.0f64; LAG_BLOCK], [0.0f64; LAG_BLOCK]);
                for (i, c) in bins.iter().enumerate() {
                    let at = i * nl + l0;
                    let zr = &offset_re[at..at + LAG_BLOCK];
                    let zi = &offset_im[at..at + LAG_BLOCK];
                    for l in 0..LAG_BLOCK {
                        acc_re[l] += c.re * zr[l] - c.im * zi[l];
                        acc_im[l] += c.re * zi[l] + c.im * zr[l];
                    }
                }
                let sr = &start_re[b * nl + l0..b * nl + l0 + LAG_BLOCK];
                let si = &start_im[b * nl + l0..b * nl + l0 + LAG_BLOCK];
                let o = &mut out[l0..l0 + LAG_BLOCK];
                for l in 0..LAG_BLOCK {
                    o[l] = 2.0 * (sr[l] * acc_re[l] - si[l] * acc_im[l]);
                }
            }
        }
    }

    /// Pair `q`'s GCC at every lag with sub-band `b` weighted by `gains[b]` (by one with `None`;
    /// sub-bands past a short `gains` count for nothing), into `out`; returns
    /// the weighted bin norms (sum g n1, sum g^2 n2).
    pub fn combine(&self, q: usize, gains: Option<&[f64]>, out: &mut [f64]) -> (f64, f64) {
        let (nl, stride) = (self.lags, self.stride);
        let out = &mut out[..nl];
        out.fill(0.0);
        let (mut t1, mut t2) = (0.0, 0.0);
        for b in 0..self.count {
            let g = match gains.map(|g| g.get(b)) {
                None => 1.0,
                Some(Some(&g)) => g,
                Some(None) => break,
            };
            let i = q * self.count + b;
            t1 += g * self.norm1[i];
            t2 += g * g * self.norm2[i];
            if g == 0.0 {
                continue;
            }
            for (o, v) in out
                .iter_mut()
                .zip(&self.values[i * stride..i * stride + nl])
            {
                *o += g * v;
            }
        }
        (t1, t2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// r(n) = 2 Re sum_k g_{b(k)} X_k e^{j 2 pi k n / N}, term by term.
    fn direct(
        band: (usize, usize),
        width: usize,
        frame: usize,
        x: &[Complex],
        g: &[f64],
        n: i64,
    ) -> f64 {
        (band.0..=band.1)
            .map(|k| {
                let gain = g[(k - band.0) / width];
                let ph = 2.0 * PI * (k as i64 * n).rem_euclid(frame as i64) as f64 / frame as f64;
                2.0 * gain * (x[k - band.0] * Complex::from_polar(1.0, ph)).re
            })
            .sum()
    }

    #[test]
    fn masked_lags_equal_the_masked_inverse_transform() {
        let (band, width, frame, span) = ((192, 767), 8, 2048, 15);
        let nb = band.1 + 1 - band.0;
        // Deterministic pseudo-random cross-spectra and gains (a short last sub-band included).
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut sub = SubbandLags::new(band, width, frame, 2, span);
        assert_eq!(sub.count, nb.div_ceil(width));
        let x: Vec<Complex> = (0..2 * nb).map(|_| Complex::new(next(), next())).collect();
        let n1: Vec<f64> = (0..nb).map(|_| next().abs()).collect();
        let n2: Vec<f64> = n1.iter().map(|v| v * v).collect();
        for q in 0..2 {
            sub.rebuild(q, &x[q * nb..(q + 1) * nb], &n1, &n2);
        }
        let g: Vec<f64> = (0..sub.count)
            .map(|b| if b % 5 == 0 { 0.0 } else { next() + 0.5 })
            .collect();
        let mut out = vec![0.0; 2 * span + 1];
        for q in 0..2 {
            let (t1, t2) = sub.combine(q, Some(&g), &mut out);
            for (i, got) in out.iter().enumerate() {
                let want = direct(
                    band,
                    width,
                    frame,
                    &x[q * nb..(q + 1) * nb],
                    &g,
                    i as i64 - span as i64,
                );
                assert!(
                    (got - want).abs() < 1e-9 * (1.0 + want.abs()),
                    "pair {q} lag {i}: {got} vs {want}"
                );
            }
            let w1: f64 = (0..nb).map(|k| g[k / width] * n1[k]).sum();
            let w2: f64 = (0..nb).map(|k| g[k / width].powi(2) * n2[k]).sum();
            assert!((t1 - w1).abs() < 1e-9 * w1 && (t2 - w2).abs() < 1e-9 * w2);
        }
    }
}
