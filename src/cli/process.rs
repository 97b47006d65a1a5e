//! `avsep process` (in progress).

use clap::Args;

use super::CliError;

/// Arguments of `avsep process`.
#[derive(Debug, Args)]
pub struct ProcessArgs {}

/// Runs the command.
pub fn run(_args: ProcessArgs) -> Result<(), CliError> {
    Err(CliError::runtime("not implemented yet"))
}
