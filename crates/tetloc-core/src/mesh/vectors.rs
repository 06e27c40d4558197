//! A vector field's three per-vertex components held a vertex at a time, for the tracers: a
//! lookup reads each corner's three components together (one cache line, not three arrays)
//! with the arithmetic of [`Mesh::value_of`], so the vector is the three components' values
//! bit for bit (tested below).

use super::{Field, FieldLocation, Mesh};
use crate::geom::{self, Real};
use rayon::prelude::*;

/// See the module's documentation.
pub struct VertexVectors<T> {
    values: Vec<[T; 3]>,
}

impl<T: Real> VertexVectors<T> {
    /// The components `xyz` of `mesh`'s vector a vertex at a time, in precision `T` (the f32
    /// values, or the file's f64 ones: [`Field::value_in`]). `None` unless all three are
    /// per-vertex fields of the mesh's vertices and its tets are linear (higher-order ones
    /// interpolate on more nodes: [`Mesh::value_of`] serves them).
    pub fn new(mesh: &Mesh, xyz: [&Field; 3]) -> Option<Self> {
        let n = mesh.points.len();
        let usable = |f: &Field| f.location == FieldLocation::Vertex && f.values.len() == n;
        if mesh.tet_nodes.is_some() || !xyz.iter().all(|f| usable(f)) {
            return None;
        }
        let values = (0..n).into_par_iter().map(|i| xyz.map(|f| f.value_in::<T>(i))).collect();
        Some(VertexVectors { values })
    }

    /// The vector at barycentrics `bary` of tet `t`: each component as
    /// [`Mesh::value_of`] interpolates it.
    #[inline]
    pub fn at(&self, mesh: &Mesh, t: usize, bary: [T; 4]) -> [T; 3] {
        let corners = mesh.tets[t].map(|i| self.values[i as usize]);
        std::array::from_fn(|k| geom::interpolate_with([0, 1, 2, 3], bary, |j| corners[j][k]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Every tet of a mesh with a vector, at pseudo-random barycentrics: the vector a vertex
    /// at a time equals `value_of` of each component to the bit, in f32 and in f64.
    #[test]
    fn the_vector_is_its_components_values_bit_for_bit() {
        let mut raw = crate::gen::generate(crate::gen::Shape::Fusion, 3000, 3);
        raw.fields.extend(crate::gen::flow::vector_fields(crate::gen::Shape::Fusion, &raw.points));
        let mesh = Mesh::new(raw, "fusion").unwrap();
        let xyz = ["v[0]", "v[1]", "v[2]"].map(|c| mesh.field(c).unwrap());
        let (v32, v64) =
            (VertexVectors::<f32>::new(&mesh, xyz).unwrap(), VertexVectors::<f64>::new(&mesh, xyz).unwrap());
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        for t in 0..mesh.n_tets() {
            let raw: [f64; 4] = std::array::from_fn(|_| rng.gen_range(0.0..1.0));
            let b64 = raw.map(|r| r / raw.iter().sum::<f64>());
            let b32 = b64.map(|x| x as f32);
            let want32 = xyz.map(|f| mesh.value_of::<f32>(f, Some((t, b32))).to_bits());
            let want64 = xyz.map(|f| mesh.value_of::<f64>(f, Some((t, b64))).to_bits());
            assert_eq!(v32.at(&mesh, t, b32).map(f32::to_bits), want32, "tet {t}");
            assert_eq!(v64.at(&mesh, t, b64).map(f64::to_bits), want64, "tet {t}");
        }
    }

    #[test]
    fn cell_fields_are_not_taken() {
        let raw = crate::gen::generate(crate::gen::Shape::Jets, 500, 1);
        let mesh = Mesh::new(raw, "jets").unwrap();
        let (f, cell) = (mesh.field("f").unwrap(), mesh.field("cellval").unwrap());
        assert!(VertexVectors::<f32>::new(&mesh, [f, f, f]).is_some());
        assert!(VertexVectors::<f32>::new(&mesh, [f, cell, f]).is_none());
    }
}
