//! VTK cell types, and picking the volume cells out of a VTK cell list.

use super::num::{self, Array};
use std::collections::BTreeMap;
use std::path::Path;
use tetloc_core::cell::{CellBlock, CellType, PolyFaces};
use tetloc_core::error::Error;
use tetloc_core::mesh::{Field, RawMesh};

/// What tetloc does with one VTK cell type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    /// A volume cell tetloc reads: its [`CellType`] follows from the code and the point count.
    Volume,
    /// A 0-, 1- or 2-D cell: not part of the volume mesh, ignored.
    Lower,
    /// A volume cell tetloc does not read: the mesh cannot be used.
    Unsupported,
}

/// VTK's cell type codes (vtkCellType.h) with their names.
const CELL_TYPES: &[(u8, &str, Kind)] = &[
    (0, "empty cell", Kind::Lower),
    (1, "vertex", Kind::Lower),
    (2, "poly-vertex", Kind::Lower),
    (3, "line", Kind::Lower),
    (4, "poly-line", Kind::Lower),
    (5, "triangle", Kind::Lower),
    (6, "triangle strip", Kind::Lower),
    (7, "polygon", Kind::Lower),
    (8, "pixel", Kind::Lower),
    (9, "quad", Kind::Lower),
    (10, "tetra", Kind::Volume),
    (11, "voxel", Kind::Unsupported),
    (12, "hexahedron", Kind::Volume),
    (13, "wedge", Kind::Volume),
    (14, "pyramid", Kind::Volume),
    (15, "pentagonal prism", Kind::Unsupported),
    (16, "hexagonal prism", Kind::Unsupported),
    (21, "quadratic edge", Kind::Lower),
    (22, "quadratic triangle", Kind::Lower),
    (23, "quadratic quad", Kind::Lower),
    (24, "quadratic tetra", Kind::Volume),
    (25, "quadratic hexahedron", Kind::Volume),
    (26, "quadratic wedge", Kind::Volume),
    (27, "quadratic pyramid", Kind::Volume),
    (28, "biquadratic quad", Kind::Lower),
    (29, "triquadratic hexahedron", Kind::Volume),
    (30, "quadratic linear quad", Kind::Lower),
    (31, "quadratic linear wedge", Kind::Unsupported),
    (32, "biquadratic quadratic wedge", Kind::Volume),
    (33, "biquadratic quadratic hexahedron", Kind::Unsupported),
    (34, "biquadratic triangle", Kind::Lower),
    (35, "cubic line", Kind::Lower),
    (36, "quadratic polygon", Kind::Lower),
    (37, "triquadratic pyramid", Kind::Unsupported),
    (41, "convex point set", Kind::Unsupported),
    (42, "polyhedron", Kind::Volume),
    (51, "parametric curve", Kind::Lower),
    (52, "parametric surface", Kind::Lower),
    (53, "parametric tri surface", Kind::Lower),
    (54, "parametric quad surface", Kind::Lower),
    (55, "parametric tetra region", Kind::Unsupported),
    (56, "parametric hex region", Kind::Unsupported),
    (60, "higher-order edge", Kind::Lower),
    (61, "higher-order triangle", Kind::Lower),
    (62, "higher-order quad", Kind::Lower),
    (63, "higher-order polygon", Kind::Lower),
    // The deprecated generic higher-order cells have no defined point order: not usable.
    (64, "higher-order tetrahedron", Kind::Unsupported),
    (65, "higher-order wedge", Kind::Unsupported),
    (66, "higher-order pyramid", Kind::Unsupported),
    (67, "higher-order hexahedron", Kind::Unsupported),
    (68, "Lagrange curve", Kind::Lower),
    (69, "Lagrange triangle", Kind::Lower),
    (70, "Lagrange quadrilateral", Kind::Lower),
    (71, "Lagrange tetrahedron", Kind::Volume),
    (72, "Lagrange hexahedron", Kind::Volume),
    (73, "Lagrange wedge", Kind::Volume),
    // VTK has no vtkLagrangePyramid: no point order is defined for it.
    (74, "Lagrange pyramid", Kind::Unsupported),
    (75, "Bezier curve", Kind::Lower),
    (76, "Bezier triangle", Kind::Lower),
    (77, "Bezier quadrilateral", Kind::Lower),
    (78, "Bezier tetrahedron", Kind::Volume),
    (79, "Bezier hexahedron", Kind::Unsupported),
    (80, "Bezier wedge", Kind::Unsupported),
    (81, "Bezier pyramid", Kind::Unsupported),
];

fn lookup(code: u8) -> Option<(&'static str, Kind)> {
    CELL_TYPES.iter().find(|c| c.0 == code).map(|c| (c.1, c.2))
}

pub(crate) const TETRA: u8 = 10;
pub(crate) const VERTEX: u8 = 1;
/// VTK_POLYHEDRON: its faces come in arrays of their own.
pub(crate) const POLYHEDRON: u8 = 42;

/// The volume cells picked out of a cell list.
#[derive(Debug)]
pub struct Extracted {
    /// Corner ids of the cells that are tets (of any order), in file order.
    pub tets: Vec<[u32; 4]>,
    /// Which cells are volume cells (`None`: all of them): cell fields keep those values only.
    pub kept: Option<Vec<bool>>,
    /// The highest polynomial order of the volume cells, when above 1.
    pub higher_order: Option<u8>,
    /// Volume cells that are not tets, counted by type code.
    pub other: BTreeMap<u8, usize>,
    /// Whether some of `other` are of a type tetloc does not read.
    pub unsupported: bool,
    /// Every volume cell with all its nodes, when some volume cell is not a linear tet (`None`:
    /// `tets` says it all).
    pub cells: Option<CellBlock>,
}

impl Extracted {
    /// Every cell a linear tet: the connectivity is the tet array, no copy.
    pub fn all_tets(conn: Vec<u32>) -> Extracted {
        let tets = bytemuck::allocation::try_cast_vec(conn)
            .unwrap_or_else(|(_, v)| v.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect());
        Extracted { tets, kept: None, higher_order: None, other: BTreeMap::new(), unsupported: false, cells: None }
    }

    /// The mesh of these cells with `points` and `fields` (cell fields already filtered to the
    /// volume cells): a mesh with cells other than tets is all in `cells`, `tets` is for tet
    /// meshes.
    pub fn into_mesh(self, points: Vec<[f32; 3]>, points64: Option<Vec<[f64; 3]>>, fields: Vec<Field>) -> RawMesh {
        let tets = if self.other.is_empty() { self.tets } else { Vec::new() };
        RawMesh { points, points64, tets, fields, higher_order: self.higher_order, cells: self.cells }
    }
}

/// Whether every cell is a linear tet with its 4 ids in order (`ends` = 4, 8, 12, ...): the
/// common case, checked on the file's arrays without converting them.
pub(crate) fn all_linear_tets(types: &Array, ends: &Array) -> bool {
    types.len() == ends.len()
        && num::all_ints(types, |_, t| t == TETRA as i64)
        && num::all_ints(ends, |i, e| e == 4 * (i as i64 + 1))
}

/// Picks the volume cells out of `types.len()` cells; cell `i` has the point ids
/// `conn[ends[i - 1]..ends[i]]` (from 0 for the first). `ends` is validated here. The faces
/// of the polyhedra (type 42) are in `polyhedra`, by their cell index in this list. Errors
/// are messages for [`Error::format`].
pub(crate) fn extract(
    types: &[u8],
    ends: &[u64],
    conn: &[u32],
    polyhedra: Option<&PolyFaces>,
) -> Result<Extracted, String> {
    let n = types.len();
    if ends.len() != n {
        return Err(format!("{} cell types but {} cell offsets", n, ends.len()));
    }
    if let Some(i) = ends.windows(2).position(|w| w[1] < w[0]) {
        return Err(format!("cell offsets decrease at cell {} ({} then {})", i + 1, ends[i], ends[i + 1]));
    }
    if ends.last().copied().unwrap_or(0) != conn.len() as u64 {
        return Err(format!(
            "the cell offsets end at {} but the connectivity has {} entries",
            ends.last().copied().unwrap_or(0),
            conn.len()
        ));
    }

    let mut tets = Vec::new();
    let mut kept = vec![false; n];
    let mut higher_order: Option<u8> = None;
    let mut other = BTreeMap::new();
    let mut unsupported = false;
    let mut cells = CellBlock::default();
    let mut last: Option<(u8, usize, CellType)> = None;
    for (i, &code) in types.iter().enumerate() {
        let start = if i == 0 { 0 } else { ends[i - 1] as usize };
        let ids = &conn[start..ends[i] as usize];
        let Some((name, kind)) = lookup(code) else {
            return Err(format!("cell {i} has cell type {code}, which VTK does not define"));
        };
        match kind {
            Kind::Volume if code == POLYHEDRON => {
                let faces = polyhedra
                    .and_then(|p| p.index_of(i).map(|k| p.faces(k)))
                    .ok_or_else(|| format!("cell {i} is a polyhedron, but the file gives no faces for it"))?;
                cells.push_polyhedron(faces);
                *other.entry(code).or_insert(0) += 1;
                kept[i] = true;
            }
            Kind::Volume => {
                // Files repeat one type for long runs: look it up once per run.
                let ty = match last {
                    Some((c, len, t)) if c == code && len == ids.len() => t,
                    _ => CellType::from_vtk(code, ids.len()).ok_or_else(|| {
                        format!("cell {i} ({name}) has {} points, which no {name} tetloc reads has", ids.len())
                    })?,
                };
                last = Some((code, ids.len(), ty));
                let order = ty.def().order();
                if order > 1 {
                    higher_order = Some(higher_order.map_or(order, |o| o.max(order)));
                }
                if ty.shape().is_tet() {
                    tets.push([ids[0], ids[1], ids[2], ids[3]]);
                } else {
                    *other.entry(code).or_insert(0) += 1;
                }
                cells.push(ty, ids);
                kept[i] = true;
            }
            Kind::Lower => {}
            Kind::Unsupported => {
                *other.entry(code).or_insert(0) += 1;
                unsupported = true;
            }
        }
    }
    let linear_tets_only = other.is_empty() && higher_order.is_none();
    let kept = (cells.len() < n).then_some(kept);
    let cells = (!linear_tets_only && !unsupported).then_some(cells);
    Ok(Extracted { tets, kept, higher_order, other, unsupported, cells })
}

/// The volume cells of a VTK cell list as pyvista holds it, for meshes made from arrays:
/// cell `i` is of type `types[i]` with the points `conn[offsets[i]..offsets[i + 1]]`
/// (`offsets` from 0 to the connectivity's length, one more than the types). Every cell must
/// be a volume cell tetloc reads: arrays handed over are meant as the volume, so a 0-2-D cell
/// is an error here, where a file's are dropped. Errors are messages; the caller names the
/// argument.
pub fn from_cell_list(types: &[u8], offsets: &[i64], conn: &[u32]) -> Result<Extracted, String> {
    let n = types.len();
    if offsets.len() != n + 1 {
        return Err(format!("{n} cell types but {} offsets (expected one more)", offsets.len()));
    }
    if offsets[0] != 0 || offsets[n] != conn.len() as i64 {
        return Err(format!(
            "offsets run from {} to {}; expected 0 to the connectivity's length {}",
            offsets[0],
            offsets[n],
            conn.len()
        ));
    }
    if let Some(i) = offsets.windows(2).position(|w| w[1] < w[0]) {
        return Err(format!("offsets decrease at cell {i} ({} then {})", offsets[i], offsets[i + 1]));
    }
    // The common case: linear tets only (a tet mesh pays nothing for other cells).
    if types.iter().all(|&t| t == TETRA) && offsets.iter().enumerate().all(|(i, &o)| o == 4 * i as i64) {
        return Ok(Extracted::all_tets(conn.to_vec()));
    }
    if let Some(i) = types.iter().position(|&t| t == POLYHEDRON) {
        return Err(format!(
            "cell {i} is a polyhedron (VTK cell type 42): a cell list does not carry its faces; read polyhedra from a file (.vtu, .vtk, an OpenFOAM case)"
        ));
    }
    // From 0 and never decreasing: the offsets are counts.
    let ends: Vec<u64> = offsets[1..].iter().map(|&o| o as u64).collect();
    let ex = extract(types, &ends, conn, None)?;
    if ex.unsupported || ex.kept.is_some() {
        let not_read = (0..n).find(|&i| {
            let len = (offsets[i + 1] - offsets[i]) as usize;
            CellType::from_vtk(types[i], len).is_none()
        });
        if let Some(i) = not_read {
            return Err(format!(
                "cell {i} has VTK cell type {} with {} points, which is not a volume cell tetloc reads",
                types[i],
                offsets[i + 1] - offsets[i]
            ));
        }
    }
    Ok(ex)
}

/// A point id of a polyhedron face, checked.
fn face_point(v: i64, n_points: usize, cell: usize) -> Result<u32, String> {
    u32::try_from(v).ok().filter(|&p| (p as usize) < n_points).ok_or_else(|| {
        format!("polyhedron (cell {cell}): face point {v} is not a point id (the mesh has {n_points} points)")
    })
}

/// The polyhedra's faces in VTK's first layout (before 9.4; also legacy `.vtk`): one stream
/// `faces` holding, per polyhedron in cell order, its face count and then each face's point
/// count and point ids; `faceoffsets` has one entry per cell, negative for the cells that are
/// not polyhedra. The streams are read in order (they follow one another).
pub(crate) fn faces_from_stream(types: &[u8], stream: &[i64], n_points: usize) -> Result<PolyFaces, String> {
    let mut out = PolyFaces::default();
    let mut at = 0usize;
    let mut next = |what: &str, cell: usize| -> Result<i64, String> {
        let v = stream.get(at).copied().ok_or_else(|| {
            format!("polyhedron (cell {cell}): the faces array ends ({} values) before its {what}", stream.len())
        })?;
        at += 1;
        Ok(v)
    };
    for (i, _) in types.iter().enumerate().filter(|(_, &t)| t == POLYHEDRON) {
        let n_faces = next("face count", i)?;
        let n_faces = usize::try_from(n_faces)
            .ok()
            .filter(|&n| n <= stream.len())
            .ok_or_else(|| format!("polyhedron (cell {i}): face count {n_faces}"))?;
        let mut faces: Vec<Vec<u32>> = Vec::with_capacity(n_faces);
        for _ in 0..n_faces {
            let n = next("point count", i)?;
            let n = usize::try_from(n)
                .ok()
                .filter(|&n| n <= stream.len())
                .ok_or_else(|| format!("polyhedron (cell {i}): face point count {n}"))?;
            faces.push(
                (0..n)
                    .map(|_| next("face points", i).and_then(|v| face_point(v, n_points, i)))
                    .collect::<Result<_, _>>()?,
            );
        }
        out.push(i as u32, faces.iter().map(Vec::as_slice));
    }
    if at != stream.len() {
        return Err(format!("the faces array has {} values, but its polyhedra use {at}", stream.len()));
    }
    Ok(out)
}

/// The polyhedra's faces in VTK 9.4's layout: faces as a cell array (`face_conn`, with the
/// end of each face's points in `face_ends`), and each cell's faces as a list of face ids
/// (`cell_faces`, with the end of each cell's ids in `cell_ends`, one per cell; cells that
/// are not polyhedra have none).
pub(crate) fn faces_from_arrays(
    types: &[u8],
    face_conn: &[i64],
    face_ends: &[i64],
    cell_faces: &[i64],
    cell_ends: &[i64],
    n_points: usize,
) -> Result<PolyFaces, String> {
    let range = |ends: &[i64], i: usize, len: usize, what: &str| -> Result<std::ops::Range<usize>, String> {
        let start = if i == 0 { 0 } else { ends[i - 1] };
        let end = ends[i];
        let ok = |v: i64| usize::try_from(v).ok().filter(|&v| v <= len);
        match (ok(start), ok(end)) {
            (Some(s), Some(e)) if s <= e => Ok(s..e),
            _ => Err(format!("{what} {i}: offsets {start}..{end} do not fit the {len} values")),
        }
    };
    if cell_ends.len() != types.len() {
        return Err(format!("{} polyhedron offsets for {} cells", cell_ends.len(), types.len()));
    }
    let mut out = PolyFaces::default();
    for (i, _) in types.iter().enumerate().filter(|(_, &t)| t == POLYHEDRON) {
        let ids = &cell_faces[range(cell_ends, i, cell_faces.len(), "polyhedron offsets of cell")?];
        let faces: Vec<Vec<u32>> = ids
            .iter()
            .map(|&f| {
                let f = usize::try_from(f).ok().filter(|&f| f < face_ends.len()).ok_or_else(|| {
                    format!("polyhedron (cell {i}): face {f} is not a face id ({} faces)", face_ends.len())
                })?;
                face_conn[range(face_ends, f, face_conn.len(), "face")?]
                    .iter()
                    .map(|&v| face_point(v, n_points, i))
                    .collect()
            })
            .collect::<Result<_, String>>()?;
        out.push(i as u32, faces.iter().map(Vec::as_slice));
    }
    Ok(out)
}

/// The [`Error::NonTetCells`] for the volume cells tetloc does not read, counted by type code
/// (those it reads among `other` are left out).
pub(crate) fn non_tet_error(path: &Path, other: &BTreeMap<u8, usize>) -> Error {
    let counts = other
        .iter()
        .filter(|(&code, _)| lookup(code).is_none_or(|c| c.1 == Kind::Unsupported))
        .map(|(&code, &k)| (lookup(code).map_or_else(|| format!("type {code}"), |c| c.0.to_string()), k))
        .collect();
    Error::NonTetCells { path: path.to_path_buf(), counts }
}

/// Keeps the values of the volume cells only, when some cells were not.
pub(crate) fn filter_cells<T: Copy>(values: Vec<T>, kept: Option<&[bool]>) -> Vec<T> {
    match kept {
        None => values,
        Some(k) => values.into_iter().zip(k).filter(|(_, &k)| k).map(|(v, _)| v).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The point ids 0..n.
    fn ids(n: u32) -> Vec<u32> {
        (0..n).collect()
    }

    #[test]
    fn mixed_cells() {
        // triangle, quadratic tet, tet, vertex
        let types = [5u8, 24, 10, 1];
        let ends = [3u64, 13, 17, 18];
        let e = extract(&types, &ends, &ids(18), None).unwrap();
        assert_eq!(e.tets, vec![[3, 4, 5, 6], [13, 14, 15, 16]]);
        assert_eq!(e.kept.as_deref(), Some(&[false, true, true, false][..]));
        assert_eq!(e.higher_order, Some(2));
        assert!(e.other.is_empty() && !e.unsupported);
        assert_eq!(filter_cells(vec![1., 2., 3., 4.], e.kept.as_deref()), vec![2., 3.]);
        // Higher-order nodes are kept with the cells.
        let cells = e.cells.unwrap();
        assert_eq!(cells.len(), 2);
        assert_eq!(cells.nodes(0), &(3..13).collect::<Vec<u32>>()[..]);
        assert_eq!(cells.types[1], CellType::tet());

        // hex, tet, hex, wedge: every volume cell in the block, the tets among them in `tets`.
        let e = extract(&[12, 10, 12, 13], &[8, 12, 20, 26], &ids(26), None).unwrap();
        assert_eq!(e.other.clone().into_iter().collect::<Vec<_>>(), vec![(12, 2), (13, 1)]);
        assert!(!e.unsupported && e.kept.is_none() && e.higher_order.is_none());
        assert_eq!(e.tets, vec![[8, 9, 10, 11]]);
        let cells = e.cells.unwrap();
        assert_eq!(cells.non_tet_counts().unwrap(), vec![("hexahedron".to_string(), 2), ("wedge".to_string(), 1)]);
        assert_eq!(cells.nodes(3), &[20, 21, 22, 23, 24, 25]);

        // A type tetloc does not read leaves no block, only the counts.
        let e = extract(&[12, 16], &[8, 20], &ids(20), None).unwrap();
        assert!(e.unsupported && e.cells.is_none());
        assert_eq!(e.other.into_iter().collect::<Vec<_>>(), vec![(12, 1), (16, 1)]);
        // A polyhedron takes its faces; without them it is an error.
        let mut faces = PolyFaces::default();
        let tet: [&[u32]; 4] = [&[8, 9, 10], &[8, 11, 9], &[9, 11, 10], &[8, 10, 11]];
        faces.push(1, tet);
        let e = extract(&[12, 42], &[8, 12], &ids(12), Some(&faces)).unwrap();
        let cells = e.cells.unwrap();
        assert!(cells.types[1].is_polyhedron() && !e.unsupported);
        assert_eq!(cells.faces_of(1).unwrap().collect::<Vec<_>>(), tet.to_vec());
        assert_eq!(cells.nodes(1), &[8, 9, 10, 11]);
        assert!(extract(&[12, 42], &[8, 12], &ids(12), None).unwrap_err().contains("no faces"));

        // Linear tets and lower cells only: no block.
        assert!(extract(&[10, 5], &[4, 7], &ids(7), None).unwrap().cells.is_none());
    }

    #[test]
    fn bad_cells() {
        assert!(extract(&[10], &[5], &ids(5), None).unwrap_err().contains("5 points"));
        assert!(extract(&[24], &[9], &ids(9), None).is_err());
        assert!(extract(&[71], &[11], &ids(11), None).is_err());
        assert!(extract(&[12], &[9], &ids(9), None).unwrap_err().contains("9 points, which no hexahedron"));
        assert!(extract(&[200], &[4], &ids(4), None).unwrap_err().contains("200"));
        assert!(extract(&[10, 10], &[4, 3], &ids(4), None).unwrap_err().contains("decrease"));
        assert!(extract(&[10], &[4], &ids(8), None).unwrap_err().contains("end at 4"));
        assert!(extract(&[10], &[], &[], None).is_err());
        assert!(extract(&[], &[], &[], None).unwrap().tets.is_empty());
    }

    #[test]
    fn all_tets_fast_path() {
        let arr = |ty, v: &[i64]| {
            let (a, _) =
                num::parse_ascii(v.iter().map(|x| x.to_string()).collect::<Vec<_>>().join(" ").as_bytes(), ty, None)
                    .unwrap();
            a
        };
        let types = arr(num::NumType::U8, &[10, 10]);
        assert!(all_linear_tets(&types, &arr(num::NumType::I64, &[4, 8])));
        assert!(!all_linear_tets(&types, &arr(num::NumType::I32, &[4, 9])));
        assert!(!all_linear_tets(&types, &arr(num::NumType::I32, &[4])));
        assert!(!all_linear_tets(&arr(num::NumType::U8, &[10, 24]), &arr(num::NumType::I32, &[4, 8])));
        let e = Extracted::all_tets((0..8).collect());
        assert_eq!(e.tets, vec![[0, 1, 2, 3], [4, 5, 6, 7]]);
        assert!(e.kept.is_none() && e.higher_order.is_none() && e.cells.is_none());
    }

    #[test]
    fn cell_lists_from_arrays() {
        // Linear tets: the fast path, no block.
        let e = from_cell_list(&[10, 10], &[0, 4, 8], &ids(8)).unwrap();
        assert_eq!(e.tets, vec![[0, 1, 2, 3], [4, 5, 6, 7]]);
        assert!(e.cells.is_none() && e.other.is_empty());
        // A hexahedron and a quadratic tet: every cell in the block, as a file's.
        let e = from_cell_list(&[12, 24], &[0, 8, 18], &ids(18)).unwrap();
        assert_eq!(e.cells.as_ref().map(CellBlock::len), Some(2));
        assert_eq!((e.tets, e.higher_order), (vec![[8, 9, 10, 11]], Some(2)));
        // Arrays are the volume: a triangle is refused where a file's is dropped.
        let err = from_cell_list(&[10, 5], &[0, 4, 7], &ids(7)).unwrap_err();
        assert!(err.contains("cell 1 has VTK cell type 5 with 3 points, which is not a volume cell"), "{err}");
        let err = from_cell_list(&[12, 42], &[0, 8, 12], &ids(12)).unwrap_err();
        assert!(err.contains("cell 1 is a polyhedron (VTK cell type 42)"), "{err}");
        // Offsets: one more than the types, from 0 to the connectivity's end, never decreasing.
        assert!(from_cell_list(&[10], &[0], &ids(4)).unwrap_err().contains("expected one more"));
        assert!(from_cell_list(&[10], &[1, 4], &ids(4)).unwrap_err().contains("expected 0 to"));
        assert!(from_cell_list(&[10, 10], &[0, 5, 4], &ids(4)).unwrap_err().contains("decrease at cell 1"));
    }
}
