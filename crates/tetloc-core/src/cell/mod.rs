//! Volume cells: the geometry of every cell type tetloc reads, one module per type.
//!
//! A cell type is a [`CellDef`]: its VTK and Gmsh codes and node orders, its reference
//! [`Shape`] (corners, faces, parametric domain), and its shape functions with their
//! derivatives, in f64 and by VTK's definitions (vtkTetra, vtkPyramid, vtkWedge, vtkHexahedron,
//! vtkQuadratic*, vtkLagrange*). Everything else is written once over that trait: the inverse
//! map by Newton's method ([`invert`]), interpolation ([`interpolate`]), and the conforming tet
//! decomposition ([`decompose`]). A new cell type is a new module and one line in `registry`.
//!
//! Conventions are VTK's: parametric coordinates `(r, s, t)`; a cell holds a point when the
//! point's parametric coordinates lie in the cell's domain (the hex's `[0,1]³`, the wedge's
//! `r, s, 1 − r − s ≥ 0, t ∈ [0,1]`, the pyramid's `[0,1]³`, the tet's barycentrics `≥ 0`);
//! faces are listed as VTK lists them, with outward normals (right hand) for a valid cell.
//! Higher-order cells are *located* by their corners (the linear cell of the same shape) and
//! *interpolate* with all their nodes.

/// The [`CellDef`] of a cell type whose shape functions are its module's generic
/// `functions` (derivatives by dual numbers, [`scalar::derivatives`]) and whose Gmsh codes are
/// its module's `GMSH`: the facts that differ, once per module.
macro_rules! cell_def {
    ($ty:ty { name: $name:expr, vtk: $vtk:expr, shape: $shape:expr, order: $order:expr, nodes: $nodes:expr $(,)? }) => {
        impl super::CellDef for $ty {
            fn name(&self) -> &'static str {
                $name
            }
            fn vtk_type(&self) -> u8 {
                $vtk
            }
            fn gmsh_types(&self) -> &[super::GmshType] {
                GMSH
            }
            fn shape(&self) -> &'static super::Shape {
                $shape
            }
            fn order(&self) -> u8 {
                $order
            }
            fn node_pcoords(&self) -> &[super::PCoords] {
                $nodes
            }
            fn shape_functions(&self, pc: super::PCoords, w: &mut [f64]) {
                functions(pc, w);
            }
            fn shape_derivatives(&self, pc: super::PCoords, d: &mut [[f64; 3]]) {
                super::scalar::derivatives(pc, d, functions);
            }
        }
    };
}

mod decompose;
mod lattice;
mod newton;
mod scalar;
mod tet_nodes;

mod bezier_tet;
mod biquadratic_wedge;
mod hex;
mod lagrange_hex;
mod lagrange_tet;
mod lagrange_wedge;
pub mod polyhedron;
mod pyramid;
mod quadratic_hex;
mod quadratic_pyramid;
mod quadratic_tet;
mod quadratic_wedge;
mod tet;
mod triquadratic_hex;
mod wedge;

#[cfg(test)]
pub(crate) mod brute_force;
#[cfg(test)]
mod oracle_tests;
#[cfg(test)]
mod tests;

pub use decompose::{
    classify_face, classify_quad, decompose, face_split, tet_faces, warped_faces, Decomposition, FaceKind,
};
pub use newton::{forward, interpolate, invert, InverseError};
pub use polyhedron::PolyFaces;
pub use tet_nodes::{barycentric_lattice, corner_permutation, TetPermutations};

use std::borrow::Cow;
use std::sync::OnceLock;

/// Parametric coordinates `(r, s, t)`.
pub type PCoords = [f64; 3];

/// A point in space, in f64.
pub type Point = [f64; 3];

/// One side of a parametric domain: the point is inside when `offset + normal · pc ≥ 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bound {
    /// The cell face this side is (index into [`Shape::faces`]), or `None` (the pyramid's apex:
    /// `t ≤ 1` is a point, not a face).
    pub face: Option<u8>,
    pub offset: f64,
    pub normal: [f64; 3],
}

impl Bound {
    /// How far inside this side `pc` is (negative: outside), in parametric units.
    pub fn margin(&self, pc: PCoords) -> f64 {
        self.offset + self.normal[0] * pc[0] + self.normal[1] * pc[1] + self.normal[2] * pc[2]
    }
}

/// A reference cell shape (tet, pyramid, wedge, hex): what cells of every order of that shape
/// share. Location works on it alone.
#[derive(Debug)]
pub struct Shape {
    /// VTK's name of the linear cell ("tetra", "pyramid", "wedge", "hexahedron").
    pub name: &'static str,
    /// The corners' parametric coordinates, in VTK's order.
    pub corners: &'static [PCoords],
    /// Faces as local corner indices, VTK's order, outward normals by the right hand.
    pub faces: &'static [&'static [u8]],
    /// Where Newton's method starts: a point well inside (the vertex centroid's preimage).
    pub center: PCoords,
    /// The domain: the point is inside when every bound's margin is ≥ 0.
    pub domain: &'static [Bound],
    /// The linear cell of this shape: what higher-order cells are located by.
    pub linear: &'static dyn CellDef,
}

impl Shape {
    pub fn n_corners(&self) -> usize {
        self.corners.len()
    }

    /// The smallest margin over the domain's sides: ≥ 0 inside, and by how much it is outside.
    pub fn margin(&self, pc: PCoords) -> f64 {
        self.domain.iter().map(|b| b.margin(pc)).fold(f64::INFINITY, f64::min)
    }

    /// Whether `pc` lies in the domain, its boundary included (VTK's tolerance 0).
    pub fn contains(&self, pc: PCoords) -> bool {
        self.margin(pc) >= 0.0
    }

    /// The sides that `pc` violates, most violated first, with their margins (all < 0).
    pub fn violated(&self, pc: PCoords) -> Vec<(Option<u8>, f64)> {
        let mut v: Vec<(Option<u8>, f64)> =
            self.domain.iter().map(|b| (b.face, b.margin(pc))).filter(|&(_, m)| m < 0.0).collect();
        v.sort_by(|a, b| a.1.total_cmp(&b.1));
        v
    }

    pub fn is_tet(&self) -> bool {
        std::ptr::eq(self, &tet::SHAPE)
    }
}

/// A Gmsh element type that is this cell type: VTK node `i` is Gmsh node `vtk_from_gmsh[i]`.
/// Gmsh nodes not listed carry nothing VTK's type has (the pyramid14's base centre).
#[derive(Clone, Debug)]
pub struct GmshType {
    pub code: u8,
    pub n_nodes: usize,
    pub vtk_from_gmsh: Cow<'static, [u16]>,
}

/// The definition of one cell type: everything tetloc knows about it.
pub trait CellDef: Send + Sync {
    /// VTK's name of the type ("hexahedron", "quadratic wedge", ...).
    fn name(&self) -> &'static str;
    /// VTK's cell type code (vtkCellType.h).
    fn vtk_type(&self) -> u8;
    /// The Gmsh element types that are this cell, with their node orders.
    fn gmsh_types(&self) -> &[GmshType] {
        &[]
    }
    /// The reference shape: corners, faces, domain.
    fn shape(&self) -> &'static Shape;
    /// Polynomial order (1 for the linear cells).
    fn order(&self) -> u8;
    /// The nodes' parametric coordinates, in VTK's order; the first ones are the corners.
    fn node_pcoords(&self) -> &[PCoords];
    fn n_nodes(&self) -> usize {
        self.node_pcoords().len()
    }
    /// Whether shape function `i` is 1 at node `i` and 0 at the others (false for Bezier
    /// cells, whose nodes are control points).
    fn interpolates_nodes(&self) -> bool {
        true
    }
    /// The shape functions at `pc`, one per node: `w.len() == n_nodes()`.
    fn shape_functions(&self, pc: PCoords, w: &mut [f64]);
    /// Their derivatives: `d[i][k] = ∂N_i/∂pc_k`.
    fn shape_derivatives(&self, pc: PCoords, d: &mut [[f64; 3]]);
}

impl std::fmt::Debug for dyn CellDef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({} nodes)", self.name(), self.n_nodes())
    }
}

/// Every cell type tetloc knows, built once. [`CellType`] indexes it.
fn registry() -> &'static [&'static dyn CellDef] {
    static REGISTRY: OnceLock<Vec<&'static dyn CellDef>> = OnceLock::new();
    REGISTRY.get_or_init(|| {
        let mut r: Vec<&'static dyn CellDef> = vec![&tet::Tet, &pyramid::Pyramid, &wedge::Wedge, &hex::Hex];
        r.push(leak(quadratic_tet::def()));
        r.push(&quadratic_pyramid::QuadraticPyramid);
        r.push(&quadratic_wedge::QuadraticWedge);
        r.push(leak(biquadratic_wedge::def()));
        r.push(&quadratic_hex::QuadraticHex);
        r.push(leak(triquadratic_hex::def()));
        r.extend(lagrange_tet::defs().into_iter().map(leak));
        r.extend(lagrange_wedge::defs().into_iter().map(leak));
        r.extend(lagrange_hex::defs().into_iter().map(leak));
        r.extend(bezier_tet::defs().into_iter().map(leak));
        r.push(&polyhedron::Polyhedron);
        assert!(r.len() <= usize::from(u8::MAX), "cell types are indexed by u8");
        r
    })
}

/// Registry entries live for the whole run: built once, never freed.
fn leak(def: lattice::LatticeCell) -> &'static dyn CellDef {
    Box::leak(Box::new(def))
}

/// A cell type: a small handle on its [`CellDef`] (an index into tetloc's table of types).
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct CellType(u8);

impl CellType {
    pub fn def(self) -> &'static dyn CellDef {
        registry()[usize::from(self.0)]
    }

    pub fn shape(self) -> &'static Shape {
        self.def().shape()
    }

    /// Every cell type, in table order.
    pub fn all() -> impl Iterator<Item = CellType> {
        (0..registry().len()).map(|i| CellType(i as u8))
    }

    /// The type of a VTK cell with type code `code` and `n_nodes` points, if tetloc reads it.
    pub fn from_vtk(code: u8, n_nodes: usize) -> Option<CellType> {
        CellType::all().find(|t| t.def().vtk_type() == code && t.def().n_nodes() == n_nodes)
    }

    /// The type of a Gmsh element type `code`, with its node order, if tetloc reads it.
    pub fn from_gmsh(code: u8) -> Option<(CellType, &'static GmshType)> {
        CellType::all().find_map(|t| t.def().gmsh_types().iter().find(|g| g.code == code).map(|g| (t, g)))
    }

    /// The linear tet.
    pub fn tet() -> CellType {
        CellType(0)
    }

    /// VTK_POLYHEDRON: a cell of any faces ([`polyhedron`]).
    pub fn polyhedron() -> CellType {
        CellType::all().find(|t| t.is_polyhedron()).expect("the registry has polyhedra")
    }

    /// Whether this is VTK_POLYHEDRON (no reference shape: its faces are in
    /// [`CellBlock::polyhedra`], its decomposition is the cell).
    pub fn is_polyhedron(self) -> bool {
        std::ptr::eq(self.shape(), &polyhedron::SHAPE)
    }
}

impl std::fmt::Debug for CellType {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?}", self.def())
    }
}

/// Volume cells of any types, in file order: what a reader hands over for a mesh that is not
/// made of linear tets only. Cell `i` has the nodes `conn[ends[i − 1]..ends[i]]` (from 0 for
/// the first), in VTK's node order for its type; a polyhedron's nodes are its distinct points,
/// and its faces are in `polyhedra`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CellBlock {
    pub types: Vec<CellType>,
    pub ends: Vec<u64>,
    pub conn: Vec<u32>,
    /// The faces of the cells that are polyhedra.
    pub polyhedra: PolyFaces,
}

impl CellBlock {
    pub fn len(&self) -> usize {
        self.types.len()
    }

    pub fn is_empty(&self) -> bool {
        self.types.is_empty()
    }

    /// All nodes of cell `i`.
    pub fn nodes(&self, i: usize) -> &[u32] {
        let start = if i == 0 { 0 } else { self.ends[i - 1] as usize };
        &self.conn[start..self.ends[i] as usize]
    }

    /// The corner nodes of cell `i`: what it is located by (all of a polyhedron's points).
    pub fn corners(&self, i: usize) -> &[u32] {
        let nodes = self.nodes(i);
        match self.types[i] {
            t if t.is_polyhedron() => nodes,
            t => &nodes[..t.shape().n_corners()],
        }
    }

    /// Appends a polyhedron of these faces (point ids); its nodes are their distinct points.
    pub fn push_polyhedron<'a>(&mut self, faces: impl IntoIterator<Item = &'a [u32]> + Clone) {
        self.polyhedra.push(self.types.len() as u32, faces.clone());
        self.types.push(CellType::polyhedron());
        self.conn.extend(polyhedron::distinct_points(faces));
        self.ends.push(self.conn.len() as u64);
    }

    /// The faces of cell `i` when it is a polyhedron.
    pub fn faces_of(&self, i: usize) -> Option<impl Iterator<Item = &[u32]> + Clone + '_> {
        self.polyhedra.index_of(i).map(|k| self.polyhedra.faces(k))
    }

    /// Appends a cell; `nodes.len()` must be its type's node count.
    pub fn push(&mut self, ty: CellType, nodes: &[u32]) {
        debug_assert_eq!(nodes.len(), ty.def().n_nodes());
        self.types.push(ty);
        self.conn.extend_from_slice(nodes);
        self.ends.push(self.conn.len() as u64);
    }

    /// Appends the cells of `other`, its node ids shifted by `id_offset`.
    pub fn append(&mut self, other: &CellBlock, id_offset: u32) {
        let base = self.conn.len() as u64;
        self.polyhedra.append(&other.polyhedra, self.types.len() as u32, id_offset);
        self.types.extend_from_slice(&other.types);
        self.ends.extend(other.ends.iter().map(|e| e + base));
        self.conn.extend(other.conn.iter().map(|&i| i + id_offset));
    }

    /// The cells that are not tets, counted by type name in VTK code order; `None` when every
    /// cell is a tet (of any order).
    pub fn non_tet_counts(&self) -> Option<Vec<(String, usize)>> {
        let mut counts = std::collections::BTreeMap::new();
        for t in self.types.iter().filter(|t| !t.shape().is_tet()) {
            *counts.entry((t.def().vtk_type(), t.def().name())).or_insert(0usize) += 1;
        }
        (!counts.is_empty()).then(|| counts.into_iter().map(|((_, name), n)| (name.to_string(), n)).collect())
    }
}
