//! Bezier tetrahedra of any order up to [`MAX_ORDER`]: VTK 78 (vtkBezierTetra), on the Lagrange
//! tet's point order. Their shape functions are Bernstein polynomials: the points are control
//! points, interpolated only at the corners (which is what location uses).

use super::lattice::{self, Family, LatticeCell};
use super::tet;

pub(super) const MAX_ORDER: u8 = 10;

pub(super) fn defs() -> Vec<LatticeCell> {
    (1..=MAX_ORDER)
        .map(|p| LatticeCell::new("Bezier tetrahedron", 78, &tet::SHAPE, Family::BezierTet, p, lattice::vtk_tet(p)))
        .collect()
}
