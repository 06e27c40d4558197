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
//! Deterministic for a seed, independent of the number of threads. The tet count lands
//! within a few percent of the target from about 5,000 tets up; tiny targets give the
//! smallest grid the shape has. Memory is the output arrays (36 B per tet and ~16 B per
//! vertex, vertices ≈ tets / 5) plus a few bytes per column.

mod agulhas;
mod fusion;
mod grid;
mod japan;
mod jets;
mod noise;
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

/// The synthetic data sets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shape {
    Jets,
    Fusion,
    Agulhas,
    Japan,
}

impl Shape {
    pub const ALL: [Shape; 4] = [Shape::Jets, Shape::Fusion, Shape::Agulhas, Shape::Japan];

    pub fn name(self) -> &'static str {
        match self {
            Shape::Jets => "jets",
            Shape::Fusion => "fusion",
            Shape::Agulhas => "agulhas",
            Shape::Japan => "japan",
        }
    }

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

impl fmt::Display for Shape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Shape {
    type Err = Error;
    fn from_str(s: &str) -> Result<Shape, Error> {
        Shape::ALL.into_iter().find(|sh| sh.name().eq_ignore_ascii_case(s.trim())).ok_or_else(|| {
            Error::Invalid(format!("unknown shape '{s}' (known: {})", Shape::ALL.map(|sh| sh.name()).join(", ")))
        })
    }
}

/// A mesh of `shape` with about `target_tets` tets, the same for the same seed.
pub fn generate(shape: Shape, target_tets: usize, seed: u64) -> RawMesh {
    generate_with_progress(shape, target_tets, seed, &|_| {})
}

/// [`generate`], calling `progress` with the fraction done (increasing, ending with 1.0),
/// from whichever thread gets there, at most about a thousand times.
pub fn generate_with_progress(shape: Shape, target_tets: usize, seed: u64, progress: &(dyn Fn(f64) + Sync)) -> RawMesh {
    let progress = Progress { callback: progress, last: Mutex::new(-1.0) };
    progress.report(0.0);
    // Every shape is made of cells of 6 tets.
    let cells = target_tets.min(MAX_TETS) / 6;
    let mesh = match shape {
        Shape::Jets => grid::build(&jets::Jets::new(cells, seed), &progress),
        Shape::Fusion => grid::build(&fusion::Fusion::new(cells, seed), &progress),
        Shape::Agulhas => grid::build(&agulhas::Agulhas::new(cells, seed), &progress),
        Shape::Japan => grid::build(&japan::Japan::new(cells, seed), &progress),
    };
    progress.report(1.0);
    mesh
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
