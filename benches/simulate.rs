//! Cost of the room simulator's parts: one room response for a circular array, and a short
//! meeting scene end to end.

use std::hint::black_box;

use avsep::geometry::Vec3;
use avsep::scene::sim::calibrate::reverberation_for;
use avsep::scene::sim::render::{RenderSettings, Renderer};
use avsep::scene::sim::room::ShoeboxRoom;
use avsep::scene::sim::{self, PresetOptions, SimConfig};
use criterion::{Criterion, criterion_group, criterion_main};

fn room_response(c: &mut Criterion) {
    let size = Vec3::new(6.0, 5.0, 3.0);
    let mics: Vec<Vec3> = (0..8)
        .map(|i| {
            let a = i as f64 * std::f64::consts::PI / 4.0;
            Vec3::new(3.0 + 0.05 * a.cos(), 2.5 + 0.05 * a.sin(), 0.8)
        })
        .collect();
    let src = Vec3::new(2.0, 3.5, 1.2);
    let rev = reverberation_for(&size, 0.3, &src, &mics[0], 343.0).unwrap();
    let room = ShoeboxRoom::new(size, rev.absorption, 343.0, 16000.0).unwrap();
    let renderer = Renderer::new(
        room,
        mics,
        RenderSettings {
            hop: 800,
            response_len: (rev.response_s * 16000.0) as usize,
            early_len: 1280,
            late_update_m: 0.25,
            highpass_hz: 60.0,
        },
    );
    c.bench_function("uca8 room response, 8 mics, RT60 0.3 s", |b| {
        b.iter(|| black_box(renderer.response_at(black_box(&src))))
    });
}

fn short_scene(c: &mut Criterion) {
    let opts = PresetOptions {
        duration_s: Some(2.0),
        ..Default::default()
    };
    let cfg = SimConfig::preset("uca8", &opts, 1).unwrap();
    let mut group = c.benchmark_group("scene");
    group.sample_size(10);
    group.bench_function("uca8 2 s", |b| {
        b.iter(|| black_box(sim::simulate(black_box(&cfg), 1).unwrap()))
    });
    group.finish();
}

criterion_group!(benches, room_response, short_scene);
criterion_main!(benches);
