//! Gmsh `.msh` reader: file formats 2.2 and 4.1, ASCII and binary (either endianness).
//!
//! What is read:
//! - `$Nodes`: any node tags (sparse, unordered); vertices are numbered densely in file order.
//!   Parametric coordinates of 4.1 node blocks are skipped.
//! - `$Elements`: tetrahedra of any order (types 4, 11, 29, 30, 31, the incomplete and
//!   order 6–10 variants): the first four nodes are the corners, and `higher_order` is the
//!   highest order seen. Points, lines and surface elements are ignored. Any other volume
//!   element (hexahedra, prisms, pyramids, ...) is an [`Error::NonTetCells`] that counts them.
//!   Cell ids are 0-based in file order of the tetrahedra.
//! - `$NodeData` / `$ElementData`: vertex / cell fields named by their first string tag, with
//!   `NAME[i]` per component when there are several. Element data is matched to tetrahedra by
//!   element tag; values on other elements are dropped. Nodes or cells that a view gives no
//!   value get NaN. When one view name appears with several time steps, the highest time step
//!   wins (the last one, in files that gmsh writes); sections of the same step (partitions)
//!   are merged.
//! - Every other section (`$Entities`, `$PhysicalNames`, `$InterpolationScheme`, ...) is
//!   skipped.
//!
//! The whole file is parsed from one byte buffer without per-line allocation; binary
//! tetrahedra and long runs of ASCII records are decoded on all cores (rayon). Declared counts
//! are checked against the bytes that are left before anything is allocated, so a truncated
//! or corrupt file is an error naming the line (ASCII) or byte offset (binary), never a panic.

use crate::error::{Error, Result};
use crate::mesh::{Field, FieldLocation, RawMesh};
use rayon::prelude::*;
use std::collections::HashMap;
use std::fmt::Display;
use std::path::Path;

pub fn read(path: &Path) -> Result<RawMesh> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse(&bytes, path)
}

/// Parses a whole file held in memory; `path` only names it in errors.
pub fn parse(bytes: &[u8], path: &Path) -> Result<RawMesh> {
    parse_with(bytes, path, MIN_PARALLEL)
}

/// `parse`, with runs of at least `min_parallel` ASCII records parsed in parallel.
fn parse_with(bytes: &[u8], path: &Path, min_parallel: usize) -> Result<RawMesh> {
    Parser {
        c: Cursor { buf: bytes, pos: 0, path, binary: false, big_endian: false, min_parallel },
        version: Version::V2,
        nodes: None,
        cells: None,
        fields: Vec::new(),
        field_values: 0,
    }
    .run()
}

// ---------------------------------------------------------------------------------------------
// Element types

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    /// 0-D, 1-D and 2-D elements: ignored.
    Lower,
    /// A tetrahedron of this polynomial order; its first four nodes are the corners.
    Tet(u8),
    /// Any other volume element, by family name.
    Volume(&'static str),
}

/// Node count and kind of a Gmsh element type (numbers from gmsh's `GmshDefines.h`).
/// `None` for types without a fixed node count (polygons, polyhedra) or that tetloc does not
/// know.
fn element_type(t: i64) -> Option<(usize, Kind)> {
    use Kind::*;
    let lower = |n: usize| (n, Lower);
    let tet = |n: usize, order: i64| (n, Tet(order as u8));
    let vol = |n: usize, name| (n, Volume(name));
    Some(match t {
        15 => lower(1),
        1 => lower(2),
        8 => lower(3),
        26..=28 => lower(t as usize - 22),
        62..=66 => lower(t as usize - 55),
        2 => lower(3),
        3 => lower(4),
        9 => lower(6),
        10 => lower(9),
        16 => lower(8),
        20 => lower(9),
        21 => lower(10),
        22 => lower(12),
        23 | 24 => lower(15),
        25 => lower(21),
        36 => lower(16),
        37 => lower(25),
        38 => lower(36),
        39 => lower(12),
        40 => lower(16),
        41 => lower(20),
        42 => lower(28),
        43 => lower(36),
        44 => lower(45),
        45 => lower(55),
        46 => lower(66),
        47 => lower(49),
        48 => lower(64),
        49 => lower(81),
        50 => lower(100),
        51 => lower(121),
        52 => lower(18),
        53 => lower(21),
        54 => lower(24),
        55 => lower(27),
        56 => lower(30),
        57 => lower(24),
        58 => lower(28),
        59 => lower(32),
        60 => lower(36),
        61 => lower(40),
        4 => tet(4, 1),
        11 => tet(10, 2),
        29 => tet(20, 3),
        30 => tet(35, 4),
        31 => tet(56, 5),
        32 => tet(22, 4),
        33 => tet(28, 5),
        137 => tet(16, 3),
        // Complete tetrahedra of order 6..10.
        71..=75 => {
            let k = t - 65;
            tet(((k + 1) * (k + 2) * (k + 3) / 6) as usize, k)
        }
        // Incomplete (no interior nodes) tetrahedra of order 6..10.
        79..=83 => {
            let k = t - 73;
            tet((4 + 6 * (k - 1)) as usize, k)
        }
        5 => vol(8, "hexahedron"),
        12 => vol(27, "hexahedron"),
        17 => vol(20, "hexahedron"),
        92 => vol(64, "hexahedron"),
        93 => vol(125, "hexahedron"),
        94..=98 => vol(((t - 88) as usize).pow(3), "hexahedron"),
        99..=105 => vol((8 + 12 * (t - 97)) as usize, "hexahedron"),
        6 => vol(6, "prism"),
        13 => vol(18, "prism"),
        18 => vol(15, "prism"),
        90 => vol(40, "prism"),
        91 => vol(75, "prism"),
        106..=110 => {
            let k = t - 101;
            vol(((k + 1) * (k + 1) * (k + 2) / 2) as usize, "prism")
        }
        111..=117 => vol((6 + 9 * (t - 109)) as usize, "prism"),
        7 => vol(5, "pyramid"),
        14 => vol(14, "pyramid"),
        19 => vol(13, "pyramid"),
        118..=124 => {
            let k = t - 115;
            vol(((k + 1) * (k + 2) * (2 * k + 3) / 6) as usize, "pyramid")
        }
        125..=131 => vol((5 + 8 * (t - 123)) as usize, "pyramid"),
        140 => vol(4, "trihedron"),
        _ => return None,
    })
}

// ---------------------------------------------------------------------------------------------
// Byte cursor: ASCII tokens and binary numbers from one buffer

struct Cursor<'a> {
    buf: &'a [u8],
    pos: usize,
    path: &'a Path,
    binary: bool,
    big_endian: bool,
    /// See [`Cursor::par_lines`].
    min_parallel: usize,
}

/// A token for an error message: lossy, and cut short.
fn show(tok: &[u8]) -> String {
    let s = String::from_utf8_lossy(&tok[..tok.len().min(40)]).into_owned();
    if tok.len() > 40 {
        s + "..."
    } else {
        s
    }
}

fn trim(mut s: &[u8]) -> &[u8] {
    while let [first, rest @ ..] = s {
        if !first.is_ascii_whitespace() {
            break;
        }
        s = rest;
    }
    while let [rest @ .., last] = s {
        if !last.is_ascii_whitespace() {
            break;
        }
        s = rest;
    }
    s
}

fn parse_u64(tok: &[u8]) -> Option<u64> {
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

fn parse_i64(tok: &[u8]) -> Option<i64> {
    match tok.strip_prefix(b"-") {
        Some(rest) if !rest.starts_with(b"+") => 0i64.checked_sub_unsigned(parse_u64(rest)?),
        Some(_) => None,
        None => i64::try_from(parse_u64(tok)?).ok(),
    }
}

fn parse_f64(tok: &[u8]) -> Option<f64> {
    std::str::from_utf8(tok).ok()?.parse().ok()
}

fn get_i32(b: &[u8], big: bool) -> i32 {
    let a = [b[0], b[1], b[2], b[3]];
    if big {
        i32::from_be_bytes(a)
    } else {
        i32::from_le_bytes(a)
    }
}

fn get_u64(b: &[u8], big: bool) -> u64 {
    let a = [b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]];
    if big {
        u64::from_be_bytes(a)
    } else {
        u64::from_le_bytes(a)
    }
}

fn get_f64(b: &[u8], big: bool) -> f64 {
    f64::from_bits(get_u64(b, big))
}

impl<'a> Cursor<'a> {
    fn fail(&self, msg: impl Display) -> Error {
        self.fail_at(self.pos, msg)
    }

    /// An error located by line (ASCII) or byte offset (binary, where lines mean little).
    fn fail_at(&self, pos: usize, msg: impl Display) -> Error {
        let pos = pos.min(self.buf.len());
        if self.binary {
            Error::format(self.path, format!("byte {pos}: {msg}"))
        } else {
            let line = self.buf[..pos].iter().filter(|&&b| b == b'\n').count() + 1;
            Error::format(self.path, format!("line {line}: {msg}"))
        }
    }

    fn remaining(&self) -> usize {
        self.buf.len() - self.pos
    }

    fn skip_ws(&mut self) {
        while self.pos < self.buf.len() && self.buf[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
    }

    /// The position of the next token, for error messages.
    fn here(&mut self) -> usize {
        self.skip_ws();
        self.pos
    }

    fn at_end(&mut self) -> bool {
        self.skip_ws();
        self.pos >= self.buf.len()
    }

    /// The next whitespace-separated ASCII token.
    fn token(&mut self, what: &str) -> Result<&'a [u8]> {
        self.skip_ws();
        let start = self.pos;
        while self.pos < self.buf.len() && !self.buf[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if start == self.pos {
            return Err(self.fail(format!("unexpected end of file: expected {what}")));
        }
        Ok(&self.buf[start..self.pos])
    }

    fn ascii_u64(&mut self, what: &str) -> Result<u64> {
        let start = self.here();
        let tok = self.token(what)?;
        parse_u64(tok)
            .ok_or_else(|| self.fail_at(start, format!("expected {what} (an integer ≥ 0), found '{}'", show(tok))))
    }

    fn ascii_i64(&mut self, what: &str) -> Result<i64> {
        let start = self.here();
        let tok = self.token(what)?;
        parse_i64(tok)
            .ok_or_else(|| self.fail_at(start, format!("expected {what} (an integer), found '{}'", show(tok))))
    }

    fn ascii_f64(&mut self, what: &str) -> Result<f64> {
        let start = self.here();
        let tok = self.token(what)?;
        parse_f64(tok).ok_or_else(|| self.fail_at(start, format!("expected {what} (a number), found '{}'", show(tok))))
    }

    /// The rest of the current line without its line ending; moves past the `\n`.
    fn line(&mut self) -> &'a [u8] {
        let start = self.pos;
        let end = self.buf[start..].iter().position(|&b| b == b'\n').map_or(self.buf.len(), |i| start + i);
        self.pos = (end + 1).min(self.buf.len());
        let line = &self.buf[start..end];
        line.strip_suffix(b"\r").unwrap_or(line)
    }

    /// `n` raw bytes of binary data.
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        if n > self.remaining() {
            return Err(
                self.fail(format!("file truncated: {what} needs {n} bytes but only {} are left", self.remaining()))
            );
        }
        let out = &self.buf[self.pos..self.pos + n];
        self.pos += n;
        Ok(out)
    }

    /// `count` records of `size` bytes of binary data, with overflow-safe size checks.
    fn take_records(&mut self, count: u64, size: usize, what: &str) -> Result<&'a [u8]> {
        let n = usize::try_from(count).ok().and_then(|c| c.checked_mul(size));
        match n {
            Some(n) => self.take(n, what),
            None => Err(self.fail(format!("file truncated: {count} {what} cannot fit in the file"))),
        }
    }

    /// An `int` in the file's data encoding (ASCII token or 4 binary bytes).
    fn int(&mut self, what: &str) -> Result<i64> {
        if self.binary {
            Ok(get_i32(self.take(4, what)?, self.big_endian) as i64)
        } else {
            self.ascii_i64(what)
        }
    }

    /// A `size_t` in the file's data encoding (ASCII token or 8 binary bytes; format 4.1).
    fn size(&mut self, what: &str) -> Result<u64> {
        if self.binary {
            Ok(get_u64(self.take(8, what)?, self.big_endian))
        } else {
            self.ascii_u64(what)
        }
    }

    /// Checks that `count` records of at least `min_bytes` each can still be in the file,
    /// so that a corrupt count never makes us allocate (or loop) for data that is not there.
    fn check_room(&self, count: u64, min_bytes: usize, what: &str) -> Result<usize> {
        let room = (self.remaining() / min_bytes.max(1)) as u64;
        if count > room {
            return Err(self.fail(format!(
                "the file declares {count} {what} but only {} bytes are left: truncated or corrupt",
                self.remaining()
            )));
        }
        Ok(count as usize)
    }

    /// Moves past the next line that starts with `marker` (e.g. `$EndEntities`).
    fn skip_past(&mut self, marker: &[u8]) -> Result<()> {
        let mut i = self.pos;
        while let Some(off) = self.buf[i..].iter().position(|&b| b == b'$') {
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
}

// ---------------------------------------------------------------------------------------------
// Parallel parsing of long runs of ASCII records
//
// Gmsh writes one node or element per line, so a long run of records can be cut at line ends
// and parsed on all cores. The parallel parser accepts only that layout, with exactly the
// expected tokens on each line; anything else (records spread over lines, blank lines, bad
// numbers, unknown nodes) makes it give up, and the sequential parser reads the run instead,
// with its precise error messages.

/// Runs of fewer ASCII records are parsed sequentially.
const MIN_PARALLEL: usize = 20_000;

/// The tokens of one line.
struct Tokens<'a>(&'a [u8]);

impl<'a> Tokens<'a> {
    fn next(&mut self) -> Option<&'a [u8]> {
        let start = self.0.iter().position(|b| !b.is_ascii_whitespace())?;
        let rest = &self.0[start..];
        let len = rest.iter().position(|b| b.is_ascii_whitespace()).unwrap_or(rest.len());
        self.0 = &rest[len..];
        Some(&rest[..len])
    }
    fn u64(&mut self) -> Option<u64> {
        parse_u64(self.next()?)
    }
    fn i64(&mut self) -> Option<i64> {
        parse_i64(self.next()?)
    }
    fn f32(&mut self) -> Option<f32> {
        parse_f64(self.next()?).map(|v| v as f32)
    }
    fn done(&self) -> bool {
        self.0.iter().all(|b| b.is_ascii_whitespace())
    }
}

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
    /// Parses the `count` lines at the cursor in parallel: `line` reads one line's tokens into
    /// a chunk's state `S` (the states come back in file order). `None`, with the cursor
    /// unmoved, when the run is short, binary, or not one record per line.
    fn par_lines<S: Default + Send>(
        &mut self,
        count: usize,
        line: impl Fn(&mut Tokens, &mut S) -> Option<()> + Sync,
    ) -> Option<Vec<S>> {
        if self.binary || count < self.min_parallel.max(1) {
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
                    let mut tokens = Tokens(l);
                    line(&mut tokens, &mut state)?;
                    if !tokens.done() {
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

/// The tetrahedra and other volume elements of one chunk of ASCII element lines.
#[derive(Default)]
struct Chunk {
    tets: Vec<[u32; 4]>,
    tags: Vec<u64>,
    order: u8,
    /// (family, nodes, count)
    others: Vec<(&'static str, usize, usize)>,
}

impl Chunk {
    /// Reads an element's `nn` node tags; keeps its corners if it is a tetrahedron.
    fn element(&mut self, t: &mut Tokens, map: &TagMap, tag: u64, kind: Kind, nn: usize) -> Option<()> {
        match kind {
            Kind::Tet(order) => {
                let mut c = [0u32; 4];
                for v in &mut c {
                    *v = map.get(t.u64()?)?;
                }
                self.tets.push(c);
                self.tags.push(tag);
                self.order = self.order.max(order);
            }
            Kind::Volume(name) => match self.others.iter_mut().find(|o| o.0 == name && o.1 == nn) {
                Some(o) => o.2 += 1,
                None => self.others.push((name, nn, 1)),
            },
            Kind::Lower => {}
        }
        let skip = if let Kind::Tet(_) = kind { nn - 4 } else { nn };
        for _ in 0..skip {
            t.u64()?;
        }
        Some(())
    }
}

// ---------------------------------------------------------------------------------------------
// Tag → dense index maps

/// Maps Gmsh tags (any u64, possibly sparse) to dense 0-based indices.
enum TagMap {
    /// Tags `min, min + 1, ...` in file order (what gmsh writes): no table at all.
    Sequential {
        min: u64,
        len: u64,
    },
    /// Tags within a span not much larger than their count: a direct lookup table.
    Dense {
        min: u64,
        index: Vec<u32>,
    },
    Sparse(HashMap<u64, u32>),
}

impl TagMap {
    /// `Err(tag)` names a tag that appears twice.
    fn new(tags: &[u64]) -> Result<TagMap, u64> {
        let (Some(&min), Some(&max)) = (tags.iter().min(), tags.iter().max()) else {
            return Ok(TagMap::Sequential { min: 0, len: 0 });
        };
        if tags.iter().enumerate().all(|(i, &t)| t == min + i as u64) {
            return Ok(TagMap::Sequential { min, len: tags.len() as u64 });
        }
        let span = max - min;
        if span < 2 * tags.len() as u64 + 1024 {
            let mut index = vec![u32::MAX; span as usize + 1];
            for (i, &t) in tags.iter().enumerate() {
                let slot = &mut index[(t - min) as usize];
                if *slot != u32::MAX {
                    return Err(t);
                }
                *slot = i as u32;
            }
            Ok(TagMap::Dense { min, index })
        } else {
            let mut map = HashMap::with_capacity(tags.len());
            for (i, &t) in tags.iter().enumerate() {
                if map.insert(t, i as u32).is_some() {
                    return Err(t);
                }
            }
            Ok(TagMap::Sparse(map))
        }
    }

    #[inline]
    fn get(&self, tag: u64) -> Option<u32> {
        match self {
            TagMap::Sequential { min, len } => tag.checked_sub(*min).filter(|i| i < len).map(|i| i as u32),
            TagMap::Dense { min, index } => {
                let i = usize::try_from(tag.checked_sub(*min)?).ok()?;
                index.get(i).copied().filter(|&v| v != u32::MAX)
            }
            TagMap::Sparse(map) => map.get(&tag).copied(),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The parser

#[derive(Clone, Copy, PartialEq, Eq)]
enum Version {
    V2,
    V41,
}

struct Nodes {
    points: Vec<[f32; 3]>,
    map: TagMap,
}

struct Cells {
    tets: Vec<[u32; 4]>,
    /// Element tag of each tet, for `$ElementData`.
    tags: Vec<u64>,
    /// Built on the first `$ElementData`.
    map: Option<TagMap>,
    order: u8,
}

/// One view being read: values interleaved by component, NaN where none was given.
struct FieldAcc {
    name: String,
    location: FieldLocation,
    step: i64,
    ncomp: usize,
    values: Vec<f32>,
}

struct Parser<'a> {
    c: Cursor<'a>,
    version: Version,
    nodes: Option<Nodes>,
    cells: Option<Cells>,
    fields: Vec<FieldAcc>,
    /// Field values allocated so far, bounded so that many tiny views cannot exhaust memory.
    field_values: usize,
}

/// Gmsh allows 1 (scalar), 3 (vector) and 9 (tensor) components.
const MAX_COMPONENTS: usize = 9;

impl Parser<'_> {
    fn run(mut self) -> Result<RawMesh> {
        self.c.skip_ws();
        if trim(self.c.line()) != b"$MeshFormat" {
            return Err(self.c.fail_at(0, "not a Gmsh .msh file (it does not start with $MeshFormat)"));
        }
        self.read_format()?;
        self.expect_end(b"MeshFormat")?;
        while !self.c.at_end() {
            let start = self.c.pos;
            let header = trim(self.c.line());
            let Some(name) = header.strip_prefix(b"$") else {
                return Err(self
                    .c
                    .fail_at(start, format!("expected a section such as $Nodes, found '{}'", show(header))));
            };
            match name {
                b"Nodes" => self.read_nodes(start)?,
                b"Elements" => self.read_elements(start)?,
                b"NodeData" => self.read_data(FieldLocation::Vertex, start)?,
                b"ElementData" => self.read_data(FieldLocation::Cell, start)?,
                b"MeshFormat" => return Err(self.c.fail_at(start, "a second $MeshFormat section")),
                _ => {
                    let mut end = b"$End".to_vec();
                    end.extend_from_slice(name);
                    self.c.skip_past(&end)?;
                    continue;
                }
            }
            self.expect_end(name)?;
        }
        self.finish()
    }

    fn read_format(&mut self) -> Result<()> {
        self.c.skip_ws();
        let start = self.c.pos;
        let version = self.c.token("the format version")?;
        self.version = match version {
            b"2" | b"2.0" | b"2.1" | b"2.2" => Version::V2,
            b"4.1" => Version::V41,
            _ => {
                return Err(self.c.fail_at(
                    start,
                    format!("Gmsh format version {} is not supported (tetloc reads 2.2 and 4.1)", show(version)),
                ))
            }
        };
        let binary = match self.c.ascii_u64("the file type (0 ascii, 1 binary)")? {
            0 => false,
            1 => true,
            t => return Err(self.c.fail(format!("file type {t}: expected 0 (ascii) or 1 (binary)"))),
        };
        let size = self.c.ascii_u64("the data size")?;
        if size != 8 {
            return Err(self.c.fail(format!("data size {size}: only 8 (64-bit size_t and double) is supported")));
        }
        self.c.line();
        if binary {
            let one = self.c.take(4, "the endianness marker")?;
            self.c.big_endian = match (get_i32(one, false), get_i32(one, true)) {
                (1, _) => false,
                (_, 1) => true,
                _ => return Err(self.c.fail(format!("bad binary endianness marker {one:?}: expected the integer 1"))),
            };
            self.c.binary = true;
        }
        Ok(())
    }

    fn expect_end(&mut self, name: &[u8]) -> Result<()> {
        self.c.skip_ws();
        let start = self.c.pos;
        let line = trim(self.c.line());
        if line.strip_prefix(b"$End") != Some(name) {
            return Err(self.c.fail_at(
                start,
                format!(
                    "expected $End{}, found '{}' (a count in the section does not match its data)",
                    show(name),
                    show(line)
                ),
            ));
        }
        Ok(())
    }

    fn read_nodes(&mut self, start: usize) -> Result<()> {
        if self.nodes.is_some() {
            return Err(self.c.fail_at(start, "a second $Nodes section"));
        }
        let (points, tags) = match self.version {
            Version::V2 => self.read_nodes_v2()?,
            Version::V41 => self.read_nodes_v41(start)?,
        };
        if points.len() >= u32::MAX as usize {
            return Err(self.c.fail(format!("{} nodes: more than tetloc's 32-bit indices can address", points.len())));
        }
        let map =
            TagMap::new(&tags).map_err(|t| self.c.fail_at(start, format!("node tag {t} appears twice in $Nodes")))?;
        self.nodes = Some(Nodes { points, map });
        Ok(())
    }

    fn read_nodes_v2(&mut self) -> Result<(Vec<[f32; 3]>, Vec<u64>)> {
        let c = &mut self.c;
        let declared = c.ascii_u64("the number of nodes")?;
        c.line();
        let n = c.check_room(declared, if c.binary { 28 } else { 8 }, "nodes")?;
        let mut points = Vec::with_capacity(n);
        let mut tags = Vec::with_capacity(n);
        if c.binary {
            let big = c.big_endian;
            let data = c.take_records(declared, 28, "nodes")?;
            for r in data.chunks_exact(28) {
                let tag = get_i32(r, big);
                if tag < 0 {
                    return Err(c.fail(format!("negative node tag {tag}")));
                }
                tags.push(tag as u64);
                points.push([
                    get_f64(&r[4..], big) as f32,
                    get_f64(&r[12..], big) as f32,
                    get_f64(&r[20..], big) as f32,
                ]);
            }
        } else if let Some(chunks) = c.par_lines(n, |t, s: &mut (Vec<u64>, Vec<[f32; 3]>)| {
            s.0.push(t.u64()?);
            s.1.push([t.f32()?, t.f32()?, t.f32()?]);
            Some(())
        }) {
            for (t, p) in chunks {
                tags.extend(t);
                points.extend(p);
            }
        } else {
            for _ in 0..n {
                tags.push(c.ascii_u64("a node tag")?);
                let p = [c.ascii_f64("x")?, c.ascii_f64("y")?, c.ascii_f64("z")?];
                points.push(p.map(|v| v as f32));
            }
        }
        Ok((points, tags))
    }

    /// `start`: where the section begins, for errors about it as a whole.
    fn read_nodes_v41(&mut self, start: usize) -> Result<(Vec<[f32; 3]>, Vec<u64>)> {
        let c = &mut self.c;
        let blocks = c.size("the number of node blocks")?;
        let declared = c.size("the number of nodes")?;
        c.size("the smallest node tag")?;
        c.size("the largest node tag")?;
        let n = c.check_room(declared, if c.binary { 32 } else { 8 }, "nodes")?;
        let mut points = Vec::with_capacity(n);
        let mut tags = Vec::with_capacity(n);
        for _ in 0..blocks {
            let dim = c.int("an entity dimension")?;
            c.int("an entity tag")?;
            let parametric = c.int("the parametric flag")?;
            let count = c.size("the number of nodes in a block")?;
            if !(0..=3).contains(&dim) || !(0..=1).contains(&parametric) {
                return Err(c.fail(format!("bad node block header: dimension {dim}, parametric {parametric}")));
            }
            if count > (n - points.len()) as u64 {
                return Err(c.fail(format!("node blocks hold more nodes than the {n} declared")));
            }
            // Parametric nodes carry u (curves), u v (surfaces) or u v w (volumes) after x y z.
            let per_node = 3 + (parametric * dim) as usize;
            if c.binary {
                let big = c.big_endian;
                let tag_bytes = c.take_records(count, 8, "node tags")?;
                let xyz = c.take_records(count, 8 * per_node, "node coordinates")?;
                tags.extend(tag_bytes.chunks_exact(8).map(|b| get_u64(b, big)));
                points
                    .extend(xyz.chunks_exact(8 * per_node).map(|r| {
                        [get_f64(r, big) as f32, get_f64(&r[8..], big) as f32, get_f64(&r[16..], big) as f32]
                    }));
            } else {
                let count = count as usize;
                if let Some(chunks) = c.par_lines(count, |t, s: &mut Vec<u64>| {
                    s.push(t.u64()?);
                    Some(())
                }) {
                    chunks.into_iter().for_each(|ch| tags.extend(ch));
                } else {
                    for _ in 0..count {
                        tags.push(c.ascii_u64("a node tag")?);
                    }
                }
                if let Some(chunks) = c.par_lines(count, |t, s: &mut Vec<[f32; 3]>| {
                    s.push([t.f32()?, t.f32()?, t.f32()?]);
                    (3..per_node).try_for_each(|_| t.f32().map(drop))
                }) {
                    chunks.into_iter().for_each(|ch| points.extend(ch));
                } else {
                    for _ in 0..count {
                        let p = [c.ascii_f64("x")?, c.ascii_f64("y")?, c.ascii_f64("z")?];
                        points.push(p.map(|v| v as f32));
                        for _ in 3..per_node {
                            c.ascii_f64("a parametric coordinate")?;
                        }
                    }
                }
            }
        }
        if points.len() != n {
            return Err(c.fail_at(start, format!("$Nodes declares {n} nodes but its blocks hold {}", points.len())));
        }
        Ok((points, tags))
    }

    fn read_elements(&mut self, start: usize) -> Result<()> {
        if self.cells.is_some() {
            return Err(self.c.fail_at(start, "a second $Elements section"));
        }
        let Some(nodes) = &self.nodes else {
            return Err(self.c.fail_at(start, "$Elements comes before $Nodes"));
        };
        let mut acc = ElementSink { nodes, tets: Vec::new(), tags: Vec::new(), order: 1, others: Vec::new() };
        match self.version {
            Version::V2 => read_elements_v2(&mut self.c, &mut acc)?,
            Version::V41 => read_elements_v41(&mut self.c, &mut acc, start)?,
        }
        if !acc.others.is_empty() {
            return Err(Error::NonTetCells { path: self.c.path.to_path_buf(), counts: acc.others });
        }
        let ElementSink { tets, tags, order, .. } = acc;
        self.cells = Some(Cells { tets, tags, map: None, order });
        Ok(())
    }

    fn read_data(&mut self, location: FieldLocation, start: usize) -> Result<()> {
        let what = match location {
            FieldLocation::Vertex => "$NodeData",
            FieldLocation::Cell => "$ElementData",
        };
        let n_items = match location {
            FieldLocation::Vertex => self.nodes.as_ref().map(|n| n.points.len()),
            FieldLocation::Cell => self.cells.as_ref().map(|c| c.tets.len()),
        };
        let Some(n_items) = n_items else {
            return Err(self.c.fail_at(start, format!("{what} comes before the mesh it refers to")));
        };
        let c = &mut self.c;

        // The header is ASCII even in binary files.
        let n_str = c.ascii_u64("the number of string tags")?;
        c.check_room(n_str, 3, "string tags")?;
        let mut name = None;
        for _ in 0..n_str {
            c.skip_ws();
            let tag = trim(c.line());
            let tag = tag.strip_prefix(b"\"").and_then(|t| t.strip_suffix(b"\"")).unwrap_or(tag);
            name.get_or_insert_with(|| String::from_utf8_lossy(tag).into_owned());
        }
        let name = name.unwrap_or_else(|| "unnamed".to_string());
        let n_real = c.ascii_u64("the number of real tags")?;
        for _ in 0..n_real {
            c.ascii_f64("a real tag")?;
        }
        let n_int = c.ascii_u64("the number of integer tags")?;
        if n_int < 3 {
            return Err(
                c.fail(format!("{what} '{name}' has {n_int} integer tags; it needs 3 (step, components, count)"))
            );
        }
        let step = c.ascii_i64("the time step")?;
        let ncomp = c.ascii_u64("the number of components")?;
        let count = c.ascii_u64("the number of values")?;
        for _ in 3..n_int {
            c.ascii_i64("an integer tag")?;
        }
        c.line(); // binary data starts on the next line
        if !(1..=MAX_COMPONENTS as u64).contains(&ncomp) {
            return Err(c.fail(format!("{what} '{name}' has {ncomp} components; Gmsh allows 1 to {MAX_COMPONENTS}")));
        }
        let ncomp = ncomp as usize;
        let record = if c.binary { 4 + 8 * ncomp } else { 2 + 2 * ncomp };
        let count = c.check_room(count, record, &format!("values of {what} '{name}'"))?;

        // Where this section's values go: a fresh view, merged into the same step, or nowhere
        // (an older step than one already read).
        let existing = self.fields.iter().position(|f| f.location == location && f.name == name);
        let slot = match existing {
            Some(i) if self.fields[i].step > step => None,
            Some(i) if self.fields[i].step == step => {
                if self.fields[i].ncomp != ncomp {
                    return Err(c.fail(format!("{what} '{name}' step {step} changes its number of components")));
                }
                Some(i)
            }
            _ => {
                let len = n_items * ncomp;
                // Many small views over a big mesh could otherwise allocate far more than the
                // file holds; real files stay well inside this bound.
                self.field_values += len;
                if self.field_values > 64 * c.buf.len() + (1 << 20) {
                    return Err(c.fail(format!("too many field values for the file's size at {what} '{name}'")));
                }
                let acc = FieldAcc { name: name.clone(), location, step, ncomp, values: vec![f32::NAN; len] };
                match existing {
                    Some(i) => {
                        self.fields[i] = acc;
                        Some(i)
                    }
                    None => {
                        self.fields.push(acc);
                        Some(self.fields.len() - 1)
                    }
                }
            }
        };

        // Entity tag → row in the field (None: drop the value).
        let cells = &mut self.cells;
        if location == FieldLocation::Cell {
            let cells = cells.as_mut().expect("checked above");
            if cells.map.is_none() {
                let map = TagMap::new(&cells.tags)
                    .map_err(|t| c.fail(format!("element tag {t} appears twice in $Elements")))?;
                cells.map = Some(map);
            }
        }
        let nodes = &self.nodes;
        let lookup = |tag: i64| -> Result<Option<usize>, String> {
            let t = u64::try_from(tag).map_err(|_| format!("negative tag {tag}"))?;
            match location {
                FieldLocation::Vertex => match nodes.as_ref().and_then(|n| n.map.get(t)) {
                    Some(i) => Ok(Some(i as usize)),
                    None => Err(format!("{what} '{name}' gives a value for node {t}, which is not in $Nodes")),
                },
                // Values on surface or line elements are dropped.
                FieldLocation::Cell => {
                    Ok(cells.as_ref().and_then(|c| c.map.as_ref()).and_then(|m| m.get(t)).map(|i| i as usize))
                }
            }
        };
        let mut values = slot.map(|i| &mut self.fields[i].values);
        let mut store = |row: Option<usize>, comp: usize, v: f64| {
            if let (Some(row), Some(values)) = (row, values.as_deref_mut()) {
                values[row * ncomp + comp] = v as f32;
            }
        };
        if c.binary {
            let big = c.big_endian;
            let data = c.take_records(count as u64, record, &format!("values of {what} '{name}'"))?;
            for r in data.chunks_exact(record) {
                let row = lookup(get_i32(r, big) as i64).map_err(|m| c.fail(m))?;
                for k in 0..ncomp {
                    store(row, k, get_f64(&r[4 + 8 * k..], big));
                }
            }
        } else {
            for _ in 0..count {
                let tag_pos = c.here();
                let row = lookup(c.ascii_i64("an entity tag")?).map_err(|m| c.fail_at(tag_pos, m))?;
                for k in 0..ncomp {
                    store(row, k, c.ascii_f64("a field value")?);
                }
            }
        }
        Ok(())
    }

    fn finish(self) -> Result<RawMesh> {
        let c = &self.c;
        let Some(nodes) = self.nodes else {
            return Err(Error::format(c.path, "no $Nodes section"));
        };
        let Some(cells) = self.cells else {
            return Err(Error::format(c.path, "no $Elements section"));
        };
        if cells.tets.is_empty() {
            return Err(Error::format(c.path, "no tetrahedra: the file holds only points, lines or surface elements"));
        }
        let mut fields = Vec::new();
        for f in self.fields {
            if f.ncomp == 1 {
                fields.push(Field { name: f.name, location: f.location, values: f.values });
            } else {
                for k in 0..f.ncomp {
                    fields.push(Field {
                        name: format!("{}[{k}]", f.name),
                        location: f.location,
                        values: f.values.iter().skip(k).step_by(f.ncomp).copied().collect(),
                    });
                }
            }
        }
        Ok(RawMesh {
            points: nodes.points,
            tets: cells.tets,
            fields,
            higher_order: (cells.order > 1).then_some(cells.order),
            cells: None,
        })
    }
}

/// Collects the tetrahedra of `$Elements` and counts other volume elements.
struct ElementSink<'n> {
    nodes: &'n Nodes,
    tets: Vec<[u32; 4]>,
    tags: Vec<u64>,
    order: u8,
    /// Volume elements that are not tetrahedra, by type name.
    others: Vec<(String, usize)>,
}

impl ElementSink<'_> {
    /// The dense vertex index of a corner, or an error message.
    #[inline]
    fn node(&self, elem: u64, tag: u64) -> Result<u32, String> {
        self.nodes.map.get(tag).ok_or_else(|| format!("element {elem} refers to node {tag}, which is not in $Nodes"))
    }

    /// Adds a block of binary tetrahedron records, decoded in parallel: they are the bulk of a
    /// large binary file. `tag(r)` and `node(r, k)` read a record's element tag and k-th node.
    fn add_binary_tets(
        &mut self,
        data: &[u8],
        record: usize,
        tag: impl Fn(&[u8]) -> u64 + Sync + Send,
        node: impl Fn(&[u8], usize) -> u64 + Sync + Send,
    ) -> Result<(), String> {
        const MISSING: u32 = u32::MAX; // never an index: there are fewer than u32::MAX nodes
        let map = &self.nodes.map;
        let start = self.tets.len();
        let records = || data.par_chunks_exact(record);
        self.tets.par_extend(records().map(|r| std::array::from_fn(|k| map.get(node(r, k)).unwrap_or(MISSING))));
        self.tags.par_extend(records().map(&tag));
        if let Some(i) = self.tets[start..].par_iter().position_first(|t| t.contains(&MISSING)) {
            let r = &data[i * record..];
            let k = (0..4).find(|&k| map.get(node(r, k)).is_none()).unwrap_or(0);
            return Err(self.node(tag(r), node(r, k)).err().unwrap_or_default());
        }
        Ok(())
    }

    /// Appends the chunks of a parallel parse, in order.
    fn merge(&mut self, chunks: Vec<Chunk>, count_others: bool) {
        let n = chunks.iter().map(|c| c.tets.len()).sum();
        self.tets.reserve(n);
        self.tags.reserve(n);
        for c in chunks {
            self.tets.extend_from_slice(&c.tets);
            self.tags.extend_from_slice(&c.tags);
            self.order = self.order.max(c.order);
            if count_others {
                c.others.iter().for_each(|&(name, nn, n)| self.other(name, nn, n));
            }
        }
    }

    fn other(&mut self, name: &str, nodes: usize, count: usize) {
        let key = format!("{name} ({nodes} nodes)");
        match self.others.iter_mut().find(|(k, _)| *k == key) {
            Some((_, n)) => *n += count,
            None => self.others.push((key, count)),
        }
    }

    fn reserve(&mut self, kind: Kind, count: usize) {
        if let (Kind::Tet(order), 1..) = (kind, count) {
            self.order = self.order.max(order);
            self.tets.reserve(count);
            self.tags.reserve(count);
        }
    }
}

fn unknown_type(c: &Cursor, pos: usize, ty: i64) -> Error {
    c.fail_at(
        pos,
        format!("element type {ty} is not a Gmsh element type with a fixed number of nodes that tetloc knows"),
    )
}

/// Reads the `nn` node tags of an ASCII element; the corners if it is a tetrahedron.
fn read_ascii_nodes(
    c: &mut Cursor,
    acc: &ElementSink,
    kind: Kind,
    nn: usize,
    tag: u64,
    pos: usize,
) -> Result<[u32; 4]> {
    let mut t = [0u32; 4];
    let corners = if let Kind::Tet(_) = kind { 4 } else { 0 };
    for v in &mut t[..corners] {
        *v = acc.node(tag, c.ascii_u64("a node tag")?).map_err(|m| c.fail_at(pos, m))?;
    }
    for _ in corners..nn {
        c.ascii_u64("a node tag")?;
    }
    Ok(t)
}

fn read_elements_v2(c: &mut Cursor, acc: &mut ElementSink) -> Result<()> {
    let declared = c.ascii_u64("the number of elements")?;
    c.line();
    if c.binary {
        // Blocks of elements of one type: header (type, count, number of tags), then for each
        // element its tag, its tags and its nodes, all 4-byte ints.
        c.check_room(declared, 16, "elements")?;
        let big = c.big_endian;
        let mut seen = 0u64;
        while seen < declared {
            let pos = c.pos;
            let h = c.take(12, "an element block header")?;
            let (ty, count, ntags) = (get_i32(h, big) as i64, get_i32(&h[4..], big), get_i32(&h[8..], big));
            let (nn, kind) = element_type(ty).ok_or_else(|| unknown_type(c, pos, ty))?;
            if count < 0 || ntags < 0 || count as u64 > declared - seen {
                return Err(c.fail_at(pos, format!("bad element block header: {count} elements with {ntags} tags")));
            }
            let record = 4 * (1 + ntags as usize + nn);
            let data = c.take_records(count as u64, record, "elements")?;
            seen += count as u64;
            acc.reserve(kind, count as usize);
            match kind {
                Kind::Lower => {}
                Kind::Volume(name) => acc.other(name, nn, count as usize),
                Kind::Tet(_) => {
                    // A negative tag becomes a huge one, which no node or data section matches.
                    let first = 4 * (1 + ntags as usize);
                    let int = move |b: &[u8]| get_i32(b, big) as i64 as u64;
                    acc.add_binary_tets(data, record, int, |r, k| int(&r[first + 4 * k..]))
                        .map_err(|m| c.fail_at(pos, m))?;
                }
            }
        }
    } else {
        let n = c.check_room(declared, 8, "elements")?;
        let map = &acc.nodes.map;
        if let Some(chunks) = c.par_lines(n, |t, s: &mut Chunk| {
            let tag = t.u64()?;
            let (nn, kind) = element_type(t.i64()?)?;
            for _ in 0..t.u64()? {
                t.next()?;
            }
            s.element(t, map, tag, kind, nn)
        }) {
            acc.merge(chunks, true);
            return Ok(());
        }
        for _ in 0..n {
            let pos = c.here();
            let tag = c.ascii_u64("an element tag")?;
            let ty = c.ascii_i64("an element type")?;
            let (nn, kind) = element_type(ty).ok_or_else(|| unknown_type(c, pos, ty))?;
            let ntags = c.ascii_u64("the number of element tags")?;
            for _ in 0..ntags {
                c.token("an element tag")?;
            }
            acc.reserve(kind, 1);
            let t = read_ascii_nodes(c, acc, kind, nn, tag, pos)?;
            match kind {
                Kind::Lower => {}
                Kind::Volume(name) => acc.other(name, nn, 1),
                Kind::Tet(_) => {
                    acc.tets.push(t);
                    acc.tags.push(tag);
                }
            }
        }
    }
    Ok(())
}

/// `start`: where the section begins, for errors about it as a whole.
fn read_elements_v41(c: &mut Cursor, acc: &mut ElementSink, start: usize) -> Result<()> {
    let blocks = c.size("the number of element blocks")?;
    let declared = c.size("the number of elements")?;
    c.size("the smallest element tag")?;
    c.size("the largest element tag")?;
    c.check_room(declared, if c.binary { 16 } else { 4 }, "elements")?;
    let mut seen = 0u64;
    for _ in 0..blocks {
        let pos = c.here();
        c.int("an entity dimension")?;
        c.int("an entity tag")?;
        let ty = c.int("an element type")?;
        let count = c.size("the number of elements in a block")?;
        let (nn, kind) = element_type(ty).ok_or_else(|| unknown_type(c, pos, ty))?;
        if count > declared - seen {
            return Err(c.fail_at(pos, format!("element blocks hold more elements than the {declared} declared")));
        }
        seen += count;
        if let Kind::Volume(name) = kind {
            acc.other(name, nn, count as usize);
        }
        if c.binary {
            let big = c.big_endian;
            let record = 8 * (1 + nn);
            let data = c.take_records(count, record, "elements")?;
            acc.reserve(kind, count as usize);
            if let Kind::Tet(_) = kind {
                acc.add_binary_tets(data, record, |r| get_u64(r, big), |r, k| get_u64(&r[8 + 8 * k..], big))
                    .map_err(|m| c.fail_at(pos, m))?;
            }
        } else {
            let count = c.check_room(count, 2 * (1 + nn), "elements")?;
            let map = &acc.nodes.map;
            if let Some(chunks) = c.par_lines(count, |t, s: &mut Chunk| {
                let tag = t.u64()?;
                s.element(t, map, tag, kind, nn)
            }) {
                acc.merge(chunks, false); // other volume elements are counted above
                continue;
            }
            acc.reserve(kind, count);
            for _ in 0..count {
                let epos = c.here();
                let tag = c.ascii_u64("an element tag")?;
                let t = read_ascii_nodes(c, acc, kind, nn, tag, epos)?;
                if let Kind::Tet(_) = kind {
                    acc.tets.push(t);
                    acc.tags.push(tag);
                }
            }
        }
    }
    if seen != declared {
        return Err(c.fail_at(start, format!("$Elements declares {declared} elements but its blocks hold {seen}")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Mesh;
    use crate::testdata::require_data;
    use rand::{Rng, SeedableRng};
    use std::path::PathBuf;

    // -----------------------------------------------------------------------------------------
    // A small mesh written in every encoding by a test-only writer

    /// (name, step, components, [(entity tag, values)]), as in $NodeData / $ElementData
    type View = (&'static str, i64, usize, Vec<(u64, Vec<f64>)>);

    struct Spec {
        nodes: Vec<(u64, [f64; 3])>,
        /// (tag, gmsh type, node tags)
        elems: Vec<(u64, i32, Vec<u64>)>,
        node_data: Vec<View>,
        elem_data: Vec<View>,
    }

    fn spec() -> Spec {
        // Sparse, unordered node tags; a point and a triangle among the tets.
        let nodes = vec![
            (10, [0.0, 0.0, 0.0]),
            (3, [1.0, 0.0, 0.0]),
            (7, [0.0, 1.0, 0.0]),
            (100, [0.0, 0.0, 1.0]),
            (5000, [1.0, 1.0, 1.0]),
        ];
        let elems = vec![
            (5, 15, vec![10]),
            (9, 4, vec![10, 3, 7, 100]),
            (1, 2, vec![3, 7, 100]),
            (2, 4, vec![3, 7, 100, 5000]),
        ];
        let node_data = vec![
            ("temp", 0, 1, nodes.iter().map(|&(t, p)| (t, vec![p[0] + 2.0 * p[1]])).collect()),
            // A later step that covers only two nodes: the others become NaN.
            ("temp", 1, 1, vec![(7, vec![-1.5]), (3, vec![2.5])]),
            ("vel", 0, 3, nodes.iter().map(|&(t, p)| (t, vec![p[0], p[1], t as f64])).collect()),
        ];
        // The triangle's value is dropped.
        let elem_data = vec![("mat", 0, 1, vec![(1, vec![7.0]), (2, vec![20.0]), (9, vec![90.0])])];
        Spec { nodes, elems, node_data, elem_data }
    }

    fn expected() -> RawMesh {
        let nan = f32::NAN;
        let field = |name: &str, location, values: Vec<f32>| Field { name: name.into(), location, values };
        RawMesh {
            points: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]],
            tets: vec![[0, 1, 2, 3], [1, 2, 3, 4]],
            fields: vec![
                field("temp", FieldLocation::Vertex, vec![nan, 2.5, -1.5, nan, nan]),
                field("vel[0]", FieldLocation::Vertex, vec![0.0, 1.0, 0.0, 0.0, 1.0]),
                field("vel[1]", FieldLocation::Vertex, vec![0.0, 0.0, 1.0, 0.0, 1.0]),
                field("vel[2]", FieldLocation::Vertex, vec![10.0, 3.0, 7.0, 100.0, 5000.0]),
                field("mat", FieldLocation::Cell, vec![90.0, 20.0]),
            ],
            higher_order: None,
            cells: None,
        }
    }

    /// Bit-exact comparison (NaN equals NaN).
    fn assert_same(got: &RawMesh, want: &RawMesh, what: &str) {
        assert_eq!(got.points, want.points, "{what}: points");
        assert_eq!(got.tets, want.tets, "{what}: tets");
        assert_eq!(got.higher_order, want.higher_order, "{what}: higher_order");
        let names = |m: &RawMesh| m.fields.iter().map(|f| (f.name.clone(), f.location)).collect::<Vec<_>>();
        assert_eq!(names(got), names(want), "{what}: fields");
        for (g, w) in got.fields.iter().zip(&want.fields) {
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&g.values), bits(&w.values), "{what}: field {}", g.name);
        }
    }

    #[derive(Clone, Copy, Debug)]
    struct Enc {
        v41: bool,
        binary: bool,
        big: bool,
    }

    const ENCODINGS: [Enc; 6] = [
        Enc { v41: false, binary: false, big: false },
        Enc { v41: false, binary: true, big: false },
        Enc { v41: false, binary: true, big: true },
        Enc { v41: true, binary: false, big: false },
        Enc { v41: true, binary: true, big: false },
        Enc { v41: true, binary: true, big: true },
    ];

    struct W {
        out: Vec<u8>,
        e: Enc,
    }

    impl W {
        fn s(&mut self, s: &str) {
            self.out.extend_from_slice(s.as_bytes());
        }
        fn int(&mut self, v: i64) {
            match (self.e.binary, self.e.big) {
                (false, _) => self.s(&format!("{v} ")),
                (true, false) => self.out.extend((v as i32).to_le_bytes()),
                (true, true) => self.out.extend((v as i32).to_be_bytes()),
            }
        }
        fn size(&mut self, v: u64) {
            match (self.e.binary, self.e.big) {
                (false, _) => self.s(&format!("{v} ")),
                (true, false) => self.out.extend(v.to_le_bytes()),
                (true, true) => self.out.extend(v.to_be_bytes()),
            }
        }
        fn f(&mut self, v: f64) {
            match (self.e.binary, self.e.big) {
                (false, _) => self.s(&format!("{v:?} ")),
                (true, false) => self.out.extend(v.to_le_bytes()),
                (true, true) => self.out.extend(v.to_be_bytes()),
            }
        }
        fn nl(&mut self) {
            if !self.e.binary {
                self.s("\n");
            }
        }
    }

    fn dim_of(ty: i32) -> i64 {
        match ty {
            15 => 0,
            1 => 1,
            2 | 3 => 2,
            _ => 3,
        }
    }

    fn write(spec: &Spec, e: Enc) -> Vec<u8> {
        let mut w = W { out: Vec::new(), e };
        w.s(&format!("$MeshFormat\n{} {} 8\n", if e.v41 { "4.1" } else { "2.2" }, e.binary as u8));
        if e.binary {
            w.int(1);
            w.s("\n");
        }
        w.s("$EndMeshFormat\n$PhysicalNames\n1\n3 1 \"$Nodes and $EndNodes\"\n$EndPhysicalNames\n");
        if e.v41 {
            // Skipped unread: binary bytes, including '$', must not confuse the parser.
            w.s("$Entities\n");
            w.out.extend_from_slice(b"\x00$\x01\x02$Nodes\n\xff\n");
            w.s("\n$EndEntities\n");
        }
        w.s("$Nodes\n");
        let n = spec.nodes.len();
        if e.v41 {
            // Two blocks; the second is parametric on a surface (u, v follow x y z).
            let (a, b) = spec.nodes.split_at(2);
            w.size(2);
            w.size(n as u64);
            w.size(spec.nodes.iter().map(|x| x.0).min().unwrap());
            w.size(spec.nodes.iter().map(|x| x.0).max().unwrap());
            w.nl();
            for (block, param) in [(a, 0), (b, 2)] {
                w.int(if param > 0 { 2 } else { 3 });
                w.int(1);
                w.int((param > 0) as i64);
                w.size(block.len() as u64);
                w.nl();
                for &(t, _) in block {
                    w.size(t);
                    w.nl();
                }
                for &(_, p) in block {
                    p.iter().for_each(|&c| w.f(c));
                    (0..param).for_each(|k| w.f(0.25 * k as f64));
                    w.nl();
                }
            }
        } else {
            w.s(&format!("{n}\n"));
            for &(t, p) in &spec.nodes {
                w.int(t as i64);
                p.iter().for_each(|&c| w.f(c));
                w.nl();
            }
        }
        w.s("\n$EndNodes\n$Elements\n");
        // Runs of one type: blocks in 4.1 and in binary 2.2.
        let mut runs: Vec<&[(u64, i32, Vec<u64>)]> = Vec::new();
        let mut rest = &spec.elems[..];
        while let Some(first) = rest.first() {
            let len = rest.iter().take_while(|x| x.1 == first.1).count();
            runs.push(&rest[..len]);
            rest = &rest[len..];
        }
        if e.v41 {
            w.size(runs.len() as u64);
            w.size(spec.elems.len() as u64);
            w.size(1);
            w.size(9);
            w.nl();
            for run in runs {
                w.int(dim_of(run[0].1));
                w.int(1);
                w.int(run[0].1 as i64);
                w.size(run.len() as u64);
                w.nl();
                for (t, _, nodes) in run {
                    w.size(*t);
                    nodes.iter().for_each(|&x| w.size(x));
                    w.nl();
                }
            }
        } else {
            w.s(&format!("{}\n", spec.elems.len()));
            for run in runs {
                if e.binary {
                    w.int(run[0].1 as i64);
                    w.int(run.len() as i64);
                    w.int(2);
                }
                for (t, ty, nodes) in run {
                    w.int(*t as i64);
                    if !e.binary {
                        w.int(*ty as i64);
                        w.int(2);
                    }
                    w.int(1); // physical tag
                    w.int(1); // elementary tag
                    nodes.iter().for_each(|&x| w.int(x as i64));
                    w.nl();
                }
            }
        }
        w.s("\n$EndElements\n");
        for (section, data) in [("NodeData", &spec.node_data), ("ElementData", &spec.elem_data)] {
            for (name, step, ncomp, rows) in data {
                w.s(&format!("${section}\n2\n\"{name}\"\n\"scheme\"\n1\n0.5\n4\n{step}\n{ncomp}\n{}\n0\n", rows.len()));
                for (t, vals) in rows {
                    w.int(*t as i64);
                    vals.iter().for_each(|&v| w.f(v));
                    w.nl();
                }
                w.s(&format!("\n$End{section}\n"));
            }
        }
        w.out
    }

    fn p() -> PathBuf {
        PathBuf::from("test.msh")
    }

    #[test]
    fn every_encoding_gives_the_same_mesh() {
        let want = expected();
        for e in ENCODINGS {
            let bytes = write(&spec(), e);
            // Sequential, and parallel on even the shortest runs of ASCII records.
            for min_parallel in [usize::MAX, 1] {
                let got = parse_with(&bytes, &p(), min_parallel).unwrap_or_else(|err| panic!("{e:?}: {err}"));
                assert_same(&got, &want, &format!("{e:?}, min_parallel {min_parallel}"));
            }
        }
    }

    /// The error for a bad file: the same whether ASCII runs are tried in parallel or not.
    fn err_of(bytes: &[u8]) -> String {
        let msgs = [1, usize::MAX].map(|min_parallel| match parse_with(bytes, &p(), min_parallel) {
            Ok(_) => panic!("parsed a bad file:\n{}", String::from_utf8_lossy(bytes)),
            Err(e) => e.to_string(),
        });
        assert_eq!(msgs[0], msgs[1]);
        msgs[1].clone()
    }

    #[test]
    fn higher_order_tets_use_their_corners() {
        let mut s = spec();
        s.nodes.extend((0..6).map(|i| (200 + i, [0.5, 0.5, 0.1 * i as f64])));
        s.elems[1] = (9, 11, vec![10, 3, 7, 100, 200, 201, 202, 203, 204, 205]);
        s.node_data.clear();
        s.elem_data.clear();
        for (e, min_parallel) in ENCODINGS.iter().flat_map(|&e| [(e, 1), (e, usize::MAX)]) {
            let m = parse_with(&write(&s, e), &p(), min_parallel).unwrap();
            assert_eq!(m.tets, vec![[0, 1, 2, 3], [1, 2, 3, 4]], "{e:?}");
            assert_eq!(m.higher_order, Some(2), "{e:?}");
            assert_eq!(m.points.len(), 11);
        }
    }

    #[test]
    fn other_volume_elements_are_counted() {
        let mut s = spec();
        s.nodes.extend((0..4).map(|i| (300 + i, [2.0, i as f64, 0.0])));
        let hex: Vec<u64> = vec![10, 3, 7, 100, 300, 301, 302, 303];
        s.elems.push((20, 5, hex.clone()));
        s.elems.push((21, 5, hex));
        s.elems.push((22, 6, vec![10, 3, 7, 300, 301, 302]));
        for (e, min_parallel) in ENCODINGS.iter().flat_map(|&e| [(e, 1), (e, usize::MAX)]) {
            match parse_with(&write(&s, e), &p(), min_parallel) {
                Err(Error::NonTetCells { path, counts }) => {
                    assert_eq!(path, p());
                    assert_eq!(
                        counts,
                        vec![("hexahedron (8 nodes)".to_string(), 2), ("prism (6 nodes)".to_string(), 1)]
                    );
                }
                other => panic!("{e:?}: {other:?}"),
            }
        }
    }

    #[test]
    fn bad_files_give_clear_errors() {
        let ascii = |v41| String::from_utf8_lossy(&write(&spec(), Enc { v41, binary: false, big: false })).into_owned();
        let cases: Vec<(String, &str)> = vec![
            (ascii(false).replace("2.2 0 8", "4.0 0 8"), "version 4.0 is not supported"),
            (ascii(false).replace("2.2 0 8", "2.2 0 4"), "data size 4"),
            (ascii(false).replace("$MeshFormat", "$Mesh"), "does not start with $MeshFormat"),
            // Element 9 refers to a node that does not exist (line 15).
            (ascii(false).replace("9 4 2 1 1 10 3", "9 4 2 1 1 11 3"), "line 20: element 9 refers to node 11"),
            (ascii(false).replace("9 4 2 1 1", "9 999 2 1 1"), "line 20: element type 999"),
            (ascii(false).replace("\n100 0.0 0.0 1.0", "\n7 0.0 0.0 1.0"), "line 8: node tag 7 appears twice"),
            (ascii(false).replace("5000 1.0 1.0 1.0", "5000 1.0 1.0 x"), "line 14: expected z (a number), found 'x'"),
            (ascii(false).replace("$Nodes\n5\n", "$Nodes\n4\n"), "expected $EndNodes"),
            (ascii(false).replace("$Nodes\n5\n", "$Nodes\n500000\n"), "declares 500000 nodes"),
            (
                ascii(true).replace("\n2 5 3 5000", "\n2 6 3 5000"),
                "line 13: $Nodes declares 6 nodes but its blocks hold 5",
            ),
            (
                ascii(false).replace("\"vel\"\n\"scheme\"\n1\n0.5\n4\n0\n3", "\"vel\"\n\"scheme\"\n1\n0.5\n4\n0\n4"),
                "expected an entity tag (an integer), found '1.0'",
            ),
            (ascii(false).replace("0\n3\n5\n0\n10 ", "0\n3\n5\n0\n11 "), "gives a value for node 11"),
            (ascii(false).replace("$Elements", "$Elementz"), "no $EndElementz"),
            (ascii(false)[..ascii(false).find("$Elements").unwrap()].to_string(), "no $Elements section"),
        ];
        for (text, want) in cases {
            let msg = err_of(text.as_bytes());
            assert!(msg.starts_with("test.msh: "), "{msg}");
            assert!(msg.contains(want), "expected '{want}' in: {msg}");
        }
        // A surface mesh: no tetrahedra.
        let mut s = spec();
        s.elems.retain(|e| e.1 != 4);
        s.elem_data.clear();
        let msg = err_of(&write(&s, ENCODINGS[0]));
        assert!(msg.contains("no tetrahedra"), "{msg}");
        // The same for the parallel decoding of binary tets.
        let mut s = spec();
        s.elems[3].2[2] = 11;
        s.elem_data.clear();
        for e in ENCODINGS {
            let msg = err_of(&write(&s, e));
            assert!(msg.contains("element 2 refers to node 11, which is not in $Nodes"), "{e:?}: {msg}");
        }
        // A binary file whose endianness marker is not 1.
        let mut bin = write(&spec(), ENCODINGS[4]);
        let at = bin.windows(4).position(|w| w == 1i32.to_le_bytes()).unwrap();
        bin[at] = 7;
        assert!(err_of(&bin).contains("endianness marker"));
    }

    /// Ok only where the cut falls right after a section's `$End...` line (a shorter but whole
    /// file); everything else is an error, never a panic.
    fn check_truncations(bytes: &[u8], lengths: impl Iterator<Item = usize>, what: &str) {
        for len in lengths {
            let cut = &bytes[..len];
            if let Ok(m) = parse(cut, &p()) {
                let last = cut.split(|&b| b == b'\n').rev().map(trim).find(|l| !l.is_empty()).unwrap_or(b"");
                assert!(last.starts_with(b"$End"), "{what}: cut at {len} parsed ({} tets)", m.tets.len());
            }
        }
    }

    #[test]
    fn truncated_files_are_errors() {
        for e in ENCODINGS {
            let bytes = write(&spec(), e);
            check_truncations(&bytes, 0..bytes.len(), &format!("{e:?}"));
        }
        let Some(dir) = require_data("truncated_files_are_errors") else { return };
        for f in ["torus_s.msh", "part_s.msh22.msh", "part_s.meshio.msh", "real/cubes_v41.msh", "real/P3.msh"] {
            let bytes = std::fs::read(dir.join(f)).unwrap();
            let step = bytes.len() / 47;
            check_truncations(&bytes, (0..bytes.len()).step_by(step).chain(bytes.len() - 40..bytes.len()), f);
        }
    }

    #[test]
    fn corrupted_files_do_not_panic() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let corrupt = |bytes: &[u8], rng: &mut rand_pcg::Pcg64| {
            let mut b = bytes.to_vec();
            for _ in 0..rng.gen_range(1..6) {
                let i = rng.gen_range(0..b.len());
                b[i] = match rng.gen_range(0..4) {
                    0 => rng.gen(),
                    1 => b"0123456789"[rng.gen_range(0..10)],
                    2 => 0xff,
                    _ => b' ',
                };
            }
            // Whatever the outcome, it must come back, the same from the sequential and the
            // parallel parser; a mesh that comes back must validate or fail cleanly.
            match (parse_with(&b, &p(), usize::MAX), parse_with(&b, &p(), 1)) {
                (Ok(seq), Ok(par)) => {
                    assert_same(&par, &seq, "corrupt file");
                    let _ = Mesh::new(seq, "corrupt");
                }
                (Err(seq), Err(par)) => assert_eq!(seq.to_string(), par.to_string()),
                (seq, par) => panic!("sequential {seq:?}\nparallel {par:?}"),
            }
        };
        for e in ENCODINGS {
            let bytes = write(&spec(), e);
            for _ in 0..1500 {
                corrupt(&bytes, &mut rng);
            }
        }
        let Some(dir) = require_data("corrupted_files_do_not_panic") else { return };
        for f in ["torus_s.msh", "real/bunny.msh", "part_s.msh22.msh"] {
            let bytes = std::fs::read(dir.join(f)).unwrap();
            for _ in 0..30 {
                corrupt(&bytes, &mut rng);
            }
        }
    }

    // -----------------------------------------------------------------------------------------
    // The shared data files

    fn mesh_json(dir: &Path, name: &str) -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(dir.join(format!("{name}.mesh.json"))).unwrap()).unwrap()
    }

    /// The generators' fields: point field `f` and cell field `cellval` (data README).
    fn check_generated_fields(m: &RawMesh, f: &str) {
        let field = |name: &str, loc| {
            let x = m.fields.iter().find(|x| x.name == name).unwrap_or_else(|| panic!("{f}: no field {name}"));
            assert_eq!(x.location, loc, "{f}: {name}");
            x
        };
        for (p, &v) in m.points.iter().zip(&field("f", FieldLocation::Vertex).values) {
            let [x, y, z] = p.map(|c| c as f64);
            let want = (3.0 * x + 1.0).sin() * (2.0 * y).cos() + 0.5 * (4.0 * z).sin() + 0.3 * x * y;
            assert!((v as f64 - want).abs() < 2e-5, "{f}: f at {p:?} is {v}, expected {want}");
        }
        for (id, &v) in field("cellval", FieldLocation::Cell).values.iter().enumerate() {
            let want = ((id as u64 * 2654435761) % (1 << 32)) as f64 / (1u64 << 32) as f64;
            assert!((v as f64 - want).abs() < 1e-7, "{f}: cellval[{id}] is {v}, expected {want}");
        }
    }

    #[test]
    fn every_shared_msh_file_reads() {
        let Some(dir) = require_data("every_shared_msh_file_reads") else { return };
        let mut seen = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            let file = path.file_name().unwrap().to_string_lossy().to_string();
            if !file.ends_with(".msh") {
                continue;
            }
            let name = file.split('.').next().unwrap();
            let meta = mesh_json(&dir, name);
            assert!(meta["files"].get(&file).is_some(), "{file} is not in {name}.mesh.json");
            let m = read(&path).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(m.points.len() as u64, meta["n_points"].as_u64().unwrap(), "{file}");
            assert_eq!(m.tets.len() as u64, meta["n_tets"].as_u64().unwrap(), "{file}");
            assert_eq!(m.higher_order, None);
            check_generated_fields(&m, &file);
            // Corners in the file's order: the inverted tets are those the generator counted.
            let mesh = Mesh::new(m, file.clone()).unwrap();
            assert_eq!(mesh.info.n_reoriented as u64, meta["n_negative_volume"].as_u64().unwrap(), "{file}");
            seen += 1;
        }
        assert_eq!(seen, 4, "generated .msh files");

        // Real files: counts from the data README. cubes_v22.msh and cubes_v41.msh hold the
        // same 32,981 tets in three volumes (three element blocks in 4.1, of which the last
        // has 11,970), whatever the README says about them differing.
        let real = [
            ("bunny.msh", 19_379, None),
            ("cubes_v22.msh", 32_981, None),
            ("cubes_v41.msh", 32_981, None),
            ("ArmadilloP4.msh", 4_680, Some(4)),
            ("P3.msh", 6_414, Some(3)),
        ];
        for (file, tets, order) in real {
            let m = read(&dir.join("real").join(file)).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(m.tets.len(), tets, "{file}");
            assert_eq!(m.higher_order, order, "{file}");
            assert!(m.fields.is_empty(), "{file}");
            Mesh::new(m, file).unwrap();
        }
        let v22 = read(&dir.join("real/cubes_v22.msh")).unwrap();
        let v41 = read(&dir.join("real/cubes_v41.msh")).unwrap();
        assert_eq!(v22.points.len(), v41.points.len());
    }

    /// Long runs of ASCII records parse in parallel, to the same arrays; a file that does not
    /// keep one record per line falls back to the sequential parser.
    #[test]
    fn parallel_ascii_parsing_agrees() {
        let Some(dir) = require_data("parallel_ascii_parsing_agrees") else { return };
        for f in ["part_s.msh22.msh", "real/bunny.msh", "real/cubes_v22.msh", "real/cubes_v41.msh"] {
            let bytes = std::fs::read(dir.join(f)).unwrap();
            let seq = parse_with(&bytes, &p(), usize::MAX).unwrap();
            assert_same(&parse_with(&bytes, &p(), 1).unwrap(), &seq, f);
            assert_same(&parse(&bytes, &p()).unwrap(), &seq, f);
        }
        // Each element of part_s.msh22.msh spread over two lines: still valid Gmsh.
        let text = std::fs::read_to_string(dir.join("part_s.msh22.msh")).unwrap();
        let (head, rest) = text.split_once("$Elements\n").unwrap();
        let (elems, tail) = rest.split_once("$EndElements").unwrap();
        let split: String = elems
            .lines()
            .map(|l| match l.split_once(' ') {
                Some((tag, more)) => format!("{tag}\n  {more}\n"),
                None => format!("{l}\n"),
            })
            .collect();
        let odd = format!("{head}$Elements\n{split}$EndElements{tail}");
        let want = parse_with(text.as_bytes(), &p(), usize::MAX).unwrap();
        assert_same(&parse_with(odd.as_bytes(), &p(), 1).unwrap(), &want, "split lines");
    }

    /// The `centers` query sets hold each tet's centroid in file order: our tets must sit
    /// around them, which checks node mapping and cell order against the files' other readers.
    #[test]
    fn tets_are_in_oracle_order() {
        let Some(dir) = require_data("tets_are_in_oracle_order") else { return };
        for file in ["torus_s.msh", "part_s.msh22.msh", "part_s.meshio.msh", "delaunay_s.msh", "real/bunny.msh"] {
            let path = dir.join(file);
            let name = path.file_name().unwrap().to_string_lossy().split('.').next().unwrap().to_string();
            let centers = path.with_file_name(format!("{name}.centers.points.bin"));
            let c: Vec<f32> = bytemuck::pod_collect_to_vec(&std::fs::read(&centers).unwrap());
            let ids = centers.with_file_name(format!("{name}.centers.cell.bin"));
            let ids: Vec<i32> = bytemuck::pod_collect_to_vec(&std::fs::read(ids).unwrap());
            let m = Mesh::new(read(&path).unwrap(), file).unwrap();
            assert_eq!(c.len(), 3 * ids.len(), "{file}");
            let tol = 1e-5 * m.info.max_edge_length;
            for (&t, want) in ids.iter().zip(c.chunks_exact(3)) {
                let got = m.tet_center(t as usize);
                let d = (0..3).map(|k| (got[k] - want[k]).abs()).fold(0.0, f32::max);
                assert!(d <= tol, "{file}: tet {t} centroid {got:?}, oracle {want:?}");
            }
        }
    }
}
