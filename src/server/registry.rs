//! The sessions a server holds: creation from a REST body (geometry and settings checked, the
//! pipeline admitted by its memory bound and built, one at a time and at a bounded rate),
//! lookup, removal, expiry of ended and idle sessions, and draining at shutdown.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock, RwLock};
use std::time::{Duration, Instant};

use axum::http::StatusCode;

use crate::geometry::Layout;
use crate::pipeline::{ConfigError, Pipeline, PipelineConfig};
use crate::protocol::rest::{CreateSession, SessionState};
use crate::scene::convert::{geometry_file, layout_from_file};
use crate::server::budget::session_bound;

use super::auth;
use super::config::ServerConfig;
use super::demo::DemoAccess;
use super::engine::Engine;
use super::error::ApiError;
use super::metrics::{ServerMetrics, Snapshot};
use super::rate_limit::TokenBucket;
use super::session::{SessionHandle, SessionSpec};

/// Called with every session the registry starts holding (see [`Registry::on_insert`]).
pub type InsertHook = Box<dyn Fn(&SessionHandle) + Send + Sync>;

/// Every session of one server.
pub struct Registry {
    sessions: RwLock<BTreeMap<String, SessionHandle>>,
    hooks: RwLock<Vec<InsertHook>>,
    config: Arc<ServerConfig>,
    metrics: Arc<ServerMetrics>,
    draining: AtomicBool,
    /// Session creations admitted at `limits.session_creations_per_min`.
    creations: Mutex<TokenBucket>,
    /// Held while a session's pipeline is built, so that concurrent creations do not build past
    /// the memory budget at once.
    building: Mutex<()>,
    /// Memory bounds admitted for sessions being created or changed, by session id, until the
    /// session or change is in force (see [`Registry::admit_memory`]).
    reserved: Mutex<BTreeMap<String, usize>>,
    /// The built-in demo session, when one was started (`avsep serve --demo`).
    demo: OnceLock<DemoAccess>,
}

impl Registry {
    /// An empty registry.
    pub fn new(config: Arc<ServerConfig>, metrics: Arc<ServerMetrics>) -> Self {
        let per_min = config.limits.session_creations_per_min;
        Self {
            creations: Mutex::new(TokenBucket::new(per_min / 60.0, per_min)),
            building: Mutex::new(()),
            reserved: Mutex::new(BTreeMap::new()),
            sessions: RwLock::new(BTreeMap::new()),
            hooks: RwLock::new(Vec::new()),
            config,
            metrics,
            draining: AtomicBool::new(false),
            demo: OnceLock::new(),
        }
    }

    /// The server's settings.
    pub fn config(&self) -> &ServerConfig {
        &self.config
    }

    /// The server's metrics.
    pub fn metrics(&self) -> &Arc<ServerMetrics> {
        &self.metrics
    }

    /// Whether the server is shutting down.
    pub fn draining(&self) -> bool {
        self.draining.load(Ordering::Acquire)
    }

    /// Sessions held.
    pub fn len(&self) -> usize {
        self.sessions.read().map_or(0, |s| s.len())
    }

    /// Whether no session is held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Publishes the demo session's credentials to the dashboard (once; later calls are
    /// ignored).
    pub fn set_demo(&self, access: DemoAccess) {
        let _ = self.demo.set(access);
    }

    /// The demo session's credentials, while it is held.
    pub fn demo(&self) -> Option<&DemoAccess> {
        self.demo.get().filter(|d| self.get(&d.id).is_some())
    }

    fn check_capacity(&self) -> Result<(), ApiError> {
        if self.draining() {
            return Err(ApiError::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "draining",
                "the server is shutting down",
            ));
        }
        let max = self.config.limits.max_sessions;
        if self.len() >= max {
            return Err(ApiError::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "at_capacity",
                format!(
                    "the server holds {max} sessions (limits.max_sessions); delete one or use another server"
                ),
            ));
        }
        Ok(())
    }

    /// Counts a creation against `limits.session_creations_per_min`, refusing it (429) past
    /// the rate.
    fn admit_creation(&self) -> Result<(), ApiError> {
        let admitted = self
            .creations
            .lock()
            .ok()
            .and_then(|mut b| b.admit(Instant::now()));
        if admitted.is_none() {
            return Err(ApiError::new(
                StatusCode::TOO_MANY_REQUESTS,
                "rate_limited",
                format!(
                    "more than limits.session_creations_per_min ({}) sessions asked for in the \
                     last minute; try again shortly",
                    self.config.limits.session_creations_per_min
                ),
            ));
        }
        Ok(())
    }

    /// Creates a session from a REST body: checks the geometry and settings (errors name the
    /// field), builds the pipeline and starts its worker. Returns the session and its token.
    /// Building the pipeline takes a while (search grids, filters): call from a blocking task.
    pub fn create(&self, req: CreateSession) -> Result<(SessionHandle, String), ApiError> {
        self.check_capacity()?;
        self.admit_creation()?;
        let scene = geometry_file(
            req.sample_rate,
            req.speed_of_sound,
            req.arrays,
            req.cameras,
            req.region,
        );
        let layout = layout_from_file(&scene).map_err(|e| ApiError::geometry(e, ""))?;
        self.config
            .limits
            .check_layout(&layout)
            .map_err(|e| ApiError::geometry(e, ""))?;
        let settings = req.settings.unwrap_or_default();
        self.config
            .limits
            .check_settings(&settings)
            .map_err(|e| ApiError::config(e, "settings"))?;
        // One build at a time bounds what building takes at once. A poisoned lock only means
        // another build panicked.
        let _building = self.building.lock().unwrap_or_else(|e| e.into_inner());
        let id = auth::new_session_id();
        let bound = self
            .session_bound(&layout, &settings)
            .map_err(|e| ApiError::config(e, "settings"))?;
        let _admitted = self.admit_memory(&id, bound)?;
        // The id is 64 random bits in hex; it seeds the session unless the settings give a seed.
        let seed = settings
            .seed
            .unwrap_or_else(|| u64::from_str_radix(&id, 16).unwrap_or(0));
        let mut pipeline = Pipeline::new(layout.clone(), settings.clone(), seed)
            .map_err(|e| ApiError::config(e, "settings"))?;
        pipeline.limit_backlog(self.config.limits.sensor_backlog_bytes);
        let token = auth::new_token();
        let spec = SessionSpec {
            id,
            name: req.name,
            token: token.clone(),
            step_s: pipeline.clock().step_s(),
            audio_delay_samples: pipeline.audio_delay_samples(),
            layout,
            settings,
            limits: self.config.limits.clone(),
            execution: self.config.execution.clone(),
        };
        let handle = self.insert(spec, pipeline)?;
        tracing::info!(session = %handle.id(), "session created");
        Ok((handle, token))
    }

    /// Starts a session driven by `engine` and registers it.
    pub fn insert<E: Engine>(
        &self,
        spec: SessionSpec,
        engine: E,
    ) -> Result<SessionHandle, ApiError> {
        self.check_capacity()?;
        let handle = SessionHandle::start(spec, engine, self.metrics.clone()).map_err(|e| {
            ApiError::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "no_thread",
                format!("cannot start the session's worker thread: {e}"),
            )
        })?;
        let mut sessions = self.sessions.write().map_err(|_| {
            ApiError::new(
                StatusCode::INTERNAL_SERVER_ERROR,
                "internal",
                "registry lock poisoned",
            )
        })?;
        if sessions.len() >= self.config.limits.max_sessions {
            handle.finish("server at capacity");
            return Err(ApiError::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "at_capacity",
                "the server filled up while the session was being created",
            ));
        }
        sessions.insert(handle.id().to_string(), handle.clone());
        drop(sessions);
        self.metrics.session_created();
        if let Ok(hooks) = self.hooks.read() {
            for hook in hooks.iter() {
                hook(&handle);
            }
        }
        Ok(handle)
    }

    /// Registers `hook`, called with every session inserted from now on before its creator gets
    /// it (so a transport that subscribes in the hook misses none of its output). A hook must not
    /// block.
    pub fn on_insert(&self, hook: InsertHook) {
        if let Ok(mut hooks) = self.hooks.write() {
            hooks.push(hook);
        }
    }

    /// The session with this id.
    pub fn get(&self, id: &str) -> Option<SessionHandle> {
        self.sessions.read().ok()?.get(id).cloned()
    }

    /// Every session, oldest first.
    pub fn list(&self) -> Vec<SessionHandle> {
        let mut v: Vec<SessionHandle> = self
            .sessions
            .read()
            .map(|s| s.values().cloned().collect())
            .unwrap_or_default();
        v.sort_by(|a, b| a.created_unix_s().total_cmp(&b.created_unix_s()));
        v
    }

    /// Removes a session; its pipeline finishes what it holds and its streams close with
    /// `reason`.
    pub fn remove(&self, id: &str, reason: &str) -> Option<SessionHandle> {
        let s = self.sessions.write().ok()?.remove(id)?;
        s.finish(reason);
        tracing::info!(session = %id, reason, "session removed");
        Some(s)
    }

    /// Removes sessions that ended more than `limits.finished_ttl_s` ago, and ends the running
    /// ones unused for `limits.idle_timeout_s` (removing at once those that never got input).
    pub fn reap(&self) {
        let limits = &self.config.limits;
        let ttl = Duration::from_secs_f64(limits.finished_ttl_s);
        let idle =
            (limits.idle_timeout_s > 0.0).then(|| Duration::from_secs_f64(limits.idle_timeout_s));
        for s in self.list() {
            if s.ended().is_some_and(|t| t.elapsed() >= ttl) {
                self.remove(s.id(), "expired");
            } else if let Some(idle) = idle
                && s.state() == SessionState::Running
                && s.unused_for().is_some_and(|d| d >= idle)
            {
                tracing::info!(session = %s.id(), "session idle for limits.idle_timeout_s");
                if s.ever_fed() {
                    s.finish("idle");
                } else {
                    self.remove(s.id(), "idle");
                }
            }
        }
    }

    /// The memory bound of a session on `layout` with `settings` under this server's limits
    /// ([`session_bound`]).
    fn session_bound(
        &self,
        layout: &Layout,
        settings: &PipelineConfig,
    ) -> Result<usize, ConfigError> {
        let c = &self.config;
        session_bound(&c.limits, &c.execution, layout, settings)
    }

    /// Admits a change of session `id`'s calibration or settings to `layout` and `settings`
    /// ([`Registry::admit_memory`]). A change no pipeline could be built with is refused by the
    /// change itself, which names why, so it is not admitted here (`None`).
    pub fn admit_change(
        &self,
        id: &str,
        layout: &Layout,
        settings: &PipelineConfig,
    ) -> Result<Option<MemoryReservation<'_>>, ApiError> {
        match self.session_bound(layout, settings) {
            Ok(bound) => self.admit_memory(id, bound).map(Some),
            Err(_) => Ok(None),
        }
    }

    /// Memory the sessions held (pipelines and buffers) may take at most, leaving out `except`'s,
    /// with the reservations `reserved`: a session counts at the larger of its bound and its
    /// reservation, a session being created at its reservation.
    fn memory_in_use(&self, reserved: &BTreeMap<String, usize>, except: Option<&str>) -> usize {
        let sessions = self.list();
        let held: usize = sessions
            .iter()
            .filter(|s| Some(s.id()) != except)
            .map(|s| {
                s.memory_bound()
                    .max(reserved.get(s.id()).copied().unwrap_or(0))
            })
            .sum();
        let creating: usize = reserved
            .iter()
            .filter(|(id, _)| {
                Some(id.as_str()) != except && !sessions.iter().any(|s| s.id() == *id)
            })
            .map(|(_, b)| b)
            .sum();
        held + creating
    }

    /// Admits the pipeline of session `id` (being created, or changing its calibration or
    /// settings) that may take `bytes`, in place of its bound in force, under
    /// `limits.max_memory_mb`: refused (503 `memory_budget`) past the budget, else reserved
    /// until the returned guard is dropped, once the session or change is in force (or failed).
    /// The check and the reservation are one step, so concurrent admissions cannot pass the
    /// budget together.
    pub fn admit_memory(&self, id: &str, bytes: usize) -> Result<MemoryReservation<'_>, ApiError> {
        let budget = self.config.limits.max_memory_mb;
        let mut reserved = self.reserved.lock().unwrap_or_else(|e| e.into_inner());
        let in_use = self.memory_in_use(&reserved, Some(id));
        if budget > 0 && in_use.saturating_add(bytes) > budget.saturating_mul(1 << 20) {
            let mb = |b: usize| b.div_ceil(1 << 20);
            return Err(ApiError::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "memory_budget",
                format!(
                    "this session may take up to {} MB and the others up to {} MB, more than \
                     limits.max_memory_mb ({budget} MB) together; fewer microphones, smaller \
                     frames or a lower separate.lifecycle.max_streams take less",
                    mb(bytes),
                    mb(in_use)
                ),
            ));
        }
        reserved.insert(id.to_owned(), bytes);
        Ok(MemoryReservation {
            registry: self,
            id: id.to_owned(),
        })
    }

    /// Gauges for `/metrics`.
    pub fn snapshot(&self) -> Snapshot {
        let mut snap = Snapshot::default();
        for s in self.list() {
            *snap.sessions.entry(s.state().as_str()).or_default() += 1;
            snap.clients += s.clients() as i64;
            let m = s.metrics();
            snap.queue_depth += m.queue_depth as i64;
            snap.separation_queue_depth += m.separation_queue_depth as i64;
            snap.live_tracks += m.live_tracks as i64;
            snap.memory_bound_bytes += s.memory_bound() as i64;
        }
        snap
    }

    /// Shutdown: refuses new sessions, ends every session's input, and waits (at most
    /// `timeout`) until their pipelines have flushed and their streams have closed.
    pub async fn drain(&self, timeout: Duration) {
        self.draining.store(true, Ordering::Release);
        let sessions = self.list();
        for s in &sessions {
            s.finish("server shutting down");
        }
        let deadline = Instant::now() + timeout;
        let busy = |s: &SessionHandle| {
            matches!(s.state(), SessionState::Running | SessionState::Finishing) || s.clients() > 0
        };
        while Instant::now() < deadline && sessions.iter().any(busy) {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let left = sessions.iter().filter(|s| busy(s)).count();
        tracing::info!(
            sessions = sessions.len(),
            unfinished = left,
            "sessions drained"
        );
    }
}

/// A session's admitted memory bound, counted for it until dropped (see
/// [`Registry::admit_memory`]).
pub struct MemoryReservation<'a> {
    registry: &'a Registry,
    id: String,
}

impl Drop for MemoryReservation<'_> {
    fn drop(&mut self) {
        let mut r = self
            .registry
            .reserved
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        r.remove(&self.id);
    }
}
