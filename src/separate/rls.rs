//! The GSC's adaptive interference canceller: complex recursive least squares per bin
//! (spec 003 eq. 31, section 6.2), minimising sum_t lambda^{n-t} |d_t - V^H u_t|^2 over the
//! blocked signals u = B^H y and the fixed-beamformer output d.
//!
//! Three additions make it safe to run unattended:
//! * a weighted step: sample weight beta in [0, 1] (adaptation control) with the forgetting slowed
//!   to lambda = 1 - (1 - gamma) beta, so a frame where the target talks neither teaches the
//!   canceller nor makes it forget;
//! * leakage: a ridge term kept in the correlation estimate by one rank-one update per step on a
//!   cycling coordinate (steady state ~ leakage * power * I), so directions that the input never
//!   excites do not let P grow like lambda^{-n};
//! * a norm bound on V (a white-noise-gain constraint), scaled back when exceeded.
//!
//! The state is single precision: the canceller's state is most of a session's memory traffic
//! (one matrix per label and bin, touched every frame), and eight f32 lanes per AVX2 register
//! do twice the work of four f64 ones. Precision is not the limit: the recursion keeps P exactly
//! Hermitian, the leakage bounds its condition number, and a bin whose P stops being positive is
//! reset. The a-priori output is accumulated in double precision.

use crate::dsp::Complex;

/// Smallest per-bin power used to scale the regularisation (input units squared); keeps the
/// inverse correlation bounded on digital silence.
pub const POWER_FLOOR: f64 = 1e-14;

/// Scalar type of the canceller's state.
pub type Real = f32;

/// Lanes of one vector register of [`Real`] (AVX2: eight f32); rows are padded to a multiple.
const LANES: usize = 8;

/// The leakage update runs on one call in this many (with a step as much larger), which keeps
/// its cost a fraction of the main update's; callers stagger `leak_index` across bins.
pub const LEAK_EVERY: usize = 4;

/// Independent accumulators of the product P u; it divides [`LANES`], so the padded rows
/// split evenly among them.
const CHAINS: usize = 4;
const _: () = assert!(LANES.is_multiple_of(CHAINS));

/// Scratch of one step per padded weight ([`adapt`]'s `scratch` holds this many times `lp`).
pub const SCRATCH_PER_LANE: usize = 2 * CHAINS;

/// Shape of one bin's canceller state: `l` weights, stored padded to `lp` (a multiple of 8) with
/// real and imaginary parts apart, so the inner loops run over contiguous equal-length rows that
/// the compiler vectorises. Layout: V re, V im (`lp` each), then P re, P im (`lp * lp` each,
/// row-major), then a scale s (and padding to keep rows aligned): the inverse correlation is
/// s P, so the division by the forgetting factor touches one number instead of the matrix.
/// Padding entries stay zero.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dims {
    /// Number of blocked channels (M - 1).
    pub l: usize,
    /// `l` rounded up to a multiple of 8.
    pub lp: usize,
}

impl Dims {
    /// Dimensions for `l` blocked channels.
    pub fn new(l: usize) -> Self {
        Self {
            l,
            lp: l.div_ceil(LANES) * LANES,
        }
    }

    /// Values of state per bin.
    pub fn stride(&self) -> usize {
        2 * self.lp + 2 * self.lp * self.lp + 4
    }
}

/// Per-step constants of the canceller.
#[derive(Debug, Clone, Copy)]
pub struct RlsStep {
    /// Forgetting factor at full adaptation.
    pub forgetting: f64,
    /// Leakage relative to the input power.
    pub leakage: f64,
    /// Upper bound on |V|^2 (absolute).
    pub max_norm2: f64,
}

/// A bin's state split into V re, V im, P re, P im and the scale of P.
type Parts<'a> = (
    &'a mut [Real],
    &'a mut [Real],
    &'a mut [Real],
    &'a mut [Real],
    &'a mut Real,
);

fn parts(state: &mut [Real], d: Dims) -> Parts<'_> {
    let (v, p) = state.split_at_mut(2 * d.lp);
    let (vr, vi) = v.split_at_mut(d.lp);
    let (p, tail) = p.split_at_mut(2 * d.lp * d.lp);
    let (pr, pi) = p.split_at_mut(d.lp * d.lp);
    (vr, vi, pr, pi, &mut tail[0])
}

/// Resets one bin's canceller: V = 0, P = I / (delta * power).
pub fn reset(state: &mut [Real], d: Dims, delta: f64, power: f64) {
    state.fill(0.0);
    let p0 = (1.0 / (delta * power.max(POWER_FLOOR))) as Real;
    let (_, _, pr, _, scale) = parts(state, d);
    for i in 0..d.l {
        pr[i * d.lp + i] = p0;
    }
    *scale = 1.0;
}

/// Trace of the inverse correlation matrix (a health measure: it stays bounded with leakage).
pub fn inverse_correlation_trace(state: &[Real], d: Dims) -> f64 {
    let p = &state[2 * d.lp..];
    let scale = f64::from(p[2 * d.lp * d.lp]);
    (0..d.l).map(|i| f64::from(p[i * d.lp + i])).sum::<f64>() * scale
}

/// The weights V of one bin (length `l`).
pub fn weights(state: &[Real], d: Dims, out: &mut [Complex]) {
    for (i, o) in out.iter_mut().enumerate().take(d.l) {
        *o = Complex::new(f64::from(state[i]), f64::from(state[d.lp + i]));
    }
}

/// A-priori output e = d - V^H u (the canceller's output with the weights before this step);
/// `ur`, `ui` are the blocked signals (length `lp`, zero padded).
pub fn output(state: &[Real], d: Dims, ur: &[Real], ui: &[Real], fixed: Complex) -> Complex {
    let (vr, vi) = (&state[..d.l], &state[d.lp..d.lp + d.l]);
    // Lane-wise partial sums (see `settle`).
    let (mut re, mut im) = ([0.0f64; 4], [0.0f64; 4]);
    for j in 0..d.l {
        // conj(v) u
        let (a, b, x, y) = (
            f64::from(vr[j]),
            f64::from(vi[j]),
            f64::from(ur[j]),
            f64::from(ui[j]),
        );
        re[j % 4] += a * x + b * y;
        im[j % 4] += a * y - b * x;
    }
    let sum = |v: [f64; 4]| (v[0] + v[1]) + (v[2] + v[3]);
    fixed - Complex::new(sum(re), sum(im))
}

/// P <- P - h h^H. h_i h_j^* and h_j h_i^* come from the same products, so a Hermitian
/// P stays exactly Hermitian without mirroring.
#[inline(always)]
fn rank_one_down(pr: &mut [Real], pi: &mut [Real], lp: usize, hr: &[Real], hi: &[Real]) {
    // With the size hidden from the optimiser the row loop stays a loop of register-wide
    // blocks; a known small size gets unrolled across rows into gathers and spills.
    let lp = std::hint::black_box(lp);
    let (hr, hi) = (&hr[..lp], &hi[..lp]);
    for i in 0..lp {
        let (ar, ai) = (hr[i], hi[i]);
        let rr = &mut pr[i * lp..(i + 1) * lp];
        let ri = &mut pi[i * lp..(i + 1) * lp];
        // Fixed register-wide blocks along the row: one vector register each, whatever lp is.
        for (((r4, i4), h4), g4) in rr
            .chunks_exact_mut(LANES)
            .zip(ri.chunks_exact_mut(LANES))
            .zip(hr.chunks_exact(LANES))
            .zip(hi.chunks_exact(LANES))
        {
            for q in 0..LANES {
                r4[q] -= ar * h4[q] + ai * g4[q];
                i4[q] -= ai * h4[q] - ar * g4[q];
            }
        }
    }
}

/// One weighted RLS step, with leakage when `leak_index` (a per-frame counter) says so. `e` is
/// the a-priori output, `power` the bin's input power, `scratch` at least
/// [`SCRATCH_PER_LANE`] times `lp` values. Returns false when the recursion produced something
/// non-finite; the caller then resets the bin.
#[allow(clippy::too_many_arguments)]
pub fn adapt(
    state: &mut [Real],
    d: Dims,
    ur: &[Real],
    ui: &[Real],
    e: Complex,
    beta: f64,
    power: f64,
    leak_index: usize,
    step: &RlsStep,
    scratch: &mut [Real],
) -> bool {
    if beta <= 0.0 || d.l == 0 {
        return true;
    }
    let args = (ur, ui, e, beta, power, leak_index, step);
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX2 and FMA, checked just above.
        return unsafe { adapt_avx2(state, d, args, scratch) };
    }
    adapt_dispatch::<Plain>(state, d, args, scratch)
}

/// [`adapt_dispatch`] compiled for AVX2 (eight lanes instead of four) with fused multiply-adds.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn adapt_avx2(state: &mut [Real], d: Dims, args: StepArgs, scratch: &mut [Real]) -> bool {
    adapt_dispatch::<Fused>(state, d, args, scratch)
}

/// a * b + c, rounded once where the CPU has fused multiply-add.
trait MulAdd {
    fn madd(a: Real, b: Real, c: Real) -> Real;
}

/// Separate multiply and add (no FMA unit assumed).
struct Plain;

impl MulAdd for Plain {
    #[inline(always)]
    fn madd(a: Real, b: Real, c: Real) -> Real {
        a * b + c
    }
}

/// Fused multiply-add; only used in code compiled with the `fma` target feature.
#[cfg(target_arch = "x86_64")]
struct Fused;

#[cfg(target_arch = "x86_64")]
impl MulAdd for Fused {
    #[inline(always)]
    fn madd(a: Real, b: Real, c: Real) -> Real {
        a.mul_add(b, c)
    }
}

#[inline(always)]
fn adapt_dispatch<F: MulAdd>(
    state: &mut [Real],
    d: Dims,
    args: StepArgs,
    scratch: &mut [Real],
) -> bool {
    // Common padded sizes get their own copy with constant loop bounds (unrolled, vectorised).
    match d.lp {
        8 => adapt_sized::<F>(state, d, 8, args, scratch),
        16 => adapt_sized::<F>(state, d, 16, args, scratch),
        lp => adapt_sized::<F>(state, d, lp, args, scratch),
    }
}

type StepArgs<'a> = (
    &'a [Real],
    &'a [Real],
    Complex,
    f64,
    f64,
    usize,
    &'a RlsStep,
);

#[inline(always)]
fn adapt_sized<F: MulAdd>(
    state: &mut [Real],
    d: Dims,
    lp: usize,
    (ur, ui, e, beta, power, leak_index, step): StepArgs,
    scratch: &mut [Real],
) -> bool {
    let (ur, ui) = (&ur[..lp], &ui[..lp]);
    let (vr, vi, pr, pi, scale) = parts(state, d);
    let (h, acc) = scratch[..2 * CHAINS * lp].split_at_mut(2 * lp);
    let (hr, hi) = h.split_at_mut(lp);
    let lam = 1.0 - (1.0 - step.forgetting) * beta;
    let sc = f64::from(*scale);
    times_p::<F>(pr, pi, lp, (ur, ui), (hr, hi), acc);
    // The conversion term u^H (sc P) u is real for a Hermitian P.
    let upu = lane_sum(lp, |i| f64::from(ur[i] * hr[i] + ui[i] * hi[i]));
    let den = lam + beta * sc * upu;
    if !(den > 0.0 && den.is_finite()) {
        return false;
    }
    // g sc with the numerator formed beside the sum, so the division follows it directly.
    let gs = (beta * sc) / den;
    // V += g (sc P u) e^*.
    let (er, ei) = ((gs * e.re) as Real, (-gs * e.im) as Real);
    for i in 0..lp {
        vr[i] = F::madd(hr[i], er, F::madd(-hi[i], ei, vr[i]));
        vi[i] = F::madd(hr[i], ei, F::madd(hi[i], er, vi[i]));
    }
    // sc P <- (sc P - g sc^2 (P u)(P u)^H) / lambda, i.e. P -= g sc (P u)(P u)^H and sc /= lambda.
    let sg = (gs as Real).sqrt();
    hr.iter_mut().chain(hi.iter_mut()).for_each(|x| *x *= sg);
    rank_one_down(pr, pi, lp, hr, hi);
    let sc = sc / lam;
    // Leakage every LEAK_EVERY-th call, with a correspondingly larger step.
    let c = step.leakage * power.max(POWER_FLOOR) * (d.l * LEAK_EVERY) as f64 * beta;
    if c > 0.0 && leak_index % LEAK_EVERY == 0 {
        let j = (leak_index / LEAK_EVERY) % d.l;
        leak((pr, pi), (vr, vi), lp, j, c, sc, (hr, hi));
    }
    settle((pr, pi), (vr, vi), scale, sc, d.l, lp, step.max_norm2)
}

/// The sum of `term(i)` over `0..len` in four lane-wise partial sums: one serial chain of f64
/// additions would cost more than the rank-one update it sits beside.
#[inline(always)]
fn lane_sum(len: usize, term: impl Fn(usize) -> f64) -> f64 {
    let mut lanes = [0.0f64; 4];
    for i in 0..len {
        lanes[i % 4] += term(i);
    }
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3])
}

/// h = P u (the true inverse correlation is sc P). P is Hermitian, so
/// (P u)_i = sum_j conj(P_ji) u_j: an axpy over contiguous rows. (The Hermitian structure of
/// P only matters in its own update, so fused products are fine here.) `acc` holds
/// `2 (CHAINS - 1) lp` values of scratch.
#[inline(always)]
fn times_p<F: MulAdd>(
    pr: &[Real],
    pi: &[Real],
    lp: usize,
    (ur, ui): (&[Real], &[Real]),
    (hr, hi): (&mut [Real], &mut [Real]),
    acc: &mut [Real],
) {
    // Rows j go to CHAINS independent accumulators (j mod CHAINS): the chain of dependent
    // multiply-adds, not the arithmetic, sets the time of this small product.
    let acc = &mut acc[..2 * (CHAINS - 1) * lp];
    acc.fill(0.0);
    hr[..lp].fill(0.0);
    hi[..lp].fill(0.0);
    for j0 in (0..lp).step_by(CHAINS) {
        for c in 0..CHAINS {
            let j = j0 + c;
            let (xr, xi) = (ur[j], ui[j]);
            let (rr, ri) = (&pr[j * lp..(j + 1) * lp], &pi[j * lp..(j + 1) * lp]);
            let (ar, ai) = if c == 0 {
                (&mut hr[..lp], &mut hi[..lp])
            } else {
                acc[2 * (c - 1) * lp..2 * c * lp].split_at_mut(lp)
            };
            for i in 0..lp {
                ar[i] = F::madd(rr[i], xr, F::madd(ri[i], xi, ar[i]));
                ai[i] = F::madd(rr[i], xi, F::madd(-ri[i], xr, ai[i]));
            }
        }
    }
    for part in acc.chunks_exact(2 * lp) {
        let (r, i) = part.split_at(lp);
        for q in 0..lp {
            hr[q] += r[q];
            hi[q] += i[q];
        }
    }
}

/// Leakage on coordinate `j` with weight `c`: R += c e_j e_j^H, i.e. with q = sc P e_j:
/// sc P -= c q q^H / (1 + c q_j), and the weights move to the regularised solution
/// V -= c q V_j / (1 + c q_j). `hr`, `hi` are scratch.
#[inline(always)]
fn leak(
    (pr, pi): (&mut [Real], &mut [Real]),
    (vr, vi): (&mut [Real], &mut [Real]),
    lp: usize,
    j: usize,
    c: f64,
    sc: f64,
    (hr, hi): (&mut [Real], &mut [Real]),
) {
    // Column j of P is the conjugate of row j.
    for i in 0..lp {
        hr[i] = pr[j * lp + i];
        hi[i] = -pi[j * lp + i];
    }
    let s = c / (1.0 + c * sc * f64::from(hr[j]));
    let (wr, wi) = (
        (s * sc * f64::from(vr[j])) as Real,
        (s * sc * f64::from(vi[j])) as Real,
    );
    for i in 0..lp {
        vr[i] -= hr[i] * wr - hi[i] * wi;
        vi[i] -= hr[i] * wi + hi[i] * wr;
    }
    let ss = (s * sc).sqrt() as Real;
    hr.iter_mut().chain(hi.iter_mut()).for_each(|x| *x *= ss);
    rank_one_down(pr, pi, lp, hr, hi);
}

/// Ends a step with scale `sc`: folds it back into P before it drifts far from 1, bounds the
/// weights' norm by `max_norm2`, and reports whether the state is still finite with a positive
/// diagonal over the `l` used coordinates.
#[inline(always)]
fn settle(
    (pr, pi): (&mut [Real], &mut [Real]),
    (vr, vi): (&mut [Real], &mut [Real]),
    scale: &mut Real,
    mut sc: f64,
    l: usize,
    lp: usize,
    max_norm2: f64,
) -> bool {
    if !(1e-6..=1e6).contains(&sc) {
        let f = sc as Real;
        pr.iter_mut().chain(pi.iter_mut()).for_each(|x| *x *= f);
        sc = 1.0;
    }
    *scale = sc as Real;
    let n2 = lane_sum(vr.len().min(vi.len()), |i| {
        f64::from(vr[i] * vr[i]) + f64::from(vi[i] * vi[i])
    });
    if n2 > max_norm2 {
        let s = (max_norm2 / n2).sqrt() as Real;
        vr.iter_mut().chain(vi.iter_mut()).for_each(|x| *x *= s);
    }
    // A finite positive diagonal (so a finite trace); independent tests, no chain.
    let mut healthy = true;
    for i in 0..l {
        let p = pr[i * lp + i];
        healthy &= p > 0.0 && p < Real::INFINITY;
    }
    healthy && n2.is_finite() && sc > 0.0 && sc.is_finite()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dsp::inner;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn cn(rng: &mut ChaCha8Rng) -> Complex {
        Complex::new(
            rng.random::<f64>() * 2.0 - 1.0,
            rng.random::<f64>() * 2.0 - 1.0,
        )
    }

    fn split(u: &[Complex], d: Dims) -> (Vec<Real>, Vec<Real>) {
        let mut r = vec![0.0; d.lp];
        let mut i = vec![0.0; d.lp];
        for (k, x) in u.iter().enumerate() {
            r[k] = x.re as Real;
            i[k] = x.im as Real;
        }
        (r, i)
    }

    /// A reset state for `d` (regularisation `delta` at input `power`) and its step scratch.
    fn fresh(d: Dims, delta: f64, power: f64) -> (Vec<Real>, Vec<Real>) {
        let mut st: Vec<Real> = vec![0.0; d.stride()];
        reset(&mut st, d, delta, power);
        (st, vec![0.0; SCRATCH_PER_LANE * d.lp])
    }

    #[test]
    fn converges_to_the_wiener_solution() {
        // Sizes padded to 8 and 16 (the unrolled copies) and to 24 (the general one).
        for l in [3, 11, 19] {
            let d = Dims::new(l);
            let mut rng = ChaCha8Rng::seed_from_u64(5 + l as u64);
            let truth: Vec<Complex> = (0..l).map(|_| cn(&mut rng) * 0.7).collect();
            let (mut st, mut scratch) = fresh(d, 1e-2, 0.66);
            let step = RlsStep {
                forgetting: 0.99,
                leakage: 1e-4,
                max_norm2: 1e6,
            };
            for n in 0..2000 {
                let u: Vec<Complex> = (0..d.l).map(|_| cn(&mut rng)).collect();
                let fixed: Complex = inner(&truth, &u);
                let (ur, ui) = split(&u, d);
                let e = output(&st, d, &ur, &ui, fixed);
                let ok = adapt(&mut st, d, &ur, &ui, e, 1.0, 0.66, n, &step, &mut scratch);
                assert!(ok, "l = {l}, step {n}");
            }
            let mut v = vec![Complex::new(0.0, 0.0); d.l];
            weights(&st, d, &mut v);
            for (a, b) in v.iter().zip(&truth) {
                assert!((a - b).norm() < 1e-2, "l = {l}: {v:?}");
            }
        }
    }

    #[test]
    fn stays_bounded_when_one_direction_is_never_excited() {
        let d = Dims::new(4);
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let (mut st, mut scratch) = fresh(d, 1e-2, 1.0);
        let step = RlsStep {
            forgetting: 0.95,
            leakage: 1e-3,
            max_norm2: 100.0,
        };
        // Rank-one input for 100k frames: plain RLS would grow P like 0.95^-n and overflow.
        let dir = [
            Complex::new(1.0, 0.0),
            Complex::new(0.0, 1.0),
            Complex::new(0.5, 0.0),
            Complex::new(0.0, 0.0),
        ];
        for n in 0..100_000 {
            let s = cn(&mut rng);
            let u: Vec<Complex> = dir.iter().map(|x| x * s).collect();
            let (ur, ui) = split(&u, d);
            let e = output(&st, d, &ur, &ui, s * 0.3);
            assert!(adapt(
                &mut st,
                d,
                &ur,
                &ui,
                e,
                1.0,
                1.0,
                n,
                &step,
                &mut scratch
            ));
        }
        let tr = inverse_correlation_trace(&st, d);
        assert!(tr.is_finite() && tr < 1e6, "P grew to trace {tr}");
        // Still cancels the excited direction.
        let s = Complex::new(0.7, -0.2);
        let u: Vec<Complex> = dir.iter().map(|x| x * s).collect();
        let (ur, ui) = split(&u, d);
        assert!(output(&st, d, &ur, &ui, s * 0.3).norm() < 0.02 * (s * 0.3).norm());
    }

    #[test]
    fn zero_weight_freezes_the_state() {
        let d = Dims::new(2);
        let mut st: Vec<Real> = vec![0.0; d.stride()];
        reset(&mut st, d, 1.0, 1.0);
        st[0] = 0.1;
        let before = st.clone();
        let step = RlsStep {
            forgetting: 0.9,
            leakage: 1e-3,
            max_norm2: 1e6,
        };
        let (ur, ui) = split(&[Complex::new(1.0, 2.0), Complex::new(-1.0, 0.5)], d);
        let mut scratch: Vec<Real> = vec![0.0; SCRATCH_PER_LANE * d.lp];
        let e = Complex::new(3.0, 0.0);
        assert!(adapt(
            &mut st,
            d,
            &ur,
            &ui,
            e,
            0.0,
            1.0,
            0,
            &step,
            &mut scratch
        ));
        assert_eq!(st, before);
    }
}
