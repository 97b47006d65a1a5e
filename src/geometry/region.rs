//! Axis-aligned boxes: the room, the search volume, the region where sources can be.

use rand::Rng;
use serde::{Deserialize, Serialize};

use super::{GeometryError, Vec3, check_finite};

/// An axis-aligned box `[min, max]` in world coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
}

impl Aabb {
    /// A box from two corners; every side must have positive length.
    pub fn new(min: Vec3, max: Vec3) -> Result<Self, GeometryError> {
        check_finite("min", min.as_slice())?;
        check_finite("max", max.as_slice())?;
        if (0..3).any(|i| max[i] <= min[i]) {
            return Err(GeometryError::new(
                "max",
                "must be greater than min on every axis",
            ));
        }
        Ok(Self { min, max })
    }

    /// Side lengths.
    pub fn size(&self) -> Vec3 {
        self.max - self.min
    }

    /// Volume in cubic metres.
    pub fn volume(&self) -> f64 {
        let s = self.size();
        s.x * s.y * s.z
    }

    /// Centre point.
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Whether `p` lies inside (boundary included).
    pub fn contains(&self, p: &Vec3) -> bool {
        (0..3).all(|i| p[i] >= self.min[i] && p[i] <= self.max[i])
    }

    /// The nearest point of the box to `p`.
    pub fn clamp(&self, p: &Vec3) -> Vec3 {
        Vec3::new(
            p.x.clamp(self.min.x, self.max.x),
            p.y.clamp(self.min.y, self.max.y),
            p.z.clamp(self.min.z, self.max.z),
        )
    }

    /// A point drawn uniformly from the box.
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> Vec3 {
        Vec3::new(
            rng.random_range(self.min.x..=self.max.x),
            rng.random_range(self.min.y..=self.max.y),
            rng.random_range(self.min.z..=self.max.z),
        )
    }

    /// The box shrunk by `margin` on every side (never past its centre).
    pub fn shrunk(&self, margin: f64) -> Self {
        let c = self.center();
        let half = self.size() * 0.5;
        let m = Vec3::new(margin.min(half.x), margin.min(half.y), margin.min(half.z));
        Self {
            min: (self.min + m).inf(&c),
            max: (self.max - m).sup(&c),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn rejects_degenerate_boxes() {
        assert!(Aabb::new(Vec3::zeros(), Vec3::new(1.0, 0.0, 1.0)).is_err());
        assert!(Aabb::new(Vec3::zeros(), Vec3::new(1.0, f64::NAN, 1.0)).is_err());
    }

    #[test]
    fn samples_stay_inside() {
        let b = Aabb::new(Vec3::new(-1.0, 0.0, 0.5), Vec3::new(2.0, 3.0, 2.0)).unwrap();
        assert!((b.volume() - 3.0 * 3.0 * 1.5).abs() < 1e-12);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for _ in 0..1000 {
            assert!(b.contains(&b.sample(&mut rng)));
        }
        assert_eq!(
            b.clamp(&Vec3::new(5.0, -1.0, 1.0)),
            Vec3::new(2.0, 0.0, 1.0)
        );
    }
}
