//! Shoebox room acoustics by the image-source method (Allen & Berkley 1979).
//!
//! Every wall has the same absorption coefficient alpha, found from the target reverberation time
//! by Sabine's formula RT60 = 24 ln(10) V / (c S alpha); an image reflected k times carries the
//! pressure gain beta^k with beta = sqrt(1 - alpha). Each image adds one fractional-delay tap set
//! (a Hann-windowed sinc, [`FRACTIONAL_TAPS`] taps) at delay r / c with gain 1 / (4 pi r). There is
//! no reflection-order cut-off: every image whose arrival falls inside the response is included,
//! and the response length follows the RT60 (by default it ends where the decay reaches -60 dB).

use std::f64::consts::PI;

use crate::geometry::Vec3;

/// Number of taps of the fractional-delay interpolator (even).
pub const FRACTIONAL_TAPS: usize = 32;
/// Fractional positions tabulated per sample (delays are rounded to 1/this of a sample).
const FRACTION_STEPS: usize = 512;

/// A virtual source: the source mirrored in the walls, with the gain of its reflections.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Image {
    /// Position in world coordinates (outside the room except for the direct path).
    pub position: Vec3,
    /// Product of the reflection coefficients met on the way (1 for the direct path).
    pub gain: f64,
    /// Number of wall reflections.
    pub order: u32,
}

/// A rectangular room with uniformly absorbing walls, one corner at the origin.
#[derive(Debug, Clone, PartialEq)]
pub struct ShoeboxRoom {
    size: Vec3,
    absorption: f64,
    beta: f64,
    speed_of_sound: f64,
    sample_rate: f64,
}

impl ShoeboxRoom {
    /// A room of `size` (metres) whose walls absorb `absorption` of the incident energy.
    pub fn new(
        size: Vec3,
        absorption: f64,
        speed_of_sound: f64,
        sample_rate: f64,
    ) -> Result<Self, String> {
        if !(size.iter().all(|s| s.is_finite() && *s > 0.0)) {
            return Err("room sides must be positive".into());
        }
        if !(0.0..=1.0).contains(&absorption) {
            return Err(format!("absorption {absorption} is not in [0, 1]"));
        }
        if !(speed_of_sound > 0.0 && sample_rate > 0.0) {
            return Err("speed of sound and sample rate must be positive".into());
        }
        Ok(Self {
            size,
            absorption,
            beta: (1.0 - absorption).sqrt(),
            speed_of_sound,
            sample_rate,
        })
    }

    /// A room whose walls are set by Sabine's formula to reverberate for `rt60_s` seconds.
    pub fn from_rt60(
        size: Vec3,
        rt60_s: f64,
        speed_of_sound: f64,
        sample_rate: f64,
    ) -> Result<Self, String> {
        let alpha = sabine_absorption(&size, rt60_s, speed_of_sound)?;
        Self::new(size, alpha, speed_of_sound, sample_rate)
    }

    /// Side lengths (m).
    pub fn size(&self) -> Vec3 {
        self.size
    }

    /// Energy absorption coefficient of the walls.
    pub fn absorption(&self) -> f64 {
        self.absorption
    }

    /// Pressure reflection coefficient of the walls, sqrt(1 - alpha).
    pub fn reflection(&self) -> f64 {
        self.beta
    }

    /// Sample rate the responses are made at (Hz).
    pub fn sample_rate(&self) -> f64 {
        self.sample_rate
    }

    /// Speed of sound (m/s).
    pub fn speed_of_sound(&self) -> f64 {
        self.speed_of_sound
    }

    /// All images of `source` within `radius` metres of `centre` (the receivers' centre), in no
    /// particular order. Images with zero gain (anechoic walls) are left out.
    pub fn images(&self, source: &Vec3, centre: &Vec3, radius: f64) -> Vec<Image> {
        let max_order = self.max_order(radius);
        let gains: Vec<f64> = (0..=max_order).map(|k| self.beta.powi(k as i32)).collect();
        let mut out = Vec::new();
        visit_images(&self.size, source, centre, radius, |position, order| {
            let gain = gains[order as usize];
            if gain > 0.0 {
                out.push(Image {
                    position,
                    gain,
                    order,
                });
            }
        });
        out
    }

    /// An upper bound of the reflection order of images within `radius` of a point in the room.
    fn max_order(&self, radius: f64) -> u32 {
        (0..3)
            .map(|a| 2 * ((radius / (2.0 * self.size[a])).ceil() as u32 + 2))
            .sum()
    }

    /// Longest distance an image may travel and still land inside a response of `len` samples.
    pub fn reach(&self, len: usize) -> f64 {
        len as f64 / self.sample_rate * self.speed_of_sound
    }

    /// Adds the room response from `images` to the microphone at `mic` into `out` (its length
    /// is the response length); taps that would fall past the end are dropped.
    pub fn add_response(
        &self,
        images: &[Image],
        mic: &Vec3,
        taps: &FractionalDelay,
        out: &mut [f64],
    ) {
        let samples_per_metre = self.sample_rate / self.speed_of_sound;
        let half = (FRACTIONAL_TAPS / 2 - 1) as isize;
        let len = out.len() as isize;
        for im in images {
            let d = (im.position - mic).norm().max(0.01);
            let delay = d * samples_per_metre;
            let whole = delay.floor();
            let start = whole as isize - half;
            if start >= len {
                continue;
            }
            let amp = im.gain / (4.0 * PI * d);
            let kernel = taps.kernel(delay - whole);
            if start >= 0 && start + FRACTIONAL_TAPS as isize <= len {
                let s = start as usize;
                for (o, k) in out[s..s + FRACTIONAL_TAPS].iter_mut().zip(kernel) {
                    *o += amp * k;
                }
            } else {
                for (j, k) in kernel.iter().enumerate() {
                    let i = start + j as isize;
                    if (0..len).contains(&i) {
                        out[i as usize] += amp * k;
                    }
                }
            }
        }
    }
}

/// Calls `f(position, order)` for every image of `source` (the source itself included) in a
/// shoebox of `size` that lies within `radius` of `centre`.
pub fn visit_images(
    size: &Vec3,
    source: &Vec3,
    centre: &Vec3,
    radius: f64,
    mut f: impl FnMut(Vec3, u32),
) {
    // Along one axis an image is (1 - 2u) s + 2 l L and has met |l - u| + |l| walls.
    let axis = |a: usize| -> Vec<(f64, u32)> {
        let len = size[a];
        let n = (radius / (2.0 * len)).ceil() as i64 + 1;
        let mut out = Vec::with_capacity(4 * n as usize + 2);
        for l in -n..=n {
            for u in 0..2i64 {
                let x = (1 - 2 * u) as f64 * source[a] + 2.0 * l as f64 * len;
                if (x - centre[a]).abs() <= radius {
                    out.push((x, ((l - u).abs() + l.abs()) as u32));
                }
            }
        }
        out
    };
    let (xs, ys, zs) = (axis(0), axis(1), axis(2));
    let r2 = radius * radius;
    for &(x, kx) in &xs {
        let dx2 = (x - centre.x).powi(2);
        for &(y, ky) in &ys {
            let dxy2 = dx2 + (y - centre.y).powi(2);
            if dxy2 > r2 {
                continue;
            }
            for &(z, kz) in &zs {
                if dxy2 + (z - centre.z).powi(2) <= r2 {
                    f(Vec3::new(x, y, z), kx + ky + kz);
                }
            }
        }
    }
}

/// Wall absorption that gives reverberation time `rt60_s` by Sabine's formula.
pub fn sabine_absorption(size: &Vec3, rt60_s: f64, speed_of_sound: f64) -> Result<f64, String> {
    if !(rt60_s.is_finite() && rt60_s > 0.0) {
        return Err(format!("RT60 {rt60_s} s must be positive"));
    }
    let volume = size.x * size.y * size.z;
    let surface = 2.0 * (size.x * size.y + size.y * size.z + size.x * size.z);
    let alpha = 24.0 * std::f64::consts::LN_10 * volume / (speed_of_sound * surface * rt60_s);
    if alpha > 1.0 {
        let shortest = 24.0 * std::f64::consts::LN_10 * volume / (speed_of_sound * surface);
        return Err(format!(
            "RT60 {rt60_s} s is shorter than this room allows with fully absorbing walls \
             ({shortest:.3} s by Sabine's formula)"
        ));
    }
    Ok(alpha)
}

/// A table of windowed-sinc fractional-delay kernels.
#[derive(Debug, Clone)]
pub struct FractionalDelay {
    table: Vec<f64>,
}

impl Default for FractionalDelay {
    fn default() -> Self {
        Self::new()
    }
}

impl FractionalDelay {
    /// Tabulates the kernels: tap j of the kernel for fraction f sits at sample
    /// floor(delay) - (taps/2 - 1) + j and holds sinc(x) w(x), x = j - (taps/2 - 1) - f, with a
    /// Hann window w over the kernel span, normalised to unit gain at DC.
    pub fn new() -> Self {
        let half = FRACTIONAL_TAPS as f64 / 2.0;
        let mut table = Vec::with_capacity((FRACTION_STEPS + 1) * FRACTIONAL_TAPS);
        for step in 0..=FRACTION_STEPS {
            let f = step as f64 / FRACTION_STEPS as f64;
            let row: Vec<f64> = (0..FRACTIONAL_TAPS)
                .map(|j| {
                    let x = j as f64 - (half - 1.0) - f;
                    let w = if x.abs() < half {
                        0.5 * (1.0 + (PI * x / half).cos())
                    } else {
                        0.0
                    };
                    sinc(x) * w
                })
                .collect();
            let sum: f64 = row.iter().sum();
            table.extend(row.iter().map(|v| v / sum));
        }
        Self { table }
    }

    /// The kernel for a fractional delay `frac` in [0, 1].
    pub fn kernel(&self, frac: f64) -> &[f64] {
        let step = ((frac * FRACTION_STEPS as f64).round() as usize).min(FRACTION_STEPS);
        &self.table[step * FRACTIONAL_TAPS..(step + 1) * FRACTIONAL_TAPS]
    }
}

/// sin(pi x) / (pi x).
pub fn sinc(x: f64) -> f64 {
    if x.abs() < 1e-12 {
        1.0
    } else {
        (PI * x).sin() / (PI * x)
    }
}

/// A second-order IIR section (direct form I): the high-pass that removes the low-frequency
/// (DC) excess of image-source responses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
}

impl Biquad {
    /// Butterworth high-pass (Q = 1/sqrt 2) at `cutoff_hz` by the bilinear transform.
    pub fn highpass(cutoff_hz: f64, sample_rate: f64) -> Self {
        let w0 = 2.0 * PI * cutoff_hz / sample_rate;
        let alpha = w0.sin() / (2.0 * std::f64::consts::FRAC_1_SQRT_2);
        let cw = w0.cos();
        let a0 = 1.0 + alpha;
        Self {
            b: [
                (1.0 + cw) / 2.0 / a0,
                -(1.0 + cw) / a0,
                (1.0 + cw) / 2.0 / a0,
            ],
            a: [-2.0 * cw / a0, (1.0 - alpha) / a0],
        }
    }

    /// Filters `x` in place from rest.
    pub fn apply(&self, x: &mut [f64]) {
        let (mut x1, mut x2, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0);
        for v in x.iter_mut() {
            let x0 = *v;
            let y0 =
                self.b[0] * x0 + self.b[1] * x1 + self.b[2] * x2 - self.a[0] * y1 - self.a[1] * y2;
            x2 = x1;
            x1 = x0;
            y2 = y1;
            y1 = y0;
            *v = y0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn room(rt60: f64) -> ShoeboxRoom {
        ShoeboxRoom::from_rt60(Vec3::new(7.67, 3.41, 2.7), rt60, 343.0, 16000.0).unwrap()
    }

    #[test]
    fn sabine_absorption_matches_the_formula_and_rejects_impossible_rooms() {
        let size = Vec3::new(7.67, 3.41, 2.7);
        let a = sabine_absorption(&size, 0.25, 343.0).unwrap();
        // V = 70.62 m^3, S = 112.13 m^2: alpha = 0.1611 V / (S T).
        assert!((a - 0.1611 * 70.62 / (112.13 * 0.25)).abs() < 2e-3, "{a}");
        assert!(sabine_absorption(&size, 0.05, 343.0).is_err());
    }

    #[test]
    fn first_order_images_mirror_the_source_in_each_wall() {
        let r = room(0.3);
        let s = Vec3::new(2.0, 1.0, 1.5);
        let ims = r.images(&s, &s, 2.0 * 7.67 + 1.0);
        let first: Vec<_> = ims.iter().filter(|i| i.order == 1).collect();
        assert_eq!(first.len(), 6);
        for want in [
            Vec3::new(-2.0, 1.0, 1.5),
            Vec3::new(2.0 * 7.67 - 2.0, 1.0, 1.5),
            Vec3::new(2.0, -1.0, 1.5),
            Vec3::new(2.0, 2.0 * 3.41 - 1.0, 1.5),
            Vec3::new(2.0, 1.0, -1.5),
            Vec3::new(2.0, 1.0, 2.0 * 2.7 - 1.5),
        ] {
            assert!(
                first.iter().any(|i| (i.position - want).norm() < 1e-9),
                "missing first-order image at {want:?}"
            );
        }
        let beta = r.reflection();
        assert!(first.iter().all(|i| (i.gain - beta).abs() < 1e-12));
        assert_eq!(ims.iter().filter(|i| i.order == 0).count(), 1);
    }

    /// Least-squares fit of an ideal band-limited impulse a sinc(n - tau) to `h` near `guess`.
    fn fit_impulse(h: &[f64], guess: f64) -> (f64, f64) {
        let mut best = (f64::NEG_INFINITY, 0.0, 0.0);
        let mut tau = guess - 0.5;
        while tau <= guess + 0.5 {
            let n0 = tau.floor() as usize - 12;
            let (mut hk, mut kk) = (0.0, 0.0);
            for (i, v) in h[n0..=n0 + 24].iter().enumerate() {
                let k = sinc((n0 + i) as f64 - tau);
                hk += v * k;
                kk += k * k;
            }
            if hk * hk / kk > best.0 {
                best = (hk * hk / kk, tau, hk / kk);
            }
            tau += 0.0005;
        }
        (best.1, best.2)
    }

    #[test]
    fn direct_path_tap_sits_at_the_geometric_delay_with_spherical_gain() {
        // A large room keeps the first reflection far from the direct tap.
        let room = ShoeboxRoom::new(Vec3::new(20.0, 20.0, 10.0), 0.4, 343.0, 16000.0).unwrap();
        let src = Vec3::new(10.0, 10.0, 5.0);
        let taps = FractionalDelay::new();
        for mic in [
            Vec3::new(11.234, 10.5, 5.3),
            Vec3::new(8.0, 11.0, 4.1),
            Vec3::new(10.6, 9.3, 5.0),
        ] {
            let r = (mic - src).norm();
            let expect = r / 343.0 * 16000.0;
            let mut h = vec![0.0; 2000];
            let images = room.images(&src, &mic, room.reach(h.len()));
            room.add_response(&images, &mic, &taps, &mut h);
            // Nothing arrives before the direct path.
            let first = expect.floor() as usize - FRACTIONAL_TAPS / 2;
            assert!(h[..first].iter().all(|v| *v == 0.0));
            let (tau, amp) = fit_impulse(&h, expect);
            assert!(
                (tau - expect).abs() < 0.01,
                "delay {tau} vs {expect} samples"
            );
            // The tap set's DC gain is the path gain; the fitted ideal sinc differs only by
            // the window's taper.
            let gain = 1.0 / (4.0 * PI * r);
            let dc: f64 = h[first..first + FRACTIONAL_TAPS + 2].iter().sum();
            assert!((dc - gain).abs() < 1e-6 * gain, "gain {dc} vs {gain}");
            assert!(
                (amp - gain).abs() < 0.03 * gain,
                "fitted gain {amp} vs {gain}"
            );
        }
    }

    #[test]
    fn fractional_kernels_are_unit_impulses_at_integer_delays() {
        let t = FractionalDelay::new();
        let k = t.kernel(0.0);
        for (j, v) in k.iter().enumerate() {
            let want = if j == FRACTIONAL_TAPS / 2 - 1 {
                1.0
            } else {
                0.0
            };
            assert!((v - want).abs() < 1e-12, "tap {j}: {v}");
        }
        // Half a sample: symmetric around the centre.
        let k = t.kernel(0.5);
        let c = FRACTIONAL_TAPS / 2 - 1;
        assert!((k[c] - k[c + 1]).abs() < 1e-12);
    }

    #[test]
    fn highpass_removes_dc_and_passes_speech() {
        let hp = Biquad::highpass(60.0, 16000.0);
        let mut dc = vec![1.0; 16000];
        hp.apply(&mut dc);
        assert!(dc[15999].abs() < 1e-6);
        let mut tone: Vec<f64> = (0..16000)
            .map(|n| (2.0 * PI * 500.0 * n as f64 / 16000.0).sin())
            .collect();
        hp.apply(&mut tone);
        let peak = tone[8000..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!((peak - 1.0).abs() < 0.02, "{peak}");
    }
}
