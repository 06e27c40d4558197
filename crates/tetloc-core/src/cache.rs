//! Files tetloc keeps between runs (the `auto` backend's measurements, the GPU's compiled
//! pipelines), in `$XDG_CACHE_HOME/tetloc` or `~/.cache/tetloc`, each written whole or not at
//! all. A cache is only ever a shortcut: one that cannot be read or written changes no answer.

use crate::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The cache directory, `None` when neither `XDG_CACHE_HOME` nor `HOME` is set.
pub fn dir() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CACHE_HOME")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("tetloc"))
}

/// The bytes of the cache file `path`, `None` when it cannot be read or is larger than
/// [`MAX_FILE`] (bounded memory whatever is found there).
pub fn read(path: &Path) -> Option<Vec<u8>> {
    let len = std::fs::metadata(path).ok()?.len();
    (len <= MAX_FILE).then(|| std::fs::read(path).ok()).flatten()
}

/// The largest cache file read (tetloc's own are a few MB at most).
pub const MAX_FILE: u64 = 64 << 20;

/// Writes `bytes` to `path` through a temporary file beside it, renamed over `path` once
/// complete: another process never reads half a cache.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let tmp = path.with_extension(format!("{}.tmp", std::process::id()));
    let written = std::fs::File::create(&tmp)
        .and_then(|mut f| f.write_all(bytes).and_then(|()| f.sync_all()))
        .and_then(|()| std::fs::rename(&tmp, path));
    written.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

/// FNV-1a, 64 bits: a check that a cache file holds the bytes that were written (a torn or
/// altered file is ignored, not trusted).
pub fn checksum(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3))
}

/// `payload` framed for a cache file: `magic`, its length and checksum, then the bytes.
pub fn frame(magic: &[u8; 8], payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(24 + payload.len());
    out.extend_from_slice(magic);
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(&checksum(payload).to_le_bytes());
    out.extend_from_slice(payload);
    out
}

/// The payload of a file [`frame`] wrote with `magic`; `None` for anything else (another
/// magic, a short or long file, a wrong checksum).
pub fn unframe<'a>(magic: &[u8; 8], file: &'a [u8]) -> Option<&'a [u8]> {
    let word = |at: usize| u64::from_le_bytes(file.get(at..at + 8)?.try_into().ok()?).into();
    let (len, sum): (Option<u64>, Option<u64>) = (word(8), word(16));
    let payload = file.get(24..)?;
    (file.get(..8)? == magic && len? == payload.len() as u64 && sum? == checksum(payload)).then_some(payload)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A framed payload comes back; any torn, altered, foreign or empty file does not.
    #[test]
    fn framed_payloads_come_back_and_nothing_else_does() {
        let payload: Vec<u8> = (0..1000u32).map(|i| (i * 7) as u8).collect();
        let file = frame(b"TESTMAGC", &payload);
        assert_eq!(unframe(b"TESTMAGC", &file), Some(&payload[..]));
        assert_eq!(unframe(b"OTHERMAG", &file), None);
        assert_eq!(unframe(b"TESTMAGC", &file[..file.len() - 1]), None);
        assert_eq!(unframe(b"TESTMAGC", &[file.clone(), vec![0]].concat()), None);
        let mut altered = file.clone();
        altered[500] ^= 1;
        assert_eq!(unframe(b"TESTMAGC", &altered), None);
        assert_eq!(unframe(b"TESTMAGC", &[]), None);
        assert_eq!(unframe(b"TESTMAGC", &file[..20]), None);
        assert_eq!(unframe(b"TESTMAGC", &frame(b"TESTMAGC", &[])), Some(&[][..]));
    }

    /// The file is written whole, no temporary file is left, and an unwritable place is an
    /// error naming it.
    #[test]
    fn writes_are_whole_and_leave_nothing_beside() {
        let dir = std::env::temp_dir().join(format!("tetloc-cache-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let path = dir.join("a/b/c.bin");
        write_atomically(&path, b"first").unwrap();
        write_atomically(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        assert_eq!(read(&path).as_deref(), Some(&b"second"[..]));
        std::fs::File::create(dir.join("big")).unwrap().set_len(MAX_FILE + 1).unwrap();
        assert_eq!(read(&dir.join("big")), None);
        std::fs::remove_file(dir.join("big")).unwrap();
        let left: Vec<_> = std::fs::read_dir(path.parent().unwrap()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(left, [std::ffi::OsString::from("c.bin")]);
        std::fs::write(dir.join("file"), "").unwrap();
        let e = write_atomically(&dir.join("file/x.bin"), b"x").unwrap_err();
        assert!(e.to_string().contains("file"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
