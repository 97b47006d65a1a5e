//! Turning inbound JSON messages into the pipeline's input frames: ids become indices, degrees
//! become radians, and everything a message can be checked for without the session's history is
//! checked here (time order and lateness are the pipeline's to judge).

use crate::geometry::{Layout, Pixel, Vec3, rad};
use crate::pipeline::InputError;
use crate::pipeline::input::{check_detections, check_device_measurements};
use crate::scene::format::{AudioMeasurementLine, BoxFile};
use crate::scene::{AudioMeasurementFrame, DetectionFrame, Doa, FaceBox};

/// Builds a camera frame from a `detections` message, naming the camera or box at fault.
pub fn detection_frame(
    layout: &Layout,
    t: f64,
    camera: &str,
    boxes: &[BoxFile],
) -> Result<DetectionFrame, InputError> {
    let index = layout.camera_index(camera).ok_or_else(|| {
        let known: Vec<&str> = layout.cameras.iter().map(|c| c.id.as_str()).collect();
        InputError::new(
            "unknown_camera",
            "camera",
            format!("unknown camera {camera:?}; this session has {known:?}"),
        )
    })?;
    let frame = DetectionFrame {
        t,
        camera: index,
        boxes: boxes
            .iter()
            .map(|b| FaceBox {
                x: b.x,
                y: b.y,
                w: b.w,
                h: b.h,
                score: b.score,
                point: b.point.map(|p| Pixel::new(p[0], p[1])),
            })
            .collect(),
    };
    check_detections(layout, &frame, f64::NEG_INFINITY)?;
    Ok(frame)
}

/// Builds a device measurement frame from an `audio_measurements` message (angles in degrees).
pub fn device_frame(
    layout: &Layout,
    line: &AudioMeasurementLine,
) -> Result<AudioMeasurementFrame, InputError> {
    let array = layout.array_index(&line.array).ok_or_else(|| {
        let known: Vec<&str> = layout.arrays.iter().map(|a| a.id.as_str()).collect();
        InputError::new(
            "unknown_array",
            "array",
            format!("unknown array {:?}; this session has {known:?}", line.array),
        )
    })?;
    for (i, d) in line.doas.iter().enumerate() {
        if let Some(e) = d.energy
            && !e.is_finite()
        {
            return Err(InputError::new(
                "bad_doa",
                format!("doas[{i}].energy"),
                "must be finite",
            ));
        }
    }
    if let Some(a) = line.activity
        && !(0.0..=1.0).contains(&a)
    {
        return Err(InputError::new(
            "bad_activity",
            "activity",
            format!("{a} is not in [0, 1]"),
        ));
    }
    let frame = AudioMeasurementFrame {
        t: line.t,
        array,
        doas: line
            .doas
            .iter()
            .map(|d| Doa {
                azimuth: rad(d.azimuth),
                elevation: d.elevation.map(rad),
                energy: d.energy,
            })
            .collect(),
        points: line.points.iter().map(|p| Vec3::from(*p)).collect(),
        activity: line.activity,
    };
    check_device_measurements(layout, &frame, f64::NEG_INFINITY)?;
    Ok(frame)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::geometry::{Camera, MicArray};
    use crate::scene::format::DoaFile;
    use nalgebra::Matrix3;

    /// A four-microphone square array and one camera at the origin looking along +z.
    pub(crate) fn layout() -> Layout {
        let mics = [(0.05, 0.0), (0.0, 0.05), (-0.05, 0.0), (0.0, -0.05)]
            .iter()
            .map(|&(x, y)| Vec3::new(x, y, 1.0))
            .collect();
        let array = MicArray::new("a0", mics, vec![0, 1, 2, 3]).unwrap();
        let k = Matrix3::new(500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0);
        let cam = Camera::from_krt(
            "cam0",
            640.0,
            480.0,
            k,
            Matrix3::identity(),
            Vec3::zeros(),
            None,
        )
        .unwrap();
        Layout::new(16_000, 343.0, vec![array], vec![cam], None).unwrap()
    }

    fn bx(x: f64) -> BoxFile {
        BoxFile {
            x,
            y: 100.0,
            w: 40.0,
            h: 50.0,
            score: Some(0.9),
            point: None,
        }
    }

    #[test]
    fn detections_map_camera_ids_and_name_bad_boxes() {
        let l = layout();
        let cam = l.cameras[0].id.clone();
        let f = detection_frame(&l, 0.5, &cam, &[bx(100.0)]).unwrap();
        assert_eq!((f.camera, f.boxes.len()), (0, 1));
        assert_eq!(f.boxes[0].measurement_point(), Pixel::new(120.0, 125.0));

        let e = detection_frame(&l, 0.5, "nope", &[]).unwrap_err();
        assert_eq!((e.code, e.field.as_str()), ("unknown_camera", "camera"));
        assert!(e.message.contains(&cam), "{}", e.message);

        let mut b = bx(100.0);
        b.w = -1.0;
        let e = detection_frame(&l, 0.5, &cam, &[bx(10.0), b]).unwrap_err();
        assert_eq!(e.field, "boxes[1].w");
        let e = detection_frame(&l, f64::NAN, &cam, &[]).unwrap_err();
        assert_eq!((e.code, e.field.as_str()), ("bad_time", "t"));
    }

    #[test]
    fn device_measurements_convert_degrees() {
        let l = layout();
        let line = AudioMeasurementLine {
            t: 0.25,
            array: l.arrays[0].id.clone(),
            doas: vec![DoaFile {
                azimuth: 90.0,
                elevation: Some(-30.0),
                energy: None,
            }],
            points: vec![],
            activity: Some(0.5),
        };
        let f = device_frame(&l, &line).unwrap();
        assert!((f.doas[0].azimuth - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((f.doas[0].elevation.unwrap() + std::f64::consts::PI / 6.0).abs() < 1e-12);

        let mut bad = line.clone();
        bad.array = "zz".into();
        assert_eq!(device_frame(&l, &bad).unwrap_err().code, "unknown_array");
        let mut bad = line.clone();
        bad.doas[0].elevation = Some(120.0);
        assert_eq!(device_frame(&l, &bad).unwrap_err().field, "doas[0]");
        let mut bad = line.clone();
        bad.activity = Some(2.0);
        assert_eq!(device_frame(&l, &bad).unwrap_err().field, "activity");
        // A point far beyond any room would overflow distances to infinity.
        let mut bad = line;
        bad.points = vec![[1.0, 2.0, 1.5], [1e200, 0.0, 1.0]];
        let e = device_frame(&l, &bad).unwrap_err();
        assert_eq!((e.code, e.field.as_str()), ("bad_point", "points[1]"));
    }
}
