//! An upper bound of the memory a separator takes with a given number of labels, from the layout
//! and the settings alone, so a server can admit a session before anything is built. Per label
//! it follows the per-bin state the streams are sized with (the canceller's RLS state dominates,
//! growing with the square of the microphones); `tests/session_memory.rs` checks the bound
//! against the bytes a separator holds, which it must not undercut.

use crate::geometry::Layout;

use super::config::{BeamformerKind, SeparatorConfig};
use super::direct_power::BAND_HZ;
use super::rls;

const F64: usize = 8;
const COMPLEX: usize = 16;
/// A `Vec`'s own header (pointer, capacity, length).
const VEC: usize = 24;
/// Per bin and label, the post-filter, grouping and output state besides the beamformer's:
/// fixed-beamformer power, post-filter state, the frame's gains, outputs and ambiguities, the
/// harmonic fit's memory and magnitudes, and the output spectrum.
const PER_LABEL_BIN: usize = F64 + 3 * F64 + F64 + COMPLEX + F64 + 2 * F64 + 2 * F64 + COMPLEX;
/// Tables that do not grow with the frame or the microphones (pitch search, envelopes).
const SLACK: usize = 256 << 10;

/// Bytes a separator for `layout` with `cfg` holds once it separates `labels` labels, at most.
/// Vectors resized as labels come grow by doubling, so the terms that grow with the labels are
/// counted twice.
pub fn footprint(layout: &Layout, cfg: &SeparatorConfig, labels: usize) -> usize {
    let bins = cfg.frame / 2 + 1;
    let channels = layout.channel_count();
    let groups: Vec<usize> = layout
        .arrays
        .iter()
        .map(|a| a.channels.len())
        .filter(|&m| m > 0)
        .collect();
    let m = groups.iter().copied().max().unwrap_or(0);
    let hz_per_bin = f64::from(layout.sample_rate) / cfg.frame as f64;
    // The direct-path fit reads every fourth bin up to the band's top, per group.
    let fitted = (BAND_HZ.1 / hz_per_bin).ceil() as usize / 4 + 1;
    let n = labels;
    // The input spectra and per-channel tables of every bin (measured: four complex values).
    let base = 4 * bins * channels * COMPLEX
        + 2 * bins * F64
        + groups
            .iter()
            .map(|&g| fitted * (g * g * F64 + F64) + g * COMPLEX)
            .sum::<usize>()
        + SLACK;
    if n == 0 {
        return base;
    }
    let beamformer = match cfg.beamformer {
        BeamformerKind::Gsc => {
            rls::Dims::new(m.saturating_sub(1)).stride() * std::mem::size_of::<rls::Real>()
        }
        BeamformerKind::Mvdr => m * m * COMPLEX,
        BeamformerKind::NullSteering | BeamformerKind::DelayAndSum => 0,
    };
    // The blocking matrix, and each label's own null-steering beamformers when the labels
    // outnumber a group's microphones (up to m constraints each).
    let blocking = m * COMPLEX + F64;
    let own = if n > m { null_steering(m) } else { 0 };
    let per_label = bins * (beamformer + blocking + own + PER_LABEL_BIN) + VEC * 8;
    // Shared null-steering beamformers per group and bin, and the pairs' tables.
    let shared = groups.len() * bins * null_steering(n.min(m.max(1)));
    let pairs = 2 * bins * n * n * F64 + fitted * (n + 1) * (n + 1) * F64 * groups.len();
    let total = base + n * per_label + 2 * (shared + pairs + groups.len() * 2 * n * m * COMPLEX);
    // The terms above are exact for the largest arrays (within 3 %); a tenth more covers the
    // smaller tables they leave out.
    total + total / 10
}

/// One bin's null-steering beamformer for `n` constraints: its Gram matrix and inverse factor,
/// two vectors of coefficients and the scales.
fn null_steering(n: usize) -> usize {
    2 * n * n * COMPLEX + 2 * n * COMPLEX + n * F64 + 5 * VEC
}
