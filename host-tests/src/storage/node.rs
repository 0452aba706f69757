//! The tree a `FileStorage` file is read into: nodes with their tag and line, and OpenCV's
//! spelling of numbers.

/// Structures nest this deep at most: a bound, so that hostile input cannot exhaust the stack
/// (dropping a tree recurses). OpenCV's files nest three or four levels.
pub(super) const MAX_DEPTH: usize = 64;

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
    pub(super) fn scalar(text: impl Into<String>, quoted: bool, line: usize) -> Self {
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
