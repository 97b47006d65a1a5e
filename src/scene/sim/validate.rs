//! Checks of a [`SimConfig`], with errors that name the offending field.

use super::SimError;
use super::config::{ArrayGeometry, CameraConfig, SimConfig, SpeakerConfig};
use super::motion::Path;

/// Largest speed (m/s) a talker's path may reach.
pub const MAX_SPEED_MPS: f64 = 1.0;
/// Closest a talker's mouth may come to a wall (m).
pub const WALL_MARGIN_M: f64 = 0.2;

fn err(field: impl Into<String>, message: impl Into<String>) -> SimError {
    SimError::Config {
        field: field.into(),
        message: message.into(),
    }
}

fn check_range(field: &str, v: f64, lo: f64, hi: f64, unit: &str) -> Result<(), SimError> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(err(
            field,
            format!("{v}{unit} is not in [{lo}, {hi}]{unit}"),
        ))
    }
}

/// Whether `p` lies inside a room of `size` (m), at least `margin` from every wall.
pub(super) fn inside_room(p: [f64; 3], size: [f64; 3], margin: f64) -> bool {
    (0..3).all(|k| p[k] >= margin && p[k] <= size[k] - margin)
}

fn check_finite(field: &str, v: &[f64]) -> Result<(), SimError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(err(field, "must be finite numbers"))
    }
}

/// A numeric field with its allowed range and unit.
type Range<'a> = (&'a str, f64, f64, f64, &'a str);

/// Checks every `(field, value, lo, hi, unit)`; the error names the first value out of range.
fn check_ranges(prefix: &str, ranges: &[Range]) -> Result<(), SimError> {
    for &(field, v, lo, hi, unit) in ranges {
        check_range(&format!("{prefix}{field}"), v, lo, hi, unit)?;
    }
    Ok(())
}

impl SimConfig {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), SimError> {
        if !(8000..=96000).contains(&self.sample_rate) {
            return Err(err(
                "sample_rate",
                format!("{} Hz is not in [8000, 96000] Hz", self.sample_rate),
            ));
        }
        check_ranges(
            "",
            &[
                ("duration_s", self.duration_s, 0.01, 3600.0, " s"),
                ("speed_of_sound", self.speed_of_sound, 200.0, 500.0, " m/s"),
                ("peak_level", self.peak_level, 1e-6, 1.0, ""),
            ],
        )?;
        self.validate_room()?;
        self.validate_sensors()?;
        let d = &self.detector;
        check_ranges(
            "detector.",
            &[
                (
                    "detection_probability",
                    d.detection_probability,
                    0.0,
                    1.0,
                    "",
                ),
                ("clutter_per_frame", d.clutter_per_frame, 0.0, 50.0, ""),
                ("point_sigma_px", d.point_sigma_px, 0.0, 200.0, " px"),
                ("max_yaw_deg", d.max_yaw_deg, 1.0, 180.0, " deg"),
                ("face_width_m", d.face_width_m, 0.01, 1.0, " m"),
                ("face_height_m", d.face_height_m, 0.01, 1.0, " m"),
                ("face_above_mouth_m", d.face_above_mouth_m, -0.5, 0.5, " m"),
            ],
        )?;
        if self.speakers.is_empty() {
            return Err(err("speakers", "must list at least one talker"));
        }
        for (i, s) in self.speakers.iter().enumerate() {
            let f = format!("speakers[{i}]");
            if let Some(id) = &s.id
                && self.speakers[..i].iter().any(|o| o.id.as_ref() == Some(id))
            {
                return Err(err(format!("{f}.id"), format!("{id:?} is not unique")));
            }
            self.validate_presence(&f, s)?;
            self.validate_voice(&f, s)?;
            self.validate_speech(&f, s)?;
        }
        self.validate_noise()?;
        if let Some(r) = &self.region {
            check_finite("region.min", &r.min)?;
            check_finite("region.max", &r.max)?;
            if (0..3).any(|k| r.max[k] <= r.min[k]) {
                return Err(err(
                    "region.max",
                    "must be greater than region.min on every axis",
                ));
            }
        }
        if let Some(dir) = &self.speech_dir
            && dir.is_empty()
        {
            return Err(err("speech_dir", "must not be empty"));
        }
        Ok(())
    }

    fn validate_sensors(&self) -> Result<(), SimError> {
        if self.arrays.is_empty() {
            return Err(err("arrays", "must list at least one microphone array"));
        }
        for (i, a) in self.arrays.iter().enumerate() {
            let f = format!("arrays[{i}]");
            if a.id.is_empty() || self.arrays[..i].iter().any(|b| b.id == a.id) {
                return Err(err(
                    format!("{f}.id"),
                    format!("{:?} is empty or not unique", a.id),
                ));
            }
            self.validate_array(&f, &a.geometry)?;
        }
        for (i, c) in self.cameras.iter().enumerate() {
            let f = format!("cameras[{i}]");
            if c.id.is_empty() || self.cameras[..i].iter().any(|b| b.id == c.id) {
                return Err(err(
                    format!("{f}.id"),
                    format!("{:?} is empty or not unique", c.id),
                ));
            }
            self.validate_camera(&f, c)?;
        }
        Ok(())
    }

    fn validate_noise(&self) -> Result<(), SimError> {
        check_range("noise.snr_db", self.noise.snr_db, -20.0, 120.0, " dB")?;
        if let Some(p) = &self.noise.point {
            self.check_inside("noise.point.position", p.position, 0.0)?;
            let top = 0.45 * self.sample_rate as f64;
            check_ranges(
                "noise.point.",
                &[
                    ("snr_db", p.snr_db, -20.0, 120.0, " dB"),
                    ("hum_hz", p.hum_hz, 0.0, top, " Hz"),
                    ("corner_hz", p.corner_hz, 10.0, top, " Hz"),
                ],
            )?;
        }
        Ok(())
    }

    fn validate_room(&self) -> Result<(), SimError> {
        let r = &self.room;
        for (k, s) in r.size_m.iter().enumerate() {
            check_range(&format!("room.size_m[{k}]"), *s, 1.0, 100.0, " m")?;
        }
        check_ranges(
            "room.",
            &[
                ("rt60_s", r.rt60_s, 0.01, 3.0, " s"),
                ("update_interval_s", r.update_interval_s, 0.002, 0.1, " s"),
                ("early_s", r.early_s, 0.0, 1.0, " s"),
                ("late_update_m", r.late_update_m, 0.0, 100.0, " m"),
                (
                    "highpass_hz",
                    r.highpass_hz,
                    0.0,
                    0.25 * self.sample_rate as f64,
                    " Hz",
                ),
            ],
        )?;
        if let Some(s) = r.response_s {
            check_range("room.response_s", s, 0.001, 5.0, " s")?;
        }
        Ok(())
    }

    /// Whether `p` lies inside the room, at least `margin` from every wall.
    fn check_inside(&self, field: &str, p: [f64; 3], margin: f64) -> Result<(), SimError> {
        check_finite(field, &p)?;
        let s = self.room.size_m;
        if inside_room(p, s, margin) {
            Ok(())
        } else {
            Err(err(
                field,
                format!(
                    "{p:?} is not inside the {:?} m room{}",
                    s,
                    if margin > 0.0 {
                        format!(" with a {margin} m margin")
                    } else {
                        String::new()
                    }
                ),
            ))
        }
    }

    fn validate_array(&self, f: &str, g: &ArrayGeometry) -> Result<(), SimError> {
        match g {
            ArrayGeometry::Linear {
                centre,
                count,
                spacing_m,
                axis,
            } => {
                self.check_inside(&format!("{f}.geometry.linear.centre"), *centre, 0.0)?;
                if *count < 1 {
                    return Err(err(
                        format!("{f}.geometry.linear.count"),
                        "must be at least 1",
                    ));
                }
                check_range(
                    &format!("{f}.geometry.linear.spacing_m"),
                    *spacing_m,
                    1e-3,
                    10.0,
                    " m",
                )?;
                check_finite(&format!("{f}.geometry.linear.axis"), axis)?;
                if axis.iter().map(|v| v * v).sum::<f64>() < 1e-12 {
                    return Err(err(format!("{f}.geometry.linear.axis"), "must not be zero"));
                }
            }
            ArrayGeometry::Circular {
                centre,
                count,
                radius_m,
                start_azimuth_deg,
            } => {
                self.check_inside(&format!("{f}.geometry.circular.centre"), *centre, 0.0)?;
                if *count < 1 {
                    return Err(err(
                        format!("{f}.geometry.circular.count"),
                        "must be at least 1",
                    ));
                }
                check_range(
                    &format!("{f}.geometry.circular.radius_m"),
                    *radius_m,
                    1e-3,
                    10.0,
                    " m",
                )?;
                check_finite(
                    &format!("{f}.geometry.circular.start_azimuth_deg"),
                    &[*start_azimuth_deg],
                )?;
            }
            ArrayGeometry::Custom { mics } => {
                if mics.is_empty() {
                    return Err(err(
                        format!("{f}.geometry.custom.mics"),
                        "must not be empty",
                    ));
                }
            }
        }
        for (m, p) in super::layout::mic_positions(g).iter().enumerate() {
            self.check_inside(&format!("{f}.mics[{m}]"), [p.x, p.y, p.z], 0.0)?;
        }
        Ok(())
    }

    fn validate_camera(&self, f: &str, c: &CameraConfig) -> Result<(), SimError> {
        if c.width < 16 || c.height < 16 {
            return Err(err(
                format!("{f}.width"),
                "width and height must be at least 16 px",
            ));
        }
        check_range(&format!("{f}.fps"), c.fps, 0.1, 240.0, " fps")?;
        check_range(&format!("{f}.start_s"), c.start_s, 0.0, 3600.0, " s")?;
        match (&c.projection, &c.position, &c.look_at) {
            (Some(p), None, None) => {
                check_finite(&format!("{f}.projection"), &p.concat())?;
            }
            (None, Some(pos), Some(look)) => {
                self.check_inside(&format!("{f}.position"), *pos, 0.0)?;
                check_finite(&format!("{f}.look_at"), look)?;
                let d: f64 = (0..3).map(|k| (look[k] - pos[k]).powi(2)).sum();
                let horizontal: f64 = (0..2).map(|k| (look[k] - pos[k]).powi(2)).sum();
                if d < 1e-6 || horizontal < 1e-6 {
                    return Err(err(
                        format!("{f}.look_at"),
                        "must differ from the position and not lie straight above or below it",
                    ));
                }
                check_range(&format!("{f}.hfov_deg"), c.hfov_deg, 10.0, 170.0, " deg")?;
            }
            _ => {
                return Err(err(
                    f,
                    "give either projection, or position and look_at (not both)",
                ));
            }
        }
        Ok(())
    }

    /// When and where a talker is: id, entry and exit, height, path, sway, facing.
    fn validate_presence(&self, f: &str, s: &SpeakerConfig) -> Result<(), SimError> {
        if let Some(id) = &s.id
            && (id.is_empty() || id.contains(['/', '\\']))
        {
            return Err(err(
                format!("{f}.id"),
                "must be non-empty and without slashes",
            ));
        }
        if let Some(x) = s.exit_s
            && !(x.is_finite() && x > s.enter_s)
        {
            return Err(err(
                format!("{f}.exit_s"),
                format!("{x} s must be after enter_s"),
            ));
        }
        let top = (self.room.size_m[2] - WALL_MARGIN_M).min(2.3);
        check_ranges(
            &format!("{f}."),
            &[
                ("enter_s", s.enter_s, 0.0, self.duration_s - 1e-3, " s"),
                ("mouth_height_m", s.mouth_height_m, 0.3, top, " m"),
                ("sway_m", s.sway_m, 0.0, 0.3, " m"),
                ("facing.jitter_deg", s.facing.jitter_deg, 0.0, 90.0, " deg"),
            ],
        )?;
        if s.path.is_empty() {
            return Err(err(format!("{f}.path"), "needs at least one keyframe"));
        }
        for (k, key) in s.path.iter().enumerate() {
            let kf = format!("{f}.path[{k}]");
            check_finite(&kf, key)?;
            if k > 0 && key[0] <= s.path[k - 1][0] {
                return Err(err(kf, format!("time {} does not increase", key[0])));
            }
            self.check_inside(&kf, [key[1], key[2], s.mouth_height_m], WALL_MARGIN_M)?;
        }
        let (v, t) = Path::from_keyframes(&s.path).max_speed();
        if v > MAX_SPEED_MPS {
            return Err(err(
                format!("{f}.path"),
                format!("reaches {v:.2} m/s at t = {t:.2} s; the limit is {MAX_SPEED_MPS} m/s"),
            ));
        }
        if let Some(p) = s.facing.look_at {
            check_finite(&format!("{f}.facing.look_at"), &p)?;
        }
        for (k, a) in s.facing.away_s.iter().enumerate() {
            if !(a[0].is_finite() && a[1].is_finite() && a[1] > a[0]) {
                return Err(err(
                    format!("{f}.facing.away_s[{k}]"),
                    "must be [start, end] with start < end",
                ));
            }
        }
        Ok(())
    }

    fn validate_voice(&self, f: &str, s: &SpeakerConfig) -> Result<(), SimError> {
        let v = &s.voice;
        check_ranges(
            &format!("{f}.voice."),
            &[
                ("f0_hz", v.f0_hz, 50.0, 500.0, " Hz"),
                ("f0_range_st", v.f0_range_st, 0.0, 24.0, " st"),
                ("formant_scale", v.formant_scale, 0.7, 1.5, ""),
                ("syllable_rate_hz", v.syllable_rate_hz, 1.0, 10.0, " Hz"),
                ("level_db", v.level_db, -40.0, 20.0, " dB"),
                ("breathiness", v.breathiness, 0.0, 1.0, ""),
                ("open_quotient", v.open_quotient, 0.3, 0.9, ""),
            ],
        )
    }

    fn validate_speech(&self, f: &str, s: &SpeakerConfig) -> Result<(), SimError> {
        let sp = &s.speech;
        let exit = s.exit_s.unwrap_or(self.duration_s).min(self.duration_s);
        for (k, p) in sp.phrases.iter().enumerate() {
            let pf = format!("{f}.speech.phrases[{k}]");
            check_finite(&pf, p)?;
            if p[1] - p[0] < 0.05 {
                return Err(err(pf, "must be [start, end] at least 50 ms long"));
            }
            if p[0] < s.enter_s || p[1] > exit + 1e-9 {
                let presence = format!("[{}, {exit}] s", s.enter_s);
                return Err(err(
                    pf,
                    format!("{p:?} is not within the talker's presence {presence}"),
                ));
            }
            if k > 0 && p[0] < sp.phrases[k - 1][1] {
                return Err(err(pf, "overlaps or precedes the previous phrase"));
            }
        }
        for (name, r) in [("phrase_s", sp.phrase_s), ("pause_s", sp.pause_s)] {
            let ok = r[0].is_finite() && r[1].is_finite() && r[0] > 0.0 && r[1] >= r[0];
            if !(ok && r[1] <= 60.0) {
                return Err(err(
                    format!("{f}.speech.{name}"),
                    format!("{r:?} must be [min, max] with 0 < min <= max <= 60"),
                ));
            }
        }
        check_range(&format!("{f}.speech.lead_s"), sp.lead_s, 0.0, 3600.0, " s")
    }
}
