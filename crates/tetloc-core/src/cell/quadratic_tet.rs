//! The quadratic (10-node) tetrahedron: VTK 24 (vtkQuadraticTetra), Gmsh 11 (tetra10). Corners,
//! then the midpoints of the edges (0,1) (1,2) (2,0) (0,3) (1,3) (2,3): the order-2 Lagrange tet.

use super::lattice::{self, Family, LatticeCell};
use super::tet;

pub(super) fn def() -> LatticeCell {
    LatticeCell::new("quadratic tetra", 24, &tet::SHAPE, Family::Tet, 2, lattice::vtk_tet(2))
        .with_gmsh(11, &lattice::gmsh_tet(2))
}
