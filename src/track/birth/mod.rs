//! Track birth: the paper's fixed birth points, and births seeded from the measurements that the
//! tracks explain poorly (adaptive birth of Reuter et al. 2014, spec 000 3.9):
//! `r_B(z) = min(r_max, (1 - r_U(z)) / sum_z' (1 - r_U(z')) * lambda_B)`.
//!
//! A camera detection is back-projected along its ray over the depths the region allows; when an
//! audio measurement (direction, cone or 3-D candidate) agrees with some point of the ray, the
//! birth sits there and is sharpened by that measurement. Lone audio candidates give births at
//! the candidate, lone directions a birth along the direction with a broad range prior.

use nalgebra::{Matrix3, Vector3};

use super::config::{BirthConfig, TrackerConfig, UkfConfig};
use super::filter::{Prepared, prepare};
use super::gaussian::Gaussian;
use super::modes::Modes;
use super::motion::{position_of, state_of};
use super::scan::SensorScan;
use super::sensor::{Observation, Sensor};

mod densities;

use crate::geometry::{Aabb, Vec3};
use densities::{
    block_cov, camera_births, direction_birth, linear_birth, make_density, position_block,
};

/// A birth term: a track that may appear in the coming step, with its existence and density.
#[derive(Debug, Clone, PartialEq)]
pub struct BirthTerm<const N: usize> {
    /// Density of the new track's state.
    pub density: Gaussian<N>,
    /// Probability that the track is born (r_B).
    pub existence: f64,
}

/// The configured fixed birth points over the 3-D state.
pub(crate) fn fixed_births(cfg: &BirthConfig) -> Vec<BirthTerm<6>> {
    cfg.fixed
        .iter()
        .map(|f| {
            let p = Vec3::from(f.position);
            BirthTerm {
                density: Gaussian {
                    mean: state_of(&p, &Vec3::zeros()),
                    cov: block_cov(
                        &(Matrix3::identity() * f.position_std_m.powi(2)),
                        f.velocity_std_m_per_s,
                    ),
                },
                existence: f.existence,
            }
        })
        .collect()
}

/// One sensor's measurements of the step with the posterior probability that each was assigned
/// to a track (r_U), and the scan's voice activity.
pub(crate) struct BirthScan<'a> {
    pub sensor: usize,
    pub z: &'a [Vector3<f64>],
    pub assoc: &'a [f64],
    pub activity: Option<f64>,
}

impl<'a> BirthScan<'a> {
    /// The step's scans paired with the association probabilities of their measurements.
    pub fn of_step(scans: &'a [SensorScan], assoc: &'a [Vec<f64>]) -> Vec<Self> {
        scans
            .iter()
            .zip(assoc)
            .map(|(s, a)| BirthScan {
                sensor: s.sensor,
                z: &s.z,
                assoc: a,
                activity: s.activity,
            })
            .collect()
    }
}

/// A measurement-driven birth: the term and its detectability modes (see `modes`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Birth<const N: usize> {
    pub term: BirthTerm<N>,
    pub modes: Vec<f64>,
}

/// What the measurement-driven birth needs to know of the tracker.
pub(crate) struct BirthContext<'a, const N: usize> {
    pub cfg: &'a BirthConfig,
    pub ukf: &'a UkfConfig,
    pub region: Option<&'a Aabb>,
    pub sensors: &'a [Sensor<N>],
    pub modes: &'a Modes,
}

impl<'a, const N: usize> BirthContext<'a, N> {
    /// The context of a tracker configured by `cfg`, over `region`, with its sensors and modes.
    pub fn new(
        cfg: &'a TrackerConfig,
        region: Option<&'a Aabb>,
        sensors: &'a [Sensor<N>],
        modes: &'a Modes,
    ) -> Self {
        Self {
            cfg: &cfg.birth,
            ukf: &cfg.ukf,
            region,
            sensors,
            modes,
        }
    }
}

/// Kinds of birth in decreasing order of trust.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Rank {
    CameraWithAudio,
    Camera,
    Point,
    Direction,
}

struct Candidate<const N: usize> {
    density: Gaussian<N>,
    weight: f64,
    rank: Rank,
    /// The scans whose measurements placed the birth.
    seeds: Vec<usize>,
}

/// Births for the next step from this step's measurements. `confirmed` are the track densities
/// likely enough to suppress births: measurements inside their gate seed nothing.
pub(crate) fn births_from_measurements<const N: usize>(
    ctx: &BirthContext<N>,
    scans: &[BirthScan],
    confirmed: &[Gaussian<N>],
) -> Vec<Birth<N>> {
    let (eligible, total) = eligibility(ctx, scans, confirmed);
    if total.is_nan() || total <= 0.0 || ctx.cfg.max_per_step == 0 {
        return Vec::new();
    }
    let mut free = eligible.clone();
    let mut cands: Vec<Candidate<N>> = Vec::new();
    if N == 6 {
        camera_births(ctx, scans, &mut free, &mut cands);
    }
    for (si, scan) in scans.iter().enumerate() {
        let sensor = &ctx.sensors[scan.sensor];
        for (j, z) in scan.z.iter().enumerate() {
            if !free[si][j] {
                continue;
            }
            let weight = 1.0 - scan.assoc[j].clamp(0.0, 1.0);
            let made = match &sensor.obs {
                Observation::Linear(_) => linear_birth(ctx, sensor, z).map(|d| (d, Rank::Point)),
                Observation::Position if N == 6 => {
                    let cov = sensor.r + Matrix3::identity() * ctx.cfg.position_std_m.powi(2);
                    Some((make_density(&Vec3::from(*z), &cov, ctx.cfg), Rank::Point))
                }
                Observation::Direction { .. } | Observation::Cone { .. } if N == 6 => {
                    direction_birth(ctx, sensor, z).map(|d| (d, Rank::Direction))
                }
                _ => None,
            };
            if let Some((density, rank)) = made {
                cands.push(Candidate {
                    density,
                    weight,
                    rank,
                    seeds: vec![si],
                });
            }
        }
    }
    select(ctx.cfg, cands, total)
        .into_iter()
        .map(|(term, seeds)| condition(ctx, scans, term, &seeds))
        .collect()
}

/// Conditions a birth on the scans of its step that did not place it: each of those sensors
/// either missed the new object or saw it in one of the measurements the tracks leave free.
/// The existence is multiplied by that likelihood ratio and the modes are updated with it, so a
/// voice heard where the camera sees no face (a reverberant image of a talker, mostly) starts
/// with the camera's miss against it, and a face seen while the array hears nothing starts as
/// silent.
fn condition<const N: usize>(
    ctx: &BirthContext<N>,
    scans: &[BirthScan],
    mut term: BirthTerm<N>,
    seeds: &[usize],
) -> Birth<N> {
    let mut modes = ctx.modes.initial();
    let mut log_ratio = 0.0;
    for (si, scan) in scans.iter().enumerate() {
        if seeds.contains(&si) {
            continue;
        }
        let sensor = &ctx.sensors[scan.sensor];
        let Some(p) = prepare(sensor, &term.density, ctx.ukf) else {
            continue;
        };
        let pd = sensor.p_detect_of(&term.density.mean, &p, scan.activity);
        if pd <= 0.0 {
            continue;
        }
        // sum over the free measurements of g(z) / kappa(z)
        let mut seen = 0.0;
        for (z, a) in scan.z.iter().zip(scan.assoc) {
            let d2 = p.mahalanobis(&p.innovation(sensor, z));
            if d2 <= sensor.gate {
                seen += (1.0 - a.clamp(0.0, 1.0))
                    * (p.log_likelihood(d2) - sensor.clutter.log_intensity()).exp();
            }
        }
        let ratio = |pd: f64| (1.0 - pd) + pd * seen;
        let l = match sensor.mode {
            Some(slot) => {
                let on = modes[slot];
                let (l_on, l_off) = (ratio(pd), ratio(sensor.off_p_detect.min(pd)));
                let l = on * l_on + (1.0 - on) * l_off;
                if l > 0.0 {
                    modes[slot] = on * l_on / l;
                }
                l
            }
            None => ratio(pd),
        };
        if l > 0.0 && l.is_finite() {
            log_ratio += l.ln();
        }
    }
    let (r, l) = (term.existence, log_ratio.exp());
    term.existence = (r * l / (1.0 - r + r * l)).clamp(0.0, 1.0);
    Birth { term, modes }
}

/// A track whose detection probability is below this fraction of the sensor's (mostly out of
/// a camera's view) does not suppress births from that sensor's measurements.
const CAN_DETECT: f64 = 0.01;

/// Which measurements may seed a birth, and the Reuter normaliser sum(1 - r_U).
fn eligibility<const N: usize>(
    ctx: &BirthContext<N>,
    scans: &[BirthScan],
    confirmed: &[Gaussian<N>],
) -> (Vec<Vec<bool>>, f64) {
    let mut total = 0.0;
    let mut eligible = Vec::with_capacity(scans.len());
    for scan in scans {
        let sensor = &ctx.sensors[scan.sensor];
        // Only tracks this sensor can detect explain its measurements (a track out of a
        // camera's view does not, whatever its gate says).
        let preps: Vec<_> = confirmed
            .iter()
            .filter_map(|g| prepare(sensor, g, ctx.ukf).map(|p| (g, p)))
            .filter(|(g, p)| {
                sensor.p_detect_of(&g.mean, p, scan.activity) > CAN_DETECT * sensor.p_detect
                    && predicts_precisely(sensor, p, ctx.cfg.suppress_max_spread)
            })
            .map(|(_, p)| p)
            .collect();
        let flags = scan
            .z
            .iter()
            .zip(scan.assoc)
            .map(|(z, &a)| {
                total += 1.0 - a.clamp(0.0, 1.0);
                a <= ctx.cfg.max_association
                    && !preps
                        .iter()
                        .any(|p| p.mahalanobis(&p.innovation(sensor, z)) <= sensor.birth_gate)
            })
            .collect();
        eligible.push(flags);
    }
    (eligible, total)
}

/// Whether a track's predicted measurement `p` is precise enough to claim the measurements in
/// its gate: the spread its own uncertainty gives each measured component is at most
/// `max_spread` of the sensor's noise standard deviations there.
fn predicts_precisely<const N: usize>(
    sensor: &Sensor<N>,
    p: &Prepared<N>,
    max_spread: f64,
) -> bool {
    (0..sensor.dim).all(|i| p.state_spread(sensor, i) <= max_spread * sensor.r[(i, i)].sqrt())
}

/// Sorts, removes births that duplicate a better one, caps and assigns r_B; with the scans that
/// seeded each birth.
fn select<const N: usize>(
    cfg: &BirthConfig,
    mut cands: Vec<Candidate<N>>,
    total: f64,
) -> Vec<(BirthTerm<N>, Vec<usize>)> {
    cands.sort_by(|a, b| a.rank.cmp(&b.rank).then(b.weight.total_cmp(&a.weight)));
    // chi-square 99% quantiles for 1, 2 and 3 position axes.
    const DUPLICATE_GATE: [f64; 3] = [6.635, 9.210, 11.345];
    let gate = DUPLICATE_GATE[(N / 2).clamp(1, 3) - 1];
    let mut out: Vec<(BirthTerm<N>, Vec<usize>)> = Vec::new();
    for c in cands {
        if out.len() >= cfg.max_per_step {
            break;
        }
        let duplicate = out.iter().any(|(b, _)| {
            let d = position_of(&c.density.mean) - position_of(&b.density.mean);
            let s = position_block(&c.density.cov) + position_block(&b.density.cov);
            s.try_inverse().is_some_and(|si| d.dot(&(si * d)) < gate)
        });
        let existence = (c.weight / total * cfg.expected_births).min(cfg.max_existence);
        if !duplicate && existence > 1e-9 {
            out.push((
                BirthTerm {
                    density: c.density,
                    existence,
                },
                c.seeds,
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Camera, Pixel};
    use crate::track::config::{FilterKind, TrackerConfig};
    use crate::track::sensor::SensorModel;
    use nalgebra::SMatrix;

    fn camera() -> Camera {
        // Looking along +y from (2, 0, 1.5), 1000 px focal length.
        let k = Matrix3::new(1000.0, 0.0, 960.0, 0.0, 1000.0, 540.0, 0.0, 0.0, 1.0);
        let r = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0);
        let c = Vec3::new(2.0, 0.0, 1.5);
        Camera::from_krt("cam", 1920.0, 1080.0, k, r, -(r * c), None).unwrap()
    }

    fn sensors(cfg: &TrackerConfig) -> (Vec<Sensor<6>>, Modes) {
        let models = [
            SensorModel::CameraPoint {
                camera: Box::new(camera()),
                noise_std_px: 10.0,
                p_detect: 0.9,
                clutter_rate: 1.0,
                filter: FilterKind::Ukf,
                face_size_m: None,
                face_size_log_std: 0.1,
            },
            SensorModel::AudioDirection {
                origin: Vec3::new(0.0, 2.0, 1.0),
                noise_std_rad: 0.03,
                uses_elevation: false,
                cone_axis: None,
                p_detect: 0.6,
                min_p_detect: 0.02,
                clutter_rate: 2.0,
                filter: FilterKind::Ekf,
            },
        ];
        let mut sensors: Vec<Sensor<6>> = models
            .iter()
            .enumerate()
            .map(|(i, m)| Sensor::compile(m, i, cfg).unwrap())
            .collect();
        let modes = Modes::assign(&mut sensors, &cfg.voice, &cfg.face);
        (sensors, modes)
    }

    /// The 4 x 5 x 2.5 m room of these tests.
    fn room() -> Aabb {
        Aabb::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(4.0, 5.0, 2.5)).unwrap()
    }

    #[test]
    fn camera_ray_and_audio_azimuth_meet_at_the_source() {
        let cfg = TrackerConfig::default();
        let (sensors, modes) = sensors(&cfg);
        let region = room();
        let source = Vec3::new(2.6, 3.0, 1.6);
        let x = state_of::<6>(&source, &Vec3::zeros());
        let px = sensors[0].measure(&x).unwrap();
        let az = sensors[1].measure(&x).unwrap();
        let ctx = BirthContext::new(&cfg, Some(&region), &sensors, &modes);
        let (zc, za) = ([px], [az]);
        let scans = [
            BirthScan {
                sensor: 0,
                z: &zc,
                assoc: &[0.0],
                activity: None,
            },
            BirthScan {
                sensor: 1,
                z: &za,
                assoc: &[0.0],
                activity: Some(1.0),
            },
        ];
        let births: Vec<_> = births_from_measurements(&ctx, &scans, &[])
            .into_iter()
            .map(|b| b.term)
            .collect();
        assert_eq!(births.len(), 1, "one fused birth, not one per sensor");
        let p = position_of(&births[0].density.mean);
        assert!((p - source).norm() < 0.05, "{p:?}");
        // The audio measurement sharpened the depth: the along-ray spread is far below the
        // region's depth span.
        let dir = camera().back_project(&Pixel::new(px[0], px[1])).direction;
        let along = (dir.transpose() * position_block(&births[0].density.cov) * dir)[0].sqrt();
        assert!(along < 0.3, "{along}");
        assert!(births[0].existence <= cfg.birth.max_existence);

        // A confirmed track at the source suppresses both measurements.
        let track = Gaussian {
            mean: x,
            cov: SMatrix::<f64, 6, 6>::identity() * 0.01,
        };
        assert!(births_from_measurements(&ctx, &scans, &[track]).is_empty());
        // Measurements already explained by the tracks seed nothing.
        let explained = [
            BirthScan {
                sensor: 0,
                z: &zc,
                assoc: &[0.95],
                activity: None,
            },
            BirthScan {
                sensor: 1,
                z: &za,
                assoc: &[0.95],
                activity: Some(1.0),
            },
        ];
        assert!(births_from_measurements(&ctx, &explained, &[]).is_empty());
    }

    #[test]
    fn a_track_unmeasured_for_long_does_not_suppress_a_birth_in_its_wide_gate() {
        let cfg = TrackerConfig::default();
        let (sensors, modes) = sensors(&cfg);
        let region = room();
        let source = Vec3::new(2.6, 3.0, 1.6);
        let px = sensors[0]
            .measure(&state_of::<6>(&source, &Vec3::zeros()))
            .unwrap();
        let ctx = BirthContext::new(&cfg, Some(&region), &sensors, &modes);
        let zc = [px];
        let scans = [BirthScan {
            sensor: 0,
            z: &zc,
            assoc: &[0.0],
            activity: None,
        }];
        // A track last measured long ago, 0.8 m from the face with 0.8 m of spread per axis:
        // the face lies inside its gate, and the camera could still see it.
        let stale = Gaussian {
            mean: state_of::<6>(&(source + Vec3::new(0.8, -0.5, 0.3)), &Vec3::zeros()),
            cov: SMatrix::<f64, 6, 6>::identity() * 0.64,
        };
        let p = prepare(&sensors[0], &stale, &cfg.ukf).unwrap();
        assert!(p.mahalanobis(&p.innovation(&sensors[0], &px)) <= sensors[0].birth_gate);
        assert!(sensors[0].p_detect_of(&stale.mean, &p, None) > CAN_DETECT * sensors[0].p_detect);
        assert_eq!(births_from_measurements(&ctx, &scans, &[stale]).len(), 1);
        // The same track measured a step ago claims the face.
        let fresh = Gaussian {
            cov: SMatrix::<f64, 6, 6>::identity() * 0.01,
            mean: state_of::<6>(&source, &Vec3::zeros()),
        };
        assert!(births_from_measurements(&ctx, &scans, &[fresh]).is_empty());
    }

    #[test]
    fn a_lone_azimuth_gives_a_broad_birth_on_its_bearing() {
        let cfg = TrackerConfig::default();
        let (sensors, modes) = sensors(&cfg);
        let region = room();
        let ctx = BirthContext::new(&cfg, Some(&region), &sensors, &modes);
        let za = [Vector3::new(0.3, 0.0, 0.0)];
        let scans = [BirthScan {
            sensor: 1,
            z: &za,
            assoc: &[0.0],
            activity: Some(1.0),
        }];
        let b = births_from_measurements(&ctx, &scans, &[]);
        assert_eq!(b.len(), 1);
        let p = position_of(&b[0].term.density.mean);
        let d = p - Vec3::new(0.0, 2.0, p.z);
        assert!((d.y.atan2(d.x) - 0.3).abs() < 1e-9);
        assert!(region.contains(&p));
    }

    #[test]
    fn a_voice_where_the_camera_sees_no_face_starts_with_the_camera_miss_against_it() {
        let cfg = TrackerConfig::default();
        let (sensors, modes) = sensors(&cfg);
        let region = room();
        let ctx = BirthContext::new(&cfg, Some(&region), &sensors, &modes);
        // An azimuth towards a point the camera sees well.
        let target = Vec3::new(2.6, 3.0, 1.6);
        let za = [sensors[1]
            .measure(&state_of::<6>(&target, &Vec3::zeros()))
            .unwrap()];
        let audio = BirthScan {
            sensor: 1,
            z: &za,
            assoc: &[0.0],
            activity: Some(1.0),
        };
        let alone = births_from_measurements(&ctx, &[audio], &[]);
        let audio = BirthScan {
            sensor: 1,
            z: &za,
            assoc: &[0.0],
            activity: Some(1.0),
        };
        let empty = BirthScan {
            sensor: 0,
            z: &[],
            assoc: &[],
            activity: None,
        };
        let unseen = births_from_measurements(&ctx, &[empty, audio], &[]);
        assert_eq!((alone.len(), unseen.len()), (1, 1));
        let (r0, r1) = (alone[0].term.existence, unseen[0].term.existence);
        // Most of the birth's bearing lies in view: the miss costs most of the existence.
        assert!(r1 < 0.5 * r0, "{r1} vs {r0}");
        let face = sensors[0].mode.unwrap();
        assert!(unseen[0].modes[face] < alone[0].modes[face]);
        // The voice seeded the birth, so its mode is left at the prior.
        let voice = sensors[1].mode.unwrap();
        assert_eq!(unseen[0].modes[voice], alone[0].modes[voice]);
    }
}
