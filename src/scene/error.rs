//! Errors of the scene reader: they name the file, the line (for JSONL) and the field.

use std::fmt;
use std::path::Path;

/// A problem with a scene or output folder.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    /// File the problem is in (as given, relative to the working directory).
    pub file: String,
    /// 1-based line number, for JSONL files and JSON syntax errors.
    pub line: Option<usize>,
    /// Dotted path of the offending field, e.g. `arrays[0].mics`.
    pub field: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl SceneError {
    /// An error in `file`.
    pub fn new(file: &Path, message: impl Into<String>) -> Self {
        Self {
            file: file.display().to_string(),
            line: None,
            field: None,
            message: message.into(),
        }
    }

    /// Sets the line number.
    pub fn at_line(mut self, line: usize) -> Self {
        self.line = Some(line);
        self
    }

    /// Sets the field path.
    pub fn field(mut self, field: impl Into<String>) -> Self {
        let f = field.into();
        self.field = if f.is_empty() { None } else { Some(f) };
        self
    }

    /// An error from a JSON document, with the path serde reached and the line it stopped at.
    pub fn from_json(
        file: &Path,
        line_offset: Option<usize>,
        err: serde_path_to_error::Error<serde_json::Error>,
    ) -> Self {
        let path = err.path().to_string();
        let inner = err.inner();
        let line = match line_offset {
            Some(l) => l,
            None => inner.line(),
        };
        // serde_json appends " at line L column C"; the line is reported separately.
        let msg = inner.to_string();
        let msg = msg.split(" at line ").next().unwrap_or(&msg).to_string();
        let field = if path == "." { String::new() } else { path };
        Self::new(file, msg).at_line(line).field(field)
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        if let Some(field) = &self.field {
            write!(f, ": field `{field}`")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for SceneError {}
