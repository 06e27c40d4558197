//! Lagrange hexahedra of the same order in every direction, up to [`MAX_ORDER`]: VTK 72
//! (vtkLagrangeHexahedron; the order follows from the point count, (p + 1)³). Files that give
//! per-direction orders (the `HigherOrderDegrees` cell array) are not read.

use super::hex;
use super::lattice::{self, Family, LatticeCell};

pub(super) const MAX_ORDER: u8 = 6;

pub(super) fn defs() -> Vec<LatticeCell> {
    (1..=MAX_ORDER)
        .map(|p| LatticeCell::new("Lagrange hexahedron", 72, &hex::SHAPE, Family::Hex, p, lattice::vtk_hex(p)))
        .collect()
}
