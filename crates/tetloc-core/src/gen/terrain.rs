//! Opaque ground that goes with a generated shape when it is rendered (the paper draws the
//! Agulhas data set over its bathymetry and continents): a height field of triangles.

use crate::geom::Vec3;
use std::io::{self, Write};

/// An indexed triangle surface.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Terrain {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

impl Terrain {
    /// A height field over `(ni + 1) × (nj + 1)` grid nodes at `node(i, j)` (plan positions
    /// increasing with i and j), each grid square cut into two triangles facing +z.
    pub(super) fn height_field(ni: usize, nj: usize, node_at: impl Fn(usize, usize) -> Vec3) -> Terrain {
        let mut positions = Vec::with_capacity((ni + 1) * (nj + 1));
        for j in 0..=nj {
            for i in 0..=ni {
                positions.push(node_at(i, j));
            }
        }
        let node = |i: usize, j: usize| (j * (ni + 1) + i) as u32;
        let mut triangles = Vec::with_capacity(2 * ni * nj);
        for j in 0..nj {
            for i in 0..ni {
                let (a, b, c, d) = (node(i, j), node(i + 1, j), node(i + 1, j + 1), node(i, j + 1));
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            }
        }
        Terrain { positions, triangles }
    }

    /// Wavefront OBJ (1-based indices), readable by `tetloc render --surface` and ParaView.
    pub fn write_obj(&self, mut w: impl Write) -> io::Result<()> {
        writeln!(w, "# tetloc terrain: {} vertices, {} triangles", self.positions.len(), self.triangles.len())?;
        for p in &self.positions {
            writeln!(w, "v {} {} {}", p[0], p[1], p[2])?;
        }
        for t in &self.triangles {
            writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
        }
        Ok(())
    }
}
