//! How large one pipeline may be sized: its microphones, the span of their pairs, its analysis
//! frames and the labels it separates at once. The per-bin tables of the localiser and the
//! separator grow with these, so a layout or settings past them would take the machine's memory
//! before the first sample. The server's `limits` carry these bounds for every session, and
//! `avsep process` applies the same defaults to a scene folder. [`footprint`] bounds what one
//! pipeline takes in memory, so the server can admit sessions by a memory budget.

use crate::geometry::{GeometryError, Layout};

use super::{ConfigError, PipelineConfig};

/// The size bounds of one pipeline; each check names the field past its bound and the limit
/// (`limits.<name>`) it passes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SizeBounds {
    /// Microphones in all arrays together.
    pub max_microphones: usize,
    /// Sum over each array's microphone pairs of their distances (m), all arrays together.
    pub max_pair_span_m: f64,
    /// Largest STFT frame (samples) of the localisation or the separation.
    pub max_frame: usize,
    /// Most labels separated at once (`separate.lifecycle.max_streams`).
    pub max_streams: usize,
    /// Cameras in the session: each keeps its latest frame and is a sensor of every step.
    pub max_cameras: usize,
}

impl Default for SizeBounds {
    /// The server's default limits: a 64-microphone array of 30 cm diameter passes, a layout
    /// whose localiser tables would take gigabytes does not.
    fn default() -> Self {
        Self {
            max_microphones: 64,
            max_pair_span_m: 250.0,
            max_frame: 4096,
            max_streams: 16,
            max_cameras: 16,
        }
    }
}

impl SizeBounds {
    /// Refuses settings whose analysis frames pass `max_frame` or whose stream cap passes
    /// `max_streams`, naming the field (`localize.frame`, `separate.lifecycle.max_streams`),
    /// before anything is sized from them.
    pub fn check_settings(&self, settings: &PipelineConfig) -> Result<(), ConfigError> {
        for (field, value, limit, name) in [
            (
                "localize.frame",
                settings.localize.frame,
                self.max_frame,
                "max_frame",
            ),
            (
                "separate.frame",
                settings.separate.frame,
                self.max_frame,
                "max_frame",
            ),
            (
                "separate.lifecycle.max_streams",
                settings.separate.lifecycle.max_streams,
                self.max_streams,
                "max_streams",
            ),
        ] {
            if value > limit {
                return Err(ConfigError::new(
                    field,
                    format!(
                        "{value} is more than limits.{name} ({limit}): a session's tables \
                         grow with it"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Refuses a layout beyond `max_microphones` or `max_pair_span_m`, naming the array that
    /// passes the limit (`arrays[i].mics`), before anything is sized from it.
    pub fn check_layout(&self, layout: &Layout) -> Result<(), GeometryError> {
        if layout.cameras.len() > self.max_cameras {
            return Err(GeometryError::new(
                "cameras",
                format!(
                    "{} cameras, more than limits.max_cameras ({})",
                    layout.cameras.len(),
                    self.max_cameras
                ),
            ));
        }
        let total: usize = layout.arrays.iter().map(|a| a.mics.len()).sum();
        let mut mics = 0;
        let mut span = 0.0;
        for (i, a) in layout.arrays.iter().enumerate() {
            let field = format!("arrays[{i}].mics");
            mics += a.mics.len();
            if mics > self.max_microphones {
                return Err(GeometryError::new(
                    field,
                    format!(
                        "the session's arrays hold {total} microphones, more than \
                         limits.max_microphones ({})",
                        self.max_microphones
                    ),
                ));
            }
            span += a
                .pairs()
                .iter()
                .map(|&(p, q)| (a.mics[p] - a.mics[q]).norm())
                .sum::<f64>();
            if span.is_nan() || span > self.max_pair_span_m {
                return Err(GeometryError::new(
                    field,
                    format!(
                        "the microphone pairs span {span:.1} m in all, more than \
                         limits.max_pair_span_m ({} m): the localiser's tables grow with it",
                        self.max_pair_span_m
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// Memory a session's pipeline state takes besides the stages' tables, at most: the tracker's
/// hypotheses and the step's buffers (an everyday session's pipeline measured 0.5 MB built).
const STATE_ALLOWANCE: usize = 2 << 20;

/// Bytes a pipeline for `layout` with `cfg` takes at most, with every label its stream cap
/// allows separated: the localiser's tables, the separator's with its streams, and the audio
/// buffers; an error naming the field for settings no pipeline could be built with. It is
/// computed from the sizes the stages are built with, without building them;
/// `tests/session_memory.rs` checks that it never undercuts what a pipeline holds.
pub fn footprint(layout: &Layout, cfg: &PipelineConfig) -> Result<usize, ConfigError> {
    const F64: usize = 8;
    const COMPLEX: usize = 16;
    // The sizes below are read from the settings of the stages a pipeline builds, which are
    // checked first, as building them would.
    cfg.validate()?;
    let channels = layout.channel_count();
    if channels == 0 {
        return Ok(STATE_ALLOWANCE);
    }
    let lf = cfg.localize.frame;
    let localizer = if cfg.audio_measurements.uses_localizer() {
        cfg.localize
            .validate(layout)
            .map_err(|e| e.within("localize"))?;
        crate::localize::footprint(layout, &cfg.localize) + channels * (lf / 2 + 1) * COMPLEX
    } else {
        0
    };
    let (sf, streams) = (cfg.separate.frame, cfg.separate.lifecycle.max_streams);
    let separator = if cfg.separation {
        cfg.separate.validate().map_err(|e| e.within("separate"))?;
        crate::separate::footprint(layout, &cfg.separate, streams)
            + channels * (sf / 2 + 1) * COMPLEX
            // Each stream's overlap-add buffers.
            + streams * 2 * sf * F64
    } else {
        0
    };
    // The audio history of every channel, as the pipeline sizes it.
    let clock = super::StepClock::new(layout.sample_rate, cfg.step_s);
    let history = channels * clock.history_samples(lf.max(sf), cfg.camera_wait_s) * 2 * F64;
    Ok(localizer + separator + history + 4 * lf.max(sf) * F64 + STATE_ALLOWANCE)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{MicArray, Vec3};

    #[test]
    fn cameras_past_the_bound_are_named() {
        let uca = crate::scene::sim::SimConfig::preset("uca8", &Default::default(), 1).unwrap();
        let mut layout = crate::scene::sim::layout::build(&uca).unwrap();
        let bounds = SizeBounds {
            max_cameras: layout.cameras.len(),
            ..SizeBounds::default()
        };
        bounds.check_layout(&layout).unwrap();
        layout.cameras.push(layout.cameras[0].clone());
        let e = bounds.check_layout(&layout).unwrap_err();
        assert_eq!(e.field, "cameras");
        assert!(e.message.contains("limits.max_cameras"), "{e}");
    }

    #[test]
    fn frames_and_stream_caps_past_the_bounds_are_named() {
        let bounds = SizeBounds::default();
        let mut settings = PipelineConfig::default();
        bounds.check_settings(&settings).unwrap();
        (settings.separate.frame, settings.separate.hop) = (8192, 4096);
        let e = bounds.check_settings(&settings).unwrap_err();
        assert_eq!(e.field, "separate.frame");
        assert!(e.message.contains("limits.max_frame"), "{e}");
        settings.localize.frame = 1 << 16;
        assert_eq!(
            bounds.check_settings(&settings).unwrap_err().field,
            "localize.frame"
        );
        let mut settings = PipelineConfig::default();
        settings.separate.lifecycle.max_streams = 17;
        let e = bounds.check_settings(&settings).unwrap_err();
        assert_eq!(e.field, "separate.lifecycle.max_streams");
        assert!(e.message.contains("limits.max_streams (16)"), "{e}");
    }

    #[test]
    fn settings_no_pipeline_could_use_have_no_footprint_and_are_named() {
        let mics = (0..4)
            .map(|i| Vec3::new(0.05 * i as f64, 0.0, 1.0))
            .collect();
        let array = MicArray::new("a", mics, (0..4).collect()).unwrap();
        let layout = Layout::new(16_000, 343.0, vec![array], vec![], None).unwrap();
        let cfg = PipelineConfig::default();
        let bound = footprint(&layout, &cfg).unwrap();
        assert!((1 << 20..64 << 20).contains(&bound), "{bound}");
        let named = |edit: fn(&mut PipelineConfig)| {
            let mut cfg = PipelineConfig::default();
            edit(&mut cfg);
            footprint(&layout, &cfg).unwrap_err().field
        };
        assert_eq!(named(|c| c.localize.frame = 0), "localize.frame");
        assert_eq!(named(|c| c.separate.frame = 3), "separate.frame");
        assert_eq!(named(|c| c.step_s = 0.0), "step_s");
    }

    #[test]
    fn a_layout_is_checked_against_the_microphone_bounds() {
        // Measurement-only arrays: the bounds count microphones whether or not they carry audio.
        let array = |id: &str, mics: Vec<Vec3>| MicArray::new(id, mics, Vec::new()).unwrap();
        let line = |n: usize, spacing: f64| -> Vec<Vec3> {
            (0..n)
                .map(|i| Vec3::new(spacing * i as f64, 0.0, 1.0))
                .collect()
        };
        let layout = |arrays: Vec<MicArray>| Layout::new(16_000, 343.0, arrays, vec![], None);
        let bounds = SizeBounds {
            max_microphones: 8,
            max_pair_span_m: 10.0,
            ..SizeBounds::default()
        };
        // Two 4-microphone lines of 10 cm spacing: 8 microphones, pairs spanning 2 m in all.
        let ok = layout(vec![array("a", line(4, 0.1)), array("b", line(4, 0.1))]).unwrap();
        assert!(bounds.check_layout(&ok).is_ok());
        // A ninth microphone: the array that passes the count is named.
        let many = layout(vec![array("a", line(4, 0.1)), array("b", line(5, 0.1))]).unwrap();
        let e = bounds.check_layout(&many).unwrap_err();
        assert_eq!(e.field, "arrays[1].mics");
        assert!(e.message.contains("9 microphones"), "{e}");
        // Pairs spanning 10.5 m, and microphones so far apart that the distances overflow.
        let wide = layout(vec![array("a", line(2, 0.5)), array("b", line(2, 10.0))]).unwrap();
        let e = bounds.check_layout(&wide).unwrap_err();
        assert_eq!(e.field, "arrays[1].mics");
        assert!(e.message.contains("limits.max_pair_span_m"), "{e}");
        let huge = vec![Vec3::new(-1e308, 0.0, 0.0), Vec3::new(1e308, 0.0, 0.0)];
        let e = bounds
            .check_layout(&layout(vec![array("a", huge)]).unwrap())
            .unwrap_err();
        assert_eq!(e.field, "arrays[0].mics");
    }
}
