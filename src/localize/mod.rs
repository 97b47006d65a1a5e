//! The acoustic localiser: GCC-PHAT per microphone pair, SRP-PHAT by table look-up, a
//! hierarchical geodesic-sphere search for directions and stochastic region contraction for 3-D
//! positions, several sources per frame by masking the sub-bands each found source dominates
//! (`masking`) and recomputing the GCCs before the next search, and a per-frame voice-activity
//! score.
//!
//! Pairs never cross arrays: each array is localised on its own (spec 000 section 2.6) and the
//! tracker fuses the arrays.

mod activity;
mod config;
mod directions;
mod footprint;
mod gcc;
mod geodesic;
mod lag_kernel;
mod masking;
mod noise_floor;
mod region_contraction;
mod sliding_max;
mod subband_lags;
#[cfg(test)]
mod synth;
#[cfg(test)]
mod tests;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

pub use config::{
    ActivityConfig, ConfigError, DirectionConfig, LocalizerConfig, PeakConfig, PositionConfig,
    SearchMode,
};
pub use footprint::footprint;

use activity::ActivityTracker;
use directions::DirectionSearch;
use gcc::{GccBank, GccSettings};
use masking::SubbandMask;
use noise_floor::BinNoiseFloor;
use region_contraction::PositionSearch;

use crate::dsp::MultiSpectrum;
use crate::geometry::{Layout, MicArray, Vec3, azimuth_of, elevation_of};

/// A direction of arrival seen from an array's centroid.
#[derive(Debug, Clone, PartialEq)]
pub struct DirectionCandidate {
    /// Unit vector from the array centroid towards the source. For a linear array only the angle
    /// to the array axis is observed; this is then the direction on that cone lying in the
    /// half-plane through the axis towards the region centre (see `directions` module docs).
    pub direction: Vec3,
    /// Azimuth of `direction` (radians, x-y plane from +x towards +y).
    pub azimuth: f64,
    /// Elevation of `direction` (radians, from the x-y plane towards +z).
    pub elevation: f64,
    /// Normalised SRP (mean GCC-PHAT per pair, in [-1, 1]) where the candidate was found.
    pub power: f64,
    /// This frame's own SRP at the candidate (without the smoothing's memory, the other
    /// candidates removed) in standard deviations of the SRP of incoherent signals: high while
    /// the source sounds, near zero once it has stopped and only the memory still holds it.
    pub fresh: f64,
    /// Whether `fresh` reaches the configured `peaks.sounding_sigmas`: the candidate is evidence
    /// that its source speaks now, not only the maps' memory of it.
    pub sounding: bool,
}

/// A 3-D position candidate (world frame).
#[derive(Debug, Clone, PartialEq)]
pub struct PositionCandidate {
    /// Position in metres.
    pub position: Vec3,
    /// Normalised SRP (mean GCC-PHAT per pair, in [-1, 1]) at the position.
    pub power: f64,
    /// This frame's own SRP at the candidate (without the smoothing's memory, the other
    /// candidates removed) in standard deviations of the SRP of incoherent signals: high while
    /// the source sounds, near zero once it has stopped and only the memory still holds it.
    pub fresh: f64,
    /// Whether `fresh` reaches the configured `peaks.sounding_sigmas`: the candidate is evidence
    /// that its source speaks now, not only the maps' memory of it.
    pub sounding: bool,
}

/// What one array saw in one localisation frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ArrayObservation {
    /// Index of the array in the layout.
    pub array: usize,
    /// Direction candidates, strongest first (empty when the direction search is off).
    pub doas: Vec<DirectionCandidate>,
    /// Position candidates, strongest first (empty when the position search is off).
    pub points: Vec<PositionCandidate>,
    /// Voice-activity score in [0, 1].
    pub activity: f64,
}

/// The searches of an array that can localise (two or more microphones).
struct Searches {
    directions: DirectionSearch,
    positions: PositionSearch,
}

/// Everything the localiser keeps for one array with audio channels.
struct ArrayState {
    index: usize,
    channels: Vec<usize>,
    /// Whitened spectra and GCC tables (no pairs for a single microphone: power only).
    bank: GccBank,
    searches: Option<Searches>,
    activity: ActivityTracker,
    floor: BinNoiseFloor,
    found: Vec<Vec3>,
    powers: Vec<f64>,
    /// Which sub-bands the candidates found so far dominate, and the mask removing them.
    mask: SubbandMask,
    /// Arrival times at the microphones of the candidate being removed.
    delays: Vec<f64>,
    /// Whether this frame was searched (loud enough), so that [`Localizer::probe`] may read it.
    searched: bool,
}

/// The localiser stage: one state per array, no I/O, no threads, no clocks.
pub struct Localizer {
    cfg: LocalizerConfig,
    arrays: Vec<ArrayState>,
    rng: ChaCha8Rng,
    channel_count: usize,
    band: (usize, usize),
    sample_rate: f64,
    /// Per layout array: whether its positions are wanted under `search = "auto"`.
    wanted_positions: Vec<bool>,
}

impl Localizer {
    /// A localiser for `layout`; `seed` drives the stochastic position search.
    pub fn new(layout: &Layout, cfg: &LocalizerConfig, seed: u64) -> Result<Self, ConfigError> {
        cfg.validate(layout)?;
        let sample_rate = f64::from(layout.sample_rate);
        let band = cfg.band_bins(layout.sample_rate);
        let mut localizer = Self {
            cfg: cfg.clone(),
            arrays: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            channel_count: 0,
            band,
            sample_rate,
            wanted_positions: Vec::new(),
        };
        localizer.set_layout(layout)?;
        Ok(localizer)
    }

    /// Which arrays (by layout index) need position candidates under `search = "auto"`: those
    /// whose positions the tracker takes. Arrays not listed get none.
    pub fn use_positions(&mut self, per_array: &[bool]) {
        self.wanted_positions = per_array.to_vec();
    }

    /// The analysis frame (samples) the spectra must come from.
    pub fn frame_size(&self) -> usize {
        self.cfg.frame
    }

    /// The configuration in use.
    pub fn config(&self) -> &LocalizerConfig {
        &self.cfg
    }

    /// Whether [`Localizer::set_layout`] would take `layout`, without changing anything.
    pub fn check_layout(&self, layout: &Layout) -> Result<(), ConfigError> {
        if f64::from(layout.sample_rate) != self.sample_rate {
            return Err(ConfigError::new(
                "sample_rate",
                "the layout's sample rate changed; build a new localiser",
            ));
        }
        self.cfg.validate(layout)
    }

    /// Rebuilds every geometry-dependent table for a recalibrated layout. The noise floors of
    /// arrays whose channels did not change are kept.
    pub fn set_layout(&mut self, layout: &Layout) -> Result<(), ConfigError> {
        self.check_layout(layout)?;
        let mut old = std::mem::take(&mut self.arrays);
        for (index, array) in layout.arrays.iter().enumerate() {
            if array.channels.is_empty() {
                continue;
            }
            let activity = old
                .iter_mut()
                .find(|s| s.index == index && s.channels == array.channels)
                .map(|s| s.activity.clone())
                .unwrap_or_else(|| ActivityTracker::new(&self.cfg.activity));
            self.arrays
                .push(self.array_state(index, array, layout, activity));
        }
        old.clear();
        self.channel_count = layout.channel_count();
        Ok(())
    }

    fn array_state(
        &self,
        index: usize,
        array: &MicArray,
        layout: &Layout,
        activity: ActivityTracker,
    ) -> ArrayState {
        let c = layout.speed_of_sound;
        let bank = GccBank::new(
            array,
            self.cfg.frame,
            self.band,
            GccSettings {
                interpolation: self.cfg.interpolation,
                beta: self.cfg.phat_exponent,
                smoothing: self.cfg.smoothing_decay,
                subband_bins: self.cfg.peaks.subband_bins,
            },
            self.sample_rate,
            c,
        );
        let searches = (array.len() >= 2).then(|| {
            let directions = DirectionSearch::new(
                array,
                &bank,
                layout.region,
                &self.cfg.directions.levels,
                self.cfg.directions.refine_step_deg.to_radians(),
                self.cfg.peaks.exclusion_lobe,
                c,
            );
            let positions = PositionSearch::new(
                array,
                &bank,
                layout.region,
                &self.cfg.positions,
                c,
                directions.mirror_normal(),
            );
            Searches {
                directions,
                positions,
            }
        });
        ArrayState {
            index,
            channels: array.channels.clone(),
            floor: BinNoiseFloor::new(bank.bin_power.len(), self.cfg.activity.noise_window_frames),
            found: Vec::with_capacity(self.cfg.max_candidates),
            powers: Vec::with_capacity(self.cfg.max_candidates),
            mask: SubbandMask::new(
                &bank,
                self.cfg.peaks.power_iterations,
                self.cfg.peaks.mask_exponent,
                self.sample_rate,
            ),
            delays: vec![0.0; array.len()],
            searched: false,
            bank,
            searches,
            activity,
        }
    }

    /// Localises one frame: `spectra` holds the one-sided spectra of every audio channel of the
    /// layout (Hann-windowed frames of `frame_size()` samples). Returns one observation per array
    /// with audio channels. Spectra of the wrong shape give observations without candidates.
    pub fn process(&mut self, spectra: &MultiSpectrum) -> Vec<ArrayObservation> {
        let shape_ok =
            spectra.bins() == self.cfg.frame / 2 + 1 && spectra.channels() >= self.channel_count;
        if !shape_ok {
            tracing::warn!(
                bins = spectra.bins(),
                channels = spectra.channels(),
                "localiser: spectra do not match the frame size or the layout's channels"
            );
        }
        let mut out = Vec::with_capacity(self.arrays.len());
        for state in &mut self.arrays {
            let mut obs = ArrayObservation {
                array: state.index,
                doas: Vec::new(),
                points: Vec::new(),
                activity: 0.0,
            };
            let positions = self.cfg.search.positions()
                || (self.cfg.search == SearchMode::Auto
                    && self
                        .wanted_positions
                        .get(state.index)
                        .copied()
                        .unwrap_or(false));
            if shape_ok {
                process_array(
                    state,
                    spectra,
                    &self.cfg,
                    positions,
                    &mut self.rng,
                    &mut obs,
                );
            }
            out.push(obs);
        }
        out
    }

    /// Whether some array can search, and so [`Localizer::probe`] can read anything.
    pub fn can_probe(&self) -> bool {
        self.arrays.iter().any(|a| a.searches.is_some())
    }

    /// The last frame's own SRP at each of `positions` (world frame), each with the others'
    /// sub-bands removed, in null standard deviations (as a candidate's `fresh`), the highest
    /// over the arrays; 0 where no array searched the frame (too quiet). Tells whether a tracked
    /// talker sounds now even where the search found no candidate for him (a quieter talker in
    /// an overlap). None when no array can search at all (single microphones only): the layout
    /// then says nothing about who sounds. Call after [`Localizer::process`] on the same frame.
    pub fn probe(&mut self, positions: &[Vec3]) -> Option<Vec<f64>> {
        if !self.can_probe() {
            return None;
        }
        let mut out = vec![0.0f64; positions.len()];
        for state in &mut self.arrays {
            let Some(searches) = state.searches.as_ref() else {
                continue;
            };
            if !state.searched || positions.is_empty() {
                continue;
            }
            let sps = state.bank.steps_per_second;
            // The search started the mask on this frame (`searched`).
            state.mask.clear_sources();
            for p in positions {
                searches.positions.delays(p, sps, &mut state.delays);
                state.mask.add(&state.delays);
            }
            for (i, p) in positions.iter().enumerate() {
                searches.positions.delays(p, sps, &mut state.delays);
                let f = fresh_sigmas(
                    &state.bank,
                    &mut state.mask,
                    &state.delays,
                    i,
                    positions.len(),
                );
                out[i] = out[i].max(f);
            }
        }
        Some(out)
    }
}

/// Decides whether a search result is accepted as a candidate, against the statistics of the
/// map it was found in (after the removal of the candidates before it).
struct Acceptance {
    min_power: f64,
    relative: f64,
    /// The least power a peak needs: the map's coarse-grid mean plus the prominence.
    floor: f64,
    first: Option<f64>,
}

impl Acceptance {
    fn new(cfg: &PeakConfig, null_std: f64, map_mean: f64) -> Self {
        Self {
            min_power: cfg.min_power,
            relative: cfg.relative_power,
            floor: map_mean + cfg.prominence_sigmas * null_std,
            first: None,
        }
    }

    /// Moves the floor to a new map (after a removal), whose null spread and mean differ.
    fn rescale(&mut self, cfg: &PeakConfig, null_std: f64, map_mean: f64) {
        self.floor = map_mean + cfg.prominence_sigmas * null_std;
    }

    /// Whether a peak of `power` is a source.
    fn accepts(&mut self, power: f64) -> bool {
        let ok = power.is_finite()
            && power >= self.min_power
            && power >= self.floor
            && self.first.is_none_or(|f| power >= self.relative * f);
        if ok && self.first.is_none() {
            self.first = Some(power);
        }
        ok
    }
}

fn process_array(
    state: &mut ArrayState,
    spectra: &MultiSpectrum,
    cfg: &LocalizerConfig,
    positions: bool,
    rng: &mut ChaCha8Rng,
    obs: &mut ArrayObservation,
) {
    state.searched = false;
    let power = state.bank.whiten(spectra);
    if ActivityTracker::is_silent(&cfg.activity, power) {
        state.bank.forget();
        return;
    }
    let snr = state.activity.update(power);
    let Some(searches) = state.searches.as_mut() else {
        obs.activity = ActivityTracker::score(&cfg.activity, snr, None);
        return;
    };
    let bank = &mut state.bank;
    let floor = state.floor.update(&bank.bin_power);
    if cfg.noise_weight > 0.0 {
        bank.weight_bins(floor, cfg.noise_weight);
    }
    bank.compute();
    let stats = searches.directions.grid_stats(bank);
    obs.activity = ActivityTracker::score(&cfg.activity, snr, Some(stats.max));
    if obs.activity < cfg.activity.min_activity {
        return;
    }
    state.searched = true;
    if cfg.search.directions() {
        find_directions(state, cfg, stats.mean, obs);
    }
    if positions {
        find_positions(state, cfg, stats.mean, rng, obs);
    }
}

/// Direction candidates of one frame: the strongest direction, then the strongest once the
/// sub-bands of the ones found are masked, until a peak fails the acceptance; then each
/// candidate is re-estimated with the others masked.
fn find_directions(
    state: &mut ArrayState,
    cfg: &LocalizerConfig,
    grid_mean: f64,
    obs: &mut ArrayObservation,
) {
    let Some(searches) = state.searches.as_mut() else {
        return;
    };
    let bank = &mut state.bank;
    let search = &mut searches.directions;
    let exclusion = cfg.peaks.exclusion_angle_deg.to_radians();
    let mut accept = Acceptance::new(&cfg.peaks, bank.null_std(), grid_mean);
    let found = &mut state.found;
    found.clear();
    state.powers.clear();
    state.mask.start(bank);
    while found.len() < cfg.max_candidates {
        let Some((d, p)) = search.search(bank, found, exclusion) else {
            break;
        };
        if !accept.accepts(p) {
            break;
        }
        found.push(d);
        state.powers.push(p);
        search.delays(&d, &mut state.delays);
        state.mask.add(&state.delays);
        if found.len() < cfg.max_candidates {
            state.mask.apply(bank, None);
            accept.rescale(&cfg.peaks, bank.null_std(), search.grid_stats(bank).mean);
        }
    }
    // Each candidate was found with the ones before it removed but not the ones after it,
    // whose lobes pull it towards them: re-estimate each with all the others removed. The last
    // one found already had all the others removed (up to their own small moves here).
    if found.len() >= 2 {
        let mut others = Vec::with_capacity(found.len());
        for _ in 0..cfg.peaks.joint_passes {
            for i in 0..found.len() - 1 {
                state.mask.apply(bank, Some(i));
                others.clear();
                others.extend((0..found.len()).filter(|&j| j != i).map(|j| found[j]));
                let (d, p) = search.polish(bank, found[i], &others, exclusion);
                found[i] = d;
                state.powers[i] = p;
                search.delays(&d, &mut state.delays);
                state.mask.set(i, &state.delays);
            }
        }
    }
    for (i, (d, &p)) in found.iter().zip(&state.powers).enumerate() {
        search.delays(d, &mut state.delays);
        let fresh = fresh_sigmas(bank, &mut state.mask, &state.delays, i, found.len());
        obs.doas.push(DirectionCandidate {
            direction: *d,
            azimuth: azimuth_of(d),
            elevation: elevation_of(d),
            power: p,
            fresh,
            sounding: fresh >= cfg.peaks.sounding_sigmas,
        });
    }
    bank.restore();
}

/// Position candidates of one frame, found and removed as the directions are (without the
/// re-estimation: the stochastic search would cost as much again).
fn find_positions(
    state: &mut ArrayState,
    cfg: &LocalizerConfig,
    grid_mean: f64,
    rng: &mut ChaCha8Rng,
    obs: &mut ArrayObservation,
) {
    let Some(searches) = state.searches.as_mut() else {
        return;
    };
    let bank = &mut state.bank;
    let sps = bank.steps_per_second;
    let mut accept = Acceptance::new(&cfg.peaks, bank.null_std(), grid_mean);
    let found = &mut state.found;
    found.clear();
    state.mask.start(bank);
    while found.len() < cfg.max_candidates {
        let pull = cfg.positions.centre_pull * bank.null_std();
        let Some((x, p)) = searches.positions.search(bank, found, rng, pull) else {
            break;
        };
        if !accept.accepts(p) {
            break;
        }
        found.push(x);
        obs.points.push(PositionCandidate {
            position: x,
            power: p,
            fresh: 0.0,
            sounding: false,
        });
        searches.positions.delays(&x, sps, &mut state.delays);
        state.mask.add(&state.delays);
        if found.len() < cfg.max_candidates {
            state.mask.apply(bank, None);
            accept.rescale(
                &cfg.peaks,
                bank.null_std(),
                searches.directions.grid_stats(bank).mean,
            );
        }
    }
    for (i, c) in obs.points.iter_mut().enumerate() {
        searches
            .positions
            .delays(&c.position, sps, &mut state.delays);
        c.fresh = fresh_sigmas(bank, &mut state.mask, &state.delays, i, found.len());
        c.sounding = c.fresh >= cfg.peaks.sounding_sigmas;
    }
    bank.restore();
}

/// [`GccBank::fresh_srp`] of candidate `i` of `n` (the others removed), in null standard
/// deviations.
fn fresh_sigmas(bank: &GccBank, mask: &mut SubbandMask, delays: &[f64], i: usize, n: usize) -> f64 {
    let gains = (n > 1).then(|| mask.weights(Some(i)));
    let (srp, std) = bank.fresh_srp(delays, gains);
    if std > 0.0 && srp.is_finite() {
        srp / std
    } else {
        0.0
    }
}
