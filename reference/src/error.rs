//! Errors for bad input: every one names the file, the position in it (line, field or index), the
//! offending value and what was expected, on one line (brief: "Bad input").
//!
//! An error in a file reached through another (a mesh named by a scene file) carries a **chain**:
//! the links that led to the file, outermost first, each `file: position = value`. It prints as
//! `forest.toml: line 9, column 8, field species[1].mesh = "oak.obj": oak.obj: line 12, face:
//! value "99/1": vertex index out of range ...`.
//!
//! No error echoes more than [`MAX_EXCERPT_CHARS`] characters of a file's content: values are cut
//! and marked `…` ([`excerpt`]), and printed quoted with control characters escaped, so an error
//! is always one line.

use std::fmt;

/// The pseudo-file of errors in command-line flags.
pub const COMMAND_LINE: &str = "<command line>";

/// Most characters of a value (file content) an error echoes; longer ones are cut and marked `…`.
pub const MAX_EXCERPT_CHARS: usize = 40;

/// Bad input found while loading or validating a scene, an instance table, a mesh or a texture.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InputError {
    /// How the file was reached, outermost first: e.g. `forest.toml: line 9, column 8, field
    /// species[1].mesh = "oak.obj"`. Empty for a file given directly.
    pub chain: Vec<String>,
    /// File the value came from, or a pseudo-name such as `<built-in synthetic>` or `<params>`.
    pub file: String,
    /// Where in the file: `line 12, column scale`, `field meshes[2].texture`, `vertex 7`...
    pub position: String,
    /// The offending value, formatted (cut to [`MAX_EXCERPT_CHARS`] characters, marked `…`).
    pub value: String,
    /// What was expected.
    pub reason: String,
}

/// `text` cut to [`MAX_EXCERPT_CHARS`] characters, with `…` appended when cut (not quoted).
pub fn cut(text: &str) -> String {
    if text.chars().count() > MAX_EXCERPT_CHARS {
        text.chars().take(MAX_EXCERPT_CHARS).collect::<String>() + "…"
    } else {
        text.to_string()
    }
}

/// `text` as an error shows file content: cut ([`cut`]), then quoted with control characters
/// escaped (so it stays on one line).
pub fn excerpt(text: &str) -> String {
    format!("{:?}", cut(text))
}

impl InputError {
    /// Builds an error; long values are cut to [`MAX_EXCERPT_CHARS`] characters, marked `…`,
    /// except those of [`COMMAND_LINE`]: what the user typed (an `--out` path, say) is echoed
    /// whole, since it is not file content and a cut path cannot be checked.
    pub fn new(
        file: impl Into<String>,
        position: impl Into<String>,
        value: impl fmt::Display,
        reason: impl Into<String>,
    ) -> Self {
        let file = file.into();
        let value = value.to_string();
        Self {
            chain: Vec::new(),
            value: if file == COMMAND_LINE {
                value
            } else {
                cut(&value)
            },
            file,
            position: position.into(),
            reason: reason.into(),
        }
    }

    /// The same error reached through `link` (e.g. `scene.toml: line 4, column 8, field
    /// species[0].mesh = "oak.obj"`), which becomes the chain's outermost link.
    pub fn within(mut self, link: impl Into<String>) -> Self {
        self.chain.insert(0, link.into());
        self
    }
}

/// 1-based line and column (in characters) of byte `offset` in `text` (an offset inside a
/// character counts from that character's start).
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, before[line_start..].chars().count() + 1)
}

/// Where a parser's error points in `text`: `("line L, column C", the first line of the span,
/// trimmed)`, or `("file", "")` without a span. The position and value of the TOML syntax errors
/// of scene files, sweep files and replays.
pub fn span_position(text: &str, span: Option<std::ops::Range<usize>>) -> (String, String) {
    let Some(span) = span else {
        return ("file".to_string(), String::new());
    };
    let (line, col) = line_col(text, span.start);
    let end = span.end.min(text.len());
    let snippet = text
        .get(span.start.min(end)..end)
        .unwrap_or("")
        .lines()
        .next()
        .unwrap_or("")
        .trim()
        .to_string();
    (format!("line {line}, column {col}"), snippet)
}

/// `text` with its control characters escaped (`\n`, `\u{1b}`), so that text a file put into a
/// key, a file name or a library's message cannot break the error's one line (issue 28: a JSON
/// key holding `\n` came back in serde's "unknown field" message; found by the `sweep_json`
/// fuzz target).
struct OneLine<'a>(&'a str);

impl fmt::Display for OneLine<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for c in self.0.chars() {
            if c.is_control() {
                write!(f, "{}", c.escape_default())?;
            } else {
                write!(f, "{c}")?;
            }
        }
        Ok(())
    }
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for link in &self.chain {
            write!(f, "{}: ", OneLine(link))?;
        }
        write!(
            f,
            "{}: {}: value {:?}: {}",
            OneLine(&self.file),
            OneLine(&self.position),
            self.value,
            OneLine(&self.reason)
        )
    }
}

impl std::error::Error for InputError {}

impl From<forestlod_shared::ParamError> for InputError {
    fn from(e: forestlod_shared::ParamError) -> Self {
        InputError::new("<params>", format!("field {}", e.field), e.value, e.reason)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_cut_and_marked_and_chains_print_outermost_first() {
        let long = "x".repeat(100);
        let e = InputError::new("a.obj", "line 3", &long, "bad");
        assert_eq!(e.value, format!("{}…", "x".repeat(MAX_EXCERPT_CHARS)));
        let e = e
            .within("s.toml: field species[0].mesh = \"a.obj\"")
            .within("outer");
        assert_eq!(
            e.to_string(),
            format!(
                "outer: s.toml: field species[0].mesh = \"a.obj\": a.obj: line 3: value \"{}…\": bad",
                "x".repeat(MAX_EXCERPT_CHARS)
            )
        );
        assert_eq!(excerpt("a\nb"), "\"a\\nb\"");
        assert_eq!(cut("short"), "short");
        let e = InputError::new(COMMAND_LINE, "--out", &long, "bad");
        assert_eq!(e.value, long, "command-line values are echoed whole");
        // Control characters anywhere (a key, a file name, a library's message) stay escaped.
        let e =
            InputError::new("a\nb.json", "key x\ny", "v", "unknown field `x\ny`").within("outer\r");
        let text = e.to_string();
        assert!(!text.contains('\n') && !text.contains('\r'), "{text}");
        assert!(
            text.contains("key x\\ny") && text.contains("a\\nb.json"),
            "{text}"
        );
    }
}
