//! An upper bound of the memory a localiser's tables take, from the layout and the settings
//! alone, so a server can admit a session (or a recalibration) before anything is built. It
//! follows the sizes the constructors use; `tests/session_memory.rs` checks it against the
//! bytes a built localiser holds, which it must not undercut.

use crate::geometry::{Layout, MicArray};

use super::LocalizerConfig;
use super::gcc::LAG_MARGIN_SAMPLES;
use super::lag_kernel::SINC_TAPS;
use super::subband_lags::LAG_BLOCK;

const F64: usize = 8;
const COMPLEX: usize = 16;
const VEC3: usize = 24;
/// A `Vec`'s own header (pointer, capacity, length).
const VEC: usize = 24;
/// Neighbours of a geodesic point (at most six) are collected into a vector that grows to eight
/// indices; a coarse point's children into one that starts at four.
const NEIGHBOURS: usize = 8;
const CHILDREN: usize = 4;
/// What each array's smaller tables and vector headers add (measured under 16 KB).
const SLACK: usize = 64 << 10;

/// Bytes a localiser built for `layout` with `cfg` holds, at most (a bound, not an estimate:
/// tables grown by pushing are counted at twice their length).
pub fn footprint(layout: &Layout, cfg: &LocalizerConfig) -> usize {
    let total: usize = layout
        .arrays
        .iter()
        .filter(|a| !a.channels.is_empty())
        .map(|a| array_bytes(a, layout, cfg))
        .sum();
    // The largest tables are counted exactly; a twentieth more covers rounding elsewhere.
    total + total / 20
}

/// One array's tables: the GCC bank with its sub-band lags, the direction and position
/// searches, the sub-band mask, the noise floor and the activity history.
fn array_bytes(array: &MicArray, layout: &Layout, cfg: &LocalizerConfig) -> usize {
    let fs = f64::from(layout.sample_rate);
    let c = layout.speed_of_sound;
    let m = array.len();
    let pairs = array.pairs();
    let np = pairs.len();
    let interp = cfg.interpolation.max(1);
    let halves: Vec<usize> = pairs
        .iter()
        .map(|&(a, b)| {
            let lag = (array.mics[a] - array.mics[b]).norm() / c * fs;
            ((lag + LAG_MARGIN_SAMPLES) * interp as f64).ceil() as usize
        })
        .collect();
    let table: usize = halves.iter().map(|h| 2 * h + 2).sum();
    let max_half = halves.iter().copied().max().unwrap_or(0);
    let lag_span = max_half / interp + 2 + SINC_TAPS;
    let (lo, hi) = cfg.band_bins(layout.sample_rate);
    let nb = (hi + 1).saturating_sub(lo).max(1);
    let width = cfg.peaks.subband_bins.clamp(1, nb);
    let count = nb.div_ceil(width);
    let stride = (2 * lag_span + 1).next_multiple_of(LAG_BLOCK);
    let kernel = 2 * max_half + 4;

    let bank = 2 * table * F64
        + nb * m * (COMPLEX + F64)
        + 2 * nb * F64
        + nb * np * 2 * (COMPLEX + F64)
        + 2 * np * count * F64
        + (2 * lag_span + 1) * F64
        + 2 * interp * 2 * SINC_TAPS * F64
        + kernel * F64
        + m * F64
        + np * count * stride * F64
        + 2 * np * count * F64
        // The sub-bands' phasor tables are pushed: up to twice their length.
        + 2 * 2 * (width + count) * stride * F64;
    let searches = if m >= 2 {
        direction_bytes(cfg, np, m, table, kernel, 2 * max_half + 2) + position_bytes(cfg, np, m)
    } else {
        0
    };
    let mask = count * np * COMPLEX + 2 * count * F64 + count * m * COMPLEX + np * 2 * F64;
    let mask = mask + 3 * m * COMPLEX + count * F64;
    let window = cfg.activity.noise_window_frames;
    let floor = nb * (window + 1) * F64 + window * F64;
    let found = cfg.max_candidates * (VEC3 + F64) + m * F64;
    bank + searches + mask + floor + found + SLACK
}

/// The direction search: every level's directions with one TDOA index per pair, their
/// neighbours and children, and one max-filtered table per level but the last.
fn direction_bytes(
    cfg: &LocalizerConfig,
    np: usize,
    m: usize,
    table: usize,
    kernel: usize,
    longest: usize,
) -> usize {
    let levels = &cfg.directions.levels;
    let points = |l: u32| 10usize.saturating_mul(4usize.saturating_pow(l)) + 2;
    let dirs: usize = levels.iter().map(|&l| points(l)).sum();
    let per_dir = VEC3 + np * 4 + 2 * VEC + (NEIGHBOURS + CHILDREN) * F64;
    let coarse = levels.len().saturating_sub(1);
    dirs * per_dir
        + coarse * (np * F64 + VEC + table * F64)
        + 2 * longest * F64
        + kernel * F64
        + np * (VEC3 + F64)
        + m * VEC3
}

/// The position search: the microphones, the pairs and the contraction's points.
fn position_bytes(cfg: &LocalizerConfig, np: usize, m: usize) -> usize {
    let points = cfg.positions.initial_points.max(cfg.positions.kept_points);
    m * (VEC3 + F64) + np * (2 * F64 + F64) + points * (VEC3 + F64)
}
