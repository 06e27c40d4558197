//! Mixed meshes on every backend: the one wrapper that turns a backend's answers in the
//! conforming tet decomposition ([`crate::mesh::Cells`]) into VTK's answers on the cells.
//!
//! For each point, with `t` the decomposition tet the backend found:
//! 1. `t`'s cell `C` answers, unless `C` has a warped quad face and the point lies within
//!    that face's *gap* of it: the decomposition and the bilinear face differ only in a
//!    sliver within `g = |a − b + c − d| / 4` of the face's two triangles (the largest
//!    distance between the bilinear patch and its split), so farther points need no more.
//! 2. Near a warped face, `C`'s parametric coordinates (Newton, f64, by its corners) decide:
//!    inside `C`'s domain → `C`; outside through warped faces → the neighbour across one of
//!    them that holds the point (all violated faces are tried), or outside when one of them is
//!    on the boundary; otherwise `C` (a point inside the mesh is never "outside").
//! 3. A point in no tet may still lie in a cell whose warped boundary face bulges out of the
//!    decomposition: the cells with a warped boundary face whose box holds it are tested by
//!    Newton (the smallest id that holds it answers).
//!
//! Values: per-vertex fields with the cell's own shape functions at its parametric
//! coordinates (all its nodes for higher-order cells); per-cell fields looked up by cell id.
//! Where Newton fails (a singular Jacobian: a degenerate cell, a pyramid's apex) the value is
//! interpolated linearly in the decomposition tet.
//!
//! Meshes of tets only pass through untouched. GPU kernels answer decomposition tet ids
//! only: values on mixed meshes are always computed here, on the CPU.

use super::{check_sample_lengths, BatchLocator, GridSampler, LineTracer, Points, Values, OUTSIDE};
use crate::bvh::{Aabb, BuildPreset, Bvh, Visitor};
use crate::cell::{face_split, interpolate, invert, PCoords, Point};
use crate::error::Result;
use crate::geom::{self, Real, Vec3};
use crate::mesh::{Cells, Field, FieldLocation, Mesh};
use rayon::prelude::*;
use std::sync::{Arc, OnceLock};

/// Where a point is: its cell, and its parametric coordinates there when they were computed
/// (or, in a polyhedron, the decomposition tet that holds it).
#[derive(Clone, Copy, Debug)]
struct Found {
    cell: usize,
    pc: Option<PCoords>,
    tet: Option<usize>,
}

/// Any backend on a mixed mesh: ids are cell ids, values come from the cells' shape functions
/// (see the module documentation). Meshes without cells pass through to `inner`.
pub struct CellLocator<L> {
    inner: L,
    mesh: Arc<Mesh>,
    bulges: OnceLock<Bulges>,
}

impl<L: BatchLocator> CellLocator<L> {
    /// `inner` must locate in `mesh`'s tets.
    pub fn new(inner: L, mesh: Arc<Mesh>) -> Self {
        CellLocator { inner, mesh, bulges: OnceLock::new() }
    }

    pub fn inner(&self) -> &L {
        &self.inner
    }

    pub fn into_inner(self) -> L {
        self.inner
    }

    fn refine_all(&self, points: &[Point], tets: &[i32]) -> Vec<Option<Found>> {
        let cells = self.mesh.cells.as_ref().expect("called on mixed meshes");
        let mesh = &self.mesh;
        // The lazy structures are made before the parallel loop: their builds run on rayon
        // too, and a worker waiting in one could be handed another point of the loop and
        // re-enter the OnceLock it is initialising (a deadlock).
        if cells.warped.par_iter().any(|&w| w != 0) {
            cells.warped_neighbors();
            if tets.par_iter().any(|&t| t < 0) {
                self.bulges.get_or_init(|| Bulges::build(mesh, cells));
            }
        }
        let bulges = self.bulges.get();
        points.par_iter().zip(tets.par_iter()).map(|(&p, &t)| refine(mesh, cells, bulges, p, t)).collect()
    }
}

/// Step 1–3 of the module documentation for one point.
/// `p` in the file's coordinates, as every step below (the backends searched the working copy).
fn refine(mesh: &Mesh, cells: &Cells, bulges: Option<&Bulges>, p: Point, t: i32) -> Option<Found> {
    if !p.iter().all(|c| c.is_finite()) {
        return None;
    }
    if t < 0 {
        return bulges.and_then(|b| b.find(mesh, cells, p));
    }
    let c = cells.cell_of(t as usize);
    let warped = cells.warped[c];
    if warped == 0 || !near_warped_face(mesh, cells, c, warped, p) {
        return Some(Found { cell: c, pc: None, tet: Some(t as usize) });
    }
    let p64 = p;
    let Some(pc) = pcoords(mesh, cells, c, p64) else {
        return Some(Found { cell: c, pc: None, tet: Some(t as usize) });
    };
    let shape = cells.block.types[c].shape();
    if shape.contains(pc) {
        return Some(Found { cell: c, pc: Some(pc), tet: None });
    }
    let neighbors = &cells.warped_neighbors()[c];
    let mut through_boundary = false;
    for (face, _) in shape.violated(pc) {
        let Some(f) = face.map(usize::from) else { continue };
        if warped & (1 << f) == 0 {
            continue;
        }
        let n = neighbors[f];
        if n < 0 {
            through_boundary = true;
            continue;
        }
        let n = n as usize;
        if let Some(pn) = pcoords(mesh, cells, n, p64).filter(|&pn| cells.block.types[n].shape().contains(pn)) {
            return Some(Found { cell: n, pc: Some(pn), tet: None });
        }
    }
    // Out through a warped boundary face: outside, as VTK says. Otherwise the decomposition's
    // cell keeps the point (a point inside the mesh is never "outside").
    (!through_boundary).then_some(Found { cell: c, pc: Some(pc), tet: None })
}

/// `p`'s parametric coordinates in cell `c`, located by its corners (`None`: Newton failed,
/// or a polyhedron, which has none); `p` and the corners in the file's coordinates.
fn pcoords(mesh: &Mesh, cells: &Cells, c: usize, p: Point) -> Option<PCoords> {
    if cells.block.types[c].is_polyhedron() {
        return None;
    }
    let corners: Vec<Point> = cells.block.corners(c).iter().map(|&i| mesh.vertex64(i)).collect();
    invert(cells.block.types[c].shape().linear, &corners, p).ok()
}

/// Whether `p` is within the gap of one of the faces in `faces` (a bit set) of cell `c`: only
/// there can the decomposition and the cell's bilinear faces disagree.
fn near_warped_face(mesh: &Mesh, cells: &Cells, c: usize, faces: u8, p: Point) -> bool {
    let shape = cells.block.types[c].shape();
    let ids = cells.block.corners(c);
    let x = |k: u8| mesh.vertex64(ids[usize::from(k)]);
    (0..shape.faces.len()).filter(|&f| faces & (1 << f) != 0).any(|f| {
        let face = shape.faces[f];
        let q = [x(face[0]), x(face[1]), x(face[2]), x(face[3])];
        let twist: Point = std::array::from_fn(|k| q[0][k] - q[1][k] + q[2][k] - q[3][k]);
        let scale = q.iter().chain([&p]).flat_map(|v| v.iter()).fold(0.0f64, |m, v| m.max(v.abs()));
        // Rounding of the f32 tet tests and of these f64 distances, well covered.
        let gap = norm(twist) / 4.0 * (1.0 + 1e-9) + 1e-12 * scale;
        face_split(face, ids).iter().any(|&[a, b, c]| {
            let (a, b, c) = (x(a), x(b), x(c));
            let n = cross(sub(b, a), sub(c, a));
            let len = norm(n);
            len == 0.0 || dot(n, sub(p, a)).abs() <= gap * len
        })
    })
}

fn sub(a: Point, b: Point) -> Point {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: Point, b: Point) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: Point, b: Point) -> Point {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn norm(a: Point) -> f64 {
    dot(a, a).sqrt()
}

/// The cells with a warped boundary face, by their boxes: where points outside the
/// decomposition may still be inside a cell.
struct Bulges {
    cells: Vec<u32>,
    bvh: Bvh,
}

impl Bulges {
    fn build(mesh: &Mesh, cells: &Cells) -> Bulges {
        let ids: Vec<u32> =
            (0..cells.len() as u32).into_par_iter().filter(|&c| cells.has_warped_boundary(c as usize)).collect();
        let boxes: Vec<Aabb> = ids
            .par_iter()
            .map(|&c| {
                // A cell lies in its corners' box (a bilinear face in its corners' hull), in
                // the working copy up to rounding: grown by a few of its ulps.
                let corners: Vec<Vec3> =
                    cells.block.corners(c as usize).iter().map(|&i| mesh.points[i as usize]).collect();
                let b = Aabb::of_points(&corners);
                let grow = (0..3).map(|k| b.min[k].abs().max(b.max[k].abs())).fold(0f32, f32::max) * 1e-6;
                Aabb { min: b.min.map(|x| x - grow), max: b.max.map(|x| x + grow) }
            })
            .collect();
        Bulges { bvh: Bvh::build_boxes(&boxes, BuildPreset::Fast), cells: ids }
    }

    /// The smallest cell id among the bulging cells that hold `p` (file coordinates).
    fn find(&self, mesh: &Mesh, cells: &Cells, p: Point) -> Option<Found> {
        struct Search<'a> {
            b: &'a Bulges,
            mesh: &'a Mesh,
            cells: &'a Cells,
            p: Point,
            working: Vec3,
            best: Option<Found>,
        }
        impl Visitor for Search<'_> {
            fn enter(&mut self, b: &Aabb) -> bool {
                b.contains(self.working)
            }
            fn prim(&mut self, id: u32) -> bool {
                let c = self.b.cells[id as usize] as usize;
                if self.best.is_some_and(|b| b.cell <= c) {
                    return false;
                }
                let (cells, mesh) = (self.cells, self.mesh);
                let n = &cells.warped_neighbors()[c];
                let boundary =
                    (0..6).filter(|&f| cells.warped[c] & (1 << f) != 0 && n[f] < 0).fold(0u8, |m, f| m | 1 << f);
                if !near_warped_face(mesh, cells, c, boundary, self.p) {
                    return false;
                }
                let pc = pcoords(mesh, cells, c, self.p);
                if let Some(pc) = pc.filter(|&pc| cells.block.types[c].shape().contains(pc)) {
                    self.best = Some(Found { cell: c, pc: Some(pc), tet: None });
                }
                false
            }
        }
        let mut s = Search { b: self, mesh, cells, p, working: mesh.info.frame.to_working(p), best: None };
        self.bvh.traverse(&mut s);
        s.best
    }
}

/// The value of `field` at `p` where it was found, in f32 (the f32 values) or f64 (the file's
/// values): shape functions in f64 either way.
fn value<T: Real>(mesh: &Mesh, cells: &Cells, field: &Field, p: Point, found: &Found) -> T {
    let c = found.cell;
    match field.location {
        FieldLocation::Cell => field.value_in(c),
        FieldLocation::Vertex => match found.pc.or_else(|| pcoords(mesh, cells, c, p)) {
            Some(pc) => {
                let nodes = cells.block.nodes(c);
                let def = cells.block.types[c].def();
                T::from_f64(interpolate(def, pc, |i| field.value_in::<T>(nodes[i] as usize).to_f64()))
            }
            // A polyhedron (its decomposition is the cell, with values at its centroids), or
            // Newton failed: linearly in the decomposition tet that holds the point.
            None if found.tet.is_some() || cells.block.types[c].is_polyhedron() => {
                let t = found.tet.filter(|&t| cells.cell_of(t) == c).unwrap_or_else(|| nearest_tet(mesh, cells, c, p));
                mesh.bary64(t, p).map_or(T::NAN, |b| {
                    T::from_f64(geom::interpolate_with(mesh.tets[t], b, |i| field.value_in::<T>(i).to_f64()))
                })
            }
            None => {
                let tets = &mesh.tets[cells.tets_of(c)];
                let w = mesh.info.frame.to_working(p);
                let held = tets.iter().find_map(|&t| Some((t, geom::point_in_tet(t, &mesh.points, w)?)));
                held.map_or(T::NAN, |(t, bary)| {
                    geom::interpolate_with(t, bary.map(|b| T::from_f64(b.into())), |i| field.value_in(i))
                })
            }
        },
    }
}

/// The (vertex, weight) pairs whose Σ weight · value is [`value`] of a per-vertex field at `p`
/// (file coordinates) in cell `c` of a mixed mesh: the cell's shape functions at its
/// parametric coordinates, or the barycentrics of its decomposition tet that holds `p` where
/// Newton fails (no pair when none holds it: [`value`] is NaN there too).
pub(crate) fn cell_weights(mesh: &Mesh, cells: &Cells, c: usize, p: Point, mut push: impl FnMut(u32, f64)) {
    match pcoords(mesh, cells, c, p) {
        Some(pc) => {
            let nodes = cells.block.nodes(c);
            let def = cells.block.types[c].def();
            let mut w = vec![0.0; def.n_nodes()];
            def.shape_functions(pc, &mut w);
            nodes.iter().zip(w).for_each(|(&id, w)| push(id, w));
        }
        None => {
            let tets = &mesh.tets[cells.tets_of(c)];
            let working = mesh.info.frame.to_working(p);
            if let Some((t, bary)) = tets.iter().find_map(|&t| Some((t, geom::point_in_tet(t, &mesh.points, working)?)))
            {
                t.iter().zip(bary).for_each(|(&id, b)| push(id, f64::from(b)));
            }
        }
    }
}

/// The tet of cell `c`'s decomposition that holds `p` (file coordinates), or the one it is
/// least outside of (a point on the cell's boundary, by rounding just off it).
fn nearest_tet(mesh: &Mesh, cells: &Cells, c: usize, p: Point) -> usize {
    let depth = |t: usize| -> f64 {
        let ids = mesh.tets[t];
        let x = ids.map(|i| mesh.vertex64(i));
        // The smallest signed barycentric, unclamped: orient3d ratios.
        let vol = geom::predicates::orient3d(x[0], x[1], x[2], x[3]);
        (0..4)
            .map(|k| {
                let mut y = x;
                y[k] = p;
                geom::predicates::orient3d(y[0], y[1], y[2], y[3]) / vol
            })
            .fold(f64::INFINITY, f64::min)
    };
    cells.tets_of(c).max_by(|&a, &b| depth(a).total_cmp(&depth(b))).expect("a cell has tets")
}

/// The value of `field` at the point `p` (working coordinates) of cell `c` (for the boundary
/// tolerance: `p` is a point of `c`'s boundary). `None` when the mesh has no cells.
pub(crate) fn value_in_cell(mesh: &Mesh, c: usize, p: Point, field: &Field) -> Option<f32> {
    let cells = mesh.cells.as_ref()?;
    let p = mesh.info.frame.to_file64(p);
    let found = Found { cell: c, pc: pcoords(mesh, cells, c, p), tet: None };
    Some(value(mesh, cells, field, p, &found))
}

impl<L: BatchLocator> BatchLocator for CellLocator<L> {
    fn name(&self) -> &str {
        self.inner.name()
    }

    /// The bulges kept (they are the geometry's).
    fn take_fields(&mut self, mesh: &Arc<Mesh>) -> bool {
        super::layer_takes_fields(&mut self.mesh, &mut self.inner, mesh)
    }

    fn preferred_batch(&self) -> Option<usize> {
        self.inner.preferred_batch()
    }

    /// Mixed meshes: the inner backend's tets (on f64 points its exact f64 path), refined to
    /// cells on the file's coordinates, and values from the cells' shape functions (in f64 on
    /// the file's values for f64 values).
    fn query(&mut self, points: Points<'_>, fields: &[&str], ids: &mut [i32], values: Values<'_>) -> Result<()> {
        if self.mesh.cells.is_none() {
            return self.inner.query(points, fields, ids, values);
        }
        match values {
            Values::F32(v) => self.sample_cells(points, fields, ids, v),
            Values::F64(v) => self.sample_cells(points, fields, ids, v),
        }
    }

    /// Only on pure tet meshes: a backend's own sampler answers in tets.
    fn grid_sampler(&mut self) -> Option<&mut dyn GridSampler> {
        match self.mesh.cells {
            Some(_) => None,
            None => self.inner.grid_sampler(),
        }
    }

    /// Only on pure tet meshes: a backend's own tracer interpolates in tets.
    fn line_tracer(&mut self) -> Option<&mut dyn LineTracer> {
        match self.mesh.cells {
            Some(_) => None,
            None => self.inner.line_tracer(),
        }
    }
}

impl<L: BatchLocator> CellLocator<L> {
    /// Ids and values on a mixed mesh, in either precision.
    fn sample_cells<T: Real>(
        &mut self,
        points: Points,
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [T],
    ) -> Result<()> {
        let n = points.len();
        check_sample_lengths(n, fields.len(), ids.len(), values.len())?;
        let mesh = self.mesh.clone();
        let fields: Vec<&Field> = fields.iter().map(|f| mesh.field(f)).collect::<Result<_>>()?;
        self.inner.query(points, &[], ids, Values::none())?;
        let points = points.wide(0..n);
        let found = self.refine_all(&points, ids);
        let cells = mesh.cells.as_ref().expect("checked above");
        let k = fields.len();
        ids.par_iter_mut().zip(&found).for_each(|(id, f)| *id = f.map_or(OUTSIDE, |f| f.cell as i32));
        values.par_chunks_mut(k.max(1)).zip(points.par_iter().zip(&found)).for_each(|(out, (&p, f))| {
            for (v, field) in out.iter_mut().zip(&fields) {
                *v = f.as_ref().map_or(T::NAN, |f| value(&mesh, cells, field, p, f));
            }
        });
        Ok(())
    }
}

#[cfg(test)]
mod tests;
