//! Synthetic meshes shaped like the paper's data sets (Wald et al. 2019, Fig. 4 and §6):
//!
//! | shape | like | occupancy of the bounding box |
//! |---|---|---|
//! | `jets` | Jets: fills a box, graded towards the jet axis and the inflow | 100 % |
//! | `fusion` | Fusion: a tokamak torus, ~10× finer near its centre line | ~54 % |
//! | `agulhas` | Agulhas: an ocean layer over a bathymetry, with continents as holes | ~49 % |
//! | `japan` | Japan: a thin curved sheet of varying thickness in a large box | ~7 % |
//!
//! All are structured grids of columns split into Kuhn tets (see `grid.rs` for why that is
//! conforming and inversion-free), with jittered vertices so that no face is axis-aligned
//! (except the box faces of `jets`, which must be flat to fill the box), a smooth vertex
//! field `f` and a cell field `cellval` (the formulas of the shared test data).
//!
//! Each shape is made of tets by default, or of other cells ([`CellKind`], written
//! `SHAPE-KIND`: `jets-hex`, `fusion-wedge`, `agulhas-hybrid`): hexahedra (warped: the jittered
//! levels make their top and bottom faces bilinear), wedges (two per cube, a prism mesh), or a
//! hybrid of hexes, pyramids, tets and wedges in layers (see `grid::cube_cells`). They use the
//! same grid of cubes as the tets, so `jets-hex:N` has the vertices of `jets:6N`.
//!
//! Deterministic for a seed, independent of the number of threads. The tet count lands
//! within a few percent of the target from about 5,000 tets up; tiny targets give the
//! smallest grid the shape has. Memory is the output arrays (36 B per tet and ~16 B per
//! vertex, vertices ≈ tets / 5) plus a few bytes per column.

mod agulhas;
pub mod flow;
mod fusion;
mod grid;
mod japan;
mod jets;
mod noise;
pub mod octree;
mod terrain;
#[cfg(test)]
mod tests;

pub use terrain::Terrain;

use crate::error::Error;
use crate::mesh::RawMesh;
use std::fmt;
use std::str::FromStr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// The largest tet count asked for: tet ids must fit an `i32` (`OUTSIDE` is -1).
pub const MAX_TETS: usize = i32::MAX as usize;

crate::named! {
    /// The synthetic data sets.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum Shape: "shape" {
        Jets => "jets",
        Fusion => "fusion",
        Agulhas => "agulhas",
        Japan => "japan",
    }
}

impl Shape {
    /// Whether [`terrain`] has ground for this shape (`agulhas`: its bathymetry and continents).
    pub fn has_terrain(self) -> bool {
        self == Shape::Agulhas
    }

    /// The share of its bounding box the shape fills (tet volume / box volume), as in the
    /// paper's data sets.
    pub fn target_occupancy(self) -> f64 {
        match self {
            Shape::Jets => 1.0,
            Shape::Fusion => fusion::OCCUPANCY,
            Shape::Agulhas => agulhas::OCCUPANCY,
            Shape::Japan => japan::OCCUPANCY,
        }
    }
}

/// A mesh of `shape` with about `target_tets` tets, the same for the same seed.
pub fn generate(shape: Shape, target_tets: usize, seed: u64) -> RawMesh {
    generate_with_progress(shape, target_tets, seed, &|_| {})
}

crate::named! {
    /// What a generated shape is made of; its name is the suffix that names the mesh
    /// (`jets-hex`; tets have none).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum CellKind: "cell kind" {
        /// Six Kuhn tets per cube (the default).
        Tets => "tet",
        /// One hexahedron per cube.
        Hexes => "hex",
        /// Two wedges per cube, their triangles in the plan of the columns.
        Wedges => "wedge",
        /// Layers of hexes, a pyramid transition, tets and wedges (`grid::cube_cells`).
        Hybrid => "hybrid",
        /// A box of hexahedra refined once inside a ball, its coarse cells beside refined ones
        /// polyhedra ([`octree`]: the shape picks only the map).
        Octree => "octree",
    }
}

impl CellKind {
    /// Cells per cube of the grid (the hybrid's mix, for a column of many levels).
    pub fn cells_per_cube(self) -> f64 {
        match self {
            CellKind::Tets => 6.0,
            CellKind::Hexes => 1.0,
            CellKind::Wedges => 2.0,
            // A quarter hexes (1), a half Kuhn tets (6), a quarter wedges (2).
            CellKind::Hybrid => 0.25 + 3.0 + 0.5,
            CellKind::Octree => octree::CELLS_PER_CUBE,
        }
    }
}

/// A generated mesh: a shape and what it is made of, written `SHAPE` (tets) or `SHAPE-KIND`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Spec {
    pub shape: Shape,
    pub cells: CellKind,
}

impl From<Shape> for Spec {
    fn from(shape: Shape) -> Spec {
        Spec { shape, cells: CellKind::Tets }
    }
}

impl fmt::Display for Spec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.cells {
            CellKind::Tets => write!(f, "{}", self.shape),
            k => write!(f, "{}-{}", self.shape, k.name()),
        }
    }
}

impl Spec {
    /// Every generated mesh by name: each shape, and each shape of each other kind of cell
    /// (`jets, jets-hex, jets-wedge, jets-hybrid, fusion, ...`).
    pub fn all_names() -> Vec<String> {
        Shape::ALL.into_iter().flat_map(|shape| CellKind::ALL.map(|cells| Spec { shape, cells }.to_string())).collect()
    }
}

impl FromStr for Spec {
    type Err = Error;
    fn from_str(s: &str) -> Result<Spec, Error> {
        let (shape, kind) = s.trim().split_once('-').unwrap_or((s.trim(), "tet"));
        let cells = kind.parse::<CellKind>().map_err(|_| {
            Error::Invalid(format!(
                "unknown cells '{kind}' in '{s}' (SHAPE or SHAPE-KIND, KIND one of: {})",
                CellKind::ALL.map(|k| k.name()).join(", ")
            ))
        })?;
        let shape = shape.parse::<Shape>().map_err(|_| {
            Error::Invalid(format!("unknown shape in '{}' (known: {})", s.trim(), Spec::all_names().join(", ")))
        })?;
        Ok(Spec { shape, cells })
    }
}

/// A mesh of `spec` with about `target_cells` cells (tets, hexes, wedges, or the hybrid's
/// cells of all types), the same for the same seed, calling `progress` as
/// [`generate_with_progress`] does.
pub fn generate_spec(spec: Spec, target_cells: usize, seed: u64, progress: &(dyn Fn(f64) + Sync)) -> RawMesh {
    let progress = Progress { callback: progress, last: Mutex::new(-1.0) };
    progress.report(0.0);
    let cubes = (target_cells.min(MAX_TETS) as f64 / spec.cells.cells_per_cube()) as usize;
    // The decomposition of a cube's cells is at most 6 tets: ids stay within i32.
    let cubes = cubes.min(MAX_TETS / 6);
    let kind = spec.cells;
    if kind == CellKind::Octree {
        let mesh = octree::build(spec.shape, target_cells.min(MAX_TETS / 24), seed);
        progress.report(1.0);
        return mesh;
    }
    let mesh = match spec.shape {
        Shape::Jets => grid::build(&jets::Jets::new(cubes, seed), kind, &progress),
        Shape::Fusion => grid::build(&fusion::Fusion::new(cubes, seed), kind, &progress),
        Shape::Agulhas => grid::build(&agulhas::Agulhas::new(cubes, seed), kind, &progress),
        Shape::Japan => grid::build(&japan::Japan::new(cubes, seed), kind, &progress),
    };
    progress.report(1.0);
    mesh
}

/// [`generate`], calling `progress` with the fraction done (increasing, ending with 1.0),
/// from whichever thread gets there, at most about a thousand times.
pub fn generate_with_progress(shape: Shape, target_tets: usize, seed: u64, progress: &(dyn Fn(f64) + Sync)) -> RawMesh {
    generate_spec(shape.into(), target_tets, seed, progress)
}

/// The ground a generated shape is drawn over, for the shapes that have one
/// ([`Shape::has_terrain`]), matching `generate(shape, target_tets, seed)`.
pub fn terrain(shape: Shape, target_tets: usize, seed: u64) -> Option<Terrain> {
    let cells = target_tets.min(MAX_TETS) / 6;
    match shape {
        Shape::Agulhas => Some(agulhas::Agulhas::new(cells, seed).terrain()),
        Shape::Jets | Shape::Fusion | Shape::Japan => None,
    }
}

/// Forwards progress to the caller's callback in increasing order and in steps of at least
/// 0.1 %, whichever thread reports.
struct Progress<'a> {
    callback: &'a (dyn Fn(f64) + Sync),
    last: Mutex<f64>,
}

impl Progress<'_> {
    fn report(&self, fraction: f64) {
        let f = fraction.clamp(0.0, 1.0);
        let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
        if f >= *last + 1e-3 || (f == 1.0 && *last < 1.0) {
            *last = f;
            (self.callback)(f);
        }
    }
}

/// One phase of the work: `total` units mapped onto the fractions `[start, end]`.
struct Phase<'a, 'b> {
    progress: &'a Progress<'b>,
    start: f64,
    end: f64,
    total: usize,
    done: AtomicUsize,
}

impl<'a, 'b> Phase<'a, 'b> {
    fn new(progress: &'a Progress<'b>, start: f64, end: f64, total: usize) -> Self {
        Phase { progress, start, end, total: total.max(1), done: AtomicUsize::new(0) }
    }

    fn advance(&self, units: usize) {
        let done = self.done.fetch_add(units, Ordering::Relaxed) + units;
        self.progress.report(self.start + (self.end - self.start) * done as f64 / self.total as f64);
    }
}
