//! Lagrange wedges of the same order on the triangle and along t, up to [`MAX_ORDER`]: VTK 73
//! (vtkLagrangeWedge; the order follows from the point count, (p + 1)²(p + 2)/2). VTK's
//! 21-node variant is not read.

use super::lattice::{self, Family, LatticeCell};
use super::wedge;

pub(super) const MAX_ORDER: u8 = 6;

pub(super) fn defs() -> Vec<LatticeCell> {
    (1..=MAX_ORDER)
        .map(|p| LatticeCell::new("Lagrange wedge", 73, &wedge::SHAPE, Family::Wedge, p, lattice::vtk_wedge(p)))
        .collect()
}
