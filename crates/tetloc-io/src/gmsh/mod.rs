//! Gmsh `.msh` reader: file formats 2.2 and 4.1, ASCII and binary (either endianness).
//!
//! What is read:
//! - `$Nodes`: any node tags (sparse, unordered); vertices are numbered densely in file order.
//!   Parametric coordinates of 4.1 node blocks are skipped.
//! - `$Elements`: volume cells: tetrahedra of any order (types 4, 11, 29, 30, 31, the
//!   incomplete and order 6–10 variants), hexahedra (5, hex20 17, hex27 12), prisms (6,
//!   prism15 18, prism18 13) and pyramids (7, pyramid13 19, pyramid14 14, whose base centre
//!   VTK's quadratic pyramid has no place for). `higher_order` is the highest order seen. A
//!   file of linear tets gives `tets`; any other file keeps every cell with all its nodes, in
//!   VTK's order, in `RawMesh::cells` (incomplete tets are refused: tetloc has no shape
//!   functions for them). Points, lines and surface elements are ignored. Any other volume
//!   element (higher-order hexahedra, trihedra, ...) is an [`Error::NonTetCells`] that counts
//!   them. Cell ids are 0-based in file order of the volume cells.
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
//!
//! The parts: `mod.rs` dispatches sections and assembles the [`RawMesh`]; `v2.rs` and `v4.rs`
//! read `$Nodes` and `$Elements` of each format version; `elements.rs` is the element type
//! table; `tets.rs` collects the tetrahedra; `tags.rs` maps tags to indices; `data.rs` reads
//! the fields. Words, numbers and binary blocks come from the shared `io/cursor.rs`.

mod cells;
mod data;
mod elements;
mod tags;
#[cfg(test)]
mod tests;
mod v2;
mod v4;

use crate::cursor::{get_i32, show, Cursor};
use cells::ElementSink;
use data::FieldAcc;
use std::path::Path;
use tags::TagMap;
use tetloc_core::cell::CellType;
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::{FieldLocation, RawMesh};

pub fn read(path: &Path) -> Result<RawMesh> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse(&bytes, path)
}

/// Parses a whole file held in memory; `path` only names it in errors.
pub fn parse(bytes: &[u8], path: &Path) -> Result<RawMesh> {
    parse_with(bytes, path, MIN_PARALLEL)
}

/// Runs of fewer ASCII records are parsed sequentially (see [`Cursor::par_lines`]).
const MIN_PARALLEL: usize = 20_000;

/// `parse`, with runs of at least `min_parallel` ASCII records parsed in parallel.
fn parse_with(bytes: &[u8], path: &Path, min_parallel: usize) -> Result<RawMesh> {
    Parser {
        c: Cursor::new(bytes, path),
        min_parallel,
        version: Version::V2,
        nodes: None,
        cells: None,
        fields: Vec::new(),
        field_values: 0,
    }
    .run()
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Version {
    V2,
    V41,
}

struct Nodes {
    points: Vec<[f64; 3]>,
    map: TagMap,
}

struct Cells {
    /// Each cell's first four nodes (a tet's corners).
    tets: Vec<[u32; 4]>,
    /// Element tag of each cell, for `$ElementData`.
    tags: Vec<u64>,
    /// Built on the first `$ElementData`.
    map: Option<TagMap>,
    order: u8,
    /// The nodes after the first four, Gmsh's order; the cells' Gmsh types, run-length encoded.
    extra: Vec<u32>,
    runs: Vec<cells::Run>,
    /// The tags of the other elements (surfaces, lines, points, volumes not read), sorted:
    /// `$ElementData` values on them are dropped; a tag in neither list is an error.
    other_tags: Vec<u64>,
}

struct Parser<'a> {
    c: Cursor<'a>,
    /// See [`MIN_PARALLEL`].
    min_parallel: usize,
    version: Version,
    nodes: Option<Nodes>,
    cells: Option<Cells>,
    fields: Vec<FieldAcc>,
    /// Field values allocated so far, bounded so that many tiny views cannot exhaust memory.
    field_values: usize,
}

impl Parser<'_> {
    fn run(mut self) -> Result<RawMesh> {
        self.c.skip_ws();
        if self.c.line().unwrap_or_default().trim_ascii() != b"$MeshFormat" {
            return Err(self.c.fail_at(0, "not a Gmsh .msh file (it does not start with $MeshFormat)"));
        }
        self.read_format()?;
        self.expect_end(b"MeshFormat")?;
        while !self.c.at_end() {
            let start = self.c.pos;
            let header = self.c.line().unwrap_or_default().trim_ascii();
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
        self.c.line(); // binary data starts on the next line
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
        let line = self.c.line().unwrap_or_default().trim_ascii();
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
            Version::V2 => v2::read_nodes(&mut self.c, self.min_parallel)?,
            Version::V41 => v4::read_nodes(&mut self.c, start, self.min_parallel)?,
        };
        if points.len() >= u32::MAX as usize {
            return Err(self.c.fail(format!("{} nodes: more than tetloc's 32-bit indices can address", points.len())));
        }
        let map =
            TagMap::new(&tags).map_err(|t| self.c.fail_at(start, format!("node tag {t} appears twice in $Nodes")))?;
        self.nodes = Some(Nodes { points, map });
        Ok(())
    }

    fn read_elements(&mut self, start: usize) -> Result<()> {
        if self.cells.is_some() {
            return Err(self.c.fail_at(start, "a second $Elements section"));
        }
        let Some(nodes) = &self.nodes else {
            return Err(self.c.fail_at(start, "$Elements comes before $Nodes"));
        };
        let mut acc = ElementSink {
            nodes,
            tets: Vec::new(),
            tags: Vec::new(),
            other_tags: Vec::new(),
            extra: Vec::new(),
            runs: Vec::new(),
            order: 1,
            others: Vec::new(),
        };
        match self.version {
            Version::V2 => v2::read_elements(&mut self.c, &mut acc, self.min_parallel)?,
            Version::V41 => v4::read_elements(&mut self.c, &mut acc, start, self.min_parallel)?,
        }
        if !acc.others.is_empty() {
            return Err(Error::NonTetCells { path: self.c.path.to_path_buf(), counts: acc.others });
        }
        let ElementSink { tets, tags, order, extra, runs, mut other_tags, .. } = acc;
        rayon::slice::ParallelSliceMut::par_sort_unstable(&mut other_tags[..]);
        self.cells = Some(Cells { tets, tags, map: None, order, extra, runs, other_tags });
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
            return Err(Error::format(
                c.path,
                "no volume cells: the file holds only points, lines or surface elements",
            ));
        }
        // Linear tets only: the corners say it all. Otherwise every cell with all its nodes.
        let all_tets = cells.runs.iter().all(|r| CellType::from_gmsh(r.0).is_some_and(|(t, _)| t.shape().is_tet()));
        let block = (cells.order > 1 || !all_tets)
            .then(|| cells::vtk_cells(&cells.tets, &cells.extra, &cells.runs))
            .transpose()
            .map_err(|m| Error::format(c.path, m))?;
        Ok(RawMesh {
            points: nodes.points.iter().map(|p| p.map(|x| x as f32)).collect(),
            points64: super::points64_if_needed(nodes.points),
            tets: if all_tets { cells.tets } else { Vec::new() },
            fields: self.fields.into_iter().flat_map(FieldAcc::into_fields).collect(),
            higher_order: (cells.order > 1).then_some(cells.order),
            cells: block,
        })
    }
}
