//! Robustness: malformed measurements and time, recalibration of the sensors and reset.

use avsep::geometry::{Pixel, Vec3};
use avsep::track::{Measurement, Scan, SensorModel, StepInput, TrackerConfig, TrackerKind};

use crate::room::{DIR_A, DT, RoomSim, room_sensors, room_tracker};

#[test]
fn bad_input_is_dropped_and_counted_and_never_yields_nan() {
    for kind in [TrackerKind::Glmb, TrackerKind::Gmphd] {
        let cfg = TrackerConfig {
            tracker: kind,
            ..TrackerConfig::default()
        };
        let mut tracker = room_tracker(&cfg, 11);
        let mut sim = RoomSim::new(12);
        let source = Vec3::new(3.0, 2.0, 1.5);
        let behind = Vec3::new(3.0, -1.0, 1.5);
        for k in 0..40u64 {
            let mut scans = vec![
                sim.camera_scan(&[source], 0.9),
                sim.position_scan(&[source, behind], 1.0, 5),
            ];
            scans[0]
                .measurements
                .push(Measurement::Pixel(Pixel::new(f64::NAN, 3.0)));
            scans[1]
                .measurements
                .push(Measurement::Position(Vec3::new(1.0, f64::INFINITY, 0.0)));
            // Wrong kinds, unknown sensors, a direction from the array centre itself, huge values.
            scans[1]
                .measurements
                .push(Measurement::Pixel(Pixel::new(1.0, 1.0)));
            scans.push(Scan {
                sensor: 99,
                measurements: vec![],
                activity: None,
                sounding: Vec::new(),
            });
            scans.push(Scan {
                sensor: DIR_A,
                measurements: vec![
                    Measurement::Direction {
                        azimuth: 1e300,
                        elevation: None,
                    },
                    Measurement::Direction {
                        azimuth: f64::NAN,
                        elevation: None,
                    },
                ],
                activity: Some(f64::NAN),
                sounding: Vec::new(),
            });
            if k % 7 == 3 {
                scans[1]
                    .measurements
                    .push(Measurement::Position(Vec3::new(1e200, -1e200, 1e200)));
            }
            // Time repeats and jumps backwards now and then.
            let t = if k % 10 == 5 { 0.0 } else { k as f64 * DT };
            let out = tracker.step(&StepInput { k, t, scans });
            for e in &out {
                let finite = e
                    .position
                    .iter()
                    .chain(e.velocity.iter())
                    .all(|v| v.is_finite())
                    && e.covariance.iter().all(|v| v.is_finite())
                    && e.existence.is_finite()
                    && e.speaking.is_finite();
                assert!(finite, "{kind:?} step {k}: {e:?}");
            }
        }
        let s = tracker.stats();
        println!("{kind:?}: {s:?}");
        assert_eq!(s.non_finite_measurements, 40 * 3);
        assert_eq!(s.mismatched_measurements, 40);
        assert_eq!(s.unknown_sensor_scans, 40);
        assert!(s.non_monotonic_steps >= 4);
    }
}

#[test]
fn recalibration_keeps_tracks_and_reset_forgets_them() {
    let source = Vec3::new(2.5, 3.0, 1.6);
    let mut tracker = room_tracker(&TrackerConfig::default(), 51);
    let mut sim = RoomSim::new(52);
    let mut label = None;
    for k in 0..20u64 {
        let scans = vec![
            sim.camera_scan(&[source], 0.9),
            sim.position_scan(&[source], 1.0, 3),
        ];
        let out = tracker.step(&StepInput {
            k,
            t: k as f64 * DT,
            scans,
        });
        label = out.first().map(|e| e.label);
    }
    assert!(label.is_some());
    tracker.set_sensors(room_sensors()).unwrap();
    let scans = vec![
        sim.camera_scan(&[source], 1.0),
        sim.position_scan(&[source], 1.0, 0),
    ];
    let out = tracker.step(&StepInput {
        k: 20,
        t: 20.0 * DT,
        scans,
    });
    assert_eq!(out.first().map(|e| e.label), label);
    let bad = vec![SensorModel::AudioPosition {
        noise_std_m: -1.0,
        p_detect: 0.6,
        min_p_detect: 0.0,
        clutter_rate: 1.0,
        clutter_volume_m3: 1.0,
    }];
    let e = tracker.set_sensors(bad).unwrap_err();
    assert_eq!(e.field, "sensors[0].noise_std_m");
    tracker.reset();
    let out = tracker.step(&StepInput {
        k: 0,
        t: 0.0,
        scans: vec![],
    });
    assert!(out.is_empty());
}
