//! Query point sets for benchmarks and checks, the paper's synthetic ones and more:
//! `centers` (the paper's "uniform": one sample at every tet centre), `random` (a random
//! tet, a uniformly random point inside it) and `bbox` (uniform in the bounding box).

use crate::geom::Vec3;
use crate::mesh::Mesh;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;
use std::str::FromStr;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum QueryKind {
    Centers,
    Random,
    Bbox,
}

impl QueryKind {
    pub const ALL: [QueryKind; 3] = [QueryKind::Centers, QueryKind::Random, QueryKind::Bbox];
    pub fn name(self) -> &'static str {
        match self {
            QueryKind::Centers => "centers",
            QueryKind::Random => "random",
            QueryKind::Bbox => "bbox",
        }
    }
}

impl std::fmt::Display for QueryKind {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for QueryKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "centers" | "uniform" => Ok(QueryKind::Centers),
            "random" => Ok(QueryKind::Random),
            "bbox" => Ok(QueryKind::Bbox),
            _ => Err(format!("unknown query set '{s}' (known: centers (alias uniform), random, bbox)")),
        }
    }
}

/// A uniformly random point in the tet with corners `v` (Rocchini & Cignoni's folding of the cube).
pub fn random_point_in_tet(v: [Vec3; 4], rng: &mut impl Rng) -> Vec3 {
    let (mut s, mut t, mut u): (f32, f32, f32) = (rng.gen(), rng.gen(), rng.gen());
    if s + t > 1.0 {
        s = 1.0 - s;
        t = 1.0 - t;
    }
    if t + u > 1.0 {
        let tmp = u;
        u = 1.0 - s - t;
        t = 1.0 - tmp;
    } else if s + t + u > 1.0 {
        let tmp = u;
        u = s + t + u - 1.0;
        s = 1.0 - t - tmp;
    }
    let a = 1.0 - s - t - u;
    std::array::from_fn(|k| a * v[0][k] + s * v[1][k] + t * v[2][k] + u * v[3][k])
}

/// `n` query points of the given kind (for `centers`, tet centres in order, cycling if `n`
/// exceeds the tet count). Deterministic for a seed.
pub fn generate(mesh: &Mesh, kind: QueryKind, n: usize, seed: u64) -> Vec<Vec3> {
    const BLOCK: usize = 1 << 16;
    (0..n.div_ceil(BLOCK))
        .into_par_iter()
        .flat_map_iter(|b| {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(seed ^ (b as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
            let range = b * BLOCK..((b + 1) * BLOCK).min(n);
            let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
            range
                .map(move |i| match kind {
                    QueryKind::Centers => mesh.tet_center(i % mesh.n_tets()),
                    QueryKind::Random => {
                        let t = mesh.tets[rng.gen_range(0..mesh.n_tets())];
                        random_point_in_tet(t.map(|i| mesh.points[i as usize]), &mut rng)
                    }
                    QueryKind::Bbox => std::array::from_fn(|k| lo[k] + rng.gen::<f32>() * (hi[k] - lo[k])),
                })
                .collect::<Vec<_>>()
        })
        .collect()
}
