//! The contracts under api/ are generated from the code; these tests fail when a checked-in file
//! differs from what the code generates. Regenerate with `AVSEP_BLESS=1 cargo test --test api_contract`.

use std::path::PathBuf;

fn check(name: &str, generated: &str) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("api")
        .join(name);
    if std::env::var_os("AVSEP_BLESS").is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, generated).unwrap();
        return;
    }
    let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        on_disk == generated,
        "api/{name} differs from what the code generates; run `AVSEP_BLESS=1 cargo test --test api_contract` and review the diff"
    );
}

#[test]
fn scene_format_schemas_are_current() {
    for (name, schema) in avsep::scene::schema::scene_format_schemas() {
        check(
            name,
            &(serde_json::to_string_pretty(&schema).unwrap() + "\n"),
        );
    }
}
