//! Line-oriented text input shared by the readers: whole-file loading (plain or gzip,
//! recognised by its magic bytes), comment skipping, and field parsing whose every error
//! names the file, the 1-based line number and what was expected.

use crate::bounds;
use crate::error::IoError;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// A text file loaded into memory.
#[derive(Debug)]
pub(crate) struct TextFile {
    pub path: PathBuf,
    pub text: String,
}

/// Reads `path` completely; gzip data (magic `1f 8b`) is decompressed, every member of a
/// multi-member file (`gzip >>` appends one) in turn, and a truncated or corrupt stream is
/// an error. At most [`bounds::MAX_TEXT_BYTES`] are read, plain or decompressed
/// ([`IoError::TooLarge`] beyond). A UTF-8 byte-order mark at the start is skipped; CRLF
/// line ends are handled by the line iterator. Non-UTF-8 content is an error naming the line.
pub(crate) fn read_text(path: &Path) -> Result<TextFile, IoError> {
    read_text_limited(path, bounds::MAX_TEXT_BYTES)
}

/// [`read_text`] with a byte limit (tests use a small one).
pub(crate) fn read_text_limited(path: &Path, limit: u64) -> Result<TextFile, IoError> {
    let bytes = read_bytes_limited(path, limit)?;
    let bytes = if bytes.len() >= 2 && bytes[0] == 0x1f && bytes[1] == 0x8b {
        let mut out = Vec::with_capacity(bytes.len().saturating_mul(4).min(limit as usize));
        flate2::read::MultiGzDecoder::new(&bytes[..])
            .take(limit.saturating_add(1))
            .read_to_end(&mut out)
            .map_err(|source| IoError::Decompress {
                path: path.to_path_buf(),
                source,
            })?;
        if out.len() as u64 > limit {
            return Err(IoError::TooLarge {
                path: path.to_path_buf(),
                what: "decompressed gzip data".into(),
                limit,
            });
        }
        out
    } else {
        bytes
    };
    let mut bytes = bytes;
    if bytes.starts_with(UTF8_BOM) {
        bytes.drain(..UTF8_BOM.len());
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        let good = e.utf8_error().valid_up_to();
        let line = e.as_bytes()[..good].iter().filter(|&&b| b == b'\n').count() + 1;
        IoError::Parse {
            path: path.to_path_buf(),
            line,
            expected: "UTF-8 text".into(),
            found: "invalid byte sequence".into(),
        }
    })?;
    Ok(TextFile {
        path: path.to_path_buf(),
        text,
    })
}

/// The UTF-8 encoding of U+FEFF, which some editors put at the start of a text file.
const UTF8_BOM: &[u8] = &[0xef, 0xbb, 0xbf];

/// Reads at most `limit` bytes of `path` ([`IoError::TooLarge`] if it holds more).
pub(crate) fn read_bytes_limited(path: &Path, limit: u64) -> Result<Vec<u8>, IoError> {
    let file = std::fs::File::open(path).map_err(|e| IoError::io(path, e))?;
    let size = file.metadata().map(|m| m.len()).unwrap_or(0);
    let mut bytes = Vec::with_capacity(size.min(limit) as usize);
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| IoError::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(IoError::TooLarge {
            path: path.to_path_buf(),
            what: "file".into(),
            limit,
        });
    }
    Ok(bytes)
}

/// The non-blank lines of a CSV `text` after its first non-blank line, which must be
/// `header` (surrounding white space aside), as (0-based line index, line); a missing or
/// other header is an error naming `path` and the line.
pub(crate) fn rows_after_header<'t>(
    path: &Path,
    text: &'t str,
    header: &str,
) -> Result<impl Iterator<Item = (usize, &'t str)>, IoError> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    match lines.next() {
        Some((_, h)) if h.trim() == header => Ok(lines),
        Some((i, h)) => Err(IoError::Parse {
            path: path.to_path_buf(),
            line: i + 1,
            expected: format!("the header {header}"),
            found: h.to_string(),
        }),
        None => Err(IoError::Empty {
            path: path.to_path_buf(),
            expected: format!("the header {header}"),
        }),
    }
}

/// Writes `content` to `path`, gzip-compressed when the name ends in `.gz`.
pub(crate) fn write_text(path: &Path, content: &str) -> Result<(), IoError> {
    let gz = path.extension().is_some_and(|e| e == "gz");
    let file = std::fs::File::create(path).map_err(|e| IoError::io(path, e))?;
    let mut w = std::io::BufWriter::new(file);
    let res = if gz {
        let mut enc = flate2::write::GzEncoder::new(&mut w, flate2::Compression::default());
        enc.write_all(content.as_bytes())
            .and_then(|_| enc.finish().map(|_| ()))
    } else {
        w.write_all(content.as_bytes())
    };
    res.and_then(|_| w.flush())
        .map_err(|e| IoError::io(path, e))
}

/// Shortens a line (or a name) for an error message: at most 60 characters, then `…`.
pub(crate) fn shorten(s: &str) -> String {
    const MAX: usize = 60;
    if s.chars().count() <= MAX {
        s.to_string()
    } else {
        let head: String = s.chars().take(MAX).collect();
        format!("{head}…")
    }
}

/// One non-blank, non-comment line, consumed field by field (whitespace separated).
pub(crate) struct Line<'a> {
    pub path: &'a Path,
    /// 1-based line number.
    pub no: usize,
    pub text: &'a str,
    fields: std::str::SplitWhitespace<'a>,
}

impl<'a> Line<'a> {
    pub fn new(path: &'a Path, no: usize, text: &'a str) -> Self {
        Self {
            path,
            no,
            text,
            fields: text.split_whitespace(),
        }
    }

    /// A parse error on this line.
    pub fn error(&self, expected: impl Into<String>, found: &str) -> IoError {
        IoError::Parse {
            path: self.path.to_path_buf(),
            line: self.no,
            expected: expected.into(),
            found: shorten(found),
        }
    }

    /// The next field, or an error saying what was expected there.
    pub fn word(&mut self, expected: &str) -> Result<&'a str, IoError> {
        self.next_word().ok_or_else(|| self.ended_early(expected))
    }

    /// The next field, if any: [`Line::word`] without building the description of the
    /// field (readers of large files build it only on error, with [`Line::ended_early`]).
    pub fn next_word(&mut self) -> Option<&'a str> {
        self.fields.next()
    }

    /// The error of a line that ended where `expected` should have been.
    pub fn ended_early(&self, expected: &str) -> IoError {
        self.error(format!("{expected} (line ended early)"), self.text.trim())
    }

    /// The next field as a finite f64 of magnitude at most [`bounds::MAX_MAGNITUDE`] (the
    /// catch-all bound; the typed readers below are stricter).
    pub fn f64(&mut self, what: &str) -> Result<f64, IoError> {
        let w = self.word(&format!("{what} (a number)"))?;
        let v: f64 = w
            .parse()
            .map_err(|_| self.error(format!("{what} (a number)"), w))?;
        if !v.is_finite() {
            return Err(IoError::NonFinite {
                path: self.path.to_path_buf(),
                line: self.no,
                what: what.to_string(),
                value: v,
            });
        }
        if v.abs() > bounds::MAX_MAGNITUDE {
            return Err(self.out_of_bounds(
                what,
                v,
                format!("|value| ≤ {:e}", bounds::MAX_MAGNITUDE),
            ));
        }
        Ok(v)
    }

    /// A value-out-of-bounds error on this line.
    pub fn out_of_bounds(&self, what: &str, value: f64, bound: impl Into<String>) -> IoError {
        IoError::OutOfBounds {
            path: self.path.to_path_buf(),
            line: self.no,
            what: what.to_string(),
            value,
            bound: bound.into(),
        }
    }

    /// The next field as a number in `[lo, hi]`; `unit` names the unit in the error.
    pub fn f64_in(&mut self, what: &str, lo: f64, hi: f64, unit: &str) -> Result<f64, IoError> {
        let v = self.f64(what)?;
        if !(lo..=hi).contains(&v) {
            return Err(self.out_of_bounds(what, v, format!("{lo} … {hi} {unit}")));
        }
        Ok(v)
    }

    /// A coordinate, metres, within ±[`bounds::MAX_COORD`].
    pub fn coord(&mut self, what: &str) -> Result<f64, IoError> {
        self.f64_in(what, -bounds::MAX_COORD, bounds::MAX_COORD, "m")
    }

    /// A robot heading, radians, within ±[`bounds::MAX_HEADING`].
    pub fn heading(&mut self, what: &str) -> Result<f64, IoError> {
        self.f64_in(what, -bounds::MAX_HEADING, bounds::MAX_HEADING, "rad")
    }

    /// A relative angle, radians, within ±[`bounds::MAX_ANGLE`] (one turn).
    pub fn angle(&mut self, what: &str) -> Result<f64, IoError> {
        self.f64_in(what, -bounds::MAX_ANGLE, bounds::MAX_ANGLE, "rad")
    }

    /// A range reading, metres, at most [`bounds::MAX_RANGE`] in magnitude (the sign is
    /// the caller's to judge: some readers list negative ranges rather than fail).
    pub fn range(&mut self, what: &str) -> Result<f64, IoError> {
        self.f64_in(what, -bounds::MAX_RANGE, bounds::MAX_RANGE, "m")
    }

    /// A time, seconds, within ±[`bounds::MAX_TIME`] and, through `span`, consistent with
    /// the file's other times (see [`bounds::TimeSpan`]).
    pub fn time(&mut self, what: &str, span: &mut bounds::TimeSpan) -> Result<f64, IoError> {
        let t = self.f64_in(what, -bounds::MAX_TIME, bounds::MAX_TIME, "s")?;
        span.check(t).map_err(|b| self.out_of_bounds(what, t, b))?;
        Ok(t)
    }

    /// The next field as an unsigned integer.
    pub fn u64(&mut self, what: &str) -> Result<u64, IoError> {
        let w = self.word(&format!("{what} (a non-negative integer)"))?;
        w.parse()
            .map_err(|_| self.error(format!("{what} (a non-negative integer)"), w))
    }

    /// Errors unless every field has been consumed.
    pub fn end(&mut self, expected: &str) -> Result<(), IoError> {
        match self.fields.next() {
            None => Ok(()),
            Some(w) => Err(self.error(
                format!("end of line after {expected}"),
                &format!("extra field {w:?} in {}", self.text.trim()),
            )),
        }
    }
}

impl TextFile {
    /// The data lines: blank lines and lines whose first non-blank character is `#` are
    /// skipped. Line numbers are 1-based.
    pub fn data_lines(&self) -> impl Iterator<Item = Line<'_>> {
        self.text
            .lines()
            .enumerate()
            .filter(|(_, l)| {
                let t = l.trim();
                !t.is_empty() && !t.starts_with('#')
            })
            .map(move |(i, l)| Line::new(&self.path, i + 1, l))
    }

    /// Errors with [`IoError::Empty`] when the file has no data line.
    pub fn ensure_not_empty(&self, expected: &str) -> Result<(), IoError> {
        if self.data_lines().next().is_none() {
            return Err(IoError::Empty {
                path: self.path.clone(),
                expected: expected.to_string(),
            });
        }
        Ok(())
    }
}

/// A text file built in memory for unit tests of readers.
#[cfg(test)]
pub(crate) fn from_str(path: &str, text: &str) -> TextFile {
    TextFile {
        path: PathBuf::from(path),
        text: text.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn field_errors_name_line_and_expectation() {
        let f = from_str("x.dat", "# c\n\n1 2 nan\n3 x\n");
        let mut lines: Vec<_> = f.data_lines().collect();
        assert_eq!(lines[0].no, 3);
        assert_eq!(lines[0].f64("a").unwrap(), 1.0);
        lines[0].f64("b").unwrap();
        let e = lines[0].f64("c").unwrap_err().to_string();
        assert!(e.contains("x.dat:3") && e.contains("not finite"), "{e}");
        lines[1].f64("a").unwrap();
        let e = lines[1].f64("b").unwrap_err().to_string();
        assert!(e.contains("x.dat:4") && e.contains("b (a number)"), "{e}");
        let e = lines[1].f64("c").unwrap_err().to_string();
        assert!(e.contains("line ended early"), "{e}");
        assert!(from_str("e", "# only\n").ensure_not_empty("data").is_err());
    }

    #[test]
    fn gzip_round_trip_and_truncation() {
        let dir = std::env::temp_dir().join(format!("slam-io-text-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("a.log.gz");
        let content: String = (0..2000).map(|i| format!("ODOM {i} 0 0\n")).collect();
        write_text(&p, &content).unwrap();
        assert_eq!(read_text(&p).unwrap().text, content);
        let bytes = std::fs::read(&p).unwrap();
        let q = dir.join("b.log.gz");
        std::fs::write(&q, &bytes[..bytes.len() / 2]).unwrap();
        assert!(matches!(read_text(&q), Err(IoError::Decompress { .. })));
        std::fs::write(&q, [b'a', 0xff, b'\n']).unwrap();
        assert!(matches!(read_text(&q), Err(IoError::Parse { line: 1, .. })));
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn multi_member_gzip_is_read_whole_and_capped() {
        let dir = std::env::temp_dir().join(format!("slam-io-text-mm-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // Two members, as `gzip -c a >> log.gz; gzip -c b >> log.gz` makes.
        let (a, b) = ("ODOM 1 0 0\n".repeat(300), "ODOM 2 0 0\n".repeat(500));
        let gz = |s: &str| {
            let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
            e.write_all(s.as_bytes()).unwrap();
            e.finish().unwrap()
        };
        let p = dir.join("two.log.gz");
        std::fs::write(&p, [gz(&a), gz(&b)].concat()).unwrap();
        assert_eq!(read_text(&p).unwrap().text, format!("{a}{b}"));
        // The cap applies to the decompressed size of all members together…
        let whole = (a.len() + b.len()) as u64;
        assert!(read_text_limited(&p, whole).is_ok());
        let e = read_text_limited(&p, whole - 1).unwrap_err();
        assert!(
            matches!(e, IoError::TooLarge { limit, .. } if limit == whole - 1),
            "{e}"
        );
        assert!(e.to_string().contains("decompressed gzip data"), "{e}");
        // …and to a plain file's size.
        let q = dir.join("plain.log");
        std::fs::write(&q, &a).unwrap();
        let e = read_text_limited(&q, 10).unwrap_err().to_string();
        assert!(
            e.contains("plain.log") && e.contains("larger than the limit of 10"),
            "{e}"
        );
        // A member followed by garbage is an error, not a silently shortened log.
        std::fs::write(&p, [gz(&a), b"garbage".to_vec()].concat()).unwrap();
        assert!(matches!(read_text(&p), Err(IoError::Decompress { .. })));
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn byte_order_mark_and_crlf_are_accepted() {
        let dir = std::env::temp_dir().join(format!("slam-io-text-bom-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("bom.tum");
        let body = "# t x y z qx qy qz qw\r\n1 2 3 0 0 0 0 1\r\n\r\n2 4 5 0 0 0 0 1\r\n";
        std::fs::write(&p, [UTF8_BOM, body.as_bytes()].concat()).unwrap();
        let f = read_text(&p).unwrap();
        assert!(f.text.starts_with('#'), "BOM kept: {:?}", &f.text[..4]);
        let t = crate::tum::read_tum(&p).unwrap();
        assert_eq!(t.len(), 2);
        assert_eq!((t[1].t, t[1].pose.x, t[1].pose.y), (2.0, 4.0, 5.0));
        // Gzip of a BOM file: the mark is skipped after decompression too.
        let q = dir.join("bom.tum.gz");
        write_text(&q, &format!("\u{feff}{body}")).unwrap();
        assert_eq!(crate::tum::read_tum(&q).unwrap(), t);
        // A BOM before the CSV header is not part of the header.
        let c = dir.join("l.csv");
        std::fs::write(&c, "\u{feff}id,x,y,cxx,cxy,cyy\r\n3,1,2,0.1,0,0.1\r\n").unwrap();
        assert_eq!(
            crate::landmarks_csv::read_landmarks_csv(&c).unwrap().len(),
            1
        );
        // A mark anywhere but at the start is content (here: not a number).
        std::fs::write(&p, "1 2 3 0 0 0 0 1\n\u{feff}2 4 5 0 0 0 0 1\n").unwrap();
        let e = crate::tum::read_tum(&p).unwrap_err().to_string();
        assert!(e.contains("bom.tum:2"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
