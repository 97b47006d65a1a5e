//! End-to-end checks of `avsep eval`: a scene and an output folder built by hand, whose scores are
//! known in advance.
//!
//! Scene (4 s, 8 kHz): one array at (0, 0, 1.5), one camera at (-1, 0, 1.5) looking along +x.
//! s1 stands at (2, 0, 1.5) and speaks in [0.5, 3.5); s2 walks along y = 2 from x = 1.4 at 0.5 m/s
//! (entering the camera's view at t = 1.45) and speaks in [1.0, 2.5).
//! Output: label 1.0 follows s1 0.2 m off sideways; s2 is followed 0.2 m off along the camera ray
//! by label 2.0 until t = 2 and by 3.0 after (one identity switch). Streams: 1.0 is exactly s1's
//! signal, 2.0 and 3.0 carry s2's signal before and after t = 2.

use std::path::Path;
use std::process::Command;

use avsep::eval::tracks::{TrackingFigures, TracksReport};
use avsep::eval::{EvalConfig, EvalReport, evaluate, plots::write_plots};
use avsep::geometry::{Camera, Layout, MicArray, Vec3, azimuth_of, deg, rad};
use avsep::label::Label;
use avsep::scene::format::{TrackFile, TracksLine};
use avsep::scene::output::Output;
use avsep::scene::{
    Audio, AudioMeasurementFrame, Doa, JsonlWriter, SampleFormat, Scene, Truth, TruthSource,
    measurement_to_line,
};
use nalgebra::Matrix3;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

const FS: u32 = 8000;
const N: usize = 32000;
const STEPS: usize = 40;
const DT: f64 = 0.1;

fn cam_centre() -> Vec3 {
    Vec3::new(-1.0, 0.0, 1.5)
}

fn s1_at(_t: f64) -> Vec3 {
    Vec3::new(2.0, 0.0, 1.5)
}

fn s2_at(t: f64) -> Vec3 {
    Vec3::new(1.4 + 0.5 * t, 2.0, 1.5)
}

fn track1_at(t: f64) -> Vec3 {
    s1_at(t) + Vec3::new(0.0, 0.2, 0.0)
}

fn track2_at(t: f64) -> Vec3 {
    let p = s2_at(t);
    p + (p - cam_centre()).normalize() * 0.2
}

fn noise_burst(seed: u64, from: usize, to: usize) -> Vec<f32> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let d = Normal::new(0.0, 0.1).unwrap();
    (0..N)
        .map(|i| {
            let v = d.sample(&mut rng) as f32;
            if (from..to).contains(&i) { v } else { 0.0 }
        })
        .collect()
}

fn layout() -> Layout {
    let mics = (0..4)
        .map(|i| {
            let a = i as f64 * std::f64::consts::FRAC_PI_2;
            Vec3::new(0.05 * a.cos(), 0.05 * a.sin(), 1.5)
        })
        .collect();
    let array = MicArray::new("a0", mics, vec![0, 1, 2, 3]).unwrap();
    let k = Matrix3::new(500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0);
    // Camera axes in world coordinates: x right = -y, y down = -z, z forward = +x.
    let r = Matrix3::new(0.0, -1.0, 0.0, 0.0, 0.0, -1.0, 1.0, 0.0, 0.0);
    let t = -(r * cam_centre());
    let cam = Camera::from_krt("cam0", 640.0, 480.0, k, r, t, None).unwrap();
    Layout::new(FS, 343.0, vec![array], vec![cam], None).unwrap()
}

fn scene(dir: &Path) -> Scene {
    let s1 = noise_burst(1, 4000, 28000);
    let s2 = noise_burst(2, 8000, 20000);
    let mut samples = Vec::with_capacity(4 * N);
    for i in 0..N {
        for _ in 0..4 {
            samples.push(s1[i] + s2[i]);
        }
    }
    let traj = |f: fn(f64) -> Vec3| {
        (0..=40)
            .map(|k| (k as f64 * 0.1, f(k as f64 * 0.1)))
            .collect()
    };
    Scene {
        dir: dir.to_path_buf(),
        layout: layout(),
        audio: Some(Audio {
            sample_rate: FS,
            channels: 4,
            samples,
        }),
        detections: vec![],
        audio_measurements: vec![],
        truth: Some(Truth {
            sources: vec![
                TruthSource {
                    id: "s1".into(),
                    signal: Some(s1),
                    trajectory: traj(s1_at),
                    active: vec![(0.5, 3.5)],
                },
                TruthSource {
                    id: "s2".into(),
                    signal: Some(s2),
                    trajectory: traj(s2_at),
                    active: vec![(1.0, 2.5)],
                },
            ],
        }),
    }
}

fn track(label: Label, p: Vec3) -> TrackFile {
    TrackFile {
        label,
        position: p.into(),
        velocity: [0.0; 3],
        existence: 1.0,
        speaking: 1.0,
        covariance: None,
    }
}

const L1: Label = Label::new(1, 0);
const L2: Label = Label::new(2, 0);
const L3: Label = Label::new(3, 0);

/// Number of sources the evaluator must see as active in the measurement frame starting at step k.
fn active_in_frame(k: usize) -> Vec<fn(f64) -> Vec3> {
    let mut v: Vec<fn(f64) -> Vec3> = Vec::new();
    if (5..35).contains(&k) {
        v.push(s1_at);
    }
    if (10..25).contains(&k) {
        v.push(s2_at);
    }
    v
}

fn write_output(scene: &Scene, dir: &Path) {
    std::fs::create_dir_all(dir.join("audio")).unwrap();
    let mut w = JsonlWriter::create(&dir.join("tracks.jsonl")).unwrap();
    for k in 0..STEPS {
        let t = k as f64 * DT;
        let l2 = if k < 20 { L2 } else { L3 };
        w.write(&TracksLine {
            t,
            tracks: vec![track(L1, track1_at(t)), track(l2, track2_at(t))],
        })
        .unwrap();
    }
    w.finish().unwrap();

    let centroid = scene.layout.arrays[0].centroid();
    let mut w = JsonlWriter::create(&dir.join("measurements.jsonl")).unwrap();
    for k in 0..STEPS {
        let t = k as f64 * DT;
        let mid = t + 0.5 * DT;
        let active = active_in_frame(k);
        let mut points: Vec<Vec3> = active
            .iter()
            .map(|f| f(mid) + Vec3::new(0.3, 0.0, 0.0))
            .collect();
        points.push(Vec3::new(-2.0, -2.0, 1.5));
        let mut doas: Vec<Doa> = active
            .iter()
            .map(|f| Doa {
                azimuth: azimuth_of(&(f(mid) - centroid)) + rad(3.0),
                elevation: None,
                energy: None,
            })
            .collect();
        doas.push(Doa {
            azimuth: rad(-135.0),
            elevation: None,
            energy: None,
        });
        let frame = AudioMeasurementFrame {
            t,
            array: 0,
            doas,
            points,
            activity: None,
        };
        w.write(&measurement_to_line(&frame, "a0")).unwrap();
    }
    w.finish().unwrap();

    let truth = scene.truth.as_ref().unwrap();
    let s1 = truth.sources[0].signal.clone().unwrap();
    let s2 = truth.sources[1].signal.clone().unwrap();
    let split = 16000; // t = 2 s
    let before: Vec<f32> = (0..N)
        .map(|i| if i < split { s2[i] } else { 0.0 })
        .collect();
    let after: Vec<f32> = (0..N)
        .map(|i| if i >= split { s2[i] } else { 0.0 })
        .collect();
    for (label, sig) in [(L1, s1), (L2, before), (L3, after)] {
        Audio::mono(FS, sig)
            .write(&dir.join(format!("audio/{label}.wav")), SampleFormat::F32)
            .unwrap();
    }
}

struct Fixture {
    _tmp: tempfile::TempDir,
    scene_dir: std::path::PathBuf,
    out_dir: std::path::PathBuf,
}

fn fixture() -> Fixture {
    let tmp = tempfile::tempdir().unwrap();
    let scene_dir = tmp.path().join("scene");
    let out_dir = tmp.path().join("out");
    let s = scene(&scene_dir);
    s.save(&scene_dir).unwrap();
    write_output(&s, &out_dir);
    Fixture {
        _tmp: tmp,
        scene_dir,
        out_dir,
    }
}

fn run_eval(f: &Fixture) -> (Scene, Output, EvalReport) {
    let scene = Scene::load(&f.scene_dir).unwrap();
    let out = Output::load(&f.out_dir, &scene.layout).unwrap();
    let report = evaluate(&scene, &out, &EvalConfig::default()).unwrap();
    (scene, out, report)
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn tracking_scores_match_hand_computation() {
    let f = fixture();
    let (_, _, r) = run_eval(&f);
    let t = r.tracks.as_ref().unwrap();
    assert_eq!((t.steps, t.labels), (STEPS, 3));
    let all = &t.all;
    assert_position_scores(all);
    assert_ospa2_over_time(t);
    assert_direction_and_pixel_scores(all);
    assert_source_scores(all);

    // Audible figures: s1 is audible from 0.5 s, s2 from 1.0 s, so the tracks before that are
    // false positives (5 + 10), and nothing is missed.
    let au = &t.audible.position;
    assert_eq!((au.false_positives, au.misses, au.switches), (15, 0, 1));
}

/// OSPA and CLEAR MOT / identity scores in 3-D against every source.
fn assert_position_scores(all: &TrackingFigures) {
    // Every step pairs both truths with a track 0.2 m away.
    assert!(close(all.ospa.total, 0.2, 1e-9), "{:?}", all.ospa);
    assert!(close(all.ospa.cardinality, 0.0, 1e-12));
    let p = &all.position;
    assert_eq!(p.switches, 1);
    assert_eq!((p.false_positives, p.misses), (0, 0));
    assert!(close(p.motp.unwrap(), 0.2, 1e-9));
    assert!(close(p.mota.unwrap(), 1.0 - 1.0 / 80.0, 1e-12));
    // IDTP: s1 40 steps + s2 20 steps with one of its two labels, out of 80 + 80.
    assert!(close(p.idf1.unwrap(), 120.0 / 160.0, 1e-12));
    assert_eq!(p.mostly_tracked, 2);
    // GOSPA: two pairs 0.2 m apart, nothing missed or false, at every step.
    assert!(close(all.gospa.total, 0.4, 1e-9), "{:?}", all.gospa);
    assert!(close(
        all.gospa.missed + all.gospa.false_objects,
        0.0,
        1e-12
    ));
    // HOTA: 0.2 m at the 0.5 m gate is similarity 0.6, a true positive at the 12 thresholds
    // 0.05-0.60 and a miss plus a false positive at the 7 above. Where matched, s1 keeps one
    // label (40 of 40 steps) and s2 shares two (20 of 40 each): AssA = (40 + 2 * 20 / 2) / 80.
    let h = p.hota.unwrap();
    let matched = 12.0 / 19.0;
    assert!(close(h.deta, matched, 1e-9), "{h:?}");
    assert!(close(h.assa, matched * 0.75, 1e-9), "{h:?}");
    assert!(close(h.hota, matched * 0.75f64.sqrt(), 1e-9), "{h:?}");
    assert!(close(h.loca, (12.0 * 0.6 + 7.0) / 19.0, 1e-9), "{h:?}");
}

/// OSPA(2) at each step and its mean.
fn assert_ospa2_over_time(t: &TracksReport) {
    // OSPA(2) with a 10-step window: 0.2 except for the 9 windows that straddle the switch,
    // where the sets are {s1, s2} vs {1.0, 2.0, 3.0} with a steps of 2.0 and b of 3.0.
    let expected: Vec<f64> = (0..STEPS)
        .map(|k| {
            if !(20..29).contains(&k) {
                0.2
            } else {
                let a = (29 - k) as f64;
                let b = 10.0 - a;
                let s2 = (0.2 * a + b).min(0.2 * b + a) / 10.0;
                (0.2 + s2 + 1.0) / 3.0
            }
        })
        .collect();
    for (got, want) in t.ospa2_over_time.iter().zip(&expected) {
        assert!(
            close(got.value, *want, 1e-9),
            "t = {}: {} vs {want}",
            got.t,
            got.value
        );
    }
    let mean = expected.iter().sum::<f64>() / STEPS as f64;
    assert!(close(t.all.ospa2.total, mean, 1e-9));
}

/// Azimuth error of the matched pairs, pixel error in the camera, and direction-space switches.
fn assert_direction_and_pixel_scores(all: &TrackingFigures) {
    // Azimuth error from the array centroid, over all matched pairs.
    let c = Vec3::new(0.0, 0.0, 1.5);
    let az_err = |a: Vec3, b: Vec3| {
        deg(avsep::geometry::angle_diff(azimuth_of(&(a - c)), azimuth_of(&(b - c))).abs())
    };
    let errs: Vec<f64> = (0..STEPS)
        .flat_map(|k| {
            let t = k as f64 * DT;
            [
                az_err(track1_at(t), s1_at(t)),
                az_err(track2_at(t), s2_at(t)),
            ]
        })
        .collect();
    let want = errs.iter().sum::<f64>() / errs.len() as f64;
    assert!(close(all.azimuth_error_deg.mean.unwrap(), want, 1e-9));
    // Pixel error: s1's track is 0.2 m sideways at 3 m depth (500 * 0.2 / 3 px) in all 40 steps;
    // s2's lies on the camera ray (0 px) in the 25 steps it is in view (t >= 1.5).
    let px = &all.pixel_error_px[0];
    assert_eq!(px.error_px.count, 65);
    assert!(close(
        px.error_px.mean.unwrap(),
        40.0 * 100.0 / 3.0 / 65.0,
        1e-6
    ));
    assert!(close(px.error_px.median.unwrap(), 100.0 / 3.0, 1e-6));
    // Direction space sees the same switch.
    assert_eq!(all.direction.switches, 1);
}

/// Per-source onset, initiation delay and the labels that carried each source.
fn assert_source_scores(all: &TrackingFigures) {
    let s1 = &all.sources[0];
    let s2 = &all.sources[1];
    assert_eq!((s1.onset_s, s1.initiation_delay_s), (Some(0.5), Some(0.0)));
    // s2 speaks from 1.0 s but enters the camera's view at 1.45 s: onset at the 1.5 s step.
    assert!(close(s2.onset_s.unwrap(), 1.5, 1e-9));
    assert_eq!(s2.initiation_delay_s, Some(0.0));
    assert_eq!((s1.labels_matched, s2.labels_matched), (1, 2));
    assert_eq!((s1.stream_labels, s2.stream_labels), (1, 2));
    assert_eq!(s2.active_labels[0].label, L2);
    assert!(close(s2.active_labels[0].share, 10.0 / 15.0, 1e-12));
}

#[test]
fn measurement_scores_match_hand_computation() {
    let f = fixture();
    let (_, _, r) = run_eval(&f);
    let m = &r.measurements.as_ref().unwrap().arrays[0];
    assert_eq!(m.frames, STEPS);
    assert!(close(m.frame_s, DT, 1e-9));
    // Frames with m active sources carry m points 0.3 m off plus one false point:
    // OSPA (0.3 m + 1) / (m + 1), and 1 for a frame with no active source.
    let per = |k: usize| {
        let n = active_in_frame(k).len() as f64;
        (0.3 * n + 1.0) / (n + 1.0)
    };
    let want = (0..STEPS).map(per).sum::<f64>() / STEPS as f64;
    let p = m.points.as_ref().unwrap();
    assert!(close(p.ospa.total, want, 1e-9), "{:?} vs {want}", p.ospa);
    assert!(close(
        p.ospa.localisation + p.ospa.cardinality,
        p.ospa.total,
        1e-12
    ));
    let d = m.doas.as_ref().unwrap();
    // 30 frames of s1 and 15 of s2, each seen 3 deg off; one false candidate per frame.
    assert_eq!((d.pairs, d.missed), (45, 0));
    assert_eq!(d.within_tolerance, Some(1.0));
    assert!(close(d.error_deg.median.unwrap(), 3.0, 1e-6));
    assert!(close(d.false_candidate_rate.unwrap(), 40.0 / 85.0, 1e-12));
}

#[test]
fn separation_scores_match_hand_computation() {
    let f = fixture();
    let (_, _, r) = run_eval(&f);
    let a = r.audio.as_ref().unwrap();
    assert_eq!(a.filter_taps, 512);
    let (s1, s2) = (&a.sources[0], &a.sources[1]);
    assert_eq!(s1.label, Some(L1));
    assert_eq!(s2.label, Some(L2));
    assert!(close(s1.active_s, 3.0, 1e-9) && close(s2.active_s, 1.5, 1e-9));
    // s1's stream is exact; the microphone holds s2 at half s1's active time with equal power.
    assert!(s1.si_sdr_db.unwrap() > 150.0);
    let half = 10.0 * 2f64.log10();
    assert!(close(s1.si_sdr_mixture_db.unwrap(), half, 0.2), "{s1:?}");
    assert!(s1.si_sdr_improvement_db.unwrap() > 140.0);
    let b = s1.bss.unwrap();
    assert!(
        b.sdr_db > 60.0 && b.sir_db > 60.0 && b.sar_db > 60.0,
        "{b:?}"
    );
    let bm = s1.bss_mixture.unwrap();
    assert!(
        close(bm.sir_db, half, 0.3) && close(bm.sdr_db, half, 0.3),
        "{bm:?}"
    );
    assert!(bm.sar_db > 40.0, "{bm:?}");
    // s2's stream 2.0 holds it for 1.0-2.0 s and is silent for 2.0-2.5 s: the best scale is 2/3
    // and SI-SDR = 10 log10((4/9) / (1/9 * 2/3 + 4/9 * 1/3)) = 10 log10(2). The microphone has
    // s1 at equal power over s2's active time: 0 dB.
    assert!(close(s2.si_sdr_db.unwrap(), half, 0.2), "{s2:?}");
    assert!(close(s2.si_sdr_mixture_db.unwrap(), 0.0, 0.2), "{s2:?}");
    assert!(close(s2.si_sdr_improvement_db.unwrap(), half, 0.3));
    // Continuity: s2's three half-second blocks split 2:1 across 2.0 and 3.0.
    assert_eq!(s1.continuity.stream_labels, 1);
    assert_eq!(s2.continuity.blocks, 3);
    assert_eq!(s2.continuity.stream_labels, 2);
    assert!(close(s2.continuity.shares[0].share, 2.0 / 3.0, 1e-12));
    assert!(a.mean.si_sdr_improvement_db.unwrap() > 70.0);
}

#[test]
fn plots_are_written_as_svg() {
    let f = fixture();
    let (scene, out, r) = run_eval(&f);
    let dir = f.out_dir.join("plots");
    let files = write_plots(&scene, &out, &r, &dir).unwrap();
    let names: Vec<String> = files
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["trajectories.svg", "azimuth.svg", "ospa2.svg"]);
    for p in &files {
        let text = std::fs::read_to_string(p).unwrap();
        assert!(text.starts_with("<svg"), "{}", p.display());
        assert!(text.trim_end().ends_with("</svg>"), "{}", p.display());
    }
    let traj = std::fs::read_to_string(&files[0]).unwrap();
    assert!(traj.contains("track 1.0") && traj.contains("truth s2"));
    assert!(traj.contains("<polyline") || traj.contains("<path"));
    // Deterministic: drawing again gives the same bytes.
    let again = write_plots(&scene, &out, &r, &f.out_dir.join("plots2")).unwrap();
    for (a, b) in files.iter().zip(&again) {
        assert_eq!(std::fs::read(a).unwrap(), std::fs::read(b).unwrap());
    }
}

#[test]
fn the_command_prints_tables_and_writes_json() {
    let f = fixture();
    let json = f.out_dir.join("report.json");
    let plots = f.out_dir.join("figs");
    let o = Command::new(env!("CARGO_BIN_EXE_avsep"))
        .arg("eval")
        .arg(&f.scene_dir)
        .arg(&f.out_dir)
        .arg("--json")
        .arg(&json)
        .arg("--plots")
        .arg(&plots)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for needle in [
        "Measurements",
        "Tracks",
        "Audio",
        "OSPA(2)",
        "3-D ID switches",
    ] {
        assert!(stdout.contains(needle), "missing {needle} in\n{stdout}");
    }
    let report: EvalReport =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    // The binary parses the same files (up to the last bit of a parsed float).
    let (_, _, direct) = run_eval(&f);
    let (a, b) = (report.tracks.unwrap().all, direct.tracks.unwrap().all);
    assert!(close(a.ospa.total, b.ospa.total, 1e-12));
    assert!(close(a.ospa2.total, b.ospa2.total, 1e-12));
    assert_eq!(a.position.switches, 1);
    assert_eq!(a.position.idf1, b.position.idf1);
    let (a, b) = (report.audio.unwrap(), direct.audio.unwrap());
    assert!(close(
        a.sources[1].si_sdr_db.unwrap(),
        b.sources[1].si_sdr_db.unwrap(),
        1e-9
    ));
    assert!(plots.join("ospa2.svg").is_file());
}

#[test]
fn bad_inputs_exit_2_with_a_message() {
    let f = fixture();
    let bin = env!("CARGO_BIN_EXE_avsep");
    // Missing output folder: named in the message.
    let missing = f.out_dir.join("nope");
    let o = Command::new(bin)
        .arg("eval")
        .arg(&f.scene_dir)
        .arg(&missing)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("nope"));
    // A scene without truth.
    let mut s = Scene::load(&f.scene_dir).unwrap();
    s.truth = None;
    let bare = f.out_dir.join("bare_scene");
    s.save(&bare).unwrap();
    let o = Command::new(bin)
        .arg("eval")
        .arg(&bare)
        .arg(&f.out_dir)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no truth"), "{err}");
    // A stream of the wrong length names the file.
    Audio::mono(FS, vec![0.0; 10])
        .write(&f.out_dir.join("audio/9.0.wav"), SampleFormat::F32)
        .unwrap();
    let o = Command::new(bin)
        .arg("eval")
        .arg(&f.scene_dir)
        .arg(&f.out_dir)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("audio/9.0.wav"));
}
