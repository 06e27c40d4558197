//! The byte cursor of the text readers (Gmsh, VTK legacy, TetGen): words and lines of ASCII
//! text, numbers, raw binary blocks, declared counts checked against the bytes that are left
//! before anything is allocated for them, and errors that name the file and the place: the
//! line in text, the byte offset in binary data (where lines mean nothing).
//!
//! The whole file is one byte buffer: no per-line allocation, and words are slices of it.

use rayon::prelude::*;
use std::fmt::Display;
use std::path::Path;
use tetloc_core::error::{Error, Result};

pub(crate) struct Cursor<'a> {
    pub buf: &'a [u8],
    pub pos: usize,
    /// Names the file in errors.
    pub path: &'a Path,
    /// Binary data from here on: errors give byte offsets instead of lines.
    pub binary: bool,
    /// The byte order of binary numbers.
    pub big_endian: bool,
}

/// An error at byte `pos` of `buf`: on its line (text) or at its offset (binary).
fn error_at(buf: &[u8], path: &Path, binary: bool, pos: usize, msg: impl Display) -> Error {
    let pos = pos.min(buf.len());
    if binary {
        Error::format(path, format!("byte {pos}: {msg}"))
    } else {
        // Counted only when an error is made: it never slows down a good file.
        let line = buf[..pos].iter().filter(|&&b| b == b'\n').count() + 1;
        Error::format(path, format!("line {line}: {msg}"))
    }
}

impl<'a> Cursor<'a> {
    /// A cursor at the start of `buf` (past a UTF-8 byte-order mark), in text mode.
    pub fn new(buf: &'a [u8], path: &'a Path) -> Self {
        let pos = buf.len() - super::strip_bom(buf).len();
        Cursor { buf, pos, path, binary: false, big_endian: false }
    }

    /// An error at the cursor.
    pub fn fail(&self, msg: impl Display) -> Error {
        self.fail_at(self.pos, msg)
    }

    /// An error at byte `pos`, e.g. where a record or a section started.
    pub fn fail_at(&self, pos: usize, msg: impl Display) -> Error {
        error_at(self.buf, self.path, self.binary, pos, msg)
    }

    pub fn remaining(&self) -> usize {
        self.buf.len() - self.pos
    }

    pub fn skip_ws(&mut self) {
        while self.pos < self.buf.len() && self.buf[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
    }

    /// Skips spaces and tabs, not line ends.
    pub fn skip_ws_on_line(&mut self) {
        while self.pos < self.buf.len() && matches!(self.buf[self.pos], b' ' | b'\t' | b'\r') {
            self.pos += 1;
        }
    }

    /// How many words are left on the current line (up to its newline).
    pub fn words_on_line(&self) -> usize {
        let rest = &self.buf[self.pos..];
        let line = &rest[..rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len())];
        line.split(|b| b.is_ascii_whitespace()).filter(|w| !w.is_empty()).count()
    }

    /// The position of the next word, for error messages about it.
    pub fn here(&mut self) -> usize {
        self.skip_ws();
        self.pos
    }

    /// Whether only whitespace is left.
    pub fn at_end(&mut self) -> bool {
        self.skip_ws();
        self.pos >= self.buf.len()
    }

    /// The next whitespace-separated word, across lines; `None` at the end of the file.
    pub fn word(&mut self) -> Option<&'a [u8]> {
        self.skip_ws();
        let start = self.pos;
        while self.pos < self.buf.len() && !self.buf[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        (self.pos > start).then(|| &self.buf[start..self.pos])
    }

    /// The next word, which must be there: `what` says what it should be.
    pub fn token(&mut self, what: &str) -> Result<&'a [u8]> {
        self.word().ok_or_else(|| self.fail(format!("unexpected end of file: expected {what}")))
    }

    /// The next word as an integer ≥ 0.
    pub fn ascii_u64(&mut self, what: &str) -> Result<u64> {
        let start = self.here();
        let tok = self.token(what)?;
        parse_u64(tok).ok_or_else(|| self.fail_at(start, expected(what, "an integer ≥ 0", tok)))
    }

    /// The next word as an integer.
    pub fn ascii_i64(&mut self, what: &str) -> Result<i64> {
        let start = self.here();
        let tok = self.token(what)?;
        parse_i64(tok).ok_or_else(|| self.fail_at(start, expected(what, "an integer", tok)))
    }

    /// The next word as a number.
    pub fn ascii_f64(&mut self, what: &str) -> Result<f64> {
        let start = self.here();
        let tok = self.token(what)?;
        parse_f64(tok).ok_or_else(|| self.fail_at(start, expected(what, "a number", tok)))
    }

    /// The rest of the current line without its line ending (`\n` or `\r\n`), moving past
    /// it; `None` at the end of the file.
    pub fn line(&mut self) -> Option<&'a [u8]> {
        let start = self.pos;
        if start >= self.buf.len() {
            return None;
        }
        let end = self.buf[start..].iter().position(|&b| b == b'\n').map_or(self.buf.len(), |i| start + i);
        self.pos = (end + 1).min(self.buf.len());
        let line = &self.buf[start..end];
        Some(line.strip_suffix(b"\r").unwrap_or(line))
    }

    /// The next line that holds data once everything from a `comment` byte on is dropped;
    /// blank lines are skipped. `None` at the end of the file.
    pub fn data_line(&mut self, comment: u8) -> Option<Line<'a>> {
        loop {
            let start = self.pos;
            let line = self.line()?;
            let data = &line[..line.iter().position(|&b| b == comment).unwrap_or(line.len())];
            if data.iter().any(|b| !b.is_ascii_whitespace()) {
                return Some(Line { words: Words(data), start, buf: self.buf, path: self.path });
            }
        }
    }

    /// Whether the next line starts with `word` (ASCII case-insensitive), after blank lines
    /// in text. In binary data only the very next byte counts: data may follow.
    pub fn next_line_starts_with(&self, word: &str) -> bool {
        let mut p = self.pos;
        if !self.binary {
            while p < self.buf.len() && self.buf[p].is_ascii_whitespace() {
                p += 1;
            }
        } else {
            // Binary data ends with a newline before the next keyword (VTK writes one after
            // each array, then e.g. `METADATA`).
            p += [&b"\r\n"[..], b"\n"].iter().find(|nl| self.buf[p..].starts_with(nl)).map_or(0, |nl| nl.len());
        }
        self.buf[p..].get(..word.len()).is_some_and(|w| w.eq_ignore_ascii_case(word.as_bytes()))
    }

    /// Moves past the next `marker` that starts a line and is followed by whitespace or the
    /// end of the file (e.g. `$EndEntities`); what comes before it, binary or not, is skipped.
    pub fn skip_past(&mut self, marker: &[u8]) -> Result<()> {
        let Some(&first) = marker.first() else { return Ok(()) };
        let mut i = self.pos;
        while let Some(off) = self.buf[i..].iter().position(|&b| b == first) {
            let at = i + off;
            let line_start = at == 0 || self.buf[at - 1] == b'\n';
            let rest = &self.buf[at..];
            if line_start
                && rest.starts_with(marker)
                && !matches!(rest.get(marker.len()), Some(b) if !b.is_ascii_whitespace())
            {
                self.pos = at + marker.len();
                return Ok(());
            }
            i = at + 1;
        }
        Err(self.fail(format!("no {} found: the file is truncated", show(marker))))
    }

    /// `n` raw bytes.
    pub fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        if n > self.remaining() {
            return Err(
                self.fail(format!("file truncated: {what} needs {n} bytes but only {} are left", self.remaining()))
            );
        }
        let out = &self.buf[self.pos..self.pos + n];
        self.pos += n;
        Ok(out)
    }

    /// `count` records of `size` raw bytes each, with overflow-safe size checks.
    pub fn take_records(&mut self, count: u64, size: usize, what: &str) -> Result<&'a [u8]> {
        match usize::try_from(count).ok().and_then(|c| c.checked_mul(size)) {
            Some(n) => self.take(n, what),
            None => Err(self.fail(format!("file truncated: {count} {what} cannot fit in the file"))),
        }
    }

    /// Checks that `count` records of at least `min_bytes` each can still be in the file, so
    /// that a corrupt count never makes a reader allocate (or loop) for data that is not there.
    pub fn check_room(&self, count: u64, min_bytes: usize, what: &str) -> Result<usize> {
        let room = (self.remaining() / min_bytes.max(1)) as u64;
        if count > room {
            return Err(self.fail(format!(
                "the file declares {count} {what} but only {} bytes are left: truncated or corrupt",
                self.remaining()
            )));
        }
        Ok(count as usize)
    }
}

/// "expected {what} ({kind}), found '{tok}'"
fn expected(what: &str, kind: &str, tok: &[u8]) -> String {
    format!("expected {what} ({kind}), found '{}'", show(tok))
}

/// A word for an error message: cut short, raw bytes escaped.
pub(crate) fn show(tok: &[u8]) -> String {
    tetloc_core::error::excerpt(tok, 40)
}

/// Decimal digits with an optional `+`; `None` on anything else or on overflow.
pub(crate) fn parse_u64(tok: &[u8]) -> Option<u64> {
    let digits = tok.strip_prefix(b"+").unwrap_or(tok);
    if digits.is_empty() {
        return None;
    }
    let mut v: u64 = 0;
    for &b in digits {
        let d = b.wrapping_sub(b'0');
        if d > 9 {
            return None;
        }
        v = v.checked_mul(10)?.checked_add(d as u64)?;
    }
    Some(v)
}

/// Decimal digits with an optional sign; `None` on anything else or on overflow.
pub(crate) fn parse_i64(tok: &[u8]) -> Option<i64> {
    match tok.strip_prefix(b"-") {
        Some(rest) if !rest.starts_with(b"+") => 0i64.checked_sub_unsigned(parse_u64(rest)?),
        Some(_) => None,
        None => i64::try_from(parse_u64(tok)?).ok(),
    }
}

/// A number as Rust reads it (`1`, `-2.5e3`, `inf`, `nan`).
pub(crate) fn parse_f64(tok: &[u8]) -> Option<f64> {
    std::str::from_utf8(tok).ok()?.parse().ok()
}

pub(crate) fn get_i32(b: &[u8], big_endian: bool) -> i32 {
    let a = [b[0], b[1], b[2], b[3]];
    if big_endian {
        i32::from_be_bytes(a)
    } else {
        i32::from_le_bytes(a)
    }
}

pub(crate) fn get_u64(b: &[u8], big_endian: bool) -> u64 {
    let a = [b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]];
    if big_endian {
        u64::from_be_bytes(a)
    } else {
        u64::from_le_bytes(a)
    }
}

pub(crate) fn get_f64(b: &[u8], big_endian: bool) -> f64 {
    f64::from_bits(get_u64(b, big_endian))
}

/// The words of one line. `None` from a number means a missing or malformed word: for fast
/// paths that fall back to a careful parse (see [`Line`] for one with error messages).
pub(crate) struct Words<'a>(pub &'a [u8]);

impl<'a> Words<'a> {
    pub fn next_word(&mut self) -> Option<&'a [u8]> {
        let start = self.0.iter().position(|b| !b.is_ascii_whitespace())?;
        let rest = &self.0[start..];
        let len = rest.iter().position(|b| b.is_ascii_whitespace()).unwrap_or(rest.len());
        self.0 = &rest[len..];
        Some(&rest[..len])
    }
    pub fn u64(&mut self) -> Option<u64> {
        parse_u64(self.next_word()?)
    }
    pub fn i64(&mut self) -> Option<i64> {
        parse_i64(self.next_word()?)
    }
    pub fn f32(&mut self) -> Option<f32> {
        parse_f64(self.next_word()?).map(|v| v as f32)
    }
    pub fn f64(&mut self) -> Option<f64> {
        parse_f64(self.next_word()?)
    }
    /// Whether only whitespace is left.
    pub fn done(&self) -> bool {
        self.0.iter().all(|b| b.is_ascii_whitespace())
    }
}

// Parallel parsing of long runs of one-record-per-line text
//
// Writers such as gmsh put one node or element per line, so a long run of records can be cut
// at line ends and parsed on all cores. The parallel parse accepts only that layout, with
// exactly the expected words on each line; anything else (records spread over lines, blank
// lines, bad numbers, unknown ids) makes it give up, and the caller's sequential parse reads
// the run instead, with its precise error messages.

/// The offset just past the `count`-th line end at or after `start`, if there are that many.
fn end_of_lines(buf: &[u8], start: usize, count: usize) -> Option<usize> {
    let mut seen = 0;
    let mut at = start;
    // Count whole blocks first (a loop the compiler vectorises), then find the exact byte.
    for block in buf[start..].chunks(1 << 16) {
        let n = block.iter().filter(|&&b| b == b'\n').count();
        if seen + n >= count {
            let i = block.iter().enumerate().filter(|(_, &b)| b == b'\n').nth(count - seen - 1)?.0;
            return Some(at + i + 1);
        }
        seen += n;
        at += block.len();
    }
    None
}

impl Cursor<'_> {
    /// Parses the `count` lines at the cursor in parallel: `line` reads one line's words into
    /// a piece's state `S` (the states come back in file order). `None`, with the cursor
    /// unmoved, when the run is shorter than `min_parallel` lines, binary, or not one record
    /// per line.
    pub fn par_lines<S: Default + Send>(
        &mut self,
        count: usize,
        min_parallel: usize,
        line: impl Fn(&mut Words, &mut S) -> Option<()> + Sync,
    ) -> Option<Vec<S>> {
        if self.binary || count < min_parallel.max(1) {
            return None;
        }
        let start = self.here();
        let end = end_of_lines(self.buf, start, count)?;
        let text = &self.buf[start..end];
        // Cut into a few pieces per thread, each just after a line end.
        let parts = 4 * rayon::current_num_threads();
        let mut cuts = vec![0];
        for k in 1..parts {
            let from = (text.len() * k / parts).max(*cuts.last().unwrap_or(&0));
            if let Some(i) = text[from..].iter().position(|&b| b == b'\n') {
                if from + i + 1 < text.len() && from + i + 1 > *cuts.last().unwrap_or(&0) {
                    cuts.push(from + i + 1);
                }
            }
        }
        cuts.push(text.len());
        let states = cuts
            .par_windows(2)
            .map(|w| {
                let mut state = S::default();
                let piece = &text[w[0]..w[1] - 1]; // without its last line end
                for l in piece.split(|&b| b == b'\n') {
                    let mut words = Words(l);
                    line(&mut words, &mut state)?;
                    if !words.done() {
                        return None;
                    }
                }
                Some(state)
            })
            .collect::<Option<Vec<S>>>()?;
        self.pos = end;
        Some(states)
    }
}

/// One line of a line-based format (from [`Cursor::data_line`]): its words, read with
/// errors that name the file and the line.
pub(crate) struct Line<'a> {
    words: Words<'a>,
    /// Where the line starts in `buf`.
    start: usize,
    buf: &'a [u8],
    path: &'a Path,
}

impl<'a> Line<'a> {
    /// An error on this line.
    pub fn fail(&self, msg: impl Display) -> Error {
        error_at(self.buf, self.path, false, self.start, msg)
    }

    /// Whether only whitespace is left on the line.
    pub fn at_end(&self) -> bool {
        self.words.done()
    }

    fn parse<T>(&mut self, what: &str, kind: &str, parse: fn(&[u8]) -> Option<T>) -> Result<T> {
        let Some(tok) = self.words.next_word() else {
            return Err(self.fail(format!("missing {what}")));
        };
        parse(tok).ok_or_else(|| self.fail(expected(what, kind, tok)))
    }

    pub fn u64(&mut self, what: &str) -> Result<u64> {
        self.parse(what, "an integer ≥ 0", parse_u64)
    }

    pub fn i64(&mut self, what: &str) -> Result<i64> {
        self.parse(what, "an integer", parse_i64)
    }

    pub fn f64(&mut self, what: &str) -> Result<f64> {
        self.parse(what, "a number", parse_f64)
    }

    /// An optional trailing integer: `default` when the line ends before it.
    pub fn u64_or(&mut self, what: &str, default: u64) -> Result<u64> {
        if self.at_end() {
            Ok(default)
        } else {
            self.u64(what)
        }
    }

    /// Nothing but whitespace may follow `what`.
    pub fn expect_end(&mut self, what: &str) -> Result<()> {
        match self.words.next_word() {
            None => Ok(()),
            Some(tok) => Err(self.fail(format!("unexpected '{}' after {what}", show(tok)))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn cursor(text: &[u8]) -> Cursor<'_> {
        Cursor::new(text, Path::new("t.txt"))
    }

    #[test]
    fn words_numbers_and_lines() {
        let mut c = cursor(b"  12 -3\r\n4.5e1 +7\n\nlast line\n");
        assert_eq!(c.ascii_u64("a").unwrap(), 12);
        assert_eq!(c.ascii_i64("b").unwrap(), -3);
        assert_eq!(c.line(), Some(&b""[..]), "the rest of the line, without \\r\\n");
        assert_eq!(c.ascii_f64("c").unwrap(), 45.0);
        assert_eq!(c.ascii_u64("d").unwrap(), 7);
        assert!(c.next_line_starts_with("LAST"));
        assert_eq!(c.word(), Some(&b"last"[..]));
        assert_eq!(c.line(), Some(&b" line"[..]));
        assert_eq!(c.line(), None);
        assert!(c.at_end());
        assert_eq!(c.word(), None);
    }

    #[test]
    fn errors_name_the_file_and_the_line_or_byte() {
        let mut c = cursor(b"1\n2\n  x 3");
        c.ascii_u64("a").unwrap();
        c.ascii_u64("b").unwrap();
        let e = c.ascii_u64("the count").unwrap_err().to_string();
        assert_eq!(e, "t.txt: line 3: expected the count (an integer ≥ 0), found 'x'");
        assert_eq!(c.ascii_u64("z").unwrap(), 3);
        let e = c.ascii_f64("a value").unwrap_err().to_string();
        assert_eq!(e, "t.txt: line 3: unexpected end of file: expected a value");
        c.binary = true;
        assert_eq!(c.fail_at(4, "bad").to_string(), "t.txt: byte 4: bad");
        let long = [b'7'; 60];
        let e = cursor(&long).ascii_i64("n").unwrap_err().to_string();
        assert!(e.ends_with(&format!("found '{}...'", "7".repeat(40))), "{e}");
    }

    #[test]
    fn integers_reject_what_is_not_one() {
        for bad in ["", "-", "+", "1.0", "1e3", "0x10", "--1", "-+1", "18446744073709551616"] {
            assert_eq!(parse_u64(bad.as_bytes()), None, "{bad}");
        }
        assert_eq!(parse_u64(b"18446744073709551615"), Some(u64::MAX));
        assert_eq!(parse_i64(b"-9223372036854775808"), Some(i64::MIN));
        assert_eq!(parse_i64(b"9223372036854775808"), None);
        assert_eq!(parse_i64(b"-9223372036854775809"), None);
        assert_eq!(parse_i64(b"+5"), Some(5));
    }

    #[test]
    fn binary_blocks_and_room_checks() {
        let mut data = b"hdr\n".to_vec();
        data.extend(7i32.to_be_bytes());
        data.extend(2.5f64.to_le_bytes());
        let mut c = cursor(&data);
        c.line();
        c.binary = true;
        c.big_endian = true;
        let b = c.take(4, "an int").unwrap();
        assert_eq!(get_i32(b, c.big_endian), 7);
        assert_eq!(get_f64(c.take_records(1, 8, "doubles").unwrap(), false), 2.5);
        let e = c.take(1, "a byte").unwrap_err().to_string();
        assert_eq!(e, "t.txt: byte 16: file truncated: a byte needs 1 bytes but only 0 are left");
        assert!(c.take_records(u64::MAX, 8, "records").unwrap_err().to_string().contains("cannot fit"));
        c.pos = 4;
        assert_eq!(c.check_room(3, 4, "ints").unwrap(), 3);
        assert!(c.check_room(4, 4, "ints").unwrap_err().to_string().contains("declares 4 ints"));
        assert!(c.check_room(u64::MAX, 0, "things").is_err());
    }

    #[test]
    fn markers_start_lines() {
        let text = b"$Entities\nx$EndEntities\n\x00$EndEntitiesX\n$EndEntities\nafter";
        let mut c = cursor(text);
        c.line();
        c.skip_past(b"$EndEntities").unwrap();
        assert_eq!(c.line(), Some(&b""[..]));
        assert_eq!(c.line(), Some(&b"after"[..]));
        let mut c = cursor(b"$A\n$EndB");
        c.line();
        let e = c.skip_past(b"$EndA").unwrap_err().to_string();
        assert_eq!(e, "t.txt: line 2: no $EndA found: the file is truncated");
    }

    #[test]
    fn data_lines_drop_comments_and_blank_lines() {
        let mut c = cursor(b"# header\n\n  3 4 # three four\n   # only a comment\n5 x 6");
        let mut l = c.data_line(b'#').unwrap();
        assert_eq!((l.u64("a").unwrap(), l.u64_or("b", 9).unwrap(), l.u64_or("c", 9).unwrap()), (3, 4, 9));
        l.expect_end("the pair").unwrap();
        let mut l = c.data_line(b'#').unwrap();
        assert_eq!(l.i64("x").unwrap(), 5);
        assert_eq!(l.f64("y").unwrap_err().to_string(), "t.txt: line 5: expected y (a number), found 'x'");
        assert_eq!(l.expect_end("y").unwrap_err().to_string(), "t.txt: line 5: unexpected '6' after y");
        assert_eq!(l.u64("z").unwrap_err().to_string(), "t.txt: line 5: missing z");
        assert!(c.data_line(b'#').is_none());
    }

    #[test]
    fn parallel_lines_agree_or_give_up() {
        let text = (0..1000).map(|i| format!("{i} {}.5\n", 2 * i)).collect::<String>() + "tail";
        let pair = |w: &mut Words, s: &mut Vec<(u64, f32)>| {
            s.push((w.u64()?, w.f32()?));
            Some(())
        };
        let mut c = cursor(text.as_bytes());
        let all: Vec<(u64, f32)> = c.par_lines(1000, 1, pair).unwrap().into_iter().flatten().collect();
        assert_eq!(all, (0..1000).map(|i| (i, 2.0 * i as f32 + 0.5)).collect::<Vec<_>>());
        assert_eq!(c.word(), Some(&b"tail"[..]));
        // Too few lines for the threshold or in the text, a bad number, a word too many,
        // binary data: no answer, and the cursor stays where it was.
        let bad = text.replacen("\n7 14.5\n", "\n7 x\n", 1);
        let extra = text.replacen("\n7 14.5\n", "\n7 14.5 1\n", 1);
        for (text, count, min, binary) in [
            (&text, 1000, 1001, false),
            (&text, 1001, 1, false),
            (&bad, 1000, 1, false),
            (&extra, 1000, 1, false),
            (&text, 1000, 1, true),
        ] {
            let mut c = cursor(text.as_bytes());
            c.binary = binary;
            assert!(c.par_lines(count, min, pair).is_none(), "{count} {min} {binary}");
            assert_eq!(c.pos, 0);
        }
    }

    proptest! {
        /// Any bytes: every reading either succeeds or errs, and the cursor only moves forward
        /// within the buffer; numbers that are printed read back exactly.
        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..200), binary: bool) {
            let mut c = cursor(&bytes);
            c.binary = binary;
            let mut last = 0;
            for step in 0.. {
                match step % 7 {
                    0 => { let _ = c.ascii_u64("a"); }
                    1 => { let _ = c.ascii_f64("b"); }
                    2 => { let _ = c.line(); }
                    3 => { let _ = c.take(3, "c"); }
                    4 => { let _ = c.check_room(5, 2, "d"); }
                    5 => { let _ = c.data_line(b'#').map(|mut l| l.i64("e").and_then(|_| l.expect_end("e"))); }
                    _ => { let _ = c.ascii_i64("f"); }
                }
                prop_assert!(c.pos >= last && c.pos <= bytes.len());
                last = c.pos;
                if c.at_end() || step > 400 {
                    break;
                }
            }
        }

        #[test]
        fn printed_numbers_read_back(u: u64, i: i64, f: f64) {
            let text = format!("{u} {i}\n{f:?}");
            let mut c = cursor(text.as_bytes());
            prop_assert_eq!(c.ascii_u64("u").unwrap(), u);
            prop_assert_eq!(c.ascii_i64("i").unwrap(), i);
            let g = c.ascii_f64("f").unwrap();
            prop_assert!(g.to_bits() == f.to_bits() || (g.is_nan() && f.is_nan()));
        }
    }
}
