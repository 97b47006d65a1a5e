//! Documented configuration: renders a configuration value as TOML in which every field is
//! preceded by its documentation (taken from the doc comments through the JSON Schema), so
//! `avsep config --defaults` is both a valid config file and its reference manual.

use schemars::{JsonSchema, schema_for};
use serde::Serialize;
use serde_json::Value as Json;

/// Renders `value` as commented TOML using the documentation in `T`'s JSON Schema.
pub fn documented_toml<T: Serialize + JsonSchema>(value: &T) -> Result<String, String> {
    let schema = serde_json::to_value(schema_for!(T)).map_err(|e| e.to_string())?;
    let data = serde_json::to_value(value).map_err(|e| e.to_string())?;
    let mut out = String::new();
    if let Some(d) = schema.get("description").and_then(Json::as_str) {
        push_comment(&mut out, d);
        out.push('\n');
    }
    render_table(&mut out, &schema, &schema, &data, &[])?;
    Ok(out)
}

fn push_comment(out: &mut String, text: &str) {
    for line in text.lines() {
        if line.trim().is_empty() {
            out.push_str("#\n");
        } else {
            out.push_str("# ");
            out.push_str(line.trim_end());
            out.push('\n');
        }
    }
}

/// Follows `$ref` and single-element `allOf` wrappers to the schema that describes a value.
fn resolve<'a>(root: &'a Json, mut s: &'a Json) -> &'a Json {
    for _ in 0..16 {
        if let Some(r) = s.get("$ref").and_then(Json::as_str) {
            let name = r.rsplit('/').next().unwrap_or(r);
            match root.get("$defs").and_then(|d| d.get(name)) {
                Some(t) => s = t,
                None => return s,
            }
        } else if let Some(Json::Array(all)) = s.get("allOf") {
            match all.first() {
                Some(first) if all.len() == 1 => s = first,
                _ => return s,
            }
        } else {
            return s;
        }
    }
    s
}

/// A short "one of" note for enums of plain strings.
fn choices(root: &Json, s: &Json) -> Option<String> {
    let s = resolve(root, s);
    let mut names: Vec<String> = Vec::new();
    if let Some(Json::Array(vals)) = s.get("enum") {
        names.extend(
            vals.iter()
                .filter_map(Json::as_str)
                .map(|v| format!("\"{v}\"")),
        );
    }
    for key in ["oneOf", "anyOf"] {
        if let Some(Json::Array(alts)) = s.get(key) {
            for a in alts {
                let a = resolve(root, a);
                if let Some(c) = a.get("const").and_then(Json::as_str) {
                    let doc = a.get("description").and_then(Json::as_str).unwrap_or("");
                    names.push(if doc.is_empty() {
                        format!("\"{c}\"")
                    } else {
                        format!("\"{c}\" ({doc})")
                    });
                } else if let Some(Json::Array(vals)) = a.get("enum") {
                    let doc = a.get("description").and_then(Json::as_str).unwrap_or("");
                    for v in vals.iter().filter_map(Json::as_str) {
                        names.push(if doc.is_empty() {
                            format!("\"{v}\"")
                        } else {
                            format!("\"{v}\" ({doc})")
                        });
                    }
                }
            }
        }
    }
    (!names.is_empty()).then(|| format!("One of: {}.", names.join(", ")))
}

fn field_doc<'a>(
    root: &'a Json,
    table_schema: &'a Json,
    key: &str,
) -> (Option<&'a str>, Option<&'a Json>) {
    let props = resolve(root, table_schema).get("properties");
    let Some(field) = props.and_then(|p| p.get(key)) else {
        return (None, None);
    };
    let doc = field.get("description").and_then(Json::as_str).or_else(|| {
        let r = resolve(root, field);
        r.get("description").and_then(Json::as_str)
    });
    (doc, Some(field))
}

fn is_table(v: &Json) -> bool {
    matches!(v, Json::Object(_))
}

fn render_table(
    out: &mut String,
    root: &Json,
    schema: &Json,
    data: &Json,
    path: &[String],
) -> Result<(), String> {
    let Json::Object(map) = data else {
        return Err("configuration must serialise to a table".into());
    };
    // Plain keys first, then sub-tables, as TOML requires.
    for (k, v) in map.iter().filter(|(_, v)| !is_table(v) && !v.is_null()) {
        let (doc, field) = field_doc(root, schema, k);
        if let Some(d) = doc {
            push_comment(out, d);
        }
        if let Some(c) = field.and_then(|f| choices(root, f)) {
            push_comment(out, &c);
        }
        out.push_str(&format!("{} = {}\n\n", toml_key(k), toml_value(v)?));
    }
    for (k, v) in map.iter().filter(|(_, v)| !v.is_null()) {
        if !is_table(v) {
            continue;
        }
        let (doc, field) = field_doc(root, schema, k);
        let mut p = path.to_vec();
        p.push(toml_key(k));
        let header = p.join(".");
        if let Some(d) = doc {
            push_comment(out, d);
        }
        out.push_str(&format!("[{header}]\n"));
        let sub_schema = field.map(|f| resolve(root, f)).unwrap_or(&Json::Null);
        render_table(out, root, sub_schema, v, &p)?;
    }
    for (k, _) in map.iter().filter(|(_, v)| v.is_null()) {
        let (doc, _) = field_doc(root, schema, k);
        if let Some(d) = doc {
            push_comment(out, d);
        }
        out.push_str(&format!("# {} = (not set)\n\n", toml_key(k)));
    }
    Ok(())
}

fn toml_key(k: &str) -> String {
    if !k.is_empty()
        && k.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        k.to_string()
    } else {
        format!("{k:?}")
    }
}

fn toml_value(v: &Json) -> Result<String, String> {
    Ok(match v {
        Json::Bool(b) => b.to_string(),
        Json::Number(n) => {
            if let Some(f) = n.as_f64().filter(|_| !n.is_i64() && !n.is_u64()) {
                let s = format!("{f:?}");
                if s.contains('.') || s.contains('e') || s.contains("inf") || s.contains("NaN") {
                    s
                } else {
                    format!("{s}.0")
                }
            } else {
                n.to_string()
            }
        }
        Json::String(s) => toml::Value::String(s.clone()).to_string(),
        Json::Array(items) => {
            if items.iter().any(is_table) {
                // Arrays of tables are written inline.
                let parts: Result<Vec<_>, _> = items.iter().map(inline_table).collect();
                format!("[{}]", parts?.join(", "))
            } else {
                let parts: Result<Vec<_>, _> = items
                    .iter()
                    .filter(|i| !i.is_null())
                    .map(toml_value)
                    .collect();
                format!("[{}]", parts?.join(", "))
            }
        }
        Json::Object(_) => inline_table(v)?,
        Json::Null => return Err("null values cannot be written as TOML".into()),
    })
}

fn inline_table(v: &Json) -> Result<String, String> {
    let Json::Object(map) = v else {
        return toml_value(v);
    };
    let parts: Result<Vec<_>, String> = map
        .iter()
        .filter(|(_, v)| !v.is_null())
        .map(|(k, v)| Ok(format!("{} = {}", toml_key(k), toml_value(v)?)))
        .collect();
    Ok(format!("{{ {} }}", parts?.join(", ")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    /// Settings of a test stage.
    #[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
    #[serde(deny_unknown_fields, default)]
    struct Inner {
        /// Frame length in samples.
        frame: usize,
        /// Which method to use.
        method: Method,
        /// Band edges in Hz.
        band_hz: [f64; 2],
    }

    /// A method.
    #[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
    #[serde(rename_all = "snake_case")]
    enum Method {
        /// The fast one.
        Fast,
        /// The good one.
        Good,
    }

    impl Default for Inner {
        fn default() -> Self {
            Self {
                frame: 2048,
                method: Method::Good,
                band_hz: [1000.0, 7000.0],
            }
        }
    }

    /// Top-level test settings.
    #[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
    #[serde(deny_unknown_fields, default)]
    struct Outer {
        /// Step period in seconds.
        step_s: f64,
        /// Random seed; derived from the session id when absent.
        seed: Option<u64>,
        /// Stage settings.
        inner: Inner,
    }

    #[test]
    fn renders_valid_commented_toml_that_round_trips() {
        let v = Outer {
            step_s: 0.128,
            seed: None,
            inner: Inner::default(),
        };
        let text = documented_toml(&v).unwrap();
        assert!(
            text.contains("# Step period in seconds.\nstep_s = 0.128"),
            "{text}"
        );
        assert!(
            text.contains("# Frame length in samples.\nframe = 2048"),
            "{text}"
        );
        assert!(text.contains("[inner]"), "{text}");
        assert!(text.contains("\"fast\" (The fast one.)"), "{text}");
        assert!(text.contains("# seed = (not set)"), "{text}");
        let back: Outer = toml::from_str(&text).unwrap();
        assert_eq!(back, v);
    }
}
