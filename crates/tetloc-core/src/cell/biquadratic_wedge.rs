//! The biquadratic-quadratic (18-node) wedge: VTK 32 (vtkBiQuadraticQuadraticWedge), Gmsh 13
//! (prism18). The 15 nodes of the quadratic wedge and the centres of the quad faces (0,1,4,3)
//! (1,2,5,4) (2,0,3,5): the order-2 Lagrange wedge, in the same order.

use super::lattice::{self, Family, LatticeCell};
use super::{quadratic_wedge::GMSH_PRISM15, wedge, GmshType};

/// Gmsh's quad-face centres come in the order (0,1,4,3) (0,3,5,2) (1,2,5,4).
const GMSH_PRISM18: [u16; 18] = {
    let mut p = [0u16; 18];
    let mut i = 0;
    while i < 15 {
        p[i] = GMSH_PRISM15[i];
        i += 1;
    }
    p[15] = 15;
    p[16] = 17;
    p[17] = 16;
    p
};

pub(super) fn def() -> LatticeCell {
    let mut c =
        LatticeCell::new("biquadratic quadratic wedge", 32, &wedge::SHAPE, Family::Wedge, 2, lattice::vtk_wedge(2));
    c.gmsh.push(GmshType { code: 13, n_nodes: 18, vtk_from_gmsh: GMSH_PRISM18[..].into() });
    c
}
