//! Matrices stored as plain text, one row a line (the Oxford data sets' homographies).

use std::path::Path;

use super::matrix::Matrix;
use super::node::parse_number;
use super::text_file::read_text;
use crate::error::{Error, ErrorKind, Result};

/// Reads a matrix stored as plain text: one row per non-empty line, numbers separated by
/// whitespace (or commas), `#` starting a comment. This is how the Oxford data sets ship their
/// homographies (`H1to3p`); the OpenCV XML copy of such a file is read with
/// [`FileStorage::matrix`](super::FileStorage::matrix).
pub fn read_matrix_text(path: impl AsRef<Path>) -> Result<Matrix> {
    let path = path.as_ref();
    parse_matrix_text(&read_text(path)?, path)
}

/// [`read_matrix_text`] on a string; `path` is only used in messages.
pub fn parse_matrix_text(text: &str, path: impl AsRef<Path>) -> Result<Matrix> {
    let path = path.as_ref();
    let mut data = Vec::new();
    let mut rows = 0usize;
    let mut cols = None;
    for (i, line) in text.lines().enumerate() {
        let content = line.split('#').next().unwrap_or("").trim();
        if content.is_empty() {
            continue;
        }
        let mut n = 0usize;
        for tok in content
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty())
        {
            let v = parse_number(tok).ok_or_else(|| {
                Error::at_line(
                    path,
                    i + 1,
                    ErrorKind::Syntax(format!("`{tok}` is not a number")),
                )
            })?;
            data.push(v);
            n += 1;
        }
        match cols {
            None => cols = Some(n),
            Some(c) if c != n => {
                return Err(Error::at_line(
                    path,
                    i + 1,
                    ErrorKind::Shape(format!("row has {n} numbers, the first row has {c}")),
                ));
            }
            _ => {}
        }
        rows += 1;
    }
    let cols = cols.ok_or_else(|| {
        Error::new(
            path,
            ErrorKind::Shape("the file holds no numbers".to_string()),
        )
    })?;
    Ok(Matrix {
        rows,
        cols,
        channels: 1,
        dt: 'd',
        data,
    })
}
#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matrix_text() {
        let m = parse_matrix_text("1 2 3\n4 5 6\n\n7 8 9.5\n", "h.txt").unwrap();
        assert_eq!((m.rows, m.cols), (3, 3));
        assert_eq!(m.get(2, 2), Some(9.5));
        assert!(parse_matrix_text("1 2\n3\n", "h.txt").is_err());
        assert!(parse_matrix_text("1 x\n", "h.txt").is_err());
        assert!(parse_matrix_text("\n", "h.txt").is_err());
    }
}
