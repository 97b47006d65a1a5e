//! Localiser speed: one 128 ms frame (2048 samples at 16 kHz) of an 8-mic UCA (28 pairs) with
//! three sources, three candidates per search; the GCC computation from the spectra is included.
//!
//! Run: `cargo bench --bench localize`. Targets (one core): directions <= 1 ms, positions <= 3 ms.
//! Each case is timed twice: `wall/...` (criterion's wall clock) and `cpu/...` (this thread's CPU
//! time, which stays meaningful when other processes share the cores).

use std::f64::consts::PI;
use std::hint::black_box;
use std::time::Duration;

use avsep::dsp::{Complex, MultiSpectrum, Stft};
use avsep::geometry::{Aabb, Layout, MicArray, Vec3, direction_from_angles};
use avsep::localize::{Localizer, LocalizerConfig, SearchMode};
use criterion::{Criterion, criterion_group, criterion_main};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const FS: f64 = 16000.0;
const FRAME: usize = 2048;

/// A deterministic pseudo-random sequence in [-0.5, 0.5).
fn noise(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n).map(|_| rng.random_range(-0.5..0.5)).collect()
}

/// CPU time consumed by the calling thread so far.
fn thread_cpu_time() -> Duration {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime only writes the timespec we pass; the clock id is a constant.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    assert_eq!(rc, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID) failed");
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

fn layout() -> Layout {
    let centre = Vec3::new(3.0, 2.5, 1.0);
    let mics = (0..8)
        .map(|i| {
            let a = 2.0 * PI * i as f64 / 8.0;
            centre + Vec3::new(0.05 * a.cos(), 0.05 * a.sin(), 0.0)
        })
        .collect();
    let array = MicArray::new("uca8", mics, (0..8).collect()).unwrap();
    let region = Aabb::new(Vec3::zeros(), Vec3::new(6.0, 5.0, 3.0)).unwrap();
    Layout::new(16000, 343.0, vec![array], vec![], Some(region)).unwrap()
}

/// Spectra of three far-apart sources of different loudness: each source's frame spectrum delayed
/// per microphone, plus sensor noise.
fn spectra(layout: &Layout) -> MultiSpectrum {
    let array = &layout.arrays[0];
    let centre = array.centroid();
    let mut stft = Stft::new(FRAME);
    let mut out = MultiSpectrum::zeros(8, FRAME / 2 + 1);
    let mut src = vec![Complex::new(0.0, 0.0); FRAME / 2 + 1];
    for (s, &(az, el, gain)) in [
        (20.0f64, 15.0f64, 1.0),
        (140.0, 30.0, 0.8),
        (-90.0, 10.0, 0.6),
    ]
    .iter()
    .enumerate()
    {
        let pos = centre + direction_from_angles(az.to_radians(), el.to_radians()) * 2.0;
        stft.forward(&noise(FRAME, s as u64 + 1), &mut src);
        for (m, mic) in array.mics.iter().enumerate() {
            let delay = (pos - mic).norm() / 343.0;
            for (k, (y, x)) in out.channel_mut(m).iter_mut().zip(&src).enumerate() {
                let w = 2.0 * PI * k as f64 * FS / FRAME as f64;
                *y += x * Complex::from_polar(gain, -w * delay);
            }
        }
    }
    for m in 0..8 {
        let mut sensor = vec![Complex::new(0.0, 0.0); FRAME / 2 + 1];
        stft.forward(&noise(FRAME, 100 + m as u64), &mut sensor);
        for (y, n) in out.channel_mut(m).iter_mut().zip(&sensor) {
            *y += n * 0.05;
        }
    }
    out
}

fn bench(c: &mut Criterion) {
    let layout = layout();
    let spectra = spectra(&layout);
    for (name, search) in [
        ("directions_uca8_3cand", SearchMode::Directions),
        ("positions_src_uca8_3cand", SearchMode::Positions),
    ] {
        let cfg = LocalizerConfig {
            search,
            max_candidates: 3,
            ..LocalizerConfig::default()
        };
        let mut loc = Localizer::new(&layout, &cfg, 1).unwrap();
        let obs = loc.process(&spectra);
        for d in &obs[0].doas {
            eprintln!(
                "{name}: az {:.1} el {:.1} p {:.3}",
                d.azimuth.to_degrees(),
                d.elevation.to_degrees(),
                d.power
            );
        }
        for d in &obs[0].points {
            eprintln!("{name}: {:?} p {:.3}", d.position.as_slice(), d.power);
        }
        let n = obs[0].doas.len() + obs[0].points.len();
        assert_eq!(n, 3, "{name}: {n} candidates");
        c.bench_function(&format!("wall/{name}"), |b| {
            b.iter(|| black_box(loc.process(black_box(&spectra))))
        });
        c.bench_function(&format!("cpu/{name}"), |b| {
            b.iter_custom(|iters| {
                let start = thread_cpu_time();
                for _ in 0..iters {
                    black_box(loc.process(black_box(&spectra)));
                }
                thread_cpu_time() - start
            })
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
