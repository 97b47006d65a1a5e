//! The birth densities each kind of measurement gives: camera rays met by audio, lone audio
//! directions with a broad range prior, 3-D candidates and linear measurements.

use nalgebra::{Matrix3, SMatrix, Vector3};

use super::{BirthContext, BirthScan, Candidate, Rank};
use crate::geometry::{Aabb, Camera, Pixel, Ray, Vec3, direction_from_angles};
use crate::track::config::BirthConfig;
use crate::track::filter::update;
use crate::track::gaussian::Gaussian;
use crate::track::motion::state_of;
use crate::track::sensor::{Observation, Sensor, ray_interval};

pub(super) fn position_block<const N: usize>(p: &SMatrix<f64, N, N>) -> Matrix3<f64> {
    let d = (N / 2).min(3);
    let mut m = Matrix3::identity();
    for i in 0..d {
        for j in 0..d {
            m[(i, j)] = p[(i, j)];
        }
    }
    m
}

pub(super) fn block_cov<const N: usize>(pos: &Matrix3<f64>, vel_std: f64) -> SMatrix<f64, N, N> {
    let d = N / 2;
    let mut c = SMatrix::<f64, N, N>::zeros();
    for i in 0..d.min(3) {
        for j in 0..d.min(3) {
            c[(i, j)] = pos[(i, j)];
        }
        c[(d + i, d + i)] = vel_std * vel_std;
    }
    c
}

/// A birth density at `p` with position covariance `pos_cov` (plus the birth spread).
pub(super) fn make_density<const N: usize>(
    p: &Vec3,
    pos_cov: &Matrix3<f64>,
    cfg: &BirthConfig,
) -> Gaussian<N> {
    let cov = pos_cov + Matrix3::identity() * cfg.position_std_m.powi(2);
    Gaussian {
        mean: state_of(p, &Vec3::zeros()),
        cov: block_cov(&cov, cfg.velocity_std_m_per_s),
    }
}

/// Covariance elongated along unit `axis`: sd `along` on it and `across` around it.
fn elongated(axis: &Vec3, along: f64, across: f64) -> Matrix3<f64> {
    let aa = axis * axis.transpose();
    aa * along * along + (Matrix3::identity() - aa) * across * across
}

/// Depth interval of a ray: inside the region when known, else the configured range.
fn depth_interval(ray: &Ray, region: Option<&Aabb>, range: [f64; 2]) -> Option<(f64, f64)> {
    match region {
        Some(r) => {
            let (t0, t1) = ray_interval(&ray.origin, &ray.direction, r)?;
            let t0 = t0.max(range[0].min(t1 * 0.5));
            (t1 > t0).then_some((t0, t1))
        }
        None => Some((range[0], range[1])),
    }
}

/// Births from camera detections: along the ray, at the depth an audio measurement picks when
/// one agrees.
pub(super) fn camera_births<const N: usize>(
    ctx: &BirthContext<N>,
    scans: &[BirthScan],
    free: &mut [Vec<bool>],
    cands: &mut Vec<Candidate<N>>,
) {
    for (si, scan) in scans.iter().enumerate() {
        let sensor = &ctx.sensors[scan.sensor];
        let Some(camera) = sensor.camera() else {
            continue;
        };
        let px_std = sensor.r[(0, 0)].sqrt();
        for (j, z) in scan.z.iter().enumerate() {
            if !free[si][j] {
                continue;
            }
            let ray = camera.back_project(&Pixel::new(z[0], z[1]));
            let Some((t0, t1)) = depth_interval(&ray, ctx.region, ctx.cfg.camera_depth_range_m)
            else {
                continue;
            };
            let partner = best_audio_partner(ctx, scans, free, &ray, (t0, t1));
            // The box size, when measured, gives the depth: log size falls as -log depth, so
            // its noise is a relative depth error.
            let sized = sensor.face_size().and_then(|_| {
                let t = size_depth(sensor, z, &ray, (t0, t1))?;
                Some((t, t * sensor.r[(2, 2)].sqrt()))
            });
            let (t, rank) = match (sized, partner) {
                (Some((t, _)), Some(_)) => (t, Rank::CameraWithAudio),
                (Some((t, _)), None) => (t, Rank::Camera),
                (None, Some((_, _, t))) => (t, Rank::CameraWithAudio),
                (None, None) => (0.5 * (t0 + t1), Rank::Camera),
            };
            let along = sized.map_or(0.25 * (t1 - t0), |(_, sd)| sd);
            let p = ray.at(t);
            let across = lateral_std(camera, &p, px_std, t);
            let pos = elongated(&ray.direction, along, across);
            let mut density = make_density::<N>(&p, &pos, ctx.cfg);
            let mut seeds = vec![si];
            if let Some((sa, ja, _)) = partner {
                let a = &scans[sa];
                if let Some((g, _)) = update(&ctx.sensors[a.sensor], &density, &a.z[ja], ctx.ukf) {
                    density = g;
                }
                free[sa][ja] = false;
                seeds.push(sa);
            }
            free[si][j] = false;
            cands.push(Candidate {
                density,
                weight: 1.0 - scan.assoc[j].clamp(0.0, 1.0),
                rank,
                seeds,
            });
        }
    }
}

/// The depth along a camera ray at which a face of the sensor's size has the measured apparent
/// size (log size in `z[2]`), within the interval; None when the model is undefined there.
fn size_depth<const N: usize>(
    sensor: &Sensor<N>,
    z: &Vector3<f64>,
    ray: &Ray,
    interval: (f64, f64),
) -> Option<f64> {
    let cost = |t: f64| -> f64 {
        let x = state_of::<N>(&ray.at(t), &Vec3::zeros());
        sensor
            .measure(&x)
            .map_or(f64::INFINITY, |h| (z[2] - h[2]).powi(2))
    };
    // Sizes beyond the interval put the birth at its end, where the ray leaves the region.
    let (t, v) = minimise_on_interval(cost, interval.0, interval.1);
    v.is_finite().then_some(t)
}

/// Lateral position standard deviation of a pixel's ray at point `p`.
fn lateral_std(camera: &Camera, p: &Vec3, px_std: f64, depth: f64) -> f64 {
    camera
        .project_with_jacobian(p)
        .and_then(|(_, j)| {
            let jj = j * j.transpose();
            let (a, b, c) = (jj[(0, 0)], jj[(0, 1)], jj[(1, 1)]);
            let lmin = 0.5 * (a + c) - (0.25 * (a - c) * (a - c) + b * b).sqrt();
            (lmin > 1e-12).then(|| px_std / lmin.sqrt())
        })
        .unwrap_or(0.02 * depth)
}

/// The free audio measurement that best agrees with some depth of the ray: (scan, index, depth).
fn best_audio_partner<const N: usize>(
    ctx: &BirthContext<N>,
    scans: &[BirthScan],
    free: &[Vec<bool>],
    ray: &Ray,
    interval: (f64, f64),
) -> Option<(usize, usize, f64)> {
    let mut best: Option<(usize, usize, f64, f64)> = None;
    for (sa, a) in scans.iter().enumerate() {
        let sensor = &ctx.sensors[a.sensor];
        if !sensor.audio {
            continue;
        }
        let Some(r_inv) = sensor.r.try_inverse() else {
            continue;
        };
        for (ja, z) in a.z.iter().enumerate() {
            if !free[sa][ja] {
                continue;
            }
            let cost = |t: f64| -> f64 {
                let x = state_of::<N>(&ray.at(t), &Vec3::zeros());
                match sensor.measure(&x) {
                    Some(h) => {
                        let r = sensor.residual(z, &h);
                        r.dot(&(r_inv * r))
                    }
                    None => f64::INFINITY,
                }
            };
            let (t, d2) = minimise_on_interval(cost, interval.0, interval.1);
            if d2 <= sensor.gate && best.is_none_or(|b| d2 < b.3) {
                best = Some((sa, ja, t, d2));
            }
        }
    }
    best.map(|(s, j, t, _)| (s, j, t))
}

/// Minimum of a 1-D function: a grid then golden-section refinement around the best node.
fn minimise_on_interval(f: impl Fn(f64) -> f64, lo: f64, hi: f64) -> (f64, f64) {
    const GRID: usize = 48;
    let step = (hi - lo) / (GRID - 1) as f64;
    let (mut bt, mut bv) = (lo, f64::INFINITY);
    for i in 0..GRID {
        let t = lo + step * i as f64;
        let v = f(t);
        if v < bv {
            (bt, bv) = (t, v);
        }
    }
    let (mut a, mut b) = ((bt - step).max(lo), (bt + step).min(hi));
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..40 {
        let c = b - g * (b - a);
        let d = a + g * (b - a);
        if f(c) < f(d) {
            b = d;
        } else {
            a = c;
        }
    }
    let t = 0.5 * (a + b);
    let v = f(t);
    if v < bv { (t, v) } else { (bt, bv) }
}

/// A birth along an audio direction (or on a cone) with a broad range prior.
pub(super) fn direction_birth<const N: usize>(
    ctx: &BirthContext<N>,
    sensor: &Sensor<N>,
    z: &Vector3<f64>,
) -> Option<Gaussian<N>> {
    let cfg = ctx.cfg;
    let ang_std = sensor.r[(0, 0)].sqrt();
    let centre = ctx.region.map(|r| r.center());
    let (origin, dir, across_extra) = match &sensor.obs {
        Observation::Direction { origin, elevation } if *elevation => {
            (*origin, direction_from_angles(z[0], z[1]), None)
        }
        Observation::Direction { origin, .. } => {
            // Azimuth only: a horizontal ray at the typical height, broad vertically.
            let height = centre.map_or(cfg.default_height_m, |c| c.z);
            let o = Vec3::new(origin.x, origin.y, height);
            let vertical = ctx.region.map_or(0.5, |r| 0.25 * (r.max.z - r.min.z));
            (
                o,
                direction_from_angles(z[0], 0.0),
                Some((Vec3::z(), vertical, false)),
            )
        }
        Observation::Cone { origin, axis } => {
            // The cone's direction nearest to the region centre (or to the horizontal).
            let toward = centre.map_or(Vec3::x(), |c| c - origin);
            let perp = toward - axis * axis.dot(&toward);
            let perp = if perp.norm() > 1e-9 {
                perp.normalize()
            } else {
                axis.cross(&Vec3::z())
                    .try_normalize(1e-9)
                    .unwrap_or(Vec3::y())
            };
            let d = axis * z[0].cos() + perp * z[0].sin();
            let around = axis.cross(&d).try_normalize(1e-9).unwrap_or(Vec3::z());
            // The roll about the axis is unmeasured: half a radian of arc, scaled by range.
            (*origin, d, Some((around, 0.5, true)))
        }
        _ => return None,
    };
    let ray = Ray {
        origin,
        direction: dir.normalize(),
    };
    let (t0, t1) = match ctx.region {
        Some(r) => ray_interval(&ray.origin, &ray.direction, r)?,
        None => (0.5 * cfg.direction_range_m, 1.5 * cfg.direction_range_m),
    };
    let t = 0.5 * (t0 + t1);
    let mut pos = elongated(&ray.direction, 0.25 * (t1 - t0).max(0.2), t * ang_std);
    if let Some((axis, sd, angular)) = across_extra {
        let sd = if angular { sd * t } else { sd };
        pos += axis * axis.transpose() * sd * sd;
    }
    Some(make_density(&ray.at(t), &pos, cfg))
}

/// A birth from a generic linear measurement: a Kalman update of a broad prior.
pub(super) fn linear_birth<const N: usize>(
    ctx: &BirthContext<N>,
    sensor: &Sensor<N>,
    z: &Vector3<f64>,
) -> Option<Gaussian<N>> {
    const BROAD_STD: f64 = 1e4;
    let d = N / 2;
    let mut cov = SMatrix::<f64, N, N>::zeros();
    for i in 0..N {
        let sd = if i < d {
            BROAD_STD
        } else {
            ctx.cfg.velocity_std_m_per_s
        };
        cov[(i, i)] = sd * sd;
    }
    let prior = Gaussian {
        mean: nalgebra::SVector::<f64, N>::zeros(),
        cov,
    };
    update(sensor, &prior, z, ctx.ukf).map(|(g, _)| g)
}
