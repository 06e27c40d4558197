//! The owner's side of a distributed query: every candidate rank's answer for a point comes
//! back, and one is chosen.
//!
//! **The rule: the lowest global cell id among the ranks that claim the point.** Under
//! tetloc's tie rule each point of a conforming mesh belongs to one cell (see `tetloc_core::geom`
//! and `geom::predicates`: the Simulation-of-Simplicity rule is geometric, it depends neither
//! on ids nor on which cells were tested first), and the pieces of a partitioned mesh are that
//! same mesh cut along faces, so at most one rank claims a point and this rule has nothing to
//! choose: the answer is the one process's answer on the whole mesh, id and value. Where several
//! ranks do claim a point (overlapping cells in a non-conforming mesh, or, while locators still
//! accept a point on a face in both tets, a point exactly on a face between two pieces), the
//! lowest global id makes the answer independent of the number of ranks and of which rank
//! answered first. Such points are counted ([`Reduced::ties`]).

use tetloc_core::geom::Real;
use tetloc_core::OUTSIDE;

/// The chosen answers for a batch, with values in f32 or f64 (`T`).
#[derive(Debug, Default)]
pub struct Reduced<T = f32> {
    /// Global cell id per point, -1 where no rank claimed it.
    pub ids: Vec<i64>,
    /// `k` values per point, NaN where no rank claimed it.
    pub values: Vec<T>,
    /// Points claimed by more than one rank.
    pub ties: usize,
}

/// Picks, for each of `n` points, the claim with the lowest global id. `index[s]` is the
/// batch index of the `s`-th answer, `ids[s]` its global id (< 0: not claimed) and
/// `values[s·k..(s+1)·k]` its values. The answers come rank after rank, each rank's in
/// ascending batch index (as `Routes::plan` sends them): blocks of points are reduced in
/// parallel, each from its own slice of every rank's answers.
pub fn reduce<T: Real>(n: usize, index: &[u32], ids: &[i64], values: &[T], k: usize) -> Reduced<T> {
    use rayon::prelude::*;
    // Each rank's run of answers: where the batch index stops ascending.
    let mut runs = vec![0];
    runs.extend((1..index.len()).filter(|&s| index[s] <= index[s - 1]));
    runs.push(index.len());
    // Blocks of ids and of values go in step; without fields, a placeholder value per point
    // keeps them so (dropped at the end).
    let per = k.max(1);
    let mut out = Reduced { ids: vec![OUTSIDE as i64; n], values: vec![T::NAN; n * per], ties: 0 };
    let ties: usize = out
        .ids
        .par_chunks_mut(BLOCK)
        .zip(out.values.par_chunks_mut(BLOCK * per))
        .enumerate()
        .map(|(b, (out_ids, out_values))| {
            let (lo, hi) = ((b * BLOCK) as u32, (b * BLOCK + out_ids.len()) as u32);
            let mut claims = vec![0u8; out_ids.len()];
            for w in runs.windows(2) {
                let run = &index[w[0]..w[1]];
                let (from, to) = (run.partition_point(|&i| i < lo), run.partition_point(|&i| i < hi));
                for s in w[0] + from..w[0] + to {
                    let id = ids[s];
                    if id < 0 {
                        continue;
                    }
                    let i = (index[s] - lo) as usize;
                    claims[i] = claims[i].saturating_add(1);
                    if out_ids[i] < 0 || id < out_ids[i] {
                        out_ids[i] = id;
                        out_values[i * k..(i + 1) * k].copy_from_slice(&values[s * k..(s + 1) * k]);
                    }
                }
            }
            claims.iter().filter(|&&c| c > 1).count()
        })
        .sum();
    out.ties = ties;
    out.values.truncate(n * k);
    out
}

/// Points a task reduces at once.
const BLOCK: usize = 1 << 16;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lowest_claimed_id_wins() {
        // Point 0: ranks claim 7 and 3; point 1: none; point 2: one claim; point 3: not sent.
        let index = [0, 1, 2, 0, 1];
        let ids = [7, -1, 5, 3, -1];
        let values = [7.0, 7.5, f32::NAN, f32::NAN, 5.0, 5.5, 3.0, 3.5, f32::NAN, f32::NAN];
        let r = reduce(4, &index, &ids, &values, 2);
        assert_eq!(r.ids, [3, -1, 5, -1]);
        assert_eq!(r.values[..2], [3.0, 3.5]);
        assert!(r.values[2..4].iter().all(|v| v.is_nan()) && r.values[6..].iter().all(|v| v.is_nan()));
        assert_eq!(r.values[4..6], [5.0, 5.5]);
        assert_eq!(r.ties, 1);
        // The order in which the answers come does not matter.
        let r2 = reduce(4, &[0, 0], &[3, 7], &[3.0, 3.5, 7.0, 7.5], 2);
        assert_eq!((r2.ids[0], r2.values[0]), (3, 3.0));
        // Several blocks, no fields: three ranks' runs, the middle one claiming every third
        // point with a lower id than the first, which claims all.
        let n = 3 * BLOCK + 17;
        let mut index: Vec<u32> = (0..n as u32).collect();
        index.extend((0..n as u32).step_by(3));
        index.extend((0..n as u32).filter(|i| i % 5 == 0));
        let ids: Vec<i64> = index
            .iter()
            .enumerate()
            .map(|(s, &i)| {
                if s < n {
                    1000 + i as i64
                } else if s < n + n.div_ceil(3) {
                    i as i64
                } else {
                    -1
                }
            })
            .collect();
        let r = reduce::<f32>(n, &index, &ids, &[], 0);
        assert!(r.values.is_empty());
        assert!((0..n).all(|i| r.ids[i] == if i % 3 == 0 { i as i64 } else { 1000 + i as i64 }));
        assert_eq!(r.ties, n.div_ceil(3));
    }
}
