//! Instance tables (module docs, "Instance table (CSV)"): a header naming the columns
//! [`CSV_COLUMNS`] in any order, then one tree per row, parsed to [`InstanceRow`]s in world
//! `f64` coordinates. Read by a minimal RFC 4180 reader that knows its line numbers exactly, so
//! every error names the file, the line, the column and the value; at most [`MAX_INSTANCES`]
//! rows of at most [`MAX_CSV_RECORD_BYTES`] each.
//!
//! Depends on `paths` and `coords`.

use std::collections::HashMap;
use std::io::{BufRead, Read};
use std::path::Path;

use super::coords::MAX_WORLD_COORDINATE;
use super::paths::{label, open_file};
use crate::InputError;
use crate::error::cut;

/// Most rows an instance table may have.
pub const MAX_INSTANCES: usize = 20_000_000;
/// The instance table's columns.
pub const CSV_COLUMNS: [&str; 6] = ["x", "y", "z", "yaw", "scale", "species"];

/// One row of an instance table, as parsed: world position in `f64`, before the origin is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstanceRow {
    /// World position, metres.
    pub position: [f64; 3],
    /// Rotation about +Z, radians (finite).
    pub yaw: f32,
    /// Uniform scale, in (0, 1000].
    pub scale: f32,
    /// Mesh (species) index.
    pub mesh: u32,
    /// 1-based line of the row in its file (the header is line 1).
    pub line: u64,
}

/// Loads an instance table (module docs: CSV) whose `species` column names one of
/// `species_names` or gives its 0-based index.
pub fn load_instances_csv(
    path: &Path,
    species_names: &[String],
) -> Result<Vec<InstanceRow>, InputError> {
    let file = label(path);
    let f = open_file(path)?;
    parse_instances_csv(std::io::BufReader::new(f), &file, species_names)
}

/// Parses an instance table from `reader`; `file` names it in errors.
pub fn parse_instances_csv<R: Read>(
    reader: R,
    file: &str,
    species_names: &[String],
) -> Result<Vec<InstanceRow>, InputError> {
    parse_instances_csv_limited(reader, file, species_names, MAX_INSTANCES)
}

/// [`parse_instances_csv`] with a row limit (tests use a small one).
fn parse_instances_csv_limited<R: Read>(
    reader: R,
    file: &str,
    species_names: &[String],
    max_rows: usize,
) -> Result<Vec<InstanceRow>, InputError> {
    let mut csv = CsvRecords::new(std::io::BufReader::new(reader), file);
    let mut record: Vec<String> = Vec::new();
    let Some(header_line) = csv.next_record(&mut record)? else {
        return Err(InputError::new(
            file,
            "line 1",
            "",
            format!("empty file: expected the header {}", CSV_COLUMNS.join(",")),
        ));
    };
    // column[k] = index in the record of CSV_COLUMNS[k]
    let mut column = [usize::MAX; 6];
    for (i, name) in record.iter().enumerate() {
        let name = name.as_str();
        match CSV_COLUMNS.iter().position(|c| *c == name) {
            Some(k) if column[k] == usize::MAX => column[k] = i,
            Some(_) => {
                return Err(InputError::new(
                    file,
                    format!("line {header_line}, column {}", i + 1),
                    name,
                    "duplicate column",
                ));
            }
            None => {
                return Err(InputError::new(
                    file,
                    format!("line {header_line}, column {}", i + 1),
                    name,
                    format!(
                        "unknown column; expected the header {}",
                        CSV_COLUMNS.join(",")
                    ),
                ));
            }
        }
    }
    if let Some(k) = column.iter().position(|&c| c == usize::MAX) {
        return Err(InputError::new(
            file,
            format!("line {header_line}, column {}", CSV_COLUMNS[k]),
            record.join(","),
            format!(
                "missing column; expected the header {}",
                CSV_COLUMNS.join(",")
            ),
        ));
    }
    let width = record.len();
    let by_name: HashMap<&str, u32> = species_names
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i as u32))
        .collect();

    let mut rows = Vec::new();
    while let Some(line) = csv.next_record(&mut record)? {
        if record.len() != width {
            return Err(InputError::new(
                file,
                format!("line {line}"),
                record.join(","),
                format!(
                    "wrong column count: expected {width} fields, found {}",
                    record.len()
                ),
            ));
        }
        if rows.len() >= max_rows {
            return Err(InputError::new(
                file,
                format!("line {line}"),
                format!("row {}", rows.len() + 1),
                format!("too many rows: at most {max_rows} trees per table"),
            ));
        }
        let field = |k: usize| record.get(column[k]).map_or("", String::as_str);
        let err = |k: usize, reason: String| {
            InputError::new(
                file,
                format!("line {line}, column {}", CSV_COLUMNS[k]),
                field(k),
                reason,
            )
        };
        let mut position = [0.0f64; 3];
        for (k, p) in position.iter_mut().enumerate() {
            let v: f64 = field(k)
                .parse()
                .map_err(|_| err(k, "expected a number (metres)".into()))?;
            if !v.is_finite() || v.abs() > MAX_WORLD_COORDINATE {
                return Err(err(
                    k,
                    format!("expected a finite coordinate within ±{MAX_WORLD_COORDINATE:e} m"),
                ));
            }
            *p = v;
        }
        let yaw: f32 = field(3)
            .parse()
            .map_err(|_| err(3, "expected a number (radians)".into()))?;
        if !yaw.is_finite() {
            return Err(err(3, "expected a finite angle (radians)".into()));
        }
        let scale: f32 = field(4)
            .parse()
            .map_err(|_| err(4, "expected a number".into()))?;
        if !(scale.is_finite() && scale > 0.0 && scale <= 1.0e3) {
            return Err(err(4, "expected a finite scale in (0, 1000]".into()));
        }
        let species = field(5);
        let mesh = match by_name.get(species) {
            Some(&m) => m,
            None => match species.parse::<u32>() {
                Ok(i) if (i as usize) < species_names.len() => i,
                _ => {
                    let mut known = species_names
                        .iter()
                        .take(8)
                        .map(|n| cut(n))
                        .collect::<Vec<_>>()
                        .join(", ");
                    if species_names.len() > 8 {
                        known.push_str(", ...");
                    }
                    return Err(err(
                        5,
                        format!(
                            "unknown species: expected one of [{known}] or an index below {}",
                            species_names.len()
                        ),
                    ));
                }
            },
        };
        rows.push(InstanceRow {
            position,
            yaw,
            scale,
            mesh,
            line,
        });
    }
    if rows.is_empty() {
        return Err(InputError::new(
            file,
            format!("line {}", header_line + 1),
            "no rows",
            "empty table: expected at least one tree after the header",
        ));
    }
    Ok(rows)
}

/// Longest record accepted in an instance table, bytes.
pub const MAX_CSV_RECORD_BYTES: usize = 1 << 16;

/// A minimal RFC 4180 reader that knows its line numbers exactly (the `csv` crate's positions skip
/// blank lines and mis-count CRLF). Fields are separated by `,`; a field may be quoted with `"`
/// (`""` inside is a quote) and then may span lines; unquoted fields and quoted contents are
/// trimmed of spaces and tabs; empty lines are skipped; a leading UTF-8 byte-order mark is dropped;
/// line ends are `\n` or `\r\n`.
pub(super) struct CsvRecords<'a, R> {
    reader: R,
    file: &'a str,
    /// Lines read so far.
    line: u64,
    buf: Vec<u8>,
}

impl<'a, R: std::io::BufRead> CsvRecords<'a, R> {
    pub(super) fn new(reader: R, file: &'a str) -> Self {
        Self {
            reader,
            file,
            line: 0,
            buf: Vec::new(),
        }
    }

    /// Reads one physical line into `self.buf` without its line end; `false` at the end of input.
    fn read_line(&mut self) -> Result<bool, InputError> {
        self.buf.clear();
        let limit = MAX_CSV_RECORD_BYTES as u64 + 2;
        let n = (&mut self.reader)
            .take(limit)
            .read_until(b'\n', &mut self.buf)
            .map_err(|e| {
                InputError::new(
                    self.file,
                    format!("line {}", self.line + 1),
                    "",
                    format!("cannot be read: {e}"),
                )
            })?;
        if n == 0 {
            return Ok(false);
        }
        self.line += 1;
        if self.buf.last() == Some(&b'\n') {
            self.buf.pop();
            if self.buf.last() == Some(&b'\r') {
                self.buf.pop();
            }
        } else if n as u64 >= limit {
            return Err(self.too_long());
        }
        if self.line == 1 && self.buf.starts_with(&[0xef, 0xbb, 0xbf]) {
            self.buf.drain(..3);
        }
        Ok(true)
    }

    fn too_long(&self) -> InputError {
        InputError::new(
            self.file,
            format!("line {}", self.line.max(1)),
            format!("more than {MAX_CSV_RECORD_BYTES} bytes"),
            format!("expected records of at most {MAX_CSV_RECORD_BYTES} bytes"),
        )
    }

    /// Reads the next non-empty record into `fields`; returns the line it starts on, or `None` at
    /// the end of input.
    pub(super) fn next_record(
        &mut self,
        fields: &mut Vec<String>,
    ) -> Result<Option<u64>, InputError> {
        fields.clear();
        // Skip empty lines.
        loop {
            if !self.read_line()? {
                return Ok(None);
            }
            if !self.buf.iter().all(|b| *b == b' ' || *b == b'\t') {
                break;
            }
        }
        let start = self.line;
        let mut record: Vec<u8> = Vec::new();
        let mut field: Vec<u8> = Vec::new();
        let mut quoted = false; // inside quotes
        let mut after_quote = false; // a quoted field has closed
        let mut raw: Vec<Vec<u8>> = Vec::new();
        loop {
            let mut i = 0;
            while i < self.buf.len() {
                let b = self.buf[i];
                if quoted {
                    if b == b'"' {
                        if self.buf.get(i + 1) == Some(&b'"') {
                            field.push(b'"');
                            i += 1;
                        } else {
                            quoted = false;
                            after_quote = true;
                        }
                    } else {
                        field.push(b);
                    }
                } else if b == b',' {
                    raw.push(std::mem::take(&mut field));
                    after_quote = false;
                } else if after_quote {
                    if b != b' ' && b != b'\t' {
                        return Err(InputError::new(
                            self.file,
                            format!("line {}", self.line),
                            String::from_utf8_lossy(&self.buf).into_owned(),
                            "invalid CSV: unexpected character after a closing quote",
                        ));
                    }
                } else if b == b'"' && field.iter().all(|c| *c == b' ' || *c == b'\t') {
                    field.clear();
                    quoted = true;
                } else {
                    field.push(b);
                }
                i += 1;
            }
            record.extend_from_slice(&self.buf);
            if record.len() > MAX_CSV_RECORD_BYTES {
                return Err(self.too_long());
            }
            if !quoted {
                break;
            }
            // The quoted field goes on on the next line.
            field.push(b'\n');
            if !self.read_line()? {
                return Err(InputError::new(
                    self.file,
                    format!("line {start}"),
                    String::from_utf8_lossy(&record).into_owned(),
                    "invalid CSV: a quoted field is never closed",
                ));
            }
        }
        raw.push(field);
        for bytes in raw {
            let text = String::from_utf8(bytes).map_err(|e| {
                InputError::new(
                    self.file,
                    format!("line {start}, column {}", fields.len() + 1),
                    format!("byte {}", e.utf8_error().valid_up_to()),
                    "expected UTF-8 text",
                )
            })?;
            fields.push(text.trim_matches(|c| c == ' ' || c == '\t').to_string());
        }
        Ok(Some(start))
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_util::{assert_mentions, names};
    use super::*;

    fn parse(text: &str) -> Result<Vec<InstanceRow>, InputError> {
        parse_instances_csv(text.as_bytes(), "trees.csv", &names())
    }

    #[test]
    fn csv_columns_may_come_in_any_order_with_spaces_and_a_bom() {
        let rows = parse("\u{feff}species, scale ,yaw,z,y,x\n pine ,2,0,1,2,3\n").unwrap();
        assert_eq!(rows[0].position, [3.0, 2.0, 1.0]);
        assert_eq!(rows[0].scale, 2.0);
        assert_eq!(rows[0].mesh, 1);
    }

    fn err(text: &str) -> String {
        parse(text).unwrap_err().to_string()
    }

    #[test]
    fn csv_errors_name_file_line_column_and_value() {
        let h = "x,y,z,yaw,scale,species\n";
        // Rows after the header `h`, and what the error must mention.
        let after_header: [(&str, &[&str]); 10] = [
            (
                "1,2,3,0,1,oak\nabc,2,3,0,1,oak\n",
                &["trees.csv", "line 3", "column x", "abc"],
            ),
            ("1,2,NaN,0,1,oak\n", &["line 2", "column z", "NaN"]),
            ("1,2,3,inf,1,oak\n", &["column yaw", "inf"]),
            ("1,2,3,0,-1,oak\n", &["column scale", "-1"]),
            ("1,2,3,0,0,oak\n", &["column scale", "\"0\""]),
            (
                "1,2,3,0,1,baobab\n",
                &["column species", "baobab", "spruce"],
            ),
            ("1,2,3,0,1,5\n", &["column species", "\"5\""]),
            ("1,2,3,0,1\n", &["line 2", "column count"]),
            ("", &["empty table"]),
            ("1e300,2,3,0,1,oak\n", &["column x", "1e300"]),
        ];
        for (rows, needles) in after_header {
            let e = err(&format!("{h}{rows}"));
            assert_mentions(&e, needles);
        }
        // Whole files: no header, or a bad one.
        let whole: [(&str, &[&str]); 4] = [
            ("", &["empty file"]),
            (
                "x,y,z,yaw,species\n1,2,3,0,oak\n",
                &["missing column", "scale"],
            ),
            (
                "x,y,z,yaw,scale,species,height\n",
                &["unknown column", "height"],
            ),
            ("x,y,z,yaw,scale,species,x\n", &["duplicate column"]),
        ];
        for (text, needles) in whole {
            let e = err(text);
            assert_mentions(&e, needles);
        }
    }

    #[test]
    fn csv_line_numbers_count_blank_lines_crlf_and_quoted_newlines() {
        let h = "x,y,z,yaw,scale,species\r\n";
        // (position, value) of the error for the table `h` + `body`.
        let error_at = |body: &str| {
            let e = parse(&format!("{h}{body}")).unwrap_err();
            (e.position, e.value)
        };
        // The quoted species spans lines 6-7 and is not a species name.
        let (position, value) =
            error_at("\r\n1,2,3,0,1,oak\r\n\n  \n\"1\",2,3,0,1,\"o\nak\"\n4,5,6,0,1,\"pine\"");
        assert_eq!(position, "line 6, column species");
        assert_eq!(value, "o\nak");
        let (position, value) =
            error_at("\r\n1,2,3,0,1,oak\r\n\n  \n\" 1 \",2,3,0,1,\"pi\"\"ne\"\n4,5,6,0,1,\"pine\"");
        assert_eq!(position, "line 6, column species");
        assert_eq!(value, "pi\"ne");
        let rows = parse(&format!(
            "{h}\r\n1,2,3,0,1,oak\r\n\n\n\"1\" ,2,3,0,1,\"pine\"\r\n4,5,6,0,1,birch"
        ))
        .unwrap();
        assert_eq!(rows.iter().map(|r| r.line).collect::<Vec<_>>(), [3, 6, 7]);
        assert_eq!(rows[1].position[0], 1.0);
        let e = err(&format!("{h}1,2,3,0,1,\"oak"));
        assert_mentions(&e, &["line 2", "never closed"]);
        let e = err(&format!("{h}1,2,3,0,1,\"oak\"x"));
        assert_mentions(&e, &["line 2", "closing quote"]);
        let long = format!("{h}{}", "1".repeat(MAX_CSV_RECORD_BYTES + 10));
        let e = err(&long);
        assert_mentions(&e, &["line 2", "at most"]);
    }

    #[test]
    fn csv_rejects_too_many_rows_at_the_first_extra_row() {
        let text = "x,y,z,yaw,scale,species\n1,2,3,0,1,oak\n1,2,3,0,1,oak\n\n1,2,3,0,1,oak\n";
        assert_eq!(
            parse_instances_csv_limited(text.as_bytes(), "big.csv", &names(), 3)
                .unwrap()
                .len(),
            3
        );
        let e = parse_instances_csv_limited(text.as_bytes(), "big.csv", &names(), 2)
            .unwrap_err()
            .to_string();
        assert_mentions(&e, &["big.csv", "line 5", "row 3", "too many rows"]);
    }

    #[test]
    fn csv_rejects_invalid_utf8_with_a_line() {
        let mut bytes = b"x,y,z,yaw,scale,species\n1,2,3,0,1,oak\n1,2,3,0,1,".to_vec();
        bytes.extend_from_slice(&[0xff, 0xfe, b'\n']);
        let e = parse_instances_csv(&bytes[..], "trees.csv", &names())
            .unwrap_err()
            .to_string();
        assert_mentions(&e, &["trees.csv", "line 3"]);
    }
}
