//! The human-readable form of an [`EvalReport`]: plain text tables.

use std::fmt::{self, Display, Write};

use super::EvalReport;
use super::audio::AudioReport;
use super::bss_eval::BssFigures;
use super::measurements::MeasurementsReport;
use super::pitch::{FrameFigures, PitchFigures, PitchReport};
use super::stats::Summary;
use super::tracks::{MotFigures, TrackingFigures, TracksReport};

fn num(v: Option<f64>, decimals: usize) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.decimals$}"),
        _ => "-".to_string(),
    }
}

fn pct(v: Option<f64>) -> String {
    v.map_or("-".to_string(), |x| format!("{:.1}%", 100.0 * x))
}

fn mean_median(s: &Summary, decimals: usize) -> String {
    format!("{} / {}", num(s.mean, decimals), num(s.median, decimals))
}

fn bss(b: Option<BssFigures>) -> [String; 3] {
    [
        num(b.map(|b| b.sdr_db), 1),
        num(b.map(|b| b.sir_db), 1),
        num(b.map(|b| b.sar_db), 1),
    ]
}

fn measurements(out: &mut String, m: &MeasurementsReport, r: &EvalReport) -> fmt::Result {
    let c = &r.config;
    writeln!(
        out,
        "Measurements (OSPA c = {} m, p = {}; DOA tolerance {} deg)",
        c.ospa_cutoff_m, c.ospa_order, c.doa_tolerance_deg
    )?;
    writeln!(
        out,
        "  {:<8} {:>6} {:>7} {:>6} {:>6} {:>6} {:>6} | {:>6} {:>7} {:>8} {:>8} {:>7}",
        "array",
        "frames",
        "active",
        "cands",
        "OSPA",
        "loc",
        "card",
        "pairs",
        "in tol",
        "med deg",
        "mean deg",
        "false"
    )?;
    for a in &m.arrays {
        let p = a.points.as_ref();
        let d = a.doas.as_ref();
        writeln!(
            out,
            "  {:<8} {:>6} {:>7.2} {:>6} {:>6} {:>6} {:>6} | {:>6} {:>7} {:>8} {:>8} {:>7}",
            a.array,
            a.frames,
            a.mean_active_sources,
            num(p.map(|p| p.mean_candidates), 2),
            num(p.map(|p| p.ospa.total), 3),
            num(p.map(|p| p.ospa.localisation), 3),
            num(p.map(|p| p.ospa.cardinality), 3),
            d.map_or("-".into(), |d| d.pairs.to_string()),
            pct(d.and_then(|d| d.within_tolerance)),
            num(d.and_then(|d| d.error_deg.median), 2),
            num(d.and_then(|d| d.error_deg.mean), 2),
            pct(d.and_then(|d| d.false_candidate_rate)),
        )?;
    }
    Ok(())
}

fn mot_rows(f: &MotFigures) -> Vec<(String, String)> {
    vec![
        ("MOTA".into(), pct(f.mota)),
        ("MOTP".into(), num(f.motp, 3)),
        ("IDF1".into(), pct(f.idf1)),
        (
            "IDP / IDR".into(),
            format!("{} / {}", pct(f.idp), pct(f.idr)),
        ),
        ("HOTA".into(), pct(f.hota.map(|h| h.hota))),
        (
            "  DetA / AssA / LocA".into(),
            format!(
                "{} / {} / {}",
                pct(f.hota.map(|h| h.deta)),
                pct(f.hota.map(|h| h.assa)),
                pct(f.hota.map(|h| h.loca))
            ),
        ),
        ("ID switches".into(), f.switches.to_string()),
        (
            "FP / FN".into(),
            format!("{} / {}", f.false_positives, f.misses),
        ),
        ("fragmentations".into(), f.fragmentations.to_string()),
        (
            "MT / PT / ML".into(),
            format!(
                "{} / {} / {}",
                f.mostly_tracked, f.partially_tracked, f.mostly_lost
            ),
        ),
    ]
}

fn figure_rows(f: &TrackingFigures) -> Vec<(String, String)> {
    let mut rows = vec![
        (
            "truth / track pairs".into(),
            format!("{} / {}", f.truth_count, f.track_count),
        ),
        ("OSPA (m)".into(), num(Some(f.ospa.total), 3)),
        (
            "  loc / card".into(),
            format!(
                "{} / {}",
                num(Some(f.ospa.localisation), 3),
                num(Some(f.ospa.cardinality), 3)
            ),
        ),
        ("OSPA(2) (m)".into(), num(Some(f.ospa2.total), 3)),
        ("GOSPA (m)".into(), num(Some(f.gospa.total), 3)),
        (
            "  loc / missed / false".into(),
            format!(
                "{} / {} / {}",
                num(Some(f.gospa.localisation), 3),
                num(Some(f.gospa.missed), 3),
                num(Some(f.gospa.false_objects), 3)
            ),
        ),
    ];
    rows.extend(
        mot_rows(&f.position)
            .into_iter()
            .map(|(k, v)| (format!("3-D {k}"), v)),
    );
    rows.push((
        "azimuth err mean/med (deg)".into(),
        mean_median(&f.azimuth_error_deg, 2),
    ));
    for c in &f.pixel_error_px {
        rows.push((
            format!("{} err mean/med (px)", c.camera),
            mean_median(&c.error_px, 1),
        ));
    }
    rows.extend(
        mot_rows(&f.direction)
            .into_iter()
            .filter(|(k, _)| k != "MOTP")
            .map(|(k, v)| (format!("dir {k}"), v)),
    );
    rows.push((
        "dir err mean/med (deg)".into(),
        mean_median(&f.direction_error_deg, 2),
    ));
    rows.push((
        "speaking precision / recall".into(),
        format!(
            "{} / {}",
            num(f.speaking.precision(), 2),
            num(f.speaking.recall(), 2)
        ),
    ));
    rows.push((
        "speaking changes / true".into(),
        num(f.speaking.change_ratio(), 2),
    ));
    rows
}

fn tracks(out: &mut String, t: &TracksReport, r: &EvalReport) -> fmt::Result {
    let c = &r.config;
    writeln!(
        out,
        "Tracks ({} steps of {} s, {} labels; gate {} m, azimuth gate {} deg, OSPA(2) window {})",
        t.steps,
        num(t.step_s, 3),
        t.labels,
        c.gate_m,
        c.azimuth_gate_deg,
        c.ospa2_window_steps
    )?;
    writeln!(out, "  {:<30} {:>22} {:>22}", "", "all present", "audible")?;
    for ((k, a), (_, b)) in figure_rows(&t.all).into_iter().zip(figure_rows(&t.audible)) {
        writeln!(out, "  {k:<30} {a:>22} {b:>22}")?;
    }
    writeln!(
        out,
        "  {:<10} {:>8} {:>9} {:>9} {:>8} {:>7} {:>8}  active labels",
        "source", "onset s", "delay s", "dir del s", "matched", "labels", "streams"
    )?;
    for s in &t.all.sources {
        let shares: Vec<String> = s
            .active_labels
            .iter()
            .map(|l| format!("{} {:.0}%", l.label, 100.0 * l.share))
            .collect();
        writeln!(
            out,
            "  {:<10} {:>8} {:>9} {:>9} {:>8} {:>7} {:>8}  {}",
            s.id,
            num(s.onset_s, 2),
            num(s.initiation_delay_s, 2),
            num(s.direction_initiation_delay_s, 2),
            format!("{}/{}", s.matched_steps, s.steps),
            s.labels_matched,
            s.stream_labels,
            shares.join(", ")
        )?;
    }
    Ok(())
}

/// One row of the audio table: SI-SDR of the stream, the mixture and the improvement, then
/// BSS Eval of the same three, then the stream count.
fn audio_row(
    out: &mut String,
    id: &str,
    label: String,
    by: &str,
    si: [Option<f64>; 3],
    b: [Option<BssFigures>; 3],
    streams: String,
) -> fmt::Result {
    let [e, m, i] = b.map(bss);
    writeln!(
        out,
        "  {:<10} {:>7} {:>6} {:>7} {:>7} {:>7} | {:>6} {:>6} {:>6} | {:>6} {:>6} {:>6} | {:>6} {:>6} {:>6} {:>7}",
        id,
        label,
        by,
        num(si[0], 1),
        num(si[1], 1),
        num(si[2], 1),
        e[0],
        e[1],
        e[2],
        m[0],
        m[1],
        m[2],
        i[0],
        i[1],
        i[2],
        streams
    )
}

fn audio(out: &mut String, a: &AudioReport) -> fmt::Result {
    writeln!(
        out,
        "Audio (over active samples; BSS Eval v3 with {} taps; dB)",
        a.filter_taps
    )?;
    writeln!(
        out,
        "  {:<10} {:>7} {:>6} {:>7} {:>7} {:>7} | {:>6} {:>6} {:>6} | {:>6} {:>6} {:>6} | {:>6} {:>6} {:>6} {:>7}",
        "source",
        "label",
        "by",
        "SI-SDR",
        "mic",
        "impr",
        "SDR",
        "SIR",
        "SAR",
        "mSDR",
        "mSIR",
        "mSAR",
        "iSDR",
        "iSIR",
        "iSAR",
        "streams"
    )?;
    for s in &a.sources {
        let by = match s.mapped_by {
            Some(super::audio::MappedBy::Tracks) => "track",
            Some(super::audio::MappedBy::DirectionTracks) => "dir",
            Some(super::audio::MappedBy::SiSdr) => "sisdr",
            None => "-",
        };
        audio_row(
            out,
            &s.id,
            s.label.map_or("-".into(), |l| l.to_string()),
            by,
            [s.si_sdr_db, s.si_sdr_mixture_db, s.si_sdr_improvement_db],
            [s.bss, s.bss_mixture, s.bss_improvement],
            s.continuity.stream_labels.to_string(),
        )?;
    }
    let m = &a.mean;
    audio_row(
        out,
        "mean",
        String::new(),
        "",
        [m.si_sdr_db, m.si_sdr_mixture_db, m.si_sdr_improvement_db],
        [m.bss, m.bss_mixture, m.bss_improvement],
        num(m.stream_labels, 2),
    )?;
    strays(out, a)
}

/// The blocks each source's own stream does not carry, and which stream does.
fn strays(out: &mut String, a: &AudioReport) -> fmt::Result {
    if a.sources.iter().all(|s| s.continuity.strays.is_empty()) {
        return Ok(());
    }
    writeln!(
        out,
        "  Blocks off the source's own stream (share of the block's source energy each stream \
         projects):"
    )?;
    for s in &a.sources {
        let own = s.label.map_or("-".into(), |l| l.to_string());
        for b in &s.continuity.strays {
            let on = b.label.map_or("no stream".into(), |l| format!("on {l}"));
            let span = format!("{:.2}-{:.2} s", b.start_s, b.end_s);
            writeln!(
                out,
                "    {:<10} {:>16}  {:<12} {:>7}   own {} {:>7}",
                s.id,
                span,
                on,
                pct(b.carried),
                own,
                pct(b.own)
            )?;
        }
    }
    Ok(())
}

fn pitch_row(out: &mut String, id: &str, label: &str, f: &FrameFigures) -> fmt::Result {
    let frames = format!("{}/{}", f.voiced_frames, f.frames);
    figures_row(out, id, label, &frames, &f.figures)
}

fn figures_row(
    out: &mut String,
    id: &str,
    label: &str,
    frames: &str,
    f: &PitchFigures,
) -> fmt::Result {
    writeln!(
        out,
        "  {:<10} {:>7} {:>13} {:>8} {:>8} {:>8} {:>8}",
        id,
        label,
        frames,
        pct(f.voiced_recall),
        pct(f.false_voicing),
        pct(f.f0_within_tolerance),
        pct(f.gross_error)
    )
}

fn pitch(out: &mut String, p: &PitchReport) -> fmt::Result {
    writeln!(
        out,
        "Separator pitch (against YIN on each source; F0 right within {:.0}%, gross over {:.0}%)",
        100.0 * p.tolerance,
        100.0 * super::pitch::GROSS_ERROR
    )?;
    writeln!(
        out,
        "  {:<10} {:>7} {:>13} {:>8} {:>8} {:>8} {:>8}",
        "source", "label", "voiced/frames", "recall", "false", "F0 ok", "gross"
    )?;
    for s in &p.sources {
        pitch_row(out, &s.id, &s.label.to_string(), &s.whole)?;
    }
    figures_row(out, "mean", "", "", &p.mean)?;
    let Some(pooled) = &p.off_stream else {
        return Ok(());
    };
    writeln!(out, "  In the blocks off the source's own stream:")?;
    for s in &p.sources {
        if let Some(o) = &s.off_stream {
            pitch_row(out, &s.id, &s.label.to_string(), o)?;
        }
    }
    pitch_row(out, "all", "", pooled)
}

impl Display for EvalReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut out = String::new();
        writeln!(
            out,
            "avsep eval: {} against {} ({:.1} s, {} true sources)",
            self.output, self.scene, self.duration_s, self.sources
        )?;
        if let Some(m) = &self.measurements {
            writeln!(out)?;
            measurements(&mut out, m, self)?;
        }
        if let Some(t) = &self.tracks {
            writeln!(out)?;
            tracks(&mut out, t, self)?;
        }
        if let Some(a) = &self.audio {
            writeln!(out)?;
            audio(&mut out, a)?;
        }
        if let Some(p) = &self.pitch {
            writeln!(out)?;
            pitch(&mut out, p)?;
        }
        if !self.notes.is_empty() {
            writeln!(out)?;
            for n in &self.notes {
                writeln!(out, "note: {n}")?;
            }
        }
        f.write_str(&out)
    }
}
