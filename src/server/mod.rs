//! The network server: sessions hosted behind a REST API and a WebSocket stream.
//!
//! A [`registry::Registry`] holds the sessions; each session ([`session::SessionHandle`]) owns a
//! pipeline on its own worker thread fed through a bounded queue, and broadcasts what it
//! produces. Transports (the WebSocket and Zenoh) only `submit` input and `subscribe` to
//! output, so they can attach to the same session side by side; the Zenoh transport
//! ([`zenoh_transport::ZenohTransport`]) attaches to every session the registry holds. See api/openapi.yaml and
//! api/protocol.md for the contracts.

pub mod app;
pub mod auth;
pub mod budget;
mod calibration;
pub mod client;
pub mod config;
mod dashboard;
pub mod demo;
pub mod engine;
pub mod error;
pub mod metrics;
pub mod openapi;
pub mod rate_limit;
pub mod registry;
mod routes;
pub mod session;
pub mod stream;
mod worker;
pub mod zenoh_transport;

pub use app::{Server, router};
pub use config::{Execution, Limits, ServerConfig};
pub use registry::Registry;
pub use session::{ClientId, Input, Output, Rejection, SessionHandle};

/// `(file name under api/, schema)` of the server's own documents (its configuration).
pub fn server_schemas() -> Vec<(&'static str, serde_json::Value)> {
    let v = serde_json::to_value(schemars::schema_for!(ServerConfig)).unwrap_or_default();
    vec![("server-config.schema.json", v)]
}
