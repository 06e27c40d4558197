//! Reader of VTK XML unstructured grids (`.vtu`).
//!
//! Data arrays may be ascii, inline base64 (`format="binary"`) or appended (raw or base64),
//! uncompressed or zlib-compressed, with UInt32 or UInt64 block headers, in either byte
//! order. Appended raw data is not XML: the XML part is parsed up to `<AppendedData>`, and
//! arrays are then read at their offsets after the `_` marker, straight from the file's
//! bytes. Every size the file declares is checked against the bytes that are there before
//! anything is allocated for it.

// The parts shared with the legacy reader and the writers live in `io/vtk/`.

use super::blocks::{self, Layout};
use super::cells;
use super::num::{self, Array, NumType};
use super::xml::{self, Node};
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::Path;
use tetloc_core::cell::{CellBlock, CellType, PolyFaces};
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::{Field, FieldLocation, RawMesh};

pub fn read(path: &Path) -> Result<RawMesh> {
    let bytes = super::read_file(path)?;
    parse(&bytes, path)
}

/// Parses a whole file held in memory; `path` only names it in errors.
pub fn parse(bytes: &[u8], path: &Path) -> Result<RawMesh> {
    parse_with_ids(bytes, path).map(|(raw, _)| raw)
}

/// Names of a cell array of global cell ids (`vtkGenerateGlobalIds` writes `GlobalCellIds`;
/// `<CellData GlobalIds="NAME">` names any other).
pub(crate) const GLOBAL_CELL_IDS: [&str; 2] = ["GlobalCellIds", "vtkGlobalIds"];
/// Names of a point array of global point ids (`<PointData GlobalIds="NAME">` names any other).
pub(crate) const GLOBAL_POINT_IDS: [&str; 2] = ["GlobalPointIds", "vtkGlobalIds"];

/// A file's global ids, exact, when it has integer arrays of them.
#[derive(Default)]
pub(crate) struct GlobalIds {
    /// One per volume cell.
    pub cells: Option<Vec<u64>>,
    /// One per point.
    pub points: Option<Vec<u64>>,
}

/// [`parse`], and the file's global cell and point ids (the arrays also stay fields as in
/// [`parse`]). Partitioned meshes (`io::vtk::pieces`) number their cells by them and merge
/// the copies of a vertex that several pieces hold.
pub(crate) fn parse_with_ids(bytes: &[u8], path: &Path) -> Result<(RawMesh, GlobalIds)> {
    let parts = each_piece(bytes, path, |ctx, piece, k| ctx.piece(piece, k))?;
    let cells = parts.iter().map(|p| p.ids.cells.as_deref()).collect::<Option<Vec<_>>>().map(|a| a.concat());
    let points = parts.iter().map(|p| p.ids.points.as_deref()).collect::<Option<Vec<_>>>().map(|a| a.concat());
    Ok((merge(parts, path)?, GlobalIds { cells, points }))
}

/// A one-piece `.vtu`'s points and cells as the file stores them (each `<Points>` and
/// `<Cells>` array's attributes and bytes before decoding, and the piece's counts), digested:
/// files of equal digests hold the same geometry. `None` for a file of several pieces. A time
/// series whose steps repeat the mesh (`pvd`) checks each step with this instead of decoding it.
pub(crate) fn stored_geometry(bytes: &[u8], path: &Path) -> Result<Option<u64>> {
    use std::hash::{Hash, Hasher};
    let digests = each_piece(bytes, path, |ctx, piece, _| {
        let mut h = std::collections::hash_map::DefaultHasher::new();
        let Layout { header64, zlib, big_endian } = ctx.layout;
        (header64, zlib, big_endian, piece.attr("NumberOfPoints"), piece.attr("NumberOfCells")).hash(&mut h);
        let mut offsets = Vec::new();
        collect_offsets(piece, &mut offsets);
        offsets.sort_unstable();
        for section in ["Points", "Cells"] {
            for da in piece.child(section).into_iter().flat_map(|s| s.children_named("DataArray")) {
                for key in ["Name", "type", "NumberOfComponents", "format"] {
                    da.attr(key).hash(&mut h);
                }
                ctx.stored(da, &offsets).hash(&mut h);
            }
        }
        Ok(h.finish())
    })?;
    Ok(match digests[..] {
        [d] => Some(d),
        _ => None,
    })
}

/// The point and cell data of a one-piece `.vtu` whose cells are all linear tets, read
/// without decoding its points and cells (what [`parse`] gives as `fields`), the fields that
/// `wanted` refuses left undecoded: for the steps of a series whose mesh [`stored_geometry`]
/// found unchanged.
pub(crate) fn tet_fields(bytes: &[u8], path: &Path, wanted: &dyn Fn(&str) -> bool) -> Result<Vec<Field>> {
    let mut parts = each_piece(bytes, path, |ctx, piece, k| {
        let n_points = ctx.count(piece, "NumberOfPoints", k)?;
        let n_cells = ctx.count(piece, "NumberOfCells", k)?;
        ctx.data(piece, n_points, n_cells, cells::Extracted::all_tets(Vec::new()), (Vec::new(), None), wanted)
    })?;
    match parts.len() {
        1 => Ok(parts.pop().expect("one part").raw.fields),
        n => Err(Error::format(path, format!("{n} pieces where the series' first step has one"))),
    }
}

/// `read` of each `<Piece>` of the file, in order.
fn each_piece<T>(bytes: &[u8], path: &Path, read: impl Fn(&Ctx, &Node, usize) -> Result<T>) -> Result<Vec<T>> {
    let fail = |msg: String| Error::format(path, msg);
    let doc = xml::parse(bytes, "AppendedData").map_err(fail)?;
    let root = &doc.root;
    if root.name != "VTKFile" {
        return Err(fail(format!("not a VTK XML file: the root element is <{}>, not <VTKFile>", root.name)));
    }
    match root.attr("type") {
        Some("UnstructuredGrid") => {}
        other => {
            return Err(fail(format!(
                "a VTK XML file of type '{}': tetloc reads UnstructuredGrid (.vtu) files",
                other.unwrap_or("(none)")
            )))
        }
    }
    let layout = Layout {
        header64: match root.attr("header_type") {
            None | Some("UInt32") => false,
            Some("UInt64") => true,
            Some(o) => return Err(fail(format!("header_type '{o}' is neither UInt32 nor UInt64"))),
        },
        zlib: match root.attr("compressor") {
            None | Some("") => false,
            Some("vtkZLibDataCompressor") => true,
            Some(o) => {
                return Err(fail(format!("compressor '{o}' is not supported (tetloc reads vtkZLibDataCompressor)")))
            }
        },
        big_endian: match root.attr("byte_order") {
            None | Some("LittleEndian") => false,
            Some("BigEndian") => true,
            Some(o) => return Err(fail(format!("byte_order '{o}' is neither LittleEndian nor BigEndian"))),
        },
    };
    let appended = match &doc.stopped_at {
        Some((node, pos)) => Some(Appended::find(bytes, node, *pos, root).map_err(fail)?),
        None => None,
    };
    let grid = root.child("UnstructuredGrid").ok_or_else(|| fail("no <UnstructuredGrid> element".into()))?;
    let ctx = Ctx { path, layout, appended };
    let pieces: Vec<&Node> = grid.children_named("Piece").collect();
    if pieces.is_empty() {
        return Err(fail("<UnstructuredGrid> has no <Piece>".into()));
    }
    pieces.iter().enumerate().map(|(k, p)| read(&ctx, p, k)).collect()
}

/// A `.vtu` as the file has it, whatever its cells (volumes, surfaces, lines, vertices):
/// what `probe` keeps of a target, which may be any point set.
#[derive(Clone, Debug, Default)]
pub struct AnyGrid {
    pub points: Vec<[f32; 3]>,
    /// The file's coordinates, when some do not round to f32 exactly.
    pub points64: Option<Vec<[f64; 3]>>,
    /// Each cell's VTK type.
    pub types: Vec<u8>,
    /// Where each cell's point ids end in `conn`.
    pub ends: Vec<u64>,
    pub conn: Vec<u32>,
    /// Point and cell data (a k-component array as the fields `NAME[0]` … `NAME[k-1]`).
    pub fields: Vec<Field>,
}

impl AnyGrid {
    /// Point `i` at the file's precision.
    pub fn point64(&self, i: usize) -> [f64; 3] {
        match &self.points64 {
            Some(p) => p[i],
            None => self.points[i].map(f64::from),
        }
    }
}

/// Reads a `.vtu` of any cells as an [`AnyGrid`].
pub fn read_any(path: &Path) -> Result<AnyGrid> {
    let bytes = super::read_file(path)?;
    parse_any(&bytes, path)
}

/// [`read_any`] of a file held in memory. Pieces are joined; they must carry the same arrays.
pub fn parse_any(bytes: &[u8], path: &Path) -> Result<AnyGrid> {
    let mut out = AnyGrid::default();
    for (k, g) in each_piece(bytes, path, |ctx, piece, k| ctx.any_piece(piece, k))?.into_iter().enumerate() {
        let names = |g: &AnyGrid| g.fields.iter().map(|f| (f.name.clone(), f.location)).collect::<Vec<_>>();
        if k == 0 {
            out.fields = g.fields.iter().map(|f| Field::new(f.name.clone(), f.location, Vec::new())).collect();
        } else if names(&g) != names(&out) {
            return Err(Error::format(path, format!("<Piece> {k} does not carry the same arrays as <Piece> 0")));
        }
        let (base, conn_base) = (out.points.len() as u64, out.conn.len() as u64);
        if base + g.points.len() as u64 > u32::MAX as u64 {
            return Err(Error::format(path, "the pieces hold more points than u32 ids can address"));
        }
        if g.points64.is_some() || out.points64.is_some() {
            let wide = out.points64.get_or_insert_with(|| out.points.iter().map(|q| q.map(f64::from)).collect());
            wide.extend((0..g.points.len()).map(|i| g.point64(i)));
        }
        out.points.extend_from_slice(&g.points);
        out.types.extend_from_slice(&g.types);
        out.ends.extend(g.ends.iter().map(|e| e + conn_base));
        out.conn.extend(g.conn.iter().map(|&i| i + base as u32));
        for (f, gf) in out.fields.iter_mut().zip(&g.fields) {
            f.extend_from(gf);
        }
    }
    Ok(out)
}

/// Where the appended data lies.
enum Appended<'a> {
    /// The bytes after `_`; offsets index them.
    Raw(&'a [u8]),
    /// The base64 text after `_`, and every array's offset into it, sorted: an array's text
    /// runs to the next offset.
    Base64(&'a [u8], Vec<usize>),
}

impl<'a> Appended<'a> {
    /// `pos` is just after the `<AppendedData ...>` tag.
    fn find(bytes: &'a [u8], node: &Node, pos: usize, root: &Node) -> Result<Appended<'a>, String> {
        let rest = &bytes[pos..];
        let skip = rest.iter().take_while(|c| c.is_ascii_whitespace()).count();
        if rest.get(skip) != Some(&b'_') {
            return Err("<AppendedData>: the data does not start with the '_' marker".into());
        }
        let data = &rest[skip + 1..];
        // A file cut short in its last array still has all the sizes it needs: ask for the
        // closing tag, which VTK writes after the data.
        let tail = bytes.trim_ascii_end();
        let closed =
            tail.ends_with(b">") && tail[tail.len().saturating_sub(64)..].windows(9).any(|w| w == b"</VTKFile");
        if !closed {
            return Err("the file does not end with </VTKFile>: truncated?".into());
        }
        match node.attr("encoding") {
            Some("raw") => Ok(Appended::Raw(data)),
            Some("base64") => {
                let end = data.iter().position(|&c| c == b'<').unwrap_or(data.len());
                let mut offsets = Vec::new();
                collect_offsets(root, &mut offsets);
                offsets.sort_unstable();
                offsets.dedup();
                Ok(Appended::Base64(&data[..end], offsets))
            }
            other => Err(format!("<AppendedData> encoding '{}' is neither raw nor base64", other.unwrap_or("(none)"))),
        }
    }
}

fn collect_offsets(node: &Node, out: &mut Vec<usize>) {
    if node.name == "DataArray" && node.attr("format") == Some("appended") {
        if let Some(o) = node.attr("offset").and_then(|o| o.trim().parse().ok()) {
            out.push(o);
        }
    }
    node.children.iter().for_each(|c| collect_offsets(c, out));
}

struct Ctx<'a, 'p> {
    path: &'p Path,
    layout: Layout,
    appended: Option<Appended<'a>>,
}

/// A piece's `<Cells>`, as [`Ctx::read_cells`] finds them.
enum PieceCells {
    /// Every cell a linear tet: the connectivity, 4 ids a tet.
    LinearTets(Vec<u32>),
    /// VTK's cell types, each cell's end in `conn`, and the cells' point ids.
    /// The faces of the polyhedra among them, when there are any.
    Any { types: Vec<u8>, ends: Vec<u64>, conn: Vec<u32>, polyhedra: Option<PolyFaces> },
}

/// One piece's mesh, or the counts of its volume cells by type when some of them are of a
/// type tetloc does not read (the mesh is refused).
struct Part {
    raw: RawMesh,
    refused: BTreeMap<u8, usize>,
    /// The global ids, when the piece has integer arrays of them.
    ids: GlobalIds,
}

impl<'a> Ctx<'a, '_> {
    fn fail(&self, msg: String) -> Error {
        Error::format(self.path, msg)
    }

    /// The values of a `<DataArray>`, which must hold exactly `n_values` of them.
    fn array(&self, da: &Node, n_values: usize) -> Result<Array<'a>> {
        self.array_of(da, Some(n_values))
    }

    /// The values of a `<DataArray>`, as many as it holds.
    fn array_any(&self, da: &Node) -> Result<Array<'a>> {
        self.array_of(da, None)
    }

    fn array_of(&self, da: &Node, n_values: Option<usize>) -> Result<Array<'a>> {
        let name = da.attr("Name").unwrap_or("(unnamed)");
        let e = |msg: String| self.fail(format!("DataArray '{name}': {msg}"));
        let ty = da.attr("type").unwrap_or("(none)");
        let ty = NumType::from_xml(ty).ok_or_else(|| e(format!("type '{ty}' is not a numeric type")))?;
        // The bytes the block at `buf[at..]` must hold: `n_values`', or what it declares.
        let bytes_at = |buf: &[u8], at: usize| match n_values {
            Some(n) => n.checked_mul(ty.size()).ok_or_else(|| e(format!("{n} values: more than memory can hold"))),
            None => blocks::declared_bytes(buf, at, self.layout).map_err(e),
        };
        let big = self.layout.big_endian;
        match da.attr("format") {
            Some("ascii") => {
                let (arr, _) = num::parse_ascii(&da.text(), ty, None).map_err(e)?;
                if let Some(n) = n_values.filter(|&n| arr.len() != n) {
                    return Err(e(format!("has {} values, expected {n}", arr.len())));
                }
                Ok(arr)
            }
            Some("binary") => {
                let decoded = blocks::base64_decode(&da.text()).map_err(e)?;
                let n_bytes = bytes_at(&decoded, 0)?;
                let block = blocks::read_block(&decoded, 0, self.layout, n_bytes).map_err(e)?;
                Ok(Array::from_bytes(ty, Cow::Owned(block.into_owned()), big))
            }
            Some("appended") => {
                let offset = da.attr("offset").unwrap_or("(none)");
                let offset: usize =
                    offset.trim().parse().map_err(|_| e(format!("offset '{offset}' is not a number")))?;
                match &self.appended {
                    None => Err(e("format is appended but the file has no <AppendedData>".into())),
                    Some(Appended::Raw(data)) => {
                        if offset > data.len() {
                            return Err(e(format!("appended block at offset {offset} is past the end of the file")));
                        }
                        let n_bytes = bytes_at(data, offset)?;
                        let block = blocks::read_block(data, offset, self.layout, n_bytes).map_err(e)?;
                        Ok(Array::from_bytes(ty, block, big))
                    }
                    Some(Appended::Base64(text, offsets)) => {
                        let end = offsets.iter().find(|&&o| o > offset).map_or(text.len(), |&o| o.min(text.len()));
                        if offset > text.len() {
                            return Err(e(format!("appended block at offset {offset} is past the end of the data")));
                        }
                        let decoded = blocks::base64_decode(&text[offset..end]).map_err(e)?;
                        let n_bytes = bytes_at(&decoded, 0)?;
                        let block = blocks::read_block(&decoded, 0, self.layout, n_bytes).map_err(e)?;
                        Ok(Array::from_bytes(ty, Cow::Owned(block.into_owned()), big))
                    }
                }
            }
            other => Err(e(format!("format '{}' is not ascii, binary or appended", other.unwrap_or("(none)")))),
        }
    }

    /// A `<DataArray>`'s bytes as stored: its text (ascii, binary), or its stretch of the
    /// appended data up to the next of the piece's `offsets` (sorted).
    fn stored(&self, da: &Node, offsets: &[usize]) -> Cow<'a, [u8]> {
        let start = da.attr("offset").and_then(|o| o.trim().parse::<usize>().ok());
        match (da.attr("format"), &self.appended, start) {
            (Some("appended"), Some(Appended::Raw(data) | Appended::Base64(data, _)), Some(start)) => {
                let end = offsets.iter().find(|&&o| o > start).map_or(data.len(), |&o| o.min(data.len()));
                Cow::Borrowed(&data[start.min(end)..end])
            }
            _ => Cow::Owned(da.text().into_owned()),
        }
    }

    fn count(&self, piece: &Node, key: &str, k: usize) -> Result<usize> {
        let v = piece.attr(key).ok_or_else(|| self.fail(format!("piece {k}: <Piece> has no {key}")))?;
        v.trim().parse().map_err(|_| self.fail(format!("piece {k}: {key}='{v}' is not a count")))
    }

    /// The piece's points, in f32 and (when f32 cannot hold them) f64.
    #[allow(clippy::type_complexity)]
    fn points(&self, piece: &Node, k: usize, n_points: usize) -> Result<(Vec<[f32; 3]>, Option<Vec<[f64; 3]>>)> {
        match piece.child("Points").and_then(|p| p.child("DataArray")) {
            Some(da) => {
                if ncomp(da) != Some(3) {
                    return Err(self.fail(format!("piece {k}: the points do not have 3 components")));
                }
                let a = self.array(da, n_points.saturating_mul(3))?;
                Ok((num::to_points(&a), num::to_points64(&a)))
            }
            None if n_points == 0 => Ok((Vec::new(), None)),
            None => Err(self.fail(format!("piece {k}: no <Points> array"))),
        }
    }

    /// The piece's `<Cells>` arrays: `None` for an empty piece without them (its point data,
    /// if any, is still read); the connectivity alone when every cell is a linear tet
    /// (checked on the file's arrays without converting them); else all three, the offsets
    /// never decreasing.
    fn read_cells(&self, piece: &Node, k: usize, n_cells: usize, n_points: usize) -> Result<Option<PieceCells>> {
        let cells_node = piece.child("Cells");
        if n_cells == 0 && cells_node.is_none() {
            return Ok(None);
        }
        let cell_array = |name: &str| {
            cells_node
                .and_then(|c| c.children_named("DataArray").find(|d| d.attr("Name") == Some(name)))
                .ok_or_else(|| self.fail(format!("piece {k}: no <Cells> array named '{name}'")))
        };
        let bad_value = |name: &str, arr: &Array, i: usize, why: &str| {
            self.fail(format!("DataArray '{name}': value {i} ({}) {why}", arr.show(i)))
        };
        let conn_ids = |n_conn: usize| {
            let arr = self.array(cell_array("connectivity")?, n_conn)?;
            num::to_ids(&arr, n_points).map_err(|i| {
                bad_value("connectivity", &arr, i, &format!("is not a point id (the piece has {n_points} points)"))
            })
        };
        let types_arr = self.array(cell_array("types")?, n_cells)?;
        let ends_arr = self.array(cell_array("offsets")?, n_cells)?;
        if cells::all_linear_tets(&types_arr, &ends_arr) {
            return Ok(Some(PieceCells::LinearTets(conn_ids(4 * n_cells)?)));
        }
        let types = num::map_ints(&types_arr, |v| u8::try_from(v).ok())
            .map_err(|i| bad_value("types", &types_arr, i, "is not a VTK cell type"))?;
        let ends = num::map_ints(&ends_arr, |v| u64::try_from(v).ok())
            .map_err(|i| bad_value("offsets", &ends_arr, i, "is not an offset"))?;
        if let Some(i) = ends.windows(2).position(|w| w[1] < w[0]) {
            return Err(bad_value("offsets", &ends_arr, i + 1, "is less than the one before it"));
        }
        let n_conn = usize::try_from(ends.last().copied().unwrap_or(0)).unwrap_or(usize::MAX);
        let polyhedra = match types.contains(&cells::POLYHEDRON) {
            true => Some(self.polyhedra(cells_node, &types, n_points, k)?),
            false => None,
        };
        Ok(Some(PieceCells::Any { types, ends, conn: conn_ids(n_conn)?, polyhedra }))
    }

    /// One piece as an [`AnyGrid`]: its cells of any type as they are, and all its data.
    fn any_piece(&self, piece: &Node, k: usize) -> Result<AnyGrid> {
        let n_points = self.count(piece, "NumberOfPoints", k)?;
        let n_cells = self.count(piece, "NumberOfCells", k)?;
        let (points, points64) = self.points(piece, k, n_points)?;
        let mut grid = AnyGrid { points, points64, ..AnyGrid::default() };
        match self.read_cells(piece, k, n_cells, n_points)? {
            None => {}
            Some(PieceCells::LinearTets(conn)) => {
                grid.types = vec![cells::TETRA; n_cells];
                grid.ends = (1..=n_cells as u64).map(|i| 4 * i).collect();
                grid.conn = conn;
            }
            Some(PieceCells::Any { types, ends, conn, .. }) => {
                if types.contains(&cells::POLYHEDRON) {
                    return Err(self.fail(format!("piece {k}: polyhedron cells (type 42) are not supported")));
                }
                (grid.types, grid.ends, grid.conn) = (types, ends, conn);
            }
        }
        let ex = cells::Extracted::all_tets(Vec::new());
        let part = self.data(piece, n_points, n_cells, ex, (Vec::new(), None), &|_: &str| true)?;
        grid.fields = part.raw.fields;
        Ok(grid)
    }

    fn piece(&self, piece: &Node, k: usize) -> Result<Part> {
        let n_points = self.count(piece, "NumberOfPoints", k)?;
        let n_cells = self.count(piece, "NumberOfCells", k)?;
        let (points, points64) = self.points(piece, k, n_points)?;
        let ex = match self.read_cells(piece, k, n_cells, n_points)? {
            None => cells::Extracted::all_tets(Vec::new()),
            Some(PieceCells::LinearTets(conn)) => cells::Extracted::all_tets(conn),
            Some(PieceCells::Any { types, ends, conn, polyhedra }) => {
                cells::extract(&types, &ends, &conn, polyhedra.as_ref())
                    .map_err(|m| self.fail(format!("piece {k}: {m}")))?
            }
        };
        if ex.unsupported {
            // The mesh is unusable: skip reading its fields.
            return Ok(Part { raw: RawMesh::default(), refused: ex.other, ids: GlobalIds::default() });
        }
        self.data(piece, n_points, n_cells, ex, (points, points64), &|_: &str| true)
    }

    /// The faces of the piece's polyhedra, in either of VTK's layouts (see
    /// [`cells::faces_from_stream`] and [`cells::faces_from_arrays`]; VTK 9.4 writes the
    /// second with snake-case names, and CamelCase ones are accepted too).
    fn polyhedra(&self, cells_node: Option<&Node>, types: &[u8], n_points: usize, k: usize) -> Result<PolyFaces> {
        let find = |names: &[&str]| {
            cells_node.and_then(|c| {
                c.children_named("DataArray").find(|d| d.attr("Name").is_some_and(|n| names.contains(&n)))
            })
        };
        let ints = |da: &Node, n: Option<usize>| -> Result<Vec<i64>> {
            let arr = match n {
                Some(n) => self.array(da, n)?,
                None => self.array_any(da)?,
            };
            let name = da.attr("Name").unwrap_or("(unnamed)").to_string();
            num::map_ints(&arr, Some)
                .map_err(|i| self.fail(format!("DataArray '{name}': value {i} ({}) is not an integer", arr.show(i))))
        };
        let fail = |m: String| self.fail(format!("piece {k}: {m}"));
        let new_layout = (
            find(&["face_connectivity", "FaceConnectivity"]),
            find(&["face_offsets", "FaceOffsets"]),
            find(&["polyhedron_to_faces", "PolyhedronToFaces"]),
            find(&["polyhedron_offsets", "PolyhedronOffsets"]),
        );
        if let (Some(conn), Some(face_ends), Some(cell_faces), Some(cell_ends)) = new_layout {
            let cell_ends = ints(cell_ends, Some(types.len()))?;
            let cell_faces = ints(cell_faces, None)?;
            let face_ends = ints(face_ends, None)?;
            let conn = ints(conn, None)?;
            return cells::faces_from_arrays(types, &conn, &face_ends, &cell_faces, &cell_ends, n_points).map_err(fail);
        }
        match find(&["faces"]) {
            Some(stream) => cells::faces_from_stream(types, &ints(stream, None)?, n_points).map_err(fail),
            None => Err(fail(
                "polyhedron cells (type 42) but no face arrays ('faces' and 'faceoffsets', or VTK 9.4's 'face_connectivity', 'face_offsets', 'polyhedron_to_faces' and 'polyhedron_offsets')".into(),
            )),
        }
    }

    /// The piece's point and cell data, and the piece made of them, its points and its cells.
    fn data(
        &self,
        piece: &Node,
        n_points: usize,
        n_cells: usize,
        ex: cells::Extracted,
        (points, points64): (Vec<[f32; 3]>, Option<Vec<[f64; 3]>>),
        wanted: &dyn Fn(&str) -> bool,
    ) -> Result<Part> {
        let bad_value = |name: &str, arr: &Array, i: usize, why: &str| {
            self.fail(format!("DataArray '{name}': value {i} ({}) {why}", arr.show(i)))
        };
        let mut fields = Vec::new();
        let mut ids = GlobalIds::default();
        for (section, location, n) in
            [("PointData", FieldLocation::Vertex, n_points), ("CellData", FieldLocation::Cell, n_cells)]
        {
            // Field name -> the array giving it: a second one would be shadowed by the first.
            let mut given = std::collections::HashMap::new();
            for da in piece.child(section).into_iter().flat_map(|s| s.children_named("DataArray")) {
                if matches!(da.attr("type"), Some("String" | "Bit")) {
                    continue; // no numeric field
                }
                let name = da.attr("Name").unwrap_or("(unnamed)");
                let nc = ncomp(da).ok_or_else(|| {
                    self.fail(format!("DataArray '{name}': NumberOfComponents is not a positive count"))
                })?;
                let field_name = |c: usize| if nc == 1 { name.to_string() } else { format!("{name}[{c}]") };
                for c in 0..nc {
                    if let Some(first) = given.insert(field_name(c), name) {
                        let what = if first == name {
                            format!("has two arrays named '{name}'")
                        } else {
                            format!("arrays '{first}' and '{name}' both give the field '{}'", field_name(c))
                        };
                        return Err(self.fail(format!("<{section}> {what}; array names must be unique")));
                    }
                }
                if !(0..nc).any(|c| wanted(&field_name(c))) {
                    continue; // not asked for: left undecoded
                }
                let arr = self.array(da, n.saturating_mul(nc))?;
                let named = piece.child(section).and_then(|c| c.attr("GlobalIds")) == Some(name);
                let is_ids = match location {
                    FieldLocation::Cell => GLOBAL_CELL_IDS.contains(&name) || named,
                    FieldLocation::Vertex => GLOBAL_POINT_IDS.contains(&name) || named,
                };
                if nc == 1 && is_ids && !arr.ty.is_float() {
                    let got = num::map_ints(&arr, |v| u64::try_from(v).ok())
                        .map_err(|i| bad_value(name, &arr, i, "is not a global id"))?;
                    match location {
                        FieldLocation::Cell => {
                            ids.cells = Some(match ex.kept.as_deref() {
                                None => got,
                                Some(k) => got.into_iter().zip(k).filter(|(_, &k)| k).map(|(v, _)| v).collect(),
                            })
                        }
                        FieldLocation::Vertex => ids.points = Some(got),
                    }
                }
                for c in 0..nc {
                    let mut values = num::component_f32(&arr, nc, c);
                    let mut values64 = num::component_f64(&arr, nc, c);
                    if location == FieldLocation::Cell {
                        values = cells::filter_cells(values, ex.kept.as_deref());
                        values64 = values64.map(|v| cells::filter_cells(v, ex.kept.as_deref()));
                    }
                    fields.push(Field { name: field_name(c), location, values, values64 });
                }
            }
        }
        Ok(Part { raw: ex.into_mesh(points, points64, fields), refused: BTreeMap::new(), ids })
    }
}

/// `NumberOfComponents` (default 1).
fn ncomp(da: &Node) -> Option<usize> {
    match da.attr("NumberOfComponents") {
        None => Some(1),
        Some(s) => s.trim().parse().ok().filter(|&n| n > 0),
    }
}

/// Joins the pieces into one mesh (their fields must agree: see [`join`]).
fn merge(mut parts: Vec<Part>, path: &Path) -> Result<RawMesh> {
    let mut refused = BTreeMap::new();
    for p in &parts {
        for (&code, &n) in &p.refused {
            *refused.entry(code).or_insert(0) += n;
        }
    }
    if !refused.is_empty() {
        return Err(cells::non_tet_error(path, &refused));
    }
    if parts.len() == 1 {
        return Ok(parts.pop().unwrap().raw);
    }
    join(parts.into_iter().map(|p| p.raw).collect(), path)
}

/// How many values a field at `location` has in `raw`: one per point or per volume cell.
fn n_at(raw: &RawMesh, location: FieldLocation) -> usize {
    match location {
        FieldLocation::Vertex => raw.points.len(),
        FieldLocation::Cell => raw.cells.as_ref().map_or(raw.tets.len(), CellBlock::len),
    }
}

/// The fields of `raw` at `location`, (name, location) in order.
fn names_at(raw: &RawMesh, location: FieldLocation) -> Vec<&str> {
    raw.fields.iter().filter(|f| f.location == location).map(|f| f.name.as_str()).collect()
}

/// The fields the pieces share: every piece with points must carry the same point arrays, and
/// every piece with cells the same cell arrays (a field missing in one would have no values
/// there: an error, never a field silently dropped). A piece with no points (or no cells)
/// carries no values there, so it may lack those arrays (an empty `<Piece/>`).
fn shared_fields(parts: &[RawMesh], path: &Path) -> Result<Vec<Field>> {
    let mut out = Vec::new();
    for location in [FieldLocation::Vertex, FieldLocation::Cell] {
        let mut with = parts.iter().enumerate().filter(|(_, p)| n_at(p, location) > 0);
        let Some((k0, first)) = with.next() else {
            // No piece has values here: keep the names the pieces declare (all empty).
            let names = parts.iter().map(|p| names_at(p, location)).max_by_key(Vec::len).unwrap_or_default();
            out.extend(names.into_iter().map(|n| Field::new(n.to_string(), location, Vec::new())));
            continue;
        };
        let names0 = names_at(first, location);
        for (k, p) in with {
            let names = names_at(p, location);
            if names != names0 {
                let what = if location == FieldLocation::Vertex { "point" } else { "cell" };
                return Err(Error::format(
                    path,
                    format!(
                        "<Piece> {k} has the {what} arrays [{}] but <Piece> {k0} has [{}]: every piece must carry the same arrays",
                        names.join(", "),
                        names0.join(", ")
                    ),
                ));
            }
        }
        out.extend(names0.into_iter().map(|n| Field::new(n.to_string(), location, Vec::new())));
    }
    Ok(out)
}

/// Joins meshes into one, point ids shifted, cells in order (the pieces of one file, or the
/// files of a partitioned mesh). Their fields must agree (see [`shared_fields`]).
pub(crate) fn join(mut parts: Vec<RawMesh>, path: &Path) -> Result<RawMesh> {
    if parts.len() == 1 {
        return Ok(parts.pop().unwrap());
    }
    let mut out = RawMesh { fields: shared_fields(&parts, path)?, ..RawMesh::default() };
    // When some piece has a cell block, every piece goes into one (linear tets as tet cells).
    let mut block = parts.iter().any(|p| p.cells.is_some()).then(CellBlock::default);
    for p in parts {
        let base = out.points.len() as u64;
        if base + p.points.len() as u64 > u32::MAX as u64 {
            return Err(Error::format(path, "the pieces hold more points than u32 ids can address"));
        }
        let base = base as u32;
        if let Some(block) = &mut block {
            match &p.cells {
                Some(c) => block.append(c, base),
                None => p.tets.iter().for_each(|t| block.push(CellType::tet(), &t.map(|i| i + base))),
            }
        }
        out.tets.extend(p.tets.iter().map(|t| t.map(|i| i + base)));
        // f64 coordinates for all pieces when some piece has them (f32 ones widen exactly).
        if p.points64.is_some() || out.points64.is_some() {
            let file = out.points64.get_or_insert_with(|| out.points.iter().map(|q| q.map(f64::from)).collect());
            match &p.points64 {
                Some(p64) => file.extend_from_slice(p64),
                None => file.extend(p.points.iter().map(|q| q.map(f64::from))),
            }
        }
        out.points.extend(p.points);
        out.higher_order = out.higher_order.max(p.higher_order);
        for f in &mut out.fields {
            // Absent only where the piece has no values at the field's location.
            if let Some(g) = p.fields.iter().find(|g| g.name == f.name && g.location == f.location) {
                f.extend_from(g);
            }
        }
    }
    if block.as_ref().is_some_and(|b| b.non_tet_counts().is_some()) {
        out.tets.clear();
    }
    out.cells = block;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_str(s: &str) -> Result<RawMesh> {
        parse(s.as_bytes(), Path::new("test.vtu"))
    }

    const ASCII_TWO_PIECES: &str = r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1">
 <UnstructuredGrid>
  <Piece NumberOfPoints="4" NumberOfCells="2">
   <PointData><DataArray type="Float64" Name="f" format="ascii">0 1 2 3</DataArray>
     <DataArray type="Int32" Name="v" NumberOfComponents="2" format="ascii">1 2 3 4 5 6 7 8</DataArray></PointData>
   <CellData><DataArray type="UInt8" Name="c" format="ascii">7 9</DataArray></CellData>
   <Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">0 0 0 1 0 0 0 1 0 0 0 1</DataArray></Points>
   <Cells>
    <DataArray type="Int32" Name="connectivity" format="ascii">0 1 2 3 3</DataArray>
    <DataArray type="Int32" Name="offsets" format="ascii">4 5</DataArray>
    <DataArray type="UInt8" Name="types" format="ascii">10 1</DataArray>
   </Cells>
  </Piece>
  <Piece NumberOfPoints="4" NumberOfCells="1">
   <PointData><DataArray type="Float64" Name="f" format="ascii">4 5 6 7</DataArray></PointData>
   <CellData><DataArray type="UInt8" Name="c" format="ascii">11</DataArray></CellData>
   <Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">0 0 0 2 0 0 0 2 0 0 0 2</DataArray></Points>
   <Cells>
    <DataArray type="Int64" Name="connectivity" format="ascii">0 1 2 3</DataArray>
    <DataArray type="Int64" Name="offsets" format="ascii">4</DataArray>
    <DataArray type="UInt8" Name="types" format="ascii">10</DataArray>
   </Cells>
  </Piece>
 </UnstructuredGrid>
</VTKFile>"#;

    #[test]
    fn ascii_pieces_and_components() {
        // "v" is only in the first piece: an error naming the file, not a field dropped.
        let e = parse_str(ASCII_TWO_PIECES).unwrap_err().to_string();
        assert!(e.starts_with("test.vtu") && e.contains("<Piece> 1 has the point arrays [f]"), "{e}");
        let src = ASCII_TWO_PIECES.replace(
            "<PointData><DataArray type=\"Float64\" Name=\"f\" format=\"ascii\">4 5 6 7</DataArray></PointData>",
            "<PointData><DataArray type=\"Float64\" Name=\"f\" format=\"ascii\">4 5 6 7</DataArray>\
             <DataArray type=\"Int32\" Name=\"v\" NumberOfComponents=\"2\" format=\"ascii\">0 0 0 0 0 0 0 0</DataArray></PointData>",
        );
        let m = parse_str(&src).unwrap();
        assert_eq!(m.points.len(), 8);
        assert_eq!(m.points[5], [2.0, 0.0, 0.0]);
        assert_eq!(m.tets, vec![[0, 1, 2, 3], [4, 5, 6, 7]]);
        let names: Vec<&str> = m.fields.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["f", "v[0]", "v[1]", "c"]);
        assert_eq!(m.fields[0].values, vec![0., 1., 2., 3., 4., 5., 6., 7.]);
        // The vertex cell's value is dropped with the vertex.
        assert_eq!(m.fields[3].values, vec![7., 11.]);

        let one = ASCII_TWO_PIECES.replacen("<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">", "<Skipped>", 1);
        let one = one.replacen("</Piece>\n </UnstructuredGrid>", "</Skipped>\n </UnstructuredGrid>", 1);
        let m = parse_str(&one).unwrap();
        let names: Vec<&str> = m.fields.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["f", "v[0]", "v[1]", "c"]);
        assert_eq!(m.fields[2].values, vec![2., 4., 6., 8.]);
    }

    /// Two arrays giving one field name at one location (the same name twice, or a vector
    /// `v` beside a scalar `v[0]`) are an error naming the file and the name; a point and a
    /// cell array of one name are two fields, as in VTK.
    #[test]
    fn arrays_of_one_name_are_refused() {
        let f = "<DataArray type=\"Float64\" Name=\"f\" format=\"ascii\">0 1 2 3</DataArray>";
        let first = ASCII_TWO_PIECES.replacen(f, &format!("{f}{f}"), 1);
        let v0 = "<DataArray type=\"Float64\" Name=\"v[0]\" format=\"ascii\">0 1 2 3</DataArray></PointData>";
        let clash = ASCII_TWO_PIECES.replacen("</PointData>", v0, 1);
        for (src, want) in
            [(first, "two arrays named 'f'"), (clash, "arrays 'v' and 'v[0]' both give the field 'v[0]'")]
        {
            let e = parse_str(&src).unwrap_err().to_string();
            assert!(e.starts_with("test.vtu") && e.contains("<PointData>") && e.contains(want), "{e}");
        }
        let c = "<CellData><DataArray type=\"UInt8\" Name=\"c\" format=\"ascii\">7 9</DataArray>";
        let point_and_cell = ASCII_TWO_PIECES.replacen(c, &c.replace("\"c\"", "\"f\""), 1);
        let point_and_cell = point_and_cell.replace("Name=\"c\" format=\"ascii\">11", "Name=\"f\" format=\"ascii\">11");
        let point_and_cell = point_and_cell.replace(
            "<PointData><DataArray type=\"Float64\" Name=\"f\" format=\"ascii\">4 5 6 7</DataArray></PointData>",
            "<PointData><DataArray type=\"Float64\" Name=\"f\" format=\"ascii\">4 5 6 7</DataArray>\
             <DataArray type=\"Int32\" Name=\"v\" NumberOfComponents=\"2\" format=\"ascii\">0 0 0 0 0 0 0 0</DataArray></PointData>",
        );
        let m = parse_str(&point_and_cell).unwrap();
        let names: Vec<_> = m.fields.iter().map(|f| (f.name.as_str(), f.location)).collect();
        assert!(names.contains(&("f", FieldLocation::Vertex)) && names.contains(&("f", FieldLocation::Cell)));
    }

    /// Issue 29 item 14: an empty second `<Piece>` (with or without its arrays) keeps the
    /// first piece's fields.
    #[test]
    fn empty_pieces_keep_the_fields() {
        let first_piece_end = ASCII_TWO_PIECES.find("</Piece>").unwrap() + "</Piece>".len();
        let first = &ASCII_TWO_PIECES[..first_piece_end];
        let end = "\n </UnstructuredGrid>\n</VTKFile>";
        let empties = [
            "<Piece NumberOfPoints=\"0\" NumberOfCells=\"0\"/>".to_string(),
            "<Piece NumberOfPoints=\"0\" NumberOfCells=\"0\"><PointData/><CellData/><Points/><Cells>\
             <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\"></DataArray>\
             <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\"></DataArray>\
             <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\"></DataArray></Cells></Piece>"
                .to_string(),
        ];
        for empty in empties {
            let (head, piece) = first.split_at(first.find("<Piece").unwrap());
            for src in [format!("{first}{empty}{end}"), format!("{head}{empty}{piece}{end}")] {
                let m = parse_str(&src).unwrap_or_else(|e| panic!("{e}\n{src}"));
                let names: Vec<&str> = m.fields.iter().map(|f| f.name.as_str()).collect();
                assert!(names.starts_with(&["f"]) && names.contains(&"c"), "{names:?}");
                assert_eq!(m.fields[0].values.len(), m.points.len());
            }
        }
    }

    #[test]
    fn clear_errors() {
        let cases = [
            (ASCII_TWO_PIECES.replace("0 1 2 3 3", "0 1 2 9 3"), "connectivity': value 3 (9) is not a point id"),
            (ASCII_TWO_PIECES.replace("10 1<", "10 12<"), "hexahedron"),
            (ASCII_TWO_PIECES.replace("0 1 2 3 3", "0 1 2 3"), "has 4 values, expected 5"),
            (ASCII_TWO_PIECES.replace("\"Float64\" Name=\"f\"", "\"Float65\" Name=\"f\""), "'Float65'"),
            (ASCII_TWO_PIECES.replace("UnstructuredGrid\"", "PolyData\""), "PolyData"),
            (ASCII_TWO_PIECES.replace("4 5<", "4 x<"), "'x'"),
            (ASCII_TWO_PIECES.replace("NumberOfCells=\"2\"", "NumberOfCells=\"-2\""), "not a count"),
            (ASCII_TWO_PIECES.replace("</VTKFile>", ""), "truncated"),
            (ASCII_TWO_PIECES.replace("version=\"0.1\"", "compressor=\"vtkLZ4DataCompressor\""), "LZ4"),
        ];
        for (src, want) in cases {
            let e = parse_str(&src).unwrap_err().to_string();
            assert!(e.contains(want) && e.starts_with("test.vtu"), "{e:?} should say {want:?}");
        }
    }

    /// A hex, a wedge, a pyramid, a quadratic tet, a tet and a triangle, over two pieces: every
    /// volume cell comes back with all its nodes, in file order, and the cell field with it.
    const ASCII_MIXED: &str = r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1">
 <UnstructuredGrid>
  <Piece NumberOfPoints="12" NumberOfCells="4">
   <CellData><DataArray type="Float32" Name="c" format="ascii">0 1 2 3</DataArray></CellData>
   <Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">
     0 0 0  1 0 0  1 1 0  0 1 0  0 0 1  1 0 1  1 1 1  0 1 1  0.5 0.5 2  2 0 0  2 1 0  2 0 1
   </DataArray></Points>
   <Cells>
    <DataArray type="Int32" Name="connectivity" format="ascii">0 1 2 3 4 5 6 7  1 9 2 5 11 6  4 5 6 7 8  0 1 3</DataArray>
    <DataArray type="Int32" Name="offsets" format="ascii">8 14 19 22</DataArray>
    <DataArray type="UInt8" Name="types" format="ascii">12 13 14 5</DataArray>
   </Cells>
  </Piece>
  <Piece NumberOfPoints="10" NumberOfCells="2">
   <CellData><DataArray type="Float32" Name="c" format="ascii">4 5</DataArray></CellData>
   <Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">
     0 0 0  1 0 0  0 1 0  0 0 1  0.5 0 0  0.5 0.5 0  0 0.5 0  0 0 0.5  0.5 0 0.5  0 0.5 0.5
   </DataArray></Points>
   <Cells>
    <DataArray type="Int32" Name="connectivity" format="ascii">0 1 2 3 4 5 6 7 8 9  0 1 2 3</DataArray>
    <DataArray type="Int32" Name="offsets" format="ascii">10 14</DataArray>
    <DataArray type="UInt8" Name="types" format="ascii">24 10</DataArray>
   </Cells>
  </Piece>
 </UnstructuredGrid>
</VTKFile>"#;

    #[test]
    fn mixed_cells_keep_every_node() {
        let m = parse_str(ASCII_MIXED).unwrap();
        let cells = m.cells.as_ref().expect("a block of cells");
        let names: Vec<&str> = cells.types.iter().map(|t| t.def().name()).collect();
        assert_eq!(names, ["hexahedron", "wedge", "pyramid", "quadratic tetra", "tetra"]);
        assert_eq!(cells.nodes(1), &[1, 9, 2, 5, 11, 6]);
        assert_eq!(cells.nodes(3), &(12..22).collect::<Vec<u32>>()[..], "second piece's ids are shifted");
        assert_eq!(cells.corners(3), &[12, 13, 14, 15]);
        assert_eq!(cells.nodes(4), &[12, 13, 14, 15]);
        assert!(m.tets.is_empty(), "tets are for tet meshes");
        assert_eq!(m.higher_order, Some(2));
        assert_eq!(m.fields[0].values, vec![0., 1., 2., 4., 5.], "the triangle's value is dropped");
        // The mesh model decomposes them, counted by type.
        let m = tetloc_core::Mesh::new(m, "test.vtu").unwrap();
        assert_eq!(m.n_cells(), 5);
        assert_eq!(m.info.cell_types.values().sum::<usize>(), 5);
        assert_eq!(m.n_tets(), 6 + 3 + 2 + 1 + 1);
    }

    /// The shared data's meshes with cells other than tets, counted independently (the files'
    /// `.mesh.json` and the data README).
    #[test]
    fn mixed_files_read_every_cell() {
        use crate::test_support::require_data;
        let Some(dir) = require_data("mixed_files_read_every_cell") else { return };
        let cases: [(&str, &[(&str, usize)]); 6] = [
            ("mixed/hexwarp.zlib.vtu", &[("hexahedron", 9424)]),
            ("mixed/prisms.zlib.vtu", &[("wedge", 20916)]),
            ("mixed/hybrid.zlib.vtu", &[("tetra", 15273), ("hexahedron", 1536), ("wedge", 4420), ("pyramid", 464)]),
            ("real/can.vtu", &[("hexahedron", 4800)]),
            ("real/notch_disp.vtu", &[("quadratic hexahedron", 2188), ("quadratic wedge", 4)]),
            ("real/quadratic_tetra.vtu", &[("quadratic tetra", 96)]),
        ];
        for (file, want) in cases {
            let path = dir.join(file);
            let m = read(&path).unwrap_or_else(|e| panic!("{e}"));
            let cells = m.cells.as_ref().unwrap_or_else(|| panic!("{file}: no cells"));
            for &(name, n) in want {
                assert_eq!(cells.types.iter().filter(|t| t.def().name() == name).count(), n, "{file}: {name}");
            }
            assert_eq!(cells.len(), want.iter().map(|w| w.1).sum::<usize>(), "{file}");
            for f in m.fields.iter().filter(|f| f.location == FieldLocation::Cell) {
                assert_eq!(f.values.len(), cells.len(), "{file}: cell field '{}'", f.name);
            }
            assert!(cells.conn.iter().all(|&i| (i as usize) < m.points.len()));
        }
        // hybrid's file order: wedges, hexes, tets, pyramids.
        let m = read(&dir.join("mixed/hybrid.zlib.vtu")).unwrap();
        let names: Vec<&str> = m.cells.unwrap().types.iter().map(|t| t.def().name()).collect();
        let mut runs = names.clone();
        runs.dedup();
        assert_eq!(runs, ["wedge", "hexahedron", "tetra", "pyramid"]);
        // Linear tets only: the fast path, no block.
        assert!(read(&dir.join("torus_s.vtu")).unwrap().cells.is_none());
    }

    #[test]
    fn gigantic_counts_fail_fast() {
        let src = ASCII_TWO_PIECES.replacen("NumberOfPoints=\"4\"", "NumberOfPoints=\"1000000000000\"", 1);
        let t = std::time::Instant::now();
        assert!(parse_str(&src).is_err());
        let src = ASCII_TWO_PIECES.replacen("NumberOfPoints=\"4\"", "NumberOfPoints=\"18446744073709551615\"", 1);
        assert!(parse_str(&src).is_err());
        assert!(t.elapsed().as_secs_f64() < 0.5);
    }
}
