//! The Zenoh transport: the server joins a Zenoh network and every session it holds streams
//! there too, under `avsep/<session>/...` (keys in `protocol::zenoh_keys`, contract in
//! api/protocol.md).
//!
//! It attaches to sessions the way the WebSocket does: inbound samples go through
//! [`SessionHandle::submit`](crate::server::session::Session::submit) into the session's bounded
//! queue, and one task per session subscribes to the session's output broadcast and publishes it
//! (separated audio and measurements only while a Zenoh subscriber wants them: `wanted.rs`). A
//! registry hook attaches every session as it is inserted, whichever transport created it, so
//! nothing it produces is missed. Session management (create, list, inspect) is a queryable under
//! `avsep/sessions/**`, served by one task from a bounded queue. Zenoh callbacks never block: they
//! decode, check and `try_send`.

mod config;
mod inbound;
mod outbound;
mod queries;
mod wanted;

use std::collections::HashSet;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use zenoh::Wait;
use zenoh::query::Queryable;

pub use config::{ZenohConfig, ZenohMode};

use crate::protocol::OutputSelection;
use crate::protocol::rest::SessionState;
use crate::protocol::zenoh_keys::{SESSIONS_ALL, SESSIONS_CREATE, session_input};

use super::registry::Registry;
use super::session::{ClientId, SessionHandle};

/// The client id under which a session sees all its Zenoh publishers: errors their samples cause
/// are addressed to it and published on `out/events`.
pub const ZENOH_CLIENT: ClientId = u64::MAX;

/// Joining Zenoh or declaring on it failed.
#[derive(Debug, thiserror::Error)]
#[error("zenoh: {0}")]
pub struct ZenohError(pub String);

/// Bytes a Zenoh message may carry beyond the largest payload the limits admit (its key,
/// attachment and encoding).
const MESSAGE_HEADROOM: usize = 64 << 10;

fn zerr(e: impl std::fmt::Display) -> ZenohError {
    ZenohError(e.to_string())
}

/// What the hook, the fan-out tasks and the query task share.
struct Shared {
    zenoh: zenoh::Session,
    registry: Arc<Registry>,
    runtime: tokio::runtime::Handle,
    /// Sessions with a fan-out task (a session is attached once).
    attached: Mutex<HashSet<String>>,
    /// Fan-out tasks still running (shutdown waits for their `closed`).
    active: AtomicUsize,
}

impl Shared {
    /// Subscribes to the session's output now (before it can produce any), declares the
    /// subscriber of its input, and starts its fan-out task.
    fn attach(self: &Arc<Self>, s: &SessionHandle) {
        let fresh = self
            .attached
            .lock()
            .is_ok_and(|mut a| a.insert(s.id().to_string()));
        if !fresh {
            return;
        }
        // The optional outputs go out only while a Zenoh subscriber wants them.
        let mut outputs = s.subscribe();
        let wanted = wanted::Wanted::declare(&self.zenoh, s.id(), &outputs);
        outputs.want(&OutputSelection::default());
        let admin = self.registry.config().admin_key.clone();
        let subscriber = self
            .zenoh
            .declare_subscriber(session_input(s.id()))
            .callback(inbound::handler(s.clone(), admin))
            .wait();
        let subscriber = match subscriber {
            Ok(sub) => Some(sub),
            Err(e) => {
                tracing::error!(session = %s.id(), "cannot subscribe to the session's Zenoh input: {e}");
                None
            }
        };
        self.active.fetch_add(1, Ordering::AcqRel);
        let task = outbound::fan_out(self.clone(), s.clone(), (outputs, wanted), subscriber);
        self.runtime.spawn(task);
    }

    /// The session's fan-out has ended.
    fn detach(&self, id: &str) {
        if let Ok(mut a) = self.attached.lock() {
            a.remove(id);
        }
        self.active.fetch_sub(1, Ordering::AcqRel);
    }
}

/// The server's presence on Zenoh; dropping it leaves Zenoh abruptly, [`ZenohTransport::close`]
/// leaves after the sessions' last messages.
pub struct ZenohTransport {
    shared: Arc<Shared>,
    queries: tokio::task::JoinHandle<()>,
    queryables: Vec<Queryable<()>>,
}

impl ZenohTransport {
    /// Joins Zenoh as `config` says, attaches to every session `registry` holds or will hold,
    /// and declares the session-management queryables. Needs a multi-threaded Tokio runtime.
    pub async fn start(config: &ZenohConfig, registry: Arc<Registry>) -> Result<Self, ZenohError> {
        let mut zc = config.to_zenoh().map_err(zerr)?;
        // Zenoh reassembles a fragmented message of up to 1 GiB (its default) per link and
        // channel before any of our checks sees it: nothing larger than our own limits admit
        // is worth reassembling.
        let limits = &registry.config().limits;
        let largest = limits.max_message_bytes.max(limits.max_body_bytes) + MESSAGE_HEADROOM;
        zc.insert_json5("transport/link/rx/max_message_size", &largest.to_string())
            .map_err(zerr)?;
        let zenoh = zenoh::open(zc).await.map_err(zerr)?;
        let shared = Arc::new(Shared {
            zenoh: zenoh.clone(),
            registry: registry.clone(),
            runtime: tokio::runtime::Handle::current(),
            attached: Mutex::new(HashSet::new()),
            active: AtomicUsize::new(0),
        });
        // Hook first, then the sessions already held: a session inserted in between is seen
        // twice and attached once.
        let weak = Arc::downgrade(&shared);
        registry.on_insert(Box::new(move |s| {
            if let Some(shared) = weak.upgrade() {
                shared.attach(s);
            }
        }));
        for s in registry.list() {
            if s.state() == SessionState::Running {
                shared.attach(&s);
            }
        }
        let (tx, rx) = tokio::sync::mpsc::channel(config.query_queue);
        // `create` is declared complete, so a query with the default target reaches one server
        // of the network (one session is created); list and inspect reach every server.
        let create = zenoh
            .declare_queryable(SESSIONS_CREATE)
            .complete(true)
            .callback(queries::enqueue(tx.clone(), true))
            .await
            .map_err(zerr)?;
        let rest = zenoh
            .declare_queryable(SESSIONS_ALL)
            .callback(queries::enqueue(tx, false))
            .await
            .map_err(zerr)?;
        let queries = tokio::spawn(queries::serve(shared.clone(), rx));
        tracing::info!(zid = %zenoh.zid(), "joined zenoh");
        Ok(Self {
            shared,
            queries,
            queryables: vec![create, rest],
        })
    }

    /// The Zenoh session (for publishing or querying alongside the transport).
    pub fn session(&self) -> &zenoh::Session {
        &self.shared.zenoh
    }

    /// Leaves Zenoh: stops answering queries, waits (at most `timeout`) until every session's
    /// fan-out has published its `closed` message, then closes the Zenoh session. Call after the
    /// registry has drained.
    pub async fn close(self, timeout: Duration) {
        let deadline = Instant::now() + timeout;
        self.queries.abort();
        drop(self.queryables);
        while self.shared.active.load(Ordering::Acquire) > 0 && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        if let Err(e) = self.shared.zenoh.close().await {
            tracing::warn!("closing zenoh: {e}");
        }
    }
}
