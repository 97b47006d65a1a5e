//! The server's contracts under api/ are generated from the code: the OpenAPI document, the JSON
//! Schemas of the stream messages, the pipeline settings and the server configuration. These
//! tests fail when a checked-in file differs from what the code generates. Regenerate with
//! `AVSEP_BLESS=1 cargo test --test server_api_contract` and review the diff.

use std::path::PathBuf;

fn check(name: &str, generated: &str) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("api")
        .join(name);
    if std::env::var_os("AVSEP_BLESS").is_some() {
        std::fs::write(&path, generated).unwrap();
        return;
    }
    let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        on_disk == generated,
        "api/{name} differs from what the code generates; run `AVSEP_BLESS=1 cargo test --test server_api_contract` and review the diff"
    );
}

#[test]
fn openapi_document_is_current() {
    let yaml = avsep::server::openapi::openapi_yaml();
    assert!(yaml.contains("/v1/sessions/{id}/stream"));
    check("openapi.yaml", &yaml);
}

#[test]
fn message_and_settings_schemas_are_current() {
    let all = avsep::protocol::schema::protocol_schemas()
        .into_iter()
        .chain(avsep::server::server_schemas());
    for (name, schema) in all {
        check(
            name,
            &(serde_json::to_string_pretty(&schema).unwrap() + "\n"),
        );
    }
}

#[test]
fn openapi_refers_only_to_schema_files_that_exist() {
    let yaml = avsep::server::openapi::openapi_yaml();
    let api = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("api");
    for line in yaml.lines().filter(|l| l.contains("$ref:")) {
        let target = line
            .split("$ref:")
            .nth(1)
            .unwrap()
            .trim()
            .trim_matches('\'')
            .trim_matches('"');
        if target.starts_with('#') {
            continue;
        }
        let (file, pointer) = target.split_once('#').unwrap_or((target, ""));
        let doc: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(api.join(file)).unwrap()).unwrap();
        assert!(
            pointer.is_empty() || doc.pointer(pointer).is_some(),
            "{target} does not resolve"
        );
    }
}
