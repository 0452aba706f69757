//! Writing OpenCV's YAML: camera files OpenCV reads.

/// Writes an OpenCV `FileStorage` YAML file the way OpenCV 4 does (`%YAML:1.0`, `key: value`
/// lines, `!!opencv-matrix` blocks, `#` comments), for files OpenCV and
/// [`FileStorage`](super::FileStorage) read.
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
}
