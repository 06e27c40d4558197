//! The mesh model: f32 vertices in a working frame (and the file's f64 coordinates where
//! they differ), canonical u32×4 tets, named scalar fields, and what is derived from them
//! (bounds, edge lengths, shared faces).

mod cells;
mod faces;
pub mod field_groups;
mod neighbors;
pub mod steps;
mod summary;
#[cfg(test)]
mod tests;
mod tet_nodes;
mod vectors;

pub use cells::{tets_per_cell, Cells};
pub use faces::{Face, FaceSet};
// The working frame is the geometry's (geom::Exact takes it); the mesh keeps one.
pub use crate::geom::Frame;
pub use steps::{StepFields, TimeSteps};
pub use summary::{FieldSummary, MeshSummary};
pub use tet_nodes::TetNodes;
pub use vectors::VertexVectors;

use crate::cell::polyhedron::Means;
use crate::error::{Error, Result};
use crate::geom::{self, Vec3};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::{Arc, OnceLock};

/// Where a scalar field lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FieldLocation {
    /// One value per vertex, interpolated barycentrically.
    Vertex,
    /// One value per cell (tet, or the file's volume cell in a mixed mesh), constant inside it.
    Cell,
}

/// A named scalar field. Multi-component arrays in files become one field per component,
/// named `NAME[i]`.
#[derive(Clone, Debug)]
pub struct Field {
    pub name: String,
    pub location: FieldLocation,
    /// The values in f32 (the file's rounded to nearest): what the GPU kernels upload.
    pub values: Vec<f32>,
    /// The file's values, when it stored them in f64 and some do not round to f32 exactly
    /// (`None`: `values` is the file's data; f32 data pays nothing). Same length as `values`.
    pub values64: Option<Vec<f64>>,
}

impl Field {
    /// A field of f32 data.
    pub fn new(name: impl Into<String>, location: FieldLocation, values: Vec<f32>) -> Field {
        Field { name: name.into(), location, values, values64: None }
    }

    /// A field of f64 data: rounded to f32 for `values`, kept in `values64` unless that
    /// rounding is exact for every finite value.
    pub fn from_f64(name: impl Into<String>, location: FieldLocation, values64: Vec<f64>) -> Field {
        let values = values64.par_iter().map(|&x| x as f32).collect();
        Field { name: name.into(), location, values, values64: f64_if_needed(values64) }
    }

    /// Value `i` as the file has it (f64).
    #[inline]
    pub fn value64(&self, i: usize) -> f64 {
        match &self.values64 {
            Some(v) => v[i],
            None => f64::from(self.values[i]),
        }
    }

    /// Value `i` in precision `T`: f32 (`values`) or f64 ([`Self::value64`]).
    #[inline(always)]
    pub fn value_in<T: geom::Real>(&self, i: usize) -> T {
        T::pick(|| self.values[i], || self.value64(i))
    }

    /// The field of the `n` values at `index(0..n)`, in both precisions.
    pub fn select(&self, index: impl Fn(usize) -> usize + Sync, n: usize) -> Field {
        Field {
            name: self.name.clone(),
            location: self.location,
            values: (0..n).into_par_iter().map(|i| self.values[index(i)]).collect(),
            values64: self.values64.as_ref().map(|v| (0..n).into_par_iter().map(|i| v[index(i)]).collect()),
        }
    }

    /// Appends `other`'s values (f64 for both when either has them: f32 ones widen exactly).
    pub fn extend_from(&mut self, other: &Field) {
        if other.values64.is_some() || self.values64.is_some() {
            let mine = self.values64.get_or_insert_with(|| self.values.iter().map(|&x| f64::from(x)).collect());
            match &other.values64 {
                Some(v) => mine.extend_from_slice(v),
                None => mine.extend(other.values.iter().map(|&x| f64::from(x))),
            }
        }
        self.values.extend_from_slice(&other.values);
    }
}

/// f64 values, when some finite one does not round to f32 exactly (`None`: their f32 copy is
/// the data).
pub fn f64_if_needed(values: Vec<f64>) -> Option<Vec<f64>> {
    values.par_iter().any(|&x| x.is_finite() && (x as f32) as f64 != x).then_some(values)
}

/// What readers and generators produce: tets in file order (corner vertices only), not yet
/// validated. `Mesh::new` turns it into a usable mesh or a clear error.
#[derive(Clone, Debug, Default)]
pub struct RawMesh {
    /// The vertices in f32 (the file's coordinates rounded to nearest).
    pub points: Vec<Vec3>,
    /// The file's coordinates, when it stored them in f64 and some do not round to f32
    /// exactly (`None`: `points` is the file's data).
    pub points64: Option<Vec<[f64; 3]>>,
    /// The tets' corners, for a mesh of tets (of any order); empty when `cells` holds other types.
    pub tets: Vec<[u32; 4]>,
    pub fields: Vec<Field>,
    /// `Some(k)` when the file held cells of polynomial order k > 1 (located by their corners,
    /// interpolated with all their nodes).
    pub higher_order: Option<u8>,
    /// Every volume cell with all its nodes, in file order, when some cell is not a linear tet
    /// (`None` for linear tets only). Cell fields have one value per cell of this block. For a
    /// mesh of higher-order tets `tets` holds their corners and this block all their nodes.
    pub cells: Option<crate::cell::CellBlock>,
}

/// A file's f64 coordinates for `RawMesh::points64`: `None` when every one rounds to f32
/// exactly (then the f32 copy is the data).
pub fn points64_if_needed(points: Vec<[f64; 3]>) -> Option<Vec<[f64; 3]>> {
    needs_f64(&points).then_some(points)
}

/// Whether some finite coordinate of `points` does not round to f32 exactly.
pub fn needs_f64(points: &[[f64; 3]]) -> bool {
    use rayon::prelude::*;
    points.par_iter().any(|p| p.iter().any(|&x| x.is_finite() && (x as f32) as f64 != x))
}

/// Facts computed on load, reported by `tetloc info`.
#[derive(Clone, Debug, Serialize)]
pub struct MeshInfo {
    /// The file (or generator) the mesh came from; used in error messages.
    pub source: String,
    pub n_points: usize,
    /// The tets located in: the mesh's own, or the conforming decomposition of its cells.
    pub n_tets: usize,
    /// The file's volume cells (cell ids `0..n_cells`); `n_tets` for a mesh of tets.
    pub n_cells: usize,
    /// Cells by type name (VTK's names: "tetra", "hexahedron", "quadratic wedge", ...).
    pub cell_types: BTreeMap<String, usize>,
    /// Cells with a warped (non-planar) quad face: located with their own parametric
    /// coordinates near those faces.
    pub n_warped_cells: usize,
    /// The faces of the polyhedra (a face shared by two counted twice); polyhedra are counted
    /// in `cell_types` ("polyhedron").
    pub n_polyhedron_faces: usize,
    /// Points the mesh added after the file's (`n_points` of them): the polyhedra's face and
    /// cell centroids, corners of their decomposition.
    pub n_centroids: usize,
    /// Bounds of the vertices in the working frame (`frame`): the file's coordinates when
    /// the frame is the identity, which it is unless the mesh is far from the origin.
    pub bounds_min: Vec3,
    pub bounds_max: Vec3,
    /// Where the working f32 copy lives relative to the file's coordinates.
    pub frame: Frame,
    pub max_edge_length: f32,
    pub mean_edge_length: f32,
    /// Cells that were inverted in the file and have been reoriented (kept, not dropped).
    pub n_reoriented: usize,
    /// Cells with zero volume (repeated or coplanar vertices): they contain no point.
    pub n_degenerate: usize,
    /// Mixed cells that fold over themselves (their decomposition tets have volumes of both
    /// signs): located by their decomposition as they are; VTK's answers there may differ.
    pub n_tangled: usize,
    pub higher_order: Option<u8>,
    pub total_volume: f64,
}

/// A validated tetrahedral mesh, ready for point location.
///
/// Its geometry (points, tets, cells, faces, neighbours) sits behind `Arc`s: the meshes of a time
/// series' steps ([`Mesh::with_fields`]) share one copy, which none of them can change.
#[derive(Debug)]
pub struct Mesh {
    /// The vertices in the working frame (`info.frame`), f32: what every backend searches.
    pub points: Arc<Vec<Vec3>>,
    /// The file's f64 coordinates when the working copy is not exactly them (f64 data, or an
    /// f32 file far from the origin, widened): exact decisions use them where the f32 filter
    /// cannot decide.
    pub points64: Option<Arc<Vec<[f64; 3]>>>,
    /// Tets in file order, each in canonical vertex order (see [`geom::canonical_tet`]).
    pub tets: Arc<Vec<[u32; 4]>>,
    pub fields: Vec<Field>,
    /// The nodes of higher-order tets beyond their corners (`None`: linear tets, or a mixed mesh).
    pub tet_nodes: Option<TetNodes>,
    /// A mesh with cells other than tets: the cells, and the map from `tets` (their conforming
    /// decomposition) to them. `None` for a mesh of tets: it pays nothing for mixed cells.
    pub cells: Option<Arc<Cells>>,
    pub info: MeshInfo,
    /// A mesh with polyhedra: the file points each centroid is the mean of, for every step's
    /// point data there.
    means: Option<Arc<Means>>,
    /// Shared by the meshes of one geometry ([`Mesh::with_fields`]), as computed by the first.
    faces: Arc<OnceLock<FaceSet>>,
    neighbors: Arc<OnceLock<Vec<[i32; 4]>>>,
    /// Which geometry this is: a number of its own from [`Mesh::new`], shared by the meshes
    /// [`Mesh::with_fields`] makes from it ([`Mesh::same_geometry`]).
    geometry: u64,
}

/// The numbers [`Mesh::new`] gives each geometry.
static GEOMETRIES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Refuses fields whose lengths do not fit the mesh (one value a file point or a cell), and
/// gives the per-vertex ones their values at the polyhedra's centroids (`means`): the means of
/// the values they are the means of.
fn complete_fields(
    fields: &mut [Field],
    n_points: usize,
    n_cells: usize,
    means: Option<&Means>,
    err: impl Fn(String) -> Error,
) -> Result<()> {
    for f in fields.iter() {
        let want = match f.location {
            FieldLocation::Vertex => n_points,
            FieldLocation::Cell => n_cells,
        };
        if f.values.len() != want {
            return Err(err(format!(
                "field '{}' has {} values, expected {want} (one per {:?})",
                f.name,
                f.values.len(),
                f.location
            )));
        }
        if let Some(v) = f.values64.as_ref().filter(|v| v.len() != want) {
            return Err(err(format!("field '{}' has {} f64 values, expected {want}", f.name, v.len())));
        }
    }
    if let Some(means) = means {
        for f in fields.iter_mut().filter(|f| f.location == FieldLocation::Vertex) {
            let file: Vec<f64> = (0..n_points).map(|i| f.value64(i)).collect();
            f.extend_from(&Field::from_f64(f.name.clone(), f.location, means.extend_values(&file)));
        }
    }
    Ok(())
}

impl Mesh {
    /// Validates a raw mesh: indices in range, finite coordinates, field sizes; reorients
    /// inverted tets; counts degenerate ones; computes bounds and edge lengths.
    pub fn new(raw: RawMesh, source: impl Into<String>) -> Result<Mesh> {
        let source = source.into();
        let err = |msg: String| Error::Mesh { source_name: source.clone(), msg };
        let RawMesh { mut points, mut points64, mut tets, mut fields, higher_order, cells } = raw;
        let is_mixed = cells.as_ref().is_some_and(|c| c.non_tet_counts().is_some());
        if tets.is_empty() && !is_mixed {
            return Err(err("the mesh has no tetrahedra".into()));
        }
        if points.len() > u32::MAX as usize {
            return Err(err(format!("{} vertices: more than u32 indices can address", points.len())));
        }
        if let Some(i) = crate::par::first_position(&points, |p| !p.iter().all(|c| c.is_finite())) {
            return Err(err(format!(
                "vertex {i} has a non-finite coordinate ({:?}) (or one too large for f32)",
                points[i]
            )));
        }
        if let Some(p64) = &points64 {
            if p64.len() != points.len() {
                return Err(err(format!("{} f64 vertices for {} f32 ones", p64.len(), points.len())));
            }
            if let Some(i) = crate::par::first_position(p64, |p| !p.iter().all(|&c| geom::predicates::in_domain(c))) {
                return Err(err(format!(
                    "vertex {i} has a coordinate outside what exact arithmetic supports ({:?}: 0 or 2^-240 to 2^240 in magnitude)",
                    p64[i]
                )));
            }
        }
        // Polyhedra: their decomposition adds centroids after the file's points.
        let n_file_points = points.len();
        let poly = match cells.as_ref().filter(|c| !c.polyhedra.is_empty()) {
            Some(block) => {
                let file = |i: u32| match &points64 {
                    Some(p) => p[i as usize],
                    None => points[i as usize].map(f64::from),
                };
                Some(crate::cell::polyhedron::decompose_all(&block.polyhedra, n_file_points, &file).map_err(err)?)
            }
            None => None,
        };
        if let Some(d) = &poly {
            let mut file = points64.take().unwrap_or_else(|| points.par_iter().map(|p| p.map(f64::from)).collect());
            file.extend_from_slice(&d.points);
            points = file.par_iter().map(|p| p.map(|x| x as f32)).collect();
            points64 = points64_if_needed(file);
        }
        // Mixed meshes too: backends search the working copy, and the cells' parametric
        // coordinates are solved on the file's f64 coordinates (locate::CellLocator).
        let (points, points64, frame) = working_copy(points, points64);
        // A mixed mesh: its tets are its cells' conforming decomposition, mapped back to them.
        let (mut mixed, mut cells, mut cell_repairs) = (None, cells, None);
        if is_mixed {
            let block = cells.take().expect("a mixed mesh has cells");
            let built = Cells::build(block, &points, poly.as_ref()).map_err(err)?;
            tets = built.tets;
            cell_repairs = Some((built.reoriented, built.degenerate, built.tangled));
            mixed = Some(built.cells);
        }
        let n = points.len() as u32;
        if let Some(t) = crate::par::first_position(&tets, |t| t.iter().any(|&i| i >= n)) {
            return Err(err(format!(
                "tet {t} references vertex {} but the mesh has only {n} vertices",
                tets[t].iter().max().unwrap()
            )));
        }
        let n_cells = mixed.as_ref().map_or(tets.len(), Cells::len);
        let means = poly.map(|d| Arc::new(d.means));
        complete_fields(&mut fields, n_file_points, n_cells, means.as_deref(), err)?;

        // Higher-order nodes follow their corners into canonical order.
        let tet_nodes = match &cells {
            Some(cells) if higher_order.is_some() => {
                let canonical: Vec<[u32; 4]> = tets.par_iter().map(|&t| geom::canonical_tet(t, &points).0).collect();
                TetNodes::build(cells, &tets, &canonical, points.len()).map_err(err)?
            }
            _ => None,
        };
        drop(cells);

        // Canonical order; count inversions and degenerates; accumulate bounds and edges.
        #[derive(Clone, Copy)]
        struct Acc {
            reoriented: usize,
            degenerate: usize,
            max_edge2: f32,
            sum_edge: f64,
            volume: f64,
        }
        let zero = Acc { reoriented: 0, degenerate: 0, max_edge2: 0.0, sum_edge: 0.0, volume: 0.0 };
        // Fixed chunks, summed in order: the f64 sums (volume, edge lengths) do not depend on
        // how rayon splits the work, so the same file gives the same info on every run.
        let per_tet = |mut a: Acc, t: &mut [u32; 4]| {
            let (canon, vol6) = match &points64 {
                Some(file) => geom::canonical_tet_exact(*t, file),
                None => geom::canonical_tet(*t, &points),
            };
            *t = canon;
            if vol6 < 0.0 {
                a.reoriented += 1;
            } else if vol6 == 0.0 {
                a.degenerate += 1;
            }
            a.volume += vol6.abs() / 6.0;
            for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                let (p, q) = (points[t[i] as usize], points[t[j] as usize]);
                let e2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2);
                a.max_edge2 = a.max_edge2.max(e2);
                a.sum_edge += (e2 as f64).sqrt();
            }
            a
        };
        let combine = |a: Acc, b: Acc| Acc {
            reoriented: a.reoriented + b.reoriented,
            degenerate: a.degenerate + b.degenerate,
            max_edge2: a.max_edge2.max(b.max_edge2),
            sum_edge: a.sum_edge + b.sum_edge,
            volume: a.volume + b.volume,
        };
        let chunks: Vec<Acc> = tets.par_chunks_mut(1 << 14).map(|c| c.iter_mut().fold(zero, per_tet)).collect();
        let acc = chunks.into_iter().fold(zero, combine);
        // Bounds over the vertices that tets use (unused vertices do not widen the box).
        let (bounds_min, bounds_max) = tets.par_iter().map(|&t| geom::tet_bounds(t, &points)).reduce(
            || ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
            |(a0, a1), (b0, b1)| (std::array::from_fn(|k| a0[k].min(b0[k])), std::array::from_fn(|k| a1[k].max(b1[k]))),
        );
        let info = MeshInfo {
            source,
            n_points: n_file_points,
            n_tets: tets.len(),
            n_cells,
            cell_types: match (&mixed, &tet_nodes) {
                (Some(c), _) => c.type_counts(),
                (None, Some(nodes)) => [(nodes.cell_type().def().name().to_string(), tets.len())].into(),
                (None, None) => [("tetra".to_string(), tets.len())].into(),
            },
            n_warped_cells: mixed.as_ref().map_or(0, Cells::n_warped),
            n_polyhedron_faces: mixed.as_ref().map_or(0, |c| c.polyhedra().1),
            n_centroids: points.len() - n_file_points,
            bounds_min,
            bounds_max,
            frame,
            max_edge_length: acc.max_edge2.sqrt(),
            mean_edge_length: (acc.sum_edge / (6.0 * tets.len() as f64)) as f32,
            n_reoriented: cell_repairs.map_or(acc.reoriented, |r| r.0),
            n_degenerate: cell_repairs.map_or(acc.degenerate, |r| r.1),
            n_tangled: cell_repairs.map_or(0, |r| r.2),
            higher_order,
            total_volume: acc.volume,
        };
        Ok(Mesh {
            points: Arc::new(points),
            points64: points64.map(Arc::new),
            tets: Arc::new(tets),
            fields,
            tet_nodes,
            cells: mixed.map(Arc::new),
            info,
            means,
            faces: Arc::default(),
            neighbors: Arc::default(),
            geometry: GEOMETRIES.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        })
    }

    /// This mesh with `fields` in place of its own: another time step of it. Its geometry
    /// (and a mixed mesh's cells) is shared, so nothing is validated or reordered again: the
    /// fields are checked and completed as [`Mesh::new`] does it (their values at the
    /// polyhedra's centroids). A locator built on this mesh can take the new one's fields and
    /// keep its search structures (`BatchLocator::take_fields`).
    pub fn with_fields(&self, mut fields: Vec<Field>) -> Result<Mesh> {
        let err = |msg: String| Error::Mesh { source_name: self.info.source.clone(), msg };
        complete_fields(&mut fields, self.info.n_points, self.n_cells(), self.means.as_deref(), err)?;
        Ok(Mesh {
            points: self.points.clone(),
            points64: self.points64.clone(),
            tets: self.tets.clone(),
            fields,
            tet_nodes: self.tet_nodes.clone(),
            cells: self.cells.clone(),
            info: self.info.clone(),
            means: self.means.clone(),
            faces: self.faces.clone(),
            neighbors: self.neighbors.clone(),
            geometry: self.geometry,
        })
    }

    /// Whether `other` has this mesh's geometry: one of them was made from the other, or
    /// both from a third, by [`Mesh::with_fields`] (whose meshes share one geometry, which
    /// none can change).
    pub fn same_geometry(&self, other: &Mesh) -> bool {
        self.geometry == other.geometry
    }

    pub fn n_tets(&self) -> usize {
        self.tets.len()
    }

    /// The file's volume cells: the tets, or a mixed mesh's cells.
    pub fn n_cells(&self) -> usize {
        self.cells.as_ref().map_or(self.tets.len(), |c| c.len())
    }

    /// The cell that tet `t` is (a tet mesh) or belongs to (a mixed mesh's decomposition).
    #[inline]
    pub fn cell_of_tet(&self, t: usize) -> usize {
        self.cells.as_ref().map_or(t, |c| c.cell_of(t))
    }

    /// The field named `name`, or an error that lists the fields there are.
    pub fn field(&self, name: &str) -> Result<&Field> {
        self.fields.iter().find(|f| f.name == name).ok_or_else(|| Error::NoSuchField {
            name: name.to_string(),
            available: if self.fields.is_empty() {
                "none".to_string()
            } else {
                self.fields.iter().map(|f| format!("'{}'", f.name)).collect::<Vec<_>>().join(", ")
            },
        })
    }

    /// A per-vertex field's value (`value` of a vertex id) at barycentrics `bary` of tet `t`:
    /// barycentric for linear tets, with the tet's own shape functions (all its nodes, in
    /// f64) for higher-order ones.
    #[inline]
    pub fn interpolate_with<T: geom::Real>(&self, t: usize, bary: [T; 4], value: impl Fn(usize) -> T) -> T {
        match &self.tet_nodes {
            None => geom::interpolate_with(self.tets[t], bary, value),
            Some(nodes) => {
                T::from_f64(nodes.interpolate_with(t, self.tets[t], bary.map(T::to_f64), |i| value(i).to_f64()))
            }
        }
    }

    /// The (vertex, weight) pairs of [`Self::interpolate_with`] at f64 barycentrics `bary` of
    /// tet `t` (it is Σ weight · value): the barycentrics on the corners for linear tets, the
    /// tet's shape functions on all its nodes for higher-order ones.
    pub fn tet_weights(&self, t: usize, bary: geom::Bary64, mut push: impl FnMut(u32, f64)) {
        match &self.tet_nodes {
            None => self.tets[t].iter().zip(bary).for_each(|(&id, w)| push(id, w)),
            Some(nodes) => nodes.weights(t, self.tets[t], bary, push),
        }
    }

    /// [`Self::interpolate_with`] of f32 values.
    #[inline]
    pub fn interpolate(&self, t: usize, bary: geom::Bary, values: &[f32]) -> f32 {
        self.interpolate_with(t, bary, |i| values[i])
    }

    /// `field`'s value for a point at barycentrics `bary` of tet `t` (None: outside, NaN):
    /// interpolated for a per-vertex field, the tet's cell's value for a per-cell one. In f32
    /// (`T = f32`: the f32 values, what the GPU kernels compute) or f64 (`T = f64`: the file's
    /// values, [`Field::value64`]): one definition for both.
    #[inline]
    pub fn value_of<T: geom::Real>(&self, field: &Field, found: Option<(usize, [T; 4])>) -> T {
        match (found, field.location) {
            (None, _) => T::NAN,
            (Some((t, b)), FieldLocation::Vertex) => self.interpolate_with(t, b, |i| field.value_in(i)),
            // A mixed mesh's tets are its cells' decomposition: the value of the tet's cell.
            (Some((t, _)), FieldLocation::Cell) => field.value_in(self.cell_of_tet(t)),
        }
    }

    /// [`Self::value_of`] in f32.
    #[inline]
    pub fn value_at(&self, field: &Field, found: Option<(usize, geom::Bary)>) -> f32 {
        self.value_of(field, found)
    }

    /// [`Self::value_at`] of each of `fields` into `out`.
    #[inline]
    pub fn values_at(&self, fields: &[&Field], found: Option<(usize, geom::Bary)>, out: &mut [f32]) {
        out.iter_mut().zip(fields).for_each(|(o, f)| *o = self.value_at(f, found));
    }

    /// [`Self::value_of`] in f64, on the file's values ([`Field::value64`]). Every
    /// backend's f64 values are this, at the barycentrics of [`Self::bary64`].
    #[inline]
    pub fn value_at64(&self, field: &Field, found: Option<(usize, geom::Bary64)>) -> f64 {
        self.value_of(field, found)
    }

    /// The f64 barycentrics of a point given in the file's coordinates in tet `t`, on the
    /// file's coordinates ([`geom::bary64`]); `None` for a zero-volume tet.
    #[inline]
    pub fn bary64(&self, t: usize, p: [f64; 3]) -> Option<geom::Bary64> {
        geom::bary64(self.tets[t], &self.points, &self.exact(), p)
    }

    /// The f64 values of `fields` (point after point) for points given in the file's
    /// coordinates and their tets (`ids`, -1 outside): what every f64 path computes once the
    /// tets are known; `T = f32` rounds them for an f32 output.
    pub fn values_at_ids64<T: geom::Real>(&self, points: &[[f64; 3]], ids: &[i32], fields: &[&Field], out: &mut [T]) {
        let k = fields.len();
        if k == 0 {
            return;
        }
        out.par_chunks_mut(k).zip(points.par_iter().zip(ids)).for_each(|(o, (&p, &t))| {
            let found = (t >= 0).then(|| self.bary64(t as usize, p).map(|b| (t as usize, b))).flatten();
            o.iter_mut().zip(fields).for_each(|(o, f)| *o = T::from_f64(self.value_at64(f, found)));
        });
    }

    /// [`Self::values_at_ids64`] of the points of one line, in order, on one core: a line's
    /// consecutive points mostly share a tet (a tracer steps a fraction of one), so each run
    /// of them reads the tet's corners and the fields' values there once. The same numbers.
    pub fn values_along64<T: geom::Real>(&self, points: &[[f64; 3]], ids: &[i32], fields: &[&Field], out: &mut [T]) {
        let k = fields.len();
        if k == 0 {
            return;
        }
        if self.tet_nodes.is_some() {
            // Higher-order tets interpolate on all their nodes: no corners to keep.
            for ((o, &p), &t) in out.chunks_mut(k).zip(points).zip(ids) {
                let found = (t >= 0).then(|| self.bary64(t as usize, p).map(|b| (t as usize, b))).flatten();
                o.iter_mut().zip(fields).for_each(|(o, f)| *o = T::from_f64(self.value_at64(f, found)));
            }
            return;
        }
        let exact = self.exact();
        // The tet of the run, its corners, and each field's values at its corners (a per-cell
        // field's value repeated) in the order of `self.tets[t]`.
        let mut held: Option<(i32, geom::Corners64)> = None;
        let mut corner_values = vec![[0f64; 4]; k];
        for ((o, &p), &t) in out.chunks_mut(k).zip(points).zip(ids) {
            if t < 0 {
                o.fill(T::from_f64(f64::NAN));
                continue;
            }
            let tet = self.tets[t as usize];
            let corners = match held {
                Some((h, c)) if h == t => c,
                _ => {
                    let c = geom::Corners64::of(tet, &self.points, &exact);
                    for (v, f) in corner_values.iter_mut().zip(fields) {
                        *v = match f.location {
                            FieldLocation::Vertex => tet.map(|i| f.value_in(i as usize)),
                            FieldLocation::Cell => [f.value_in(self.cell_of_tet(t as usize)); 4],
                        };
                    }
                    held = Some((t, c));
                    c
                }
            };
            let bary = corners.bary64(p);
            for ((o, f), v) in o.iter_mut().zip(fields).zip(&corner_values) {
                // As value_of: interpolated at the corners, or the cell's value; NaN for a
                // tet of no volume.
                *o = T::from_f64(match (bary, f.location) {
                    (None, _) => f64::NAN,
                    (Some(b), FieldLocation::Vertex) => geom::interpolate_with([0, 1, 2, 3], b, |j| v[j]),
                    (Some(_), FieldLocation::Cell) => v[0],
                });
            }
        }
    }

    /// Unique faces with their front and back tets, computed on first use (a parallel sort
    /// of all 4·T tet faces: memory-hungry on huge meshes, so only when a kernel needs it).
    pub fn faces(&self) -> &FaceSet {
        self.faces.get_or_init(|| FaceSet::build(&self.tets))
    }

    /// For each tet and stored vertex i, the tet across the face opposite vertex i (-1 on
    /// the boundary). Computed on first use.
    pub fn neighbors(&self) -> &[[i32; 4]] {
        self.neighbors.get_or_init(|| neighbors::build(&self.tets))
    }

    /// The vertices' bounds in the file's coordinates (`info.bounds_*` are the working frame's).
    pub fn file_bounds(&self) -> ([f64; 3], [f64; 3]) {
        let f = &self.info.frame;
        (f.to_file(self.info.bounds_min), f.to_file(self.info.bounds_max))
    }

    /// The vertices' exact box in the file's coordinates ([`Self::file_bounds`] maps the
    /// working copy's bounds back, within its rounding). One pass over the f64 coordinates
    /// when the mesh has them; without them the working copy is the file's data.
    pub fn file_box(&self) -> ([f64; 3], [f64; 3]) {
        match &self.points64 {
            Some(p) => bounds_of(p, |p| *p),
            None => (self.info.frame.to_file(self.info.bounds_min), self.info.frame.to_file(self.info.bounds_max)),
        }
    }

    /// Whether the file's coordinates are not its f32 working copy (f64 data, or a centred
    /// frame: also f32 data far from the origin). Then f64 query points keep their precision
    /// (on f32 data near the origin, rounding them to f32 first keeps the f32 path, several
    /// times faster, and its answers), and answers decided on the copy (the GPU kernels') are
    /// checked on the file's data (`locate::certify`).
    pub fn wants_f64_points(&self) -> bool {
        self.points64.is_some() || !self.info.frame.is_identity()
    }

    /// Each vertex's file coordinates minus its working copy, in the working frame, rounded
    /// to f32; `None` when the working copy is the file's data. The two together give the
    /// file's coordinates to about 2⁻⁴⁸ of their size: what the GPU kernels interpolate with
    /// ([`geom::refined_bary`]), so that their values on slivers stored in f64 match the
    /// CPU's. (The difference is exact in f64: the copy is its rounding.)
    pub fn working_residuals(&self) -> Option<Vec<Vec3>> {
        let file = self.points64.as_ref()?;
        let frame = &self.info.frame;
        let residual = |(&x, w): (&[f64; 3], &Vec3)| -> Vec3 {
            let x = frame.to_working64(x);
            std::array::from_fn(|k| (x[k] - f64::from(w[k])) as f32)
        };
        Some(file.par_iter().zip(self.points.par_iter()).map(residual).collect())
    }

    /// Vertex `i` as the file has it (f64).
    #[inline]
    pub fn vertex64(&self, i: u32) -> [f64; 3] {
        match &self.points64 {
            Some(p) => p[i as usize],
            None => self.info.frame.to_file(self.points[i as usize]),
        }
    }

    /// The exact-decision context of `geom::test_point_with` for this mesh's tets.
    #[inline]
    pub fn exact(&self) -> geom::Exact<'_> {
        geom::Exact { file: self.points64.as_deref().map(Vec::as_slice), frame: &self.info.frame }
    }

    /// The centroid of tet `t`.
    pub fn tet_center(&self, t: usize) -> Vec3 {
        let ids = self.tets[t];
        let mut c = [0f32; 3];
        for &i in &ids {
            for (ck, pk) in c.iter_mut().zip(self.points[i as usize]) {
                *ck += pk;
            }
        }
        c.map(|x| x * 0.25)
    }
}

/// The working f32 copy of the vertices and its frame, and the file's f64 coordinates when
/// the copy is not exactly them (see [`Frame`]).
fn working_copy(points: Vec<Vec3>, points64: Option<Vec<[f64; 3]>>) -> (Vec<Vec3>, Option<Vec<[f64; 3]>>, Frame) {
    let file = match points64 {
        Some(file) => file,
        None if points.is_empty() => return (points, None, Frame::IDENTITY),
        None => {
            let (lo, hi) = bounds_of(&points, |p| p.map(f64::from));
            let frame = Frame::for_bounds(lo, hi);
            if frame.is_identity() {
                // f32 data near the origin is its own working copy; the frame's delta bounds
                // the rounding of f64 queries to it.
                return (points, None, frame);
            }
            // f32 data far from the origin (or tiny, or huge): its f32 copy would round f64
            // queries by up to half an ulp of the distance from the origin, far more than
            // the cells' size allows. Its coordinates widen to f64 exactly and take the f64
            // data's path: a centred working copy, exact decisions on the file's values.
            points.par_iter().map(|p| p.map(f64::from)).collect()
        }
    };
    if file.is_empty() {
        return (points, None, Frame::IDENTITY);
    }
    let (lo, hi) = bounds_of(&file, |p| *p);
    let frame = Frame::for_bounds(lo, hi);
    let working: Vec<Vec3> = file.par_iter().map(|&p| frame.to_working(p)).collect();
    let exact = frame.is_identity() && file.par_iter().zip(&working).all(|(p, w)| w.map(f64::from) == *p);
    if exact {
        (working, None, frame)
    } else {
        (working, Some(file), frame)
    }
}

/// The f64 bounds of points (infinite ones for none).
fn bounds_of<P: Sync>(points: &[P], f64_of: impl Fn(&P) -> [f64; 3] + Sync) -> ([f64; 3], [f64; 3]) {
    points.par_iter().map(|p| (f64_of(p), f64_of(p))).reduce(
        || ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
        |(a0, a1), (b0, b1)| (std::array::from_fn(|k| a0[k].min(b0[k])), std::array::from_fn(|k| a1[k].max(b1[k]))),
    )
}
