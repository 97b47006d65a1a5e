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
}
