//! Small meshes for unit tests: a jittered grid of cubes, each split into 6 tets
//! (Kuhn triangulation along the main diagonal, conforming across cubes).

use crate::geom::Vec3;
use crate::mesh::{Field, FieldLocation, Mesh, RawMesh};
use rand::{Rng, SeedableRng};

/// `n`³ cubes on [0,1]³, interior vertices jittered by up to `jitter` × spacing.
pub fn jittered_grid(n: usize, jitter: f32, seed: u64) -> RawMesh {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let h = 1.0 / n as f32;
    let idx = |i: usize, j: usize, k: usize| (i + (n + 1) * (j + (n + 1) * k)) as u32;
    let mut points = Vec::new();
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                let mut p = [i as f32 * h, j as f32 * h, k as f32 * h];
                for (c, &g) in p.iter_mut().zip(&[i, j, k]) {
                    if g > 0 && g < n {
                        *c += rng.gen_range(-jitter..=jitter) * h;
                    }
                }
                points.push(p);
            }
        }
    }
    const PERMS: [[usize; 3]; 6] = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    let mut tets = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                for perm in PERMS {
                    let mut c = [i, j, k];
                    let mut t = [idx(c[0], c[1], c[2]); 4];
                    for (s, &axis) in perm.iter().enumerate() {
                        c[axis] += 1;
                        t[s + 1] = idx(c[0], c[1], c[2]);
                    }
                    tets.push(t);
                }
            }
        }
    }
    let f: Vec<f32> = points.iter().map(|p: &Vec3| (3.0 * p[0]).sin() + p[1] * p[2]).collect();
    let cell: Vec<f32> = (0..tets.len()).map(|t| t as f32).collect();
    RawMesh {
        points,
        tets,
        fields: vec![
            Field { name: "f".into(), location: FieldLocation::Vertex, values: f },
            Field { name: "cellval".into(), location: FieldLocation::Cell, values: cell },
        ],
        higher_order: None,
    }
}

pub fn grid_mesh(n: usize, jitter: f32, seed: u64) -> Mesh {
    Mesh::new(jittered_grid(n, jitter, seed), "test grid").unwrap()
}
