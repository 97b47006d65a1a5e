//! Speed of the separator: one hop (1024-sample frame, 512 hop, 16 kHz) with 8 microphones and 3
//! labels, post-filter on, for each beamformer; and with 13 silent faces beside the 3 talkers,
//! running (a crowded session's first seconds) and resting.

use std::hint::black_box;

use avsep::dsp::{Complex, MultiSpectrum};
use avsep::geometry::{Layout, MicArray, Vec3};
use avsep::label::Label;
use avsep::separate::harmonic::{HarmonicFit, hann_transform};
use avsep::separate::{Separator, SeparatorConfig, Target};
use criterion::{Criterion, criterion_group};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn layout() -> Layout {
    let mics = (0..8)
        .map(|i| {
            let a = 2.0 * std::f64::consts::PI * i as f64 / 8.0;
            Vec3::new(0.05 * a.cos(), 0.05 * a.sin(), 1.2)
        })
        .collect();
    let arr = MicArray::new("a0", mics, (0..8).collect()).unwrap();
    Layout::new(16000, 343.0, vec![arr], vec![], None).unwrap()
}

/// Random-phase spectra (a new frame each call, so nothing is cached between frames).
fn frames(count: usize, bins: usize) -> Vec<MultiSpectrum> {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut rnd = move || rng.random_range(-0.5..0.5);
    (0..count)
        .map(|_| {
            let mut m = MultiSpectrum::zeros(8, bins);
            for c in 0..8 {
                for v in m.channel_mut(c) {
                    *v = Complex::new(rnd(), rnd());
                }
            }
            m
        })
        .collect()
}

fn targets(frame: usize, speaking: f64) -> Vec<Target> {
    // Slowly moving talkers: the steering is recomputed every frame, as in the pipeline.
    let d = 0.001 * frame as f64;
    [(1.5, 0.3), (-0.8, 1.2), (-0.5, -1.5)]
        .iter()
        .enumerate()
        .map(|(i, (x, y))| Target {
            label: Label::new(0, i as u32),
            position: Vec3::new(x + d, y - d, 1.6),
            direction_only: false,
            speaking,
            activity: 1.0,
            pitch: None,
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    for (name, json, speaking) in [
        ("gsc_adapting", r#"{}"#, 0.0),
        ("gsc_frozen", r#"{}"#, 1.0),
        // Fixed beamformers and blocking matrices rebuilt every hop (the cost before the
        // steering tolerance; a moving talker costs this only on the hops where it moved enough).
        (
            "gsc_rebuild_every_hop",
            r#"{"steering_tolerance_rad": 0.0}"#,
            0.0,
        ),
        (
            "gsc_mask_bf",
            r#"{"post_filter": {"kind": "mask", "apply_to": "beamformer_output"}}"#,
            0.0,
        ),
        ("mvdr", r#"{"beamformer": "mvdr"}"#, 0.0),
        ("null_steering", r#"{"beamformer": "null_steering"}"#, 0.0),
        ("delay_and_sum", r#"{"beamformer": "delay_and_sum"}"#, 0.0),
    ] {
        let mut cfg: SeparatorConfig = serde_json::from_str(json).unwrap();
        // The adapting labels read silent, so that their cancellers adapt: they must not rest.
        cfg.lifecycle.rest_after_s = 0.0;
        // Warm up past the fade-in so every label runs at full strength.
        let name = format!("separate/hop_8mics_3labels/{name}");
        bench_hops(c, &name, &cfg, 10, |f| targets(f, speaking));
    }
}

/// Benchmarks one hop of a separator with `cfg` on random-phase input after `warm_up` hops,
/// with `targets(hop)`.
fn bench_hops(
    c: &mut Criterion,
    name: &str,
    cfg: &SeparatorConfig,
    warm_up: usize,
    targets: impl Fn(usize) -> Vec<Target>,
) {
    let mut sep = Separator::new(&layout(), cfg).unwrap();
    let input = frames(64, sep.frame_geometry().bins());
    let mut out = Vec::new();
    for f in 0..warm_up {
        sep.process_into(&input[f % 64], &targets(f), &mut out);
    }
    let mut f = warm_up;
    c.bench_function(name, |b| {
        b.iter(|| {
            let t = targets(f);
            sep.process_into(black_box(&input[f % 64]), &t, &mut out);
            f += 1;
            black_box(&out);
        })
    });
}

/// Three talking labels and 13 silent faces around the array: 16 labels on 8 microphones, so
/// each label nulls its 7 loudest others. `running`: the faces have not been silent long enough
/// to rest (`rest_after_s = 0` keeps them so); `resting`: past `rest_after_s`.
fn bench_crowd(c: &mut Criterion) {
    let crowd = |f: usize| -> Vec<Target> {
        let mut t = targets(f, 1.0);
        t.extend((0..13).map(|i| {
            let a = 2.0 * std::f64::consts::PI * f64::from(i) / 13.0 + 0.1;
            Target {
                label: Label::new(1, i),
                position: Vec3::new(2.0 * a.cos(), 2.0 * a.sin(), 1.5),
                direction_only: false,
                speaking: 0.0,
                activity: 1.0,
                pitch: None,
            }
        }));
        t
    };
    for (name, json) in [
        ("running", r#"{"lifecycle": {"rest_after_s": 0}}"#),
        ("resting", r#"{}"#),
    ] {
        let cfg: SeparatorConfig = serde_json::from_str(json).unwrap();
        // Past the faces' rest time (5 s is 157 hops) and fade-out.
        let name = format!("separate/hop_8mics_3talkers_13faces/{name}");
        bench_hops(c, &name, &cfg, 200, crowd);
    }
}

/// The harmonic amplitude fit of one frame's bins below 1 kHz with three wholly voiced labels
/// at the lowest F0s the search allows (the most columns: 14 harmonics each), which the
/// random-phase hops above never reach (no label reads a pitch in noise).
fn bench_fit(c: &mut Criterion) {
    let (frame, hz) = (1024, 16_000.0 / 1024.0);
    let top = (1000.0 / hz) as usize + 1;
    let f0s = [70.0, 74.0, 81.0];
    let mut x = vec![Complex::new(0.0, 0.0); top];
    for (i, f0) in f0s.iter().enumerate() {
        let mut h = 1.0;
        while h * f0 < 1000.0 {
            let nu = h * f0 / hz;
            for (k, v) in x.iter_mut().enumerate() {
                *v += Complex::from_polar(1.0 / h, i as f64 + h)
                    * hann_transform(k as f64 - nu, frame);
            }
            h += 1.0;
        }
    }
    let mut fit = HarmonicFit::new(frame, hz, top, 1e-3);
    let (mut power, mut residual) = (Vec::new(), Vec::new());
    c.bench_function("separate/harmonic_fit/3_voices_70hz", |b| {
        b.iter(|| {
            let ok = fit.fit(black_box(&x), &f0s, |_, _| 1.0, &mut power, &mut residual);
            black_box((ok, &power));
        })
    });
}

criterion_group!(benches, bench, bench_crowd, bench_fit);

/// `AVSEP_SEPARATE_ITERS=n` runs n hops of the default (adapting GSC) without criterion, for
/// measuring CPU time with `perf stat` on a loaded machine.
fn main() {
    if let Some(n) = std::env::var("AVSEP_SEPARATE_ITERS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
    {
        let json = std::env::var("AVSEP_SEPARATE_CONFIG").unwrap_or_else(|_| "{}".into());
        let mut cfg: SeparatorConfig = serde_json::from_str(&json).unwrap();
        cfg.lifecycle.rest_after_s = 0.0;
        let mut sep = Separator::new(&layout(), &cfg).unwrap();
        let input = frames(64, sep.frame_geometry().bins());
        let ts: Vec<Vec<Target>> = (0..64).map(|f| targets(f, 0.0)).collect();
        let mut out = Vec::new();
        for f in 0..n {
            sep.process_into(black_box(&input[f % 64]), &ts[f % 64], &mut out);
            black_box(&out);
        }
        return;
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}
