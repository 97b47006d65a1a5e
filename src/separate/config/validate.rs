//! Checks of a separator configuration: every field against its range, each section naming its
//! own fields and the separator prefixing the section's name.

use super::{
    AdaptationConfig, ConfigError, HarmonicConfig, LifecycleConfig, MvdrConfig, PostFilterConfig,
    RlsConfig, SeparatorConfig,
};

fn in_range(field: &str, v: f64, lo: f64, hi: f64) -> Result<(), ConfigError> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(ConfigError::new(
            field,
            format!("must be a number in [{lo}, {hi}], got {v}"),
        ))
    }
}

/// Checks a pair of thresholds `{prefix}_low` < `{prefix}_high`, both in [0, 1].
fn unit_interval(prefix: &str, low: f64, high: f64) -> Result<(), ConfigError> {
    in_range(&format!("{prefix}_low"), low, 0.0, 1.0)?;
    in_range(&format!("{prefix}_high"), high, 0.0, 1.0)?;
    if high <= low {
        return Err(ConfigError::new(
            format!("{prefix}_high"),
            format!("must be above {prefix}_low"),
        ));
    }
    Ok(())
}

impl SeparatorConfig {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.frame_geometry()
            .validate(true)
            .map_err(|m| ConfigError::new("frame", m))?;
        in_range("min_frequency_hz", self.min_frequency_hz, 0.0, 1e6)?;
        if let Some(f) = self.max_frequency_hz {
            in_range("max_frequency_hz", f, 0.0, 1e6)?;
            if f <= self.min_frequency_hz {
                return Err(ConfigError::new(
                    "max_frequency_hz",
                    "must be above min_frequency_hz",
                ));
            }
        }
        in_range("null_loading", self.null_loading, 1e-9, 1e3)?;
        in_range(
            "steering_tolerance_rad",
            self.steering_tolerance_rad,
            0.0,
            1.0,
        )?;
        self.rls.validate().map_err(|e| e.within("rls"))?;
        self.mvdr.validate().map_err(|e| e.within("mvdr"))?;
        self.adaptation
            .validate()
            .map_err(|e| e.within("adaptation"))?;
        self.post_filter
            .validate()
            .map_err(|e| e.within("post_filter"))?;
        self.lifecycle.validate().map_err(|e| e.within("lifecycle"))
    }
}

impl RlsConfig {
    /// Checks the canceller's fields.
    pub fn validate(&self) -> Result<(), ConfigError> {
        in_range("forgetting", self.forgetting, 0.5, 1.0 - 1e-9)?;
        in_range("init_regularisation", self.init_regularisation, 1e-9, 1e6)?;
        in_range("leakage", self.leakage, 0.0, 1e3)?;
        in_range("max_norm_ratio", self.max_norm_ratio, 0.0, 1e6)?;
        if !(1..=8).contains(&self.update_every) {
            return Err(ConfigError::new(
                "update_every",
                format!("{} is outside 1..=8", self.update_every),
            ));
        }
        Ok(())
    }
}

impl MvdrConfig {
    /// Checks the MVDR fields.
    pub fn validate(&self) -> Result<(), ConfigError> {
        in_range("forgetting", self.forgetting, 0.5, 1.0 - 1e-9)?;
        in_range("loading", self.loading, 1e-9, 1e3)
    }
}

impl AdaptationConfig {
    /// Checks the adaptation control's thresholds.
    pub fn validate(&self) -> Result<(), ConfigError> {
        unit_interval("presence", self.presence_low, self.presence_high)?;
        in_range("power_smoothing", self.power_smoothing, 0.0, 0.999)?;
        unit_interval("dominance", self.dominance_low, self.dominance_high)
    }
}

impl PostFilterConfig {
    /// Checks the post-filter's fields and its harmonic grouping.
    pub fn validate(&self) -> Result<(), ConfigError> {
        in_range("gain_floor", self.gain_floor, 0.0, 1.0)?;
        in_range("power_smoothing", self.power_smoothing, 0.0, 0.999)?;
        in_range("exponent", self.exponent, 0.1, 10.0)?;
        in_range("mask_threshold", self.mask_threshold, 1e-3, 1e3)?;
        in_range("untracked_weight", self.untracked_weight, 0.0, 100.0)?;
        in_range("untracked_margin", self.untracked_margin, 1.0, 1000.0)?;
        in_range("noise_rise_db_per_s", self.noise_rise_db_per_s, 0.01, 100.0)?;
        in_range("presence_floor", self.presence_floor, 1e-3, 1.0)?;
        in_range("demix_below_hz", self.demix_below_hz, 0.0, 1e6)?;
        self.harmonic.validate().map_err(|e| e.within("harmonic"))
    }
}

impl HarmonicConfig {
    /// Checks the harmonic grouping's fields.
    pub fn validate(&self) -> Result<(), ConfigError> {
        in_range("boost", self.boost, 0.0, 1e4)?;
        in_range("leakage_exponent", self.leakage_exponent, 0.01, 10.0)?;
        in_range("ownership_exponent", self.ownership_exponent, 0.0, 10.0)?;
        in_range("spatial_discount", self.spatial_discount, 0.0, 1.0)?;
        in_range("f0_min_hz", self.f0_min_hz, 20.0, 2000.0)?;
        in_range("f0_max_hz", self.f0_max_hz, self.f0_min_hz, 2000.0)?;
        in_range(
            "max_frequency_hz",
            self.max_frequency_hz,
            self.f0_max_hz,
            1e6,
        )?;
        in_range("voicing_low", self.voicing_low, -1.0, 1.0)?;
        if !(self.voicing_high > self.voicing_low && self.voicing_high <= 1.0) {
            return Err(ConfigError::new(
                "voicing_high",
                "must be above voicing_low and at most 1",
            ));
        }
        in_range("periodicity_low", self.periodicity_low, 0.0, 1.0)?;
        if !(self.periodicity_high > self.periodicity_low && self.periodicity_high <= 1.0) {
            return Err(ConfigError::new(
                "periodicity_high",
                "must be above periodicity_low and at most 1",
            ));
        }
        in_range("periodicity_weight", self.periodicity_weight, 0.0, 16.0)?;
        in_range("register_semitones", self.register_semitones, 0.0, 48.0)?;
        in_range("register_memory_s", self.register_memory_s, 0.01, 3600.0)?;
        in_range(
            "register_confidence_s",
            self.register_confidence_s,
            0.001,
            3600.0,
        )?;
        in_range("register_ownership", self.register_ownership, 0.0, 10.0)?;
        in_range(
            "track_semitones_per_s",
            self.track_semitones_per_s,
            0.0,
            1000.0,
        )?;
        in_range("track_jump", self.track_jump, 0.0, 100.0)?;
        in_range(
            "competitor_audibility_exponent",
            self.competitor_audibility_exponent,
            0.0,
            16.0,
        )?;
        unit_interval("activity", self.activity_low, self.activity_high)?;
        in_range("activity_smoothing", self.activity_smoothing, 0.0, 0.999)?;
        in_range("activity_room_level", self.activity_room_level, 0.0, 1.0)?;
        in_range(
            "activity_room_memory_s",
            self.activity_room_memory_s,
            0.1,
            3600.0,
        )?;
        in_range("activity_hold", self.activity_hold, 0.0, 1.0)?;
        in_range("activity_hold_max_s", self.activity_hold_max_s, 0.0, 10.0)?;
        in_range("salience_whitening", self.salience_whitening, 0.0, 2.0)?;
        in_range(
            "whitening_bandwidth_hz",
            self.whitening_bandwidth_hz,
            0.0,
            8000.0,
        )?;
        in_range("fit_below_hz", self.fit_below_hz, 0.0, 8000.0)?;
        in_range("fit_min_voicing", self.fit_min_voicing, 0.0, 1.0)?;
        in_range("fit_memory", self.fit_memory, 0.0, 0.999)?;
        in_range("fit_memory_exponent", self.fit_memory_exponent, 0.0, 4.0)?;
        if !(self.fit_loading > 0.0 && self.fit_loading <= 1e3) {
            return Err(ConfigError::new(
                "fit_loading",
                format!("must be in (0, 1000], got {}", self.fit_loading),
            ));
        }
        Ok(())
    }
}

impl LifecycleConfig {
    /// Checks the fades, the grace time and the stream cap.
    pub fn validate(&self) -> Result<(), ConfigError> {
        in_range("fade_in_s", self.fade_in_s, 0.0, 10.0)?;
        in_range("grace_s", self.grace_s, 0.0, 60.0)?;
        in_range("fade_out_s", self.fade_out_s, 0.0, 10.0)?;
        in_range("rest_after_s", self.rest_after_s, 0.0, 3600.0)?;
        in_range("wake_speaking", self.wake_speaking, 0.0, 1.0)?;
        ConfigError::check(
            (1..=1024).contains(&self.max_streams),
            "max_streams",
            "must be in 1..=1024",
        )
    }
}
