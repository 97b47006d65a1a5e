//! The browser dashboard (clients/web/): its files embedded in the binary and served at `/` and
//! `/dashboard/assets/{file}`, and the two read-only endpoints only it uses:
//!
//! - `GET /dashboard/api/demo`: the demo session's id and token when `avsep serve --demo` runs
//!   one (404 otherwise), for whoever may list sessions (the admin key when one is set). The
//!   token opens that session only, and its data is simulated.
//! - `GET /dashboard/api/sessions/{id}/detections`: the latest accepted camera frame of each
//!   camera, for the camera panel (the session's token or the admin key).
//!
//! Neither is part of the versioned `/v1` API.

use axum::Json;
use axum::Router;
use axum::extract::{Path, RawQuery, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde::Serialize;

use crate::scene::convert::box_to_file;
use crate::scene::format::DetectionLine;

use super::app::AppState;
use super::demo::DemoAccess;
use super::error::ApiError;
use super::routes::{require_admin, session_access};

/// One embedded file.
struct Asset {
    name: &'static str,
    content_type: &'static str,
    body: &'static [u8],
}

macro_rules! asset {
    ($name:literal, $type:expr) => {
        Asset {
            name: $name,
            content_type: $type,
            body: include_bytes!(concat!(env!("CARGO_MANIFEST_DIR"), "/clients/web/", $name)),
        }
    };
}

const JS: &str = "text/javascript; charset=utf-8";

/// The dashboard's files (clients/web/), compiled in so the binary serves them anywhere.
const ASSETS: &[Asset] = &[
    asset!("index.html", "text/html; charset=utf-8"),
    asset!("style.css", "text/css; charset=utf-8"),
    asset!("main.js", JS),
    asset!("api.js", JS),
    asset!("sessions.js", JS),
    asset!("live.js", JS),
    asset!("stream.js", JS),
    asset!("labels.js", JS),
    asset!("roommap.js", JS),
    asset!("camera.js", JS),
    asset!("audio.js", JS),
    asset!("metrics.js", JS),
];

/// Same-origin only: no inline script, no third-party loads; WebSockets to this server.
const CSP: &str = "default-src 'self'; connect-src 'self' ws: wss:; img-src 'self' data:; \
                   object-src 'none'; base-uri 'none'; frame-ancestors 'none'";

/// The dashboard's routes, merged into the API router.
pub(super) fn routes() -> Router<AppState> {
    Router::new()
        .route("/", get(index))
        .route("/dashboard/assets/{file}", get(asset))
        .route("/dashboard/api/demo", get(demo))
        .route("/dashboard/api/sessions/{id}/detections", get(detections))
}

fn serve(a: &Asset) -> Response {
    (
        [
            (header::CONTENT_TYPE, a.content_type),
            // The files change with the binary; revalidating is cheap on a local server.
            (header::CACHE_CONTROL, "no-cache"),
            (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
            (header::CONTENT_SECURITY_POLICY, CSP),
        ],
        a.body,
    )
        .into_response()
}

async fn index() -> Response {
    ASSETS
        .iter()
        .find(|a| a.name == "index.html")
        .map_or_else(|| StatusCode::NOT_FOUND.into_response(), serve)
}

async fn asset(Path(file): Path<String>) -> Response {
    match ASSETS.iter().find(|a| a.name == file) {
        Some(a) => serve(a),
        None => ApiError::new(
            StatusCode::NOT_FOUND,
            "not_found",
            format!("no dashboard file {file:?}"),
        )
        .into_response(),
    }
}

async fn demo(
    State(app): State<AppState>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
) -> Result<Json<DemoAccess>, ApiError> {
    require_admin(&app, &headers, query.as_deref())?;
    app.registry.demo().cloned().map(Json).ok_or_else(|| {
        ApiError::new(
            StatusCode::NOT_FOUND,
            "no_demo",
            "no demo session (start the server with --demo; it appears once simulated)",
        )
    })
}

/// Answer of the detections endpoint.
#[derive(Debug, Serialize)]
struct LatestDetections {
    /// The latest accepted frame of each camera that sent one.
    cameras: Vec<DetectionLine>,
}

async fn detections(
    State(app): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
) -> Result<Json<LatestDetections>, ApiError> {
    let s = session_access(&app, &id, &headers, query.as_deref())?;
    let layout = s.layout();
    let cameras = s
        .latest_detections()
        .into_iter()
        .filter_map(|f| {
            Some(DetectionLine {
                t: f.t,
                camera: layout.cameras.get(f.camera)?.id.clone(),
                boxes: f.boxes.iter().map(box_to_file).collect(),
            })
        })
        .collect();
    Ok(Json(LatestDetections { cameras }))
}
