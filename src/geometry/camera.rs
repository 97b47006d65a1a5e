//! Pinhole cameras with optional OpenCV lens distortion.
//!
//! A camera is given by its 3x4 projection matrix P (world metres to pixels) or by K, R, t with
//! P = K [R | t]. When intrinsics K and distortion (k1, k2, p1, p2, k3) are both present, the
//! undistorted pixel from P is normalised with K^-1, distorted with the OpenCV model and mapped back
//! with K, exactly as the scene format specifies.

use nalgebra::{Matrix2, Matrix2x3, Matrix3, Matrix3x4, Vector3, Vector4};

use super::{GeometryError, Pixel, Vec3, check_finite};

/// OpenCV radial-tangential distortion coefficients.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Distortion {
    /// Radial coefficient of r^2.
    pub k1: f64,
    /// Radial coefficient of r^4.
    pub k2: f64,
    /// First tangential coefficient.
    pub p1: f64,
    /// Second tangential coefficient.
    pub p2: f64,
    /// Radial coefficient of r^6.
    pub k3: f64,
}

impl Distortion {
    /// Coefficients from a list `[k1, k2, p1, p2, k3]`; shorter lists mean trailing zeros.
    pub fn from_slice(c: &[f64]) -> Result<Self, GeometryError> {
        if c.len() > 5 {
            return Err(GeometryError::new(
                "distortion",
                "has more than 5 coefficients (k1, k2, p1, p2, k3)",
            ));
        }
        check_finite("distortion", c)?;
        let g = |i: usize| c.get(i).copied().unwrap_or(0.0);
        Ok(Self {
            k1: g(0),
            k2: g(1),
            p1: g(2),
            p2: g(3),
            k3: g(4),
        })
    }

    /// The coefficients as `[k1, k2, p1, p2, k3]`.
    pub fn to_array(&self) -> [f64; 5] {
        [self.k1, self.k2, self.p1, self.p2, self.k3]
    }

    /// Whether all coefficients are zero (no distortion).
    pub fn is_zero(&self) -> bool {
        self.to_array().iter().all(|&c| c == 0.0)
    }

    /// Distorts a normalised image point.
    pub fn apply(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
        (xd, yd)
    }

    /// Jacobian of [`Self::apply`] with respect to (x, y).
    pub fn jacobian(&self, x: f64, y: f64) -> Matrix2<f64> {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        // d(radial)/d(r2)
        let dr = self.k1 + r2 * (2.0 * self.k2 + 3.0 * r2 * self.k3);
        let dxd_dx = radial + x * dr * 2.0 * x + 2.0 * self.p1 * y + 6.0 * self.p2 * x;
        let dxd_dy = x * dr * 2.0 * y + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
        let dyd_dx = y * dr * 2.0 * x + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
        let dyd_dy = radial + y * dr * 2.0 * y + 6.0 * self.p1 * y + 2.0 * self.p2 * x;
        Matrix2::new(dxd_dx, dxd_dy, dyd_dx, dyd_dy)
    }

    /// Inverts [`Self::apply`] by Newton iteration (falls back to the input if it diverges).
    pub fn remove(&self, xd: f64, yd: f64) -> (f64, f64) {
        let (mut x, mut y) = (xd, yd);
        for _ in 0..30 {
            let (fx, fy) = self.apply(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            if ex.abs() < 1e-14 && ey.abs() < 1e-14 {
                break;
            }
            let Some(inv) = self.jacobian(x, y).try_inverse() else {
                break;
            };
            x -= inv[(0, 0)] * ex + inv[(0, 1)] * ey;
            y -= inv[(1, 0)] * ex + inv[(1, 1)] * ey;
            if !x.is_finite() || !y.is_finite() {
                return (xd, yd);
            }
        }
        (x, y)
    }
}

/// A ray from a camera centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Camera centre.
    pub origin: Vec3,
    /// Unit direction, pointing in front of the camera.
    pub direction: Vec3,
}

impl Ray {
    /// The point at `distance` metres along the ray.
    pub fn at(&self, distance: f64) -> Vec3 {
        self.origin + self.direction * distance
    }
}

/// A calibrated camera.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    /// Identifier, unique within a layout.
    pub id: String,
    /// Image width in pixels.
    pub width: f64,
    /// Image height in pixels.
    pub height: f64,
    /// The projection matrix as given.
    projection: Matrix3x4<f64>,
    /// P scaled so that its third row gives the depth in metres, positive in front.
    normalized: Matrix3x4<f64>,
    /// Inverse of the left 3x3 block of `normalized`.
    m_inv: Matrix3<f64>,
    centre: Vec3,
    intrinsics: Option<Matrix3<f64>>,
    k_inv: Option<Matrix3<f64>>,
    distortion: Distortion,
}

impl Camera {
    /// A camera from its projection matrix, with optional intrinsics and distortion
    /// (distortion requires intrinsics).
    pub fn from_projection(
        id: impl Into<String>,
        width: f64,
        height: f64,
        projection: Matrix3x4<f64>,
        intrinsics: Option<Matrix3<f64>>,
        distortion: Option<&[f64]>,
    ) -> Result<Self, GeometryError> {
        let id = id.into();
        if id.is_empty() {
            return Err(GeometryError::new("id", "must not be empty"));
        }
        for (field, v) in [("width", width), ("height", height)] {
            if !(v.is_finite() && v >= 1.0) {
                return Err(GeometryError::new(field, "must be at least 1 pixel"));
            }
        }
        check_finite("projection", projection.as_slice())?;
        let m = projection.fixed_view::<3, 3>(0, 0).into_owned();
        let det = m.determinant();
        let row3 = Vector3::new(projection[(2, 0)], projection[(2, 1)], projection[(2, 2)]);
        let scale = row3.norm();
        if det.abs() < 1e-12 * scale.powi(3).max(1e-300) || scale < 1e-12 {
            return Err(GeometryError::new(
                "projection",
                "is singular (its left 3x3 block has no inverse)",
            ));
        }
        let normalized = projection * (det.signum() / scale);
        let mn = normalized.fixed_view::<3, 3>(0, 0).into_owned();
        let m_inv = mn
            .try_inverse()
            .ok_or_else(|| GeometryError::new("projection", "is singular"))?;
        let centre = -(m_inv * normalized.column(3));
        let (k_inv, distortion) = match (&intrinsics, distortion) {
            (Some(k), d) => {
                check_finite("intrinsics", k.as_slice())?;
                if k[(2, 0)] != 0.0 || k[(2, 1)] != 0.0 || (k[(2, 2)] - 1.0).abs() > 1e-9 {
                    return Err(GeometryError::new(
                        "intrinsics",
                        "last row must be [0, 0, 1]",
                    ));
                }
                if k[(1, 0)] != 0.0 || k[(0, 0)] <= 0.0 || k[(1, 1)] <= 0.0 {
                    return Err(GeometryError::new(
                        "intrinsics",
                        "must be upper triangular with positive focal lengths",
                    ));
                }
                let k_inv = k
                    .try_inverse()
                    .ok_or_else(|| GeometryError::new("intrinsics", "is singular"))?;
                (Some(k_inv), Distortion::from_slice(d.unwrap_or(&[]))?)
            }
            (None, Some(d)) if d.iter().any(|&c| c != 0.0) => {
                return Err(GeometryError::new("distortion", "requires intrinsics"));
            }
            (None, _) => (None, Distortion::default()),
        };
        Ok(Self {
            id,
            width,
            height,
            projection,
            normalized,
            m_inv,
            centre,
            intrinsics,
            k_inv,
            distortion,
        })
    }

    /// A camera from intrinsics K, rotation R (world to camera) and translation t: P = K [R | t].
    pub fn from_krt(
        id: impl Into<String>,
        width: f64,
        height: f64,
        k: Matrix3<f64>,
        r: Matrix3<f64>,
        t: Vec3,
        distortion: Option<&[f64]>,
    ) -> Result<Self, GeometryError> {
        check_finite("rotation", r.as_slice())?;
        check_finite("translation", t.as_slice())?;
        if (r.transpose() * r - Matrix3::identity()).norm() > 1e-6
            || (r.determinant() - 1.0).abs() > 1e-6
        {
            return Err(GeometryError::new(
                "rotation",
                "must be a rotation matrix (orthonormal, det +1)",
            ));
        }
        let mut rt = Matrix3x4::zeros();
        rt.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        rt.set_column(3, &t);
        Self::from_projection(id, width, height, k * rt, Some(k), distortion)
    }

    /// The projection matrix as given.
    pub fn projection(&self) -> &Matrix3x4<f64> {
        &self.projection
    }

    /// The intrinsics, when given.
    pub fn intrinsics(&self) -> Option<&Matrix3<f64>> {
        self.intrinsics.as_ref()
    }

    /// The distortion coefficients (all zero when none).
    pub fn distortion(&self) -> &Distortion {
        &self.distortion
    }

    /// Camera centre in world coordinates.
    pub fn centre(&self) -> Vec3 {
        self.centre
    }

    /// Unit optical axis (world direction the camera looks along).
    pub fn optical_axis(&self) -> Vec3 {
        Vec3::new(
            self.normalized[(2, 0)],
            self.normalized[(2, 1)],
            self.normalized[(2, 2)],
        )
    }

    /// Depth of `x` along the optical axis in metres; positive in front of the camera.
    pub fn depth(&self, x: &Vec3) -> f64 {
        (self.normalized * Vector4::new(x.x, x.y, x.z, 1.0))[2]
    }

    fn distorts(&self) -> bool {
        self.k_inv.is_some() && !self.distortion.is_zero()
    }

    /// Pixel of world point `x`, or `None` when it is not in front of the camera.
    pub fn project(&self, x: &Vec3) -> Option<Pixel> {
        self.project_with_jacobian(x).map(|(p, _)| p)
    }

    /// Pixel of `x` and the 2x3 Jacobian d(pixel)/d(x), or `None` behind the camera.
    pub fn project_with_jacobian(&self, x: &Vec3) -> Option<(Pixel, Matrix2x3<f64>)> {
        let h = self.normalized * Vector4::new(x.x, x.y, x.z, 1.0);
        if h[2].is_nan() || h[2] <= 1e-6 {
            return None;
        }
        let (u0, v0) = (h[0] / h[2], h[1] / h[2]);
        let p = &self.normalized;
        let mut j0 = Matrix2x3::zeros();
        for c in 0..3 {
            j0[(0, c)] = (p[(0, c)] - u0 * p[(2, c)]) / h[2];
            j0[(1, c)] = (p[(1, c)] - v0 * p[(2, c)]) / h[2];
        }
        if !self.distorts() {
            return Some((Pixel::new(u0, v0), j0));
        }
        let (k, k_inv) = (self.intrinsics.as_ref()?, self.k_inv.as_ref()?);
        let n = k_inv * Vector3::new(u0, v0, 1.0);
        let (xd, yd) = self.distortion.apply(n[0], n[1]);
        let px = k * Vector3::new(xd, yd, 1.0);
        let k22 = k.fixed_view::<2, 2>(0, 0).into_owned();
        let kinv22 = k_inv.fixed_view::<2, 2>(0, 0).into_owned();
        let j = k22 * self.distortion.jacobian(n[0], n[1]) * kinv22 * j0;
        Some((Pixel::new(px[0], px[1]), j))
    }

    /// Removes lens distortion from a pixel (identity without distortion).
    pub fn undistort(&self, pixel: &Pixel) -> Pixel {
        match (&self.intrinsics, &self.k_inv) {
            (Some(k), Some(k_inv)) if !self.distortion.is_zero() => {
                let d = k_inv * Vector3::new(pixel.x, pixel.y, 1.0);
                let (x, y) = self.distortion.remove(d[0], d[1]);
                let u = k * Vector3::new(x, y, 1.0);
                Pixel::new(u[0], u[1])
            }
            _ => *pixel,
        }
    }

    /// The ray of world points that project to `pixel`.
    pub fn back_project(&self, pixel: &Pixel) -> Ray {
        let u = self.undistort(pixel);
        let mut d = self.m_inv * Vector3::new(u.x, u.y, 1.0);
        // The normalised P gives depth = m3 . d for a direction d from the centre.
        if self.optical_axis().dot(&d) < 0.0 {
            d = -d;
        }
        Ray {
            origin: self.centre,
            direction: d.normalize(),
        }
    }

    /// Whether `pixel` lies inside the image.
    pub fn contains_pixel(&self, pixel: &Pixel) -> bool {
        pixel.x >= 0.0 && pixel.x <= self.width && pixel.y >= 0.0 && pixel.y <= self.height
    }

    /// Whether `x` is in front of the camera and projects inside the image.
    pub fn in_view(&self, x: &Vec3) -> bool {
        let Some(p) = self.project(x) else {
            return false;
        };
        if !self.contains_pixel(&p) {
            return false;
        }
        // Strong distortion polynomials fold far-off-axis points back into the image; require
        // the undistorted pixel to be near the image as well.
        if self.distorts() {
            let h = self.normalized * Vector4::new(x.x, x.y, x.z, 1.0);
            let (u0, v0) = (h[0] / h[2], h[1] / h[2]);
            let (mw, mh) = (self.width, self.height);
            return u0 > -mw && u0 < 2.0 * mw && v0 > -mh && v0 < 2.0 * mh;
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Camera 1 of the seed paper (Table II).
    fn paper_camera() -> Camera {
        let p = Matrix3x4::new(
            -1021.7, -827.2, -575.8, 7071.5, 31.8, 142.0, -1184.0, 2012.8, 0.04, -0.83, -0.56, 3.81,
        );
        Camera::from_projection("cam0", 1920.0, 1080.0, p, None, None).unwrap()
    }

    fn krt_camera(distortion: Option<&[f64]>) -> Camera {
        let k = Matrix3::new(800.0, 0.5, 640.0, 0.0, 810.0, 360.0, 0.0, 0.0, 1.0);
        // Looking along +y from (0, -3, 1.5): camera x = world x, camera y = -world z, z = world y.
        let r = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0);
        let c = Vec3::new(0.0, -3.0, 1.5);
        Camera::from_krt("c", 1280.0, 720.0, k, r, -(r * c), distortion).unwrap()
    }

    #[test]
    fn paper_camera_matches_published_decomposition() {
        let cam = paper_camera();
        let c = cam.centre();
        assert!(
            (c - Vec3::new(3.048, 3.270, 2.174)).norm() < 0.01,
            "centre {c}"
        );
        // The birth point (3.0, 0.5, 1.7) lands near (1020, 65) px (spec 003 section 4.3).
        let p = cam.project(&Vec3::new(3.0, 0.5, 1.7)).unwrap();
        assert!((p - Pixel::new(1020.0, 65.0)).norm() < 3.0, "pixel {p}");
        assert!(cam.in_view(&Vec3::new(3.0, 0.5, 1.7)));
        // Behind the camera (beyond the wall at y = 3.41) nothing projects.
        assert!(cam.project(&Vec3::new(3.0, 4.5, 2.2)).is_none());
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        for cam in [
            paper_camera(),
            krt_camera(Some(&[-0.3, 0.1, 0.001, -0.002, 0.01])),
        ] {
            let x = Vec3::new(0.4, 1.0, 1.2);
            let x = if cam.id == "cam0" {
                Vec3::new(3.2, 1.0, 1.5)
            } else {
                x
            };
            let (_, j) = cam.project_with_jacobian(&x).unwrap();
            let h = 1e-6;
            for c in 0..3 {
                let mut dx = Vec3::zeros();
                dx[c] = h;
                let num =
                    (cam.project(&(x + dx)).unwrap() - cam.project(&(x - dx)).unwrap()) / (2.0 * h);
                for r in 0..2 {
                    assert!(
                        (num[r] - j[(r, c)]).abs() < 1e-3 * (1.0 + num[r].abs()),
                        "{num} vs {j}"
                    );
                }
            }
        }
    }

    #[test]
    fn back_projection_inverts_projection() {
        for cam in [
            paper_camera(),
            krt_camera(None),
            krt_camera(Some(&[-0.25, 0.08, 0.001, 0.002])),
        ] {
            let x = if cam.id == "cam0" {
                Vec3::new(2.5, 1.2, 1.6)
            } else {
                Vec3::new(0.5, 1.0, 1.3)
            };
            let p = cam.project(&x).unwrap();
            let ray = cam.back_project(&p);
            let dist = (x - ray.origin).norm();
            assert!((ray.at(dist) - x).norm() < 1e-6, "{}", cam.id);
            assert!(cam.depth(&ray.at(1.0)) > 0.0);
        }
    }

    #[test]
    fn distortion_changes_pixels_and_inverts() {
        let d = Distortion::from_slice(&[-0.3, 0.1, 0.001, -0.002, 0.01]).unwrap();
        let (xd, yd) = d.apply(0.3, -0.2);
        assert!((xd - 0.3).abs() > 1e-3);
        let (x, y) = d.remove(xd, yd);
        assert!((x - 0.3).abs() < 1e-10 && (y + 0.2).abs() < 1e-10);
        let plain = krt_camera(None);
        let bent = krt_camera(Some(&[-0.3, 0.1]));
        let x = Vec3::new(0.8, 1.0, 1.0);
        assert!((plain.project(&x).unwrap() - bent.project(&x).unwrap()).norm() > 1.0);
        // The image centre is a fixed point of radial distortion.
        let on_axis = Vec3::new(0.0, 2.0, 1.5);
        assert!((bent.project(&on_axis).unwrap() - Pixel::new(640.0, 360.0)).norm() < 1e-6);
    }

    #[test]
    fn in_view_checks_image_bounds_and_side() {
        let cam = krt_camera(None);
        assert!(cam.in_view(&Vec3::new(0.0, 1.0, 1.5)));
        assert!(!cam.in_view(&Vec3::new(0.0, -5.0, 1.5)), "behind");
        assert!(!cam.in_view(&Vec3::new(10.0, -2.9, 1.5)), "far to the side");
    }

    #[test]
    fn rejects_bad_calibration() {
        let z = Matrix3x4::zeros();
        assert_eq!(
            Camera::from_projection("c", 10.0, 10.0, z, None, None)
                .unwrap_err()
                .field,
            "projection"
        );
        let p = paper_camera().projection().to_owned();
        let e = Camera::from_projection("c", 10.0, 10.0, p, None, Some(&[0.1])).unwrap_err();
        assert_eq!(e.field, "distortion");
        let k = Matrix3::identity();
        let r = Matrix3::new(1.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 1.0);
        assert_eq!(
            Camera::from_krt("c", 10.0, 10.0, k, r, Vec3::zeros(), None)
                .unwrap_err()
                .field,
            "rotation"
        );
    }
}
