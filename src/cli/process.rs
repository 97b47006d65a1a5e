//! `avsep process SCENE --out DIR`: the pipeline offline on a scene folder.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

use super::{CliError, Progress};
use crate::pipeline::offline::{OfflineOptions, ProcessError, process_scene};
use crate::pipeline::{PipelineConfig, SizeBounds};
use crate::scene::Scene;
use crate::separate::PitchPart;

/// Arguments of `avsep process`.
#[derive(Debug, Args)]
pub struct ProcessArgs {
    /// Scene folder (scene.json and the files it names).
    pub scene: PathBuf,
    /// Output folder (created if needed).
    #[arg(long)]
    pub out: PathBuf,
    /// Pipeline settings as TOML or JSON; absent fields keep their defaults (see `avsep config --defaults`).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Seed of the run's random numbers (overrides the configuration).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Steer the separator with the scene's true trajectories instead of the tracker.
    #[arg(long)]
    pub oracle_tracks: bool,
    /// Lift the server's default size limits (microphones, the span of their pairs, analysis
    /// frames, separated labels), which a scene or settings otherwise must pass before anything
    /// is sized from them: a layout past them can take gigabytes.
    #[arg(long)]
    pub no_limits: bool,
    /// With --oracle-tracks: give the harmonic grouping each true source's pitch (read from its
    /// truth signal) instead of estimating it, to measure the grouping with the right pitch.
    /// `--oracle-pitch=f0` hands over the F0 only (the voicing is the comb's there, through the
    /// activity gate); `--oracle-pitch=voicing` the voicing only (the grouping reads the F0).
    #[arg(
        long,
        requires = "oracle_tracks",
        value_name = "PART",
        num_args = 0..=1,
        require_equals = true,
        default_missing_value = "both"
    )]
    pub oracle_pitch: Option<OraclePitchArg>,
    /// With --oracle-tracks: write as each label's audio the ideal ratio mask of its true source
    /// on the reference microphone (from the truth images) instead of the separator's output:
    /// the ceiling of a single-channel mask, to measure the separator against.
    #[arg(long, requires = "oracle_tracks")]
    pub oracle_mask: bool,
    /// Print the run summary as JSON instead of a short report.
    #[arg(long)]
    pub json: bool,
}

/// The part of the true pitch `--oracle-pitch` hands over.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OraclePitchArg {
    /// F0 and voicing.
    Both,
    /// The F0 only.
    F0,
    /// The voicing only.
    Voicing,
}

impl From<OraclePitchArg> for PitchPart {
    fn from(a: OraclePitchArg) -> Self {
        match a {
            OraclePitchArg::Both => Self::Both,
            OraclePitchArg::F0 => Self::F0,
            OraclePitchArg::Voicing => Self::Voicing,
        }
    }
}

/// Reads a pipeline configuration file, naming the file and field on error.
pub fn load_config(path: &std::path::Path) -> Result<PipelineConfig, CliError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| CliError::input(format!("{}: cannot read: {e}", path.display())))?;
    PipelineConfig::parse(&text).map_err(|e| {
        let field = if e.field.is_empty() {
            String::new()
        } else {
            format!("field `{}`: ", e.field)
        };
        CliError::input(format!("{}: {field}{}", path.display(), e.message))
    })
}

/// Runs the command.
pub fn run(args: ProcessArgs) -> Result<(), CliError> {
    let mut cfg = match &args.config {
        Some(p) => load_config(p)?,
        None => PipelineConfig::default(),
    };
    if args.seed.is_some() {
        cfg.seed = args.seed;
    }
    let scene = Scene::load(&args.scene)?;
    let bar = Progress::new(1000, "processing");
    let summary = process_scene(
        &scene,
        cfg,
        &args.out,
        OfflineOptions {
            oracle_tracks: args.oracle_tracks,
            oracle_pitch: args.oracle_pitch.map(PitchPart::from),
            oracle_mask: args.oracle_mask,
            bounds: (!args.no_limits).then(SizeBounds::default),
            ..Default::default()
        },
        &|f| bar.set((f * 1000.0) as u64),
    )
    .map_err(|e| match e {
        ProcessError::Files(e) => CliError::input(e),
        ProcessError::Config(e) => CliError::input(format!("configuration: {e}")),
        ProcessError::Scene(m) => CliError::input(m),
        ProcessError::TooLarge(e) => CliError::input(format!(
            "{}: {e} (the server's default limits; --no-limits lifts them)",
            args.scene.display()
        )),
    })?;
    bar.finish();
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&summary).map_err(CliError::runtime)?
        );
    } else {
        println!(
            "processed {:.2} s of input in {:.2} s (real-time factor {:.3}); {} tracks, {} speech segments -> {}",
            summary.duration_s,
            summary.processing_s,
            summary.real_time_factor,
            summary.tracks.len(),
            summary.speech_segments,
            args.out.display()
        );
        for (code, n) in &summary.warnings {
            println!("warning {code}: {n} times");
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::{Cli, Command};
    use super::*;
    use clap::Parser;

    fn oracle_pitch(args: &[&str]) -> Result<Option<PitchPart>, clap::Error> {
        let cli = Cli::try_parse_from(
            ["avsep", "process", "scene", "--out", "out"]
                .iter()
                .chain(args),
        )?;
        match cli.command {
            Command::Process(p) => Ok(p.oracle_pitch.map(PitchPart::from)),
            other => panic!("parsed as {other:?}"),
        }
    }

    /// A bare `--oracle-pitch` hands over the whole pitch; `=f0` and `=voicing` a part; it needs
    /// oracle tracks, and a value needs the `=` so it never swallows the next argument.
    #[test]
    fn oracle_pitch_takes_an_optional_part() {
        let tracks = "--oracle-tracks";
        assert_eq!(oracle_pitch(&[tracks]).ok(), Some(None));
        assert_eq!(
            oracle_pitch(&[tracks, "--oracle-pitch"]).ok(),
            Some(Some(PitchPart::Both))
        );
        assert_eq!(
            oracle_pitch(&[tracks, "--oracle-pitch=f0"]).ok(),
            Some(Some(PitchPart::F0))
        );
        assert_eq!(
            oracle_pitch(&["--oracle-pitch=voicing", tracks]).ok(),
            Some(Some(PitchPart::Voicing))
        );
        assert!(oracle_pitch(&["--oracle-pitch"]).is_err());
        assert!(oracle_pitch(&[tracks, "--oracle-pitch=pitch"]).is_err());
        assert!(oracle_pitch(&[tracks, "--oracle-pitch", "voicing"]).is_err());
    }
}
