//! Point lists as CSV, the CLI's convention for every list of points (see `CLI.md`):
//!
//! * one point per line, fields separated by `,` (spaces around fields are ignored; a field
//!   may be in double quotes);
//! * an optional header: the first non-blank line is a header when none of its fields is a
//!   number (`X,Y,Z`); it must have as many fields as the data rows. A first line that mixes
//!   numbers and text (`0,zero,1`) is a bad data row, not a header;
//! * blank lines and lines starting with `#` are skipped;
//! * every data field must be a finite number (NaN and infinities are input errors).
//!
//! Output numbers are written by [`format_float`]: the shortest text that reads back to the same
//! value (Rust's `{:?}`: `342.28315473308373`, `320.0`, `1e-7`), and `nan` for a missing value.
//! Tables (a header naming the columns, then a row per point) are written by [`format_csv`];
//! structured results are JSON, written by [`to_json`].

use std::fmt::Debug;
use std::path::Path;

use nalgebra::{Point2, Point3};

use crate::error::{Error, ErrorKind, Result};
use crate::storage::{parse_number, read_text};

/// Rows of numbers read from a CSV file.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// The header's field names, when the file has a header.
    pub header: Option<Vec<String>>,
    /// The data rows, each with the expected number of fields.
    pub rows: Vec<Vec<f64>>,
    /// The 1-based line of each row.
    pub lines: Vec<usize>,
}

/// Reads a CSV file of rows with one number per name in `columns` (`-` reads standard input).
pub fn read_csv(path: impl AsRef<Path>, columns: &[&str]) -> Result<Table> {
    let path = path.as_ref();
    parse_csv(&read_text(path)?, path, columns)
}

/// [`read_csv`] on a string; `path` is only used in messages.
///
/// The `csv` crate splits the records (fields may be in double quotes, as spreadsheets write
/// them) and trims the fields; the rules of the module docs are checked here, each error
/// naming the record's line.
pub fn parse_csv(text: &str, path: impl AsRef<Path>, columns: &[&str]) -> Result<Table> {
    let path = path.as_ref();
    let n = columns.len();
    let want = columns.join(",");
    let mut table = Table {
        header: None,
        rows: Vec::new(),
        lines: Vec::new(),
    };
    let mut reader = csv::ReaderBuilder::new()
        // Whether the first record is a header is decided from its fields, below.
        .has_headers(false)
        // A record's field count is checked below, with the expected columns in the message.
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let mut lines = LineOf::new(text);
    let mut first = true;
    let mut record = csv::StringRecord::new();
    loop {
        let more = reader.read_record(&mut record);
        // The crate's own line count leaves out comment and empty lines: count to where the
        // record ends.
        let line = lines.ending_at(reader.position().byte());
        if !more.map_err(|e| Error::at_line(path, line, ErrorKind::Syntax(e.to_string())))? {
            break;
        }
        let fields: Vec<&str> = record.iter().collect();
        // The crate skips empty lines and a `#` in the first column; a line of spaces, or a
        // comment after spaces, is skipped here.
        if fields.first().is_some_and(|f| f.starts_with('#')) || fields == [""] {
            continue;
        }
        let is_first = std::mem::replace(&mut first, false);
        if is_first && fields.iter().all(|f| parse_number(f).is_none()) {
            if fields.len() != n {
                return Err(Error::at_line(
                    path,
                    line,
                    ErrorKind::Shape(format!(
                        "header has {} fields, expected {n} ({want})",
                        fields.len()
                    )),
                ));
            }
            table.header = Some(fields.iter().map(|f| f.to_string()).collect());
            continue;
        }
        if fields.len() != n {
            return Err(Error::at_line(
                path,
                line,
                ErrorKind::Shape(format!(
                    "expected {n} comma-separated numbers ({want}), found {} fields",
                    fields.len()
                )),
            ));
        }
        let mut row = Vec::with_capacity(n);
        for (f, name) in fields.iter().zip(columns) {
            let v = parse_number(f).ok_or_else(|| {
                Error::at_line(
                    path,
                    line,
                    ErrorKind::Syntax(format!("{name} is not a number: `{f}`")),
                )
            })?;
            if !v.is_finite() {
                return Err(Error::at_line(
                    path,
                    line,
                    ErrorKind::Syntax(format!("{name} is not finite: `{f}`")),
                ));
            }
            row.push(v);
        }
        table.rows.push(row);
        table.lines.push(line);
    }
    Ok(table)
}

/// The 1-based line on which a record of a text ends, from the offset just past it, for
/// offsets in increasing order.
struct LineOf<'a> {
    text: &'a [u8],
    /// The last offset asked for and the newlines before it.
    byte: usize,
    newlines: usize,
}

impl<'a> LineOf<'a> {
    fn new(text: &'a str) -> Self {
        Self {
            text: text.as_bytes(),
            byte: 0,
            newlines: 0,
        }
    }

    /// The line of the last byte before `end` that is not the record's final `\n`.
    fn ending_at(&mut self, end: u64) -> usize {
        let end = usize::try_from(end).map_or(self.text.len(), |e| e.min(self.text.len()));
        if let Some(skipped) = self.text.get(self.byte..end) {
            self.newlines += skipped.iter().filter(|&&b| b == b'\n').count();
            self.byte = end;
        }
        let terminated = end.checked_sub(1).and_then(|i| self.text.get(i)) == Some(&b'\n');
        self.newlines - usize::from(terminated) + 1
    }
}

/// Reads 3-D points, rows `X,Y,Z`.
pub fn read_points3(path: impl AsRef<Path>) -> Result<Vec<Point3<f64>>> {
    Ok(read_csv(path, &["X", "Y", "Z"])?
        .rows
        .iter()
        .map(|r| Point3::new(r[0], r[1], r[2]))
        .collect())
}

/// Reads 2-D points, rows `u,v`.
pub fn read_points2(path: impl AsRef<Path>) -> Result<Vec<Point2<f64>>> {
    Ok(read_csv(path, &["u", "v"])?
        .rows
        .iter()
        .map(|r| Point2::new(r[0], r[1]))
        .collect())
}

/// Parses `N` comma-separated finite numbers (a command-line vector such as `--rvec 0.1,0,0`).
pub fn parse_vector<const N: usize>(s: &str) -> std::result::Result<[f64; N], String> {
    let fields: Vec<&str> = s.split(',').map(str::trim).collect();
    if fields.len() != N {
        return Err(format!(
            "expected {N} comma-separated numbers, found {} in `{s}`",
            fields.len()
        ));
    }
    let mut out = [0.0; N];
    for (o, f) in out.iter_mut().zip(&fields) {
        *o = parse_number(f)
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("`{f}` is not a finite number"))?;
    }
    Ok(out)
}

/// The CLI's CSV: the `header` line, then one line per row of `rows`, each field as given
/// (the `csv` crate quotes a field only when it holds a `,`, a quote or a line break, which
/// numbers and status names never do), lines ending in `\n`.
pub fn format_csv<R, F>(header: &[&str], rows: impl IntoIterator<Item = R>) -> String
where
    R: IntoIterator<Item = F>,
    F: AsRef<[u8]>,
{
    let mut writer = csv::WriterBuilder::new()
        .terminator(csv::Terminator::Any(b'\n'))
        // A row may have other fields than the header; written as given.
        .flexible(true)
        .from_writer(Vec::new());
    // Writing to memory cannot fail, nor can text fields make the bytes anything but UTF-8.
    let _ = writer.write_record(header);
    for row in rows {
        let _ = writer.write_record(row);
    }
    let bytes = writer.into_inner().unwrap_or_default();
    String::from_utf8(bytes).unwrap_or_default()
}

/// The CLI's JSON: pretty-printed (2-space indent) with a final newline. Floats are written with
/// the shortest text that reads back to the same value; NaN and infinities, which JSON lacks,
/// become `null`.
pub fn to_json<S: serde::Serialize>(value: &S) -> String {
    // The CLI's outputs hold numbers, strings, booleans, options and lists, with string keys:
    // serde_json cannot fail on them.
    let mut s = serde_json::to_string_pretty(value).unwrap_or_default();
    s.push('\n');
    s
}

/// The CLI's JSON as one line (no final newline): one object a line for streams (JSON Lines),
/// the numbers as in [`to_json`].
pub fn to_json_line<S: serde::Serialize>(value: &S) -> String {
    serde_json::to_string(value).unwrap_or_default()
}

/// Formats a float for CSV output: the shortest text that reads back to the same value, `nan`
/// for NaN (also used for a point that has no value).
pub fn format_float<T: Debug + PartialEq>(v: T) -> String {
    #[allow(clippy::eq_op)] // NaN test without a Float bound.
    if v != v {
        "nan".to_string()
    } else {
        format!("{v:?}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_blank_lines_and_comments() {
        let t = parse_csv(
            "# c\nX, Y ,Z\n\n1,2,3\n 4 ,5,6e-1\n",
            "p.csv",
            &["X", "Y", "Z"],
        )
        .unwrap();
        assert_eq!(t.header.as_deref().map(|h| h.len()), Some(3));
        assert_eq!(t.rows, vec![vec![1.0, 2.0, 3.0], vec![4.0, 5.0, 0.6]]);
        assert_eq!(t.lines, vec![4, 5]);
        // No header.
        let t = parse_csv("1,2,3\n", "p.csv", &["X", "Y", "Z"]).unwrap();
        assert!(t.header.is_none());
    }

    #[test]
    fn bad_rows_name_the_line() {
        let cols = ["X", "Y", "Z"];
        let e = parse_csv("X,Y,Z\n1,2,3\n1,2\n", "p.csv", &cols).unwrap_err();
        assert_eq!(e.line(), Some(3));
        let e = parse_csv("1,2,3\n1,a,3\n", "p.csv", &cols).unwrap_err();
        assert_eq!(e.line(), Some(2));
        assert!(e.to_string().contains("Y is not a number"), "{e}");
        let e = parse_csv("1,2,nan\n", "p.csv", &cols).unwrap_err();
        assert!(e.to_string().contains("not finite"), "{e}");
        // A first row mixing numbers and text is a bad row, not a header.
        let e = parse_csv("0,zero,1\n0,0,1\n", "p.csv", &cols).unwrap_err();
        assert_eq!(e.line(), Some(1));
        let e = parse_csv("X,Y\n", "p.csv", &cols).unwrap_err();
        assert!(e.to_string().contains("header"), "{e}");
    }

    #[test]
    fn spaces_comments_quotes_and_line_ends() {
        let cols = ["X", "Y", "Z"];
        // A line of spaces and a comment after spaces are skipped; lines are counted through
        // comments, blank lines and CRLF ends.
        let t = parse_csv(
            "# c, d\r\n   \r\n  # e\r\n\"X\",\"Y\",\"Z\"\r\n1,2,3\r\n\r\n\" 4\",5,6\r\n",
            "p.csv",
            &cols,
        )
        .unwrap();
        assert_eq!(t.header, Some(vec!["X".into(), "Y".into(), "Z".into()]));
        assert_eq!(t.rows, vec![vec![1.0, 2.0, 3.0], vec![4.0, 5.0, 6.0]]);
        assert_eq!(t.lines, vec![5, 7]);
        // A comment in a later line, and a row without a final newline.
        let t = parse_csv("1,2,3\n# x\n4,5,6", "p.csv", &cols).unwrap();
        assert_eq!(t.lines, vec![1, 3]);
        // A trailing comma is a fourth field.
        let e = parse_csv("1,2,3,\n", "p.csv", &cols).unwrap_err();
        assert_eq!(e.line(), Some(1));
        assert!(e.to_string().contains("found 4 fields"), "{e}");
        // Empty input: no rows.
        assert!(parse_csv("", "p.csv", &cols).unwrap().rows.is_empty());
    }

    #[test]
    fn vectors_and_floats() {
        assert_eq!(parse_vector::<3>("0.1, -2,3e1"), Ok([0.1, -2.0, 30.0]));
        assert!(parse_vector::<3>("1,2").is_err());
        assert!(parse_vector::<3>("1,2,inf").is_err());
        assert_eq!(format_float(320.0f64), "320.0");
        assert_eq!(format_float(0.1f32), "0.1");
        assert_eq!(format_float(f64::NAN), "nan");
        assert_eq!(format_float(1e300f64), "1e300");
    }

    #[test]
    fn tables() {
        let rows = [["1.5", "nan", "ok"], ["-2.0", "", "behind_camera"]];
        assert_eq!(
            format_csv(&["u", "v", "status"], rows),
            "u,v,status\n1.5,nan,ok\n-2.0,,behind_camera\n"
        );
        assert_eq!(format_csv(&["a"], [["x,y"]]), "a\n\"x,y\"\n");
        assert_eq!(format_csv(&["a", "b"], Vec::<[&str; 2]>::new()), "a,b\n");
    }
}
