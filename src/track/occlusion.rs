//! Shadow test for occlusion-aware camera detection (spec 000 3.9, A5): is a track's centre
//! hidden from a camera by another track, modelled as a person-sized axis-aligned ellipsoid?

use crate::geometry::Vec3;

/// Whether the ellipsoid (centre, half-sizes) blocks the line of sight from `eye` to `target`.
///
/// This is the thesis's quadratic (4.39-4.43) in coordinates scaled to the unit sphere, with the
/// two fixes its notes call for: an intersection must lie on the segment (0 < chi < 1), and the
/// occluder must be nearer to the camera than the target.
pub(crate) fn occludes(eye: &Vec3, target: &Vec3, centre: &Vec3, half: &Vec3) -> bool {
    let e = (eye - centre).component_div(half);
    let d = (target - eye).component_div(half);
    let a = d.dot(&d);
    if a.is_nan() || a <= 1e-18 {
        return false;
    }
    let to_target = target - eye;
    if (centre - eye).dot(&to_target) >= to_target.norm_squared() {
        return false;
    }
    let b = 2.0 * e.dot(&d);
    let c = e.dot(&e) - 1.0;
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return false;
    }
    let sq = disc.sqrt();
    let (r0, r1) = ((-b - sq) / (2.0 * a), (-b + sq) / (2.0 * a));
    // The segment meets the ellipsoid iff the root interval overlaps (0, 1).
    r0 < 1.0 && r1 > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_head_between_camera_and_target_occludes() {
        let cam = Vec3::new(0.0, 0.0, 2.0);
        let target = Vec3::new(4.0, 0.0, 1.6);
        let half = Vec3::new(0.2, 0.2, 0.25);
        let between = Vec3::new(2.0, 0.05, 1.8);
        assert!(occludes(&cam, &target, &between, &half));
        // Beside the line of sight, behind the target, or behind the camera: no occlusion.
        assert!(!occludes(&cam, &target, &Vec3::new(2.0, 1.0, 1.8), &half));
        assert!(!occludes(&cam, &target, &Vec3::new(6.0, 0.0, 1.5), &half));
        assert!(!occludes(&cam, &target, &Vec3::new(-2.0, 0.0, 2.2), &half));
        // The camera itself inside an ellipsoid is still a blocked view.
        assert!(occludes(&cam, &target, &Vec3::new(0.1, 0.0, 2.0), &half));
    }
}
