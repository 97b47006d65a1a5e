//! `avsep simulate`: writes a scene folder with known truth, from a preset or a configuration.

use std::path::{Path, PathBuf};

use clap::Args;

use super::{CliError, Progress};
use crate::scene::sim::{self, PRESETS, PresetOptions, SimConfig, SimError};

/// Arguments of `avsep simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Preset to simulate (see --list-presets).
    #[arg(long, conflicts_with = "config")]
    pub preset: Option<String>,
    /// A complete simulator configuration instead of a preset: JSON, or TOML when the file name
    /// ends in .toml (print one with --print-config).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Seed of every random choice: the same seed gives the same scene, bit for bit.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Scene folder to write (created if needed).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Scene length in seconds (overrides the preset's).
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub duration: Option<f64>,
    /// Number of talkers (presets only).
    #[arg(long, value_name = "N")]
    pub speakers: Option<usize>,
    /// Reverberation time T30 in seconds.
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub rt60: Option<f64>,
    /// Sensor-noise SNR in dB (speech power at the reference microphone while anyone talks).
    #[arg(long, value_name = "DB", allow_negative_numbers = true)]
    pub snr: Option<f64>,
    /// Folder of WAV files (one per talker, name order) to use as speech instead of synthetic
    /// voices; resampled and mixed to mono as needed.
    #[arg(long, value_name = "DIR")]
    pub speech: Option<PathBuf>,
    /// List the presets and exit.
    #[arg(long)]
    pub list_presets: bool,
    /// Print the resolved configuration as JSON and exit without simulating.
    #[arg(long)]
    pub print_config: bool,
}

/// Runs the command.
pub fn run(args: SimulateArgs) -> Result<(), CliError> {
    if args.list_presets {
        for (name, about) in PRESETS {
            println!("{name:<14} {about}");
        }
        return Ok(());
    }
    let cfg = resolve(&args)?;
    if args.print_config {
        let text = serde_json::to_string_pretty(&cfg).map_err(CliError::runtime)?;
        println!("{text}");
        return Ok(());
    }
    let Some(out) = &args.out else {
        return Err(CliError::input("--out DIR is required to write the scene"));
    };
    let mut bar: Option<Progress> = None;
    let scene = sim::simulate_with_progress(&cfg, args.seed, &mut |done, total| {
        bar.get_or_insert_with(|| Progress::new(total as u64, "simulating"))
            .set(done as u64);
    })
    .map_err(sim_error)?;
    if let Some(b) = &bar {
        b.finish();
    }
    scene
        .save(out)
        .map_err(|e| CliError::runtime(format!("cannot write the scene: {e}")))?;
    let frames = scene.detections.len();
    let talkers = scene.truth.as_ref().map_or(0, |t| t.sources.len());
    println!(
        "wrote {} ({:.1} s, {} channels, {} talkers, {} camera frames)",
        out.display(),
        scene.duration(),
        scene.layout.channel_count(),
        talkers,
        frames
    );
    Ok(())
}

fn sim_error(e: SimError) -> CliError {
    CliError::input(e)
}

/// The configuration the arguments ask for.
fn resolve(args: &SimulateArgs) -> Result<SimConfig, CliError> {
    let mut cfg = match (&args.preset, &args.config) {
        (Some(name), None) => {
            let opts = PresetOptions {
                duration_s: args.duration,
                speakers: args.speakers,
                rt60_s: args.rt60,
                snr_db: args.snr,
            };
            SimConfig::preset(name, &opts, args.seed).map_err(|e| match e {
                SimError::Config { field, message } => {
                    let flag = match field.as_str() {
                        "duration_s" => "--duration",
                        "speakers" => "--speakers",
                        "room.rt60_s" => "--rt60",
                        "noise.snr_db" => "--snr",
                        _ => "--preset",
                    };
                    CliError::input(format!("{flag}: {message}"))
                }
                other => sim_error(other),
            })?
        }
        (None, Some(path)) => {
            if args.speakers.is_some() {
                return Err(CliError::input(
                    "--speakers applies to presets; list the talkers in the configuration",
                ));
            }
            let mut cfg = read_config(path)?;
            if let Some(d) = args.duration {
                cfg.duration_s = d;
            }
            if let Some(r) = args.rt60 {
                cfg.room.rt60_s = r;
            }
            if let Some(s) = args.snr {
                cfg.noise.snr_db = s;
            }
            cfg
        }
        _ => {
            return Err(CliError::input(
                "give --preset NAME or --config FILE (see --list-presets)",
            ));
        }
    };
    if let Some(dir) = &args.speech {
        if !dir.exists() {
            return Err(CliError::input(format!(
                "--speech: {} does not exist",
                dir.display()
            )));
        }
        cfg.speech_dir = Some(dir.to_string_lossy().into_owned());
    }
    cfg.validate().map_err(sim_error)?;
    Ok(cfg)
}

/// Reads a configuration file: TOML by extension, JSON otherwise; errors name the field.
fn read_config(path: &Path) -> Result<SimConfig, CliError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| CliError::input(format!("{}: cannot read: {e}", path.display())))?;
    let is_toml = path
        .extension()
        .is_some_and(|e| e.to_string_lossy().eq_ignore_ascii_case("toml"));
    if is_toml {
        toml::from_str(&text).map_err(|e| CliError::input(format!("{}: {e}", path.display())))
    } else {
        let de = &mut serde_json::Deserializer::from_str(&text);
        serde_path_to_error::deserialize(de).map_err(|e| {
            CliError::input(format!("{}: {}: {}", path.display(), e.path(), e.inner()))
        })
    }
}
