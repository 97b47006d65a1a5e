//! REST errors: `{"error": {"code", "message", "field"}}` with the status that fits, and a JSON
//! body extractor whose refusals take the same form and name the field at fault.

use axum::Json;
use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::de::DeserializeOwned;

use crate::geometry::GeometryError;
use crate::pipeline::ConfigError;
use crate::protocol::ErrorBody;
use crate::protocol::rest::ErrorResponse;

use super::session::{ControlError, Rejection};

/// An error answer.
#[derive(Debug, Clone, PartialEq)]
pub struct ApiError {
    /// HTTP status.
    pub status: StatusCode,
    /// Body.
    pub body: ErrorBody,
}

impl ApiError {
    /// An error with `status`, `code` and `message`.
    pub fn new(status: StatusCode, code: &str, message: impl Into<String>) -> Self {
        Self {
            status,
            body: ErrorBody {
                code: code.to_string(),
                message: message.into(),
                field: None,
            },
        }
    }

    /// The same error naming `field`.
    pub fn field(mut self, field: impl Into<String>) -> Self {
        let f = field.into();
        self.body.field = (!f.is_empty()).then_some(f);
        self
    }

    /// 401: no credential presented.
    pub fn unauthorized(what: &str) -> Self {
        Self::new(
            StatusCode::UNAUTHORIZED,
            "unauthorized",
            format!(
                "{what} needs a credential: `Authorization: Bearer <secret>` or `?token=<secret>`"
            ),
        )
    }

    /// 403: a credential that does not open this resource.
    pub fn forbidden(what: &str) -> Self {
        Self::new(
            StatusCode::FORBIDDEN,
            "forbidden",
            format!("the credential presented does not open {what}"),
        )
    }

    /// 404 for an unknown session.
    pub fn no_session(id: &str) -> Self {
        Self::new(
            StatusCode::NOT_FOUND,
            "not_found",
            format!("no session {id:?}"),
        )
        .field("id")
    }

    /// 422 from a geometry error, with its field under `prefix`.
    pub fn geometry(e: GeometryError, prefix: &str) -> Self {
        let e = if prefix.is_empty() {
            e
        } else {
            e.within(prefix)
        };
        Self::new(StatusCode::UNPROCESSABLE_ENTITY, "invalid", e.message).field(e.field)
    }

    /// 422 from a configuration error, with its field under `prefix`.
    pub fn config(e: ConfigError, prefix: &str) -> Self {
        let field = match (prefix.is_empty(), e.field.is_empty()) {
            (true, _) => e.field,
            (false, true) => prefix.to_string(),
            (false, false) => format!("{prefix}.{}", e.field),
        };
        Self::new(StatusCode::UNPROCESSABLE_ENTITY, "invalid", e.message).field(field)
    }
}

impl From<Rejection> for ApiError {
    fn from(r: Rejection) -> Self {
        let status = match r.code {
            "queue_full" | "too_many_clients" => StatusCode::TOO_MANY_REQUESTS,
            "session_closed" | "session_failed" => StatusCode::CONFLICT,
            "internal" => StatusCode::INTERNAL_SERVER_ERROR,
            _ => StatusCode::UNPROCESSABLE_ENTITY,
        };
        Self {
            status,
            body: r.to_body(),
        }
    }
}

impl From<ControlError> for ApiError {
    fn from(e: ControlError) -> Self {
        match e {
            ControlError::Invalid(e) => Self::config(e, "").with_status_for_live_change(),
            ControlError::Rejected(r) => r.into(),
            ControlError::Timeout => Self::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "timeout",
                "the session's pipeline did not apply the change in time (limits.control_timeout_s); it may still apply it",
            ),
            ControlError::Ended => Self::new(
                StatusCode::CONFLICT,
                "session_closed",
                "the session ended before applying the change",
            ),
        }
    }
}

impl ApiError {
    /// A setting that cannot change live conflicts with the running session (409); a value out
    /// of range stays 422.
    fn with_status_for_live_change(mut self) -> Self {
        if self.body.message.starts_with("cannot change") {
            self.status = StatusCode::CONFLICT;
            self.body.code = "not_live".into();
        }
        self
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let unauthorized = self.status == StatusCode::UNAUTHORIZED;
        let mut resp = (self.status, Json(ErrorResponse { error: self.body })).into_response();
        if unauthorized {
            resp.headers_mut()
                .insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer"));
        }
        resp
    }
}

/// A JSON request body; malformed JSON is 400, a body that does not fit the type is 422 naming
/// the field, and a body past `limits.max_body_bytes` is 413.
pub struct JsonBody<T>(pub T);

impl<S: Send + Sync, T: DeserializeOwned> FromRequest<S> for JsonBody<T> {
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &S) -> Result<Self, ApiError> {
        let bytes = Bytes::from_request(req, state).await.map_err(|e| {
            if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
                ApiError::new(
                    StatusCode::PAYLOAD_TOO_LARGE,
                    "too_large",
                    "the request body exceeds limits.max_body_bytes",
                )
            } else {
                ApiError::new(StatusCode::BAD_REQUEST, "bad_body", e.body_text())
            }
        })?;
        parse_json(&bytes).map(Self)
    }
}

/// Parses JSON with the error naming the path of the offending field.
pub fn parse_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    let de = &mut serde_json::Deserializer::from_slice(bytes);
    serde_path_to_error::deserialize(de).map_err(|e| {
        let path = e.path().to_string();
        let inner = e.into_inner();
        if inner.is_data() {
            ApiError::new(
                StatusCode::UNPROCESSABLE_ENTITY,
                "invalid",
                inner.to_string(),
            )
            .field(if path == "." { String::new() } else { path })
        } else {
            ApiError::new(
                StatusCode::BAD_REQUEST,
                "bad_json",
                format!("the body is not valid JSON: {inner}"),
            )
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::rest::CreateSession;

    #[test]
    fn body_errors_name_the_field() {
        let e = parse_json::<CreateSession>(b"{\"sample_rate\": 16000, ").unwrap_err();
        assert_eq!(
            (e.status, e.body.code.as_str()),
            (StatusCode::BAD_REQUEST, "bad_json")
        );
        let e = parse_json::<CreateSession>(
            br#"{"sample_rate": 16000, "arrays": [{"id": "a", "mics": [[0, 0]]}]}"#,
        )
        .unwrap_err();
        assert_eq!(e.status, StatusCode::UNPROCESSABLE_ENTITY);
        assert_eq!(e.body.field.as_deref(), Some("arrays[0].mics[0]"));
        let e = parse_json::<CreateSession>(
            br#"{"sample_rate": 16000, "arrays": [], "settings": {"track": {"survival": 1}}}"#,
        )
        .unwrap_err();
        assert!(
            e.body
                .field
                .as_deref()
                .unwrap()
                .starts_with("settings.track"),
            "{e:?}"
        );
    }

    #[test]
    fn rejections_map_to_statuses() {
        let r = Rejection::new("queue_full", "full");
        assert_eq!(ApiError::from(r).status, StatusCode::TOO_MANY_REQUESTS);
        let c = ControlError::Invalid(ConfigError::new(
            "step_s",
            "cannot change on a running session",
        ));
        let e = ApiError::from(c);
        assert_eq!(
            (e.status, e.body.code.as_str()),
            (StatusCode::CONFLICT, "not_live")
        );
    }
}
