//! `avsep eval SCENE OUT`: scores an output folder against its scene's truth, prints the tables,
//! and optionally writes the full report as JSON and SVG plots.

use std::path::{Path, PathBuf};

use clap::Args;

use crate::eval::{EvalConfig, EvalError, evaluate, plots::write_plots};
use crate::scene::Scene;
use crate::scene::output::Output;

use super::CliError;

/// Arguments of `avsep eval`.
#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Scene folder (must carry truth).
    pub scene: PathBuf,
    /// Output folder written by `avsep process` (tracks.jsonl, measurements.jsonl, audio/).
    pub out: PathBuf,
    /// Write the full report as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write SVG plots (trajectories, azimuth, OSPA(2)) into this folder.
    #[arg(long, value_name = "DIR")]
    pub plots: Option<PathBuf>,
    /// Evaluation settings (JSON, or TOML by extension) merged over the defaults.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// CLEAR MOT / IDF1 distance gate in metres, where HOTA's similarity reaches 0 (overrides
    /// the settings file).
    #[arg(long, value_name = "M")]
    pub gate: Option<f64>,
}

fn eval_error(e: EvalError) -> CliError {
    if e.is_input() {
        CliError::input(e)
    } else {
        CliError::runtime(e)
    }
}

/// Reads a settings file: TOML when it ends in `.toml`, JSON otherwise.
fn load_config(path: &Path) -> Result<EvalConfig, CliError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| CliError::input(format!("{}: cannot read: {e}", path.display())))?;
    let parsed = if path.extension().and_then(|e| e.to_str()) == Some("toml") {
        toml::from_str(&text).map_err(|e| e.to_string())
    } else {
        serde_json::from_str(&text).map_err(|e| e.to_string())
    };
    parsed.map_err(|e| CliError::input(format!("{}: {e}", path.display())))
}

/// Runs the command.
pub fn run(args: EvalArgs) -> Result<(), CliError> {
    let mut cfg = match &args.config {
        Some(p) => load_config(p)?,
        None => EvalConfig::default(),
    };
    if let Some(g) = args.gate {
        cfg.gate_m = g;
    }
    let scene = Scene::load(&args.scene)?;
    if scene.truth.is_none() {
        return Err(eval_error(EvalError::NoTruth(
            args.scene.display().to_string(),
        )));
    }
    let out = Output::load(&args.out, &scene.layout)?;
    let report = evaluate(&scene, &out, &cfg).map_err(eval_error)?;
    print!("{report}");
    if let Some(path) = &args.json {
        crate::scene::write_json(path, &report).map_err(CliError::runtime)?;
    }
    if let Some(dir) = &args.plots {
        let files = write_plots(&scene, &out, &report, dir).map_err(eval_error)?;
        for f in files {
            eprintln!("wrote {}", f.display());
        }
    }
    Ok(())
}
