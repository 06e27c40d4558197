//! Face adjacency: for each tet and each of its stored vertices, the tet across the face
//! opposite that vertex (-1 on the boundary). Found, like the unique faces, by a parallel
//! sort of all tet faces rather than a hash map.

use rayon::prelude::*;

/// `tets` must be in canonical order. Tet counts up to 2³⁰ (two bits hold the local face).
pub fn build(tets: &[[u32; 4]]) -> Vec<[i32; 4]> {
    assert!(tets.len() < 1 << 30, "face adjacency supports up to 2^30 tets");
    let mut recs: Vec<[u32; 4]> = tets
        .par_iter()
        .enumerate()
        .flat_map_iter(|(t, &tet)| {
            (0..4).map(move |i| {
                let mut f = [0u32; 3];
                let mut k = 0;
                for (j, &v) in tet.iter().enumerate() {
                    if j != i {
                        f[k] = v;
                        k += 1;
                    }
                }
                f.sort_unstable();
                [f[0], f[1], f[2], (t as u32) << 2 | i as u32]
            })
        })
        .collect();
    sort_faces(&mut recs);
    let mut out = vec![[-1i32; 4]; tets.len()];
    // Pairs of equal faces are neighbours; a face shared by more than two tets (a broken
    // mesh) links only its first two.
    let pairs: Vec<(u32, u32)> = (1..recs.len())
        .into_par_iter()
        .filter(|&k| recs[k][..3] == recs[k - 1][..3] && (k < 2 || recs[k - 2][..3] != recs[k][..3]))
        .map(|k| (recs[k - 1][3], recs[k][3]))
        .collect();
    for (a, b) in pairs {
        out[(a >> 2) as usize][(a & 3) as usize] = (b >> 2) as i32;
        out[(b >> 2) as usize][(b & 3) as usize] = (a >> 2) as i32;
    }
    out
}

/// Sorts face records (three ascending vertex ids, then the tet and local face) into the
/// order of `sort_unstable`: a counting sort on the smallest vertex (linear), then each
/// vertex's few dozen faces sorted alone, in parallel. Several times quicker than a
/// comparison sort of every record.
fn sort_faces(recs: &mut Vec<[u32; 4]>) {
    let n = recs.par_iter().map(|r| r[0] as usize + 1).max().unwrap_or(0);
    let mut next = vec![0usize; n + 1];
    for r in recs.iter() {
        next[r[0] as usize + 1] += 1;
    }
    for v in 1..=n {
        next[v] += next[v - 1];
    }
    let mut sorted = vec![[0u32; 4]; recs.len()];
    for r in recs.iter() {
        let at = &mut next[r[0] as usize];
        sorted[*at] = *r;
        *at += 1;
    }
    sorted.par_chunk_by_mut(|a, b| a[0] == b[0]).for_each(|c| c.sort_unstable());
    *recs = sorted;
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The counting sort gives the comparison sort's order, repeated records included.
    #[test]
    fn face_records_sort_as_a_comparison_sort() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
        for n in [0usize, 1, 7, 5000] {
            let mut recs: Vec<[u32; 4]> = (0..n)
                .map(|_| {
                    let mut f: [u32; 3] = std::array::from_fn(|_| rng.gen_range(0..40));
                    f.sort_unstable();
                    [f[0], f[1], f[2], rng.gen_range(0..8)]
                })
                .collect();
            let mut want = recs.clone();
            want.sort_unstable();
            sort_faces(&mut recs);
            assert_eq!(recs, want);
        }
    }

    /// Neighbours are mutual across shared faces, and -1 exactly on the boundary: a KuhnGrid
    /// cube of n^3 cubes has 12 n^2 boundary faces.
    #[test]
    fn neighbours_of_a_grid() {
        let m = crate::test_support::KuhnGrid::new(3).mesh("cube");
        let nb = build(&m.tets);
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
