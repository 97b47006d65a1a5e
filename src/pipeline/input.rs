//! Validation of inbound data before it reaches the stages. Every problem becomes an
//! [`InputError`] naming the field; the session keeps running and nothing accepted is lost.

use serde::Serialize;

use crate::geometry::{Layout, MAX_COORDINATE_M};
use crate::scene::{AudioMeasurementFrame, DetectionFrame, box_problem};

/// Why an inbound message was refused.
#[derive(Debug, Clone, PartialEq, Serialize, thiserror::Error)]
#[error("{field}: {message}")]
pub struct InputError {
    /// Machine-readable reason, e.g. `time_backwards`.
    pub code: &'static str,
    /// The offending field, e.g. `boxes[2].w`.
    pub field: String,
    /// Human-readable explanation.
    pub message: String,
}

impl InputError {
    /// An error about `field`.
    pub fn new(code: &'static str, field: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            code,
            field: field.into(),
            message: message.into(),
        }
    }
}

/// Checks an interleaved audio block's shape and values.
pub fn check_audio(layout: &Layout, channels: usize, samples: &[f32]) -> Result<(), InputError> {
    let expect = layout.channel_count();
    if expect == 0 {
        return Err(InputError::new(
            "no_audio",
            "channels",
            "this session's arrays carry no audio channels",
        ));
    }
    if channels != expect {
        return Err(InputError::new(
            "bad_channels",
            "channels",
            format!("{channels} channels sent but the session's arrays have {expect}"),
        ));
    }
    if !samples.len().is_multiple_of(channels) {
        return Err(InputError::new(
            "truncated",
            "samples",
            format!(
                "{} samples is not a whole number of {channels}-channel frames",
                samples.len()
            ),
        ));
    }
    if let Some(i) = samples.iter().position(|s| !s.is_finite()) {
        return Err(InputError::new(
            "non_finite",
            "samples",
            format!(
                "sample {} of channel {} is not a finite number",
                i / channels,
                i % channels
            ),
        ));
    }
    Ok(())
}

fn check_time(t: f64, last: f64) -> Result<(), InputError> {
    if !t.is_finite() || t < 0.0 {
        return Err(InputError::new(
            "bad_time",
            "t",
            format!("time {t} must be a finite number of seconds >= 0"),
        ));
    }
    if t < last {
        return Err(InputError::new(
            "time_backwards",
            "t",
            format!("time goes backwards: {t} after {last}"),
        ));
    }
    Ok(())
}

/// Checks a camera frame against the layout and the camera's previous frame time.
pub fn check_detections(
    layout: &Layout,
    frame: &DetectionFrame,
    last_t: f64,
) -> Result<(), InputError> {
    let Some(cam) = layout.cameras.get(frame.camera) else {
        return Err(InputError::new(
            "unknown_camera",
            "camera",
            format!("no camera with index {}", frame.camera),
        ));
    };
    check_time(frame.t, last_t)?;
    for (i, b) in frame.boxes.iter().enumerate() {
        let f = |n: &str| format!("boxes[{i}].{n}");
        if let Some((field, why)) = box_problem(b.x, b.y, b.w, b.h) {
            return Err(InputError::new("bad_box", f(field), why));
        }
        if let Some(s) = b.score
            && !(0.0..=1.0).contains(&s)
        {
            return Err(InputError::new(
                "bad_box",
                f("score"),
                format!("score {s} is not in [0, 1]"),
            ));
        }
        if let Some(p) = b.point
            && !(p.x.is_finite() && p.y.is_finite())
        {
            return Err(InputError::new("bad_box", f("point"), "must be finite"));
        }
        if !cam.contains_pixel(&b.measurement_point()) {
            return Err(InputError::new(
                "box_outside_image",
                f(if b.point.is_some() { "point" } else { "x" }),
                format!(
                    "the box's measurement point lies outside the {}x{} image",
                    cam.width, cam.height
                ),
            ));
        }
    }
    Ok(())
}

/// Checks a device-side localisation frame.
pub fn check_device_measurements(
    layout: &Layout,
    m: &AudioMeasurementFrame,
    last_t: f64,
) -> Result<(), InputError> {
    if m.array >= layout.arrays.len() {
        return Err(InputError::new(
            "unknown_array",
            "array",
            format!("no array with index {}", m.array),
        ));
    }
    check_time(m.t, last_t)?;
    for (i, d) in m.doas.iter().enumerate() {
        if !d.azimuth.is_finite()
            || d.elevation
                .is_some_and(|e| !e.is_finite() || e.abs() > std::f64::consts::FRAC_PI_2)
        {
            return Err(InputError::new(
                "bad_doa",
                format!("doas[{i}]"),
                "angles must be finite, elevation within +-90 deg",
            ));
        }
    }
    for (i, p) in m.points.iter().enumerate() {
        // Far beyond any room a coordinate overflows distances (and steering) to NaN.
        if !p
            .iter()
            .all(|v| v.is_finite() && v.abs() <= MAX_COORDINATE_M)
        {
            return Err(InputError::new(
                "bad_point",
                format!("points[{i}]"),
                format!("must be finite coordinates within {MAX_COORDINATE_M} m"),
            ));
        }
    }
    Ok(())
}
