//! Conversions between the scene format's wire types and the geometry types, with errors that
//! name the field. The REST API uses the same conversions for session bodies.

use nalgebra::{Matrix3, Matrix3x4};

use crate::geometry::{Aabb, Camera, GeometryError, Layout, MicArray, Vec3};

use super::format::{ArrayFile, BoxFile, CameraFile, RegionFile, SCENE_FORMAT, SceneFile};
use super::model::FaceBox;

/// Builds a validated array from its wire form.
pub fn array_from_file(a: &ArrayFile) -> Result<MicArray, GeometryError> {
    let mics = a.mics.iter().map(|m| Vec3::new(m[0], m[1], m[2])).collect();
    MicArray::new(a.id.clone(), mics, a.channels.clone())
}

/// The wire form of an array.
pub fn array_to_file(a: &MicArray) -> ArrayFile {
    ArrayFile {
        id: a.id.clone(),
        channels: a.channels.clone(),
        mics: a.mics.iter().map(|m| [m.x, m.y, m.z]).collect(),
    }
}

fn mat3(rows: &[[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_fn(|r, c| rows[r][c])
}

/// Builds a validated camera from its wire form: a projection matrix, or intrinsics with
/// rotation and translation.
pub fn camera_from_file(c: &CameraFile) -> Result<Camera, GeometryError> {
    let k = c.intrinsics.as_ref().map(mat3);
    let distortion = c.distortion.as_deref();
    match (&c.projection, &c.rotation, &c.translation) {
        (Some(p), _, _) => {
            let p = Matrix3x4::from_fn(|r, col| p[r][col]);
            Camera::from_projection(c.id.clone(), c.width, c.height, p, k, distortion)
        }
        (None, Some(r), Some(t)) => {
            let k = k.ok_or_else(|| {
                GeometryError::new("intrinsics", "is required with rotation and translation")
            })?;
            Camera::from_krt(
                c.id.clone(),
                c.width,
                c.height,
                k,
                mat3(r),
                Vec3::new(t[0], t[1], t[2]),
                distortion,
            )
        }
        (None, None, _) => Err(GeometryError::new(
            "projection",
            "is required (or intrinsics, rotation and translation)",
        )),
        (None, Some(_), None) => Err(GeometryError::new(
            "translation",
            "is required with rotation",
        )),
    }
}

/// The wire form of a camera (its projection matrix as given, intrinsics and distortion).
pub fn camera_to_file(c: &Camera) -> CameraFile {
    let p = c.projection();
    let d = c.distortion();
    CameraFile {
        id: c.id.clone(),
        width: c.width,
        height: c.height,
        projection: Some(std::array::from_fn(|r| {
            std::array::from_fn(|col| p[(r, col)])
        })),
        intrinsics: c
            .intrinsics()
            .map(|k| std::array::from_fn(|r| std::array::from_fn(|col| k[(r, col)]))),
        distortion: if d.is_zero() {
            None
        } else {
            Some(d.to_array().to_vec())
        },
        rotation: None,
        translation: None,
    }
}

/// Builds a validated region.
pub fn region_from_file(r: &RegionFile) -> Result<Aabb, GeometryError> {
    Aabb::new(Vec3::from(r.min), Vec3::from(r.max))
}

/// The file form of a region (the inverse of [`region_from_file`]).
pub fn region_to_file(r: &Aabb) -> RegionFile {
    RegionFile {
        min: r.min.into(),
        max: r.max.into(),
    }
}

/// A `scene.json` holding only geometry (no data files), from its wire-form parts.
pub fn geometry_file(
    sample_rate: u32,
    speed_of_sound: f64,
    arrays: Vec<ArrayFile>,
    cameras: Vec<CameraFile>,
    region: Option<RegionFile>,
) -> SceneFile {
    SceneFile {
        format: SCENE_FORMAT.into(),
        sample_rate,
        speed_of_sound,
        audio: None,
        arrays,
        cameras,
        region,
        detections: None,
        audio_measurements: None,
        truth: None,
    }
}

/// The wire form of a layout: a `scene.json` holding only geometry (the inverse of
/// [`layout_from_file`]).
pub fn layout_to_file(l: &Layout) -> SceneFile {
    geometry_file(
        l.sample_rate,
        l.speed_of_sound,
        l.arrays.iter().map(array_to_file).collect(),
        l.cameras.iter().map(camera_to_file).collect(),
        l.region.as_ref().map(region_to_file),
    )
}

/// The wire form of a detected face box.
pub fn box_to_file(b: &FaceBox) -> BoxFile {
    BoxFile {
        x: b.x,
        y: b.y,
        w: b.w,
        h: b.h,
        score: b.score,
        point: b.point.map(|p| [p.x, p.y]),
    }
}

/// Builds the validated layout of a `scene.json`, naming the offending field on error.
pub fn layout_from_file(s: &SceneFile) -> Result<Layout, GeometryError> {
    let arrays = s
        .arrays
        .iter()
        .enumerate()
        .map(|(i, a)| array_from_file(a).map_err(|e| e.within(&format!("arrays[{i}]"))))
        .collect::<Result<Vec<_>, _>>()?;
    let cameras = s
        .cameras
        .iter()
        .enumerate()
        .map(|(i, c)| camera_from_file(c).map_err(|e| e.within(&format!("cameras[{i}]"))))
        .collect::<Result<Vec<_>, _>>()?;
    let region = s
        .region
        .as_ref()
        .map(region_from_file)
        .transpose()
        .map_err(|e| e.within("region"))?;
    Layout::new(s.sample_rate, s.speed_of_sound, arrays, cameras, region)
}
