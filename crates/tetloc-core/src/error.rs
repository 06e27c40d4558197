//! The library's typed errors. Every error that comes from a file names that file.

use std::path::PathBuf;

/// Everything that can go wrong in the core library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },

    /// The file is not what its format says it should be (truncated, malformed, bad values).
    #[error("{path}: {msg}")]
    Format { path: PathBuf, msg: String },

    /// The extension (or `--format`) names no format we read or write.
    #[error("{path}: unknown file format (known: {known})")]
    UnknownFormat { path: PathBuf, known: &'static str },

    /// Volume cells tetloc does not read: we count them by type instead of dropping them.
    #[error("{path}: the mesh has volume cells that tetloc does not read ({}); tetloc reads tetrahedra, pyramids, wedges and hexahedra (linear, quadratic and Lagrange) and polyhedra", fmt_counts(.counts))]
    NonTetCells { path: PathBuf, counts: Vec<(String, usize)> },

    /// The mesh itself is unusable (empty, indices out of range, NaN coordinates, ...).
    #[error("{source_name}: {msg}")]
    Mesh { source_name: String, msg: String },

    /// A field name that the mesh does not carry.
    #[error("no field named '{name}' (the mesh has: {available})")]
    NoSuchField { name: String, available: String },

    /// Input arrays that do not fit together (query points vs output buffer, ...).
    #[error("{0}")]
    Invalid(String),

    /// Work refused before it starts: it needs more memory than this process may take
    /// ([`crate::memory::available_bytes`]). `what` names the work and its counts.
    #[error("{what} need about {:.1} GB of memory, {:.1} GB are available", gb(*.need), gb(*.available as u128))]
    OutOfMemory { what: String, need: u128, available: u64 },

    /// An error from a GPU or other pluggable backend.
    #[error("{backend}: {source}")]
    Backend { backend: String, source: Box<dyn std::error::Error + Send + Sync> },
}

fn gb(bytes: u128) -> f64 {
    bytes as f64 / 1e9
}

fn fmt_counts(counts: &[(String, usize)]) -> String {
    counts.iter().map(|(k, n)| format!("{n} {k}")).collect::<Vec<_>>().join(", ")
}

impl Error {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), source }
    }
    /// A format error; control characters that the message echoes from the file (a terminal
    /// escape, a NUL) are escaped, so that the message prints as the text it is.
    pub fn format(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        let msg = msg.into();
        let msg = if msg.chars().any(is_raw_control) { escape_controls(&msg) } else { msg };
        Error::Format { path: path.into(), msg }
    }
}

/// Control characters other than newline and tab, which messages may hold on purpose.
fn is_raw_control(c: char) -> bool {
    c.is_control() && c != '\n' && c != '\t'
}

fn escape_controls(s: &str) -> String {
    s.chars().map(|c| if is_raw_control(c) { c.escape_default().to_string() } else { c.to_string() }).collect()
}

/// `bytes` quoted in an error message: at most `max_chars` characters (then `...`), bytes that
/// are not UTF-8 and control characters escaped (`\x1b`, `\u{0}`), so that a binary or
/// multi-megabyte line never reaches the terminal as it is.
pub fn excerpt(bytes: &[u8], max_chars: usize) -> String {
    let mut out = String::new();
    let mut n = 0;
    for chunk in bytes.utf8_chunks() {
        for c in chunk.valid().chars() {
            if n == max_chars {
                return out + "...";
            }
            if c.is_control() {
                out.extend(c.escape_default());
            } else {
                out.push(c);
            }
            n += 1;
        }
        for b in chunk.invalid() {
            if n == max_chars {
                return out + "...";
            }
            out += &format!("\\x{b:02x}");
            n += 1;
        }
    }
    out
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 29 item 19: raw bytes are escaped and long text is cut short.
    #[test]
    fn excerpts_escape_and_cut() {
        assert_eq!(excerpt(b"1,2,x", 80), "1,2,x");
        assert_eq!(excerpt(b"a\x1b[31m\x00\xff\xfeb", 80), "a\\u{1b}[31m\\u{0}\\xff\\xfeb");
        let long = "9,".repeat(2_000_000);
        let e = excerpt(long.as_bytes(), 80);
        assert_eq!(e.chars().count(), 83);
        assert!(e.ends_with("..."));
        let e = Error::format("f.vtu", "type 'x\x1b[2Jy' is bad\nsecond line").to_string();
        assert_eq!(e, "f.vtu: type 'x\\u{1b}[2Jy' is bad\nsecond line");
    }
}
