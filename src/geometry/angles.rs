//! Azimuth/elevation conventions of the scene format.
//!
//! Azimuth is measured in the world x-y plane from +x towards +y; elevation from the x-y plane
//! towards +z. Both in radians here.

use std::f64::consts::PI;

use super::Vec3;

/// Degrees to radians.
pub fn rad(deg: f64) -> f64 {
    deg.to_radians()
}

/// Radians to degrees.
pub fn deg(rad: f64) -> f64 {
    rad.to_degrees()
}

/// Azimuth of vector `v` (radians, in (-pi, pi]).
pub fn azimuth_of(v: &Vec3) -> f64 {
    v.y.atan2(v.x)
}

/// Elevation of vector `v` (radians, in [-pi/2, pi/2]).
pub fn elevation_of(v: &Vec3) -> f64 {
    v.z.atan2(v.x.hypot(v.y))
}

/// Unit vector pointing at the given azimuth and elevation (radians).
pub fn direction_from_angles(azimuth: f64, elevation: f64) -> Vec3 {
    let (sa, ca) = azimuth.sin_cos();
    let (se, ce) = elevation.sin_cos();
    Vec3::new(ce * ca, ce * sa, se)
}

/// Wraps an angle to (-pi, pi].
pub fn wrap_angle(a: f64) -> f64 {
    let mut w = (a + PI).rem_euclid(2.0 * PI) - PI;
    if w <= -PI {
        w += 2.0 * PI;
    }
    w
}

/// Signed smallest difference `a - b` between two angles, in (-pi, pi].
pub fn angle_diff(a: f64, b: f64) -> f64 {
    wrap_angle(a - b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn azimuth_follows_scene_convention() {
        assert!((azimuth_of(&Vec3::new(1.0, 0.0, 0.0))).abs() < 1e-12);
        assert!((azimuth_of(&Vec3::new(0.0, 1.0, 0.0)) - PI / 2.0).abs() < 1e-12);
        assert!((elevation_of(&Vec3::new(1.0, 0.0, 1.0)) - PI / 4.0).abs() < 1e-12);
    }

    #[test]
    fn direction_round_trips_angles() {
        for &(az, el) in &[(0.3, 0.1), (-2.9, -0.7), (3.1, 1.2)] {
            let d = direction_from_angles(az, el);
            assert!((d.norm() - 1.0).abs() < 1e-12);
            assert!(angle_diff(azimuth_of(&d), az).abs() < 1e-12);
            assert!((elevation_of(&d) - el).abs() < 1e-12);
        }
    }

    #[test]
    fn wrapping_stays_in_half_open_interval() {
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((angle_diff(rad(179.0), rad(-179.0)) - rad(-2.0)).abs() < 1e-12);
    }
}
