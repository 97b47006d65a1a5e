//! The HTTP application: routes, body limits, CORS and request tracing, and the server's life
//! (bind, serve, drain on shutdown).

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::extract::{DefaultBodyLimit, Request};
use axum::http::{HeaderValue, Method, header};
use axum::routing::{get, post, put};
use axum::serve::ListenerExt;
use tokio::net::TcpListener;
use tower_http::cors::{AllowOrigin, Any, CorsLayer};
use tower_http::trace::TraceLayer;

use super::config::ServerConfig;
use super::metrics::ServerMetrics;
use super::registry::Registry;
use super::{calibration, dashboard, openapi, routes, stream};

/// What every handler shares.
#[derive(Clone)]
pub struct AppState {
    /// The sessions.
    pub registry: Arc<Registry>,
    openapi_yaml: Arc<str>,
}

fn cors(origins: &[String]) -> Option<CorsLayer> {
    if origins.is_empty() {
        return None;
    }
    let layer = CorsLayer::new()
        .allow_methods([
            Method::GET,
            Method::POST,
            Method::PUT,
            Method::PATCH,
            Method::DELETE,
        ])
        .allow_headers([header::AUTHORIZATION, header::CONTENT_TYPE]);
    Some(if origins.iter().any(|o| o == "*") {
        layer.allow_origin(Any)
    } else {
        let list: Vec<HeaderValue> = origins.iter().filter_map(|o| o.parse().ok()).collect();
        layer.allow_origin(AllowOrigin::list(list))
    })
}

/// The router of the whole API over `registry`.
pub fn router(registry: Arc<Registry>) -> Router {
    let limits = registry.config().limits.clone();
    let origins = registry.config().cors_origins.clone();
    let state = AppState {
        registry,
        openapi_yaml: openapi::openapi_yaml().into(),
    };
    let app = Router::new()
        .route(
            "/v1/sessions",
            post(routes::create_session).get(routes::list_sessions),
        )
        .route(
            "/v1/sessions/{id}",
            get(routes::inspect_session).delete(routes::delete_session),
        )
        .route("/v1/sessions/{id}/arrays/{array}", put(calibration::put_array))
        .route(
            "/v1/sessions/{id}/cameras/{camera}",
            put(calibration::put_camera),
        )
        .route(
            "/v1/sessions/{id}/settings",
            get(calibration::get_settings).patch(calibration::patch_settings),
        )
        .route("/v1/sessions/{id}/tracks", get(routes::current_tracks))
        .route(
            "/v1/sessions/{id}/tracks/history",
            get(routes::track_history),
        )
        .route("/v1/sessions/{id}/metrics", get(routes::session_metrics))
        .route("/v1/sessions/{id}/stream", get(stream::open_stream))
        .route(
            "/v1/openapi.yaml",
            get(|axum::extract::State(s): axum::extract::State<AppState>| async move {
                ([(header::CONTENT_TYPE, "application/yaml")], s.openapi_yaml.to_string())
            }),
        )
        .route("/metrics", get(routes::prometheus))
        .route("/healthz", get(routes::healthz))
        .route("/readyz", get(routes::readyz))
        .merge(dashboard::routes())
        .fallback(routes::not_found)
        .layer(DefaultBodyLimit::max(limits.max_body_bytes))
        // Spans carry the path only: query strings may hold a token.
        .layer(TraceLayer::new_for_http().make_span_with(|req: &Request| {
            tracing::info_span!("http", method = %req.method(), path = %req.uri().path())
        }))
        .with_state(state);
    match cors(&origins) {
        Some(c) => app.layer(c),
        None => app,
    }
}

/// A bound server, not yet serving.
pub struct Server {
    listener: TcpListener,
    registry: Arc<Registry>,
}

impl Server {
    /// Binds `config.bind` (port 0 picks a free port).
    pub async fn bind(config: ServerConfig) -> std::io::Result<Self> {
        config
            .validate()
            .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e.to_string()))?;
        let metrics = ServerMetrics::new().map_err(std::io::Error::other)?;
        let listener = TcpListener::bind(&config.bind).await?;
        let registry = Arc::new(Registry::new(Arc::new(config), Arc::new(metrics)));
        Ok(Self { listener, registry })
    }

    /// The address it listens on.
    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.listener.local_addr()
    }

    /// The sessions it holds.
    pub fn registry(&self) -> Arc<Registry> {
        self.registry.clone()
    }

    /// Serves until `shutdown` resolves, then drains: new sessions are refused, every session
    /// finishes its pipeline and closes its streams (within `drain_timeout_s`), and the
    /// listener stops.
    pub async fn run(
        self,
        shutdown: impl Future<Output = ()> + Send + 'static,
    ) -> std::io::Result<()> {
        let registry = self.registry.clone();
        let reaper = {
            let registry = registry.clone();
            tokio::spawn(async move {
                let mut tick = tokio::time::interval(Duration::from_secs(5));
                loop {
                    tick.tick().await;
                    registry.reap();
                }
            })
        };
        let timeout = Duration::from_secs_f64(registry.config().drain_timeout_s);
        let drained = {
            let registry = registry.clone();
            async move {
                shutdown.await;
                tracing::info!("shutting down: draining sessions");
                registry.drain(timeout).await;
            }
        };
        let listener = self.listener.tap_io(|tcp| {
            // Small JSON messages should leave at once.
            let _ = tcp.set_nodelay(true);
        });
        let result = axum::serve(listener, router(registry))
            .with_graceful_shutdown(drained)
            .await;
        reaper.abort();
        result
    }
}
