//! The pipeline's `speaking` against a simulated room's talk spurts: the offline pipeline runs on
//! a generated `uca8` scene (two talkers, RT60 0.3 s) and `avsep eval`'s scoring reads its tracks.

use avsep::eval::{EvalConfig, evaluate};
use avsep::pipeline::PipelineConfig;
use avsep::pipeline::offline::{OfflineOptions, process_scene};
use avsep::scene::output::Output;
use avsep::scene::sim::{PresetOptions, SimConfig, simulate};

/// Precision, recall and changes per true change of `speaking` on one seed.
fn speaking_on(seed: u64) -> (f64, f64, f64) {
    let opts = PresetOptions {
        duration_s: Some(10.0),
        speakers: Some(2),
        rt60_s: Some(0.3),
        snr_db: Some(25.0),
    };
    let cfg = SimConfig::preset("uca8", &opts, seed).expect("preset");
    let scene = simulate(&cfg, seed).expect("simulates");
    let out = tempfile::tempdir().expect("temp dir");
    let pipeline = PipelineConfig {
        separation: false,
        ..PipelineConfig::default()
    };
    process_scene(
        &scene,
        pipeline,
        out.path(),
        OfflineOptions::default(),
        &|_| {},
    )
    .expect("processes");
    let output = Output::load(out.path(), &scene.layout).expect("output loads");
    let report = evaluate(&scene, &output, &EvalConfig::default()).expect("evaluates");
    let sp = report.tracks.expect("tracks scored").all.speaking;
    (
        sp.precision().expect("some steps read speaking"),
        sp.recall().expect("the talkers talk"),
        sp.change_ratio().expect("the talkers pause"),
    )
}

/// Two talkers who take turns and overlap: their tracks read speaking while they talk and
/// silent while they pause, without flickering in between. Measured on the landing that
/// filtered the probe's reading, seeds 1 / 2: precision 0.93 / 0.93, recall 0.91 / 0.94, 1.25 /
/// 1.43 changes per true change; thresholding the reading (the landing before) gave 0.98 /
/// 0.97, 0.78 / 0.78 and 2.83 / 2.86.
#[test]
fn speaking_follows_the_talk_spurts_without_flicker() {
    for seed in [1, 2] {
        let (precision, recall, changes) = speaking_on(seed);
        eprintln!("seed {seed}: precision {precision:.2} recall {recall:.2} changes {changes:.2}");
        assert!(precision >= 0.85, "seed {seed}: precision {precision:.2}");
        assert!(recall >= 0.8, "seed {seed}: recall {recall:.2}");
        assert!(
            changes <= 2.0,
            "seed {seed}: {changes:.2} changes per true change"
        );
    }
}
