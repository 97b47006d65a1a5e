//! Session management over Zenoh, so an edge device needs no HTTP: `avsep/sessions/create`
//! (payload: the body of `POST /v1/sessions`; answer: the same `SessionCreated`, token
//! included), `avsep/sessions/list` and `avsep/sessions/<id>`. Credentials ride in the query's
//! attachment: the admin key (when configured) for create and list, the session's token or the
//! admin key for inspect. Errors are `reply_err` with the REST error body `{"error": {...}}`.
//!
//! The queryable callbacks only `try_send` the query into a bounded queue (a full queue answers
//! `busy` at once); one task serves the queue, building pipelines on the blocking pool.

use std::sync::Arc;

use tokio::sync::mpsc::error::TrySendError;
use tokio::sync::mpsc::{Receiver, Sender};
use zenoh::Wait;
use zenoh::bytes::Encoding;
use zenoh::query::Query;

use crate::protocol::ErrorBody;
use crate::protocol::rest::{CreateSession, ErrorResponse, SessionCreated, SessionList};
use crate::protocol::zenoh_keys::SessionQuery;
use crate::server::auth;
use crate::server::error::parse_json;

use super::Shared;
use super::inbound::check_credential;

fn error(code: &str, field: Option<&str>, message: impl Into<String>) -> ErrorBody {
    ErrorBody {
        code: code.to_string(),
        message: message.into(),
        field: field.map(str::to_string),
    }
}

fn reply_error(q: &Query, e: ErrorBody) {
    let body = serde_json::to_vec(&ErrorResponse { error: e }).unwrap_or_default();
    if let Err(err) = q
        .reply_err(body)
        .encoding(Encoding::APPLICATION_JSON)
        .wait()
    {
        tracing::debug!("zenoh error reply failed: {err}");
    }
}

/// The callback of a management queryable: queues the query without blocking. The `create`
/// queryable takes only creates; the `avsep/sessions/**` one takes everything else (a create
/// reaching it as well is left to the `create` queryable).
pub(super) fn enqueue(tx: Sender<Query>, create: bool) -> impl Fn(Query) + Send + Sync + 'static {
    move |q| {
        let is_create = SessionQuery::parse(q.key_expr().as_str()) == Some(SessionQuery::Create);
        if is_create != create {
            return;
        }
        match tx.try_send(q) {
            Ok(()) => {}
            Err(TrySendError::Full(q)) => reply_error(
                &q,
                error(
                    "busy",
                    None,
                    "the server's query queue is full (zenoh.query_queue); retry shortly",
                ),
            ),
            Err(TrySendError::Closed(q)) => {
                reply_error(&q, error("draining", None, "the server is shutting down"))
            }
        }
    }
}

/// Serves queued queries one at a time until the transport closes.
pub(super) async fn serve(shared: Arc<Shared>, mut rx: Receiver<Query>) {
    while let Some(q) = rx.recv().await {
        let result = answer(&shared, &q).await;
        let key = q.key_expr().clone();
        match result {
            Ok(Some(body)) => {
                if let Err(e) = q
                    .reply(key, body)
                    .encoding(Encoding::APPLICATION_JSON)
                    .await
                {
                    tracing::debug!("zenoh reply failed: {e}");
                }
            }
            // Not ours to answer (a session held by another server).
            Ok(None) => {}
            Err(e) => reply_error(&q, e),
        }
    }
}

fn admin_only(shared: &Shared, q: &Query) -> Result<(), ErrorBody> {
    let Some(key) = shared.registry.config().admin_key.as_deref() else {
        return Ok(());
    };
    check_credential(
        q.attachment(),
        |p| auth::same_secret(key, p),
        "this query (admin key)",
    )
    .map_err(|(code, message)| error(code, Some("attachment"), message))
}

async fn answer(shared: &Shared, q: &Query) -> Result<Option<Vec<u8>>, ErrorBody> {
    let key = q.key_expr().as_str();
    let Some(what) = SessionQuery::parse(key) else {
        return Err(error(
            "unknown_key",
            Some("key"),
            format!(
                "{key:?} is not a session query (avsep/sessions/create, avsep/sessions/list, avsep/sessions/<id>)"
            ),
        ));
    };
    let registry = &shared.registry;
    let body = match what {
        SessionQuery::Create => {
            admin_only(shared, q)?;
            // Measured before it is copied.
            let max = registry.config().limits.max_body_bytes;
            if q.payload().map_or(0, |p| p.len()) > max {
                return Err(error(
                    "too_large",
                    Some("payload"),
                    format!("the body exceeds limits.max_body_bytes ({max})"),
                ));
            }
            let payload = q
                .payload()
                .map(|p| p.to_bytes().into_owned())
                .unwrap_or_default();
            let req: CreateSession = parse_json(&payload).map_err(|e| e.body)?;
            let r = registry.clone();
            let (session, token) = tokio::task::spawn_blocking(move || r.create(req))
                .await
                .map_err(|e| error("internal", None, format!("session creation failed: {e}")))?
                .map_err(|e| e.body)?;
            serde_json::to_vec(&SessionCreated {
                stream: format!("/v1/sessions/{}/stream", session.id()),
                id: session.id().to_string(),
                token,
                session: session.info(),
            })
        }
        SessionQuery::List => {
            admin_only(shared, q)?;
            let sessions = registry.list().iter().map(|s| s.summary()).collect();
            serde_json::to_vec(&SessionList { sessions })
        }
        SessionQuery::Inspect(id) => {
            let Some(s) = registry.get(&id) else {
                return Ok(None);
            };
            let admin = registry.config().admin_key.as_deref();
            let accepts =
                |p: &str| s.token_matches(p) || admin.is_some_and(|k| auth::same_secret(k, p));
            check_credential(q.attachment(), accepts, "this session")
                .map_err(|(code, message)| error(code, Some("attachment"), message))?;
            serde_json::to_vec(&s.info())
        }
    };
    body.map(Some)
        .map_err(|e| error("internal", None, format!("cannot encode the answer: {e}")))
}
