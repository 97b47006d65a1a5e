//! `avsep config`: prints the pipeline settings, documented.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

use super::CliError;
use super::process::load_config;
use crate::pipeline::PipelineConfig;
use crate::pipeline::config_doc::documented_toml;

/// Output formats of `avsep config`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ConfigFormat {
    /// TOML with every field's documentation as comments.
    Toml,
    /// JSON.
    Json,
    /// The JSON Schema of the settings.
    Schema,
}

/// Arguments of `avsep config`.
#[derive(Debug, Args)]
pub struct ConfigArgs {
    /// Print the defaults (the default when no FILE is given).
    #[arg(long)]
    pub defaults: bool,
    /// A settings file to check and print merged over the defaults.
    pub file: Option<PathBuf>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = ConfigFormat::Toml)]
    pub format: ConfigFormat,
}

/// Runs the command.
pub fn run(args: ConfigArgs) -> Result<(), CliError> {
    let cfg = match (&args.file, args.defaults) {
        (Some(_), true) => {
            return Err(CliError::input(
                "give either --defaults or a FILE, not both",
            ));
        }
        (Some(p), false) => load_config(p)?,
        (None, _) => PipelineConfig::default(),
    };
    let text = match args.format {
        ConfigFormat::Toml => documented_toml(&cfg).map_err(CliError::runtime)?,
        ConfigFormat::Json => serde_json::to_string_pretty(&cfg).map_err(CliError::runtime)?,
        ConfigFormat::Schema => {
            serde_json::to_string_pretty(&schemars::schema_for!(PipelineConfig))
                .map_err(CliError::runtime)?
        }
    };
    println!("{}", text.trim_end());
    Ok(())
}
