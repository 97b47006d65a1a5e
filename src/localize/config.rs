//! Configuration of the localiser and its validation.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::geometry::Layout;

pub use crate::field_error::FieldError as ConfigError;

/// Which searches the localiser runs on every frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum SearchMode {
    /// Directions of arrival only (hierarchical geodesic-sphere scan).
    Directions,
    /// 3-D position candidates only (stochastic region contraction).
    Positions,
    /// Both directions and positions.
    Both,
    /// Directions, and positions only for the arrays whose positions the tracker takes
    /// (`localized_measurements`; see [`crate::localize::Localizer::use_positions`]): nothing
    /// else consumes them, and the 3-D search is a fifth of a session's processing. `both`
    /// also records every array's positions (measurements.jsonl, measurement OSPA).
    Auto,
}

impl SearchMode {
    /// Whether the direction search runs.
    pub fn directions(self) -> bool {
        matches!(self, Self::Directions | Self::Both | Self::Auto)
    }

    /// Whether the position search runs on every array (`auto` decides per array).
    pub fn positions(self) -> bool {
        matches!(self, Self::Positions | Self::Both)
    }
}

/// The SRP-PHAT localiser: GCC-PHAT per microphone pair, then direction and/or position search.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct LocalizerConfig {
    /// Analysis frame in samples (Hann window and FFT length); 2048 = 128 ms at 16 kHz as in the paper.
    pub frame: usize,
    /// Lower edge (Hz) of the band used for GCC/SRP. The paper high-passes at 1 kHz; 1.5 kHz
    /// measured better on the simulator's uca8 and paper-linear6 scenes: below it a small
    /// array's lobes are so wide that two talkers' peaks merge, and reverberation is stronger.
    pub band_low_hz: f64,
    /// Upper edge (Hz) of the band used for GCC/SRP; clamped to just below half the sample rate.
    /// 6 kHz measured best on the simulator's uca8 and paper-linear6 scenes (speech still
    /// carries formants and fricatives there, and the higher bins sharpen a small array's peaks).
    pub band_high_hz: f64,
    /// PHAT exponent beta: each bin is divided by |Y|^beta before the cross-correlation (1 =
    /// classic PHAT; below 1 the bins where speech is strong weigh more than those between its
    /// harmonics, which noise and reverberation fill).
    pub phat_exponent: f64,
    /// Bins are weighted by P / (P + noise_weight * N), P the bin's power and N its noise floor
    /// (minimum over `activity.noise_window_frames` frames), so bins the sources do not reach
    /// count less; 0 weighs all bins alike (plain PHAT).
    pub noise_weight: f64,
    /// The cross-spectra are smoothed recursively over the frames: each frame's smoothed
    /// cross-spectrum is its own plus smoothing_decay times the previous frame's (0: none), so
    /// the frame i steps back weighs smoothing_decay^i. A source that stays in place adds up
    /// coherently over them, while reverberation and sensor noise, whose phases change from
    /// frame to frame, do not; and a talker quieter in this frame than in the last few is still
    /// there to be found once the louder one is masked. Measured on the simulator's uca8 scenes
    /// (two talkers, RT60 0.3 s, 20 dB, seeds 1-6; talker-frames with a candidate within 5
    /// degrees): 0.8 89.7 %, 0.85 91.5 %, 0.9 92.8 % (with relative_power 0.3); 0.9 also
    /// tracks best (avsep process + eval, uca8 2 talkers audio-only and 3 talkers AV). The memory
    /// lags a talker who walks while he talks (recorded uca8 seed 8: a walker's candidate stayed at
    /// 97-98 degrees while he walked from 96 to 88). Re-measured once the tracker took only
    /// candidates heard in their own frame, 0.7 against 0.9, full pipeline, 3-D MOTA: uca8 three
    /// talkers seeds 1-18 95.0 against 93.5 %, recorded speech seeds 1-12 93.4 against 92.7 %
    /// (-0.10 dB SI-SDRi), paper-linear6 unchanged, audio-only uca8 36.3 against 40.9 % (see the
    /// README's tracker limits). With the tracks' gait, 0.7 tracks better still (3-D MOTA
    /// two-arrays seeds 13-24 70.5 against 65.5 %, uca8 seeds 1-18 96.7 against 94.8 %), but the
    /// uca8 figure above falls to 87.1 % and audio-only uca8 seeds 1-30 to 41.0 against 44.0 %,
    /// so 0.9 stays the default.
    pub smoothing_decay: f64,
    /// GCC lags are tabulated this many times finer than one sample (band-limited interpolation).
    pub interpolation: usize,
    /// Most candidates reported per array and frame (for each search).
    pub max_candidates: usize,
    /// Which searches to run: "directions", "positions", "both", or "auto" (directions, and
    /// positions where the tracker uses them).
    pub search: SearchMode,
    /// Direction search on geodesic spheres.
    pub directions: DirectionConfig,
    /// 3-D position search by stochastic region contraction.
    pub positions: PositionConfig,
    /// Acceptance of peaks and removal of found sources before the next search.
    pub peaks: PeakConfig,
    /// Per-frame voice-activity score.
    pub activity: ActivityConfig,
}

impl Default for LocalizerConfig {
    fn default() -> Self {
        Self {
            frame: 2048,
            band_low_hz: 1500.0,
            band_high_hz: 6000.0,
            phat_exponent: 1.0,
            noise_weight: 2.0,
            smoothing_decay: 0.9,
            interpolation: 10,
            max_candidates: 3,
            search: SearchMode::Auto,
            directions: DirectionConfig::default(),
            positions: PositionConfig::default(),
            peaks: PeakConfig::default(),
            activity: ActivityConfig::default(),
        }
    }
}

/// Hierarchical direction search (as ODAS SRP-PHAT-HSDA).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct DirectionConfig {
    /// Subdivision levels of the icosahedral geodesic spheres scanned coarse to fine (level L has
    /// 10*4^L+2 points: 2 -> 162, 4 -> 2562); each level after the first is scanned only around the
    /// best point of the previous one. Strictly increasing, at most 6.
    pub levels: Vec<u32>,
    /// The best point of the finest level is refined by a local pattern search down to this step (degrees).
    pub refine_step_deg: f64,
}

impl Default for DirectionConfig {
    fn default() -> Self {
        Self {
            levels: vec![2, 4],
            refine_step_deg: 0.1,
        }
    }
}

/// Stochastic region contraction (Do, Silverman & Yu 2007).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct PositionConfig {
    /// J0: random points drawn in the whole search box at the start of each search.
    pub initial_points: usize,
    /// N: points kept and replenished while the box contracts.
    pub kept_points: usize,
    /// The contraction stops when the box is smaller than this (cubic metres).
    pub min_volume_m3: f64,
    /// The contraction stops after this many SRP evaluations per search (including J0).
    pub max_evaluations: usize,
    /// Half the side (metres) of the cube around the array searched when the layout has no region.
    pub default_half_size_m: f64,
    /// Points closer than this (metres) to a microphone of the array are not considered.
    pub min_range_m: f64,
    /// Later searches of the same frame draw no points within this distance (metres) of an
    /// accepted candidate.
    pub exclusion_radius_m: f64,
    /// Where the SRP is flat along a ridge (range of a small array, the cone of a linear one),
    /// the final ascent trades this many null standard deviations of SRP (see
    /// `peaks.prominence_sigmas`) per half box diagonal, squared, of distance from the box centre
    /// and of range away from the box's mean range from the array, so the candidate is the most
    /// central of the equally good points rather than wherever noise put the maximum. 0 keeps
    /// the plain SRP maximum.
    pub centre_pull: f64,
}

impl Default for PositionConfig {
    fn default() -> Self {
        Self {
            initial_points: 1500,
            kept_points: 100,
            min_volume_m3: 1e-4,
            max_evaluations: 3500,
            default_half_size_m: 3.0,
            min_range_m: 0.3,
            exclusion_radius_m: 0.3,
            centre_pull: 2.0,
        }
    }
}

/// When a peak counts as a source, and how a found source is removed before searching again:
/// the sub-bands it dominates are masked and the GCCs recomputed (see `masking`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct PeakConfig {
    /// Smallest normalised SRP (mean GCC-PHAT per pair, in [-1, 1]) a candidate must reach in
    /// the map it was found in.
    pub min_power: f64,
    /// Candidates after the first must reach this fraction of the first candidate's SRP. 0.3
    /// measured on uca8 (seeds 1-6): 92.8 % of talker-frames within 5 degrees against 93.2 %
    /// at 0.2 and about 0.1 fewer candidates per frame; tracking on uca8 (3 talkers AV, seeds
    /// 1-6) changed within noise over 0.2-0.4 (0-0.7 label switches per scene, 0 at 0.3).
    pub relative_power: f64,
    /// Every candidate must exceed the mean SRP over the coarse direction grid of the map it was
    /// found in (after masking the candidates before it) by this many null standard deviations,
    /// the spread of the SRP of incoherent signals with that map's bin weights (about
    /// 1 / sqrt(2 * band bins * pairs) unmasked; the map's own spread is dominated by the
    /// sources' main lobes). 8 (with the masking) measured on the simulator's uca8 scenes
    /// (seeds 1-6): 86 % of talker-frames within 5 degrees with 0.29 false or duplicate
    /// candidates per frame, against 87 % with 0.61 at 5.
    pub prominence_sigmas: f64,
    /// Later direction searches of the same frame skip directions within this angle (degrees) of an
    /// accepted candidate (for linear arrays: cone angles within it).
    pub exclusion_angle_deg: f64,
    /// Later direction searches of the same frame also skip directions where a lone source at
    /// an accepted candidate would give more than this fraction of its peak SRP: inside its main
    /// lobe as the array sees it, which for a small planar array stretches far in elevation
    /// (reflections and the unmasked rest of a found talker peak there); 1 turns this off.
    pub exclusion_lobe: f64,
    /// A found source's weight on a sub-band it dominates to degree rho in [0, 1] is
    /// (1 - rho)^mask_exponent: large exponents keep sub-bands it only leaks into (rho of the
    /// beam pattern, 0.2-0.6 for talkers 40 degrees apart on a 10 cm array) and still remove
    /// those it dominates. 4 measured best on the uca8 scenes (1: 77 %, 2: 80 %, 8: 82 %).
    pub mask_exponent: f64,
    /// Bins per sub-band whose summed covariance decides which source dominates it: wide enough
    /// to average out reverberation, narrow enough that a quieter talker's harmonics can
    /// dominate one. 8 bins (62.5 Hz at 2048 samples and 16 kHz) measured best on uca8 (6: same
    /// hits, more false candidates; 12: 84 % against 85 %).
    pub subband_bins: usize,
    /// Power iterations (from the first candidate's steering vector) towards each sub-band's
    /// principal eigenvector; 1 measured 79 %, 3 85 %, 8 86 % on uca8.
    pub power_iterations: usize,
    /// Passes of re-estimation once the candidates are found: each is re-maximised with all the
    /// others masked, so that a later-found talker's lobe no longer pulls it (0: none).
    pub joint_passes: usize,
    /// A candidate is `sounding` (evidence that its source speaks now, which the tracker's
    /// `speaking` counts) when it stands this many null standard deviations above zero in the
    /// frame's own, unsmoothed SRP (its `fresh`). The smoothing keeps a talker who stopped in
    /// the maps for a second or more, and the tracker read that memory as speech. Candidates
    /// matched to the truth, paper-linear6 seeds 1-12: a talking source's median 19, a silent
    /// one's 0.4. 5 against every candidate sounding, full pipeline, paper-linear6 seeds 1-12 /
    /// uca8 3 talkers seeds 1-6 / real speech seeds 1-6: silent steps read as speaking 38 / 58
    /// / 47 % -> 8 / 10 / 7 %, precision of `speaking` 0.75 / 0.77 / 0.73 -> 0.92 / 0.94 /
    /// 0.94, recall 0.68 / 0.82 / 0.81 -> 0.52 / 0.63 / 0.66 (3: 0.89 / 0.90 / 0.89 and 0.56 /
    /// 0.69 / 0.70), measured when the tracker's `speaking` was the one reported. The tracks
    /// themselves do not change. The flag now feeds only the tracker's own `speaking`, which a
    /// pipeline whose localiser can probe replaces by the same reading at each track's position
    /// ([`Localizer::probe`](super::Localizer::probe)) filtered over the steps (the pipeline's
    /// `speaking` settings); the threshold then changes no output of the pipeline.
    pub sounding_sigmas: f64,
}

impl Default for PeakConfig {
    fn default() -> Self {
        Self {
            min_power: 0.05,
            relative_power: 0.3,
            prominence_sigmas: 8.0,
            exclusion_angle_deg: 10.0,
            exclusion_lobe: 0.2,
            mask_exponent: 4.0,
            subband_bins: 8,
            power_iterations: 8,
            joint_passes: 1,
            sounding_sigmas: 5.0,
        }
    }
}

/// Voice activity from energy above a tracked noise floor and the SRP peak.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct ActivityConfig {
    /// The noise floor is the minimum in-band power over this many past frames (minimum statistics);
    /// longer than the longest expected stretch of uninterrupted speech.
    pub noise_window_frames: usize,
    /// Energy-to-floor ratio (dB) at which the energy score is one half.
    pub snr_midpoint_db: f64,
    /// Width (dB) of the energy score's sigmoid.
    pub snr_scale_db: f64,
    /// Normalised SRP of the strongest peak at which the coherence score is one half.
    pub coherence_midpoint: f64,
    /// Width of the coherence score's sigmoid (normalised SRP units).
    pub coherence_scale: f64,
    /// Frames whose mean in-band power per sample is below this (full scale = 1) are silent.
    pub min_power: f64,
    /// Frames whose activity is below this report no candidates (0 reports whatever passes the
    /// peak tests).
    pub min_activity: f64,
}

impl Default for ActivityConfig {
    fn default() -> Self {
        Self {
            noise_window_frames: 24,
            snr_midpoint_db: 4.5,
            snr_scale_db: 2.0,
            coherence_midpoint: 0.1,
            coherence_scale: 0.03,
            min_power: 1e-10,
            min_activity: 0.0,
        }
    }
}

fn finite_in(v: f64, lo: f64, hi: f64) -> bool {
    v.is_finite() && v >= lo && v <= hi
}

impl LocalizerConfig {
    /// The inclusive range of FFT bins of the band at `sample_rate` (DC and Nyquist excluded,
    /// the upper edge clamped below Nyquist).
    pub fn band_bins(&self, sample_rate: u32) -> (usize, usize) {
        let bin_hz = f64::from(sample_rate) / self.frame as f64;
        let lo = ((self.band_low_hz / bin_hz).ceil().max(1.0)) as usize;
        let hi = ((self.band_high_hz / bin_hz).floor() as usize).min(self.frame / 2 - 1);
        (lo, hi)
    }

    /// Checks the configuration against itself and the layout's sample rate.
    pub fn validate(&self, layout: &Layout) -> Result<(), ConfigError> {
        let nyquist = f64::from(layout.sample_rate) / 2.0;
        ConfigError::check(
            (64..=65536).contains(&self.frame) && self.frame.is_multiple_of(2),
            "frame",
            "must be an even number of samples in 64..=65536",
        )?;
        ConfigError::check(
            finite_in(self.band_low_hz, 0.0, nyquist),
            "band_low_hz",
            "must be between 0 and half the sample rate",
        )?;
        ConfigError::check(
            finite_in(self.band_high_hz, self.band_low_hz, 1e6)
                && self.band_high_hz > self.band_low_hz,
            "band_high_hz",
            "must be above band_low_hz",
        )?;
        let (lo, hi) = self.band_bins(layout.sample_rate);
        ConfigError::check(
            hi >= lo + 7,
            "band_low_hz",
            "the band (up to half the sample rate) must span at least 8 frequency bins",
        )?;
        ConfigError::check(
            finite_in(self.phat_exponent, 0.0, 1.0),
            "phat_exponent",
            "must be in [0, 1]",
        )?;
        ConfigError::check(
            finite_in(self.noise_weight, 0.0, 1e6),
            "noise_weight",
            "must be in [0, 1e6]",
        )?;
        ConfigError::check(
            finite_in(self.smoothing_decay, 0.0, 0.99),
            "smoothing_decay",
            "must be in [0, 0.99]",
        )?;
        ConfigError::check(
            (1..=64).contains(&self.interpolation),
            "interpolation",
            "must be in 1..=64",
        )?;
        ConfigError::check(
            (1..=16).contains(&self.max_candidates),
            "max_candidates",
            "must be in 1..=16",
        )?;
        self.validate_directions()?;
        self.validate_positions()?;
        self.validate_peaks()?;
        self.validate_activity()
    }

    fn validate_directions(&self) -> Result<(), ConfigError> {
        let d = &self.directions;
        ConfigError::check(
            !d.levels.is_empty()
                && d.levels.iter().all(|&l| l <= 6)
                && d.levels.windows(2).all(|w| w[0] < w[1]),
            "directions.levels",
            "must be a non-empty, strictly increasing list of levels in 0..=6",
        )?;
        ConfigError::check(
            finite_in(d.refine_step_deg, 1e-3, 10.0),
            "directions.refine_step_deg",
            "must be between 0.001 and 10 degrees",
        )
    }

    fn validate_positions(&self) -> Result<(), ConfigError> {
        let p = &self.positions;
        // Each evaluation is an SRP over every pair, every frame: a session's settings may ask
        // for some thirty times the default's work, not for seconds per frame.
        ConfigError::check(
            (2..=10_000).contains(&p.kept_points),
            "positions.kept_points",
            "must be in 2..=10000",
        )?;
        ConfigError::check(
            p.initial_points >= p.kept_points && p.initial_points <= 100_000,
            "positions.initial_points",
            "must be at least kept_points and at most 100000",
        )?;
        ConfigError::check(
            p.max_evaluations >= p.initial_points && p.max_evaluations <= 100_000,
            "positions.max_evaluations",
            "must be at least initial_points and at most 100000",
        )?;
        ConfigError::check(
            p.min_volume_m3.is_finite() && p.min_volume_m3 > 0.0,
            "positions.min_volume_m3",
            "must be a positive number",
        )?;
        ConfigError::check(
            finite_in(p.default_half_size_m, 0.01, 1000.0),
            "positions.default_half_size_m",
            "must be between 0.01 and 1000 m",
        )?;
        ConfigError::check(
            finite_in(p.min_range_m, 0.0, 100.0),
            "positions.min_range_m",
            "must be between 0 and 100 m",
        )?;
        ConfigError::check(
            finite_in(p.exclusion_radius_m, 0.0, 100.0),
            "positions.exclusion_radius_m",
            "must be between 0 and 100 m",
        )?;
        ConfigError::check(
            finite_in(p.centre_pull, 0.0, 1000.0),
            "positions.centre_pull",
            "must be between 0 and 1000",
        )
    }

    fn validate_peaks(&self) -> Result<(), ConfigError> {
        let p = &self.peaks;
        ConfigError::check(
            finite_in(p.min_power, -1.0, 1.0),
            "peaks.min_power",
            "must be in [-1, 1]",
        )?;
        ConfigError::check(
            finite_in(p.relative_power, 0.0, 1.0),
            "peaks.relative_power",
            "must be in [0, 1]",
        )?;
        ConfigError::check(
            finite_in(p.prominence_sigmas, 0.0, 100.0),
            "peaks.prominence_sigmas",
            "must be in [0, 100]",
        )?;
        ConfigError::check(
            finite_in(p.exclusion_angle_deg, 0.0, 179.0),
            "peaks.exclusion_angle_deg",
            "must be in [0, 179] degrees",
        )?;
        ConfigError::check(
            finite_in(p.exclusion_lobe, 0.0, 1.0),
            "peaks.exclusion_lobe",
            "must be in [0, 1]",
        )?;
        ConfigError::check(
            finite_in(p.mask_exponent, 0.0, 64.0),
            "peaks.mask_exponent",
            "must be in [0, 64]",
        )?;
        ConfigError::check(
            (1..=256).contains(&p.subband_bins),
            "peaks.subband_bins",
            "must be in 1..=256",
        )?;
        ConfigError::check(
            p.power_iterations <= 100,
            "peaks.power_iterations",
            "must be in 0..=100",
        )?;
        ConfigError::check(
            p.joint_passes <= 10,
            "peaks.joint_passes",
            "must be in 0..=10",
        )?;
        ConfigError::check(
            p.sounding_sigmas.is_finite() && (0.0..=100.0).contains(&p.sounding_sigmas),
            "peaks.sounding_sigmas",
            "must be in [0, 100]",
        )
    }

    fn validate_activity(&self) -> Result<(), ConfigError> {
        let a = &self.activity;
        ConfigError::check(
            (1..=100_000).contains(&a.noise_window_frames),
            "activity.noise_window_frames",
            "must be in 1..=100000",
        )?;
        ConfigError::check(
            finite_in(a.snr_midpoint_db, -100.0, 100.0),
            "activity.snr_midpoint_db",
            "must be in [-100, 100] dB",
        )?;
        ConfigError::check(
            finite_in(a.snr_scale_db, 0.01, 100.0),
            "activity.snr_scale_db",
            "must be in [0.01, 100] dB",
        )?;
        ConfigError::check(
            finite_in(a.coherence_midpoint, -1.0, 1.0),
            "activity.coherence_midpoint",
            "must be in [-1, 1]",
        )?;
        ConfigError::check(
            finite_in(a.coherence_scale, 1e-4, 10.0),
            "activity.coherence_scale",
            "must be in [0.0001, 10]",
        )?;
        ConfigError::check(
            finite_in(a.min_power, 0.0, 1.0),
            "activity.min_power",
            "must be in [0, 1]",
        )?;
        ConfigError::check(
            finite_in(a.min_activity, 0.0, 1.0),
            "activity.min_activity",
            "must be in [0, 1]",
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use crate::localize::synth;

    fn layout() -> Layout {
        let a = synth::uca(8, 0.05, Vec3::new(3.0, 2.0, 1.0), 0, "a");
        synth::layout(vec![a], Some(synth::room_box()))
    }

    #[test]
    fn config_errors_name_the_field() {
        let layout = layout();
        let bad = |f: &dyn Fn(&mut LocalizerConfig)| {
            let mut c = LocalizerConfig::default();
            f(&mut c);
            match c.validate(&layout) {
                Err(e) => e.field,
                Ok(()) => panic!("accepted"),
            }
        };
        assert!(LocalizerConfig::default().validate(&layout).is_ok());
        assert_eq!(bad(&|c| c.band_high_hz = 900.0), "band_high_hz");
        assert_eq!(
            bad(&|c| {
                c.band_low_hz = 7990.0;
                c.band_high_hz = 20000.0;
            }),
            "band_low_hz"
        );
        // The default band reaches above 4 kHz: at 8 kHz sampling it is clamped, not refused.
        let narrow =
            Layout::new(8000, 343.0, layout.arrays.clone(), vec![], layout.region).unwrap();
        assert!(LocalizerConfig::default().validate(&narrow).is_ok());
        assert_eq!(LocalizerConfig::default().band_bins(8000), (384, 1023));
        assert_eq!(bad(&|c| c.frame = 1001), "frame");
        assert_eq!(bad(&|c| c.smoothing_decay = 1.0), "smoothing_decay");
        assert_eq!(bad(&|c| c.smoothing_decay = -0.1), "smoothing_decay");
        assert_eq!(
            bad(&|c| c.directions.levels = vec![4, 2]),
            "directions.levels"
        );
        assert_eq!(
            bad(&|c| c.positions.kept_points = 5000),
            "positions.initial_points"
        );
        assert_eq!(
            bad(&|c| {
                c.positions.initial_points = 100_000;
                c.positions.max_evaluations = 100_000_000;
            }),
            "positions.max_evaluations"
        );
        assert_eq!(
            bad(&|c| c.peaks.relative_power = f64::NAN),
            "peaks.relative_power"
        );
        assert_eq!(
            bad(&|c| c.peaks.exclusion_lobe = 1.5),
            "peaks.exclusion_lobe"
        );
        assert_eq!(
            bad(&|c| c.peaks.mask_exponent = f64::INFINITY),
            "peaks.mask_exponent"
        );
        assert_eq!(bad(&|c| c.peaks.subband_bins = 0), "peaks.subband_bins");
        assert_eq!(
            bad(&|c| c.peaks.power_iterations = 1000),
            "peaks.power_iterations"
        );
        assert_eq!(bad(&|c| c.peaks.joint_passes = 11), "peaks.joint_passes");
        assert_eq!(
            bad(&|c| c.peaks.sounding_sigmas = f64::NAN),
            "peaks.sounding_sigmas"
        );
        let err =
            serde_json::from_str::<LocalizerConfig>(r#"{"positions": {"j0": 5}}"#).unwrap_err();
        assert!(err.to_string().contains("j0"), "{err}");
        let err =
            serde_json::from_str::<LocalizerConfig>(r#"{"smoothing_frames": 3}"#).unwrap_err();
        assert!(err.to_string().contains("smoothing_frames"), "{err}");
        let cfg: LocalizerConfig =
            serde_json::from_str(r#"{"search": "directions", "peaks": {"min_power": 0.2}}"#)
                .unwrap();
        assert_eq!(cfg.search, SearchMode::Directions);
        assert_eq!(cfg.peaks.min_power, 0.2);
        assert_eq!(cfg.frame, 2048);
    }
}
