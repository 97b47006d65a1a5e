//! Scores of the tracker's output (`tracks.jsonl`): at each line's time the estimated set against
//! the true positions of the sources present then (OSPA, GOSPA, OSPA(2), CLEAR MOT, IDF1, HOTA),
//! the same figures in direction space (azimuth from the first array's centroid) and in each
//! camera's image, and per source the track initiation delay and the labels that carried it.
//!
//! The figures are computed twice: against every source present (`all`), and against the
//! "audible" sources only: present and having spoken within the last `audible_hold_s` seconds,
//! which is what an audio-only run can be expected to track.

use serde::{Deserialize, Serialize};

use crate::geometry::{Layout, Vec3, angle_diff, azimuth_of, deg, rad};
use crate::scene::TruthSource;
use crate::scene::format::TracksLine;

use super::clear_mot::{MotResult, clear_mot};
use super::config::EvalConfig;
use super::gospa::{GospaValue, gospa, mean_gospa};
use super::hota::{HotaScores, hota};
use super::identity::{IdentityScores, identity_scores};
use super::ospa::{OspaParams, OspaValue, TrackSamples, mean_ospa, ospa, ospa2_series};
use super::source_tracking::{SourceContext, source_tracking};
use super::stats::Summary;
use super::track_grid::Grid;

pub use super::source_tracking::{LabelShare, SourceTracking, SpeakingScore};

/// Tracking scores.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TracksReport {
    /// Number of tracker steps (lines of tracks.jsonl).
    pub steps: usize,
    /// Median spacing of the steps (s).
    pub step_s: Option<f64>,
    /// Distinct labels in the output.
    pub labels: usize,
    /// Figures against every source present.
    pub all: TrackingFigures,
    /// Figures against the sources present that spoke within the last `audible_hold_s`.
    pub audible: TrackingFigures,
    /// OSPA(2) (m) against every source present, at each step (for plots).
    pub ospa2_over_time: Vec<TimeValue>,
}

/// A value at a time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TimeValue {
    /// Time (s).
    pub t: f64,
    /// Value.
    pub value: f64,
}

/// Tracking figures against one selection of true sources.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrackingFigures {
    /// Number of (step, true source) pairs.
    pub truth_count: usize,
    /// Number of (step, track) pairs.
    pub track_count: usize,
    /// Mean OSPA (m) over steps.
    pub ospa: OspaValue,
    /// Mean OSPA(2) (m) over steps.
    pub ospa2: OspaValue,
    /// Mean GOSPA (m, alpha = 2, OSPA's cut-off and order) over steps.
    pub gospa: GospaValue,
    /// CLEAR MOT and identity scores in 3-D with the distance gate.
    pub position: MotFigures,
    /// Azimuth error (deg, from the first array's centroid) of the 3-D matched pairs.
    pub azimuth_error_deg: Summary,
    /// Pixel error of the 3-D matched pairs in each camera where the truth is in view.
    pub pixel_error_px: Vec<CameraError>,
    /// CLEAR MOT and identity scores in azimuth with the azimuth gate.
    pub direction: MotFigures,
    /// Azimuth error (deg) of the pairs matched in azimuth.
    pub direction_error_deg: Summary,
    /// Whether the matched tracks' `speaking` follows the sources' talk spurts, summed over
    /// the sources.
    pub speaking: SpeakingScore,
    /// Per true source.
    pub sources: Vec<SourceTracking>,
}

/// CLEAR MOT and identity figures of one matching.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotFigures {
    /// The gate (m, or deg for the direction figures).
    pub gate: f64,
    /// MOTA.
    pub mota: Option<f64>,
    /// MOTP: mean distance of the matches (m, or deg).
    pub motp: Option<f64>,
    /// Matches.
    pub matches: usize,
    /// False positives.
    pub false_positives: usize,
    /// Misses (false negatives).
    pub misses: usize,
    /// Identity switches.
    pub switches: usize,
    /// Fragmentations.
    pub fragmentations: usize,
    /// Mostly tracked sources.
    pub mostly_tracked: usize,
    /// Partially tracked sources.
    pub partially_tracked: usize,
    /// Mostly lost sources.
    pub mostly_lost: usize,
    /// IDF1.
    pub idf1: Option<f64>,
    /// IDP.
    pub idp: Option<f64>,
    /// IDR.
    pub idr: Option<f64>,
    /// HOTA with its parts; the similarity falls linearly from 1 at distance 0 to 0 at the gate.
    pub hota: Option<HotaScores>,
}

impl MotFigures {
    fn new(
        m: &MotResult,
        (id, hota): (&IdentityScores, Option<HotaScores>),
        gate: f64,
        to_unit: fn(f64) -> f64,
    ) -> Self {
        Self {
            gate: to_unit(gate),
            mota: m.mota(),
            motp: m.motp().map(to_unit),
            matches: m.match_count(),
            false_positives: m.false_positives,
            misses: m.misses,
            switches: m.switches,
            fragmentations: m.fragmentations,
            mostly_tracked: m.mostly_tracked,
            partially_tracked: m.partially_tracked,
            mostly_lost: m.mostly_lost,
            idf1: id.idf1(),
            idp: id.idp(),
            idr: id.idr(),
            hota,
        }
    }
}

/// Pixel error in one camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraError {
    /// Camera id.
    pub camera: String,
    /// Error (px) of the matched pairs whose truth is in view.
    pub error_px: Summary,
}

/// Whether `s` spoke at some time in `[t - hold, t]`.
fn spoke_within(s: &TruthSource, t: f64, hold: f64) -> bool {
    s.active.iter().any(|&(a, b)| a <= t && b >= t - hold)
}

/// Scores the tracks against the truth.
pub fn score_tracks(
    layout: &Layout,
    sources: &[TruthSource],
    lines: &[TracksLine],
    cfg: &EvalConfig,
) -> TracksReport {
    let grid = Grid::new(lines, sources);
    let present: Vec<Vec<bool>> = grid
        .truth
        .iter()
        .map(|s| s.iter().map(Option::is_some).collect())
        .collect();
    let audible: Vec<Vec<bool>> = sources
        .iter()
        .zip(&present)
        .map(|(s, p)| {
            grid.times
                .iter()
                .zip(p)
                .map(|(&t, &here)| here && spoke_within(s, t, cfg.audible_hold_s))
                .collect()
        })
        .collect();
    let (all, series) = figures(layout, sources, &grid, &present, cfg);
    let (audible, _) = figures(layout, sources, &grid, &audible, cfg);
    let mut spacing: Vec<f64> = grid.times.windows(2).map(|w| w[1] - w[0]).collect();
    spacing.sort_by(f64::total_cmp);
    TracksReport {
        steps: grid.times.len(),
        step_s: spacing.get(spacing.len() / 2).copied(),
        labels: grid.labels.len(),
        all,
        audible,
        ospa2_over_time: grid
            .times
            .iter()
            .zip(series)
            .map(|(&t, v)| TimeValue { t, value: v.total })
            .collect(),
    }
}

/// The figures against the truths `selected[source][step]`, and the OSPA(2) at each step.
fn figures(
    layout: &Layout,
    sources: &[TruthSource],
    grid: &Grid,
    selected: &[Vec<bool>],
    cfg: &EvalConfig,
) -> (TrackingFigures, Vec<OspaValue>) {
    let (ospas, gospas, ospa2) = set_distances(grid, selected, cfg);
    let origin = layout
        .arrays
        .first()
        .map_or(Vec3::zeros(), |a| a.centroid());
    let az = |p: &Vec3| azimuth_of(&(p - origin));
    let pos_frames = grid.frames(selected, |a, b| (a - b).norm());
    let dir_frames = grid.frames(selected, |a, b| angle_diff(az(b), az(a)).abs());
    let pos = clear_mot(&pos_frames, cfg.gate_m);
    let pos_id = identity_scores(&pos_frames, cfg.gate_m);
    let pos_hota = hota(&pos_frames, cfg.gate_m);
    let az_gate = rad(cfg.azimuth_gate_deg);
    let dir = clear_mot(&dir_frames, az_gate);
    let dir_id = identity_scores(&dir_frames, az_gate);
    let dir_hota = hota(&dir_frames, az_gate);

    let pos_pairs = matched_pairs(grid, &pos);
    let az_error = |(_, t, e): &(usize, Vec3, Vec3)| deg(angle_diff(az(e), az(t)).abs());
    let az_errors: Vec<f64> = pos_pairs.iter().map(az_error).collect();
    let dir_errors: Vec<f64> = matched_pairs(grid, &dir).iter().map(az_error).collect();
    let pixel_error_px = pixel_errors(layout, &pos_pairs);

    let ctx = SourceContext {
        layout,
        grid,
        selected,
        pos: &pos,
        dir: &dir,
        cfg,
    };
    let per_source: Vec<SourceTracking> = sources
        .iter()
        .enumerate()
        .map(|(i, s)| source_tracking(&ctx, s, i))
        .collect();
    let speaking = per_source
        .iter()
        .fold(SpeakingScore::default(), |a, s| a.add(&s.speaking));
    let figures = TrackingFigures {
        truth_count: pos.truth_count,
        track_count: pos.est_count,
        ospa: mean_ospa(&ospas),
        ospa2: mean_ospa(&ospa2),
        gospa: mean_gospa(&gospas),
        position: MotFigures::new(&pos, (&pos_id, pos_hota), cfg.gate_m, |v| v),
        azimuth_error_deg: Summary::of(&az_errors),
        pixel_error_px,
        direction: MotFigures::new(&dir, (&dir_id, dir_hota), az_gate, deg),
        direction_error_deg: Summary::of(&dir_errors),
        speaking,
        sources: per_source,
    };
    (figures, ospa2)
}

/// OSPA and GOSPA at every step and OSPA(2) over the sliding window, against the selected
/// truths.
fn set_distances(
    grid: &Grid,
    selected: &[Vec<bool>],
    cfg: &EvalConfig,
) -> (Vec<OspaValue>, Vec<GospaValue>, Vec<OspaValue>) {
    let params = OspaParams::new(cfg.ospa_cutoff_m, cfg.ospa_order);
    let steps = grid.times.len();
    let truth_samples: Vec<TrackSamples> = grid
        .truth
        .iter()
        .zip(selected)
        .map(|(s, sel)| s.iter().zip(sel).map(|(p, &on)| p.filter(|_| on)).collect())
        .collect();
    let est_samples = grid.est_samples();
    let (ospas, gospas): (Vec<OspaValue>, Vec<GospaValue>) = (0..steps)
        .map(|k| {
            let x: Vec<Vec3> = truth_samples.iter().filter_map(|s| s[k]).collect();
            let y: Vec<Vec3> = grid.est[k].iter().map(|e| e.1).collect();
            (ospa(&x, &y, params), gospa(&x, &y, params))
        })
        .unzip();
    let ospa2 = ospa2_series(
        &truth_samples,
        &est_samples,
        steps,
        cfg.ospa2_window_steps,
        params,
    );
    (ospas, gospas, ospa2)
}

/// `(step, true position, estimated position)` of every correspondence of a matching.
fn matched_pairs(grid: &Grid, m: &MotResult) -> Vec<(usize, Vec3, Vec3)> {
    m.matches
        .iter()
        .enumerate()
        .flat_map(|(k, ms)| {
            ms.iter().filter_map(move |mt| {
                let t = grid.truth[mt.truth][k]?;
                let e = grid.est[k].iter().find(|e| e.0 == mt.est)?.1;
                Some((k, t, e))
            })
        })
        .collect()
}

/// Pixel error of the matched pairs in each camera, where the truth is in view.
fn pixel_errors(layout: &Layout, pairs: &[(usize, Vec3, Vec3)]) -> Vec<CameraError> {
    layout
        .cameras
        .iter()
        .map(|cam| {
            let errs: Vec<f64> = pairs
                .iter()
                .filter(|(_, t, _)| cam.in_view(t))
                .filter_map(|(_, t, e)| Some((cam.project(e)? - cam.project(t)?).norm()))
                .collect();
            CameraError {
                camera: cam.id.clone(),
                error_px: Summary::of(&errs),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::MicArray;
    use crate::label::Label;
    use crate::scene::format::TrackFile;

    fn layout() -> Layout {
        let mics = vec![Vec3::new(-0.05, 0.0, 1.0), Vec3::new(0.05, 0.0, 1.0)];
        let a = MicArray::new("a0", mics, vec![0, 1]).unwrap();
        Layout::new(16000, 343.0, vec![a], vec![], None).unwrap()
    }

    fn track(label: Label, p: Vec3) -> TrackFile {
        TrackFile {
            label,
            position: p.into(),
            velocity: [0.0; 3],
            existence: 1.0,
            speaking: 1.0,
            covariance: None,
        }
    }

    fn source(id: &str, p: Vec3, active: Vec<(f64, f64)>) -> TruthSource {
        TruthSource {
            id: id.into(),
            signal: None,
            trajectory: vec![(0.0, p), (10.0, p)],
            active,
        }
    }

    #[test]
    fn offset_track_and_a_label_switch() {
        let p = Vec3::new(2.0, 0.0, 1.0);
        let q = Vec3::new(0.0, 2.0, 1.0);
        let sources = [source("s1", p, vec![(0.0, 10.0)]), source("s2", q, vec![])];
        let (l1, l2) = (Label::new(0, 0), Label::new(5, 0));
        // s1 is followed 0.2 m off by label 0.0 for 5 steps, then by 5.0; s2 is never tracked.
        let lines: Vec<TracksLine> = (0..10)
            .map(|k| TracksLine {
                t: k as f64 * 0.5,
                tracks: vec![track(
                    if k < 5 { l1 } else { l2 },
                    p + Vec3::new(0.0, 0.2, 0.0),
                )],
            })
            .collect();
        let cfg = EvalConfig::default();
        let r = score_tracks(&layout(), &sources, &lines, &cfg);
        assert_eq!(r.steps, 10);
        assert_eq!(r.labels, 2);
        assert_eq!(r.step_s, Some(0.5));
        let all = &r.all;
        // Every step: one pair at 0.2 m and one missed source: (0.2 + 1) / 2.
        assert!((all.ospa.total - 0.6).abs() < 1e-12, "{:?}", all.ospa);
        assert_eq!(all.position.switches, 1);
        assert_eq!(all.position.misses, 10);
        assert_eq!(all.position.false_positives, 0);
        assert!((all.position.motp.unwrap() - 0.2).abs() < 1e-12);
        assert!((all.position.mota.unwrap() - (1.0 - 11.0 / 20.0)).abs() < 1e-12);
        let s1 = &all.sources[0];
        assert_eq!(s1.labels_matched, 2);
        assert_eq!(s1.stream_labels, 2);
        assert_eq!(s1.initiation_delay_s, Some(0.0));
        assert_eq!(s1.active_labels[0].share, 0.5);
        // Seen from the array at the origin: atan(0.2 / 2) of azimuth error.
        let want = deg((0.2f64 / 2.0).atan());
        assert!((all.azimuth_error_deg.mean.unwrap() - want).abs() < 1e-9);
        assert_eq!(all.direction.switches, 1);
        // The silent source s2 is not audible: the audible figures only see s1.
        assert!((r.audible.ospa.total - 0.2).abs() < 1e-12);
        assert_eq!(r.audible.position.misses, 0);
        assert!(all.sources[1].onset_s.is_none());
    }

    /// Ten steps of 0.5 s of one track at `p` whose read at step k (time t) is `says(k, t)`
    /// (speaking 0.9, else 0.1).
    fn speaking_lines(p: Vec3, says: impl Fn(usize, f64) -> bool) -> Vec<TracksLine> {
        (0..10)
            .map(|k| {
                let t = k as f64 * 0.5;
                let mut tr = track(Label::new(0, 0), p);
                tr.speaking = if says(k, t) { 0.9 } else { 0.1 };
                TracksLine {
                    t,
                    tracks: vec![tr],
                }
            })
            .collect()
    }

    #[test]
    fn speaking_is_scored_against_the_matched_sources_talk_spurts() {
        let p = Vec3::new(2.0, 0.0, 1.0);
        // s1 talks during [1, 3); its track reads speaking from t = 1.5 to the end.
        let sources = [source("s1", p, vec![(1.0, 3.0)])];
        let lines = speaking_lines(p, |_, t| t >= 1.5);
        let r = score_tracks(&layout(), &sources, &lines, &EvalConfig::default());
        let sp = r.all.sources[0].speaking;
        // Talking at t = 1, 1.5, 2, 2.5 (read at 1.5-2.5); silent at 0, 0.5 and 3-4.5, of
        // which 3-4.5 read speaking.
        assert_eq!((sp.talking_steps, sp.detected), (4, 3));
        assert_eq!((sp.silent_steps, sp.false_alarms), (6, 4));
        assert_eq!(sp.recall(), Some(0.75));
        assert_eq!(sp.precision(), Some(3.0 / 7.0));
        // The read switches once (at 1.5), the talker twice (at 1 and 3).
        assert_eq!((sp.changes, sp.true_changes), (1, 2));
        assert_eq!(sp.change_ratio(), Some(0.5));
        assert_eq!(r.all.speaking, sp);
    }

    #[test]
    fn a_flickering_speaking_counts_every_switch() {
        let p = Vec3::new(2.0, 0.0, 1.0);
        // s1 talks throughout [1, 4); its track reads speaking on every other step while he talks.
        let sources = [source("s1", p, vec![(1.0, 4.0)])];
        let lines = speaking_lines(p, |k, t| (1.0..4.0).contains(&t) && k % 2 == 0);
        let r = score_tracks(&layout(), &sources, &lines, &EvalConfig::default());
        let sp = r.all.sources[0].speaking;
        // Talking at steps 2-7, read at 2, 4, 6: the read switches at 2, 3, 4, 5, 6 and 7, the
        // talker at 2 and 8.
        assert_eq!((sp.changes, sp.true_changes), (6, 2));
        assert_eq!(sp.change_ratio(), Some(3.0));
    }

    #[test]
    fn initiation_delay_counts_from_the_speech_onset() {
        let p = Vec3::new(1.0, 1.0, 1.0);
        let sources = [source("s1", p, vec![(1.0, 9.0)])];
        let lines: Vec<TracksLine> = (0..20)
            .map(|k| {
                let t = k as f64 * 0.25;
                TracksLine {
                    t,
                    tracks: if t >= 1.75 {
                        vec![track(Label::new(7, 0), p)]
                    } else {
                        vec![]
                    },
                }
            })
            .collect();
        let r = score_tracks(&layout(), &sources, &lines, &EvalConfig::default());
        let s = &r.all.sources[0];
        assert_eq!(s.onset_s, Some(1.0));
        assert!((s.initiation_delay_s.unwrap() - 0.75).abs() < 1e-12);
        assert_eq!(s.stream_labels, 1);
        // Audible from t = 1 on: 3 missed audible steps (1.0, 1.25, 1.5), none before.
        assert_eq!(r.audible.position.misses, 3);
        assert_eq!(r.all.position.misses, 7);
    }
}
