//! The localiser driven the way the pipeline drives it: spectra of every audio column of the
//! layout from `dsp::StreamingStft`, one localisation frame at a time.
//!
//! The scene measurements of the issue (uca8 azimuth hit rate, paper-linear6 OSPA) are in the
//! ignored tests at the end: `cargo test --release --test localize -- --ignored --nocapture`.

#[path = "localize/scene_eval.rs"]
mod scene_eval;

use std::f64::consts::PI;

use avsep::dsp::{Complex, FrameGeometry, StreamingStft};
use avsep::geometry::{
    Aabb, Layout, MicArray, Vec3, angle_diff, azimuth_of, deg, direction_from_angles, rad,
};
use avsep::localize::{ArrayObservation, Localizer, LocalizerConfig, SearchMode};
use avsep::scene::Scene;
use avsep::scene::sim::{PresetOptions, SimConfig, simulate};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use realfft::RealFftPlanner;

const FS: f64 = 16000.0;
const C: f64 = 343.0;

/// A deterministic pseudo-random sequence with unit-ish variance.
fn noise(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n).map(|_| rng.random_range(-1.7..1.7)).collect()
}

/// Free-field recordings of `sources` at `mics`: exact fractional delays and 1/r gains.
fn record(mics: &[Vec3], sources: &[(Vec3, Vec<f64>)], sensor_noise: f64) -> Vec<Vec<f64>> {
    let len = sources[0].1.len();
    let n = (len + 2048).next_power_of_two();
    let mut planner = RealFftPlanner::<f64>::new();
    let (fwd, inv) = (planner.plan_fft_forward(n), planner.plan_fft_inverse(n));
    let spectra: Vec<Vec<Complex>> = sources
        .iter()
        .map(|(_, s)| {
            let mut buf = vec![0.0; n];
            buf[..len].copy_from_slice(s);
            let mut out = vec![Complex::new(0.0, 0.0); n / 2 + 1];
            fwd.process(&mut buf, &mut out).unwrap();
            out
        })
        .collect();
    mics.iter()
        .enumerate()
        .map(|(m, mic)| {
            let mut acc = vec![Complex::new(0.0, 0.0); n / 2 + 1];
            for ((pos, _), spec) in sources.iter().zip(&spectra) {
                let r = (pos - mic).norm();
                for (k, (a, s)) in acc.iter_mut().zip(spec).enumerate() {
                    let phase = -2.0 * PI * k as f64 / n as f64 * r / C * FS;
                    *a += s * Complex::from_polar(1.0 / r, phase);
                }
            }
            acc[0].im = 0.0;
            acc[n / 2].im = 0.0;
            let mut x = vec![0.0; n];
            inv.process(&mut acc, &mut x).unwrap();
            let e = noise(len, 500 + m as u64);
            (0..len)
                .map(|t| x[t] / n as f64 + sensor_noise * e[t])
                .collect()
        })
        .collect()
}

/// Runs the localiser over non-overlapping frames streamed through `StreamingStft`.
fn localise(loc: &mut Localizer, channels: &[Vec<f64>]) -> Vec<Vec<ArrayObservation>> {
    let frame = loc.frame_size();
    let mut stft = StreamingStft::new(FrameGeometry { frame, hop: frame }, channels.len());
    let mut out = Vec::new();
    let mut start = 0;
    while start + frame <= channels[0].len() {
        let hop: Vec<&[f64]> = channels.iter().map(|c| &c[start..start + frame]).collect();
        out.push(loc.process(stft.push(&hop)));
        start += frame;
    }
    out
}

fn uca(centre: Vec3, radius: f64, first_channel: usize, id: &str) -> MicArray {
    let mics = (0..8)
        .map(|i| {
            let a = 2.0 * PI * i as f64 / 8.0;
            centre + Vec3::new(radius * a.cos(), radius * a.sin(), 0.0)
        })
        .collect();
    MicArray::new(id, mics, (first_channel..first_channel + 8).collect()).unwrap()
}

#[test]
fn two_arrays_in_channel_column_order_each_see_both_talkers() {
    // The second array's channels come first in the audio columns: the localiser must follow
    // `channels`, not the array order.
    let a0 = uca(Vec3::new(2.0, 2.0, 0.8), 0.05, 8, "left");
    let a1 = uca(Vec3::new(4.0, 2.0, 0.8), 0.05, 0, "right");
    let region = Aabb::new(Vec3::zeros(), Vec3::new(6.0, 4.0, 2.7)).unwrap();
    let layout = Layout::new(16000, C, vec![a0, a1], vec![], Some(region)).unwrap();
    // Equidistant from both arrays, so each array hears both at the same level.
    let talkers = [Vec3::new(3.0, 3.4, 1.5), Vec3::new(3.0, 0.6, 1.3)];
    let sources: Vec<(Vec3, Vec<f64>)> = talkers
        .iter()
        .enumerate()
        .map(|(i, p)| (*p, noise(2048 * 6, 10 + i as u64)))
        .collect();
    let mut columns = vec![Vec::new(); 16];
    for array in &layout.arrays {
        let rec = record(&array.mics, &sources, 0.01);
        for (ch, x) in array.channels.iter().zip(rec) {
            columns[*ch] = x;
        }
    }
    let mut loc = Localizer::new(&layout, &both_searches(), 5).unwrap();
    for frame in localise(&mut loc, &columns) {
        assert_eq!(frame.len(), 2);
        for obs in &frame {
            let centre = layout.arrays[obs.array].centroid();
            for talker in &talkers {
                let az = azimuth_of(&(talker - centre));
                let hit = obs
                    .doas
                    .iter()
                    .any(|d| angle_diff(d.azimuth, az).abs() < rad(3.0));
                assert!(
                    hit,
                    "array {} misses the talker at azimuth {:.1} deg: {:?}",
                    obs.array,
                    deg(az),
                    obs.doas
                        .iter()
                        .map(|d| (deg(d.azimuth), d.power))
                        .collect::<Vec<_>>()
                );
            }
            assert!(obs.points.len() >= 2);
            assert!(obs.activity.is_finite() && (0.0..=1.0).contains(&obs.activity));
        }
    }
}

#[test]
fn candidates_are_in_world_coordinates_and_inside_the_region() {
    let array = uca(Vec3::new(1.0, 3.0, 1.1), 0.05, 0, "a");
    let region = Aabb::new(Vec3::new(0.5, 0.5, 0.0), Vec3::new(5.0, 4.0, 2.5)).unwrap();
    let layout = Layout::new(16000, C, vec![array.clone()], vec![], Some(region)).unwrap();
    let talker = Vec3::new(3.5, 1.5, 1.6);
    let rec = record(&array.mics, &[(talker, noise(2048 * 4, 3))], 0.01);
    let mut loc = Localizer::new(&layout, &both_searches(), 9).unwrap();
    for frame in localise(&mut loc, &rec) {
        let obs = &frame[0];
        let expect = (talker - array.centroid()).normalize();
        let d = &obs.doas[0];
        assert!(deg(d.direction.dot(&expect).acos()) < 2.0);
        assert!((d.direction - direction_from_angles(d.azimuth, d.elevation)).norm() < 1e-9);
        for p in &obs.points {
            assert!(region.contains(&p.position), "{:?}", p.position);
        }
        let p = obs.points[0].position - array.centroid();
        assert!(deg(p.normalize().dot(&expect).acos()) < 2.0);
    }
}

/// The default configuration with both searches on every array (the default `auto` runs the
/// 3-D search only for arrays whose positions the tracker takes, which a bare localiser has
/// none of), with the overrides in `AVSEP_LOCALIZE_CONFIG` (JSON), for tuning.
fn config_from_env() -> LocalizerConfig {
    std::env::var("AVSEP_LOCALIZE_CONFIG")
        .map(|j| serde_json::from_str(&j).expect("valid localiser config JSON"))
        .unwrap_or_else(|_| both_searches())
}

/// The default configuration with directions and positions searched on every array.
fn both_searches() -> LocalizerConfig {
    LocalizerConfig {
        search: SearchMode::Both,
        ..LocalizerConfig::default()
    }
}

/// The scenes a measurement runs on: the folder in `dir_var` if set, else the preset simulated
/// in memory for each seed of `AVSEP_LOCALIZE_SEEDS` (default "1 2 3 4 5 6"). Scenes are
/// generated, never committed.
fn scenes(dir_var: &str, preset: &str, opts: &PresetOptions) -> Vec<(String, Scene)> {
    if let Ok(dir) = std::env::var(dir_var) {
        let scene = Scene::load(std::path::Path::new(&dir)).expect("scene loads");
        return vec![(dir, scene)];
    }
    let seeds = std::env::var("AVSEP_LOCALIZE_SEEDS").unwrap_or_else(|_| "1 2 3 4 5 6".into());
    seeds
        .split_whitespace()
        .map(|s| {
            let seed: u64 = s.parse().expect("seed");
            let cfg = SimConfig::preset(preset, opts, seed).expect("preset");
            (
                format!("{preset} seed {seed}"),
                simulate(&cfg, seed).expect("simulates"),
            )
        })
        .collect()
}

/// Issue measurement: uca8 with two talkers, 20 dB SNR, RT60 0.3 s. Targets: a talker active in
/// a frame is among the direction candidates within 5 degrees of azimuth in >= 90 % of frames,
/// median azimuth error <= 2 degrees. Prints the figures (it measures; it does not gate).
#[test]
#[ignore = "measurement: cargo test --release --test localize -- --ignored --nocapture"]
fn uca8_two_talkers_azimuths() {
    let opts = PresetOptions {
        speakers: Some(2),
        snr_db: Some(20.0),
        rt60_s: Some(0.3),
        ..PresetOptions::default()
    };
    let cfg = config_from_env();
    let (mut hits, mut errors) = (Vec::new(), Vec::new());
    for (name, scene) in scenes("AVSEP_UCA8_SCENE", "uca8", &opts) {
        let report = scene_eval::evaluate(&scene, &cfg, 0);
        eprintln!("uca8 [{name}]: {}", report.summary());
        assert!(report.frames > 0 && report.active > 0);
        hits.push(report.hit_rate());
        errors.push(report.median_azimuth_error());
    }
    eprintln!(
        "uca8 over {} scenes: within 5 deg {:.1} %, median azimuth error {:.2} deg (targets >= 90 %, <= 2 deg)",
        hits.len(),
        100.0 * hits.iter().sum::<f64>() / hits.len() as f64,
        errors.iter().sum::<f64>() / errors.len() as f64
    );
}

/// Issue measurement: paper-linear6 preset, mean OSPA (c = 1 m, p = 1) of the 3-D candidates
/// against the active talkers per frame (the paper's Table VI metric; it got 0.814 m). Target:
/// <= 0.7 m. Prints the figures (it measures; it does not gate).
#[test]
#[ignore = "measurement: cargo test --release --test localize -- --ignored --nocapture"]
fn paper_linear6_ospa() {
    let cfg = config_from_env();
    let mut ospas = Vec::new();
    for (name, scene) in scenes(
        "AVSEP_LINEAR6_SCENE",
        "paper-linear6",
        &PresetOptions::default(),
    ) {
        let report = scene_eval::evaluate(&scene, &cfg, 0);
        eprintln!("paper-linear6 [{name}]: {}", report.summary());
        assert!(report.frames > 0);
        ospas.push(report.mean_ospa());
    }
    eprintln!(
        "paper-linear6 over {} scenes: mean OSPA {:.3} m (target <= 0.7 m)",
        ospas.len(),
        ospas.iter().sum::<f64>() / ospas.len() as f64
    );
}
