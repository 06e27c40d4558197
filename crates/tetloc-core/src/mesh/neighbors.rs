//! Face adjacency: for each tet and each of its stored vertices, the tet across the face
//! opposite that vertex (-1 on the boundary). Each face is owned by its smallest vertex:
//! the tets listed at each vertex (a counting sort, linear, on every core) give that vertex's
//! faces, a few dozen, matched among themselves in parallel (a small hash table each). No sort of
//! every face of the mesh.

use crate::buckets::Buckets;
use rayon::prelude::*;
use std::sync::atomic::{AtomicI32, Ordering::Relaxed};

/// `tets` must be in canonical order (`geom::canonical_tet`: ids ascending but for the last
/// two, which may be swapped), so that each face's vertices come sorted with no sort. Tet
/// counts up to 2³⁰ (two bits hold the local face).
pub fn build(tets: &[[u32; 4]]) -> Vec<[i32; 4]> {
    assert!(tets.len() < 1 << 30, "face adjacency supports up to 2^30 tets");
    debug_assert!(tets.iter().all(|&[a, b, c, d]| a <= b && b <= c.min(d)), "tets in canonical order");
    let around = VertexTets::build(tets);
    let mut result = vec![[-1i32; 4]; tets.len()];
    const _: () = assert!(std::mem::align_of::<AtomicI32>() == std::mem::align_of::<i32>());
    // SAFETY: AtomicI32 has the same size and bit validity as i32 (std's documentation) and,
    // checked above, its alignment; `result` is borrowed only through `out` until the loop
    // below ends: the rows are written in place, with no second array to copy back.
    let out: &[[AtomicI32; 4]] = unsafe { &*(result.as_mut_slice() as *mut [[i32; 4]] as *const [[AtomicI32; 4]]) };
    // Each vertex's faces (those it is the smallest vertex of): the other two vertices, then
    // the tet and local face. Every (tet, face) slot is written by one vertex only.
    let buffers = || (Vec::new(), Vec::new());
    (0..around.n_vertices()).into_par_iter().with_min_len(1024).for_each_init(buffers, |(faces, table), v| {
        faces.clear();
        for &t in around.of(v) {
            // Canonical order: a ≤ b ≤ c, d (c and d in either order). The face opposite a
            // is owned by b, the other three by a (by both where a = b). Pushed in (tet,
            // local face) order, the order in which equal faces pair.
            let [a, b, c, d] = tets[t as usize];
            let (lo, hi) = (c.min(d), c.max(d));
            let t = t << 2;
            if b == v as u32 {
                faces.push([lo, hi, t]);
            }
            if a == v as u32 {
                faces.extend([[lo, hi, t | 1], [b, d, t | 2], [b, c, t | 3]]);
            }
        }
        // The first two of each face are neighbours; a face shared by more than two tets (a
        // broken mesh) links only its first two.
        pair(faces, table, |a, b| {
            out[(a >> 2) as usize][(a & 3) as usize].store((b >> 2) as i32, Relaxed);
            out[(b >> 2) as usize][(b & 3) as usize].store((a >> 2) as i32, Relaxed);
        });
    });
    result
}

/// In `table` (0: empty; else 1 + the index in `faces` of the first of a face, with this bit
/// set once its second has come).
const PAIRED: u32 = 1 << 31;

/// Calls `link(first, second)` with the tet-and-face codes of the first two of each of one
/// vertex's faces (its other two vertices, then the code), in the order the faces came:
/// matched by a small open-addressing table (`table`, reused) rather than a sort, as a
/// vertex owns a few dozen faces.
fn pair(faces: &[[u32; 3]], table: &mut Vec<u32>, mut link: impl FnMut(u32, u32)) {
    let n = faces.len();
    if n < 2 {
        return;
    }
    // At most half full: short probes.
    let bits = (2 * n).next_power_of_two().trailing_zeros();
    table.clear();
    table.resize(1 << bits, 0);
    let mask = (1usize << bits) - 1;
    for (i, &[lo, hi, code]) in faces.iter().enumerate() {
        let key = (lo as u64) << 32 | hi as u64;
        let mut at = (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - bits)) as usize;
        loop {
            let slot = table[at];
            if slot == 0 {
                table[at] = i as u32 + 1;
                break;
            }
            let first = faces[((slot & !PAIRED) - 1) as usize];
            if first[..2] == [lo, hi] {
                if slot & PAIRED == 0 {
                    link(first[2], code);
                    table[at] = slot | PAIRED;
                }
                break;
            }
            at = (at + 1) & mask;
        }
    }
}

/// The tets that own a face at each vertex, in ascending tet order (compressed rows). A
/// face's owner is its smallest vertex, which is its tet's smallest (the three faces through
/// it) or, for the face opposite that one, the tet's second smallest: a tet is listed at
/// those two vertices only (once where they are equal, in a degenerate tet).
struct VertexTets(Buckets<u32>);

impl VertexTets {
    fn build(tets: &[[u32; 4]]) -> VertexTets {
        let n = tets.par_iter().map(|t| t.iter().max().map_or(0, |&m| m as usize + 1)).max().unwrap_or(0);
        // SAFETY: a tet's vertices are a function of `tets`, borrowed unchanged.
        let lists = unsafe {
            Buckets::build(n, tets.len(), |t| {
                let v = tets[t];
                let second = (v[1] != v[0]).then_some((v[1] as usize, t as u32));
                std::iter::once((v[0] as usize, t as u32)).chain(second)
            })
        };
        VertexTets(lists)
    }

    fn n_vertices(&self) -> usize {
        self.0.n_keys()
    }

    fn of(&self, v: usize) -> &[u32] {
        self.0.of(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

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

    /// Random canonical tets over few vertices (repeated ids too) share faces two, three and
    /// more at a time.
    #[test]
    fn vertex_owned_faces_pair_as_sorting_every_face() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
        for n in [0usize, 1, 7, 5000] {
            let tets: Vec<[u32; 4]> = (0..n)
                .map(|_| {
                    let mut t: [u32; 4] = std::array::from_fn(|_| rng.gen_range(0..12));
                    t.sort_unstable();
                    if rng.gen_bool(0.5) {
                        t.swap(2, 3);
                    }
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
