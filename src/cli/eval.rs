//! `avsep eval` (in progress).

use clap::Args;

use super::CliError;

/// Arguments of `avsep eval`.
#[derive(Debug, Args)]
pub struct EvalArgs {}

/// Runs the command.
pub fn run(_args: EvalArgs) -> Result<(), CliError> {
    Err(CliError::runtime("not implemented yet"))
}
