//! OpenCV `FileStorage` files, YAML and XML, read into one small tree.
//!
//! serde_yaml is deprecated and rejects OpenCV's `%YAML:1.0` directive, so this is a small parser
//! for the subset OpenCV writes:
//!
//! * YAML: an optional `%YAML:1.0` (or `%YAML 1.0`) line and `---`; block mappings
//!   `key: value` nested by indentation; block sequences `- item` (also `- key: value` items);
//!   flow sequences `[a, b, ...]` and flow mappings `{ k: v, ... }` that may span lines; tags such
//!   as `!!opencv-matrix` before a block or flow mapping; plain, `"double"` and `'single'`
//!   quoted scalars; `#` comments. Block scalars (`|`, `>`), anchors and multi-line plain scalars
//!   are not part of OpenCV's output and are rejected with an error.
//! * XML: `<opencv_storage>` with one element per key; `type_id="opencv-matrix"` elements with
//!   `<rows>`, `<cols>`, `<dt>`, `<data>`; whitespace-separated numbers in text form a sequence;
//!   elements named `_` are sequence items.
//!
//! [`FileStorage::matrix`] turns an `opencv-matrix` node into a [`Matrix`], checking that `data`
//! holds `rows * cols * channels` numbers.

use std::path::{Path, PathBuf};

use nalgebra::Matrix3;

use crate::error::{Error, ErrorKind, Result};

/// A value in a `FileStorage` tree.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// A scalar as written (numbers are parsed on demand).
    Scalar {
        /// The text, unquoted.
        text: String,
        /// `true` for a quoted string (which is never read as a number).
        quoted: bool,
    },
    /// A sequence.
    Seq(Vec<Node>),
    /// A mapping, in file order.
    Map(Vec<(String, Node)>),
}

/// A node of the tree: its value, its tag (`opencv-matrix`, without `!!`) and the line it starts
/// on (1-based, for error messages).
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// Tag without the leading `!`/`!!` (YAML) or the `type_id` attribute (XML).
    pub tag: Option<String>,
    /// 1-based line where the node starts.
    pub line: usize,
    /// The value.
    pub value: Value,
}

impl Node {
    fn scalar(text: impl Into<String>, quoted: bool, line: usize) -> Self {
        Node {
            tag: None,
            line,
            value: Value::Scalar {
                text: text.into(),
                quoted,
            },
        }
    }

    /// The child of a mapping node.
    pub fn get(&self, key: &str) -> Option<&Node> {
        match &self.value {
            Value::Map(entries) => entries.iter().find(|(k, _)| k == key).map(|(_, v)| v),
            _ => None,
        }
    }

    /// The scalar text, if this is a scalar.
    pub fn as_scalar(&self) -> Option<&str> {
        match &self.value {
            Value::Scalar { text, .. } => Some(text),
            _ => None,
        }
    }

    /// The number held by an unquoted scalar, if it is one (OpenCV's `.Inf`, `-.Inf` and `.NaN`
    /// included).
    pub fn as_f64(&self) -> Option<f64> {
        match &self.value {
            Value::Scalar {
                text,
                quoted: false,
            } => parse_number(text),
            _ => None,
        }
    }
}

/// Parses a number as OpenCV writes it: `1.`, `5.3e+02`, `-2`, `.Inf`, `-.Inf`, `.NaN`.
pub fn parse_number(text: &str) -> Option<f64> {
    let t = text.trim();
    match t.to_ascii_lowercase().as_str() {
        ".inf" | "+.inf" => return Some(f64::INFINITY),
        "-.inf" => return Some(f64::NEG_INFINITY),
        ".nan" => return Some(f64::NAN),
        _ => {}
    }
    // Rust's parser also takes "inf"/"nan"/"infinity": harmless, camgeom rejects non-finite
    // values with its own typed error.
    t.parse::<f64>().ok()
}

/// A dense matrix read from an `opencv-matrix` node (row-major, channels interleaved, as OpenCV
/// stores it).
#[derive(Debug, Clone, PartialEq)]
pub struct Matrix {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Channels per element (`dt: 3d` has 3; usually 1).
    pub channels: usize,
    /// The element type code (`d`, `f`, `i`, `u`, ...), without the channel count.
    pub dt: char,
    /// `rows * cols * channels` values, row-major.
    pub data: Vec<f64>,
}

impl Matrix {
    /// Element `(r, c)` of a single-channel matrix.
    pub fn get(&self, r: usize, c: usize) -> Option<f64> {
        if r < self.rows && c < self.cols && self.channels == 1 {
            self.data.get(r * self.cols + c).copied()
        } else {
            None
        }
    }

    /// Row `r` (all its columns and channels).
    pub fn row(&self, r: usize) -> Option<&[f64]> {
        let w = self.cols * self.channels;
        self.data.get(r * w..(r + 1) * w)
    }

    /// The matrix as an nalgebra 3x3, when it is a single-channel 3x3.
    pub fn to_matrix3(&self) -> Option<Matrix3<f64>> {
        if self.rows == 3 && self.cols == 3 && self.channels == 1 {
            Some(Matrix3::from_row_slice(&self.data))
        } else {
            None
        }
    }

    /// `true` for a single-channel row or column vector.
    pub fn is_vector(&self) -> bool {
        self.channels == 1 && (self.rows == 1 || self.cols == 1)
    }
}

/// A parsed OpenCV `FileStorage` file (YAML or XML).
#[derive(Debug, Clone, PartialEq)]
pub struct FileStorage {
    path: PathBuf,
    root: Node,
}

impl FileStorage {
    /// Reads and parses `path`, choosing the syntax by extension: `.yml`/`.yaml` or `.xml`.
    pub fn open(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let ext = extension(path);
        let text = read_text(path)?;
        match ext.as_str() {
            "yml" | "yaml" => Self::parse_yaml(&text, path),
            "xml" => Self::parse_xml(&text, path),
            _ => Err(Error::new(
                path,
                ErrorKind::Unsupported(format!(
                    "`{}` is not an OpenCV FileStorage extension (expected .yml, .yaml or .xml)",
                    ext_display(&ext)
                )),
            )),
        }
    }

    /// Parses OpenCV's YAML; `path` is only used in error messages.
    pub fn parse_yaml(text: &str, path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let root = yaml::Parser::new(text, path).document()?;
        Ok(Self {
            path: path.to_path_buf(),
            root,
        })
    }

    /// Parses OpenCV's XML; `path` is only used in error messages.
    pub fn parse_xml(text: &str, path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let root = xml::Parser::new(text, path).document()?;
        Ok(Self {
            path: path.to_path_buf(),
            root,
        })
    }

    /// The file the storage was read from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The top-level mapping.
    pub fn root(&self) -> &Node {
        &self.root
    }

    /// A top-level node.
    pub fn get(&self, key: &str) -> Option<&Node> {
        self.root.get(key)
    }

    /// The first of `keys` that is present (for keys with several spellings in the wild).
    pub fn get_any<'k>(&self, keys: &[&'k str]) -> Option<(&'k str, &Node)> {
        keys.iter().find_map(|k| self.get(k).map(|n| (*k, n)))
    }

    /// A top-level number; `Ok(None)` when the key is absent, an error when it is not a number.
    pub fn number(&self, key: &str) -> Result<Option<f64>> {
        match self.get(key) {
            None => Ok(None),
            Some(n) => n.as_f64().map(Some).ok_or_else(|| {
                self.err(
                    n.line,
                    ErrorKind::Syntax(format!("`{key}` is not a number")),
                )
            }),
        }
    }

    /// A top-level non-negative integer; `Ok(None)` when absent.
    pub fn integer(&self, key: &str) -> Result<Option<u64>> {
        match self.get(key) {
            None => Ok(None),
            Some(n) => node_integer(n)
                .map(Some)
                .ok_or_else(|| self.err(n.line, not_integer(key))),
        }
    }

    /// The top-level `opencv-matrix` `key`; [`ErrorKind::MissingKey`] when absent.
    pub fn matrix(&self, key: &str) -> Result<Matrix> {
        let node = self
            .get(key)
            .ok_or_else(|| Error::new(&self.path, ErrorKind::MissingKey(key.to_string())))?;
        self.node_matrix(node, key)
    }

    /// Reads `node` (named `name` in messages) as an `opencv-matrix`.
    pub fn node_matrix(&self, node: &Node, name: &str) -> Result<Matrix> {
        if let Some(tag) = node.tag.as_deref() {
            if tag == "opencv-nd-matrix" {
                return Err(self.err(
                    node.line,
                    ErrorKind::Unsupported(format!("`{name}` is an opencv-nd-matrix")),
                ));
            }
            if tag != "opencv-matrix" {
                return Err(self.err(
                    node.line,
                    ErrorKind::Syntax(format!(
                        "`{name}` is tagged `{tag}`, expected an opencv-matrix"
                    )),
                ));
            }
        }
        if !matches!(node.value, Value::Map(_)) {
            return Err(self.err(
                node.line,
                ErrorKind::Syntax(format!(
                    "`{name}` is not an opencv-matrix (a mapping with rows, cols, dt, data)"
                )),
            ));
        }
        let field = |f: &str| {
            node.get(f)
                .ok_or_else(|| self.err(node.line, ErrorKind::MissingKey(format!("{name}.{f}"))))
        };
        let dim = |f: &str| -> Result<usize> {
            let n = field(f)?;
            node_integer(n)
                .and_then(|v| usize::try_from(v).ok())
                .ok_or_else(|| self.err(n.line, not_integer(&format!("{name}.{f}"))))
        };
        let rows = dim("rows")?;
        let cols = dim("cols")?;
        let dt_node = field("dt")?;
        let (channels, dt) = dt_node.as_scalar().and_then(parse_dt).ok_or_else(|| {
            self.err(
                dt_node.line,
                ErrorKind::Syntax(format!(
                    "`{name}.dt` must be an OpenCV element type such as `d`, `f` or `3d`"
                )),
            )
        })?;
        let data_node = field("data")?;
        let items: Vec<&Node> = match &data_node.value {
            Value::Seq(items) => items.iter().collect(),
            // A 1x1 matrix in XML is a single token; an empty `<data>` is an empty scalar.
            Value::Scalar { text, .. } if text.trim().is_empty() => Vec::new(),
            Value::Scalar { .. } => vec![data_node],
            Value::Map(_) => {
                return Err(self.err(
                    data_node.line,
                    ErrorKind::Syntax(format!("`{name}.data` must be a list of numbers")),
                ));
            }
        };
        let mut data = Vec::with_capacity(items.len());
        for (i, item) in items.iter().enumerate() {
            let v = item.as_f64().ok_or_else(|| {
                let shown = item.as_scalar().unwrap_or("(a nested list or mapping)");
                self.err(
                    item.line,
                    ErrorKind::Syntax(format!("`{name}.data[{i}]` is not a number: `{shown}`")),
                )
            })?;
            data.push(v);
        }
        let expected = rows.checked_mul(cols).and_then(|n| n.checked_mul(channels));
        if expected != Some(data.len()) {
            return Err(self.err(
                data_node.line,
                ErrorKind::Shape(format!(
                    "`{name}` declares {rows}x{cols}{} but `data` holds {} values",
                    if channels == 1 {
                        String::new()
                    } else {
                        format!(" with {channels} channels")
                    },
                    data.len()
                )),
            ));
        }
        Ok(Matrix {
            rows,
            cols,
            channels,
            dt,
            data,
        })
    }

    fn err(&self, line: usize, kind: ErrorKind) -> Error {
        Error::at_line(&self.path, line, kind)
    }
}

fn not_integer(name: &str) -> ErrorKind {
    ErrorKind::Syntax(format!("`{name}` must be a non-negative integer"))
}

fn node_integer(n: &Node) -> Option<u64> {
    match &n.value {
        Value::Scalar {
            text,
            quoted: false,
        } => text.trim().parse::<u64>().ok(),
        _ => None,
    }
}

/// `d` → (1, 'd'), `3f` → (3, 'f'). OpenCV's element codes: u c w s i f d h r.
fn parse_dt(s: &str) -> Option<(usize, char)> {
    let s = s.trim();
    let digits = s.chars().take_while(|c| c.is_ascii_digit()).count();
    let rest = &s[digits..];
    let mut chars = rest.chars();
    let code = chars.next()?;
    if chars.next().is_some() || !"ucwsifdhr".contains(code) {
        return None;
    }
    let channels = if digits == 0 {
        1
    } else {
        s[..digits].parse::<usize>().ok().filter(|&c| c >= 1)?
    };
    Some((channels, code))
}

/// The lower-case extension of `path` (`""` when none).
pub(crate) fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

pub(crate) fn ext_display(ext: &str) -> String {
    if ext.is_empty() {
        "(no extension)".to_string()
    } else {
        format!(".{ext}")
    }
}

/// Reads a UTF-8 text file (`-` reads standard input), dropping a byte-order mark and turning
/// CRLF into LF.
pub fn read_text(path: &Path) -> Result<String> {
    let raw = if path.as_os_str() == "-" {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut std::io::stdin(), &mut s)
            .map(|_| s)
            .map_err(|e| Error::new(path, ErrorKind::Io(e)))?
    } else {
        std::fs::read_to_string(path).map_err(|e| Error::new(path, ErrorKind::Io(e)))?
    };
    let s = raw.strip_prefix('\u{feff}').unwrap_or(&raw);
    Ok(if s.contains('\r') {
        s.replace("\r\n", "\n")
    } else {
        s.to_string()
    })
}

/// Reads a matrix stored as plain text: one row per non-empty line, numbers separated by
/// whitespace (or commas), `#` starting a comment. This is how the Oxford data sets ship their
/// homographies (`H1to3p`); the OpenCV XML copy of such a file is read with
/// [`FileStorage::matrix`].
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

mod yaml {
    //! The YAML subset of OpenCV's `FileStorage` (see the module docs).

    use std::path::Path;

    use super::{Node, Value};
    use crate::error::{Error, ErrorKind, Result};

    pub(super) struct Parser<'a> {
        src: &'a str,
        b: &'a [u8],
        pos: usize,
        line: usize,
        path: &'a Path,
    }

    /// Flow collections nest this deep at most (a bound, so hostile input cannot overflow the
    /// stack).
    const MAX_DEPTH: usize = 64;

    impl<'a> Parser<'a> {
        pub(super) fn new(src: &'a str, path: &'a Path) -> Self {
            Self {
                src,
                b: src.as_bytes(),
                pos: 0,
                line: 1,
                path,
            }
        }

        fn err(&self, msg: impl Into<String>) -> Error {
            Error::at_line(self.path, self.line, ErrorKind::Syntax(msg.into()))
        }

        fn peek(&self) -> Option<u8> {
            self.b.get(self.pos).copied()
        }

        fn peek_at(&self, off: usize) -> Option<u8> {
            self.b.get(self.pos + off).copied()
        }

        fn bump(&mut self) {
            if self.peek() == Some(b'\n') {
                self.line += 1;
            }
            self.pos += 1;
        }

        fn col(&self) -> usize {
            let start = self.b[..self.pos]
                .iter()
                .rposition(|&c| c == b'\n')
                .map_or(0, |p| p + 1);
            self.pos - start
        }

        /// Skips spaces and tabs on the current line.
        fn skip_spaces(&mut self) {
            while matches!(self.peek(), Some(b' ' | b'\t')) {
                self.bump();
            }
        }

        /// Skips to just past the end of the current line.
        fn skip_line(&mut self) {
            while let Some(c) = self.peek() {
                self.bump();
                if c == b'\n' {
                    break;
                }
            }
        }

        /// After a value: only spaces and a comment may follow on the line; moves to the start
        /// of the next line.
        fn end_of_line(&mut self) -> Result<()> {
            self.skip_spaces();
            match self.peek() {
                None => Ok(()),
                Some(b'\n') => {
                    self.bump();
                    Ok(())
                }
                Some(b'#') => {
                    self.skip_line();
                    Ok(())
                }
                Some(c) => Err(self.err(format!(
                    "unexpected `{}` after a value",
                    char::from(c).escape_default()
                ))),
            }
        }

        /// From the start of a line: skips blank and comment-only lines and returns the indent
        /// of the next content line without consuming it (`None` at the end of the document).
        fn next_content_indent(&mut self) -> Result<Option<usize>> {
            loop {
                let mut i = self.pos;
                while self.b.get(i) == Some(&b' ') {
                    i += 1;
                }
                match self.b.get(i) {
                    None => {
                        self.pos = i;
                        return Ok(None);
                    }
                    Some(b'\n') => {
                        self.pos = i;
                        self.bump();
                    }
                    Some(b'#') => {
                        self.pos = i;
                        self.skip_line();
                    }
                    Some(b'\t') => {
                        self.pos = i;
                        return Err(self.err("tab in indentation"));
                    }
                    Some(_) => {
                        let indent = i - self.pos;
                        // The document end marker `...` or a second document `---`.
                        if indent == 0 && self.is_marker(i) {
                            return Ok(None);
                        }
                        return Ok(Some(indent));
                    }
                }
            }
        }

        fn is_marker(&self, i: usize) -> bool {
            let rest = &self.b[i..];
            (rest.starts_with(b"---") || rest.starts_with(b"..."))
                && matches!(rest.get(3), None | Some(b' ' | b'\n'))
        }

        fn at_seq_entry(&self) -> bool {
            self.peek() == Some(b'-') && matches!(self.peek_at(1), None | Some(b' ' | b'\n'))
        }

        pub(super) fn document(mut self) -> Result<Node> {
            // Directives (`%YAML:1.0`, `%YAML 1.0`, `%TAG ...`) and the `---` marker.
            loop {
                match self.next_content_indent()? {
                    Some(0) if self.peek() == Some(b'%') => self.skip_line(),
                    _ => break,
                }
            }
            if self.is_marker(self.pos) && self.b[self.pos..].starts_with(b"---") {
                self.pos += 3;
                self.skip_spaces();
                if !matches!(self.peek(), None | Some(b'\n' | b'#')) {
                    return Err(self.err("content on the `---` line is not supported"));
                }
                self.skip_line();
            }
            let line = self.line;
            let root = match self.next_content_indent()? {
                None => Node {
                    tag: None,
                    line,
                    value: Value::Map(Vec::new()),
                },
                Some(ind) => {
                    self.pos += ind;
                    if self.at_seq_entry() {
                        return Err(self.err("the top level must be a mapping (`key: value`)"));
                    }
                    self.block_map(ind)?
                }
            };
            // Anything after the root must be the end of the document.
            if self.pos < self.b.len() {
                let rest = &self.b[self.pos..];
                if rest.starts_with(b"---") {
                    return Err(self.err("more than one YAML document in the file"));
                }
                if !rest.starts_with(b"...") {
                    return Err(self.err("unexpected content after the document"));
                }
            }
            Ok(root)
        }

        /// A block node whose first line's content starts at the cursor, in column `ind`.
        fn block_node(&mut self, ind: usize) -> Result<Node> {
            if self.at_seq_entry() {
                self.block_seq(ind)
            } else {
                self.block_map(ind)
            }
        }

        fn block_map(&mut self, ind: usize) -> Result<Node> {
            let line = self.line;
            let mut entries: Vec<(String, Node)> = Vec::new();
            loop {
                let key_line = self.line;
                let key = self.block_key()?;
                if entries.iter().any(|(k, _)| *k == key) {
                    return Err(Error::at_line(
                        self.path,
                        key_line,
                        ErrorKind::Syntax(format!("duplicate key `{key}`")),
                    ));
                }
                let value = self.value_after_indicator(ind, true)?;
                entries.push((key, value));
                match self.next_content_indent()? {
                    None => break,
                    Some(i) if i < ind => break,
                    Some(i) if i == ind => {
                        self.pos += i;
                        if self.at_seq_entry() {
                            return Err(self.err("a sequence entry `- ` where a key was expected"));
                        }
                    }
                    Some(_) => {
                        self.skip_spaces();
                        return Err(self.err(
                            "unexpected indentation (multi-line plain scalars are not supported)",
                        ));
                    }
                }
            }
            Ok(Node {
                tag: None,
                line,
                value: Value::Map(entries),
            })
        }

        fn block_seq(&mut self, ind: usize) -> Result<Node> {
            let line = self.line;
            let mut items = Vec::new();
            loop {
                // At `-`.
                self.bump();
                let item = self.value_after_indicator(ind, false)?;
                items.push(item);
                match self.next_content_indent()? {
                    None => break,
                    Some(i) if i < ind => break,
                    Some(i) if i == ind => {
                        self.pos += i;
                        if !self.at_seq_entry() {
                            // A key at the same indent belongs to the parent mapping (the
                            // compact `key:\n- a\n- b` form); give control back.
                            self.pos -= i;
                            break;
                        }
                    }
                    Some(_) => {
                        self.skip_spaces();
                        return Err(self.err("unexpected indentation in a sequence"));
                    }
                }
            }
            Ok(Node {
                tag: None,
                line,
                value: Value::Seq(items),
            })
        }

        /// A mapping key up to its `:` (which must be followed by a space or the line end);
        /// consumes the `:`.
        fn block_key(&mut self) -> Result<String> {
            if matches!(self.peek(), Some(b'"' | b'\'')) {
                let key = self.quoted()?;
                self.skip_spaces();
                if self.peek() != Some(b':') {
                    return Err(self.err("expected `:` after a quoted key"));
                }
                self.bump();
                return Ok(key);
            }
            let start = self.pos;
            loop {
                match self.peek() {
                    None | Some(b'\n') => {
                        return Err(self.err(format!(
                            "expected `key: value`, found `{}`",
                            self.src[start..self.pos].trim()
                        )));
                    }
                    Some(b':') if matches!(self.peek_at(1), None | Some(b' ' | b'\t' | b'\n')) => {
                        let key = self.src[start..self.pos].trim_end().to_string();
                        self.bump();
                        if key.is_empty() {
                            return Err(self.err("empty key"));
                        }
                        return Ok(key);
                    }
                    Some(b'#') if self.pos > start && self.b[self.pos - 1] == b' ' => {
                        return Err(self.err("expected `key: value` before the comment"));
                    }
                    Some(_) => self.bump(),
                }
            }
        }

        /// The value after `key:` (`in_map`) or after `- `; ends at the start of the next line.
        fn value_after_indicator(&mut self, ind: usize, in_map: bool) -> Result<Node> {
            self.skip_spaces();
            let tag = self.tag()?;
            self.skip_spaces();
            let line = self.line;
            let mut node = match self.peek() {
                None | Some(b'\n') | Some(b'#') => {
                    self.end_of_line()?;
                    match self.next_content_indent()? {
                        Some(i) if i > ind => {
                            self.pos += i;
                            self.block_node(i)?
                        }
                        Some(i) if i == ind && in_map => {
                            self.pos += i;
                            let seq = self.at_seq_entry();
                            if seq {
                                self.block_seq(i)?
                            } else {
                                self.pos -= i;
                                Node::scalar("", false, line)
                            }
                        }
                        _ => Node::scalar("", false, line),
                    }
                }
                Some(b'[' | b'{') => {
                    let n = self.flow_node(0)?;
                    self.end_of_line()?;
                    n
                }
                Some(b'"' | b'\'') => {
                    let s = self.quoted()?;
                    self.skip_spaces();
                    if !in_map && self.peek() == Some(b':') {
                        return Err(self.err("quoted keys in sequence items are not supported"));
                    }
                    self.end_of_line()?;
                    Node::scalar(s, true, line)
                }
                Some(b'|' | b'>') => {
                    return Err(self.err("block scalars (`|`, `>`) are not supported"));
                }
                Some(b'&' | b'*') => {
                    return Err(self.err("anchors and aliases are not supported"));
                }
                Some(b'-') if !in_map && self.at_seq_entry() => {
                    // `- - a`: a nested sequence starting on the item's line.
                    let c = self.col();
                    self.block_seq(c)?
                }
                Some(_) => {
                    if !in_map && self.line_has_key() {
                        // `- key: value` starts a mapping in the item's column.
                        let c = self.col();
                        self.block_map(c)?
                    } else {
                        let s = self.plain_block_scalar();
                        self.end_of_line()?;
                        Node::scalar(s, false, line)
                    }
                }
            };
            if tag.is_some() {
                node.tag = tag;
            }
            Ok(node)
        }

        /// `true` when the rest of the line reads `key: ...`.
        fn line_has_key(&self) -> bool {
            let rest = &self.b[self.pos..];
            let end = rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
            let line = &rest[..end];
            line.windows(2).any(|w| w == b": ") || line.last() == Some(&b':')
        }

        /// An optional `!tag` / `!!tag`, returned without the `!`s.
        fn tag(&mut self) -> Result<Option<String>> {
            if self.peek() != Some(b'!') {
                return Ok(None);
            }
            let start = self.pos;
            while matches!(self.peek(), Some(c) if !matches!(c, b' ' | b'\t' | b'\n' | b'{' | b'['))
            {
                self.bump();
            }
            let t = self.src[start..self.pos].trim_start_matches('!');
            if t.is_empty() {
                return Err(self.err("empty tag"));
            }
            Ok(Some(t.to_string()))
        }

        /// A plain scalar to the end of the line or a ` #` comment, trimmed.
        fn plain_block_scalar(&mut self) -> String {
            let start = self.pos;
            while let Some(c) = self.peek() {
                if c == b'\n' || (c == b'#' && self.pos > start && self.b[self.pos - 1] == b' ') {
                    break;
                }
                self.bump();
            }
            self.src[start..self.pos].trim().to_string()
        }

        /// A `"..."` or `'...'` scalar, unescaped.
        fn quoted(&mut self) -> Result<String> {
            let q = self.peek().unwrap_or(b'"');
            let line = self.line;
            self.bump();
            let mut out = String::new();
            loop {
                let Some(c) = self.peek() else {
                    return Err(Error::at_line(
                        self.path,
                        line,
                        ErrorKind::Syntax("unterminated quoted string".to_string()),
                    ));
                };
                if c == q {
                    if q == b'\'' && self.peek_at(1) == Some(b'\'') {
                        out.push('\'');
                        self.bump();
                        self.bump();
                        continue;
                    }
                    self.bump();
                    return Ok(out);
                }
                if c == b'\\' && q == b'"' {
                    self.bump();
                    let e = self.peek().ok_or_else(|| self.err("unterminated escape"))?;
                    out.push(match e {
                        b'n' => '\n',
                        b't' => '\t',
                        b'r' => '\r',
                        b'0' => '\0',
                        b'"' => '"',
                        b'\\' => '\\',
                        b'/' => '/',
                        _ => return Err(self.err("unsupported escape in a quoted string")),
                    });
                    self.bump();
                    continue;
                }
                // Copy one UTF-8 character.
                let ch = self.src[self.pos..].chars().next().unwrap_or('\u{fffd}');
                out.push(ch);
                for _ in 0..ch.len_utf8() {
                    self.bump();
                }
            }
        }

        /// Skips whitespace, newlines and comments inside a flow collection.
        fn skip_flow_space(&mut self) -> Result<()> {
            loop {
                match self.peek() {
                    Some(b' ' | b'\t' | b'\n') => self.bump(),
                    Some(b'#') => self.skip_line(),
                    None => return Err(self.err("unterminated `[` or `{`")),
                    Some(_) => return Ok(()),
                }
            }
        }

        fn flow_node(&mut self, depth: usize) -> Result<Node> {
            if depth > MAX_DEPTH {
                return Err(self.err("flow collections nested too deeply"));
            }
            let tag = self.tag()?;
            if tag.is_some() {
                self.skip_flow_space()?;
            }
            let line = self.line;
            let mut node = match self.peek() {
                Some(b'[') => {
                    self.bump();
                    let mut items = Vec::new();
                    loop {
                        self.skip_flow_space()?;
                        if self.peek() == Some(b']') {
                            self.bump();
                            break;
                        }
                        items.push(self.flow_node(depth + 1)?);
                        self.skip_flow_space()?;
                        match self.peek() {
                            Some(b',') => self.bump(),
                            Some(b']') => {
                                self.bump();
                                break;
                            }
                            _ => return Err(self.err("expected `,` or `]` in a flow sequence")),
                        }
                    }
                    Node {
                        tag: None,
                        line,
                        value: Value::Seq(items),
                    }
                }
                Some(b'{') => {
                    self.bump();
                    let mut entries: Vec<(String, Node)> = Vec::new();
                    loop {
                        self.skip_flow_space()?;
                        if self.peek() == Some(b'}') {
                            self.bump();
                            break;
                        }
                        let key = if matches!(self.peek(), Some(b'"' | b'\'')) {
                            self.quoted()?
                        } else {
                            self.plain_flow_scalar(true)
                        };
                        if key.is_empty() {
                            return Err(self.err("expected a key in a flow mapping"));
                        }
                        self.skip_flow_space()?;
                        if self.peek() != Some(b':') {
                            return Err(self.err(format!("expected `:` after key `{key}`")));
                        }
                        self.bump();
                        self.skip_flow_space()?;
                        let value = self.flow_node(depth + 1)?;
                        if entries.iter().any(|(k, _)| *k == key) {
                            return Err(self.err(format!("duplicate key `{key}`")));
                        }
                        entries.push((key, value));
                        self.skip_flow_space()?;
                        match self.peek() {
                            Some(b',') => self.bump(),
                            Some(b'}') => {
                                self.bump();
                                break;
                            }
                            _ => return Err(self.err("expected `,` or `}` in a flow mapping")),
                        }
                    }
                    Node {
                        tag: None,
                        line,
                        value: Value::Map(entries),
                    }
                }
                Some(b'"' | b'\'') => Node::scalar(self.quoted()?, true, line),
                _ => {
                    let s = self.plain_flow_scalar(false);
                    if s.is_empty() {
                        return Err(self.err("expected a value"));
                    }
                    Node::scalar(s, false, line)
                }
            };
            if tag.is_some() {
                node.tag = tag;
            }
            Ok(node)
        }

        /// A plain scalar inside `[ ]` or `{ }`: ends at `,` `]` `}`, a line end, a ` #`
        /// comment, or (for keys) `:`.
        fn plain_flow_scalar(&mut self, key: bool) -> String {
            let start = self.pos;
            while let Some(c) = self.peek() {
                let stop = match c {
                    b',' | b']' | b'}' | b'\n' => true,
                    b':' => key || matches!(self.peek_at(1), Some(b' ' | b'\n')),
                    b'#' => self.pos > start && self.b[self.pos - 1] == b' ',
                    _ => false,
                };
                if stop {
                    break;
                }
                self.bump();
            }
            self.src[start..self.pos].trim().to_string()
        }
    }
}

mod xml {
    //! The XML form of OpenCV's `FileStorage`: a small, non-validating element parser.

    use std::path::Path;

    use super::{Node, Value};
    use crate::error::{Error, ErrorKind, Result};

    pub(super) struct Parser<'a> {
        src: &'a str,
        pos: usize,
        path: &'a Path,
    }

    const MAX_DEPTH: usize = 64;

    struct Element {
        name: String,
        type_id: Option<String>,
        line: usize,
        children: Vec<Element>,
        text: String,
        text_line: usize,
    }

    impl<'a> Parser<'a> {
        pub(super) fn new(src: &'a str, path: &'a Path) -> Self {
            Self { src, pos: 0, path }
        }

        fn line(&self) -> usize {
            self.src[..self.pos].bytes().filter(|&c| c == b'\n').count() + 1
        }

        fn err(&self, msg: impl Into<String>) -> Error {
            Error::at_line(self.path, self.line(), ErrorKind::Syntax(msg.into()))
        }

        fn rest(&self) -> &'a str {
            &self.src[self.pos..]
        }

        fn skip_ws(&mut self) {
            let r = self.rest();
            self.pos += r.len() - r.trim_start().len();
        }

        /// Skips `<?...?>`, `<!--...-->` and `<!DOCTYPE ...>` with the whitespace around them.
        fn skip_misc(&mut self) -> Result<()> {
            loop {
                self.skip_ws();
                let r = self.rest();
                let close = if r.starts_with("<?") {
                    "?>"
                } else if r.starts_with("<!--") {
                    "-->"
                } else if r.starts_with("<!") {
                    ">"
                } else {
                    return Ok(());
                };
                match r.find(close) {
                    Some(i) => self.pos += i + close.len(),
                    None => return Err(self.err("unterminated `<?`, `<!--` or `<!`")),
                }
            }
        }

        pub(super) fn document(mut self) -> Result<Node> {
            self.skip_misc()?;
            if !self.rest().starts_with('<') {
                return Err(self.err("expected `<opencv_storage>`"));
            }
            let root = self.element(0)?;
            if root.name != "opencv_storage" {
                return Err(Error::at_line(
                    self.path,
                    root.line,
                    ErrorKind::Syntax(format!(
                        "the root element is `<{}>`, expected `<opencv_storage>`",
                        root.name
                    )),
                ));
            }
            self.skip_misc()?;
            if !self.rest().is_empty() {
                return Err(self.err("unexpected content after `</opencv_storage>`"));
            }
            let line = root.line;
            let mut node = self.to_node(root)?;
            if !matches!(node.value, Value::Map(_)) {
                node = Node {
                    tag: None,
                    line,
                    value: Value::Map(Vec::new()),
                };
            }
            Ok(node)
        }

        fn name(&mut self) -> Result<String> {
            let r = self.rest();
            let n = r
                .find(|c: char| c.is_whitespace() || c == '>' || c == '/' || c == '=')
                .unwrap_or(r.len());
            if n == 0 {
                return Err(self.err("expected an element or attribute name"));
            }
            self.pos += n;
            Ok(r[..n].to_string())
        }

        fn element(&mut self, depth: usize) -> Result<Element> {
            if depth > MAX_DEPTH {
                return Err(self.err("elements nested too deeply"));
            }
            let line = self.line();
            self.pos += 1; // '<'
            let name = self.name()?;
            let mut type_id = None;
            // Attributes.
            loop {
                self.skip_ws();
                let r = self.rest();
                if r.starts_with("/>") {
                    self.pos += 2;
                    return Ok(Element {
                        name,
                        type_id,
                        line,
                        children: Vec::new(),
                        text: String::new(),
                        text_line: line,
                    });
                }
                if r.starts_with('>') {
                    self.pos += 1;
                    break;
                }
                if r.is_empty() {
                    return Err(self.err(format!("unterminated tag `<{name}`")));
                }
                let attr = self.name()?;
                self.skip_ws();
                if !self.rest().starts_with('=') {
                    return Err(self.err(format!("expected `=` after attribute `{attr}`")));
                }
                self.pos += 1;
                self.skip_ws();
                let q = self.rest().chars().next();
                let Some(q @ ('"' | '\'')) = q else {
                    return Err(self.err(format!("attribute `{attr}` needs a quoted value")));
                };
                self.pos += 1;
                let r = self.rest();
                let end = r
                    .find(q)
                    .ok_or_else(|| self.err("unterminated attribute value"))?;
                let value = decode_entities(&r[..end]).map_err(|m| self.err(m))?;
                self.pos += end + 1;
                if attr == "type_id" {
                    type_id = Some(value);
                }
            }
            // Content.
            let mut children = Vec::new();
            let mut text = String::new();
            let mut text_line = self.line();
            loop {
                let r = self.rest();
                let lt = r
                    .find('<')
                    .ok_or_else(|| self.err(format!("`<{name}>` is never closed")))?;
                if !r[..lt].trim().is_empty() {
                    if text.trim().is_empty() {
                        let chunk = &r[..lt];
                        let lead = &chunk[..chunk.len() - chunk.trim_start().len()];
                        text_line = self.line() + lead.bytes().filter(|&c| c == b'\n').count();
                    }
                    text.push_str(&decode_entities(&r[..lt]).map_err(|m| self.err(m))?);
                } else {
                    text.push(' ');
                }
                self.pos += lt;
                let r = self.rest();
                if r.starts_with("</") {
                    self.pos += 2;
                    let close = self.name()?;
                    if close != name {
                        return Err(self.err(format!("`<{name}>` is closed by `</{close}>`")));
                    }
                    self.skip_ws();
                    if !self.rest().starts_with('>') {
                        return Err(self.err(format!("expected `>` after `</{close}`")));
                    }
                    self.pos += 1;
                    break;
                } else if r.starts_with("<!--") {
                    let end = r
                        .find("-->")
                        .ok_or_else(|| self.err("unterminated comment"))?;
                    self.pos += end + 3;
                } else if r.starts_with("<![CDATA[") {
                    let end = r
                        .find("]]>")
                        .ok_or_else(|| self.err("unterminated CDATA"))?;
                    text.push_str(&r[9..end]);
                    self.pos += end + 3;
                } else {
                    children.push(self.element(depth + 1)?);
                }
            }
            Ok(Element {
                name,
                type_id,
                line,
                children,
                text,
                text_line,
            })
        }

        fn to_node(&self, e: Element) -> Result<Node> {
            let tag = e.type_id.clone();
            if !e.children.is_empty() {
                if !e.text.trim().is_empty() {
                    return Err(Error::at_line(
                        self.path,
                        e.text_line,
                        ErrorKind::Syntax(format!("`<{}>` mixes text with child elements", e.name)),
                    ));
                }
                let seq = e.children.iter().all(|c| c.name == "_");
                let value = if seq {
                    Value::Seq(
                        e.children
                            .into_iter()
                            .map(|c| self.to_node(c))
                            .collect::<Result<_>>()?,
                    )
                } else {
                    let mut entries: Vec<(String, Node)> = Vec::new();
                    for c in e.children {
                        if entries.iter().any(|(k, _)| *k == c.name) {
                            return Err(Error::at_line(
                                self.path,
                                c.line,
                                ErrorKind::Syntax(format!("duplicate key `{}`", c.name)),
                            ));
                        }
                        let name = c.name.clone();
                        entries.push((name, self.to_node(c)?));
                    }
                    Value::Map(entries)
                };
                return Ok(Node {
                    tag,
                    line: e.line,
                    value,
                });
            }
            if tag.as_deref() == Some("opencv-matrix") {
                // A matrix element without children is malformed; let the matrix reader say
                // which field is missing.
                return Ok(Node {
                    tag,
                    line: e.line,
                    value: Value::Map(Vec::new()),
                });
            }
            // Text: one token is a scalar, several form a sequence (how OpenCV writes lists of
            // numbers); a quoted token is a string.
            let tokens = tokenize(&e.text, e.text_line)
                .map_err(|m| Error::at_line(self.path, e.text_line, ErrorKind::Syntax(m)))?;
            let value = match tokens.len() {
                0 => Value::Scalar {
                    text: String::new(),
                    quoted: false,
                },
                1 => tokens
                    .into_iter()
                    .next()
                    .map(|n| n.value)
                    .unwrap_or(Value::Seq(Vec::new())),
                _ => Value::Seq(tokens),
            };
            Ok(Node {
                tag,
                line: e.line,
                value,
            })
        }
    }

    /// Splits text into whitespace-separated tokens, keeping `"quoted strings"` whole, each with
    /// its line.
    fn tokenize(text: &str, first_line: usize) -> std::result::Result<Vec<Node>, String> {
        let mut out = Vec::new();
        let mut line = first_line;
        let mut chars = text.chars().peekable();
        // The text may start with the newline after the opening tag, already counted.
        let mut seen_content = false;
        while let Some(&c) = chars.peek() {
            if c.is_whitespace() {
                if c == '\n' && seen_content {
                    line += 1;
                }
                chars.next();
                continue;
            }
            seen_content = true;
            if c == '"' {
                chars.next();
                let mut s = String::new();
                loop {
                    match chars.next() {
                        Some('"') => break,
                        Some(ch) => s.push(ch),
                        None => return Err("unterminated quoted string".to_string()),
                    }
                }
                out.push(Node::scalar(s, true, line));
            } else {
                let mut s = String::new();
                while let Some(&ch) = chars.peek() {
                    if ch.is_whitespace() {
                        break;
                    }
                    s.push(ch);
                    chars.next();
                }
                out.push(Node::scalar(s, false, line));
            }
        }
        Ok(out)
    }

    fn decode_entities(s: &str) -> std::result::Result<String, String> {
        if !s.contains('&') {
            return Ok(s.to_string());
        }
        let mut out = String::with_capacity(s.len());
        let mut rest = s;
        while let Some(i) = rest.find('&') {
            out.push_str(&rest[..i]);
            let after = &rest[i + 1..];
            let semi = after
                .find(';')
                .ok_or_else(|| "`&` without `;` (unescaped ampersand?)".to_string())?;
            let ent = &after[..semi];
            let ch = match ent {
                "lt" => '<',
                "gt" => '>',
                "amp" => '&',
                "quot" => '"',
                "apos" => '\'',
                _ => {
                    let code = if let Some(h) = ent.strip_prefix("#x") {
                        u32::from_str_radix(h, 16).ok()
                    } else if let Some(d) = ent.strip_prefix('#') {
                        d.parse().ok()
                    } else {
                        None
                    };
                    code.and_then(char::from_u32)
                        .ok_or_else(|| format!("unknown entity `&{ent};`"))?
                }
            };
            out.push(ch);
            rest = &after[semi + 1..];
        }
        out.push_str(rest);
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn yaml(s: &str) -> Result<FileStorage> {
        FileStorage::parse_yaml(s, "t.yml")
    }

    #[test]
    fn dt_codes() {
        assert_eq!(parse_dt("d"), Some((1, 'd')));
        assert_eq!(parse_dt("3f"), Some((3, 'f')));
        assert_eq!(parse_dt("x"), None);
        assert_eq!(parse_dt("0d"), None);
        assert_eq!(parse_dt(""), None);
    }

    #[test]
    fn block_and_flow_structures() {
        let fs = yaml(
            "%YAML:1.0\n---\na: 1\nb: \"two words\" # comment\nlist:\n  - 1\n  - { x: 1, y: 2 }\n  - k: v\n    k2: w\ncompact:\n- 3\n- 4\nnested:\n  inner: [1, [2, 3],\n     4]\nlast: x\n",
        )
        .unwrap();
        assert_eq!(fs.number("a").unwrap(), Some(1.0));
        assert_eq!(fs.get("b").unwrap().as_scalar(), Some("two words"));
        let Value::Seq(items) = &fs.get("list").unwrap().value else {
            panic!("list")
        };
        assert_eq!(items.len(), 3);
        assert_eq!(items[1].get("y").unwrap().as_f64(), Some(2.0));
        assert_eq!(items[2].get("k2").unwrap().as_scalar(), Some("w"));
        let Value::Seq(c) = &fs.get("compact").unwrap().value else {
            panic!("compact")
        };
        assert_eq!(c.len(), 2);
        let inner = fs.get("nested").unwrap().get("inner").unwrap();
        let Value::Seq(i) = &inner.value else {
            panic!("inner")
        };
        assert_eq!(i.len(), 3);
        assert_eq!(fs.get("last").unwrap().as_scalar(), Some("x"));
    }

    #[test]
    fn xml_text_and_sequences() {
        let fs = FileStorage::parse_xml(
            "<?xml version=\"1.0\"?>\n<opencv_storage>\n<!-- c -->\n<n>3</n>\n<s>\"a b\"</s>\n<v>1 2 3</v>\n<items><_>1</_><_>2</_></items>\n<m><a>1</a></m>\n</opencv_storage>\n",
            "t.xml",
        )
        .unwrap();
        assert_eq!(fs.integer("n").unwrap(), Some(3));
        assert_eq!(fs.get("s").unwrap().as_scalar(), Some("a b"));
        assert!(matches!(&fs.get("v").unwrap().value, Value::Seq(v) if v.len() == 3));
        assert!(matches!(&fs.get("items").unwrap().value, Value::Seq(v) if v.len() == 2));
        assert_eq!(fs.get("m").unwrap().get("a").unwrap().as_f64(), Some(1.0));
    }

    #[test]
    fn syntax_errors_carry_lines() {
        let e = yaml("a: 1\nb: [1, 2\n").unwrap_err();
        assert!(matches!(e.kind(), ErrorKind::Syntax(_)), "{e}");
        let e = yaml("a: 1\n  b: 2\n").unwrap_err();
        assert_eq!(e.line(), Some(2), "{e}");
        let e = yaml("a: 1\na: 2\n").unwrap_err();
        assert!(e.to_string().contains("duplicate key"), "{e}");
        let e = FileStorage::parse_xml("<opencv_storage><a>1</b></opencv_storage>", "t.xml")
            .unwrap_err();
        assert!(e.to_string().contains("closed by"), "{e}");
    }

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
