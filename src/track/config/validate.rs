//! Checks of a tracker configuration: every field against its range, the error naming the
//! first offending one by its dotted path.

use super::TrackerConfig;
use crate::geometry::MAX_COORDINATE_M;

pub use crate::field_error::FieldError as ConfigError;

/// Most Gibbs samples a GLMB step may request (ten times the default).
pub const MAX_REQUESTED_HYPOTHESES: usize = 10_000;
/// Most hypotheses a GLMB step may keep.
pub const MAX_KEPT_HYPOTHESES: usize = 10_000;
/// Most Gaussian components a GM-PHD may keep (ten times the default).
pub const MAX_COMPONENTS: usize = 1_000;
/// Most fixed birth points: each is offered every step.
pub const MAX_FIXED_BIRTHS: usize = 64;

fn positive(v: f64, field: &str) -> Result<(), ConfigError> {
    ConfigError::check(v.is_finite() && v > 0.0, field, "must be a positive number")
}

fn probability_open(v: f64, field: &str) -> Result<(), ConfigError> {
    ConfigError::check(
        v.is_finite() && v > 0.0 && v < 1.0,
        field,
        "must be a probability strictly between 0 and 1",
    )
}

fn probability(v: f64, field: &str) -> Result<(), ConfigError> {
    ConfigError::check(
        v.is_finite() && (0.0..=1.0).contains(&v),
        field,
        "must be a probability in [0, 1]",
    )
}

/// Detection probabilities must stay below 1 so that a miss keeps a finite log weight.
fn detect_probability(v: f64, field: &str) -> Result<(), ConfigError> {
    ConfigError::check(
        v.is_finite() && (0.0..1.0).contains(&v),
        field,
        "must be in [0, 1) (a miss must remain possible)",
    )
}

fn non_negative(v: f64, field: &str) -> Result<(), ConfigError> {
    ConfigError::check(
        v.is_finite() && v >= 0.0,
        field,
        "must be a non-negative number",
    )
}

impl TrackerConfig {
    /// Checks every field; the error names the first offending one.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.validate_motion()?;
        probability_open(self.survival_probability, "survival_probability")?;
        self.validate_sensors()?;
        self.validate_filters()?;
        self.validate_birth()?;
        self.validate_modes()?;
        self.validate_gmphd()
    }

    /// The motion model.
    fn validate_motion(&self) -> Result<(), ConfigError> {
        let m = &self.motion;
        positive(m.beta_per_s, "motion.beta_per_s")?;
        positive(m.nu_m_per_s, "motion.nu_m_per_s")?;
        positive(m.walking_beta_per_s, "motion.walking_beta_per_s")?;
        for (i, s) in m.walking_sigma_m_per_s.iter().enumerate() {
            non_negative(*s, &format!("motion.walking_sigma_m_per_s[{i}]"))?;
        }
        non_negative(m.gait_camera_memory_s, "motion.gait_camera_memory_s")?;
        positive(m.mean_walk_s, "motion.mean_walk_s")?;
        positive(m.mean_stand_s, "motion.mean_stand_s")?;
        for (i, s) in m.sigma_m_per_s.iter().enumerate() {
            non_negative(*s, &format!("motion.sigma_m_per_s[{i}]"))?;
        }
        for (i, s) in m.accel_std_m_per_s2.iter().enumerate() {
            non_negative(*s, &format!("motion.accel_std_m_per_s2[{i}]"))?;
        }
        Ok(())
    }

    /// The audio and camera sensor models.
    fn validate_sensors(&self) -> Result<(), ConfigError> {
        let a = &self.audio_position;
        positive(a.noise_std_m, "audio_position.noise_std_m")?;
        detect_probability(a.p_detect, "audio_position.p_detect")?;
        detect_probability(a.min_p_detect, "audio_position.min_p_detect")?;
        positive(a.clutter_rate, "audio_position.clutter_rate")?;
        positive(a.clutter_volume_m3, "audio_position.clutter_volume_m3")?;
        let d = &self.audio_direction;
        positive(d.noise_std_deg, "audio_direction.noise_std_deg")?;
        detect_probability(d.p_detect, "audio_direction.p_detect")?;
        detect_probability(d.min_p_detect, "audio_direction.min_p_detect")?;
        positive(d.clutter_rate, "audio_direction.clutter_rate")?;
        let c = &self.camera;
        positive(c.noise_std_px, "camera.noise_std_px")?;
        positive(c.reference_height_px, "camera.reference_height_px")?;
        detect_probability(c.p_detect, "camera.p_detect")?;
        positive(c.clutter_rate, "camera.clutter_rate")?;
        probability(c.occluded_factor, "camera.occluded_factor")?;
        positive(c.face_size_m[0], "camera.face_size_m[0]")?;
        positive(c.face_size_m[1], "camera.face_size_m[1]")?;
        positive(c.face_size_log_std, "camera.face_size_log_std")?;
        for (i, s) in c.occluder_half_size_m.iter().enumerate() {
            positive(*s, &format!("camera.occluder_half_size_m[{i}]"))?;
        }
        Ok(())
    }

    /// The filters and the GLMB's hypothesis management.
    fn validate_filters(&self) -> Result<(), ConfigError> {
        positive(self.ukf.alpha, "ukf.alpha")?;
        non_negative(self.ukf.beta, "ukf.beta")?;
        non_negative(self.ukf.kappa, "ukf.kappa")?;
        ConfigError::check(
            self.gate_probability.is_finite()
                && self.gate_probability > 0.5
                && self.gate_probability <= 1.0,
            "gate_probability",
            "must be in (0.5, 1]",
        )?;
        let g = &self.glmb;
        // The step's work and memory grow with these; a session's settings cannot ask for more.
        ConfigError::check(
            (1..=MAX_REQUESTED_HYPOTHESES).contains(&g.requested_hypotheses),
            "glmb.requested_hypotheses",
            &format!("must be between 1 and {MAX_REQUESTED_HYPOTHESES}"),
        )?;
        ConfigError::check(
            (1..=MAX_KEPT_HYPOTHESES).contains(&g.max_hypotheses),
            "glmb.max_hypotheses",
            &format!("must be between 1 and {MAX_KEPT_HYPOTHESES}"),
        )?;
        ConfigError::check(
            (1..=g.requested_hypotheses).contains(&g.min_parent_samples),
            "glmb.min_parent_samples",
            "must be between 1 and requested_hypotheses",
        )?;
        probability_open(g.prune_threshold, "glmb.prune_threshold")?;
        Ok(())
    }

    /// The GM-PHD's pruning, merging and label association.
    fn validate_gmphd(&self) -> Result<(), ConfigError> {
        let p = &self.gmphd;
        probability_open(p.prune_threshold, "gmphd.prune_threshold")?;
        positive(p.merge_threshold, "gmphd.merge_threshold")?;
        ConfigError::check(
            (1..=MAX_COMPONENTS).contains(&p.max_components),
            "gmphd.max_components",
            &format!("must be between 1 and {MAX_COMPONENTS}"),
        )?;
        positive(p.extraction_threshold, "gmphd.extraction_threshold")?;
        positive(p.label_gate_m, "gmphd.label_gate_m")?;
        Ok(())
    }

    /// The talking and facing modes, the estimator and the speaking smoothing.
    fn validate_modes(&self) -> Result<(), ConfigError> {
        let v = &self.voice;
        positive(v.mean_talk_s, "voice.mean_talk_s")?;
        positive(v.mean_pause_s, "voice.mean_pause_s")?;
        probability(v.initial_talking, "voice.initial_talking")?;
        let f = &self.face;
        positive(f.mean_towards_s, "face.mean_towards_s")?;
        positive(f.mean_away_s, "face.mean_away_s")?;
        detect_probability(f.away_p_detect, "face.away_p_detect")?;
        ConfigError::check(
            f.away_p_detect <= self.camera.p_detect,
            "face.away_p_detect",
            "must not exceed camera.p_detect",
        )?;
        probability(f.initial_towards, "face.initial_towards")?;
        positive(self.clutter.time_constant_s, "clutter.time_constant_s")?;
        let e = &self.estimator;
        probability(e.hysteresis_existence, "estimator.hysteresis_existence")?;
        ConfigError::check(
            self.speaking_smoothing.is_finite()
                && self.speaking_smoothing > 0.0
                && self.speaking_smoothing <= 1.0,
            "speaking_smoothing",
            "must be in (0, 1]",
        )?;
        Ok(())
    }

    fn validate_birth(&self) -> Result<(), ConfigError> {
        let b = &self.birth;
        ConfigError::check(
            b.fixed.len() <= MAX_FIXED_BIRTHS,
            "birth.fixed",
            &format!("at most {MAX_FIXED_BIRTHS} fixed births"),
        )?;
        for (i, f) in b.fixed.iter().enumerate() {
            for (j, v) in f.position.iter().enumerate() {
                ConfigError::check(
                    v.is_finite() && v.abs() <= MAX_COORDINATE_M,
                    &format!("birth.fixed[{i}].position[{j}]"),
                    &format!("must be a finite number of metres within {MAX_COORDINATE_M}"),
                )?;
            }
            probability_open(f.existence, &format!("birth.fixed[{i}].existence"))?;
            positive(
                f.position_std_m,
                &format!("birth.fixed[{i}].position_std_m"),
            )?;
            positive(
                f.velocity_std_m_per_s,
                &format!("birth.fixed[{i}].velocity_std_m_per_s"),
            )?;
        }
        positive(b.expected_births, "birth.expected_births")?;
        probability_open(b.max_existence, "birth.max_existence")?;
        probability(b.max_association, "birth.max_association")?;
        ConfigError::check(
            b.max_per_step <= 64,
            "birth.max_per_step",
            "must be at most 64",
        )?;
        positive(b.position_std_m, "birth.position_std_m")?;
        positive(b.velocity_std_m_per_s, "birth.velocity_std_m_per_s")?;
        let [d0, d1] = b.camera_depth_range_m;
        ConfigError::check(
            d0.is_finite() && d1.is_finite() && d0 > 0.0 && d1 > d0,
            "birth.camera_depth_range_m",
            "must be [near, far] with 0 < near < far",
        )?;
        positive(b.direction_range_m, "birth.direction_range_m")?;
        ConfigError::check(
            b.default_height_m.is_finite(),
            "birth.default_height_m",
            "must be finite",
        )?;
        probability_open(
            b.suppress_gate_probability,
            "birth.suppress_gate_probability",
        )?;
        probability(b.suppress_existence, "birth.suppress_existence")?;
        positive(b.suppress_max_spread, "birth.suppress_max_spread")?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track::config::{FixedBirth, TrackerConfig, TrackerKind};

    #[test]
    fn defaults_are_valid_and_round_trip() {
        let c = TrackerConfig::default();
        c.validate().unwrap();
        let s = serde_json::to_string(&c).unwrap();
        let back: TrackerConfig = serde_json::from_str(&s).unwrap();
        assert_eq!(back, c);
    }

    #[test]
    fn unknown_fields_and_bad_values_name_the_field() {
        let e = serde_json::from_str::<TrackerConfig>(r#"{"camera": {"p_detekt": 0.5}}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("p_detekt"), "{e}");
        let mut c = TrackerConfig::default();
        c.camera.p_detect = 1.0;
        assert_eq!(c.validate().unwrap_err().field, "camera.p_detect");
        let mut c = TrackerConfig::default();
        c.birth.camera_depth_range_m = [2.0, 1.0];
        assert_eq!(
            c.validate().unwrap_err().field,
            "birth.camera_depth_range_m"
        );
        let c: TrackerConfig = serde_json::from_str(r#"{"tracker": "gmphd"}"#).unwrap();
        assert_eq!(c.tracker, TrackerKind::Gmphd);
    }

    fn birth(position: [f64; 3]) -> FixedBirth {
        FixedBirth {
            position,
            existence: 0.005,
            position_std_m: 0.2,
            velocity_std_m_per_s: 0.2,
        }
    }

    #[test]
    fn sizes_a_session_could_not_afford_are_named() {
        let field = |edit: fn(&mut TrackerConfig)| {
            let mut c = TrackerConfig::default();
            edit(&mut c);
            c.validate().unwrap_err().field
        };
        // More samples per parent than the step requests would spin the Gibbs chain for ever.
        assert_eq!(
            field(|c| c.glmb.min_parent_samples = 1_000_000_000_000_000),
            "glmb.min_parent_samples"
        );
        assert_eq!(
            field(|c| c.glmb.requested_hypotheses = MAX_REQUESTED_HYPOTHESES + 1),
            "glmb.requested_hypotheses"
        );
        assert_eq!(
            field(|c| c.glmb.max_hypotheses = MAX_KEPT_HYPOTHESES + 1),
            "glmb.max_hypotheses"
        );
        assert_eq!(
            field(|c| c.gmphd.max_components = MAX_COMPONENTS + 1),
            "gmphd.max_components"
        );
        assert_eq!(
            field(|c| c.birth.fixed = vec![birth([1.0, 1.0, 1.5]); MAX_FIXED_BIRTHS + 1]),
            "birth.fixed"
        );
        assert_eq!(
            field(|c| c.birth.fixed = vec![birth([1e200, 0.0, 1.0])]),
            "birth.fixed[0].position[0]"
        );
    }
}
