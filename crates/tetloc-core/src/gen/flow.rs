//! A closed-form vector field `v` on a generated shape, for tracing particles (`tetloc gen
//! --vector`, the particle benchmarks). On `fusion` it is a tokamak's field: a toroidal flow
//! around the vertical axis plus a poloidal one around the centre line, tangent to the
//! nested (elongated) tori of the cross-section, so streamlines wind around the torus and
//! stay inside until they meet its staircase boundary. On the other shapes it is a
//! horizontal rotation about the vertical line through the centre of the bounds.

use super::fusion::{ELONGATION, MAJOR};
use super::Shape;
use crate::geom::Vec3;
use crate::mesh::{Field, FieldLocation};
use rayon::prelude::*;

/// Poloidal turns per toroidal turn on `fusion`.
const POLOIDAL: f64 = 2.0;

/// The field at `p`, for a mesh of `shape` whose vertices span `lo..hi`.
pub fn velocity(shape: Shape, p: Vec3, lo: Vec3, hi: Vec3) -> [f32; 3] {
    let [x, y, z] = p.map(f64::from);
    let v = match shape {
        Shape::Fusion => {
            let r = x.hypot(y).max(1e-12);
            // (v_r, v_z) is tangent to the ellipses (r - R)² + (z / E)² = c.
            let (vr, vz) = (-POLOIDAL * z / ELONGATION, POLOIDAL * ELONGATION * (r - MAJOR));
            [(-y + vr * x) / r, (x + vr * y) / r, vz]
        }
        _ => {
            let c = [0, 1].map(|k| 0.5 * (lo[k] as f64 + hi[k] as f64));
            let scale = 0.5 * (hi[0] - lo[0]).max(hi[1] - lo[1]).max(f32::MIN_POSITIVE) as f64;
            [-(y - c[1]) / scale, (x - c[0]) / scale, 0.0]
        }
    };
    v.map(|c| c as f32)
}

/// The three vertex fields `v[0]`, `v[1]`, `v[2]` (read back as one vector `v`) at `points`.
pub fn vector_fields(shape: Shape, points: &[Vec3]) -> Vec<Field> {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let v: Vec<[f32; 3]> = points.par_iter().map(|&p| velocity(shape, p, lo, hi)).collect();
    (0..3).map(|c| Field::new(format!("v[{c}]"), FieldLocation::Vertex, v.iter().map(|x| x[c]).collect())).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On fusion the field is tangent to the tori around the centre line: no component along
    /// the gradient of (r - R)² + (z / E)²; elsewhere a rotation, perpendicular to the radius.
    #[test]
    fn the_field_follows_the_shape() {
        for p in [[1.2f32, 0.3, 0.2], [-0.7, 0.5, -0.4], [0.1, -1.3, 0.0]] {
            let v = velocity(Shape::Fusion, p, [0.0; 3], [0.0; 3]).map(f64::from);
            let [x, y, z] = p.map(f64::from);
            let r = x.hypot(y);
            let grad = [2.0 * (r - MAJOR) * x / r, 2.0 * (r - MAJOR) * y / r, 2.0 * z / (ELONGATION * ELONGATION)];
            let dot: f64 = (0..3).map(|k| v[k] * grad[k]).sum();
            assert!(dot.abs() < 1e-6, "{p:?}: {v:?}");
            let w = velocity(Shape::Jets, p, [-2.0; 3], [2.0; 3]);
            assert!((w[0] * p[0] + w[1] * p[1]).abs() < 1e-6 && w[2] == 0.0, "{w:?}");
        }
        let f = vector_fields(Shape::Japan, &[[0.0; 3], [1.0, 2.0, 3.0]]);
        assert_eq!(f.iter().map(|f| f.name.as_str()).collect::<Vec<_>>(), ["v[0]", "v[1]", "v[2]"]);
    }
}
