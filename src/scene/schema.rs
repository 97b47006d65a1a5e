//! JSON Schemas of the scene format's files, generated from the wire types so the checked-in
//! copies under `api/` cannot drift from the code (a test compares them).

use schemars::schema_for;

use super::format::{
    AudioMeasurementLine, DetectionLine, PitchLine, SceneFile, TracksLine, TruthFile,
};

/// `(file name under api/, schema)` for every scene-format document.
pub fn scene_format_schemas() -> Vec<(&'static str, serde_json::Value)> {
    let v = |s: schemars::Schema| serde_json::to_value(s).unwrap_or_default();
    vec![
        ("scene.schema.json", v(schema_for!(SceneFile))),
        ("detections-line.schema.json", v(schema_for!(DetectionLine))),
        (
            "audio-measurements-line.schema.json",
            v(schema_for!(AudioMeasurementLine)),
        ),
        ("truth.schema.json", v(schema_for!(TruthFile))),
        ("tracks-line.schema.json", v(schema_for!(TracksLine))),
        ("pitch-line.schema.json", v(schema_for!(PitchLine))),
    ]
}
