//! The scene's sensor layout from the configuration: microphones, cameras and region.

use nalgebra::{Matrix3, Matrix3x4};

use crate::geometry::{Aabb, Camera, Layout, MicArray, Vec3};

use super::config::{ArrayGeometry, CameraConfig, SimConfig};
use super::{SimError, WALL_MARGIN_M};

/// Microphone positions of an array geometry.
pub fn mic_positions(g: &ArrayGeometry) -> Vec<Vec3> {
    match g {
        ArrayGeometry::Linear {
            centre,
            count,
            spacing_m,
            axis,
        } => {
            let c = Vec3::from(*centre);
            let a = Vec3::from(*axis)
                .try_normalize(1e-12)
                .unwrap_or_else(Vec3::x);
            let mid = (*count as f64 - 1.0) / 2.0;
            (0..*count)
                .map(|i| c + a * ((i as f64 - mid) * spacing_m))
                .collect()
        }
        ArrayGeometry::Circular {
            centre,
            count,
            radius_m,
            start_azimuth_deg,
        } => {
            let c = Vec3::from(*centre);
            let a0 = start_azimuth_deg.to_radians();
            (0..*count)
                .map(|i| {
                    let a = a0 + 2.0 * std::f64::consts::PI * i as f64 / *count as f64;
                    c + Vec3::new(radius_m * a.cos(), radius_m * a.sin(), 0.0)
                })
                .collect()
        }
        ArrayGeometry::Custom { mics } => mics.iter().map(|m| Vec3::from(*m)).collect(),
    }
}

/// The camera of a configuration entry: its projection matrix, or a distortion-free pinhole at
/// `position` looking at `look_at` with the principal point at the image centre.
pub fn camera(c: &CameraConfig, field: &str) -> Result<Camera, SimError> {
    let bad = |e: crate::geometry::GeometryError| SimError::Config {
        field: format!("{field}.{}", e.field),
        message: e.message,
    };
    let (w, h) = (c.width as f64, c.height as f64);
    if let Some(p) = &c.projection {
        let m = Matrix3x4::from_fn(|r, k| p[r][k]);
        return Camera::from_projection(c.id.clone(), w, h, m, None, None).map_err(bad);
    }
    let (Some(pos), Some(look)) = (c.position, c.look_at) else {
        return Err(SimError::Config {
            field: field.into(),
            message: "needs a projection, or a position and a look_at point".into(),
        });
    };
    let pos = Vec3::from(pos);
    let forward = (Vec3::from(look) - pos).normalize();
    let right = forward.cross(&Vec3::z()).normalize();
    let down = forward.cross(&right);
    let r = Matrix3::from_rows(&[right.transpose(), down.transpose(), forward.transpose()]);
    let f = 0.5 * w / (0.5 * c.hfov_deg.to_radians()).tan();
    let k = Matrix3::new(f, 0.0, 0.5 * w, 0.0, f, 0.5 * h, 0.0, 0.0, 1.0);
    Camera::from_krt(c.id.clone(), w, h, k, r, -(r * pos), None).map_err(bad)
}

/// The region where talkers can be: as configured, or the room shrunk by [`WALL_MARGIN_M`] on
/// every wall between heights 0.9 and 2.0 m.
pub fn region(cfg: &SimConfig) -> Result<Aabb, SimError> {
    let (min, max) = match &cfg.region {
        Some(r) => (Vec3::from(r.min), Vec3::from(r.max)),
        None => {
            let s = cfg.room.size_m;
            (
                Vec3::new(WALL_MARGIN_M, WALL_MARGIN_M, 0.9_f64.min(0.5 * s[2])),
                Vec3::new(
                    s[0] - WALL_MARGIN_M,
                    s[1] - WALL_MARGIN_M,
                    2.0_f64.min(s[2] - WALL_MARGIN_M),
                ),
            )
        }
    };
    Aabb::new(min, max).map_err(|e| SimError::Config {
        field: format!("region.{}", e.field),
        message: e.message,
    })
}

/// The validated layout; channels run through the arrays in order.
pub fn build(cfg: &SimConfig) -> Result<Layout, SimError> {
    let mut next = 0usize;
    let mut arrays = Vec::with_capacity(cfg.arrays.len());
    for (i, a) in cfg.arrays.iter().enumerate() {
        let mics = mic_positions(&a.geometry);
        let channels: Vec<usize> = (next..next + mics.len()).collect();
        next += mics.len();
        arrays.push(
            MicArray::new(a.id.clone(), mics, channels).map_err(|e| SimError::Config {
                field: format!("arrays[{i}].{}", e.field),
                message: e.message,
            })?,
        );
    }
    let cameras = cfg
        .cameras
        .iter()
        .enumerate()
        .map(|(i, c)| camera(c, &format!("cameras[{i}]")))
        .collect::<Result<Vec<_>, _>>()?;
    Layout::new(
        cfg.sample_rate,
        cfg.speed_of_sound,
        arrays,
        cameras,
        Some(region(cfg)?),
    )
    .map_err(|e| SimError::Config {
        field: e.field,
        message: e.message,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_at_camera_sees_its_target_at_the_image_centre() {
        let c = CameraConfig::default();
        let cam = camera(&c, "cameras[0]").unwrap();
        let p = cam.project(&Vec3::from(c.look_at.unwrap())).unwrap();
        assert!(
            (p.x - 640.0).abs() < 1e-6 && (p.y - 360.0).abs() < 1e-6,
            "{p:?}"
        );
        // A point above the target is higher in the image (smaller v).
        let q = cam
            .project(&(Vec3::from(c.look_at.unwrap()) + Vec3::new(0.0, 0.0, 0.3)))
            .unwrap();
        assert!(q.y < p.y);
        // A point to the camera's right (+x when looking along +y) has larger u.
        let r = cam
            .project(&(Vec3::from(c.look_at.unwrap()) + Vec3::new(0.3, 0.0, 0.0)))
            .unwrap();
        assert!(r.x > p.x);
    }

    #[test]
    fn arrays_have_the_configured_shape() {
        let lin = mic_positions(&ArrayGeometry::Linear {
            centre: [3.0, 3.25, 1.95],
            count: 6,
            spacing_m: 0.04,
            axis: [1.0, 0.0, 0.0],
        });
        assert!((lin[0].x - 2.9).abs() < 1e-12 && (lin[5].x - 3.1).abs() < 1e-12);
        let circ = mic_positions(&ArrayGeometry::Circular {
            centre: [1.0, 1.0, 0.8],
            count: 8,
            radius_m: 0.05,
            start_azimuth_deg: 0.0,
        });
        assert!(
            circ.iter()
                .all(|m| ((m - Vec3::new(1.0, 1.0, 0.8)).norm() - 0.05).abs() < 1e-12)
        );
    }
}
