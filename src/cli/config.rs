//! `avsep config` (in progress).

use clap::Args;

use super::CliError;

/// Arguments of `avsep config`.
#[derive(Debug, Args)]
pub struct ConfigArgs {}

/// Runs the command.
pub fn run(_args: ConfigArgs) -> Result<(), CliError> {
    Err(CliError::runtime("not implemented yet"))
}
