//! JSON Schemas of the live-session messages and of the pipeline settings, generated from the
//! types so the copies under `api/` cannot drift from the code (a test compares them).

use schemars::schema_for;

use crate::pipeline::PipelineConfig;

use super::rest::PIPELINE_CONFIG_SCHEMA;
use super::zenoh_keys::ClosedMessage;
use super::{ClientMessage, ServerMessage};

/// `(file name under api/, schema)` for every message document of the stream protocol.
pub fn protocol_schemas() -> Vec<(&'static str, serde_json::Value)> {
    let v = |s: schemars::Schema| serde_json::to_value(s).unwrap_or_default();
    vec![
        ("client-message.schema.json", v(schema_for!(ClientMessage))),
        ("server-message.schema.json", v(schema_for!(ServerMessage))),
        (PIPELINE_CONFIG_SCHEMA, v(schema_for!(PipelineConfig))),
        (
            "zenoh-closed-message.schema.json",
            v(schema_for!(ClosedMessage)),
        ),
    ]
}
