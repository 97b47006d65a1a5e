//! Geometry of a room: microphone arrays, cameras, the search region and angle conventions.
//!
//! Everything here is in metres, seconds and radians; degrees appear only at the edges (scene
//! format, API). World frame: right-handed, z up.

mod angles;
mod array;
mod camera;
mod layout;
mod region;

pub use angles::{
    angle_diff, azimuth_of, deg, direction_from_angles, elevation_of, rad, wrap_angle,
};
pub use array::{ArrayShape, MicArray};
pub use camera::{Camera, Distortion, Ray};
pub use layout::Layout;
pub use region::Aabb;

/// A point or vector in world coordinates (metres).
pub type Vec3 = nalgebra::Vector3<f64>;
/// A pixel position (u to the right, v down, origin at the top-left pixel corner).
pub type Pixel = nalgebra::Vector2<f64>;

pub use crate::field_error::FieldError as GeometryError;

/// Largest coordinate (m, either sign) a position from outside may have: no room is larger,
/// and coordinates far beyond it overflow distances to infinity (and steering gains to NaN).
pub const MAX_COORDINATE_M: f64 = 1e4;

pub(crate) fn check_finite(field: &str, values: &[f64]) -> Result<(), GeometryError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(GeometryError::new(field, "must be finite numbers"))
    }
}
