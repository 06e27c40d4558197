//! Unique faces with front and back tets, by a parallel sort of all tet faces.

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;
use serde::Serialize;

/// One unique triangle of the mesh: vertex ids ascending, and the tets on either side.
/// `front` is the tet on the side where `geom::orient(v0, v1, v2, x) > 0`; since
/// `orient(a, b, c, x) = -(x - a)·((b - a) × (c - a))`, that is the side the normal
/// `n = (v1 - v0) × (v2 - v0)` points *away* from; `back` is the side `n` points to.
/// -1 means no tet on that side (a boundary face).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct Face {
    pub v: [u32; 3],
    pub front: i32,
    pub back: i32,
}
const _: () = assert!(std::mem::size_of::<Face>() == 20);

/// The unique faces of a mesh and a few counts.
#[derive(Debug, Clone, Default)]
pub struct FaceSet {
    pub faces: Vec<Face>,
    pub stats: FaceStats,
}

#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct FaceStats {
    pub n_faces: usize,
    pub n_boundary: usize,
    /// Faces shared by more than two tets (a broken mesh); the extra tets are ignored here.
    pub n_non_manifold: usize,
}

/// Faces of a canonical tet with ascending ids, and whether the tet is on the front side.
fn tet_faces(t: [u32; 4]) -> [([u32; 3], bool); 4] {
    crate::geom::ascending_faces(t).map(|(f, s)| (f, s > 0.0))
}

impl FaceSet {
    /// `tets` must be in canonical order (as in [`super::Mesh`]).
    pub fn build(tets: &[[u32; 4]]) -> FaceSet {
        // [a, b, c, tet | front<<31] records; sorting groups equal faces together.
        let mut recs: Vec<[u32; 4]> = tets
            .par_iter()
            .enumerate()
            .flat_map_iter(|(t, &tet)| {
                tet_faces(tet).into_iter().map(move |(v, front)| [v[0], v[1], v[2], t as u32 | ((front as u32) << 31)])
            })
            .collect();
        recs.par_sort_unstable();
        // Group starts, found in parallel.
        let starts: Vec<usize> =
            (0..recs.len()).into_par_iter().filter(|&i| i == 0 || recs[i][..3] != recs[i - 1][..3]).collect();
        let faces: Vec<(Face, u8)> = starts
            .par_iter()
            .enumerate()
            .map(|(g, &s)| {
                let e = starts.get(g + 1).copied().unwrap_or(recs.len());
                let r = recs[s];
                let mut face = Face { v: [r[0], r[1], r[2]], front: -1, back: -1 };
                for rec in &recs[s..e] {
                    let tet = (rec[3] & 0x7fff_ffff) as i32;
                    let slot = if rec[3] >> 31 == 1 { &mut face.front } else { &mut face.back };
                    if *slot < 0 {
                        *slot = tet;
                    }
                }
                (face, (e - s).min(3) as u8)
            })
            .collect();
        drop(recs);
        let n_boundary = faces.par_iter().filter(|(f, _)| f.front < 0 || f.back < 0).count();
        let n_non_manifold = faces.par_iter().filter(|(_, n)| *n > 2).count();
        let faces: Vec<Face> = faces.into_par_iter().map(|(f, _)| f).collect();
        FaceSet { stats: FaceStats { n_faces: faces.len(), n_boundary, n_non_manifold }, faces }
    }
}
