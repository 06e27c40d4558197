//! Small tet meshes built from a (jittered) grid, for tests and demos of the renderer on any
//! backend: a solid cube, two separated blobs and a torus (the sparse cases skipping helps).
//!
//! Each mesh carries a per-vertex field `f` and a per-cell field `c`.

use crate::KuhnGrid;
use std::f32::consts::TAU;
use tetloc_core::{Mesh, Vec3};

/// A grid of `n³` cubes over `[0, 1]³`, each split into 6 tets (Kuhn split:
/// [`KuhnGrid`]), keeping the tets whose centroid satisfies `keep`. Interior
/// vertices are moved by up to `jitter` cell widths per axis (≤ 0.1 keeps every tet
/// positively shaped). `f(p)` gives the vertex field `f`, and at the centroids the cell field `c`.
///
/// # Panics
/// When `n` is 0 or `jitter` is outside 0..=0.1, or `keep` rejects every tet.
pub fn grid(
    n: usize,
    jitter: f32,
    seed: u64,
    keep: impl Fn(Vec3) -> bool,
    f: impl Fn(Vec3) -> f32,
    name: &str,
) -> Mesh {
    assert!(n >= 1 && (0.0..=0.1).contains(&jitter));
    KuhnGrid::new(n).jitter(jitter, seed).keep(keep).vertex_field(&f).cell_field("c", |_, c| f(c)).mesh(name)
}

/// A smooth field with structure at a few scales.
pub fn wavy(p: Vec3) -> f32 {
    (TAU * p[0]).sin() * (TAU * p[1]).cos() + 0.5 * (2.0 * TAU * p[2]).sin() + p[2]
}

/// The cube `[0, side]³` of `n³ · 6` regular tets with both fields constant at `value`.
pub fn cube(n: usize, side: f32, value: f32) -> Mesh {
    KuhnGrid::new(n).spacing([side / n as f32; 3]).vertex_field(|_| value).cell_field("c", |_, _| value).mesh("cube")
}

/// Two balls of radius 0.2 at opposite corners of the unit square's diagonal, z = 0.5.
pub fn two_blobs(n: usize, seed: u64) -> Mesh {
    let ball = |p: Vec3, c: Vec3| (0..3).map(|k| (p[k] - c[k]).powi(2)).sum::<f32>() < 0.04;
    grid(n, 0.1, seed, |p| ball(p, [0.25, 0.25, 0.5]) || ball(p, [0.75, 0.75, 0.5]), wavy, "two-blobs")
}

/// A torus around the z axis through the unit cube's centre: radii 0.35 and 0.12.
pub fn torus(n: usize, seed: u64) -> Mesh {
    let keep = |p: Vec3| {
        let (x, y, z) = (p[0] - 0.5, p[1] - 0.5, p[2] - 0.5);
        let ring = (x * x + y * y).sqrt() - 0.35;
        ring * ring + z * z < 0.12 * 0.12
    };
    grid(n, 0.1, seed, keep, wavy, "torus")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meshes_are_valid_and_sparse_where_meant() {
        let cube = cube(3, 2.0, 1.5);
        assert_eq!(cube.n_tets(), 162);
        assert!((cube.info.total_volume - 8.0).abs() < 1e-5);
        assert_eq!(cube.info.n_degenerate, 0);
        let blobs = two_blobs(16, 1);
        assert_eq!(blobs.info.n_degenerate, 0);
        let vol = blobs.info.total_volume;
        let expect = 2.0 * 4.0 / 3.0 * std::f64::consts::PI * 0.008;
        assert!((vol - expect).abs() < 0.3 * expect, "{vol} vs {expect}");
        // Faces are shared exactly: every interior face has two tets.
        let fs = &blobs.faces().stats;
        assert_eq!(fs.n_non_manifold, 0);
        let t = torus(12, 2);
        assert!(t.n_tets() > 0 && t.info.n_degenerate == 0);
    }
}
