//! A mesh of flat tets stored in f64, for the values of GPU kernels on slivers (issue 29.12)
//! from a fresh clone (the Delaunay oracle set has real slivers).
//!
//! One source for two crates, like `kuhn.rs`: core's unit tests compile it into
//! `test_support`, and `tetloc-testdata` includes it by path.

use super::{Field, FieldLocation, KuhnGrid, RawMesh};

/// A Kuhn grid of `n`³ cubes squashed into a layer `thickness` thick at z ≈ 0.5: tets
/// `1/n` wide and `thickness/n` high, with every coordinate jittered in f64 (by up to 0.1
/// of a cube in x and y, 0.1 of a layer in z: no tet inverts) so that none is an f32. The
/// f32 copy then moves the vertices by up to 3e-8 (half an f32 ulp at 0.5), a visible
/// fraction of a tet's height for a thickness of 1e-5: barycentrics on it are off by
/// percents. Vertex field `f` = sin(3x + 1)·cos(2y) + 0.3xy (range about 2.3), in f64.
pub fn flat_layers(n: usize, thickness: f64) -> RawMesh {
    let mut raw = KuhnGrid::new(n).raw();
    // A cheap deterministic hash of the vertex index, in [-1, 1).
    let unit = |i: usize, axis: usize| {
        let h = ((i * 3 + axis) as u64 + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        (h >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    };
    let cube = 1.0 / n as f64;
    let file: Vec<[f64; 3]> = raw
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let interior = |c: f32| c > 0.0 && c < 1.0;
            let jitter = |a: usize, size: f64| if interior(p[a]) { 0.1 * size * unit(i, a) } else { 0.0 };
            let x = f64::from(p[0]) + jitter(0, cube) + 1e-9 * unit(i, 0);
            let y = f64::from(p[1]) + jitter(1, cube) + 1e-9 * unit(i, 1);
            let z = 0.5 + thickness * (f64::from(p[2]) + jitter(2, cube)) + 1e-13 * unit(i, 2);
            [x, y, z]
        })
        .collect();
    let f = file.iter().map(|p| (3.0 * p[0] + 1.0).sin() * (2.0 * p[1]).cos() + 0.3 * p[0] * p[1]).collect();
    raw.points = file.iter().map(|p| p.map(|c| c as f32)).collect();
    raw.points64 = Some(file);
    raw.fields = vec![Field::from_f64("f", FieldLocation::Vertex, f)];
    raw
}
