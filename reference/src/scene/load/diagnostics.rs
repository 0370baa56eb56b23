//! Positions and excerpts for error messages: the 1-based line and column of a byte offset,
//! the line of the first invalid UTF-8 byte, and parser messages with their quoted file
//! content cut to [`crate::error::MAX_EXCERPT_CHARS`] characters (module docs, "Every input is
//! validated": every error names the position and never echoes more than a short excerpt).
//!
//! Imports none of the other loader files.

pub(super) use crate::error::line_col;

/// 1-based line of the first invalid UTF-8 byte.
pub(super) fn utf8_error_line(bytes: &[u8], e: &std::str::Utf8Error) -> usize {
    bytes[..e.valid_up_to()]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// Shortens every double-quoted part of a parser's message to [`crate::error::MAX_EXCERPT_CHARS`]
/// characters (marked `…`) and puts it on one line: messages such as TOML's `invalid type: string
/// "..."` quote the file's content.
pub(super) fn cut_quoted(message: &str) -> String {
    let mut out = String::new();
    let mut inside = false;
    let mut escaped = false;
    let mut count = 0;
    for c in message.trim().chars() {
        let c = if c == '\n' || c == '\r' { ' ' } else { c };
        if !inside {
            out.push(c);
            if c == '"' {
                inside = true;
                count = 0;
            }
            continue;
        }
        if !escaped && c == '"' {
            if count > crate::error::MAX_EXCERPT_CHARS {
                out.push('…');
            }
            out.push(c);
            inside = false;
            continue;
        }
        escaped = !escaped && c == '\\';
        count += 1;
        if count <= crate::error::MAX_EXCERPT_CHARS {
            out.push(c);
        }
    }
    if inside && count > crate::error::MAX_EXCERPT_CHARS {
        out.push('…');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_col_counts_characters() {
        assert_eq!(line_col("ab\ncdé\nf", 0), (1, 1));
        assert_eq!(line_col("ab\ncdé\nf", 3), (2, 1));
        assert_eq!(line_col("ab\ncdé\nf", 8), (3, 1));
        assert_eq!(line_col("ab", 100), (1, 3));
    }
}
