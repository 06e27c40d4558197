//! Lagrange tetrahedra of any order up to [`MAX_ORDER`]: VTK 71 (vtkLagrangeTetra; the order
//! follows from the point count), and Gmsh's complete tets of order 3 to 10 (tetra20 = 29,
//! tetra35 = 30, tetra56 = 31, 71–75), whose nodes Gmsh orders otherwise.

use super::lattice::{self, Family, LatticeCell};
use super::tet;

pub(super) const MAX_ORDER: u8 = 10;

/// Gmsh's element type of the complete tet of order `p` (order 2 is the quadratic tet's).
fn gmsh_code(p: u8) -> Option<u8> {
    match p {
        3 => Some(29),
        4 => Some(30),
        5 => Some(31),
        6..=10 => Some(65 + p),
        _ => None,
    }
}

pub(super) fn defs() -> Vec<LatticeCell> {
    (1..=MAX_ORDER)
        .map(|p| {
            let c = LatticeCell::new("Lagrange tetrahedron", 71, &tet::SHAPE, Family::Tet, p, lattice::vtk_tet(p));
            match gmsh_code(p) {
                Some(code) => c.with_gmsh(code, &lattice::gmsh_tet(p)),
                None => c,
            }
        })
        .collect()
}
