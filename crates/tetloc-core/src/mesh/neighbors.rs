//! Face adjacency: for each tet and each of its stored vertices, the tet across the face
//! opposite that vertex (-1 on the boundary). Each face is owned by its smallest vertex:
//! the tets around each vertex (a counting sort, linear) give that vertex's faces, a few
//! dozen, matched among themselves in parallel. No sort of every face of the mesh.

use rayon::prelude::*;
use std::sync::atomic::{AtomicI32, Ordering::Relaxed};

/// `tets` must be in canonical order. Tet counts up to 2³⁰ (two bits hold the local face).
pub fn build(tets: &[[u32; 4]]) -> Vec<[i32; 4]> {
    assert!(tets.len() < 1 << 30, "face adjacency supports up to 2^30 tets");
    let around = VertexTets::build(tets);
    let out: Vec<[AtomicI32; 4]> =
        (0..tets.len()).into_par_iter().map(|_| [(); 4].map(|_| AtomicI32::new(-1))).collect();
    // Each vertex's faces (those it is the smallest vertex of): the other two vertices, then
    // the tet and local face. Every (tet, face) slot is written by one vertex only.
    (0..around.n_vertices()).into_par_iter().with_min_len(1024).for_each_init(Vec::new, |faces, v| {
        faces.clear();
        let mut last = u32::MAX;
        for &t in around.of(v) {
            // A tet listed twice here has this vertex twice (degenerate): its faces once.
            if std::mem::replace(&mut last, t) == t {
                continue;
            }
            let tet = tets[t as usize];
            for i in 0..4 {
                let mut f = [0u32; 3];
                let mut k = 0;
                for (j, &w) in tet.iter().enumerate() {
                    if j != i {
                        f[k] = w;
                        k += 1;
                    }
                }
                f.sort_unstable();
                if f[0] == v as u32 {
                    faces.push([f[1], f[2], t << 2 | i as u32]);
                }
            }
        }
        faces.sort_unstable();
        // Pairs of equal faces are neighbours; a face shared by more than two tets (a broken
        // mesh) links only its first two (in tet order).
        for k in 1..faces.len() {
            let (a, b) = (faces[k - 1], faces[k]);
            if a[..2] == b[..2] && (k < 2 || faces[k - 2][..2] != b[..2]) {
                out[(a[2] >> 2) as usize][(a[2] & 3) as usize].store((b[2] >> 2) as i32, Relaxed);
                out[(b[2] >> 2) as usize][(b[2] & 3) as usize].store((a[2] >> 2) as i32, Relaxed);
            }
        }
    });
    out.into_par_iter().map(|row| row.map(AtomicI32::into_inner)).collect()
}

/// The tets around each vertex, in ascending tet order (compressed rows).
struct VertexTets {
    start: Vec<u32>,
    tets: Vec<u32>,
}

impl VertexTets {
    fn build(tets: &[[u32; 4]]) -> VertexTets {
        let n = tets.par_iter().map(|t| t.iter().max().map_or(0, |&m| m as usize + 1)).max().unwrap_or(0);
        let mut start = vec![0u32; n + 1];
        for t in tets {
            for &v in t {
                start[v as usize + 1] += 1;
            }
        }
        for v in 1..=n {
            start[v] += start[v - 1];
        }
        let mut next = start.clone();
        let mut around = vec![0u32; 4 * tets.len()];
        for (t, tet) in tets.iter().enumerate() {
            for &v in tet {
                around[next[v as usize] as usize] = t as u32;
                next[v as usize] += 1;
            }
        }
        VertexTets { start, tets: around }
    }

    fn n_vertices(&self) -> usize {
        self.start.len().saturating_sub(1)
    }

    fn of(&self, v: usize) -> &[u32] {
        &self.tets[self.start[v] as usize..self.start[v + 1] as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{seq::SliceRandom, SeedableRng};

    /// The reference: every face record of the mesh sorted together, equal neighbours paired
    /// (the first two where more than two tets share a face).
    fn by_sorting_every_face(tets: &[[u32; 4]]) -> Vec<[i32; 4]> {
        let mut recs: Vec<[u32; 4]> = Vec::new();
        for (t, tet) in tets.iter().enumerate() {
            for i in 0..4 {
                let mut f: Vec<u32> = (0..4).filter(|&j| j != i).map(|j| tet[j]).collect();
                f.sort_unstable();
                recs.push([f[0], f[1], f[2], (t as u32) << 2 | i as u32]);
            }
        }
        recs.sort_unstable();
        let mut out = vec![[-1i32; 4]; tets.len()];
        for k in 1..recs.len() {
            if recs[k][..3] == recs[k - 1][..3] && (k < 2 || recs[k - 2][..3] != recs[k][..3]) {
                let (a, b) = (recs[k - 1][3], recs[k][3]);
                out[(a >> 2) as usize][(a & 3) as usize] = (b >> 2) as i32;
                out[(b >> 2) as usize][(b & 3) as usize] = (a >> 2) as i32;
            }
        }
        out
    }

    /// Random tets over few vertices share faces two, three and more at a time.
    #[test]
    fn vertex_owned_faces_pair_as_sorting_every_face() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
        let ids: Vec<u32> = (0..12).collect();
        for n in [0usize, 1, 7, 5000] {
            let tets: Vec<[u32; 4]> = (0..n)
                .map(|_| {
                    let mut t = [0u32; 4];
                    t.copy_from_slice(&ids.choose_multiple(&mut rng, 4).copied().collect::<Vec<_>>());
                    t
                })
                .collect();
            assert_eq!(build(&tets), by_sorting_every_face(&tets), "{n} tets");
        }
    }

    /// Neighbours are mutual across shared faces, and -1 exactly on the boundary: a KuhnGrid
    /// cube of n^3 cubes has 12 n^2 boundary faces.
    #[test]
    fn neighbours_of_a_grid() {
        let m = crate::test_support::KuhnGrid::new(3).mesh("cube");
        let nb = build(&m.tets);
        assert_eq!(nb, by_sorting_every_face(&m.tets));
        let mut boundary = 0;
        for (t, row) in nb.iter().enumerate() {
            for &o in row {
                if o < 0 {
                    boundary += 1;
                } else {
                    assert!(nb[o as usize].contains(&(t as i32)), "{t} -> {o}");
                }
            }
        }
        assert_eq!(boundary, 12 * 9);
    }
}
