//! The seed paper's recording room (spec 003 sections 4.3, 7.1-7.2).

use rand::Rng;

use super::super::config::{
    ArrayConfig, ArrayGeometry, CameraConfig, FacingConfig, SimConfig, SpeakerConfig, SpeechConfig,
    VoiceConfig,
};
use super::super::{rng_for, streams};
use super::{PresetOptions, base, draw_phrases, draw_voices, place_apart, r3, u, walk};

/// The seed paper's recording room (spec 003 sections 4.3, 7.1-7.2).
pub(super) fn paper_linear6(opts: &PresetOptions, seed: u64) -> SimConfig {
    let mut rng = rng_for(seed, streams::PRESET, 0);
    let mut cfg = base(opts, 12.0, [7.67, 3.41, 2.7], 0.25, 25.0);
    let d = cfg.duration_s;
    let n = opts.speakers.unwrap_or(3);
    cfg.arrays = vec![ArrayConfig {
        id: "a0".into(),
        geometry: ArrayGeometry::Linear {
            centre: [3.0, 3.25, 1.95],
            count: 6,
            spacing_m: 0.04,
            axis: [1.0, 0.0, 0.0],
        },
    }];
    cfg.cameras = vec![CameraConfig {
        id: "cam0".into(),
        width: 1920,
        height: 1080,
        fps: 8.0,
        start_s: 0.0,
        projection: Some([
            [-1021.7, -827.2, -575.8, 7071.5],
            [31.8, 142.0, -1184.0, 2012.8],
            [0.04, -0.83, -0.56, 3.81],
        ]),
        position: None,
        look_at: None,
        hfov_deg: 84.0,
    }];
    cfg.detector.clutter_per_frame = 0.5;
    let away = rng.random_range(0..n);
    let voices = draw_voices(n, &mut rng);
    cfg.speakers = place_apart(d, || {
        let s = (0..n)
            .map(|i| paper_talker(i, d, i == away, voices[i].clone(), &mut rng))
            .collect();
        (s, true)
    });
    cfg
}

/// Talker `i` of the paper's scenarios: enters near the paper's entry point i at about its entry
/// time, walks towards the sensors, talks with pauses; `turns_away` near the end.
fn paper_talker<R: Rng + ?Sized>(
    i: usize,
    d: f64,
    turns_away: bool,
    voice: VoiceConfig,
    rng: &mut R,
) -> SpeakerConfig {
    const CAMERA_XY: [f64; 2] = [3.048, 3.270];
    const ENTRIES: [[f64; 2]; 4] = [[2.0, 0.7], [3.0, 0.5], [4.0, 0.6], [5.0, 0.7]];
    const ENTER_S: [f64; 4] = [0.5, 3.0, 6.0, 8.0];
    // Short scenes keep the choreography, compressed in time.
    let squeeze = (d / 12.0).min(1.0);
    let enter = r3(((ENTER_S[i] + u(rng, -0.3, 0.3)) * squeeze).max(0.0));
    let start = [
        r3(ENTRIES[i][0] + u(rng, -0.15, 0.15)),
        r3(ENTRIES[i][1] + u(rng, -0.1, 0.1)),
    ];
    // Converge a little towards the sensors so that nobody leaves the camera's field of view.
    let end = [
        start[0] + 0.3 * (CAMERA_XY[0] - start[0]) + u(rng, -0.1, 0.1),
        u(rng, 1.8, 2.2),
    ];
    let depart = r3(enter + u(rng, 0.3, 1.0) * squeeze);
    let mut path = vec![[enter, start[0], start[1]], [depart, start[0], start[1]]];
    let speed = u(rng, 0.2, 0.45);
    walk(&mut path, start, end, depart, speed, rng);
    let away_s = if turns_away {
        vec![[r3(d - u(rng, 1.5, 2.5) * squeeze), r3(d + 1.0)]]
    } else {
        Vec::new()
    };
    // The talker stops talking before turning away, as in the paper's exits.
    let quiet_from = away_s.first().map_or(d - 0.1, |a| a[0] - 0.3);
    let speech = SpeechConfig::default();
    let lead = u(rng, 0.2, 0.6) * squeeze.max(0.5);
    SpeakerConfig {
        id: None,
        enter_s: enter,
        exit_s: None,
        mouth_height_m: r3(u(rng, 1.6, 1.75)),
        path,
        sway_m: 0.02,
        facing: FacingConfig {
            look_at: Some(CAMERA_XY),
            follow_motion: true,
            away_s,
            jitter_deg: 10.0,
        },
        voice,
        speech: SpeechConfig {
            phrases: draw_phrases(enter + lead, quiet_from, &speech, rng),
            ..speech
        },
    }
}
