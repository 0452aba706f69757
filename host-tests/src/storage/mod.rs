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
//! The files: `node.rs` (the tree), `matrix.rs`, `text_file.rs` (reading text), `yaml.rs` and
//! `xml.rs` (the two syntaxes), `text_matrix.rs` (plain-text matrices), `writer.rs` (OpenCV's
//! YAML out); `mod.rs` holds [`FileStorage`].
//!
//! [saphyr-parser]: https://docs.rs/saphyr-parser
//! [roxmltree]: https://docs.rs/roxmltree

mod matrix;
mod node;
mod text_file;
mod text_matrix;
mod writer;
mod xml;
mod yaml;

pub use matrix::Matrix;
pub use node::{Node, Value, parse_number};
pub use text_file::read_text;
pub(crate) use text_file::{ext_display, extension};
pub use text_matrix::{parse_matrix_text, read_matrix_text};
pub use writer::{YamlWriter, format_double};

use std::path::{Path, PathBuf};

use crate::error::{Error, ErrorKind, Result};

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
        assert!(
            e.to_string().contains("`<a>` (line 1) is closed by `</b>`"),
            "{e}"
        );
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
