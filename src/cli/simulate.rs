//! `avsep simulate` (in progress).

use clap::Args;

use super::CliError;

/// Arguments of `avsep simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {}

/// Runs the command.
pub fn run(_args: SimulateArgs) -> Result<(), CliError> {
    Err(CliError::runtime("not implemented yet"))
}
