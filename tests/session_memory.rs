//! What a session's pipeline takes in memory, measured by counting this thread's allocations:
//! the everyday session stays a few megabytes, the largest one the default size bounds admit
//! stays within the figure `limits` documents, and the footprint the server admits sessions by
//! (`pipeline::footprint`, computed without building anything) never undercuts what a pipeline
//! and its separator's streams hold.

use std::alloc::{GlobalAlloc, Layout as AllocLayout, System};
use std::cell::Cell;

use avsep::dsp::{Complex, MultiSpectrum};
use avsep::geometry::{Layout, MicArray, Vec3};
use avsep::label::Label;
use avsep::pipeline::{Pipeline, PipelineConfig, SizeBounds, footprint};
use avsep::separate::BeamformerKind;
use avsep::separate::{Separator, Target};

/// The system allocator, counting each thread's live bytes (tests run on parallel threads).
struct Counting;

thread_local! {
    static LIVE: Cell<isize> = const { Cell::new(0) };
}

fn count(delta: isize) {
    // During thread teardown the counter may be gone; such bytes belong to no measurement.
    let _ = LIVE.try_with(|c| c.set(c.get() + delta));
}

// SAFETY: every call forwards to the system allocator with the same arguments; the counter is
// a const-initialised thread-local that never allocates.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: AllocLayout) -> *mut u8 {
        count(layout.size() as isize);
        // SAFETY: the caller's contract, forwarded.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: AllocLayout) -> *mut u8 {
        count(layout.size() as isize);
        // SAFETY: the caller's contract, forwarded.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: AllocLayout) {
        count(-(layout.size() as isize));
        // SAFETY: the caller's contract, forwarded.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: AllocLayout, new_size: usize) -> *mut u8 {
        count(new_size as isize - layout.size() as isize);
        // SAFETY: the caller's contract, forwarded.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// What `f` leaves allocated on this thread (MB), with its result.
fn kept_by<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let before = LIVE.with(Cell::get);
    let out = f();
    let after = LIVE.with(Cell::get);
    (out, (after - before) as f64 / 1e6)
}

/// A circular array of `m` microphones of radius `r` at 1 m height.
fn circle(m: usize, r: f64) -> Layout {
    one_array(
        (0..m)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / m as f64;
                Vec3::new(3.0 + r * a.cos(), 2.5 + r * a.sin(), 1.0)
            })
            .collect(),
    )
}

/// A line of `m` microphones `d` apart along x at 1 m height.
fn line(m: usize, d: f64) -> Layout {
    one_array(
        (0..m)
            .map(|i| Vec3::new(3.0 + d * i as f64, 2.5, 1.0))
            .collect(),
    )
}

/// A layout of one array whose microphones each carry an audio channel.
fn one_array(mics: Vec<Vec3>) -> Layout {
    let channels = (0..mics.len()).collect();
    let array = MicArray::new("a0", mics, channels).expect("array");
    Layout::new(16_000, 343.0, vec![array], vec![], None).expect("layout")
}

#[test]
fn an_everyday_session_takes_a_few_megabytes() {
    // The uca8 room's array: 8 microphones on a 5 cm radius, default settings.
    let (pipeline, mb) = kept_by(|| Pipeline::new(circle(8, 0.05), PipelineConfig::default(), 1));
    assert!(pipeline.is_ok());
    assert!((1.0..8.0).contains(&mb), "{mb:.1} MB");
}

/// The largest session the default bounds admit: 64 microphones as wide as the span of their
/// pairs allows, both analysis frames at the bound and every stream the cap allows. Its
/// pipeline and its separator's streams stay within the figure `limits.max_streams` and
/// `limits.max_frame` document (about 0.3 GB built, 1.1 GB more at 16 streams).
#[test]
fn the_largest_session_the_default_bounds_admit_is_bounded() {
    let bounds = SizeBounds::default();
    let layout = circle(64, 0.095);
    bounds.check_layout(&layout).expect("within the bounds");
    assert!(bounds.check_layout(&circle(64, 0.1)).is_err(), "the widest");
    let mut cfg = PipelineConfig::default();
    cfg.localize.frame = bounds.max_frame;
    (cfg.separate.frame, cfg.separate.hop) = (bounds.max_frame, bounds.max_frame / 2);
    cfg.separate.lifecycle.max_streams = bounds.max_streams;
    bounds.check_settings(&cfg).expect("within the bounds");

    let (pipeline, built) = kept_by(|| Pipeline::new(layout.clone(), cfg.clone(), 1));
    assert!(pipeline.is_ok());
    drop(pipeline);
    assert!((100.0..400.0).contains(&built), "built {built:.0} MB");

    // The streams: one frame with every label the cap allows (the state is sized at birth).
    let (separator, _) = kept_by(|| Separator::new(&layout, &cfg.separate));
    let mut separator = separator.expect("separator");
    let bins = bounds.max_frame / 2 + 1;
    let mut spectra = MultiSpectrum::zeros(64, bins);
    for c in 0..64 {
        for (k, v) in spectra.channel_mut(c).iter_mut().enumerate() {
            *v = Complex::new(((k * 7 + c) % 5) as f64 - 2.0, 0.5);
        }
    }
    let (out, streams) = kept_by(|| separator.process(&spectra, &targets(bounds.max_streams + 4)));
    assert_eq!(out.len(), bounds.max_streams, "the cap holds");
    let bound = footprint(&layout, &cfg).unwrap() as f64 / 1e6;
    assert!(
        (built + streams..1.3 * (built + streams)).contains(&bound),
        "bound {bound:.0} MB against {:.0} MB held",
        built + streams
    );
    let per_stream = streams / bounds.max_streams as f64;
    let c = avsep::server::ServerConfig::default();
    let session = avsep::server::budget::session_bound(&c.limits, &c.execution, &layout, &cfg)
        .unwrap() as f64
        / 1e6;
    println!(
        "built {built:.0} MB; {streams:.0} MB for {} streams; bound {bound:.0} MB, {session:.0} MB \
         with the server's buffers",
        out.len()
    );
    assert!((bound..bound + 100.0).contains(&session), "{session:.0} MB");
    assert!(
        (10.0..100.0).contains(&per_stream),
        "{per_stream:.1} MB a stream"
    );
    assert!(built + streams < 1600.0, "{:.0} MB", built + streams);
}

/// The targets of `n` labels on a circle around the arrays.
fn targets(n: usize) -> Vec<Target> {
    (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / 20.0;
            Target {
                label: Label::new(1, i as u32),
                position: Vec3::new(3.0 + 1.5 * a.cos(), 2.5 + 1.5 * a.sin(), 1.5),
                direction_only: false,
                speaking: 1.0,
                activity: 1.0,
                pitch: None,
            }
        })
        .collect()
}

/// Over arrays of 2 to 32 microphones, both shapes, frames, beamformers and stream caps: the
/// footprint is at least what the built pipeline and its separator at the cap hold, and not
/// wildly more (a bound too loose would refuse sessions a server could hold).
#[test]
fn the_footprint_never_undercuts_what_a_pipeline_holds() {
    let kinds = [
        BeamformerKind::Gsc,
        BeamformerKind::Mvdr,
        BeamformerKind::NullSteering,
    ];
    let cases = [
        (line(2, 0.2), 2048, 1024, 0, 4),
        (line(6, 0.04), 2048, 1024, 0, 16),
        (line(16, 0.05), 1024, 2048, 1, 8),
        (circle(4, 0.05), 4096, 1024, 2, 16),
        (circle(8, 0.05), 2048, 1024, 0, 16),
        (circle(8, 0.05), 2048, 1024, 0, 3),
        (circle(8, 1.0), 1024, 512, 1, 12),
        (circle(16, 0.1), 2048, 4096, 0, 16),
        (circle(32, 0.1), 2048, 1024, 0, 6),
    ];
    for (layout, lf, sf, kind, cap) in cases {
        let mut cfg = PipelineConfig::default();
        cfg.localize.frame = lf;
        (cfg.separate.frame, cfg.separate.hop) = (sf, sf / 2);
        cfg.separate.beamformer = kinds[kind];
        cfg.separate.lifecycle.max_streams = cap;
        let (pipeline, built) = kept_by(|| Pipeline::new(layout.clone(), cfg.clone(), 1));
        assert!(pipeline.is_ok());
        let m = layout.channel_count();
        let (separator, _) = kept_by(|| Separator::new(&layout, &cfg.separate));
        let mut separator = separator.expect("separator");
        let spectra = MultiSpectrum::zeros(m, sf / 2 + 1);
        let (out, streams) = kept_by(|| separator.process(&spectra, &targets(cap + 2)));
        assert_eq!(out.len(), cap);
        let held = built + streams;
        let bound = footprint(&layout, &cfg).unwrap() as f64 / 1e6;
        let case = format!(
            "{m} microphones, frames {lf}/{sf}, {:?}, {cap} streams",
            kinds[kind]
        );
        println!("{case}: {held:.2} MB held, bound {bound:.2} MB");
        assert!(
            bound >= held,
            "{case}: bound {bound:.2} MB under {held:.2} MB held"
        );
        assert!(
            bound <= 2.0 * held + 4.0,
            "{case}: bound {bound:.2} MB, {held:.2} MB held"
        );
    }
}
