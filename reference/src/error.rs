//! Errors for bad input: every one names the file, the position in it (line, field or index), the
//! offending value and what was expected, on one line (brief: "Bad input").

use std::fmt;

/// Bad input found while loading or validating a scene, an instance table, a mesh or a texture.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InputError {
    /// File the value came from, or a pseudo-name such as `<built-in synthetic>` or `<params>`.
    pub file: String,
    /// Where in the file: `line 12, column scale`, `field meshes[2].texture`, `vertex 7`...
    pub position: String,
    /// The offending value, formatted (truncated to 80 characters).
    pub value: String,
    /// What was expected.
    pub reason: String,
}

impl InputError {
    /// Builds an error; long values are cut to 80 characters with an ellipsis.
    pub fn new(
        file: impl Into<String>,
        position: impl Into<String>,
        value: impl fmt::Display,
        reason: impl Into<String>,
    ) -> Self {
        let mut value = value.to_string();
        if value.chars().count() > 80 {
            value = value.chars().take(77).collect::<String>() + "...";
        }
        Self {
            file: file.into(),
            position: position.into(),
            value,
            reason: reason.into(),
        }
    }
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: {}: value {:?}: {}",
            self.file, self.position, self.value, self.reason
        )
    }
}

impl std::error::Error for InputError {}

impl From<forestlod_shared::ParamError> for InputError {
    fn from(e: forestlod_shared::ParamError) -> Self {
        InputError::new("<params>", format!("field {}", e.field), e.value, e.reason)
    }
}
