//! Audio arrays that give directions only (a compact circular array's azimuths, a linear
//! array's cone angles), alone or with the camera.

use std::f64::consts::PI;

use avsep::geometry::{Layout, MicArray, Vec3, angle_diff, azimuth_of};
use avsep::label::Label;
use avsep::track::{
    FilterKind, Measurement, Scan, SensorKey, SensorModel, StepInput, TrackEstimate, Tracker,
    TrackerConfig, build_tracker, sensors_from_layout,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Poisson};

use crate::room::{DT, RoomSim, camera_sensor, nearest, room};

/// Talk spurts (s) of the two `uca8` speakers; the gaps are the pauses, at most 2 s.
const UCA8_TALKS: [&[(f64, f64)]; 2] = [
    &[(0.0, 3.0), (5.0, 8.0), (10.0, 12.0)],
    &[(1.0, 4.5), (6.5, 9.0), (11.0, 12.0)],
];

/// A tracker on a compact 8-microphone circular array (5 cm radius) at `centre` in the room,
/// with the index of the array's direction sensor.
fn uca8_tracker(centre: Vec3, cfg: &TrackerConfig) -> (Box<dyn Tracker>, usize) {
    let mics: Vec<Vec3> = (0..8)
        .map(|i| {
            let a = 2.0 * PI * i as f64 / 8.0;
            centre + Vec3::new(0.05 * a.cos(), 0.05 * a.sin(), 0.0)
        })
        .collect();
    let array = MicArray::new("uca8", mics, (0..8).collect()).unwrap();
    let layout = Layout::new(16000, 343.0, vec![array], vec![], Some(room())).unwrap();
    let keyed = sensors_from_layout(&layout, cfg);
    let dir = keyed
        .iter()
        .position(|(k, _)| *k == SensorKey::ArrayDirections(0))
        .unwrap();
    let sensors = keyed.into_iter().map(|(_, m)| m).collect();
    (build_tracker(cfg, sensors, layout.region, 21).unwrap(), dir)
}

/// Azimuths as the array at `centre` reports them: the talking speakers' with 2 degrees of
/// noise (P_D 0.8), and Poisson(0.5) uniform clutter.
struct AzimuthSim {
    rng: ChaCha8Rng,
    noise: Normal<f64>,
    clutter: Poisson<f64>,
}

impl AzimuthSim {
    fn new(seed: u64) -> Self {
        Self {
            rng: ChaCha8Rng::seed_from_u64(seed),
            noise: Normal::new(0.0, 2f64.to_radians()).unwrap(),
            clutter: Poisson::new(0.5).unwrap(),
        }
    }

    fn measurements(
        &mut self,
        centre: Vec3,
        sources: &[Vec3],
        talking: &[bool],
    ) -> Vec<Measurement> {
        let rng = &mut self.rng;
        let mut z = Vec::new();
        for (i, s) in sources.iter().enumerate() {
            if talking[i] && rng.random::<f64>() < 0.8 {
                z.push(Measurement::Direction {
                    azimuth: azimuth_of(&(s - centre)) + self.noise.sample(rng),
                    elevation: None,
                });
            }
        }
        let n: f64 = self.clutter.sample(rng);
        for _ in 0..n as usize {
            z.push(Measurement::Direction {
                azimuth: rng.random_range(-PI..PI),
                elevation: None,
            });
        }
        z
    }
}

/// The estimate closest in azimuth (seen from `centre`) to `truth`, and its azimuth error (rad).
fn closest_in_azimuth(
    out: &[TrackEstimate],
    centre: Vec3,
    truth: f64,
) -> Option<(&TrackEstimate, f64)> {
    let err = |e: &TrackEstimate| angle_diff(azimuth_of(&(e.position - centre)), truth).abs();
    out.iter()
        .min_by(|a, b| err(a).total_cmp(&err(b)))
        .map(|e| (e, err(e)))
}

/// The `uca8` situation: one compact circular array, azimuths only, two speakers who take turns
/// with pauses of up to 2 s (the array's voice activity is on while either speaks).
#[test]
fn azimuth_only_tracks_two_speakers_through_their_pauses() {
    let centre = Vec3::new(3.0, 2.5, 0.8);
    let (mut tracker, dir) = uca8_tracker(centre, &TrackerConfig::default());
    let sources = [Vec3::new(1.2, 4.2, 1.6), Vec3::new(5.0, 1.0, 1.5)];
    let talks = UCA8_TALKS;
    let mut sim = AzimuthSim::new(22);
    let mut labels: [Option<Label>; 2] = [None, None];
    let mut errors = [Vec::new(), Vec::new()];
    for k in 0..94u64 {
        let t = k as f64 * DT;
        let talking: Vec<bool> = talks
            .iter()
            .map(|spans| spans.iter().any(|&(a, b)| t >= a && t < b))
            .collect();
        let z = sim.measurements(centre, &sources, &talking);
        let activity = if talking.iter().any(|&b| b) {
            0.9
        } else {
            0.05
        };
        let out = tracker.step(&StepInput {
            k,
            t,
            scans: vec![Scan {
                sensor: dir,
                measurements: z,
                activity: Some(activity),
                sounding: Vec::new(),
            }],
        });
        for (i, s) in sources.iter().enumerate() {
            // Scored from 1 s after the speaker first spoke.
            if t < talks[i][0].0 + 1.0 {
                continue;
            }
            let (e, err) = closest_in_azimuth(&out, centre, azimuth_of(&(s - centre)))
                .unwrap_or_else(|| panic!("t = {t:.2}: no track for speaker {i}"));
            errors[i].push(err.to_degrees());
            match labels[i] {
                None => labels[i] = Some(e.label),
                Some(l) => assert_eq!(e.label, l, "t = {t:.2}: speaker {i} changed label"),
            }
        }
    }
    assert_ne!(labels[0], labels[1]);
    for (i, e) in errors.iter().enumerate() {
        let mean = e.iter().sum::<f64>() / e.len() as f64;
        let max = e.iter().cloned().fold(0.0, f64::max);
        println!("speaker {i}: mean azimuth error {mean:.2} deg, max {max:.2} deg");
        assert!(mean <= 3.0, "speaker {i}: mean azimuth error {mean} deg");
    }
}

/// A linear array (cone angles) on a side wall and the camera: positions from the
/// intersection of cones and rays, two speakers who pause, labels kept.
#[test]
fn cone_angles_and_camera_rays_localise_two_speakers() {
    let axis_origin = Vec3::new(0.1, 2.5, 1.2);
    let sensors = vec![
        camera_sensor(),
        SensorModel::AudioDirection {
            origin: axis_origin,
            noise_std_rad: 3f64.to_radians(),
            uses_elevation: false,
            cone_axis: Some(Vec3::y()),
            p_detect: 0.6,
            min_p_detect: 0.02,
            clutter_rate: 2.0,
            filter: FilterKind::Ekf,
        },
    ];
    let mut tracker = build_tracker(&TrackerConfig::default(), sensors, Some(room()), 31).unwrap();
    let sources = [Vec3::new(2.0, 3.2, 1.6), Vec3::new(4.2, 2.0, 1.5)];
    let mut sim = RoomSim::new(32);
    let noise = Normal::new(0.0, 2f64.to_radians()).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(33);
    let mut labels: [Option<Label>; 2] = [None, None];
    let mut err = Vec::new();
    for k in 0..80u64 {
        let t = k as f64 * DT;
        // Speaker 0 pauses from 4 to 6 s, speaker 1 from 6.5 to 8.5 s.
        let talking = [!(4.0..6.0).contains(&t), !(6.5..8.5).contains(&t)];
        let mut cones = Vec::new();
        for (i, s) in sources.iter().enumerate() {
            if talking[i] && rng.random::<f64>() < 0.7 {
                // A cone-angle reading delivered as a direction in the plane z = const.
                let d = (s - axis_origin).normalize();
                let theta = d.y.clamp(-1.0, 1.0).acos() + noise.sample(&mut rng);
                cones.push(Measurement::Direction {
                    azimuth: PI / 2.0 - theta,
                    elevation: None,
                });
            }
        }
        let out = tracker.step(&StepInput {
            k,
            t,
            scans: vec![
                sim.camera_scan(&sources, 0.9),
                Scan {
                    sensor: 1,
                    measurements: cones,
                    activity: Some(1.0),
                    sounding: Vec::new(),
                },
            ],
        });
        if t < 1.0 {
            continue;
        }
        assert_eq!(out.len(), 2, "t = {t:.2}: {out:?}");
        for (i, s) in sources.iter().enumerate() {
            let e = nearest(&out, s).unwrap();
            err.push((e.position - s).norm());
            match labels[i] {
                None => labels[i] = Some(e.label),
                Some(l) => assert_eq!(e.label, l, "t = {t:.2}: speaker {i} changed label"),
            }
        }
    }
    let mean = err.iter().sum::<f64>() / err.len() as f64;
    println!("camera + cone: mean position error {mean:.3} m");
    assert!(mean < 0.15, "mean error {mean}");
}
