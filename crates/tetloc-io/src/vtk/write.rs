//! VTK XML writers: a mesh with its fields (`.vtu`), and a point set with the located tet
//! ids, values and `vtkValidPointMask` (`.vtu` with vertex cells, or `.vtp` polydata with
//! verts), with appended raw data (UInt64 block headers, optionally zlib-compressed),
//! readable by ParaView and VTK. Files are written atomically (see [`crate::output`]).
//!
//! Uncompressed arrays stream through a `BufWriter` in chunks, so writing a large mesh needs
//! no copy of it; compressed ones are compressed first, a group of parallel blocks at a time,
//! into anonymous files next to the output (their sizes go in the XML header, which is
//! written before them): memory stays bounded for any size.

use super::blocks;
use super::cells;
use super::num::NumType;
use crate::arrays::{Values, VALID_MASK};
use crate::output::write_atomically;
use std::io::Write;
use std::ops::Range;
use std::path::Path;
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::{FieldLocation, Mesh};

/// Block size of compressed arrays (VTK's own default is 32 KiB; larger blocks compress a
/// little better and VTK reads any size).
const ZLIB_BLOCK: usize = 1 << 18;

/// Writes a mesh: its points in the file's coordinates (Float32, or Float64 where f32
/// cannot hold them), Int32 connectivity and offsets (Int64 when the mesh is too large for
/// Int32), VTK_TETRA types (or the higher-order tets' own type, with all their nodes), and
/// every field as a PointData or CellData array, Float32 or Float64 as its data (the runs
/// `NAME[0]` … `NAME[k-1]` as one k-component array `NAME`). Tets are written positively
/// oriented in VTK's convention.
pub fn write_mesh_vtu(path: &Path, mesh: &Mesh, zlib: bool) -> Result<()> {
    write_mesh(path, mesh, &[], zlib, false)
}

/// [`write_mesh_vtu`] with more point data: `extra` arrays (one tuple per vertex) are written
/// after the mesh's own, and replace a mesh array of the same name.
pub fn write_mesh_with(path: &Path, mesh: &Mesh, extra: &[NamedArray], zlib: bool) -> Result<()> {
    write_mesh(path, mesh, extra, zlib, false)
}

/// Values of an array to write.
#[derive(Clone, Copy, Debug)]
pub enum ArrayData<'a> {
    F32(&'a [f32]),
    F64(&'a [f64]),
    I32(&'a [i32]),
    I64(&'a [i64]),
    I8(&'a [i8]),
    U8(&'a [u8]),
}

/// Sampled values as a VTK array's data (Float32 or Float64).
impl<'a> From<Values<'a>> for ArrayData<'a> {
    fn from(v: Values<'a>) -> ArrayData<'a> {
        match v {
            Values::F32(v) => ArrayData::F32(v),
            Values::F64(v) => ArrayData::F64(v),
        }
    }
}

/// A named array of `n_components` values per tuple, tuple after tuple.
#[derive(Clone, Debug)]
pub struct NamedArray<'a> {
    pub name: String,
    pub n_components: usize,
    pub data: ArrayData<'a>,
}

impl<'a> NamedArray<'a> {
    fn n_tuples(&self) -> usize {
        let n = match self.data {
            ArrayData::F32(v) => v.len(),
            ArrayData::F64(v) => v.len(),
            ArrayData::I32(v) => v.len(),
            ArrayData::I64(v) => v.len(),
            ArrayData::I8(v) => v.len(),
            ArrayData::U8(v) => v.len(),
        };
        n / self.n_components.max(1)
    }

    fn out(&self) -> OutArray<'a> {
        let (name, k) = (self.name.as_str(), self.n_components);
        match self.data {
            ArrayData::F32(v) => OutArray::floats(name, k, v),
            ArrayData::F64(v) => OutArray::slice(name, NumType::F64, k, v),
            ArrayData::I32(v) => OutArray::slice(name, NumType::I32, k, v),
            ArrayData::I64(v) => OutArray::slice(name, NumType::I64, k, v),
            ArrayData::I8(v) => OutArray::slice(name, NumType::I8, k, v),
            ArrayData::U8(v) => OutArray::slice(name, NumType::U8, k, v),
        }
    }

    /// An error unless the array has `n` whole tuples.
    fn check(&self, n: usize, what: &str) -> Result<()> {
        if self.n_components == 0 || self.n_tuples() != n || self.n_tuples() * self.n_components != self.len() {
            return Err(Error::Invalid(format!(
                "array '{}' has {} values of {} components, but there are {n} {what}",
                self.name,
                self.len(),
                self.n_components
            )));
        }
        Ok(())
    }

    fn num_type(&self) -> NumType {
        match self.data {
            ArrayData::F32(_) => NumType::F32,
            ArrayData::F64(_) => NumType::F64,
            ArrayData::I32(_) => NumType::I32,
            ArrayData::I64(_) => NumType::I64,
            ArrayData::I8(_) => NumType::I8,
            ArrayData::U8(_) => NumType::U8,
        }
    }

    /// The values as native-endian bytes.
    fn bytes(&self) -> &[u8] {
        match self.data {
            ArrayData::F32(v) => bytemuck::cast_slice(v),
            ArrayData::F64(v) => bytemuck::cast_slice(v),
            ArrayData::I32(v) => bytemuck::cast_slice(v),
            ArrayData::I64(v) => bytemuck::cast_slice(v),
            ArrayData::I8(v) => bytemuck::cast_slice(v),
            ArrayData::U8(v) => v,
        }
    }

    fn len(&self) -> usize {
        match self.data {
            ArrayData::F32(v) => v.len(),
            ArrayData::F64(v) => v.len(),
            ArrayData::I32(v) => v.len(),
            ArrayData::I64(v) => v.len(),
            ArrayData::I8(v) => v.len(),
            ArrayData::U8(v) => v.len(),
        }
    }
}

/// The mesh's fields as arrays: each run `NAME[0]` … `NAME[k-1]` interleaved into one;
/// Float64 when some component has f64 data (the file's values, kept), else Float32. Point
/// fields named in `skip_points` and cell fields named in `skip_cells` are left out (point
/// data and cell data are two sets of names, as in VTK).
fn field_arrays<'a>(
    all: &'a [tetloc_core::mesh::Field],
    skip_points: &[&str],
    skip_cells: &[&str],
) -> (Vec<OutArray<'a>>, Vec<OutArray<'a>>) {
    let (mut point_data, mut cell_data) = (Vec::new(), Vec::new());
    for g in tetloc_core::mesh::field_groups::groups_of(all) {
        let skip = match g.location {
            FieldLocation::Vertex => skip_points,
            FieldLocation::Cell => skip_cells,
        };
        if skip.contains(&g.name.as_str()) {
            continue;
        }
        let fields: Vec<&'a tetloc_core::mesh::Field> =
            g.components.iter().filter_map(|c| all.iter().find(|f| &f.name == c && f.location == g.location)).collect();
        let k = fields.len();
        let n = fields.first().map_or(0, |f| f.values.len());
        let arr = if fields.iter().any(|f| f.values64.is_some()) {
            OutArray::new(&g.name, NumType::F64, k, k * n, move |r, out| {
                r.for_each(|i| out.extend_from_slice(&fields[i % k].value64(i / k).to_ne_bytes()))
            })
        } else if k == 1 {
            OutArray::floats(&g.name, 1, &fields[0].values)
        } else {
            OutArray::new(&g.name, NumType::F32, k, k * n, move |r, out| {
                r.for_each(|i| out.extend_from_slice(&fields[i % k].values[i / k].to_ne_bytes()))
            })
        };
        match g.location {
            FieldLocation::Vertex => point_data.push(arr),
            FieldLocation::Cell => cell_data.push(arr),
        }
    }
    (point_data, cell_data)
}

/// [`write_mesh_with`] with `wide_ids` forcing Int64 connectivity and offsets (as VTK writes).
pub(crate) fn write_mesh(path: &Path, mesh: &Mesh, extra: &[NamedArray], zlib: bool, wide_ids: bool) -> Result<()> {
    write_mesh_full(path, mesh, extra, &[], zlib, wide_ids)
}

/// [`write_mesh_with`] with more cell data too: `cell_extra` arrays (one tuple per cell, in
/// the mesh's cell order) after the mesh's own cell fields; a piece of a partitioned mesh
/// carries its `GlobalCellIds` this way.
pub fn write_mesh_with_cell_data(
    path: &Path,
    mesh: &Mesh,
    extra: &[NamedArray],
    cell_extra: &[NamedArray],
    zlib: bool,
) -> Result<()> {
    write_mesh_full(path, mesh, extra, cell_extra, zlib, false)
}

fn write_mesh_full(
    path: &Path,
    mesh: &Mesh,
    extra: &[NamedArray],
    cell_extra: &[NamedArray],
    zlib: bool,
    wide_ids: bool,
) -> Result<()> {
    if let Some(cells) = &mesh.cells {
        return write_cells(path, mesh, cells, extra, cell_extra, zlib, wide_ids);
    }
    let n_tets = mesh.tets.len();
    // Nodes per tet, and the VTK type: all of one type.
    let (per_tet, vtk_type) = match &mesh.tet_nodes {
        Some(n) => (4 + n.n_extra(), n.cell_type().def().vtk_type()),
        None => (4, cells::TETRA),
    };
    let wide = wide_ids || (per_tet * n_tets).max(mesh.points.len()) as u64 > i32::MAX as u64;
    let id_type = if wide { NumType::I64 } else { NumType::I32 };
    let (tets, nodes) = (&mesh.tets, &mesh.tet_nodes);

    let (point_data, cell_data) = data_arrays(mesh, extra, cell_extra)?;
    let grid = Grid {
        kind: Kind::Unstructured,
        n_points: mesh.points.len(),
        n_cells: n_tets,
        point_data,
        cell_data,
        points: points_array(mesh),
        // Canonical tets are right-handed, as VTK expects: written as they are (higher-order
        // nodes are stored in VTK's order over the canonical corners).
        // (Chunks hold whole tets: they start at multiples of CHUNK, a multiple of 4.)
        connectivity: OutArray::new("connectivity", id_type, 1, per_tet * n_tets, move |r, out| match nodes {
            Some(nodes) => {
                for i in r {
                    let (t, k) = (i / per_tet, i % per_tet);
                    let id = if k < 4 { tets[t][k] } else { nodes.extra(t)[k - 4] };
                    push_id(out, u64::from(id), wide);
                }
            }
            None => {
                let tets = &tets[r.start / 4..r.end / 4];
                if wide {
                    tets.iter().for_each(|t| out.extend_from_slice(bytemuck::bytes_of(&t.map(i64::from))));
                } else {
                    // Ids below 2^31 (checked above): their u32 bytes are their i32 bytes.
                    out.extend_from_slice(bytemuck::cast_slice(tets));
                }
            }
        }),
        offsets: OutArray::new("offsets", id_type, 1, n_tets, move |r, out| {
            r.for_each(|i| push_id(out, (per_tet * (i + 1)) as u64, wide))
        }),
        types: Some(OutArray::new("types", NumType::U8, 1, n_tets, move |r, out| {
            out.resize(out.len() + r.len(), vtk_type)
        })),
        faces: Vec::new(),
    };
    grid.write(path, zlib)
}

/// The mesh's vertices as the file had them: Float32 when the working copy is the file's data,
/// else Float64 in the file's coordinates (never the centred working frame).
fn points_array(mesh: &Mesh) -> OutArray<'_> {
    if !mesh.wants_f64_points() {
        return OutArray::floats("Points", 3, bytemuck::cast_slice(&mesh.points));
    }
    OutArray::new("Points", NumType::F64, 3, 3 * mesh.points.len(), move |r, out| {
        // A chunk may start inside a point: one coordinate at a time.
        r.for_each(|j| out.extend_from_slice(&mesh.vertex64((j / 3) as u32)[j % 3].to_le_bytes()))
    })
}

/// The VTK type name of [`points_array`]'s values.
pub(crate) fn points_type(mesh: &Mesh) -> &'static str {
    if mesh.wants_f64_points() {
        "Float64"
    } else {
        "Float32"
    }
}

/// The mesh's fields and `extra` (per vertex, replacing fields of the same name) as the
/// point and cell data arrays of a written mesh.
fn data_arrays<'a>(
    mesh: &'a Mesh,
    extra: &'a [NamedArray],
    cell_extra: &'a [NamedArray],
) -> Result<(Vec<OutArray<'a>>, Vec<OutArray<'a>>)> {
    for a in extra {
        a.check(mesh.points.len(), "vertices")?;
    }
    for a in cell_extra {
        a.check(mesh.n_cells(), "cells")?;
    }
    // An extra point array replaces a point field of its name; a cell field of that name stays
    // (vtkResampleWithDataSet keeps the target's cell array beside the probed point array).
    let names = |arrays: &'a [NamedArray]| arrays.iter().map(|a| a.name.as_str()).collect::<Vec<_>>();
    let (mut point_data, mut cell_data) = field_arrays(&mesh.fields, &names(extra), &names(cell_extra));
    point_data.extend(extra.iter().map(NamedArray::out));
    cell_data.extend(cell_extra.iter().map(NamedArray::out));
    Ok((point_data, cell_data))
}

/// [`write_mesh`] for a mixed mesh: its cells as the file had them (all their nodes, VTK's
/// types), not their decomposition.
fn write_cells(
    path: &Path,
    mesh: &Mesh,
    cells: &tetloc_core::mesh::Cells,
    extra: &[NamedArray],
    cell_extra: &[NamedArray],
    zlib: bool,
    wide_ids: bool,
) -> Result<()> {
    let block = &cells.block;
    let wide = wide_ids || (block.conn.len()).max(mesh.points.len()) as u64 > i32::MAX as u64;
    let id_type = if wide { NumType::I64 } else { NumType::I32 };
    let (point_data, cell_data) = data_arrays(mesh, extra, cell_extra)?;
    let grid = Grid {
        kind: Kind::Unstructured,
        n_points: mesh.points.len(),
        n_cells: block.len(),
        point_data,
        cell_data,
        points: points_array(mesh),
        connectivity: OutArray::new("connectivity", id_type, 1, block.conn.len(), move |r, out| {
            block.conn[r].iter().for_each(|&id| push_id(out, u64::from(id), wide))
        }),
        offsets: OutArray::new("offsets", id_type, 1, block.len(), move |r, out| {
            block.ends[r].iter().for_each(|&e| push_id(out, e, wide))
        }),
        types: Some(OutArray::new("types", NumType::U8, 1, block.len(), move |r, out| {
            out.extend(block.types[r].iter().map(|t| t.def().vtk_type()))
        })),
        faces: polyhedron_arrays(block),
    };
    grid.write(path, zlib)
}

/// A block's polyhedra as VTK 9.4 writes them: every face's points (`face_connectivity`, ends
/// in `face_offsets`), each cell's faces (`polyhedron_to_faces`, ends per cell in
/// `polyhedron_offsets`, none for the other cells). Empty without polyhedra. (The centroids
/// tetloc added are written as points too, unused by any cell.)
fn polyhedron_arrays(block: &tetloc_core::cell::CellBlock) -> Vec<OutArray<'_>> {
    let p = &block.polyhedra;
    if p.is_empty() {
        return Vec::new();
    }
    let mut cell_ends = Vec::with_capacity(block.len());
    let (mut k, mut end) = (0, 0u64);
    for c in 0..block.len() {
        if p.cells.get(k) == Some(&(c as u32)) {
            end = p.cell_ends[k];
            k += 1;
        }
        cell_ends.push(end);
    }
    let ids = |name: &str, v: &[u64]| -> OutArray<'static> {
        let v: Vec<i64> = v.iter().map(|&x| x as i64).collect();
        OutArray::new(name, NumType::I64, 1, v.len(), move |r, out| out.extend_from_slice(bytemuck::cast_slice(&v[r])))
    };
    let n_faces = p.face_ends.len() as u64;
    vec![
        ids("face_connectivity", &p.points.iter().map(|&x| u64::from(x)).collect::<Vec<_>>()),
        ids("face_offsets", &p.face_ends),
        ids("polyhedron_to_faces", &(0..n_faces).collect::<Vec<_>>()),
        ids("polyhedron_offsets", &cell_ends),
    ]
}

/// Writes a grid read by [`super::vtu::read_any`]: its points, cells and data as they were,
/// and the `extra` point arrays (replacing point data of their names; cell data stays).
pub fn write_any_grid(path: &Path, grid: &super::vtu::AnyGrid, extra: &[NamedArray], zlib: bool) -> Result<()> {
    let n_points = grid.points.len();
    for a in extra {
        a.check(n_points, "points")?;
    }
    let names: Vec<&str> = extra.iter().map(|a| a.name.as_str()).collect();
    let (mut point_data, cell_data) = field_arrays(&grid.fields, &names, &[]);
    point_data.extend(extra.iter().map(NamedArray::out));
    let wide = grid.conn.len().max(n_points) as u64 > i32::MAX as u64;
    let id_type = if wide { NumType::I64 } else { NumType::I32 };
    let points = match &grid.points64 {
        Some(p) => Coords::F64(p),
        None => Coords::F32(&grid.points),
    };
    let out = Grid {
        kind: Kind::Unstructured,
        n_points,
        n_cells: grid.types.len(),
        point_data,
        cell_data,
        points: points.array(),
        connectivity: OutArray::new("connectivity", id_type, 1, grid.conn.len(), move |r, out| {
            grid.conn[r].iter().for_each(|&id| push_id(out, u64::from(id), wide))
        }),
        offsets: OutArray::new("offsets", id_type, 1, grid.ends.len(), move |r, out| {
            grid.ends[r].iter().for_each(|&e| push_id(out, e, wide))
        }),
        types: Some(OutArray::slice("types", NumType::U8, 1, &grid.types)),
        faces: Vec::new(),
    };
    out.write(path, zlib)
}

/// Writes a point set as an unstructured grid: one VTK_VERTEX cell per point, point data
/// `tet_id` (Int32, -1 for points without an answer), the named values (Float32) if given,
/// and `vtkValidPointMask` (UInt8, 1 where a point got an answer).
pub fn write_points_vtu(path: &Path, points: Coords, ids: &[i32], values: Option<(&str, Values)>) -> Result<()> {
    point_set(Kind::Unstructured, points, ids, values)?.write(path, false)
}

/// [`write_points_vtu`] as VTK polydata (`.vtp`): the same arrays, one vertex (`Verts`) per point.
pub fn write_points_vtp(path: &Path, points: Coords, ids: &[i32], values: Option<(&str, Values)>) -> Result<()> {
    point_set(Kind::PolyVerts, points, ids, values)?.write(path, false)
}

fn point_set<'a>(
    kind: Kind,
    points: Coords<'a>,
    ids: &'a [i32],
    values: Option<(&str, Values<'a>)>,
) -> Result<Grid<'a>> {
    let n = points.len();
    if ids.len() != n {
        return Err(Error::Invalid(format!("{} points but {} tet ids", n, ids.len())));
    }
    let mut point_data = vec![OutArray::new("tet_id", NumType::I32, 1, n, |r, out| {
        out.extend_from_slice(bytemuck::cast_slice(&ids[r]))
    })];
    if let Some((name, v)) = values {
        if v.len() != n {
            return Err(Error::Invalid(format!("{} points but {} values of '{name}'", n, v.len())));
        }
        crate::arrays::check_value_name(name)?;
        point_data.push(NamedArray { name: name.into(), n_components: 1, data: v.into() }.out());
    }
    point_data.push(OutArray::new(VALID_MASK, NumType::U8, 1, n, |r, out| {
        out.extend(ids[r].iter().map(|&i| u8::from(i >= 0)))
    }));
    let mut grid = point_cloud(kind, points);
    grid.point_data = point_data;
    Ok(grid)
}

/// A point set's coordinates at the precision they are written in (Float32 or Float64): f64
/// where f32 cannot hold the points (far from the origin), so that ParaView shows them where
/// they are.
#[derive(Clone, Copy, Debug)]
pub enum Coords<'a> {
    F32(&'a [[f32; 3]]),
    F64(&'a [[f64; 3]]),
}

impl<'a> Coords<'a> {
    pub fn len(&self) -> usize {
        match self {
            Coords::F32(p) => p.len(),
            Coords::F64(p) => p.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// f64 where some point does not round to f32 exactly, else f32.
    pub fn of(points64: &'a [[f64; 3]], points32: &'a [[f32; 3]]) -> Coords<'a> {
        if crate::needs_f64(points64) {
            Coords::F64(points64)
        } else {
            Coords::F32(points32)
        }
    }

    fn array(self) -> OutArray<'a> {
        match self {
            Coords::F32(p) => OutArray::floats("Points", 3, bytemuck::cast_slice(p)),
            Coords::F64(p) => OutArray::slice("Points", NumType::F64, 3, bytemuck::cast_slice::<_, f64>(p)),
        }
    }
}

/// Points, one vertex cell each, and no data yet.
fn point_cloud(kind: Kind, points: Coords<'_>) -> Grid<'_> {
    let n = points.len();
    let wide = n as u64 > i32::MAX as u64;
    let id_type = if wide { NumType::I64 } else { NumType::I32 };
    Grid {
        kind,
        n_points: n,
        n_cells: n,
        point_data: Vec::new(),
        cell_data: Vec::new(),
        points: points.array(),
        connectivity: OutArray::new("connectivity", id_type, 1, n, move |r, out| {
            r.for_each(|i| push_id(out, i as u64, wide))
        }),
        offsets: OutArray::new("offsets", id_type, 1, n, move |r, out| {
            r.for_each(|i| push_id(out, i as u64 + 1, wide))
        }),
        types: (kind == Kind::Unstructured).then(|| {
            OutArray::new("types", NumType::U8, 1, n, |r, out| out.resize(out.len() + r.len(), cells::VERTEX))
        }),
        faces: Vec::new(),
    }
}

/// Writes a point set with any arrays of point data, as `.vtu` (one VTK_VERTEX cell per
/// point) or `.vtp` (polydata, one vertex per point), by the extension of `path`.
pub fn write_point_set(path: &Path, points: Coords, arrays: &[NamedArray], zlib: bool) -> Result<()> {
    let kind = match crate::output::extension(path).as_str() {
        "vtu" => Kind::Unstructured,
        "vtp" => Kind::PolyVerts,
        _ => return Err(Error::format(path, "a point set is written as .vtu or .vtp")),
    };
    for a in arrays {
        a.check(points.len(), "points")?;
    }
    let mut grid = point_cloud(kind, points);
    grid.point_data = arrays.iter().map(NamedArray::out).collect();
    grid.write(path, zlib)
}

/// Polylines written as they are made, so that an output of any size needs memory for one
/// batch only: each batch's points and arrays are appended to temporary files in the output's
/// directory (only the line ends stay in memory, 8 B a line), and [`PolylineWriter::finish`]
/// writes the `.vtp`, header first, atomically (complete or absent; the temporary files go
/// with the writer). Every batch has the same arrays; lines are numbered across batches.
pub struct PolylineWriter {
    path: std::path::PathBuf,
    points: std::io::BufWriter<std::fs::File>,
    ends: Vec<usize>,
    point_data: Vec<Spilled>,
    cell_data: Vec<Spilled>,
}

/// One array of a [`PolylineWriter`], in its temporary file.
struct Spilled {
    name: String,
    ty: NumType,
    ncomp: usize,
    n_values: usize,
    file: std::io::BufWriter<std::fs::File>,
}

impl PolylineWriter {
    /// A writer of `path` (nothing is written there before `finish`).
    pub fn new(path: &Path) -> Result<PolylineWriter> {
        let path = path.to_path_buf();
        let points = spill_file(&path)?;
        Ok(PolylineWriter { path, points, ends: Vec::new(), point_data: Vec::new(), cell_data: Vec::new() })
    }

    /// Points so far.
    pub fn n_points(&self) -> usize {
        self.ends.last().copied().unwrap_or(0)
    }

    /// Lines so far.
    pub fn n_lines(&self) -> usize {
        self.ends.len()
    }

    /// Appends lines: line `i` of the batch is its points `ends[i-1]..ends[i]`, `point_data`
    /// has a tuple per point and `cell_data` one per line, the same arrays as every batch.
    pub fn push(
        &mut self,
        points: &[[f32; 3]],
        ends: &[usize],
        point_data: &[NamedArray],
        cell_data: &[NamedArray],
    ) -> Result<()> {
        if ends.windows(2).any(|w| w[0] > w[1]) || ends.last().copied().unwrap_or(0) != points.len() {
            return Err(Error::Invalid(format!("{} points do not split into lines ending at {ends:?}", points.len())));
        }
        for a in point_data {
            a.check(points.len(), "points")?;
        }
        for a in cell_data {
            a.check(ends.len(), "lines")?;
        }
        let io = |e| Error::io(&self.path, e);
        if self.ends.is_empty() && self.point_data.is_empty() && self.cell_data.is_empty() {
            self.point_data = point_data.iter().map(|a| Spilled::new(&self.path, a)).collect::<Result<_>>()?;
            self.cell_data = cell_data.iter().map(|a| Spilled::new(&self.path, a)).collect::<Result<_>>()?;
        }
        // Every array checked before any is written: a refused batch leaves the file as it was.
        for (have, new) in [(&self.point_data, point_data), (&self.cell_data, cell_data)] {
            if have.len() != new.len() {
                return Err(Error::Invalid(format!("a batch of lines with {} arrays after {}", new.len(), have.len())));
            }
            for (s, a) in have.iter().zip(new) {
                s.check(a).map_err(|e| Error::Invalid(format!("{}: {e}", self.path.display())))?;
            }
        }
        for (have, new) in [(&mut self.point_data, point_data), (&mut self.cell_data, cell_data)] {
            for (s, a) in have.iter_mut().zip(new) {
                s.n_values += a.len();
                s.file.write_all(a.bytes()).map_err(io)?;
            }
        }
        self.points.write_all(bytemuck::cast_slice(points)).map_err(io)?;
        let base = self.n_points();
        self.ends.extend(ends.iter().map(|e| base + e));
        Ok(())
    }

    /// Writes the file: every line pushed, with its arrays.
    pub fn finish(self, zlib: bool) -> Result<()> {
        let io = |e: std::io::Error| Error::io(&self.path, e);
        let done = |w: std::io::BufWriter<std::fs::File>| w.into_inner().map_err(|e| io(e.into_error()));
        let n = self.n_points();
        let points = done(self.points)?;
        let arrays = |v: Vec<Spilled>| -> Result<Vec<_>> {
            v.into_iter().map(|s| Ok((s.name, s.ty, s.ncomp, s.n_values, done(s.file)?))).collect()
        };
        let (point_data, cell_data) = (arrays(self.point_data)?, arrays(self.cell_data)?);
        fn out(v: &[(String, NumType, usize, usize, std::fs::File)]) -> Vec<OutArray<'_>> {
            v.iter().map(|(name, ty, k, n, f)| OutArray::spilled(name, *ty, *k, *n, f)).collect()
        }
        let ends = &self.ends;
        let wide = n as u64 > i32::MAX as u64;
        let id_type = if wide { NumType::I64 } else { NumType::I32 };
        let grid = Grid {
            kind: Kind::PolyLines,
            n_points: n,
            n_cells: ends.len(),
            point_data: out(&point_data),
            cell_data: out(&cell_data),
            points: OutArray::spilled("Points", NumType::F32, 3, 3 * n, &points),
            connectivity: OutArray::new("connectivity", id_type, 1, n, move |r, out| {
                r.for_each(|i| push_id(out, i as u64, wide))
            }),
            offsets: OutArray::new("offsets", id_type, 1, ends.len(), move |r, out| {
                r.for_each(|i| push_id(out, ends[i] as u64, wide))
            }),
            types: None,
            faces: Vec::new(),
        };
        grid.write(&self.path, zlib)
    }
}

impl Spilled {
    fn new(path: &Path, a: &NamedArray) -> Result<Spilled> {
        let ty = a.num_type();
        Ok(Spilled { name: a.name.clone(), ty, ncomp: a.n_components, n_values: 0, file: spill_file(path)? })
    }

    /// An error unless `a` is this array's next batch (same name, type and components).
    fn check(&self, a: &NamedArray) -> std::result::Result<(), String> {
        if a.name != self.name || a.num_type() != self.ty || a.n_components != self.ncomp {
            return Err(format!(
                "array '{}' ({} x{}) in a batch of lines where '{}' ({} x{}) was",
                a.name,
                a.num_type().name(),
                a.n_components,
                self.name,
                self.ty.name(),
                self.ncomp
            ));
        }
        Ok(())
    }
}

/// A temporary file next to `path` (removed when closed, however the process ends).
fn spill_file(path: &Path) -> Result<std::io::BufWriter<std::fs::File>> {
    let f = tempfile::tempfile_in(crate::output::parent_dir(path)).map_err(|e| Error::io(path, e))?;
    Ok(std::io::BufWriter::with_capacity(1 << 20, f))
}

fn push_id(out: &mut Vec<u8>, v: u64, wide: bool) {
    if wide {
        out.extend_from_slice(&(v as i64).to_ne_bytes());
    } else {
        out.extend_from_slice(&(v as i32).to_ne_bytes());
    }
}

/// Values per chunk of a streamed array (a multiple of 4: chunks hold whole tets).
const CHUNK: usize = 1 << 16;

/// Appends values `range` (counted in values, not tuples) as native-endian bytes.
type Fill<'a> = Box<dyn Fn(Range<usize>, &mut Vec<u8>) + Sync + 'a>;

/// Where an array's bytes come from.
enum Source<'a> {
    /// Made on demand.
    Fill(Fill<'a>),
    /// Spilled to a file (native-endian, from its start): outputs larger than memory.
    File(&'a std::fs::File),
}

/// One data array to write. Values are produced on demand, in native byte order (the file
/// declares the machine's byte order).
struct OutArray<'a> {
    name: String,
    ty: NumType,
    ncomp: usize,
    n_values: usize,
    source: Source<'a>,
}

impl<'a> OutArray<'a> {
    fn new(
        name: &str,
        ty: NumType,
        ncomp: usize,
        n_values: usize,
        fill: impl Fn(Range<usize>, &mut Vec<u8>) + Sync + 'a,
    ) -> Self {
        OutArray { name: name.to_string(), ty, ncomp, n_values, source: Source::Fill(Box::new(fill)) }
    }

    /// An array of `n_values` values of `ty` spilled to `file`.
    fn spilled(name: &str, ty: NumType, ncomp: usize, n_values: usize, file: &'a std::fs::File) -> Self {
        OutArray { name: name.to_string(), ty, ncomp, n_values, source: Source::File(file) }
    }

    /// An array of the values of `v`, which are of `ty`.
    fn slice<T: bytemuck::Pod + Sync>(name: &str, ty: NumType, ncomp: usize, v: &'a [T]) -> Self {
        Self::new(name, ty, ncomp, v.len(), move |r, out| out.extend_from_slice(bytemuck::cast_slice(&v[r])))
    }

    fn floats(name: &str, ncomp: usize, v: &'a [f32]) -> Self {
        Self::slice(name, NumType::F32, ncomp, v)
    }

    fn n_bytes(&self) -> usize {
        self.n_values * self.ty.size()
    }

    /// The values, uncompressed, to `w`: made in chunks, or copied from their spill file.
    fn write_raw(&self, w: &mut crate::output::AtomicFile) -> std::io::Result<()> {
        match &self.source {
            Source::File(f) => w.append_file(f, self.n_bytes() as u64),
            Source::Fill(fill) => {
                let mut buf = Vec::with_capacity(CHUNK * 8);
                (0..self.n_values).step_by(CHUNK).try_for_each(|start| {
                    buf.clear();
                    fill(start..(start + CHUNK).min(self.n_values), &mut buf);
                    w.write_all(&buf)
                })
            }
        }
    }

    /// The values as VTK zlib blocks, compressed a group of blocks at a time into an
    /// anonymous file next to `path` (so that memory stays bounded for any array size).
    fn zlib_blocks(&self, path: &Path) -> std::io::Result<Compressed> {
        // Blocks compressed at once (in parallel); a whole number of values of any type.
        const GROUP_BYTES: usize = 64 * ZLIB_BLOCK;
        let size = self.ty.size();
        let file = tempfile::tempfile_in(crate::output::parent_dir(path))?;
        let mut out = std::io::BufWriter::with_capacity(1 << 20, &file);
        let mut src = match &self.source {
            Source::File(f) => Some(rewound(f)?),
            Source::Fill(_) => None,
        };
        let (n_bytes, mut sizes, mut buf) = (self.n_bytes(), Vec::new(), Vec::with_capacity(GROUP_BYTES));
        for start in (0..n_bytes).step_by(GROUP_BYTES) {
            let end = (start + GROUP_BYTES).min(n_bytes);
            buf.clear();
            match (&self.source, &mut src) {
                (Source::Fill(fill), _) => fill(start / size..end / size, &mut buf),
                (Source::File(_), Some(f)) => {
                    buf.resize(end - start, 0);
                    std::io::Read::read_exact(f, &mut buf)?;
                }
                (Source::File(_), None) => unreachable!("rewound above"),
            }
            use rayon::prelude::*;
            let parts: Vec<Vec<u8>> = buf.par_chunks(ZLIB_BLOCK).map(blocks::zlib_compress).collect();
            for p in parts {
                sizes.push(p.len());
                out.write_all(&p)?;
            }
        }
        out.flush()?;
        drop(out);
        let len = sizes.iter().sum::<usize>() as u64;
        Ok(Compressed { header: blocks::zlib_header(n_bytes, ZLIB_BLOCK, sizes.into_iter()), file, len })
    }
}

/// An array compressed as VTK zlib blocks: the header ints in memory, the zlib streams in an
/// anonymous file (`len` bytes).
struct Compressed {
    header: Vec<u8>,
    file: std::fs::File,
    len: u64,
}

/// `f` read from its start.
fn rewound(f: &std::fs::File) -> std::io::Result<&std::fs::File> {
    use std::io::Seek;
    let mut f = f;
    f.seek(std::io::SeekFrom::Start(0))?;
    Ok(f)
}

/// The dataset type of a file.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// `UnstructuredGrid`: cells with connectivity, offsets and types.
    Unstructured,
    /// `PolyData` whose cells are all vertices (`Verts`: connectivity and offsets).
    PolyVerts,
    /// `PolyData` whose cells are all polylines (`Lines`).
    PolyLines,
}

struct Grid<'a> {
    kind: Kind,
    n_points: usize,
    n_cells: usize,
    point_data: Vec<OutArray<'a>>,
    cell_data: Vec<OutArray<'a>>,
    points: OutArray<'a>,
    connectivity: OutArray<'a>,
    offsets: OutArray<'a>,
    /// Unstructured grids only.
    types: Option<OutArray<'a>>,
    /// The polyhedra's faces, in VTK 9.4's four arrays (unstructured grids with polyhedra).
    faces: Vec<OutArray<'a>>,
}

impl Grid<'_> {
    /// Arrays in the order of the file.
    fn arrays(&self) -> Vec<&OutArray<'_>> {
        let mut v: Vec<&OutArray> = self.point_data.iter().chain(&self.cell_data).collect();
        v.extend([&self.points, &self.connectivity, &self.offsets]);
        v.extend(&self.types);
        v.extend(&self.faces);
        v
    }

    fn write(&self, path: &Path, zlib: bool) -> Result<()> {
        let io = |e| Error::io(path, e);
        let arrays = self.arrays();
        use rayon::prelude::*;
        let compressed: Option<Vec<Compressed>> = zlib
            .then(|| arrays.par_iter().map(|a| a.zlib_blocks(path)).collect::<std::io::Result<_>>())
            .transpose()
            .map_err(io)?;
        let sizes: Vec<usize> = match &compressed {
            Some(c) => c.iter().map(|c| c.header.len() + c.len as usize).collect(),
            None => arrays.iter().map(|a| 8 + a.n_bytes()).collect(),
        };
        let mut offsets = Vec::with_capacity(sizes.len());
        let mut at = 0;
        for s in &sizes {
            offsets.push(at);
            at += s;
        }

        write_atomically(path, |w| {
            w.write_all(self.header(&arrays, &offsets, zlib).as_bytes()).map_err(io)?;
            match compressed {
                Some(blocks) => {
                    for b in &blocks {
                        w.write_all(&b.header).map_err(io)?;
                        w.append_file(&b.file, b.len).map_err(io)?;
                    }
                }
                None => {
                    for a in &arrays {
                        w.write_all(&(a.n_bytes() as u64).to_ne_bytes()).map_err(io)?;
                        a.write_raw(w).map_err(io)?;
                    }
                }
            }
            w.write_all(b"\n  </AppendedData>\n</VTKFile>\n").map_err(io)
        })
    }

    fn header(&self, arrays: &[&OutArray], offsets: &[usize], zlib: bool) -> String {
        use std::fmt::Write;
        let order = if cfg!(target_endian = "little") { "LittleEndian" } else { "BigEndian" };
        let compressor = if zlib { " compressor=\"vtkZLibDataCompressor\"" } else { "" };
        let mut s = String::new();
        let _ = writeln!(s, "<?xml version=\"1.0\"?>");
        let (dataset, cells, counts) = match self.kind {
            Kind::Unstructured => ("UnstructuredGrid", "Cells", format!("NumberOfCells=\"{}\"", self.n_cells)),
            Kind::PolyVerts => (
                "PolyData",
                "Verts",
                format!(
                    "NumberOfVerts=\"{}\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"0\"",
                    self.n_cells
                ),
            ),
            Kind::PolyLines => (
                "PolyData",
                "Lines",
                format!(
                    "NumberOfVerts=\"0\" NumberOfLines=\"{}\" NumberOfStrips=\"0\" NumberOfPolys=\"0\"",
                    self.n_cells
                ),
            ),
        };
        let _ = writeln!(
            s,
            "<VTKFile type=\"{dataset}\" version=\"1.0\" byte_order=\"{order}\" header_type=\"UInt64\"{compressor}>"
        );
        let _ = writeln!(s, "  <{dataset}>");
        let _ = writeln!(s, "    <Piece NumberOfPoints=\"{}\" {counts}>", self.n_points);
        let mut k = 0;
        let mut section = |s: &mut String, tag: &str, n: usize| {
            let _ = writeln!(s, "      <{tag}>");
            for _ in 0..n {
                let a = arrays[k];
                let comps = if a.ncomp > 1 { format!(" NumberOfComponents=\"{}\"", a.ncomp) } else { String::new() };
                let _ = writeln!(
                    s,
                    "        <DataArray type=\"{}\" Name=\"{}\"{comps} format=\"appended\" offset=\"{}\"/>",
                    a.ty.name(),
                    escape(&a.name),
                    offsets[k]
                );
                k += 1;
            }
            let _ = writeln!(s, "      </{tag}>");
        };
        section(&mut s, "PointData", self.point_data.len());
        section(&mut s, "CellData", self.cell_data.len());
        section(&mut s, "Points", 1);
        section(&mut s, cells, 2 + self.types.is_some() as usize + self.faces.len());
        let _ = writeln!(s, "    </Piece>");
        let _ = writeln!(s, "  </{dataset}>");
        let _ = write!(s, "  <AppendedData encoding=\"raw\">\n   _");
        s
    }
}

/// Escapes a name for an XML attribute value.
pub(crate) fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\n' => out.push_str("&#10;"),
            '\t' => out.push_str("&#9;"),
            '\r' => out.push_str("&#13;"),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vtk::vtu;
    use std::path::PathBuf;
    use tetloc_core::mesh::{Field, RawMesh};

    /// A unique path in the temp folder, removed on drop.
    pub(crate) struct TempPath(pub PathBuf);
    impl TempPath {
        pub fn new(tag: &str) -> TempPath {
            use std::sync::atomic::{AtomicUsize, Ordering};
            static N: AtomicUsize = AtomicUsize::new(0);
            let n = N.fetch_add(1, Ordering::Relaxed);
            TempPath(std::env::temp_dir().join(format!("tetloc-{}-{n}-{tag}.vtu", std::process::id())))
        }
    }
    impl Drop for TempPath {
        fn drop(&mut self) {
            let _ = std::fs::remove_file(&self.0);
        }
    }

    fn round_trip(mesh: &Mesh, zlib: bool, wide: bool) {
        let tmp = TempPath::new("mesh");
        write_mesh(&tmp.0, mesh, &[], zlib, wide).unwrap();
        let back = vtu::read(&tmp.0).unwrap();
        assert_eq!(back.points[..], mesh.points[..]);
        // Canonical tets are written as they are (right-handed, VTK's orientation).
        assert_eq!(back.tets[..], mesh.tets[..]);
        assert_eq!(back.fields.len(), mesh.fields.len());
        for (a, b) in back.fields.iter().zip(&mesh.fields) {
            assert_eq!((&a.name, a.location), (&b.name, b.location));
            assert!(a.values.iter().zip(&b.values).all(|(x, y)| x.to_bits() == y.to_bits()));
            assert_eq!(a.values.len(), b.values.len());
        }
        // Positive volume in VTK's convention: det(p1 - p0, p2 - p0, p3 - p0) > 0.
        for t in &back.tets {
            let p = t.map(|i| back.points[i as usize].map(f64::from));
            let d = |k: usize| [0, 1, 2].map(|c| p[k][c] - p[0][c]);
            let (a, b, c) = (d(1), d(2), d(3));
            let det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]);
            assert!(det > 0.0, "tet {t:?} is not positive in VTK's convention");
        }
        // Reading it again as a mesh gives the same canonical tets.
        let again = Mesh::new(back, "again").unwrap();
        assert_eq!(again.tets, mesh.tets);
    }

    #[test]
    fn mesh_round_trips() {
        let mesh = small_mesh();
        for (zlib, wide) in [(false, false), (true, false), (false, true), (true, true)] {
            round_trip(&mesh, zlib, wide);
        }
    }

    fn small_mesh() -> Mesh {
        // Two tets sharing a face, one given inverted; fields with awkward names.
        let raw = RawMesh {
            points64: None,
            points: vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.], [0.7, 0.7, 0.7]],
            tets: vec![[0, 1, 2, 3], [1, 2, 3, 4]],
            fields: vec![
                Field {
                    values64: None,
                    name: "p <&\"'> x".into(),
                    location: FieldLocation::Vertex,
                    values: vec![0.5, -1., 2., f32::NAN, 4.],
                },
                Field { values64: None, name: "c[0]".into(), location: FieldLocation::Cell, values: vec![7., 8.] },
            ],
            higher_order: None,
            cells: None,
        };
        Mesh::new(raw, "small").unwrap()
    }

    #[test]
    fn points_round_trip() {
        let tmp = TempPath::new("points");
        let pts = vec![[0.5, 1.5, 2.5], [3., 4., 5.], [-1., -2., -3.]];
        write_points_vtu(
            &tmp.0,
            Coords::F32(&pts),
            &[4, -1, 0],
            Some(("value of f", Values::F32(&[1.0, f32::NAN, 3.0]))),
        )
        .unwrap();
        let bytes = std::fs::read(&tmp.0).unwrap();
        let doc = super::super::xml::parse(&bytes, "AppendedData").unwrap();
        let piece = doc.root.child("UnstructuredGrid").unwrap().child("Piece").unwrap();
        let pd = piece.child("PointData").unwrap();
        let ids = pd.children_named("DataArray").find(|d| d.attr("Name") == Some("tet_id")).unwrap();
        assert_eq!(ids.attr("type"), Some("Int32"));
        // The reader drops the vertex cells and keeps the points and their data.
        let back = vtu::read(&tmp.0).unwrap();
        assert!(back.tets.is_empty());
        assert_eq!(back.points, pts);
        let names: Vec<&str> = back.fields.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["tet_id", "value of f", "vtkValidPointMask"]);
        assert_eq!(back.fields[0].values, vec![4.0, -1.0, 0.0]);
        assert_eq!(back.fields[1].values[0], 1.0);
        assert!(back.fields[1].values[1].is_nan());
        assert_eq!(back.fields[2].values, vec![1.0, 0.0, 1.0]);
        let mask = pd.children_named("DataArray").find(|d| d.attr("Name") == Some("vtkValidPointMask")).unwrap();
        assert_eq!(mask.attr("type"), Some("UInt8"));
    }

    /// Points far from the origin and f64 values are written as Float64 and read back
    /// exactly.
    #[test]
    fn f64_point_sets_keep_every_digit() {
        let tmp = TempPath::new("points64");
        let pts = [[512345.123456789, 4123456.987654321, -0.1], [1e7 + 0.25, 3.0, 4.0]];
        let pts32: Vec<[f32; 3]> = pts.iter().map(|p| p.map(|c| c as f32)).collect();
        let coords = Coords::of(&pts, &pts32);
        assert!(matches!(coords, Coords::F64(_)));
        let v = [0.1 + 1e-12, f64::NAN];
        write_points_vtu(&tmp.0, coords, &[0, -1], Some(("f", Values::F64(&v)))).unwrap();
        let back = vtu::read(&tmp.0).unwrap();
        assert_eq!(back.points64.as_deref(), Some(&pts[..]));
        let f = back.fields.iter().find(|f| f.name == "f").unwrap();
        assert_eq!(f.values64.as_ref().unwrap()[0], v[0]);
        // Points that f32 holds exactly stay Float32.
        let near = [[0.5, 1.5, 2.5]];
        assert!(matches!(Coords::of(&near, &[[0.5, 1.5, 2.5]]), Coords::F32(_)));
    }

    /// The polydata point set: the same arrays, `Verts` instead of `Cells`. (VTK itself reads
    /// it in the CLI's boundary-tolerance test.)
    #[test]
    fn vtp_point_set() {
        let tmp = TempPath::new("points");
        let pts = vec![[0.5, 1.5, 2.5], [3., 4., 5.]];
        write_points_vtp(&tmp.0, Coords::F32(&pts), &[-1, 2], Some(("f", Values::F32(&[f32::NAN, 3.0])))).unwrap();
        let bytes = std::fs::read(&tmp.0).unwrap();
        let doc = super::super::xml::parse(&bytes, "AppendedData").unwrap();
        assert_eq!(doc.root.attr("type"), Some("PolyData"));
        let piece = doc.root.child("PolyData").unwrap().child("Piece").unwrap();
        assert_eq!(piece.attr("NumberOfPoints"), Some("2"));
        assert_eq!(piece.attr("NumberOfVerts"), Some("2"));
        assert_eq!(piece.attr("NumberOfPolys"), Some("0"));
        let names: Vec<_> =
            piece.child("PointData").unwrap().children_named("DataArray").map(|d| d.attr("Name").unwrap()).collect();
        assert_eq!(names, ["tet_id", "f", "vtkValidPointMask"]);
        let verts: Vec<_> =
            piece.child("Verts").unwrap().children_named("DataArray").map(|d| d.attr("Name").unwrap()).collect();
        assert_eq!(verts, ["connectivity", "offsets"]);
        assert!(piece.child("Cells").is_none());
    }

    /// Lines pushed in batches make the file one push of all of them makes, byte for byte;
    /// nothing is at the path before `finish`, nor after a writer dropped unfinished.
    #[test]
    fn polylines_in_batches_are_one_file() {
        let pts: Vec<[f32; 3]> = (0..7).map(|i| [i as f32, 0.5 * i as f32, 1.0]).collect();
        let time: Vec<f64> = (0..7).map(|i| 0.1 * i as f64).collect();
        let vec3: Vec<f32> = (0..21).map(|i| i as f32 * 0.25).collect();
        let (ends, reasons) = ([2usize, 3, 7], [1i32, 2, 5]);
        let arrays = |r: Range<usize>, lines: Range<usize>| {
            let point = vec![
                NamedArray { name: "v".into(), n_components: 3, data: ArrayData::F32(&vec3[3 * r.start..3 * r.end]) },
                NamedArray { name: "IntegrationTime".into(), n_components: 1, data: ArrayData::F64(&time[r]) },
            ];
            let cell = vec![NamedArray {
                name: "ReasonForTermination".into(),
                n_components: 1,
                data: ArrayData::I32(&reasons[lines]),
            }];
            (point, cell)
        };
        for zlib in [false, true] {
            let (one, batched) = (TempPath::new("one"), TempPath::new("batched"));
            let mut w = PolylineWriter::new(&one.0).unwrap();
            let (p, c) = arrays(0..7, 0..3);
            w.push(&pts, &ends, &p, &c).unwrap();
            w.finish(zlib).unwrap();
            let mut w = PolylineWriter::new(&batched.0).unwrap();
            for (r, lines, local_ends) in [(0..3, 0..2, vec![2, 3]), (3..3, 2..2, vec![]), (3..7, 2..3, vec![4])] {
                let (p, c) = arrays(r.clone(), lines);
                w.push(&pts[r], &local_ends, &p, &c).unwrap();
            }
            assert!(!batched.0.exists());
            assert_eq!((w.n_points(), w.n_lines()), (7, 3));
            w.finish(zlib).unwrap();
            let bytes = std::fs::read(&one.0).unwrap();
            assert_eq!(bytes, std::fs::read(&batched.0).unwrap(), "zlib {zlib}");
            let doc = super::super::xml::parse(&bytes, "AppendedData").unwrap();
            let piece = doc.root.child("PolyData").unwrap().child("Piece").unwrap();
            assert_eq!((piece.attr("NumberOfPoints"), piece.attr("NumberOfLines")), (Some("7"), Some("3")));
        }
        // Arrays that change between batches, lines that do not cover the points.
        let tmp = TempPath::new("bad-lines");
        let mut w = PolylineWriter::new(&tmp.0).unwrap();
        let (p, c) = arrays(0..3, 0..2);
        w.push(&pts[..3], &[2, 3], &p, &c).unwrap();
        let err = w.push(&pts[..3], &[2, 3], &p[..1], &c).unwrap_err().to_string();
        assert!(err.contains("1 arrays after 2"), "{err}");
        let err = w.push(&pts[..3], &[2, 3], &[p[1].clone(), p[0].clone()], &c).unwrap_err().to_string();
        assert!(err.contains("'IntegrationTime'") && err.contains("bad-lines"), "{err}");
        assert!(w.push(&pts[..3], &[2], &p, &c).is_err());
        drop(w);
        assert!(!tmp.0.exists());
    }

    #[test]
    fn bad_point_inputs() {
        let tmp = TempPath::new("bad");
        assert!(write_points_vtu(&tmp.0, Coords::F32(&[[0.; 3]]), &[], None).is_err());
        assert!(write_points_vtu(&tmp.0, Coords::F32(&[[0.; 3]]), &[1], Some(("v", Values::F32(&[])))).is_err());
        let e = write_mesh_vtu(Path::new("/nonexistent-dir/x.vtu"), &small_mesh(), false).unwrap_err();
        assert!(e.to_string().starts_with("/nonexistent-dir/x.vtu"), "{e}");
    }

    /// Runs `NAME[0]` … `NAME[k-1]` are written as one k-component array and read back as
    /// the same fields; extra point arrays replace a mesh array of the same name.
    #[test]
    fn vectors_are_written_as_one_array() {
        let m = small_mesh();
        let mut raw = RawMesh { points: m.points.to_vec(), tets: m.tets.to_vec(), ..Default::default() };
        for c in 0..3 {
            let values = (0..5).map(|i| (10 * c + i) as f32).collect();
            raw.fields.push(Field { values64: None, name: format!("v[{c}]"), location: FieldLocation::Vertex, values });
        }
        raw.fields.push(Field {
            values64: None,
            name: "g".into(),
            location: FieldLocation::Vertex,
            values: vec![1.0; 5],
        });
        let mesh = Mesh::new(raw, "v").unwrap();
        let tmp = TempPath::new("vector");
        let mask = [1u8, 0, 1, 1, 0];
        let g2: Vec<f32> = (0..10).map(|i| i as f32).collect();
        let extra = [
            NamedArray { name: "g".into(), n_components: 2, data: ArrayData::F32(&g2) },
            NamedArray { name: VALID_MASK.into(), n_components: 1, data: ArrayData::U8(&mask) },
        ];
        write_mesh_with(&tmp.0, &mesh, &extra, true).unwrap();
        let text = String::from_utf8_lossy(&std::fs::read(&tmp.0).unwrap()).into_owned();
        assert!(text.contains("Name=\"v\" NumberOfComponents=\"3\""), "{text:.600}");
        let back = vtu::read(&tmp.0).unwrap();
        let names: Vec<&str> = back.fields.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["v[0]", "v[1]", "v[2]", "g[0]", "g[1]", VALID_MASK]);
        for c in 0..3 {
            assert_eq!(back.fields[c].values, mesh.fields[c].values);
        }
        assert_eq!(back.fields[4].values, [1.0, 3.0, 5.0, 7.0, 9.0]);
        let short = [NamedArray { name: "s".into(), n_components: 3, data: ArrayData::F32(&g2) }];
        assert!(write_mesh_with(&tmp.0, &mesh, &short, false).is_err());
    }

    #[test]
    fn escaping() {
        assert_eq!(escape("a<b>&\"c'"), "a&lt;b&gt;&amp;&quot;c&apos;");
    }
}
