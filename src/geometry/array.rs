//! Microphone arrays of any shape.

use nalgebra::Matrix3;

use super::{GeometryError, Vec3, check_finite};

/// The spatial extent of an array, which decides what it can resolve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ArrayShape {
    /// A single microphone: no spatial information.
    Point,
    /// All microphones on a line: only the angle to `axis` (a cone) is observable.
    Linear {
        /// Unit vector along the array.
        axis: Vec3,
    },
    /// All microphones in a plane: the two sides of the plane are mirror images.
    Planar {
        /// Unit normal of the plane (sign chosen with non-negative z).
        normal: Vec3,
    },
    /// A three-dimensional array: full direction observable.
    Volumetric,
}

/// A microphone array: positions in world coordinates and the audio columns that carry them.
#[derive(Debug, Clone, PartialEq)]
pub struct MicArray {
    /// Identifier, unique within a layout (e.g. `"a0"`).
    pub id: String,
    /// Microphone positions (metres, world frame).
    pub mics: Vec<Vec3>,
    /// `channels[i]` is the audio column carrying `mics[i]`; empty for measurement-only arrays.
    pub channels: Vec<usize>,
}

impl MicArray {
    /// Validates and builds an array. `channels` must be empty or as long as `mics`.
    pub fn new(
        id: impl Into<String>,
        mics: Vec<Vec3>,
        channels: Vec<usize>,
    ) -> Result<Self, GeometryError> {
        let id = id.into();
        if id.is_empty() {
            return Err(GeometryError::new("id", "must not be empty"));
        }
        if mics.is_empty() {
            return Err(GeometryError::new(
                "mics",
                "must list at least one microphone",
            ));
        }
        for (i, m) in mics.iter().enumerate() {
            check_finite(&format!("mics[{i}]"), m.as_slice())?;
        }
        for i in 0..mics.len() {
            for j in i + 1..mics.len() {
                if (mics[i] - mics[j]).norm() < 1e-6 {
                    return Err(GeometryError::new(
                        format!("mics[{j}]"),
                        format!("coincides with mics[{i}]"),
                    ));
                }
            }
        }
        if !channels.is_empty() && channels.len() != mics.len() {
            return Err(GeometryError::new(
                "channels",
                format!(
                    "has {} entries but there are {} microphones",
                    channels.len(),
                    mics.len()
                ),
            ));
        }
        Ok(Self { id, mics, channels })
    }

    /// Number of microphones.
    pub fn len(&self) -> usize {
        self.mics.len()
    }

    /// Whether the array has no microphones (never true for a validated array).
    pub fn is_empty(&self) -> bool {
        self.mics.is_empty()
    }

    /// Mean microphone position: the origin of the array's directions of arrival.
    pub fn centroid(&self) -> Vec3 {
        self.mics.iter().sum::<Vec3>() / self.mics.len() as f64
    }

    /// All unordered microphone pairs `(a, b)` with `a < b`.
    pub fn pairs(&self) -> Vec<(usize, usize)> {
        let n = self.mics.len();
        (0..n)
            .flat_map(|a| (a + 1..n).map(move |b| (a, b)))
            .collect()
    }

    /// Largest distance between two microphones.
    pub fn aperture(&self) -> f64 {
        self.pairs()
            .iter()
            .map(|&(a, b)| (self.mics[a] - self.mics[b]).norm())
            .fold(0.0, f64::max)
    }

    /// Time of flight (s) from `source` to microphone `m`.
    pub fn time_of_flight(&self, source: &Vec3, m: usize, speed_of_sound: f64) -> f64 {
        (source - self.mics[m]).norm() / speed_of_sound
    }

    /// Time difference of arrival `tau_a - tau_b` (s) of a source at `source` for pair (a, b).
    pub fn tdoa(&self, source: &Vec3, a: usize, b: usize, speed_of_sound: f64) -> f64 {
        ((source - self.mics[a]).norm() - (source - self.mics[b]).norm()) / speed_of_sound
    }

    /// Far-field TDOA `tau_a - tau_b` (s) of a plane wave arriving from unit direction `dir`.
    pub fn tdoa_far(&self, dir: &Vec3, a: usize, b: usize, speed_of_sound: f64) -> f64 {
        (self.mics[b] - self.mics[a]).dot(dir) / speed_of_sound
    }

    /// Shape classification from the spread of the microphones (tolerance 1 mm).
    pub fn shape(&self) -> ArrayShape {
        if self.mics.len() < 2 {
            return ArrayShape::Point;
        }
        let c = self.centroid();
        let mut cov = Matrix3::zeros();
        for m in &self.mics {
            let d = m - c;
            cov += d * d.transpose();
        }
        let eig = cov.symmetric_eigen();
        let mut order = [0usize, 1, 2];
        order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
        // Standard deviation along each principal axis, largest first.
        let sd = order.map(|i| (eig.eigenvalues[i].max(0.0) / self.mics.len() as f64).sqrt());
        let tol = 1e-3;
        if sd[1] < tol {
            let axis: Vec3 = eig.eigenvectors.column(order[0]).into();
            ArrayShape::Linear {
                axis: axis.normalize(),
            }
        } else if sd[2] < tol {
            let mut normal: Vec3 = eig.eigenvectors.column(order[2]).into();
            if normal.z < 0.0 {
                normal = -normal;
            }
            ArrayShape::Planar {
                normal: normal.normalize(),
            }
        } else {
            ArrayShape::Volumetric
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(n: usize, r: f64, z: f64) -> Vec<Vec3> {
        (0..n)
            .map(|i| {
                let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                Vec3::new(r * a.cos(), r * a.sin(), z)
            })
            .collect()
    }

    #[test]
    fn validates_inputs() {
        assert!(MicArray::new("", circle(4, 0.05, 0.0), vec![]).is_err());
        assert!(MicArray::new("a", vec![], vec![]).is_err());
        let e = MicArray::new("a", circle(4, 0.05, 0.0), vec![0, 1]).unwrap_err();
        assert_eq!(e.field, "channels");
        let e = MicArray::new("a", vec![Vec3::zeros(), Vec3::zeros()], vec![]).unwrap_err();
        assert_eq!(e.field, "mics[1]");
    }

    #[test]
    fn classifies_shapes() {
        let lin: Vec<_> = (0..6)
            .map(|i| Vec3::new(1.0 + 0.04 * i as f64, 2.0, 1.0))
            .collect();
        match MicArray::new("l", lin, vec![]).unwrap().shape() {
            ArrayShape::Linear { axis } => assert!((axis.x.abs() - 1.0).abs() < 1e-9),
            s => panic!("{s:?}"),
        }
        match MicArray::new("c", circle(8, 0.05, 0.8), vec![])
            .unwrap()
            .shape()
        {
            ArrayShape::Planar { normal } => assert!((normal.z - 1.0).abs() < 1e-9),
            s => panic!("{s:?}"),
        }
        let mut mics = circle(4, 0.05, 0.0);
        mics.push(Vec3::new(0.0, 0.0, 0.05));
        assert_eq!(
            MicArray::new("v", mics, vec![]).unwrap().shape(),
            ArrayShape::Volumetric
        );
    }

    #[test]
    fn tdoa_matches_geometry() {
        let a = MicArray::new(
            "a",
            vec![Vec3::zeros(), Vec3::new(0.1, 0.0, 0.0)],
            vec![0, 1],
        )
        .unwrap();
        // A far source on +x reaches mic 1 first: tau_0 - tau_1 = 0.1 / c.
        let s = Vec3::new(100.0, 0.0, 0.0);
        assert!((a.tdoa(&s, 0, 1, 343.0) - 0.1 / 343.0).abs() < 1e-8);
        assert!((a.tdoa_far(&Vec3::x(), 0, 1, 343.0) - 0.1 / 343.0).abs() < 1e-12);
        assert!((a.aperture() - 0.1).abs() < 1e-12);
    }
}
