//! The OpenAPI document of the REST API, generated from the handlers' annotations and the body
//! types. Fields typed by the scene format or the pipeline settings refer to their JSON Schema
//! files under `api/` (see `protocol::rest`).

use utoipa::openapi::security::{ApiKey, ApiKeyValue, Http, HttpAuthScheme, SecurityScheme};
use utoipa::{Modify, OpenApi};

use crate::protocol::ErrorBody;
use crate::protocol::rest::{
    ArrayCalibration, CameraCalibration, CreateSession, ErrorResponse, FrameCounts, Health,
    LatencySummary, SessionCreated, SessionInfo, SessionList, SessionMetrics, SessionState,
    SessionSummary, TrackHistory, TracksSnapshot,
};

use super::{calibration, routes, stream};

/// The REST API's OpenAPI description.
#[derive(OpenApi)]
#[openapi(
    info(
        title = "avsep",
        description = "Sessions of online audio-visual multi-speaker tracking and separation. \
            Create a session (a calibrated room), stream audio and detections into it over the \
            WebSocket of api/protocol.md, and read tracks, separated audio and metrics.",
        license(name = "MIT OR Apache-2.0")
    ),
    paths(
        routes::create_session,
        routes::list_sessions,
        routes::inspect_session,
        routes::delete_session,
        calibration::put_array,
        calibration::put_camera,
        calibration::get_settings,
        calibration::patch_settings,
        routes::current_tracks,
        routes::track_history,
        routes::session_metrics,
        stream::open_stream,
        routes::healthz,
        routes::readyz,
        routes::prometheus,
    ),
    components(schemas(
        CreateSession,
        SessionCreated,
        SessionInfo,
        SessionSummary,
        SessionList,
        SessionState,
        ArrayCalibration,
        CameraCalibration,
        TracksSnapshot,
        TrackHistory,
        SessionMetrics,
        LatencySummary,
        FrameCounts,
        ErrorResponse,
        ErrorBody,
        Health,
    )),
    modifiers(&Security),
    tags(
        (name = "sessions", description = "Create, list, inspect and delete sessions"),
        (name = "calibration", description = "Replace sensor calibration on a running session"),
        (name = "settings", description = "Read and change pipeline settings"),
        (name = "tracks", description = "Current tracks and recent history"),
        (name = "stream", description = "The WebSocket stream (protocol in api/protocol.md)"),
        (name = "server", description = "Health, readiness and Prometheus metrics"),
    )
)]
pub struct ApiDoc;

/// Adds the credentials: a bearer secret (session token or admin key), or the `token` query
/// parameter for browsers' WebSockets.
struct Security;

impl Modify for Security {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        let components = openapi.components.get_or_insert_with(Default::default);
        let mut bearer = Http::new(HttpAuthScheme::Bearer);
        bearer.description = Some(
            "The session token returned at creation (opens that session), or the admin key \
             (guards creating, listing and deleting sessions when configured; opens every session)"
                .into(),
        );
        components.add_security_scheme("bearer", SecurityScheme::Http(bearer));
        components.add_security_scheme(
            "token_query",
            SecurityScheme::ApiKey(ApiKey::Query(ApiKeyValue::with_description(
                "token",
                "The same secret as a query parameter, for browsers' WebSockets",
            ))),
        );
    }
}

/// The document as YAML (what `api/openapi.yaml` holds).
pub fn openapi_yaml() -> String {
    ApiDoc::openapi()
        .to_yaml()
        .unwrap_or_else(|e| format!("# cannot render the OpenAPI document: {e}\n"))
}
