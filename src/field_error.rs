//! The one error type of every configuration and calibration check: what is wrong, and the
//! dotted path of the field it is wrong in (`track.camera.p_detect`, `cameras[0].projection`),
//! which the REST API returns as the error's `field`. Each layer checks its own fields and the
//! layer that nests them prefixes the path ([`FieldError::within`]).

/// An invalid value, naming its field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field}: {message}")]
pub struct FieldError {
    /// Dotted path of the offending field (empty for the document as a whole).
    pub field: String,
    /// What is wrong with it.
    pub message: String,
}

impl FieldError {
    /// An error about `field`.
    pub fn new(field: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            message: message.into(),
        }
    }

    /// The same error with `prefix.` prepended to the field path.
    pub fn within(mut self, prefix: &str) -> Self {
        self.field = if self.field.is_empty() {
            prefix.to_string()
        } else {
            format!("{prefix}.{}", self.field)
        };
        self
    }

    /// Ok when `ok` holds, else an error about `field`.
    pub fn check(ok: bool, field: &str, message: &str) -> Result<(), Self> {
        if ok {
            Ok(())
        } else {
            Err(Self::new(field, message))
        }
    }
}

/// Reads a settings document: JSON when the text starts with `{`, else TOML. Absent fields take
/// the type's serde defaults; an unknown or mistyped field is named by its dotted path.
pub fn parse_document<T: serde::de::DeserializeOwned>(text: &str) -> Result<T, FieldError> {
    if text.trim_start().starts_with('{') {
        let de = &mut serde_json::Deserializer::from_str(text);
        serde_path_to_error::deserialize(de)
            .map_err(|e| FieldError::new(e.path().to_string(), e.inner().to_string()))
    } else {
        let de = toml::Deserializer::parse(text).map_err(|e| FieldError::new("", e.to_string()))?;
        serde_path_to_error::deserialize(de)
            .map_err(|e| FieldError::new(e.path().to_string(), e.inner().message().to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nesting_prefixes_the_path() {
        let e = FieldError::new("camera.p_detect", "must be in (0, 1]").within("track");
        assert_eq!(e.field, "track.camera.p_detect");
        assert_eq!(e.to_string(), "track.camera.p_detect: must be in (0, 1]");
        assert_eq!(
            FieldError::new("", "bad").within("separate").field,
            "separate"
        );
        assert!(FieldError::check(true, "x", "m").is_ok());
        assert_eq!(FieldError::check(false, "x", "m").unwrap_err().field, "x");
    }

    #[derive(Debug, PartialEq, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Doc {
        #[serde(default)]
        inner: Inner,
    }

    #[derive(Debug, Default, PartialEq, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Inner {
        #[serde(default)]
        rate: f64,
    }

    #[test]
    fn documents_read_as_json_or_toml_and_name_the_bad_field() {
        let json: Doc = parse_document(" {\"inner\": {\"rate\": 2.5}}").unwrap();
        let toml: Doc = parse_document("[inner]\nrate = 2.5\n").unwrap();
        assert_eq!(json, toml);
        assert_eq!(parse_document::<Doc>("").unwrap().inner.rate, 0.0);
        let e = parse_document::<Doc>("[inner]\nrate = \"fast\"\n").unwrap_err();
        assert_eq!(e.field, "inner.rate");
        let e = parse_document::<Doc>("{\"inner\": {\"speed\": 1}}").unwrap_err();
        assert_eq!(e.field, "inner.speed");
        assert!(e.message.contains("unknown field"), "{}", e.message);
    }
}
