//! Query point sets for benchmarks and checks, the paper's synthetic ones and more:
//! `centers` (the paper's "uniform": one sample at every tet centre), `random` (a random
//! tet, a uniformly random point inside it), `bbox` (uniform in the bounding box) and `host`
//! (the `random` points, made on the host and handed over as a batch), and `grid` (the
//! regular grid over the bounding box that `resample` samples, N³ ≥ n points, its first n). The one enum that
//! names them: the CLI, the GPU kernels (which generate the first three themselves) and the
//! benchmarks all use [`QueryKind`].

use crate::geom::ImageGrid;
use crate::geom::Vec3;
use crate::mesh::Mesh;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;

crate::named! {
    /// A query set.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
    #[serde(rename_all = "lowercase")]
    pub enum QueryKind: "query set", Err = String {
        /// The centre of every tet, in mesh order (the paper's "uniform").
        Centers => "centers" | "uniform",
        /// A random point in a random tet (the paper's "random").
        Random => "random",
        /// Uniform in the mesh's bounding box (many points outside).
        Bbox => "bbox",
        /// The `random` points made on the host and handed to the locator as a batch: GPU
        /// benchmarks then time the transfers too, where the others generate points in the kernel.
        Host => "host",
        /// The first n points of the N×N×N grid over the mesh's bounds ([`grid`]), x fastest:
        /// resampling to an image (n = N³ gives the whole grid).
        Grid => "grid",
    }
}

/// Rocchini & Cignoni's folding of a uniform point `(s, t, u)` of the unit cube into the
/// tet's parameter domain (all ≥ 0, sum ≤ 1), still uniform. Generic so that the f32 mirror of
/// the GPU's `random` samples (shaders/common/samples.glsl) folds with the same operations.
pub fn fold_cube_into_tet<T>(s: T, t: T, u: T) -> [T; 3]
where
    T: Copy + PartialOrd + std::ops::Add<Output = T> + std::ops::Sub<Output = T> + From<f32>,
{
    let one = T::from(1.0);
    let (mut s, mut t, mut u) = (s, t, u);
    if s + t > one {
        s = one - s;
        t = one - t;
    }
    if t + u > one {
        let tmp = u;
        u = one - s - t;
        t = one - tmp;
    } else if s + t + u > one {
        let tmp = u;
        u = s + t + u - one;
        s = one - t - tmp;
    }
    [s, t, u]
}

/// A uniformly random point in the tet with corners `v` ([`fold_cube_into_tet`]), computed in
/// f64 and pulled towards the centre by 1e-3 of the way, so that rounding
/// to f32 cannot put it outside a boundary tet (such points would count as "outside").
pub fn random_point_in_tet(v: [Vec3; 4], rng: &mut impl Rng) -> Vec3 {
    let [s, t, u] = fold_cube_into_tet::<f64>(rng.gen(), rng.gen(), rng.gen());
    const PULL: f64 = 1e-3;
    let w = [1.0 - s - t - u, s, t, u].map(|x| (1.0 - PULL) * x + PULL * 0.25);
    std::array::from_fn(|k| (0..4).map(|i| w[i] * v[i][k] as f64).sum::<f64>() as f32)
}

/// The grid of the `grid` query set for `n` points: N per axis, the smallest N with N³ ≥ n,
/// over the mesh's bounds (working frame) as `resample` lays it out.
pub fn grid(mesh: &Mesh, n: usize) -> ImageGrid {
    let mut side = (n as f64).cbrt().round().max(1.0) as usize;
    while side.saturating_pow(3) < n {
        side += 1;
    }
    let (lo, hi) = (mesh.info.bounds_min.map(f64::from), mesh.info.bounds_max.map(f64::from));
    ImageGrid::over_bounds(lo, hi, [side; 3]).expect("finite bounds and a positive size")
}

/// `n` query points of the given kind (for `centers`, tet centres in order, cycling if `n`
/// exceeds the tet count; `host` makes the `random` points). Deterministic for a seed.
pub fn generate(mesh: &Mesh, kind: QueryKind, n: usize, seed: u64) -> Vec<Vec3> {
    const BLOCK: usize = 1 << 16;
    (0..n.div_ceil(BLOCK))
        .into_par_iter()
        .flat_map_iter(|b| {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(seed ^ (b as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
            let range = b * BLOCK..((b + 1) * BLOCK).min(n);
            let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
            let image = (kind == QueryKind::Grid).then(|| grid(mesh, n));
            range
                .map(move |i| match kind {
                    QueryKind::Centers => mesh.tet_center(i % mesh.n_tets()),
                    QueryKind::Random | QueryKind::Host => {
                        let t = mesh.tets[rng.gen_range(0..mesh.n_tets())];
                        random_point_in_tet(t.map(|i| mesh.points[i as usize]), &mut rng)
                    }
                    QueryKind::Bbox => std::array::from_fn(|k| lo[k] + rng.gen::<f32>() * (hi[k] - lo[k])),
                    QueryKind::Grid => image.as_ref().expect("made above").point(i),
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Random points lie inside their tet, also in a flat one.
    #[test]
    fn random_points_are_inside_their_tet() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
        let pts = vec![[1.0, 1.0, 1.0], [1.1, 1.0, 1.0], [1.0, 1.1, 1.0], [1.03, 1.03, 1.01]];
        let (tet, _) = crate::geom::canonical_tet([0, 1, 2, 3], &pts);
        for _ in 0..20000 {
            let p = random_point_in_tet(tet.map(|i| pts[i as usize]), &mut rng);
            assert!(crate::geom::point_in_tet(tet, &pts, p).is_some(), "{p:?}");
        }
    }

    #[test]
    fn query_sets_have_the_asked_size_and_kind() {
        let mesh = crate::test_support::grid_mesh(3, 0.2, 1);
        for kind in QueryKind::ALL {
            let q = generate(&mesh, kind, 70_000, 3);
            assert_eq!(q.len(), 70_000);
            assert_eq!(q, generate(&mesh, kind, 70_000, 3), "deterministic");
            let inside = |p: &Vec3| p.iter().all(|&c| (0.0..=1.0).contains(&c));
            assert!(q.iter().all(inside), "{kind}");
        }
        assert_eq!(generate(&mesh, QueryKind::Centers, 5, 0)[2], mesh.tet_center(2));
        assert_eq!(generate(&mesh, QueryKind::Host, 100, 5), generate(&mesh, QueryKind::Random, 100, 5));
        for kind in QueryKind::ALL {
            assert_eq!(kind.name().parse::<QueryKind>().unwrap(), kind);
        }
        // The grid of 8 points: the box's corners (nudged inwards by 1e-6), x fastest.
        assert_eq!(grid(&mesh, 8).dims, [2; 3]);
        assert_eq!(grid(&mesh, 9).dims, [3; 3]);
        let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
        for (i, p) in generate(&mesh, QueryKind::Grid, 8, 0).iter().enumerate() {
            for k in 0..3 {
                let want = if (i >> k) & 1 == 1 { hi[k] } else { lo[k] };
                assert!((p[k] - want).abs() < 1e-5, "corner {i}: {p:?}");
            }
        }
        assert_eq!("uniform".parse::<QueryKind>().unwrap(), QueryKind::Centers);
        assert!("nope".parse::<QueryKind>().is_err());
    }
}
