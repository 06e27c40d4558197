//! The triquadratic (27-node) hexahedron: VTK 29 (vtkTriQuadraticHexahedron), Gmsh 12 (hex27).
//! The 20 nodes of the quadratic hex, the face centres of the faces r = 0, r = 1, s = 0, s = 1,
//! t = 0, t = 1, and the body centre: the order-2 Lagrange hex, in the same order.

use super::lattice::{self, Family, LatticeCell};
use super::{hex, quadratic_hex::GMSH_HEX20, GmshType};

/// Gmsh's face centres come in the order t = 0, s = 0, r = 0, r = 1, s = 1, t = 1.
pub(super) const GMSH_HEX27: [u16; 27] = {
    let mut p = [0u16; 27];
    let mut i = 0;
    while i < 20 {
        p[i] = GMSH_HEX20[i];
        i += 1;
    }
    let faces = [22, 23, 21, 24, 20, 25, 26];
    while i < 27 {
        p[i] = faces[i - 20];
        i += 1;
    }
    p
};

pub(super) fn def() -> LatticeCell {
    let mut c = LatticeCell::new("triquadratic hexahedron", 29, &hex::SHAPE, Family::Hex, 2, lattice::vtk_hex(2));
    c.gmsh.push(GmshType { code: 12, n_nodes: 27, vtk_from_gmsh: GMSH_HEX27[..].into() });
    c
}
