//! The `avsep` command line: simulate scenes, process them offline, score the results, print the
//! configuration (and, later, serve sessions).

mod client;
mod config;
mod eval;
mod loadgen;
mod process;
mod progress;
mod serve;
mod simulate;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

pub use progress::Progress;

/// avsep: online audio-visual multi-speaker tracking and separation.
#[derive(Debug, Parser)]
#[command(name = "avsep", version, about, propagate_version = true)]
pub struct Cli {
    /// The command to run.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Simulate a room and write a scene folder with known truth.
    Simulate(simulate::SimulateArgs),
    /// Run the pipeline offline on a scene folder and write an output folder.
    Process(process::ProcessArgs),
    /// Score an output folder against its scene's truth.
    Eval(eval::EvalArgs),
    /// Print the pipeline configuration (defaults, or a file merged over them).
    Config(config::ConfigArgs),
    /// Host sessions: REST API under /v1 and WebSocket streams (see api/).
    Serve(serve::ServeArgs),
    /// Load-test a running server with N concurrent simulated sessions.
    Loadgen(loadgen::LoadgenArgs),
    /// Talk to a running server as a client (stream a scene and record what comes back).
    Client(client::ClientArgs),
}

/// A command failure with its exit code: 2 for bad input (arguments, scenes, configuration),
/// 1 for everything else.
#[derive(Debug)]
pub struct CliError {
    /// Process exit code.
    pub code: u8,
    /// Message printed to stderr.
    pub message: String,
}

impl CliError {
    /// Bad input: exit code 2.
    pub fn input(message: impl std::fmt::Display) -> Self {
        Self {
            code: 2,
            message: message.to_string(),
        }
    }

    /// A failure while running: exit code 1.
    pub fn runtime(message: impl std::fmt::Display) -> Self {
        Self {
            code: 1,
            message: message.to_string(),
        }
    }
}

impl From<crate::scene::SceneError> for CliError {
    fn from(e: crate::scene::SceneError) -> Self {
        Self::input(e)
    }
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> Result<(), CliError> {
    match cli.command {
        Command::Simulate(a) => simulate::run(a),
        Command::Process(a) => process::run(a),
        Command::Eval(a) => eval::run(a),
        Command::Config(a) => config::run(a),
        Command::Serve(a) => serve::run(a),
        Command::Loadgen(a) => loadgen::run(a),
        Command::Client(a) => client::run(a),
    }
}

/// Entry point of the binary.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    if matches!(
        cli.command,
        Command::Simulate(_) | Command::Process(_) | Command::Eval(_) | Command::Config(_)
    ) {
        die_quietly_on_closed_pipe();
    }
    match &cli.command {
        // A server logs what it does; JSON lines on request.
        Command::Serve(a) => init_logging("info", a.log_json),
        _ => init_logging("warn", false),
    }
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", e.message);
            ExitCode::from(e.code)
        }
    }
}

/// Rust ignores SIGPIPE, so `avsep config --defaults | head` would panic in `println!` once
/// `head` exits. Commands that only print and write files get the Unix default back (end
/// quietly); the server and the network clients keep ignoring it, since for them a closed
/// socket is an error to handle, not a reason to die.
fn die_quietly_on_closed_pipe() {
    #[cfg(unix)]
    // SAFETY: called before any thread is started; SIG_DFL is a valid disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn init_logging(default_level: &str, json: bool) {
    use tracing_subscriber::EnvFilter;
    let filter =
        EnvFilter::try_from_env("AVSEP_LOG").unwrap_or_else(|_| EnvFilter::new(default_level));
    let fmt = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    let _ = if json {
        fmt.json().try_init()
    } else {
        fmt.try_init()
    };
}
