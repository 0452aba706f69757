//! The XML form: roxmltree's document mapped onto a [`Node`] tree.

use std::path::Path;

use super::node::{MAX_DEPTH, Node, Value};
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
