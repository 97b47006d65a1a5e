//! The simulator's configuration: a complete, concrete description of one scene (room, sensors,
//! talkers, noise). Presets build one of these from a seed; a JSON or TOML file can give one
//! directly. Units: metres, seconds, hertz; angles in degrees (they are configuration edges).

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A complete scene description for [`super::simulate`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct SimConfig {
    /// Length of the scene (s).
    pub duration_s: f64,
    /// Audio sample rate (Hz).
    pub sample_rate: u32,
    /// Speed of sound (m/s).
    pub speed_of_sound: f64,
    /// The room and how its responses are computed.
    pub room: RoomConfig,
    /// Microphone arrays. Channels are numbered through the arrays in this order; the first
    /// array's first microphone is the reference microphone of the truth signals.
    pub arrays: Vec<ArrayConfig>,
    /// Cameras (may be empty).
    pub cameras: Vec<CameraConfig>,
    /// The simulated face detector that turns the talkers into camera detections.
    pub detector: DetectorConfig,
    /// The talkers, in truth order (ids default to s1, s2, ...).
    pub speakers: Vec<SpeakerConfig>,
    /// Sensor noise and an optional point noise source.
    pub noise: NoiseConfig,
    /// Region written to the scene as where sources can be; default: the room shrunk by 0.2 m
    /// on every wall (as close as talkers may come), between heights 0.9 and 2.0 m.
    pub region: Option<RegionConfig>,
    /// Folder of WAV files used as the talkers' speech instead of synthetic voices (files in name
    /// order, one per talker; resampled and mixed to mono as needed).
    pub speech_dir: Option<String>,
    /// Peak magnitude of the mixture: every signal (mixture, truth, noise) is scaled by one
    /// common factor so that the largest mixture sample has this magnitude.
    pub peak_level: f64,
}

impl Default for SimConfig {
    /// The `single` preset with seed 1: one talker at a table in a quiet meeting room.
    fn default() -> Self {
        super::presets::single(&super::PresetOptions::default(), 1)
    }
}

/// The shoebox room.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct RoomConfig {
    /// Inner size [x, y, z] (m). One corner is the world origin, z points up.
    pub size_m: [f64; 3],
    /// Target reverberation time T30 (s). The wall absorption starts from Sabine's formula and
    /// is tuned so that the T30 of the simulated responses equals this value.
    pub rt60_s: f64,
    /// Interval (s) between room-response updates along a moving source's path (at most 0.1).
    pub update_interval_s: f64,
    /// Images arriving within this time (s) form the early response, recomputed at every update.
    pub early_s: f64,
    /// The late reverberation (images after `early_s`), which is diffuse and changes little with
    /// small movements, is recomputed once the source has moved this far (m) from where it was
    /// last computed.
    pub late_update_m: f64,
    /// Cut-off (Hz) of the second-order high-pass applied to every response (removes the
    /// low-frequency excess of image-source responses); 0 disables it.
    pub highpass_hz: f64,
    /// Response length (s); default: where the energy decay reaches -60 dB.
    pub response_s: Option<f64>,
}

impl Default for RoomConfig {
    fn default() -> Self {
        Self {
            size_m: [6.0, 5.0, 3.0],
            rt60_s: 0.3,
            update_interval_s: 0.05,
            early_s: 0.08,
            late_update_m: 0.25,
            highpass_hz: 60.0,
            response_s: None,
        }
    }
}

/// One microphone array.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct ArrayConfig {
    /// Identifier, unique among the arrays.
    pub id: String,
    /// Where its microphones are.
    pub geometry: ArrayGeometry,
}

impl Default for ArrayConfig {
    fn default() -> Self {
        Self {
            id: "a0".into(),
            geometry: ArrayGeometry::Circular {
                centre: [3.0, 2.5, 0.8],
                count: 8,
                radius_m: 0.05,
                start_azimuth_deg: 0.0,
            },
        }
    }
}

/// Microphone positions of an array.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, rename_all = "snake_case")]
pub enum ArrayGeometry {
    /// Equally spaced microphones on a line.
    Linear {
        /// Centre of the array (m).
        centre: [f64; 3],
        /// Number of microphones.
        count: usize,
        /// Distance between neighbours (m).
        spacing_m: f64,
        /// Direction of the line (normalised); microphone 0 is at the negative end.
        axis: [f64; 3],
    },
    /// A uniform circular array in a horizontal plane.
    Circular {
        /// Centre of the circle (m).
        centre: [f64; 3],
        /// Number of microphones.
        count: usize,
        /// Radius (m).
        radius_m: f64,
        /// Azimuth of microphone 0 (deg, from +x towards +y); the others follow counter-clockwise.
        start_azimuth_deg: f64,
    },
    /// Microphones at explicit positions (m).
    Custom {
        /// The positions.
        mics: Vec<[f64; 3]>,
    },
}

/// One camera with its simulated frame rate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct CameraConfig {
    /// Identifier, unique among the cameras.
    pub id: String,
    /// Image width (px).
    pub width: u32,
    /// Image height (px).
    pub height: u32,
    /// Frames per second (one detection line per frame).
    pub fps: f64,
    /// Time of the first frame (s).
    pub start_s: f64,
    /// The 3x4 projection matrix (world metres to pixels), given instead of position/look_at.
    pub projection: Option<[[f64; 4]; 3]>,
    /// Camera centre (m), used with `look_at` and `hfov_deg` when no projection is given.
    pub position: Option<[f64; 3]>,
    /// Point the optical axis goes through (m).
    pub look_at: Option<[f64; 3]>,
    /// Horizontal field of view (deg) of the distortion-free pinhole built from position/look_at.
    pub hfov_deg: f64,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self {
            id: "cam0".into(),
            width: 1280,
            height: 720,
            fps: 15.0,
            start_s: 0.0,
            projection: None,
            position: Some([3.0, 0.12, 2.2]),
            look_at: Some([3.0, 2.6, 1.2]),
            hfov_deg: 80.0,
        }
    }
}

/// The simulated face detector.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct DetectorConfig {
    /// Probability that a visible face is detected in a frame.
    pub detection_probability: f64,
    /// Mean number of false detections per frame (Poisson), uniform over the image.
    pub clutter_per_frame: f64,
    /// Standard deviation (px) of the detected mouth point for a 1080-row image; scaled by
    /// height / 1080 for other resolutions.
    pub point_sigma_px: f64,
    /// A face is detectable while the angle between where it faces and the direction to the
    /// camera (in the horizontal plane) is at most this (deg).
    pub max_yaw_deg: f64,
    /// Face width (m).
    pub face_width_m: f64,
    /// Face height (m).
    pub face_height_m: f64,
    /// Height of the face centre above the mouth (m).
    pub face_above_mouth_m: f64,
}

impl Default for DetectorConfig {
    fn default() -> Self {
        Self {
            detection_probability: 0.9,
            clutter_per_frame: 0.5,
            point_sigma_px: 4.0,
            max_yaw_deg: 75.0,
            face_width_m: 0.16,
            face_height_m: 0.22,
            face_above_mouth_m: 0.06,
        }
    }
}

/// One talker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct SpeakerConfig {
    /// Identifier in the truth (default s1, s2, ... by position in the list).
    pub id: Option<String>,
    /// Time the talker enters the scene (s).
    pub enter_s: f64,
    /// Time the talker leaves the scene (s); default: stays to the end.
    pub exit_s: Option<f64>,
    /// Mouth height (m): about 1.1-1.3 seated, 1.5-1.75 standing.
    pub mouth_height_m: f64,
    /// Keyframes [t, x, y] (s, m, m) of the mouth's path, interpolated smoothly (cubic Hermite,
    /// at rest at the first and last keyframe); the talker stays put before the first and after
    /// the last. At least one keyframe.
    pub path: Vec<[f64; 3]>,
    /// Standard deviation (m) of a slow random sway added to the path (posture shifts).
    pub sway_m: f64,
    /// Where the talker faces.
    pub facing: FacingConfig,
    /// The synthetic voice.
    pub voice: VoiceConfig,
    /// When the talker speaks.
    pub speech: SpeechConfig,
}

impl Default for SpeakerConfig {
    fn default() -> Self {
        Self {
            id: None,
            enter_s: 0.0,
            exit_s: None,
            mouth_height_m: 1.6,
            path: vec![[0.0, 3.0, 3.8]],
            sway_m: 0.02,
            facing: FacingConfig::default(),
            voice: VoiceConfig::default(),
            speech: SpeechConfig::default(),
        }
    }
}

/// Where a talker faces (the horizontal direction of the face).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct FacingConfig {
    /// Point [x, y] (m) the talker looks at when not walking; default: the first camera, or the
    /// first array when there is no camera.
    pub look_at: Option<[f64; 2]>,
    /// Face the walking direction while moving faster than 0.2 m/s.
    pub follow_motion: bool,
    /// Intervals [start, end] (s) during which the talker is turned away (by about 180 deg;
    /// each turn takes about 0.5 s).
    pub away_s: Vec<[f64; 2]>,
    /// Standard deviation (deg) of slow random head turns.
    pub jitter_deg: f64,
}

impl Default for FacingConfig {
    fn default() -> Self {
        Self {
            look_at: None,
            follow_motion: true,
            away_s: Vec::new(),
            jitter_deg: 12.0,
        }
    }
}

/// The synthetic voice: a glottal source with wandering pitch through moving formants.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct VoiceConfig {
    /// Median fundamental frequency (Hz): about 85-155 for male and 165-255 for female voices.
    pub f0_hz: f64,
    /// Range of the intonation (semitones): declination plus accents over a phrase.
    pub f0_range_st: f64,
    /// Scale of the formant frequencies (vocal-tract length): 1.0 adult male, 1.15-1.2 female.
    pub formant_scale: f64,
    /// Speaking rate (syllables per second, typically 3-6).
    pub syllable_rate_hz: f64,
    /// Loudness (dB) relative to the nominal speech level.
    pub level_db: f64,
    /// Aspiration noise mixed into voiced sounds (0-1).
    pub breathiness: f64,
    /// Fraction of each glottal period during which the glottis is open (0.3-0.9).
    pub open_quotient: f64,
}

impl Default for VoiceConfig {
    fn default() -> Self {
        Self {
            f0_hz: 120.0,
            f0_range_st: 5.0,
            formant_scale: 1.0,
            syllable_rate_hz: 4.5,
            level_db: 0.0,
            breathiness: 0.1,
            open_quotient: 0.6,
        }
    }
}

/// When a talker speaks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct SpeechConfig {
    /// Phrases [start, end] (s) while the talker is present. When empty, phrases are drawn from
    /// `phrase_s` and `pause_s`, starting `lead_s` after the talker enters.
    pub phrases: Vec<[f64; 2]>,
    /// Range [min, max] of drawn phrase lengths (s).
    pub phrase_s: [f64; 2],
    /// Range [min, max] of drawn pauses between phrases (s).
    pub pause_s: [f64; 2],
    /// Silence after entering before the first drawn phrase (s).
    pub lead_s: f64,
}

impl Default for SpeechConfig {
    fn default() -> Self {
        Self {
            phrases: Vec::new(),
            phrase_s: [1.0, 4.0],
            pause_s: [0.2, 2.0],
            lead_s: 0.3,
        }
    }
}

/// Noise added to the microphones.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct NoiseConfig {
    /// Sensor-noise SNR (dB): the mean power of the speech mixture at the reference microphone
    /// over the samples where any talker is active, over the mean power of the (white,
    /// independent) noise of each microphone.
    pub snr_db: f64,
    /// A noise source in the room (e.g. a fan), convolved with its room response; none when
    /// absent.
    pub point: Option<PointNoiseConfig>,
}

impl Default for NoiseConfig {
    fn default() -> Self {
        Self {
            snr_db: 25.0,
            point: None,
        }
    }
}

/// A stationary noise source in the room, like a fan or a projector.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct PointNoiseConfig {
    /// Position (m).
    pub position: [f64; 3],
    /// Its level as an SNR (dB): the same speech power as `noise.snr_db` over the mean power of
    /// this source's image at the reference microphone.
    pub snr_db: f64,
    /// Blade-pass hum fundamental (Hz), with decaying harmonics; 0 for none.
    pub hum_hz: f64,
    /// Corner (Hz) of the low-pass that colours the broadband part.
    pub corner_hz: f64,
}

impl Default for PointNoiseConfig {
    fn default() -> Self {
        Self {
            position: [0.4, 0.4, 2.5],
            snr_db: 20.0,
            hum_hz: 110.0,
            corner_hz: 400.0,
        }
    }
}

/// An axis-aligned box (m).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RegionConfig {
    /// Lower corner.
    pub min: [f64; 3],
    /// Upper corner.
    pub max: [f64; 3],
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn configurations_round_trip_through_json_and_toml() {
        let cfg =
            SimConfig::preset("two-arrays", &super::super::PresetOptions::default(), 3).unwrap();
        let json = serde_json::to_string(&cfg).unwrap();
        assert_eq!(serde_json::from_str::<SimConfig>(&json).unwrap(), cfg);
        let toml_text = toml::to_string(&cfg).unwrap();
        assert_eq!(toml::from_str::<SimConfig>(&toml_text).unwrap(), cfg);
        // Missing fields take their defaults; unknown ones are errors that name them.
        let partial: SimConfig = serde_json::from_str(r#"{"duration_s": 3.0}"#).unwrap();
        assert_eq!(partial.room, SimConfig::default().room);
        let e = serde_json::from_str::<SimConfig>(r#"{"room": {"rt6": 0.3}}"#).unwrap_err();
        assert!(e.to_string().contains("rt6"), "{e}");
    }

    #[test]
    fn the_schema_documents_every_field() {
        let schema = serde_json::to_value(schemars::schema_for!(SimConfig)).unwrap();
        let text = schema.to_string();
        for needle in [
            "rt60_s",
            "Target reverberation time",
            "clutter_per_frame",
            "snr_db",
        ] {
            assert!(text.contains(needle), "{needle} missing from the schema");
        }
    }
}
