//! Moving sources heard through a time-varying room response.
//!
//! The source signal is cut into segments by periodic Hann windows of length 2H at hop H (they sum
//! to one), and each segment is convolved (FFT, realfft) with the room response at the source's
//! position at the segment centre; the convolved segments are added. The response therefore
//! changes every H samples and the change is a cross-fade over 2H samples between responses,
//! without discontinuities (each windowed segment is smooth and rings out through its own
//! response). The early response (direct path and images arriving within `early_len`) is
//! recomputed at every update; the late part, diffuse and insensitive to small movements, is
//! recomputed when the source has moved `late_update_m` from where it was last computed. Image
//! positions depend only on the source, so they are found once per update and used for every
//! microphone.

use std::sync::Arc;

use num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};

use crate::geometry::Vec3;

use super::room::{Biquad, FractionalDelay, Image, ShoeboxRoom};

/// How often and how far responses are computed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderSettings {
    /// Samples between response updates (H).
    pub hop: usize,
    /// Response length (samples).
    pub response_len: usize,
    /// Images arriving at the microphones' centre within this many samples are the early part.
    pub early_len: usize,
    /// Movement (m) after which the late part is recomputed.
    pub late_update_m: f64,
    /// High-pass cut-off (Hz) applied to each response; 0 for none.
    pub highpass_hz: f64,
}

/// Renders sources in one room for one set of microphones.
pub struct Renderer {
    room: ShoeboxRoom,
    mics: Vec<Vec3>,
    centre: Vec3,
    spread: f64,
    taps: FractionalDelay,
    settings: RenderSettings,
    highpass: Option<Biquad>,
    nfft: usize,
    forward: Arc<dyn RealToComplex<f64>>,
    inverse: Arc<dyn ComplexToReal<f64>>,
    window: Vec<f64>,
}

/// The responses currently in use for one source.
struct Responses {
    early_at: Option<Vec3>,
    late_at: Option<Vec3>,
    early: Vec<Vec<f64>>,
    late: Vec<Vec<f64>>,
    spectra: Vec<Vec<Complex<f64>>>,
}

impl Renderer {
    /// A renderer for `mics` (in channel order) in `room`.
    pub fn new(room: ShoeboxRoom, mics: Vec<Vec3>, settings: RenderSettings) -> Self {
        let n = mics.len().max(1) as f64;
        let centre = mics.iter().fold(Vec3::zeros(), |a, m| a + m) / n;
        let spread = mics.iter().map(|m| (m - centre).norm()).fold(0.0, f64::max);
        let settings = RenderSettings {
            hop: settings.hop.max(1),
            response_len: settings.response_len.max(1),
            ..settings
        };
        let nfft = (2 * settings.hop + settings.response_len).next_power_of_two();
        let mut planner = RealFftPlanner::<f64>::new();
        let highpass = (settings.highpass_hz > 0.0)
            .then(|| Biquad::highpass(settings.highpass_hz, room.sample_rate()));
        let window = (0..2 * settings.hop)
            .map(|i| 0.5 - 0.5 * (std::f64::consts::PI * i as f64 / settings.hop as f64).cos())
            .collect();
        Self {
            forward: planner.plan_fft_forward(nfft),
            inverse: planner.plan_fft_inverse(nfft),
            room,
            mics,
            centre,
            spread,
            taps: FractionalDelay::new(),
            settings,
            highpass,
            nfft,
            window,
        }
    }

    /// The room.
    pub fn room(&self) -> &ShoeboxRoom {
        &self.room
    }

    /// Number of microphones (output channels).
    pub fn channels(&self) -> usize {
        self.mics.len()
    }

    /// Number of segments (progress units) a signal of `len` samples is rendered in.
    pub fn segments(&self, len: usize) -> usize {
        len.div_ceil(self.settings.hop) + 1
    }

    /// The images of `pos` in the early part (`early == true`) or the late part.
    fn part_images(&self, pos: &Vec3, early: bool) -> Vec<Image> {
        let c = self.room.speed_of_sound() / self.room.sample_rate();
        let early_r = self.settings.early_len as f64 * c;
        if early {
            let mut ims = self.room.images(pos, &self.centre, early_r + self.spread);
            ims.retain(|im| (im.position - self.centre).norm() <= early_r);
            ims
        } else {
            let reach = self.room.reach(self.settings.response_len) + self.spread;
            let mut ims = self.room.images(pos, &self.centre, reach);
            ims.retain(|im| (im.position - self.centre).norm() > early_r);
            ims
        }
    }

    /// One part of the response at `pos` for every microphone (no high-pass).
    fn part(&self, pos: &Vec3, early: bool) -> Vec<Vec<f64>> {
        let ims = self.part_images(pos, early);
        self.mics
            .iter()
            .map(|m| {
                let mut h = vec![0.0; self.settings.response_len];
                self.room.add_response(&ims, m, &self.taps, &mut h);
                h
            })
            .collect()
    }

    /// The complete (high-passed) response from `pos` to every microphone.
    pub fn response_at(&self, pos: &Vec3) -> Vec<Vec<f64>> {
        let early = self.part(pos, true);
        let late = self.part(pos, false);
        early
            .into_iter()
            .zip(late)
            .map(|(mut e, l)| {
                e.iter_mut().zip(&l).for_each(|(a, b)| *a += b);
                if let Some(hp) = &self.highpass {
                    hp.apply(&mut e);
                }
                e
            })
            .collect()
    }

    /// Adds the images of `signal` moving along `position(t)` at every microphone to `out`
    /// (one buffer per microphone, each as long as the signal); `tick` is called per segment.
    pub fn render(
        &self,
        signal: &[f64],
        position: &dyn Fn(f64) -> Vec3,
        out: &mut [Vec<f64>],
        tick: &mut dyn FnMut(),
    ) {
        let len = signal.len();
        let hop = self.settings.hop;
        let fs = self.room.sample_rate();
        let bins = self.nfft / 2 + 1;
        let mut state = Responses {
            early_at: None,
            late_at: None,
            early: Vec::new(),
            late: Vec::new(),
            spectra: vec![vec![Complex::default(); bins]; self.mics.len()],
        };
        let mut time = self.forward.make_input_vec();
        let mut resp_buf = self.forward.make_input_vec();
        let mut seg_spec = self.forward.make_output_vec();
        let mut prod = self.inverse.make_input_vec();
        let mut scratch_f = self.forward.make_scratch_vec();
        let mut scratch_i = self.inverse.make_scratch_vec();
        let scale = 1.0 / self.nfft as f64;
        for k in 0..self.segments(len) {
            tick();
            let centre = k * hop;
            let start = centre as isize - hop as isize;
            if !self.window_segment(signal, start, &mut time) {
                continue;
            }
            // A convolution is causal and finite: keep only the span the segment can reach, so
            // that FFT round-off never leaks before the sound starts or after it has died out.
            let first = time.iter().position(|v| *v != 0.0).unwrap_or(0);
            let last = time.iter().rposition(|v| *v != 0.0).unwrap_or(0);
            let span = (last + self.settings.response_len).min(self.nfft);
            let pos = position(centre as f64 / fs);
            self.update(&mut state, &pos, &mut resp_buf, &mut scratch_f);
            if self
                .forward
                .process_with_scratch(&mut time, &mut seg_spec, &mut scratch_f)
                .is_err()
            {
                continue;
            }
            for (m, o) in out.iter_mut().enumerate() {
                for ((p, s), h) in prod.iter_mut().zip(&seg_spec).zip(&state.spectra[m]) {
                    *p = s * h;
                }
                prod[0].im = 0.0;
                if let Some(top) = prod.last_mut() {
                    top.im = 0.0;
                }
                if self
                    .inverse
                    .process_with_scratch(&mut prod, &mut time, &mut scratch_i)
                    .is_err()
                {
                    continue;
                }
                for (i, v) in time[..span].iter().enumerate().skip(first) {
                    let n = start + i as isize;
                    if n >= 0 && (n as usize) < o.len() {
                        o[n as usize] += v * scale;
                    }
                }
            }
        }
    }

    /// Fills `buf` with the Hann-windowed segment of `signal` starting at sample `start` (zero
    /// padded); false when the segment is silent.
    fn window_segment(&self, signal: &[f64], start: isize, buf: &mut [f64]) -> bool {
        let mut sound = false;
        buf.iter_mut().for_each(|v| *v = 0.0);
        for (i, (v, w)) in buf.iter_mut().zip(&self.window).enumerate() {
            let n = start + i as isize;
            if n >= 0 && (n as usize) < signal.len() {
                *v = signal[n as usize] * w;
                sound |= *v != 0.0;
            }
        }
        sound
    }

    /// Brings the responses up to date for a source at `pos`.
    fn update(
        &self,
        state: &mut Responses,
        pos: &Vec3,
        buf: &mut [f64],
        scratch: &mut [Complex<f64>],
    ) {
        let moved = |at: &Option<Vec3>, limit: f64| at.is_none_or(|p| (p - pos).norm() > limit);
        let late = moved(&state.late_at, self.settings.late_update_m);
        let early = moved(&state.early_at, 1e-4);
        if late {
            state.late = self.part(pos, false);
            state.late_at = Some(*pos);
        }
        if early {
            state.early = self.part(pos, true);
            state.early_at = Some(*pos);
        }
        if !(late || early) {
            return;
        }
        let len = self.settings.response_len;
        for m in 0..self.mics.len() {
            buf.iter_mut().for_each(|v| *v = 0.0);
            for (i, v) in buf[..len].iter_mut().enumerate() {
                *v = state.early[m][i] + state.late[m][i];
            }
            if let Some(hp) = &self.highpass {
                hp.apply(&mut buf[..len]);
            }
            if self
                .forward
                .process_with_scratch(buf, &mut state.spectra[m], scratch)
                .is_err()
            {
                state.spectra[m]
                    .iter_mut()
                    .for_each(|v| *v = Complex::default());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::sim::calibrate::reverberation_for;
    use crate::scene::sim::decay::schroeder_rt60;
    use std::f64::consts::PI;

    const FS: f64 = 16000.0;

    fn renderer(size: Vec3, rt60: f64, mics: Vec<Vec3>) -> Renderer {
        let probe = Vec3::new(size.x * 0.5, size.y * 0.5, 1.4);
        let rev = reverberation_for(&size, rt60, &probe, &mics[0], 343.0).unwrap();
        let room = ShoeboxRoom::new(size, rev.absorption, 343.0, FS).unwrap();
        Renderer::new(
            room,
            mics,
            RenderSettings {
                hop: 800,
                response_len: (rev.response_s * FS).ceil() as usize,
                early_len: (0.08 * FS) as usize,
                late_update_m: 0.25,
                highpass_hz: 60.0,
            },
        )
    }

    #[test]
    fn simulated_responses_reverberate_for_the_target_time() {
        let size = Vec3::new(7.67, 3.41, 2.7);
        let mics = vec![Vec3::new(3.0, 3.25, 1.95), Vec3::new(1.2, 1.0, 1.0)];
        for target in [0.25, 0.5] {
            let r = renderer(size, target, mics.clone());
            for src in [Vec3::new(2.0, 0.7, 1.65), Vec3::new(5.5, 2.2, 1.2)] {
                for h in r.response_at(&src) {
                    let t20 = schroeder_rt60(&h, FS, 20.0).unwrap();
                    let t30 = schroeder_rt60(&h, FS, 30.0).unwrap();
                    println!("target {target} s: T20 {t20:.3} s, T30 {t30:.3} s");
                    for t in [t20, t30] {
                        assert!((t - target).abs() < 0.2 * target, "{t} vs {target}");
                    }
                }
            }
        }
    }

    /// Convolves `x` with `h` directly.
    fn convolve(x: &[f64], h: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; x.len()];
        for (n, &v) in x.iter().enumerate() {
            if v == 0.0 {
                continue;
            }
            for (k, &c) in h.iter().enumerate().take(x.len() - n) {
                y[n + k] += v * c;
            }
        }
        y
    }

    #[test]
    fn a_static_source_is_an_exact_convolution_with_its_response() {
        let mics = vec![Vec3::new(3.0, 2.5, 0.8), Vec3::new(3.05, 2.5, 0.8)];
        let r = renderer(Vec3::new(6.0, 5.0, 3.0), 0.3, mics);
        let pos = Vec3::new(2.0, 3.5, 1.2);
        let x: Vec<f64> = (0..8000)
            .map(|n| ((n as f64) * 0.37).sin() * if n % 3000 < 2000 { 1.0 } else { 0.0 })
            .collect();
        let mut out = vec![vec![0.0; x.len()]; 2];
        r.render(&x, &|_| pos, &mut out, &mut || {});
        for (o, h) in out.iter().zip(r.response_at(&pos)) {
            let want = convolve(&x, &h);
            let err = o
                .iter()
                .zip(&want)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            let peak = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(err < 1e-9 * peak.max(1e-12), "error {err}, peak {peak}");
        }
    }

    /// Energy above 2 kHz in 5 ms frames (two cascaded second-order high-passes).
    fn high_band_frames(y: &[f64]) -> Vec<f64> {
        let mut z = y.to_vec();
        let hp = Biquad::highpass(2000.0, FS);
        hp.apply(&mut z);
        hp.apply(&mut z);
        z.chunks(80)
            .map(|c| c.iter().map(|v| v * v).sum())
            .collect()
    }

    #[test]
    fn a_moving_source_changes_its_response_without_clicks() {
        let mics = vec![Vec3::new(3.0, 2.5, 0.8)];
        let r = renderer(Vec3::new(6.0, 5.0, 3.0), 0.3, mics);
        // A 300 Hz tone walking at 1 m/s past the array: any discontinuity would put broadband
        // energy above 2 kHz, where the tone itself has none.
        let len = 32000;
        let x: Vec<f64> = (0..len)
            .map(|n| (2.0 * PI * 300.0 * n as f64 / FS).sin())
            .collect();
        let path = |t: f64| Vec3::new(1.5 + 1.0 * t, 3.8, 1.5);
        let mut out = vec![vec![0.0; len]];
        r.render(&x, &path, &mut out, &mut || {});
        let y = &out[0];
        let total: f64 = y[4000..].iter().map(|v| v * v).sum::<f64>() / (len - 4000) as f64 * 80.0;
        let smooth = high_band_frames(y);
        let worst = smooth[50..].iter().fold(0.0f64, |m, v| m.max(*v));
        assert!(
            worst < 1e-4 * total,
            "high-band frame energy {worst} vs {total}"
        );

        // The same path with the response switched abruptly every 50 ms does click, so the
        // measure above would catch a broken cross-fade.
        let mut hard = vec![0.0; len];
        for block in 0..len / 800 {
            let h = &r.response_at(&path(block as f64 * 0.05))[0];
            for n in block * 800..(block + 1) * 800 {
                hard[n] = (0..h.len().min(n + 1)).map(|k| h[k] * x[n - k]).sum();
            }
        }
        let clicks = high_band_frames(&hard);
        let worst_hard = clicks[50..].iter().fold(0.0f64, |m, v| m.max(*v));
        assert!(worst_hard > 100.0 * worst, "{worst_hard} vs {worst}");
    }
}
