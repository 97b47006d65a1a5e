//! The strict scene reader.

use std::path::Path;

use serde::de::DeserializeOwned;

use crate::geometry::{Layout, Pixel, Vec3, rad};

use super::convert::layout_from_file;
use super::format::{AudioMeasurementLine, DetectionLine, SCENE_FORMAT, SceneFile, TruthFile};
use super::{
    Audio, AudioMeasurementFrame, DetectionFrame, Doa, FaceBox, Scene, SceneError, Truth,
    TruthSource,
};

/// Parses one JSON document, reporting the field path and line of any error.
pub fn parse_json<T: DeserializeOwned>(
    file: &Path,
    text: &str,
    line: Option<usize>,
) -> Result<T, SceneError> {
    let de = &mut serde_json::Deserializer::from_str(text);
    serde_path_to_error::deserialize(de).map_err(|e| SceneError::from_json(file, line, e))
}

fn read_text(path: &Path) -> Result<String, SceneError> {
    std::fs::read_to_string(path).map_err(|e| SceneError::new(path, format!("cannot read: {e}")))
}

/// Reads a JSONL file, calling `each(line_number, value)` for every non-blank line.
pub fn read_jsonl<T: DeserializeOwned>(
    path: &Path,
    mut each: impl FnMut(usize, T) -> Result<(), SceneError>,
) -> Result<(), SceneError> {
    let text = read_text(path)?;
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let value = parse_json(path, line, Some(i + 1))?;
        each(i + 1, value)?;
    }
    Ok(())
}

fn check_time(path: &Path, line: usize, t: f64, last: &mut f64) -> Result<(), SceneError> {
    let err = |m: String| SceneError::new(path, m).at_line(line).field("t");
    if !t.is_finite() || t < 0.0 {
        return Err(err(format!(
            "time {t} must be a finite number of seconds >= 0"
        )));
    }
    if t < *last {
        return Err(err(format!("time goes backwards: {t} after {last}")));
    }
    *last = t;
    Ok(())
}

fn finite(vals: &[f64]) -> bool {
    vals.iter().all(|v| v.is_finite())
}

impl Scene {
    /// Reads and validates the scene in folder `dir`.
    pub fn load(dir: &Path) -> Result<Scene, SceneError> {
        let scene_path = dir.join("scene.json");
        let file: SceneFile = parse_json(&scene_path, &read_text(&scene_path)?, None)?;
        if file.format != SCENE_FORMAT {
            return Err(SceneError::new(
                &scene_path,
                format!(
                    "unsupported format {:?}; this reader understands {SCENE_FORMAT:?}",
                    file.format
                ),
            )
            .field("format"));
        }
        let layout = layout_from_file(&file)
            .map_err(|e| SceneError::new(&scene_path, e.message).field(e.field))?;
        let audio = match (&file.audio, &file.audio_measurements) {
            (Some(a), _) => Some(load_audio(&dir.join(a), &layout)?),
            (None, Some(_)) => None,
            (None, None) => {
                return Err(SceneError::new(
                    &scene_path,
                    "is required unless audio_measurements is given",
                )
                .field("audio"));
            }
        };
        let detections = match &file.detections {
            Some(p) => load_detections(&dir.join(p), &layout)?,
            None => Vec::new(),
        };
        let audio_measurements = match &file.audio_measurements {
            Some(p) => load_audio_measurements(&dir.join(p), &layout)?,
            None => Vec::new(),
        };
        let frames = audio.as_ref().map(|a| a.frames());
        let truth = match &file.truth {
            Some(p) => Some(load_truth(dir, &dir.join(p), layout.sample_rate, frames)?),
            None => None,
        };
        Ok(Scene {
            dir: dir.to_path_buf(),
            layout,
            audio,
            detections,
            audio_measurements,
            truth,
        })
    }
}

fn load_audio(path: &Path, layout: &Layout) -> Result<Audio, SceneError> {
    let audio = Audio::read(path)?;
    if audio.sample_rate != layout.sample_rate {
        return Err(SceneError::new(
            path,
            format!(
                "sample rate is {} Hz but scene.json says {} Hz",
                audio.sample_rate, layout.sample_rate
            ),
        )
        .field("sample_rate"));
    }
    if audio.channels != layout.channel_count() {
        return Err(SceneError::new(
            path,
            format!(
                "has {} channels but the arrays in scene.json list {} (arrays[].channels)",
                audio.channels,
                layout.channel_count()
            ),
        )
        .field("channels"));
    }
    Ok(audio)
}

fn load_detections(path: &Path, layout: &Layout) -> Result<Vec<DetectionFrame>, SceneError> {
    let mut out = Vec::new();
    let mut last = f64::NEG_INFINITY;
    read_jsonl(path, |line, d: DetectionLine| {
        check_time(path, line, d.t, &mut last)?;
        let err = |field: String, m: String| SceneError::new(path, m).at_line(line).field(field);
        let camera = layout.camera_index(&d.camera).ok_or_else(|| {
            let known: Vec<_> = layout.cameras.iter().map(|c| c.id.as_str()).collect();
            err(
                "camera".into(),
                format!("unknown camera {:?} (scene.json lists {known:?})", d.camera),
            )
        })?;
        let cam = &layout.cameras[camera];
        let mut boxes = Vec::with_capacity(d.boxes.len());
        for (i, b) in d.boxes.iter().enumerate() {
            let f = |name: &str| format!("boxes[{i}].{name}");
            if let Some((field, why)) = super::box_problem(b.x, b.y, b.w, b.h) {
                return Err(err(f(field), why.into()));
            }
            if let Some(s) = b.score
                && !(0.0..=1.0).contains(&s)
            {
                return Err(err(f("score"), format!("score {s} is not in [0, 1]")));
            }
            let point = match b.point {
                Some(p) if !finite(&p) => return Err(err(f("point"), "must be finite".into())),
                Some(p) => Some(Pixel::new(p[0], p[1])),
                None => None,
            };
            let fb = FaceBox {
                x: b.x,
                y: b.y,
                w: b.w,
                h: b.h,
                score: b.score,
                point,
            };
            if !cam.contains_pixel(&fb.measurement_point()) {
                return Err(err(
                    f(if b.point.is_some() { "point" } else { "x" }),
                    format!(
                        "measurement point lies outside the {}x{} image",
                        cam.width, cam.height
                    ),
                ));
            }
            boxes.push(fb);
        }
        out.push(DetectionFrame {
            t: d.t,
            camera,
            boxes,
        });
        Ok(())
    })?;
    Ok(out)
}

pub(crate) fn load_audio_measurements(
    path: &Path,
    layout: &Layout,
) -> Result<Vec<AudioMeasurementFrame>, SceneError> {
    let mut out = Vec::new();
    let mut last = f64::NEG_INFINITY;
    read_jsonl(path, |line, m: AudioMeasurementLine| {
        check_time(path, line, m.t, &mut last)?;
        let err =
            |field: String, msg: String| SceneError::new(path, msg).at_line(line).field(field);
        let array = layout.array_index(&m.array).ok_or_else(|| {
            let known: Vec<_> = layout.arrays.iter().map(|a| a.id.as_str()).collect();
            err(
                "array".into(),
                format!("unknown array {:?} (scene.json lists {known:?})", m.array),
            )
        })?;
        let mut doas = Vec::with_capacity(m.doas.len());
        for (i, d) in m.doas.iter().enumerate() {
            if !d.azimuth.is_finite() || d.azimuth.abs() > 360.0 {
                return Err(err(
                    format!("doas[{i}].azimuth"),
                    "must be a finite angle in degrees".into(),
                ));
            }
            if let Some(e) = d.elevation
                && !(-90.0..=90.0).contains(&e)
            {
                return Err(err(
                    format!("doas[{i}].elevation"),
                    format!("{e} is not in [-90, 90] degrees"),
                ));
            }
            if let Some(e) = d.energy
                && !e.is_finite()
            {
                return Err(err(format!("doas[{i}].energy"), "must be finite".into()));
            }
            doas.push(Doa {
                azimuth: rad(d.azimuth),
                elevation: d.elevation.map(rad),
                energy: d.energy,
            });
        }
        let mut points = Vec::with_capacity(m.points.len());
        for (i, p) in m.points.iter().enumerate() {
            if !finite(p) {
                return Err(err(format!("points[{i}]"), "must be finite".into()));
            }
            points.push(Vec3::from(*p));
        }
        if let Some(a) = m.activity
            && !(0.0..=1.0).contains(&a)
        {
            return Err(err("activity".into(), format!("{a} is not in [0, 1]")));
        }
        out.push(AudioMeasurementFrame {
            t: m.t,
            array,
            doas,
            points,
            activity: m.activity,
        });
        Ok(())
    })?;
    Ok(out)
}

fn load_truth(
    dir: &Path,
    path: &Path,
    sample_rate: u32,
    frames: Option<usize>,
) -> Result<Truth, SceneError> {
    let file: TruthFile = parse_json(path, &read_text(path)?, None)?;
    let mut sources = Vec::with_capacity(file.sources.len());
    for (i, s) in file.sources.iter().enumerate() {
        let err = |field: String, m: String| {
            SceneError::new(path, m).field(format!("sources[{i}].{field}"))
        };
        if s.trajectory.is_empty() {
            return Err(err(
                "trajectory".into(),
                "must have at least one sample".into(),
            ));
        }
        let mut trajectory = Vec::with_capacity(s.trajectory.len());
        for (j, p) in s.trajectory.iter().enumerate() {
            if !finite(p) {
                return Err(err(format!("trajectory[{j}]"), "must be finite".into()));
            }
            if let Some(&(t_prev, _)) = trajectory.last()
                && p[0] <= t_prev
            {
                return Err(err(
                    format!("trajectory[{j}]"),
                    format!("time {} does not increase", p[0]),
                ));
            }
            trajectory.push((p[0], Vec3::new(p[1], p[2], p[3])));
        }
        let mut active = Vec::with_capacity(s.active.len());
        for (j, a) in s.active.iter().enumerate() {
            if !finite(a) || a[1] <= a[0] {
                return Err(err(
                    format!("active[{j}]"),
                    "must be [start, end] with start < end".into(),
                ));
            }
            active.push((a[0], a[1]));
        }
        let signal = match &s.signal {
            Some(rel) => {
                let wav = dir.join(rel);
                let a = Audio::read(&wav)?;
                if a.channels != 1 || a.sample_rate != sample_rate {
                    return Err(
                        SceneError::new(&wav, format!("must be mono at {sample_rate} Hz"))
                            .field("channels"),
                    );
                }
                if let Some(n) = frames
                    && a.frames() != n
                {
                    return Err(SceneError::new(
                        &wav,
                        format!("has {} samples but audio.wav has {n}", a.frames()),
                    )
                    .field("samples"));
                }
                Some(a.samples)
            }
            None => None,
        };
        sources.push(TruthSource {
            id: s.id.clone(),
            signal,
            trajectory,
            active,
        });
    }
    Ok(Truth { sources })
}
