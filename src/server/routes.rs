//! REST handlers of sessions under `/v1`: create, list, inspect, delete; tracks, history and
//! metrics; and the server's health, readiness and Prometheus endpoints.

use axum::Json;
use axum::extract::{Path, Query, RawQuery, Request, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;

use crate::protocol::rest::{
    CreateSession, Health, SessionCreated, SessionInfo, SessionList, SessionMetrics, TrackHistory,
    TracksSnapshot,
};

use super::app::AppState;
use super::auth;
use super::error::{ApiError, JsonBody};
use super::session::SessionHandle;

/// Checks the admin key when one is configured.
pub(super) fn require_admin(
    app: &AppState,
    headers: &HeaderMap,
    query: Option<&str>,
) -> Result<(), ApiError> {
    let Some(key) = &app.registry.config().admin_key else {
        return Ok(());
    };
    match auth::presented(headers, query) {
        None => Err(ApiError::unauthorized("this endpoint")),
        Some(p) if auth::same_secret(key, &p) => Ok(()),
        Some(_) => Err(ApiError::forbidden(
            "this endpoint (it needs the admin key)",
        )),
    }
}

fn is_admin(app: &AppState, presented: &str) -> bool {
    app.registry
        .config()
        .admin_key
        .as_deref()
        .is_some_and(|k| auth::same_secret(k, presented))
}

/// The session `id`, when the request presents its token or the admin key.
pub(super) fn session_access(
    app: &AppState,
    id: &str,
    headers: &HeaderMap,
    query: Option<&str>,
) -> Result<SessionHandle, ApiError> {
    let Some(presented) = auth::presented(headers, query) else {
        return Err(ApiError::unauthorized("a session's endpoints"));
    };
    let session = app
        .registry
        .get(id)
        .ok_or_else(|| ApiError::no_session(id))?;
    if session.token_matches(&presented) || is_admin(app, &presented) {
        Ok(session)
    } else {
        Err(ApiError::forbidden("this session"))
    }
}

/// Creates a session.
#[utoipa::path(
    post,
    path = "/v1/sessions",
    tag = "sessions",
    request_body = CreateSession,
    responses(
        (status = 201, description = "Created; the token opens the session's endpoints and stream", body = SessionCreated),
        (status = 400, description = "Malformed JSON", body = crate::protocol::rest::ErrorResponse),
        (status = 401, description = "Admin key configured but not presented", body = crate::protocol::rest::ErrorResponse),
        (status = 403, description = "Wrong admin key", body = crate::protocol::rest::ErrorResponse),
        (status = 413, description = "Body larger than limits.max_body_bytes", body = crate::protocol::rest::ErrorResponse),
        (status = 422, description = "Invalid geometry or settings; `field` names it", body = crate::protocol::rest::ErrorResponse),
        (status = 429, description = "More creations than limits.session_creations_per_min (`rate_limited`)", body = crate::protocol::rest::ErrorResponse),
        (status = 503, description = "At limits.max_sessions (`at_capacity`), past limits.max_memory_mb (`memory_budget`), or shutting down", body = crate::protocol::rest::ErrorResponse),
    ),
    security((), ("bearer" = []))
)]
pub(super) async fn create_session(
    State(app): State<AppState>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
    req: Request,
) -> Result<(StatusCode, Json<SessionCreated>), ApiError> {
    require_admin(&app, &headers, query.as_deref())?;
    let JsonBody(body) = JsonBody::<CreateSession>::from_request_checked(req, &app).await?;
    let registry = app.registry.clone();
    let (session, token) = tokio::task::spawn_blocking(move || registry.create(body))
        .await
        .map_err(|e| {
            ApiError::new(
                StatusCode::INTERNAL_SERVER_ERROR,
                "internal",
                format!("session creation failed: {e}"),
            )
        })??;
    let created = SessionCreated {
        stream: format!("/v1/sessions/{}/stream", session.id()),
        id: session.id().to_string(),
        token,
        session: session.info(),
    };
    Ok((StatusCode::CREATED, Json(created)))
}

impl<T: serde::de::DeserializeOwned> JsonBody<T> {
    /// Reads the body after the handler has checked credentials (so an unauthenticated request
    /// gets 401/403, not a body error).
    pub(super) async fn from_request_checked(
        req: Request,
        app: &AppState,
    ) -> Result<Self, ApiError> {
        <Self as axum::extract::FromRequest<AppState>>::from_request(req, app).await
    }
}

/// Lists sessions.
#[utoipa::path(
    get,
    path = "/v1/sessions",
    tag = "sessions",
    responses(
        (status = 200, body = SessionList),
        (status = 401, body = crate::protocol::rest::ErrorResponse),
        (status = 403, body = crate::protocol::rest::ErrorResponse),
    ),
    security((), ("bearer" = []))
)]
pub(super) async fn list_sessions(
    State(app): State<AppState>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
) -> Result<Json<SessionList>, ApiError> {
    require_admin(&app, &headers, query.as_deref())?;
    let sessions = app.registry.list().iter().map(|s| s.summary()).collect();
    Ok(Json(SessionList { sessions }))
}

/// Describes a session with its current calibration.
#[utoipa::path(
    get,
    path = "/v1/sessions/{id}",
    tag = "sessions",
    params(("id" = String, Path, description = "Session id")),
    responses(
        (status = 200, body = SessionInfo),
        (status = 401, body = crate::protocol::rest::ErrorResponse),
        (status = 403, body = crate::protocol::rest::ErrorResponse),
        (status = 404, body = crate::protocol::rest::ErrorResponse),
    ),
    security(("bearer" = []), ("token_query" = []))
)]
pub(super) async fn inspect_session(
    State(app): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
) -> Result<Json<SessionInfo>, ApiError> {
    let s = session_access(&app, &id, &headers, query.as_deref())?;
    Ok(Json(s.info()))
}

/// Deletes a session: its pipeline finishes what it holds, its streams close.
#[utoipa::path(
    delete,
    path = "/v1/sessions/{id}",
    tag = "sessions",
    params(("id" = String, Path, description = "Session id")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 401, body = crate::protocol::rest::ErrorResponse),
        (status = 403, description = "Needs the admin key when one is configured, else the session token", body = crate::protocol::rest::ErrorResponse),
        (status = 404, body = crate::protocol::rest::ErrorResponse),
    ),
    security(("bearer" = []))
)]
pub(super) async fn delete_session(
    State(app): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
) -> Result<StatusCode, ApiError> {
    if app.registry.config().admin_key.is_some() {
        require_admin(&app, &headers, query.as_deref())?;
        app.registry
            .get(&id)
            .ok_or_else(|| ApiError::no_session(&id))?;
    } else {
        session_access(&app, &id, &headers, query.as_deref())?;
    }
    app.registry
        .remove(&id, "session deleted")
        .ok_or_else(|| ApiError::no_session(&id))?;
    Ok(StatusCode::NO_CONTENT)
}

/// The latest track estimate.
#[utoipa::path(
    get,
    path = "/v1/sessions/{id}/tracks",
    tag = "tracks",
    params(("id" = String, Path, description = "Session id")),
    responses(
        (status = 200, body = TracksSnapshot),
        (status = 404, description = "Unknown session, or no step has run yet (`no_step_yet`)", body = crate::protocol::rest::ErrorResponse),
    ),
    security(("bearer" = []), ("token_query" = []))
)]
pub(super) async fn current_tracks(
    State(app): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
) -> Result<Json<TracksSnapshot>, ApiError> {
    let s = session_access(&app, &id, &headers, query.as_deref())?;
    s.latest_tracks().map(Json).ok_or_else(|| {
        ApiError::new(
            StatusCode::NOT_FOUND,
            "no_step_yet",
            "the tracker has not run a step yet (it needs one step of audio)",
        )
    })
}

/// Query of the track history.
#[derive(Debug, Deserialize, utoipa::IntoParams)]
#[serde(deny_unknown_fields)]
pub(super) struct HistoryQuery {
    /// First step wanted (default: the oldest held).
    from_step: Option<u64>,
    /// Most steps returned (default and maximum: limits.history_steps).
    limit: Option<usize>,
    /// The session token, for clients that cannot set headers.
    #[allow(dead_code)]
    token: Option<String>,
}

/// Recent track estimates (a bounded ring of limits.history_steps steps).
#[utoipa::path(
    get,
    path = "/v1/sessions/{id}/tracks/history",
    tag = "tracks",
    params(("id" = String, Path, description = "Session id"), HistoryQuery),
    responses(
        (status = 200, body = TrackHistory),
        (status = 400, body = crate::protocol::rest::ErrorResponse),
        (status = 404, body = crate::protocol::rest::ErrorResponse),
    ),
    security(("bearer" = []), ("token_query" = []))
)]
pub(super) async fn track_history(
    State(app): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
) -> Result<Json<TrackHistory>, ApiError> {
    let s = session_access(&app, &id, &headers, query.as_deref())?;
    let q: HistoryQuery = match query.as_deref() {
        Some(raw) => {
            Query::<HistoryQuery>::try_from_uri(
                &format!("/?{raw}")
                    .parse()
                    .map_err(|_| bad_query("the query string"))?,
            )
            .map_err(|e| bad_query(&e.body_text()))?
            .0
        }
        None => HistoryQuery {
            from_step: None,
            limit: None,
            token: None,
        },
    };
    let max = app.registry.config().limits.history_steps;
    Ok(Json(
        s.history(q.from_step, q.limit.unwrap_or(max).min(max)),
    ))
}

fn bad_query(what: &str) -> ApiError {
    ApiError::new(
        StatusCode::BAD_REQUEST,
        "bad_query",
        format!("invalid query: {what}"),
    )
}

/// The session's metrics.
#[utoipa::path(
    get,
    path = "/v1/sessions/{id}/metrics",
    tag = "sessions",
    params(("id" = String, Path, description = "Session id")),
    responses((status = 200, body = SessionMetrics), (status = 404, body = crate::protocol::rest::ErrorResponse)),
    security(("bearer" = []), ("token_query" = []))
)]
pub(super) async fn session_metrics(
    State(app): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
) -> Result<Json<SessionMetrics>, ApiError> {
    let s = session_access(&app, &id, &headers, query.as_deref())?;
    Ok(Json(s.metrics()))
}

/// Liveness: the process answers.
#[utoipa::path(get, path = "/healthz", tag = "server", responses((status = 200, body = Health)))]
pub(super) async fn healthz(State(app): State<AppState>) -> Json<Health> {
    Json(Health {
        status: "ok".into(),
        sessions: app.registry.len(),
    })
}

/// Readiness: 200 while the server accepts sessions, 503 when draining or full.
#[utoipa::path(
    get,
    path = "/readyz",
    tag = "server",
    responses((status = 200, body = Health), (status = 503, body = Health))
)]
pub(super) async fn readyz(State(app): State<AppState>) -> (StatusCode, Json<Health>) {
    let sessions = app.registry.len();
    let (status, text) = if app.registry.draining() {
        (StatusCode::SERVICE_UNAVAILABLE, "draining")
    } else if sessions >= app.registry.config().limits.max_sessions {
        (StatusCode::SERVICE_UNAVAILABLE, "full")
    } else {
        (StatusCode::OK, "ready")
    };
    (
        status,
        Json(Health {
            status: text.into(),
            sessions,
        }),
    )
}

/// Prometheus text exposition of the server's metrics.
#[utoipa::path(
    get,
    path = "/metrics",
    tag = "server",
    responses((status = 200, description = "Prometheus text format 0.0.4", content_type = "text/plain"))
)]
pub(super) async fn prometheus(State(app): State<AppState>) -> Response {
    let text = app.registry.metrics().render(&app.registry.snapshot());
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text).into_response()
}

/// 404 in the API's error form for unknown paths.
pub(super) async fn not_found() -> ApiError {
    ApiError::new(StatusCode::NOT_FOUND, "not_found", "no such endpoint")
}
