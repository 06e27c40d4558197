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
//!   functions for them). Points, lines and surface elements are ignored ([`read_any`], which
//!   reads a file as a point set with its elements, keeps those that VTK has). Any other volume
//!   element (higher-order hexahedra, trihedra, ...) is an [`Error::NonTetCells`] that counts
//!   them. Cell ids are 0-based in file order of the volume cells.
//! - `$NodeData` / `$ElementData`: vertex / cell fields named by their first string tag, with
//!   `NAME[i]` per component when there are several. Element data is matched to tetrahedra by
//!   element tag; values on other elements are dropped. Nodes or cells that a view gives no
//!   value get NaN. When one view name appears with several time steps, the mesh holds its
//!   first (lowest) step, and [`read_series`] reads the others as time steps; sections of the
//!   same step (partitions) are merged.
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
use crate::vtk::vtu::AnyGrid;
use cells::{ElementSink, LowerElements};
use data::FieldAcc;
use std::path::{Path, PathBuf};
use tags::TagMap;
use tetloc_core::cell::CellType;
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::{Field, FieldLocation, RawMesh, StepFields, TimeSteps};

pub fn read(path: &Path) -> Result<RawMesh> {
    let bytes = crate::read_file(path)?;
    parse(&bytes, path)
}

/// Reads the mesh (each view at its first step, as [`read`] does) and, when the views hold
/// two or more time steps, the steps: step `k` is the `k`-th smallest step number of any
/// section, at the time of that step's first section that gives one (its first real tag;
/// else the step number). A step's fields are every view at its highest step up to that one
/// (a view written at fewer steps keeps its last values), read from the file when asked.
pub fn read_series(path: &Path) -> Result<(RawMesh, Option<TimeSteps>)> {
    let bytes = crate::read_file(path)?;
    let parser = Parser::new(&bytes, path, MIN_PARALLEL, false).run()?;
    let mut steps: Vec<(i64, Option<f64>)> = Vec::new();
    let mut sections = parser.step_times.clone();
    sections.sort_by_key(|s| s.0); // stable: each step's sections stay in file order
    for (step, time) in sections {
        match steps.last_mut() {
            Some(last) if last.0 == step => {
                last.1 = last.1.or(time);
            }
            _ => steps.push((step, time)),
        }
    }
    let raw = parser.finish()?;
    if steps.len() < 2 {
        return Ok((raw, None));
    }
    let times: Vec<f64> = steps.iter().map(|&(step, time)| time.unwrap_or(step as f64)).collect();
    if let Some(k) = times.windows(2).position(|w| w[0].partial_cmp(&w[1]) != Some(std::cmp::Ordering::Less)) {
        return Err(Error::format(
            path,
            format!(
                "the times of steps {} and {} ({} and {}) do not increase: tetloc reads the time steps of a \
                 Gmsh file in the order of their step numbers, at rising times",
                steps[k].0,
                steps[k + 1].0,
                times[k],
                times[k + 1]
            ),
        ));
    }
    let fields = GmshSteps { path: path.to_path_buf(), steps: steps.iter().map(|s| s.0).collect() };
    Ok((raw, Some(TimeSteps::new(path.display().to_string(), times, Box::new(fields)))))
}

/// The time steps of a Gmsh file: each step's fields are read from the file again, keeping
/// views at the highest step up to that one, so one step is in memory at a time.
struct GmshSteps {
    path: PathBuf,
    /// The step numbers, ascending.
    steps: Vec<i64>,
}

impl StepFields for GmshSteps {
    fn read(&self, k: usize) -> Result<Vec<Field>> {
        let bytes = crate::read_file(&self.path)?;
        let mut parser = Parser::new(&bytes, &self.path, MIN_PARALLEL, false);
        parser.step_limit = Some(self.steps[k]);
        Ok(parser.run()?.finish()?.fields)
    }
}

/// Parses a whole file held in memory; `path` only names it in errors.
pub fn parse(bytes: &[u8], path: &Path) -> Result<RawMesh> {
    parse_with(bytes, path, MIN_PARALLEL)
}

/// Runs of fewer ASCII records are parsed sequentially (see [`Cursor::par_lines`]).
const MIN_PARALLEL: usize = 20_000;

/// `parse`, with runs of at least `min_parallel` ASCII records parsed in parallel.
fn parse_with(bytes: &[u8], path: &Path, min_parallel: usize) -> Result<RawMesh> {
    Parser::new(bytes, path, min_parallel, false).run()?.finish()
}

/// Reads a `.msh` file as a point set with its elements as they are: every node, the volume
/// cells tetloc reads, then the points, lines and surface elements that have a VTK cell type
/// (vertices, linear and quadratic lines, triangles and quadrilaterals), with their
/// `$NodeData` and `$ElementData`. What `probe` keeps of a target, which may be any point set:
/// a surface mesh, a cloud of points, a volume.
pub fn read_any(path: &Path) -> Result<AnyGrid> {
    let bytes = crate::read_file(path)?;
    parse_any(&bytes, path)
}

/// [`read_any`] of a file held in memory; `path` only names it in errors.
pub fn parse_any(bytes: &[u8], path: &Path) -> Result<AnyGrid> {
    Parser::new(bytes, path, MIN_PARALLEL, true).run()?.finish_any()
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
    /// The points, lines and surface elements, when kept ([`read_any`]): `$ElementData` rows
    /// after the volume cells'.
    lower: Option<LowerElements>,
}

impl Cells {
    /// The element tags of `$ElementData`'s rows: the volume cells', then the kept lower
    /// elements'.
    fn data_tags(&self) -> std::borrow::Cow<'_, [u64]> {
        match &self.lower {
            Some(l) => [&self.tags[..], &l.tags[..]].concat().into(),
            None => self.tags.as_slice().into(),
        }
    }
}

struct Parser<'a> {
    c: Cursor<'a>,
    /// Whether points, lines and surface elements are kept ([`read_any`]).
    keep_lower: bool,
    /// See [`MIN_PARALLEL`].
    min_parallel: usize,
    version: Version,
    nodes: Option<Nodes>,
    cells: Option<Cells>,
    fields: Vec<FieldAcc>,
    /// Field values allocated so far, bounded so that many tiny views cannot exhaust memory.
    field_values: usize,
    /// Views beyond this step are skipped (a time series' step); `None`: none is.
    step_limit: Option<i64>,
    /// Every data section's step and time (its first real tag), in file order.
    step_times: Vec<(i64, Option<f64>)>,
}

impl<'a> Parser<'a> {
    fn new(bytes: &'a [u8], path: &'a Path, min_parallel: usize, keep_lower: bool) -> Parser<'a> {
        Parser {
            c: Cursor::new(bytes, path),
            keep_lower,
            min_parallel,
            version: Version::V2,
            nodes: None,
            cells: None,
            fields: Vec::new(),
            field_values: 0,
            step_limit: None,
            step_times: Vec::new(),
        }
    }

    /// Reads every section; [`Self::finish`] or [`Self::finish_any`] assembles the result.
    fn run(mut self) -> Result<Self> {
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
                // Skipping it would drop a view silently.
                b"ElementNodeData" => {
                    let c = &mut self.c;
                    let view = match c.ascii_u64("the number of string tags")? {
                        0 => "unnamed".to_string(),
                        _ => {
                            c.skip_ws();
                            let tag = c.line().unwrap_or_default().trim_ascii();
                            String::from_utf8_lossy(tag).trim_matches('"').to_string()
                        }
                    };
                    return Err(c.fail_at(
                        start,
                        format!(
                            "$ElementNodeData view '{view}': values per element node are not supported \
                             (tetloc reads $NodeData and $ElementData)"
                        ),
                    ));
                }
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
        Ok(self)
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
            lower: self.keep_lower.then(LowerElements::default),
        };
        match self.version {
            Version::V2 => v2::read_elements(&mut self.c, &mut acc, self.min_parallel)?,
            Version::V41 => v4::read_elements(&mut self.c, &mut acc, start, self.min_parallel)?,
        }
        if !acc.others.is_empty() {
            return Err(Error::NonTetCells { path: self.c.path.to_path_buf(), counts: acc.others });
        }
        let ElementSink { tets, tags, order, extra, runs, mut other_tags, lower, .. } = acc;
        rayon::slice::ParallelSliceMut::par_sort_unstable(&mut other_tags[..]);
        self.cells = Some(Cells { tets, tags, map: None, order, extra, runs, other_tags, lower });
        Ok(())
    }

    /// The point set of [`read_any`]: the volume cells in VTK's order, then the lower elements.
    fn finish_any(self) -> Result<AnyGrid> {
        let path = self.c.path;
        let (Some(nodes), Some(cells)) = (self.nodes, self.cells) else {
            return Err(Error::format(path, "no $Nodes or no $Elements section"));
        };
        let volumes = cells::vtk_cells(&cells.tets, &cells.extra, &cells.runs).map_err(|m| Error::format(path, m))?;
        let mut grid = AnyGrid {
            points: nodes.points.iter().map(|p| p.map(|x| x as f32)).collect(),
            points64: super::points64_if_needed(nodes.points),
            types: volumes.types.iter().map(|t| t.def().vtk_type()).collect(),
            ends: volumes.ends,
            conn: volumes.conn,
            fields: self.fields.into_iter().flat_map(FieldAcc::into_fields).collect(),
        };
        let lower = cells.lower.unwrap_or_default();
        let mut at = 0;
        for &(code, nn, count) in &lower.runs {
            let vtk = elements::vtk_lower(code).ok_or_else(|| {
                Error::format(
                    path,
                    format!(
                        "element type {code} ({nn} nodes) has no VTK cell type that tetloc writes: a target's points, \
                         lines and surfaces may be vertices, lines, triangles or quadrilaterals of order 1 or 2"
                    ),
                )
            })?;
            for _ in 0..count {
                grid.types.push(vtk);
                grid.conn.extend_from_slice(&lower.nodes[at..at + nn]); // VTK's node order is Gmsh's here
                grid.ends.push(grid.conn.len() as u64);
                at += nn;
            }
        }
        Ok(grid)
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
