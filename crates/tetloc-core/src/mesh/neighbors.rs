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
    recs.par_sort_unstable();
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
