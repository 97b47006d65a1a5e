//! SVG figures of an evaluation (plotters, SVG backend only: no fonts or C libraries needed):
//! trajectories seen from above, azimuth over time from the first array, OSPA(2) over time.
//!
//! The output is deterministic: colours follow the sorted order of sources and labels.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use plotters::prelude::*;

use crate::geometry::{Vec3, azimuth_of, deg};
use crate::label::Label;
use crate::scene::Scene;
use crate::scene::output::Output;

use super::{EvalError, EvalReport};

const SIZE: (u32, u32) = (900, 700);

/// Distinguishable colours for estimated labels, used in label order.
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(127, 127, 127),
];

/// Greys for the (dashed) truth, so estimated colours stay free for labels.
const TRUTH: [RGBColor; 3] = [
    RGBColor(0, 0, 0),
    RGBColor(90, 90, 90),
    RGBColor(150, 150, 150),
];

fn label_colour(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

fn draw_err<E: std::fmt::Display>(what: &str) -> impl Fn(E) -> EvalError + '_ {
    move |e| EvalError::Write(format!("cannot draw {what}: {e}"))
}

/// Estimated tracks by label: `(t, position)` samples in time order.
fn tracks_by_label(out: &Output) -> BTreeMap<Label, Vec<(f64, Vec3)>> {
    let mut by: BTreeMap<Label, Vec<(f64, Vec3)>> = BTreeMap::new();
    for line in out.tracks.iter().flatten() {
        for tr in &line.tracks {
            by.entry(tr.label)
                .or_default()
                .push((line.t, Vec3::from(tr.position)));
        }
    }
    by
}

/// Padded range covering `values` (or `fallback` when there are none).
fn span(values: impl Iterator<Item = f64>, fallback: Range<f64>) -> Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if lo > hi {
        return fallback;
    }
    let pad = ((hi - lo) * 0.05).max(0.1);
    lo - pad..hi + pad
}

/// Writes the figures into `dir` (created if needed) and returns the files written.
pub fn write_plots(
    scene: &Scene,
    out: &Output,
    report: &EvalReport,
    dir: &Path,
) -> Result<Vec<PathBuf>, EvalError> {
    std::fs::create_dir_all(dir)
        .map_err(|e| EvalError::Write(format!("{}: cannot create folder: {e}", dir.display())))?;
    let tracks = tracks_by_label(out);
    let mut written = Vec::new();
    let mut save = |name: &str, svg: String| -> Result<(), EvalError> {
        let path = dir.join(name);
        std::fs::write(&path, svg)
            .map_err(|e| EvalError::Write(format!("{}: cannot write: {e}", path.display())))?;
        written.push(path);
        Ok(())
    };
    save("trajectories.svg", trajectories(scene, &tracks)?)?;
    save("azimuth.svg", azimuth(scene, &tracks)?)?;
    if let Some(t) = &report.tracks {
        let series: Vec<(f64, f64)> = t.ospa2_over_time.iter().map(|v| (v.t, v.value)).collect();
        save(
            "ospa2.svg",
            ospa2(&series, report.config.ospa_cutoff_m, report.duration_s)?,
        )?;
    }
    Ok(written)
}

fn trajectories(
    scene: &Scene,
    tracks: &BTreeMap<Label, Vec<(f64, Vec3)>>,
) -> Result<String, EvalError> {
    let truth = scene.truth.as_ref().map_or(&[][..], |t| &t.sources[..]);
    let err = draw_err("the trajectory plot");
    let (xs, ys) = equal_aspect(plane_ranges(scene, tracks));
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(&err)?;
        let mut chart = ChartBuilder::on(&root)
            .caption("Trajectories seen from above", ("sans-serif", 22))
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(xs, ys)
            .map_err(&err)?;
        chart
            .configure_mesh()
            .x_desc("x (m)")
            .y_desc("y (m)")
            .draw()
            .map_err(&err)?;
        for (i, s) in truth.iter().enumerate() {
            let c = TRUTH[i % TRUTH.len()];
            let pts: Vec<(f64, f64)> = s.trajectory.iter().map(|(_, p)| (p.x, p.y)).collect();
            // A hollow circle marks where the source appears (all of a static source).
            let start = pts.first().copied();
            chart
                .draw_series(DashedLineSeries::new(pts, 6, 4, c.stroke_width(2)))
                .map_err(&err)?
                .label(format!("truth {}", s.id))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c));
            chart
                .draw_series(start.map(|p| Circle::new(p, 6, c.stroke_width(2))))
                .map_err(&err)?;
        }
        for (i, (label, pts)) in tracks.iter().enumerate() {
            let c = label_colour(i);
            let xy: Vec<(f64, f64)> = pts.iter().map(|(_, p)| (p.x, p.y)).collect();
            chart
                .draw_series(LineSeries::new(xy.clone(), c.stroke_width(2)))
                .map_err(&err)?
                .label(format!("track {label}"))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c));
            chart
                .draw_series(xy.into_iter().map(|p| Circle::new(p, 2, c.filled())))
                .map_err(&err)?;
        }
        let arrays: Vec<(f64, f64)> = scene
            .layout
            .arrays
            .iter()
            .map(|a| (a.centroid().x, a.centroid().y))
            .collect();
        chart
            .draw_series(
                arrays
                    .into_iter()
                    .map(|p| Cross::new(p, 6, BLACK.stroke_width(2))),
            )
            .map_err(&err)?
            .label("microphone array")
            .legend(|(x, y)| Cross::new((x + 10, y), 6, BLACK.stroke_width(2)));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(&err)?;
        root.present().map_err(&err)?;
    }
    Ok(svg)
}

/// x and y ranges of the trajectory plot: the region, else what there is to draw.
fn plane_ranges(
    scene: &Scene,
    tracks: &BTreeMap<Label, Vec<(f64, Vec3)>>,
) -> (Range<f64>, Range<f64>) {
    let truth = scene.truth.as_ref().map_or(&[][..], |t| &t.sources[..]);
    match scene.layout.region {
        Some(r) => (r.min.x..r.max.x, r.min.y..r.max.y),
        None => {
            let pts = || {
                truth
                    .iter()
                    .flat_map(|s| s.trajectory.iter().map(|p| p.1))
                    .chain(scene.layout.arrays.iter().map(|a| a.centroid()))
                    .chain(tracks.values().flat_map(|v| v.iter().map(|p| p.1)))
            };
            (
                span(pts().map(|p| p.x), -1.0..1.0),
                span(pts().map(|p| p.y), -1.0..1.0),
            )
        }
    }
}

/// Widens the shorter of two ranges so that a metre is as long on both axes of the plot area.
fn equal_aspect((xs, ys): (Range<f64>, Range<f64>)) -> (Range<f64>, Range<f64>) {
    // Plot area left by the caption, margins and label areas of the trajectory chart.
    let (w, h) = (f64::from(SIZE.0) - 80.0, f64::from(SIZE.1) - 110.0);
    let (dx, dy) = (xs.end - xs.start, ys.end - ys.start);
    if dx / dy > w / h {
        let pad = 0.5 * (dx * h / w - dy);
        (xs, ys.start - pad..ys.end + pad)
    } else {
        let pad = 0.5 * (dy * w / h - dx);
        (xs.start - pad..xs.end + pad, ys)
    }
}

/// Splits a series of angles (deg) where it wraps around +-180 so lines do not cross the plot.
fn unwrapped_segments(points: &[(f64, f64)]) -> Vec<Vec<(f64, f64)>> {
    let mut segs: Vec<Vec<(f64, f64)>> = Vec::new();
    for &p in points {
        match segs.last_mut() {
            Some(seg) if seg.last().is_some_and(|q| (p.1 - q.1).abs() < 180.0) => seg.push(p),
            _ => segs.push(vec![p]),
        }
    }
    segs
}

fn azimuth(scene: &Scene, tracks: &BTreeMap<Label, Vec<(f64, Vec3)>>) -> Result<String, EvalError> {
    let truth = scene.truth.as_ref().map_or(&[][..], |t| &t.sources[..]);
    let err = draw_err("the azimuth plot");
    let origin = scene
        .layout
        .arrays
        .first()
        .map_or(Vec3::zeros(), |a| a.centroid());
    let az = |p: &Vec3| deg(azimuth_of(&(p - origin)));
    let duration = scene.duration().max(
        tracks
            .values()
            .flat_map(|v| v.iter().map(|p| p.0))
            .fold(0.0, f64::max),
    );
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(&err)?;
        let first = scene.layout.arrays.first().map_or("-", |a| a.id.as_str());
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("Azimuth seen from array {first}"),
                ("sans-serif", 22),
            )
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..duration.max(1e-3), -180.0..180.0)
            .map_err(&err)?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc("azimuth (deg)")
            .draw()
            .map_err(&err)?;
        for (i, s) in truth.iter().enumerate() {
            let c = TRUTH[i % TRUTH.len()];
            let pts: Vec<(f64, f64)> = s.trajectory.iter().map(|(t, p)| (*t, az(p))).collect();
            for (k, seg) in unwrapped_segments(&pts).into_iter().enumerate() {
                let drawn = chart
                    .draw_series(DashedLineSeries::new(seg, 6, 4, c.stroke_width(2)))
                    .map_err(&err)?;
                if k == 0 {
                    drawn
                        .label(format!("truth {}", s.id))
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c));
                }
            }
        }
        for (i, (label, pts)) in tracks.iter().enumerate() {
            let c = label_colour(i);
            chart
                .draw_series(
                    pts.iter()
                        .map(|(t, p)| Circle::new((*t, az(p)), 2, c.filled())),
                )
                .map_err(&err)?
                .label(format!("track {label}"))
                .legend(move |(x, y)| Circle::new((x + 10, y), 3, c.filled()));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(&err)?;
        root.present().map_err(&err)?;
    }
    Ok(svg)
}

fn ospa2(series: &[(f64, f64)], cutoff: f64, duration: f64) -> Result<String, EvalError> {
    let err = draw_err("the OSPA(2) plot");
    let t_end = series
        .iter()
        .map(|p| p.0)
        .fold(duration, f64::max)
        .max(1e-3);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (SIZE.0, SIZE.1 / 2)).into_drawing_area();
        root.fill(&WHITE).map_err(&err)?;
        let mut chart = ChartBuilder::on(&root)
            .caption("OSPA(2) over time", ("sans-serif", 22))
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..t_end, 0.0..cutoff * 1.05)
            .map_err(&err)?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc("OSPA(2) (m)")
            .draw()
            .map_err(&err)?;
        chart
            .draw_series(LineSeries::new(
                series.iter().copied(),
                label_colour(0).stroke_width(2),
            ))
            .map_err(&err)?;
        root.present().map_err(&err)?;
    }
    Ok(svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_aspect_widens_the_short_side() {
        let (xs, ys) = equal_aspect((0.0..1.0, 0.0..10.0));
        assert_eq!(ys, 0.0..10.0);
        let ratio = (xs.end - xs.start) / (ys.end - ys.start);
        let want = (f64::from(SIZE.0) - 80.0) / (f64::from(SIZE.1) - 110.0);
        assert!((ratio - want).abs() < 1e-12);
        assert!((xs.start + xs.end - 1.0).abs() < 1e-12);
    }

    #[test]
    fn wrapping_angles_split_the_line() {
        let segs = unwrapped_segments(&[(0.0, 170.0), (1.0, 179.0), (2.0, -179.0), (3.0, -170.0)]);
        assert_eq!(segs.len(), 2);
        assert_eq!(segs[1], vec![(2.0, -179.0), (3.0, -170.0)]);
    }

    #[test]
    fn ospa2_plot_is_svg() {
        let svg = ospa2(&[(0.0, 0.2), (0.5, 0.4), (1.0, 0.1)], 1.0, 1.0).unwrap();
        assert!(svg.starts_with("<svg"), "{}", &svg[..40.min(svg.len())]);
        assert!(svg.trim_end().ends_with("</svg>"));
        assert!(svg.contains("OSPA(2) over time"));
    }
}
