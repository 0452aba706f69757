//! The YAML form: OpenCV's YAML rewritten as YAML 1.2 line for line, then saphyr-parser's
//! events built into a [`Node`] tree.

use std::path::Path;

use saphyr_parser::{Event, Parser, ScalarStyle};

use super::node::{MAX_DEPTH, Node, Value};
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
        let tag = |t: Option<std::borrow::Cow<'_, saphyr_parser::Tag>>| t.map(|t| t.suffix.clone());
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
#[cfg(test)]
mod tests {
    use super::*;

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
}
