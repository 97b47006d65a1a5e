//! Live changes to a running session: an array's microphone positions, a camera's calibration,
//! and the settings that can change live. Each goes through the session's queue, so the
//! pipeline applies it after the input sent before it, at its next step, keeping its tracks.

use axum::Json;
use axum::extract::{Path, RawQuery, Request, State};
use axum::http::{HeaderMap, StatusCode};

use crate::pipeline::PipelineConfig;
use crate::protocol::rest::{ArrayCalibration, CameraCalibration, SessionInfo};
use crate::scene::convert::{array_from_file, camera_from_file, layout_from_file, layout_to_file};
use crate::scene::format::SceneFile;

use super::app::AppState;
use super::error::{ApiError, JsonBody, parse_json};
use super::routes::session_access;
use super::session::SessionHandle;

/// The session's layout in scene-format form, to edit one sensor and rebuild it.
fn scene_of(s: &SessionHandle) -> SceneFile {
    layout_to_file(&s.layout())
}

fn unknown(kind: &str, id: &str, known: Vec<String>) -> ApiError {
    ApiError::new(
        StatusCode::NOT_FOUND,
        "not_found",
        format!("no {kind} {id:?} in this session (it has {known:?})"),
    )
    .field(kind)
}

fn running(s: &SessionHandle) -> Result<(), ApiError> {
    use crate::protocol::rest::SessionState;
    match s.state() {
        SessionState::Running => Ok(()),
        state => Err(ApiError::new(
            StatusCode::CONFLICT,
            "session_closed",
            format!(
                "the session is {}; it takes no more changes",
                state.as_str()
            ),
        )),
    }
}

/// Replaces an array's microphone positions.
#[utoipa::path(
    put,
    path = "/v1/sessions/{id}/arrays/{array}",
    tag = "calibration",
    params(("id" = String, Path, description = "Session id"), ("array" = String, Path, description = "Array id")),
    request_body = ArrayCalibration,
    responses(
        (status = 200, description = "Applied; the session with its new calibration", body = SessionInfo),
        (status = 404, description = "Unknown session or array", body = crate::protocol::rest::ErrorResponse),
        (status = 409, description = "Session not running, or a change that cannot happen live (channels, microphone count)", body = crate::protocol::rest::ErrorResponse),
        (status = 503, description = "The new layout's memory bound would pass limits.max_memory_mb (`memory_budget`)", body = crate::protocol::rest::ErrorResponse),
        (status = 422, description = "Invalid positions; `field` names them", body = crate::protocol::rest::ErrorResponse),
        (status = 429, description = "The session's queue is full", body = crate::protocol::rest::ErrorResponse),
    ),
    security(("bearer" = []), ("token_query" = []))
)]
pub(super) async fn put_array(
    State(app): State<AppState>,
    Path((id, array)): Path<(String, String)>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
    req: Request,
) -> Result<Json<SessionInfo>, ApiError> {
    let s = session_access(&app, &id, &headers, query.as_deref())?;
    let JsonBody(body) = JsonBody::<ArrayCalibration>::from_request_checked(req, &app).await?;
    running(&s)?;
    // Held until the new layout is applied: a concurrent change waits, then builds on it.
    let _change = s.begin_change().await;
    let mut scene = scene_of(&s);
    let known = scene.arrays.iter().map(|a| a.id.clone()).collect();
    let a = scene
        .arrays
        .iter_mut()
        .find(|a| a.id == array)
        .ok_or_else(|| unknown("array", &array, known))?;
    if body.mics.len() != a.mics.len() {
        return Err(ApiError::new(
            StatusCode::CONFLICT,
            "not_live",
            format!(
                "the array has {} microphones; recalibration cannot add or remove any",
                a.mics.len()
            ),
        )
        .field("mics"));
    }
    if let Some(ch) = &body.channels
        && *ch != a.channels
    {
        return Err(ApiError::new(
            StatusCode::CONFLICT,
            "not_live",
            "the audio columns of a running session cannot change",
        )
        .field("channels"));
    }
    a.mics = body.mics;
    array_from_file(a).map_err(|e| ApiError::geometry(e, ""))?;
    let layout = layout_from_file(&scene).map_err(|e| ApiError::geometry(e, ""))?;
    // Only this array's spacing changed, so it is the one a limit names.
    s.limits().check_layout(&layout).map_err(|e| {
        let e = crate::geometry::GeometryError::new("mics", e.message);
        ApiError::geometry(e, "")
    })?;
    let _admitted = app.registry.admit_change(s.id(), &layout, &s.settings())?;
    s.recalibrate(layout).await?;
    Ok(Json(s.info()))
}

/// Replaces a camera's calibration (projection, or K with R and t, and distortion).
#[utoipa::path(
    put,
    path = "/v1/sessions/{id}/cameras/{camera}",
    tag = "calibration",
    params(("id" = String, Path, description = "Session id"), ("camera" = String, Path, description = "Camera id")),
    request_body = CameraCalibration,
    responses(
        (status = 200, description = "Applied; the session with its new calibration", body = SessionInfo),
        (status = 404, description = "Unknown session or camera", body = crate::protocol::rest::ErrorResponse),
        (status = 409, description = "Session not running", body = crate::protocol::rest::ErrorResponse),
        (status = 422, description = "Invalid calibration; `field` names it", body = crate::protocol::rest::ErrorResponse),
        (status = 429, description = "The session's queue is full", body = crate::protocol::rest::ErrorResponse),
    ),
    security(("bearer" = []), ("token_query" = []))
)]
pub(super) async fn put_camera(
    State(app): State<AppState>,
    Path((id, camera)): Path<(String, String)>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
    req: Request,
) -> Result<Json<SessionInfo>, ApiError> {
    let s = session_access(&app, &id, &headers, query.as_deref())?;
    let JsonBody(body) = JsonBody::<CameraCalibration>::from_request_checked(req, &app).await?;
    running(&s)?;
    // Held until the new layout is applied: a concurrent change waits, then builds on it.
    let _change = s.begin_change().await;
    let mut scene = scene_of(&s);
    let known = scene.cameras.iter().map(|c| c.id.clone()).collect();
    let c = scene
        .cameras
        .iter_mut()
        .find(|c| c.id == camera)
        .ok_or_else(|| unknown("camera", &camera, known))?;
    let file = body.to_file(c);
    camera_from_file(&file).map_err(|e| ApiError::geometry(e, ""))?;
    *c = file;
    let layout = layout_from_file(&scene).map_err(|e| ApiError::geometry(e, ""))?;
    s.recalibrate(layout).await?;
    Ok(Json(s.info()))
}

/// The settings in force.
#[utoipa::path(
    get,
    path = "/v1/sessions/{id}/settings",
    tag = "settings",
    params(("id" = String, Path, description = "Session id")),
    responses(
        (status = 200, description = "The pipeline settings (see pipeline-config.schema.json)", body = Object),
        (status = 404, body = crate::protocol::rest::ErrorResponse),
    ),
    security(("bearer" = []), ("token_query" = []))
)]
pub(super) async fn get_settings(
    State(app): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
) -> Result<Json<PipelineConfig>, ApiError> {
    let s = session_access(&app, &id, &headers, query.as_deref())?;
    Ok(Json(s.settings()))
}

/// Changes settings (a JSON merge patch over the settings in force). What can change live:
/// `camera_wait_s`, `min_box_score`, `localized_min_fresh_sigmas`, `max_gap_s`, `max_lead_s`,
/// `cameras`, the tracker's sensor
/// models (`track.audio_position`, `track.audio_direction`, `track.camera` noise, detection and
/// clutter), the clutter-rate estimation (`track.clutter`; turned off, every sensor is back on its
/// configured rate) and the separator except `separate.frame` and `separate.hop`; any other change
/// is refused with 409 `not_live` naming the field. A refused change changes nothing.
#[utoipa::path(
    patch,
    path = "/v1/sessions/{id}/settings",
    tag = "settings",
    params(("id" = String, Path, description = "Session id")),
    request_body(content = Object, description = "JSON merge patch (RFC 7386) over the settings", content_type = "application/merge-patch+json"),
    responses(
        (status = 200, description = "Applied; the settings now in force", body = Object),
        (status = 409, description = "A setting that cannot change on a running session (`not_live`), or the session is not running", body = crate::protocol::rest::ErrorResponse),
        (status = 503, description = "The new settings' memory bound would pass limits.max_memory_mb (`memory_budget`)", body = crate::protocol::rest::ErrorResponse),
        (status = 422, description = "Unknown field or value out of range; `field` names it", body = crate::protocol::rest::ErrorResponse),
        (status = 429, description = "The session's queue is full", body = crate::protocol::rest::ErrorResponse),
    ),
    security(("bearer" = []), ("token_query" = []))
)]
pub(super) async fn patch_settings(
    State(app): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    RawQuery(query): RawQuery,
    req: Request,
) -> Result<Json<PipelineConfig>, ApiError> {
    let s = session_access(&app, &id, &headers, query.as_deref())?;
    let JsonBody(patch) = JsonBody::<serde_json::Value>::from_request_checked(req, &app).await?;
    running(&s)?;
    if !patch.is_object() {
        return Err(ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid",
            "the body must be a JSON object (a merge patch over the settings)",
        ));
    }
    // Held until the merged settings are applied: a concurrent patch waits, then merges on them.
    let _change = s.begin_change().await;
    let mut merged = serde_json::to_value(s.settings())
        .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, "internal", e.to_string()))?;
    merge_patch(&mut merged, &patch);
    let text = merged.to_string();
    let settings: PipelineConfig = parse_json(text.as_bytes())?;
    settings.validate().map_err(|e| ApiError::config(e, ""))?;
    s.limits()
        .check_settings(&settings)
        .map_err(|e| ApiError::config(e, ""))?;
    // Settings no pipeline could use are refused by the change itself (a frame, which cannot
    // change live, as not live), not by the budget.
    let _admitted = app.registry.admit_change(s.id(), &s.layout(), &settings)?;
    s.configure(settings).await?;
    Ok(Json(s.settings()))
}

/// RFC 7386 JSON merge patch: objects merge recursively, `null` removes, anything else replaces.
fn merge_patch(target: &mut serde_json::Value, patch: &serde_json::Value) {
    let serde_json::Value::Object(p) = patch else {
        *target = patch.clone();
        return;
    };
    if !target.is_object() {
        *target = serde_json::Value::Object(serde_json::Map::new());
    }
    if let serde_json::Value::Object(t) = target {
        for (k, v) in p {
            if v.is_null() {
                t.remove(k);
            } else {
                merge_patch(t.entry(k.clone()).or_insert(serde_json::Value::Null), v);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn merge_patch_follows_rfc_7386() {
        let mut t = json!({"a": 1, "b": {"c": 2, "d": 3}, "e": [1]});
        merge_patch(
            &mut t,
            &json!({"b": {"c": 5, "d": null}, "e": [2, 3], "f": true}),
        );
        assert_eq!(t, json!({"a": 1, "b": {"c": 5}, "e": [2, 3], "f": true}));
    }
}
