//! Round trip and rejection tests of the scene reader and writer.

use std::path::Path;

use nalgebra::Matrix3x4;

use super::*;
use crate::geometry::{Aabb, Camera, Layout, MicArray, Pixel, Vec3};

fn sample_scene() -> Scene {
    let mics = (0..4)
        .map(|i| Vec3::new(1.0 + 0.05 * i as f64, 0.2, 1.0))
        .collect();
    let array = MicArray::new("a0", mics, vec![0, 1, 2, 3]).unwrap();
    let p = Matrix3x4::new(
        -1021.7, -827.2, -575.8, 7071.5, 31.8, 142.0, -1184.0, 2012.8, 0.04, -0.83, -0.56, 3.81,
    );
    let cam = Camera::from_projection("cam0", 1920.0, 1080.0, p, None, None).unwrap();
    let region = Aabb::new(Vec3::zeros(), Vec3::new(7.7, 3.4, 2.7)).unwrap();
    let layout = Layout::new(16000, 343.0, vec![array], vec![cam], Some(region)).unwrap();
    let frames = 1600;
    let samples = (0..frames * 4)
        .map(|i| ((i as f32) * 0.01).sin() * 0.5)
        .collect();
    let sig: Vec<f32> = (0..frames).map(|i| (i as f32 * 0.02).cos() * 0.1).collect();
    Scene {
        dir: Default::default(),
        layout,
        audio: Some(Audio {
            sample_rate: 16000,
            channels: 4,
            samples,
        }),
        detections: vec![
            DetectionFrame {
                t: 0.0,
                camera: 0,
                boxes: vec![FaceBox {
                    x: 900.0,
                    y: 40.0,
                    w: 60.0,
                    h: 70.0,
                    score: Some(0.9),
                    point: None,
                }],
            },
            DetectionFrame {
                t: 0.05,
                camera: 0,
                boxes: vec![],
            },
            DetectionFrame {
                t: 0.09,
                camera: 0,
                boxes: vec![FaceBox {
                    x: 900.0,
                    y: 40.0,
                    w: 60.0,
                    h: 70.0,
                    score: None,
                    point: Some(Pixel::new(930.0, 90.0)),
                }],
            },
        ],
        audio_measurements: vec![AudioMeasurementFrame {
            t: 0.064,
            array: 0,
            doas: vec![Doa {
                azimuth: 0.5,
                elevation: Some(0.1),
                energy: Some(0.8),
            }],
            points: vec![Vec3::new(2.0, 1.0, 1.6)],
            activity: Some(0.7),
        }],
        truth: Some(Truth {
            sources: vec![TruthSource {
                id: "s1".into(),
                signal: Some(sig),
                trajectory: vec![
                    (0.0, Vec3::new(3.0, 0.5, 1.7)),
                    (0.1, Vec3::new(3.0, 0.6, 1.7)),
                ],
                active: vec![(0.0, 0.08)],
            }],
        }),
    }
}

fn assert_close(a: &Scene, b: &Scene) {
    assert_eq!(a.layout.arrays, b.layout.arrays);
    assert_eq!(a.layout.cameras, b.layout.cameras);
    assert_eq!(a.layout.region, b.layout.region);
    assert_eq!(a.audio, b.audio);
    assert_eq!(a.detections, b.detections);
    assert_eq!(a.truth, b.truth);
    assert_eq!(a.audio_measurements.len(), b.audio_measurements.len());
    for (x, y) in a.audio_measurements.iter().zip(&b.audio_measurements) {
        assert!((x.doas[0].azimuth - y.doas[0].azimuth).abs() < 1e-12);
        assert_eq!(x.points, y.points);
    }
}

#[test]
fn scene_round_trips_through_the_folder() {
    let dir = tempfile::tempdir().unwrap();
    let scene = sample_scene();
    scene.save(dir.path()).unwrap();
    let back = Scene::load(dir.path()).unwrap();
    assert_close(&scene, &back);
    // Saving what was read gives the same files again.
    let dir2 = tempfile::tempdir().unwrap();
    back.save(dir2.path()).unwrap();
    for f in [
        "scene.json",
        "detections.jsonl",
        "audio_measurements.jsonl",
        "truth/truth.json",
    ] {
        let a = std::fs::read_to_string(dir.path().join(f)).unwrap();
        let b = std::fs::read_to_string(dir2.path().join(f)).unwrap();
        assert_eq!(a, b, "{f}");
    }
}

fn saved() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    sample_scene().save(dir.path()).unwrap();
    dir
}

fn edit(dir: &Path, file: &str, f: impl FnOnce(String) -> String) {
    let p = dir.join(file);
    let s = std::fs::read_to_string(&p).unwrap();
    std::fs::write(&p, f(s)).unwrap();
}

fn load_err(dir: &Path) -> SceneError {
    Scene::load(dir).expect_err("malformed scene accepted")
}

#[test]
fn missing_field_is_named() {
    let d = saved();
    edit(d.path(), "scene.json", |s| {
        s.replace("\"sample_rate\"", "\"sample_rat\"")
    });
    let e = load_err(d.path());
    assert!(e.file.ends_with("scene.json"), "{e}");
    assert!(e.message.contains("sample_rate"), "{e}");
}

#[test]
fn wrong_type_is_named_with_its_path() {
    let d = saved();
    edit(d.path(), "scene.json", |s| {
        s.replacen("\"mics\": [", "\"mics\": [\"x\",", 1)
    });
    let e = load_err(d.path());
    assert_eq!(e.field.as_deref(), Some("arrays[0].mics[0]"), "{e}");
    assert!(e.line.is_some());
}

#[test]
fn channel_count_must_match_the_wav() {
    let d = saved();
    let mut s = sample_scene();
    s.audio = Some(Audio {
        sample_rate: 16000,
        channels: 3,
        samples: vec![0.0; 300],
    });
    s.audio
        .as_ref()
        .unwrap()
        .write(&d.path().join("audio.wav"), SampleFormat::I16)
        .unwrap();
    let e = load_err(d.path());
    assert!(e.file.ends_with("audio.wav"), "{e}");
    assert_eq!(e.field.as_deref(), Some("channels"));
    assert!(
        e.message.contains("3 channels") && e.message.contains("list 4"),
        "{e}"
    );
}

#[test]
fn nan_samples_are_rejected() {
    let d = saved();
    let mut a = sample_scene().audio.unwrap();
    a.samples[4 * 10 + 2] = f32::NAN;
    a.write(&d.path().join("audio.wav"), SampleFormat::F32)
        .unwrap();
    let e = load_err(d.path());
    assert_eq!(e.field.as_deref(), Some("samples"));
    assert!(e.message.contains("sample 10 of channel 2"), "{e}");
}

#[test]
fn unknown_camera_names_line_and_field() {
    let d = saved();
    edit(d.path(), "detections.jsonl", |s| {
        s.replacen("\"cam0\"", "\"cam9\"", 2)
    });
    let e = load_err(d.path());
    assert!(e.file.ends_with("detections.jsonl"));
    assert_eq!(
        (e.line, e.field.as_deref()),
        (Some(1), Some("camera")),
        "{e}"
    );
    assert!(e.message.contains("cam9"));
}

#[test]
fn time_going_backwards_is_rejected() {
    let d = saved();
    edit(d.path(), "detections.jsonl", |s| {
        s.replacen("\"t\":0.09", "\"t\":0.01", 1)
    });
    let e = load_err(d.path());
    assert_eq!((e.line, e.field.as_deref()), (Some(3), Some("t")), "{e}");
    assert!(e.message.contains("backwards"));
}

#[test]
fn unsupported_format_version_is_rejected() {
    let d = saved();
    edit(d.path(), "scene.json", |s| {
        s.replace("avsep-scene/1", "avsep-scene/2")
    });
    assert_eq!(load_err(d.path()).field.as_deref(), Some("format"));
}

#[test]
fn bad_geometry_is_named() {
    let d = saved();
    edit(d.path(), "scene.json", |s| {
        s.replacen(
            "\"channels\": [\n        0,",
            "\"channels\": [\n        1,",
            1,
        )
    });
    let e = load_err(d.path());
    assert!(
        e.message.contains("twice") || e.message.contains("no array"),
        "{e}"
    );
}

#[test]
fn unknown_fields_are_ignored() {
    let d = saved();
    edit(d.path(), "scene.json", |s| {
        s.replacen('{', "{\"future_field\": 1,", 1)
    });
    assert!(Scene::load(d.path()).is_ok());
}

#[test]
fn layout_round_trips_through_its_wire_form() {
    let s = sample_scene();
    let file = convert::layout_to_file(&s.layout);
    assert!(file.audio.is_none() && file.detections.is_none() && file.truth.is_none());
    assert_eq!(convert::layout_from_file(&file).unwrap(), s.layout);
}
