//! OpenCV `FileStorage` files, YAML and XML, read into one small tree.
//!
//! The syntax is read by maintained parsers, [saphyr-parser] (YAML 1.2) and [roxmltree] (XML);
//! this module maps what they read onto [`Node`]s the way OpenCV lays its files out, and an
//! `opencv-matrix` node onto a [`Matrix`]:
//!
//! * YAML: OpenCV 3 and 4 start the file with `%YAML:1.0`, which no YAML 1.2 parser accepts, and
//!   OpenCV writes flow mappings as `{ a:1, b:2 }`, which YAML 1.2 reads as the single keys
//!   `"a:1"` and `"b:2"`. Both are rewritten before parsing (the directive becomes an empty
//!   line, the flow keys get a space after their `:`), keeping every line where it was so that
//!   messages give the file's own line numbers. Matrices are mappings tagged `!!opencv-matrix`
//!   with `rows`, `cols`, `dt` and `data` (a flow or block sequence). Aliases are rejected; a
//!   file holds one document whose top level is a mapping. (OpenCV's YAML writer puts a matrix
//!   inside a flow mapping as a block mapping, which is no YAML and which OpenCV's own reader
//!   rejects too: such a file is an error here.)
//! * XML: the root is `<opencv_storage>` with one element per key. An element with named
//!   children is a mapping; `<_>` children are sequence items; text is split at whitespace
//!   (keeping `"quoted strings"` whole) and several tokens form a sequence, one token a scalar.
//!   OpenCV writes a sequence of scalars and structures as text followed by `<_>` elements: the
//!   items keep the file's order. `type_id="opencv-matrix"` is the tag.
//!
//! [`FileStorage::matrix`] turns an `opencv-matrix` node into a [`Matrix`], checking that `data`
//! holds `rows * cols * channels` numbers. Every error names the file and the line.
//!
//! [`YamlWriter`] writes the other way: OpenCV's YAML layout, for camera files OpenCV reads
//! (`camgeom calibrate`).
//!
//! [saphyr-parser]: https://docs.rs/saphyr-parser
//! [roxmltree]: https://docs.rs/roxmltree

use std::path::{Path, PathBuf};

use nalgebra::Matrix3;

use crate::error::{Error, ErrorKind, Result};

/// Structures nest this deep at most: a bound, so that hostile input cannot exhaust the stack
/// (dropping a tree recurses). OpenCV's files nest three or four levels.
const MAX_DEPTH: usize = 64;

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
        let root = yaml::document(text, path)?;
        Ok(Self {
            path: path.to_path_buf(),
            root,
        })
    }

    /// Parses OpenCV's XML; `path` is only used in error messages.
    pub fn parse_xml(text: &str, path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let root = xml::document(text, path)?;
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

/// OpenCV's YAML as YAML 1.2, every line kept where it was (so that a parser's line numbers are
/// the file's):
///
/// * a `%YAML` directive before the document (`%YAML:1.0`, as OpenCV 3 and 4 write it, is not
///   YAML 1.2 syntax) becomes an empty line: the version changes nothing camgeom reads;
/// * in a flow mapping, OpenCV writes `key:value` without a space, which YAML 1.2 reads as one
///   plain scalar `"key:value"` with no value: a space is put after the key's `:`.
///
/// Quoted scalars and comments are copied untouched, so a `{` or `:` inside them changes
/// nothing. All other text is copied as it is. Also returns the innermost `[` or `{` left open
/// at the end of the text and its line, for messages.
fn to_yaml12(text: &str) -> (String, Option<(char, usize)>) {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len() + 16);
    // The open flow collections, `[` or `{` and its line, innermost last.
    let mut flow: Vec<(u8, usize)> = Vec::new();
    let mut line = 1;
    // Where a node may begin: a line start in block context, after `: `, `- `, `[`, `{`, `,`,
    // a tag or an anchor.
    let mut node_start = true;
    // At the start of an entry of a flow mapping, where OpenCV writes `key:value`.
    let mut flow_key = false;
    // Before the document's content, where directives are.
    let mut prolog = true;
    let mut i = 0;
    while let Some(c) = text.get(i..).and_then(|s| s.chars().next()) {
        let start = i;
        let blank_after = matches!(b.get(i + 1), None | Some(b' ' | b'\t' | b'\r' | b'\n'));
        let at_line_start = i == 0 || b.get(i - 1) == Some(&b'\n');
        i += c.len_utf8();
        match c {
            '%' if prolog && at_line_start => {
                i = end_of_line(text, start);
                if text[start..i].starts_with("%YAML") {
                    continue;
                }
            }
            '\n' => {
                line += 1;
                node_start |= flow.is_empty();
            }
            ' ' | '\t' | '\r' => {}
            '#' if start == 0 || matches!(b.get(start - 1), Some(b' ' | b'\t' | b'\n')) => {
                i = end_of_line(text, start);
            }
            '"' | '\'' if node_start => {
                i = end_of_quoted(b, start);
                line += text[start..i].matches('\n').count();
                node_start = false;
                flow_key = false;
                prolog = false;
            }
            '[' | '{' if node_start => {
                flow.push((c as u8, line));
                flow_key = c == '{';
                prolog = false;
            }
            ']' | '}' if !flow.is_empty() => {
                flow.pop();
                node_start = false;
                flow_key = false;
            }
            ',' if !flow.is_empty() => {
                node_start = true;
                flow_key = matches!(flow.last(), Some((b'{', _)));
            }
            ':' if blank_after => {
                node_start = true;
                flow_key = false;
            }
            '-' if node_start && blank_after && flow.is_empty() => prolog = false,
            '!' | '&' if node_start => {
                // A tag or an anchor: a node follows it.
                let len = text[i..]
                    .find(|c: char| c.is_whitespace() || ",[]{}".contains(c))
                    .unwrap_or(text.len() - i);
                i += len;
                prolog = false;
            }
            _ => {
                prolog = false;
                node_start = false;
                if std::mem::take(&mut flow_key) {
                    // A plain key: up to the first indicator.
                    let len = text[start..]
                        .find(|c: char| ":,[]{}#\n".contains(c))
                        .unwrap_or(text.len() - start);
                    let colon = start + len;
                    let adjacent = b.get(colon) == Some(&b':')
                        && !matches!(
                            b.get(colon + 1),
                            None | Some(b' ' | b'\t' | b'\r' | b'\n' | b',' | b']' | b'}')
                        );
                    if adjacent {
                        out.push_str(&text[start..=colon]);
                        out.push(' ');
                        i = colon + 1;
                        node_start = true;
                        continue;
                    }
                }
            }
        }
        out.push_str(&text[start..i]);
    }
    let unclosed = flow.last().map(|&(c, line)| (char::from(c), line));
    (out, unclosed)
}

/// The index of the `\n` ending the line that holds `i` (or the end of the text).
fn end_of_line(text: &str, i: usize) -> usize {
    text[i..].find('\n').map_or(text.len(), |n| i + n)
}

/// Just past the quote closing the scalar that opens at `i` (`"` with `\` escapes, `'` with
/// `''`); the end of the text if it is never closed (the parser then reports it).
fn end_of_quoted(b: &[u8], i: usize) -> usize {
    let q = b.get(i).copied();
    let mut j = i + 1;
    while let Some(&c) = b.get(j) {
        match c {
            b'\\' if q == Some(b'"') => j += 2,
            b'\'' if q == Some(b'\'') && b.get(j + 1) == Some(&b'\'') => j += 2,
            _ if Some(c) == q => return j + 1,
            _ => j += 1,
        }
    }
    b.len()
}

mod yaml {
    //! The YAML form: saphyr-parser's events built into a [`Node`] tree.

    use std::path::Path;

    use saphyr_parser::{Event, Parser, ScalarStyle};

    use super::{MAX_DEPTH, Node, Value, to_yaml12};
    use crate::error::{Error, ErrorKind, Result};

    /// A structure being read, and (for a mapping) the key whose value comes next.
    struct Open {
        node: Node,
        key: Option<String>,
    }

    /// Parses OpenCV's YAML into the tree of its one document (an empty mapping for an empty
    /// file).
    pub(super) fn document(text: &str, path: &Path) -> Result<Node> {
        let (yaml, unclosed) = to_yaml12(text);
        let err = |line: usize, msg: String| Error::at_line(path, line, ErrorKind::Syntax(msg));
        let mut parser = Parser::new_from_str(&yaml);
        let mut open: Vec<Open> = Vec::new();
        let mut root: Option<Node> = None;
        let mut documents = 0usize;
        while let Some(event) = parser.next_event() {
            let (event, span) = event.map_err(|e| {
                let line = e.marker().line();
                // saphyr's messages are one line; make sure.
                let mut msg = e.info().replace('\n', " ");
                // The parser notices an unclosed `[` where the text stops making sense, often
                // lines later: say where it was opened.
                if let Some((c, open)) = unclosed.filter(|&(_, open)| open <= line) {
                    msg.push_str(&format!(" (the `{c}` on line {open} is never closed)"));
                }
                err(line, msg)
            })?;
            let line = span.start.line();
            let tag =
                |t: Option<std::borrow::Cow<'_, saphyr_parser::Tag>>| t.map(|t| t.suffix.clone());
            let is_seq = matches!(event, Event::SequenceStart(..));
            let done = match event {
                Event::Nothing | Event::StreamStart | Event::StreamEnd | Event::DocumentEnd => None,
                Event::DocumentStart(_) => {
                    documents += 1;
                    if documents > 1 {
                        return Err(err(line, "more than one YAML document in the file".into()));
                    }
                    None
                }
                Event::Alias(_) => {
                    return Err(err(line, "aliases (`*name`) are not supported".into()));
                }
                Event::Scalar(text, style, _, t) => Some(Node {
                    tag: tag(t),
                    line,
                    value: Value::Scalar {
                        text: text.into_owned(),
                        quoted: style != ScalarStyle::Plain,
                    },
                }),
                Event::SequenceStart(_, t) | Event::MappingStart(_, t) => {
                    if open.len() >= MAX_DEPTH {
                        return Err(err(line, "structures nested too deeply".into()));
                    }
                    let value = if is_seq {
                        Value::Seq(Vec::new())
                    } else {
                        Value::Map(Vec::new())
                    };
                    open.push(Open {
                        node: Node {
                            tag: tag(t),
                            line,
                            value,
                        },
                        key: None,
                    });
                    None
                }
                Event::SequenceEnd | Event::MappingEnd => open.pop().map(|o| o.node),
            };
            let Some(node) = done else { continue };
            // A complete node: the root, an item, a key or a value.
            let Some(parent) = open.last_mut() else {
                root = Some(node);
                continue;
            };
            match (&mut parent.node.value, parent.key.take()) {
                (Value::Seq(items), _) => items.push(node),
                (Value::Map(entries), Some(key)) => entries.push((key, node)),
                (Value::Map(entries), None) => {
                    let Value::Scalar { text, .. } = node.value else {
                        return Err(err(node.line, "a mapping key must be a scalar".into()));
                    };
                    if entries.iter().any(|(k, _)| *k == text) {
                        return Err(err(node.line, format!("duplicate key `{text}`")));
                    }
                    parent.key = Some(text);
                }
                (Value::Scalar { .. }, _) => {}
            }
        }
        match root {
            None => Ok(Node {
                tag: None,
                line: 1,
                value: Value::Map(Vec::new()),
            }),
            Some(n) if matches!(n.value, Value::Map(_)) => Ok(n),
            // An empty document (`---` alone) is an empty scalar.
            Some(n) if n.as_scalar() == Some("") && n.tag.is_none() => Ok(Node {
                value: Value::Map(Vec::new()),
                ..n
            }),
            Some(n) => Err(err(
                n.line,
                "the top level must be a mapping (`key: value`)".into(),
            )),
        }
    }
}

mod xml {
    //! The XML form: roxmltree's document mapped onto a [`Node`] tree.

    use std::path::Path;

    use super::{MAX_DEPTH, Node, Value};
    use crate::error::{Error, ErrorKind, Result};

    /// Parses OpenCV's XML into the tree under `<opencv_storage>`.
    pub(super) fn document(text: &str, path: &Path) -> Result<Node> {
        let reader = Reader {
            path,
            newlines: text
                .bytes()
                .enumerate()
                .filter_map(|(i, c)| (c == b'\n').then_some(i))
                .collect(),
        };
        let doc = roxmltree::Document::parse(text).map_err(|e| reader.syntax_error(text, &e))?;
        let root = doc.root_element();
        let line = reader.line(root.range().start);
        if root.tag_name().name() != "opencv_storage" {
            return Err(reader.err(
                line,
                format!(
                    "the root element is `<{}>`, expected `<opencv_storage>`",
                    root.tag_name().name()
                ),
            ));
        }
        let node = reader.element(root, 0)?;
        match node.value {
            Value::Map(_) => Ok(node),
            Value::Scalar { ref text, .. } if text.is_empty() => Ok(Node {
                value: Value::Map(Vec::new()),
                ..node
            }),
            _ => Err(reader.err(
                line,
                "`<opencv_storage>` must hold one element per key".into(),
            )),
        }
    }

    struct Reader<'a> {
        path: &'a Path,
        /// Byte offsets of the text's line ends, for line numbers.
        newlines: Vec<usize>,
    }

    impl Reader<'_> {
        /// The 1-based line of byte `offset`.
        fn line(&self, offset: usize) -> usize {
            self.newlines.partition_point(|&n| n < offset) + 1
        }

        fn err(&self, line: usize, msg: String) -> Error {
            Error::at_line(self.path, line, ErrorKind::Syntax(msg))
        }

        /// roxmltree's error, on its line. roxmltree ends most messages with " at LINE:COLUMN"
        /// (dropped: the line goes in front); for a close tag that does not match, say which
        /// element is left open and where it was opened.
        fn syntax_error(&self, text: &str, e: &roxmltree::Error) -> Error {
            let line = e.pos().row as usize;
            if let roxmltree::Error::UnexpectedCloseTag(open, close, _) = e {
                // The last `<open` before the close tag (roxmltree's column counts characters
                // from 1).
                let line_start = line
                    .checked_sub(2)
                    .and_then(|l| self.newlines.get(l))
                    .map_or(0, |&n| n + 1);
                let col = (e.pos().col as usize).saturating_sub(1);
                let before = text.get(line_start..).map_or(text.len(), |rest| {
                    line_start + rest.chars().take(col).map(char::len_utf8).sum::<usize>()
                });
                let opened = text[..before]
                    .rmatch_indices(&format!("<{open}"))
                    .map(|(i, _)| i)
                    .find(|&i| {
                        let after = text.as_bytes().get(i + open.len() + 1).copied();
                        matches!(after, Some(b'>' | b' ' | b'\t' | b'\r' | b'\n'))
                    });
                let at = opened.map_or(String::new(), |i| format!(" (line {})", self.line(i)));
                return self.err(line, format!("`<{open}>`{at} is closed by `</{close}>`"));
            }
            let msg = e.to_string();
            let pos = format!(" at {}", e.pos());
            self.err(line, msg.strip_suffix(&pos).unwrap_or(&msg).to_string())
        }

        fn element(&self, e: roxmltree::Node<'_, '_>, depth: usize) -> Result<Node> {
            let line = self.line(e.range().start);
            let name = e.tag_name().name();
            if depth > MAX_DEPTH {
                return Err(self.err(line, "elements nested too deeply".into()));
            }
            // Sequence items in file order (text tokens and `<_>` elements), mapping entries.
            let mut items: Vec<Node> = Vec::new();
            let mut entries: Vec<(String, Node)> = Vec::new();
            let mut tokens = 0usize;
            for child in e.children() {
                if child.is_element() {
                    let node = self.element(child, depth + 1)?;
                    let key = child.tag_name().name();
                    if key == "_" {
                        items.push(node);
                    } else if entries.iter().any(|(k, _)| k == key) {
                        return Err(self.err(node.line, format!("duplicate key `{key}`")));
                    } else {
                        entries.push((key.to_string(), node));
                    }
                } else if let Some(text) = child.text().filter(|_| child.is_text()) {
                    let first = self.line(child.range().start);
                    let before = items.len();
                    tokenize(text, first, &mut items).map_err(|(l, m)| self.err(l, m))?;
                    tokens += items.len() - before;
                }
            }
            let tag = e.attribute("type_id").map(str::to_string);
            let value = if !entries.is_empty() {
                if let Some(item) = items.first() {
                    return Err(self.err(
                        item.line,
                        format!("`<{name}>` mixes named elements with text or `<_>` items"),
                    ));
                }
                Value::Map(entries)
            } else if items.len() > tokens || tokens > 1 {
                Value::Seq(items)
            } else if tag.as_deref() == Some("opencv-matrix") {
                // A matrix without its fields: the matrix reader says which one is missing.
                Value::Map(Vec::new())
            } else if let Some(item) = items.pop() {
                item.value
            } else {
                Value::Scalar {
                    text: String::new(),
                    quoted: false,
                }
            };
            Ok(Node { tag, line, value })
        }
    }

    /// Appends the whitespace-separated tokens of `text` (whose first byte is on line `line`)
    /// to `out`, a `"quoted string"` being one token.
    fn tokenize(
        text: &str,
        mut line: usize,
        out: &mut Vec<Node>,
    ) -> std::result::Result<(), (usize, String)> {
        let mut rest = text;
        loop {
            let trimmed = rest.trim_start();
            line += rest[..rest.len() - trimmed.len()].matches('\n').count();
            rest = trimmed;
            if rest.is_empty() {
                return Ok(());
            }
            let (token, quoted, len) = if let Some(q) = rest.strip_prefix('"') {
                let end = q
                    .find('"')
                    .ok_or_else(|| (line, "unterminated quoted string".to_string()))?;
                (&q[..end], true, end + 2)
            } else {
                let end = rest.find(char::is_whitespace).unwrap_or(rest.len());
                (&rest[..end], false, end)
            };
            out.push(Node::scalar(token, quoted, line));
            line += token.matches('\n').count();
            rest = &rest[len..];
        }
    }
}

/// Writes an OpenCV `FileStorage` YAML file the way OpenCV 4 does (`%YAML:1.0`, `key: value`
/// lines, `!!opencv-matrix` blocks, `#` comments), for files OpenCV and [`FileStorage`] read.
///
/// Floating-point values are written as OpenCV writes doubles (`%.16e`, 17 significant digits,
/// which read back to the same `f64`).
#[derive(Debug, Clone)]
pub struct YamlWriter {
    text: String,
}

impl Default for YamlWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl YamlWriter {
    /// The header, `%YAML:1.0` and `---`.
    pub fn new() -> Self {
        Self {
            text: "%YAML:1.0\n---\n".to_string(),
        }
    }

    /// `key: value` for an integer.
    pub fn int(&mut self, key: &str, v: i64) -> &mut Self {
        self.text.push_str(&format!("{key}: {v}\n"));
        self
    }

    /// `key: value` for a real number.
    pub fn real(&mut self, key: &str, v: f64) -> &mut Self {
        self.text
            .push_str(&format!("{key}: {}\n", format_double(v)));
        self
    }

    /// `key: "text"` (quoted; `"` and `\\` escaped).
    pub fn string(&mut self, key: &str, v: &str) -> &mut Self {
        let v = v.replace('\\', "\\\\").replace('"', "\\\"");
        self.text.push_str(&format!("{key}: \"{v}\"\n"));
        self
    }

    /// A `# comment` line.
    pub fn comment(&mut self, text: &str) -> &mut Self {
        self.text.push_str(&format!("# {text}\n"));
        self
    }

    /// `key: !!opencv-matrix` with `rows x cols` doubles (`dt: d`), row-major.
    pub fn matrix(&mut self, key: &str, rows: usize, cols: usize, data: &[f64]) -> &mut Self {
        self.text.push_str(&format!(
            "{key}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: ["
        ));
        for (i, v) in data.iter().enumerate() {
            if i > 0 {
                self.text.push(',');
                self.text
                    .push_str(if i % 3 == 0 { "\n       " } else { " " });
            } else {
                self.text.push(' ');
            }
            self.text.push_str(&format_double(*v));
        }
        self.text.push_str(" ]\n");
        self
    }

    /// The file's text.
    pub fn finish(&self) -> String {
        self.text.clone()
    }
}

/// A double as OpenCV's writer prints it: `%.16e` (`5.3591573396163199e+02`), with integral
/// values as `1.` / `0.` / `-2.` and non-finite values as `.Nan`, `.Inf`, `-.Inf`.
pub fn format_double(v: f64) -> String {
    if v.is_nan() {
        return ".Nan".into();
    }
    if v.is_infinite() {
        return if v > 0.0 { ".Inf" } else { "-.Inf" }.into();
    }
    if v == v.trunc() && v.abs() < 1e15 {
        return format!("{}.", v as i64);
    }
    let s = format!("{v:.16e}");
    match s.split_once('e') {
        Some((m, e)) => {
            let (sign, digits) = match e.strip_prefix('-') {
                Some(d) => ('-', d),
                None => ('+', e),
            };
            format!("{m}e{sign}{digits:0>2}")
        }
        None => s,
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
    fn opencv_yaml_becomes_yaml12_line_for_line() {
        let (t, unclosed) = to_yaml12(
            "%YAML:1.0\n---\nf: { a:1, b:[ 1, 2 ], c:\"x:y\", d:{ e:1 }, s:two words }\n\
             s: \"{ k:v\" # { a:b\nq: 'it''s { a:b'\nu: http://x\n",
        );
        assert_eq!(
            t,
            "\n---\nf: { a: 1, b: [ 1, 2 ], c: \"x:y\", d: { e: 1 }, s: two words }\n\
             s: \"{ k:v\" # { a:b\nq: 'it''s { a:b'\nu: http://x\n"
        );
        assert_eq!(unclosed, None);
        // Spaced flow keys and block mappings are left alone; an unclosed `[` is reported.
        let text = "a: { b: 1 }\nc:\n  d: [ 1,\n    { e:2 }\n";
        let (t, unclosed) = to_yaml12(text);
        assert_eq!(t, text.replace("e:2", "e: 2"));
        assert_eq!(unclosed, Some(('[', 3)));
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
        assert!(
            e.to_string().contains("`<a>` (line 1) is closed by `</b>`"),
            "{e}"
        );
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

    #[test]
    fn doubles_are_written_as_opencv_writes_them() {
        // OpenCV's "%.16e" with integral values as "1." (left_intrinsics.yml has both forms).
        assert_eq!(format_double(535.915_733_961_632), "5.3591573396163199e+02");
        assert_eq!(
            format_double(-2.812_210_044_111_547e-4),
            "-2.8122100441115472e-04"
        );
        assert_eq!(format_double(0.0), "0.");
        assert_eq!(format_double(1.0), "1.");
        assert_eq!(format_double(-2.0), "-2.");
        assert_eq!(format_double(f64::NAN), ".Nan");
        assert_eq!(format_double(f64::NEG_INFINITY), "-.Inf");
        assert_eq!(format_double(1e300), "1.0000000000000001e+300");
    }

    #[test]
    fn written_yaml_reads_back_exactly() {
        let data = [0.1, 1.0 / 3.0, -7.25e-9, 1e22, 5.0e-324, 2.0];
        let mut w = YamlWriter::new();
        w.int("n", -3)
            .real("r", std::f64::consts::PI)
            .comment("flags: +x")
            .string("s", "a \"b\" \\ c")
            .matrix("m", 2, 3, &data);
        let text = w.finish();
        assert!(text.starts_with("%YAML:1.0\n---\n"), "{text}");
        let fs = FileStorage::parse_yaml(&text, "w.yml").unwrap();
        assert_eq!(fs.number("r").unwrap(), Some(std::f64::consts::PI));
        assert_eq!(fs.get("n").unwrap().as_f64(), Some(-3.0));
        assert_eq!(fs.get("s").unwrap().as_scalar(), Some("a \"b\" \\ c"));
        let m = fs.matrix("m").unwrap();
        assert_eq!((m.rows, m.cols), (2, 3));
        assert_eq!(m.data, data);
    }
}
