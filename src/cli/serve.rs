//! `avsep serve`: hosts sessions behind the REST API, the WebSocket stream and (unless disabled)
//! Zenoh until ctrl-c or SIGTERM, then drains them (pipelines finish, streams close with a close
//! frame or a `closed` message).

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;

use clap::Args;

use super::CliError;
use crate::pipeline::config_doc::documented_toml;
use crate::server::demo::{self, DemoOptions};
use crate::server::zenoh_transport::{ZenohMode, ZenohTransport};
use crate::server::{Registry, Server, ServerConfig};

/// Arguments of `avsep serve`. Flags override environment variables, which override the file.
#[derive(Debug, Args)]
pub struct ServeArgs {
    /// Server settings (TOML or JSON); see `avsep serve --print-config`.
    #[arg(long, env = "AVSEP_CONFIG")]
    pub config: Option<PathBuf>,
    /// Address and port to listen on [default: 127.0.0.1:8080].
    #[arg(long, env = "AVSEP_BIND")]
    pub bind: Option<String>,
    /// Admin key guarding session creation, listing and deletion (at least 16 characters).
    #[arg(long, env = "AVSEP_ADMIN_KEY", hide_env_values = true)]
    pub admin_key: Option<String>,
    /// Origins allowed to call the API from browsers, comma-separated (`*` for any).
    #[arg(long, env = "AVSEP_CORS_ORIGINS", value_delimiter = ',')]
    pub cors_origins: Option<Vec<String>>,
    /// Most sessions held at once.
    #[arg(long, env = "AVSEP_MAX_SESSIONS")]
    pub max_sessions: Option<usize>,
    /// Memory (MB) the running sessions (pipelines and buffers) may take together, by their
    /// bounds; 0 for no budget.
    #[arg(long, env = "AVSEP_MAX_MEMORY_MB")]
    pub max_memory_mb: Option<usize>,
    /// Inbound messages queued per session before `queue_full`.
    #[arg(long, env = "AVSEP_QUEUE_DEPTH")]
    pub queue_depth: Option<usize>,
    /// Bytes the messages queued per session may hold, decoded, before `queue_full`.
    #[arg(long, env = "AVSEP_QUEUE_BYTES")]
    pub queue_bytes: Option<usize>,
    /// Do not join Zenoh (REST and WebSocket only).
    #[arg(long, env = "AVSEP_NO_ZENOH")]
    pub no_zenoh: bool,
    /// Zenoh role: peer, client or router [default: peer].
    #[arg(long, env = "AVSEP_ZENOH_MODE", value_parser = parse_mode)]
    pub zenoh_mode: Option<ZenohMode>,
    /// Zenoh endpoints to connect to, comma-separated (e.g. `tcp/10.0.0.5:7447`).
    #[arg(long, env = "AVSEP_ZENOH_CONNECT", value_delimiter = ',')]
    pub zenoh_connect: Option<Vec<String>>,
    /// Zenoh endpoints to listen on, comma-separated [default: tcp/127.0.0.1:7447].
    #[arg(long, env = "AVSEP_ZENOH_LISTEN", value_delimiter = ',')]
    pub zenoh_listen: Option<Vec<String>>,
    /// Log as JSON lines (for log collectors) instead of text.
    #[arg(long, env = "AVSEP_LOG_JSON")]
    pub log_json: bool,
    /// Print the settings in force (documented TOML) and exit.
    #[arg(long)]
    pub print_config: bool,
    /// Also run the demo room: a simulated session (uca8 preset, looped) streamed into the
    /// server in real time; the dashboard at `/` finds it (its token is given to whoever may
    /// list sessions).
    #[arg(long, env = "AVSEP_DEMO")]
    pub demo: bool,
}

impl ServeArgs {
    /// The settings: file, then environment and flags over it.
    pub fn settings(&self) -> Result<ServerConfig, CliError> {
        let mut cfg = match &self.config {
            Some(p) => {
                let text = std::fs::read_to_string(p)
                    .map_err(|e| CliError::input(format!("{}: cannot read: {e}", p.display())))?;
                ServerConfig::parse(&text)
                    .map_err(|e| CliError::input(format!("{}: {e}", p.display())))?
            }
            None => ServerConfig::default(),
        };
        if let Some(b) = &self.bind {
            cfg.bind = b.clone();
        }
        if let Some(k) = &self.admin_key {
            cfg.admin_key = Some(k.clone());
        }
        if let Some(o) = &self.cors_origins {
            cfg.cors_origins = o.clone();
        }
        if let Some(n) = self.max_sessions {
            cfg.limits.max_sessions = n;
        }
        if let Some(n) = self.max_memory_mb {
            cfg.limits.max_memory_mb = n;
        }
        if let Some(n) = self.queue_depth {
            cfg.limits.queue_depth = n;
        }
        if let Some(n) = self.queue_bytes {
            cfg.limits.queue_bytes = n;
        }
        if self.no_zenoh {
            cfg.zenoh.enabled = false;
        }
        if let Some(m) = self.zenoh_mode {
            cfg.zenoh.mode = m;
        }
        if let Some(c) = &self.zenoh_connect {
            cfg.zenoh.connect = c.clone();
        }
        if let Some(l) = &self.zenoh_listen {
            cfg.zenoh.listen = l.clone();
        }
        cfg.validate().map_err(CliError::input)?;
        Ok(cfg)
    }
}

pub(super) fn parse_mode(s: &str) -> Result<ZenohMode, String> {
    serde_json::from_value(serde_json::Value::String(s.to_string()))
        .map_err(|_| format!("{s:?} is not a Zenoh mode (peer, client, router)"))
}

/// Resolves on ctrl-c or SIGTERM.
async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        _ = ctrl_c => {},
        _ = term => {},
    }
}

/// Starts the demo room in the background; prints the dashboard's address once it streams.
fn start_demo(registry: Arc<Registry>, addr: SocketAddr) {
    tokio::spawn(async move {
        tracing::info!("simulating the demo room");
        match demo::start(registry, DemoOptions::default()).await {
            Ok(d) => {
                println!(
                    "demo room ready: open http://{addr}/ in a browser (session {})",
                    d.id
                );
            }
            Err(e) => tracing::error!("the demo room did not start: {e}"),
        }
    });
}

/// Runs the command.
pub fn run(args: ServeArgs) -> Result<(), CliError> {
    let cfg = args.settings()?;
    if args.print_config {
        let mut shown = cfg.clone();
        if shown.admin_key.is_some() {
            shown.admin_key = Some("<hidden>".into());
        }
        println!(
            "{}",
            documented_toml(&shown)
                .map_err(CliError::runtime)?
                .trim_end()
        );
        return Ok(());
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .thread_name("avsep-io")
        .build()
        .map_err(CliError::runtime)?;
    runtime.block_on(async {
        let server = Server::bind(cfg.clone())
            .await
            .map_err(|e| CliError::input(format!("cannot listen on {}: {e}", cfg.bind)))?;
        let addr = server.local_addr().map_err(CliError::runtime)?;
        if args.demo {
            start_demo(server.registry(), addr);
        }
        tracing::info!(%addr, admin_key = cfg.admin_key.is_some(), "avsep serving");
        let zenoh = if cfg.zenoh.enabled {
            let z = ZenohTransport::start(&cfg.zenoh, server.registry())
                .await
                .map_err(|e| CliError::input(format!("cannot join Zenoh: {e}")))?;
            tracing::info!(listen = ?cfg.zenoh.listen, connect = ?cfg.zenoh.connect, "zenoh joined");
            Some(z)
        } else {
            None
        };
        // Scripts and tests read the address from stdout (the port may have been 0).
        println!("listening on http://{addr}");
        let served = server.run(shutdown_signal()).await.map_err(CliError::runtime);
        if let Some(z) = zenoh {
            z.close(std::time::Duration::from_secs(2)).await;
        }
        served
    })?;
    tracing::info!("stopped");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        serve: ServeArgs,
    }

    #[test]
    fn flags_override_the_limits_that_size_a_server() {
        let cli = Cli::try_parse_from([
            "avsep",
            "--max-sessions",
            "3",
            "--max-memory-mb",
            "0",
            "--queue-bytes",
            "8388608",
        ]);
        let l = cli.unwrap().serve.settings().unwrap().limits;
        assert_eq!(
            (l.max_sessions, l.max_memory_mb, l.queue_bytes),
            (3, 0, 8 << 20)
        );
        let cfg = Cli::try_parse_from(["avsep"])
            .unwrap()
            .serve
            .settings()
            .unwrap();
        assert_eq!(cfg.limits, crate::server::Limits::default());
    }
}
