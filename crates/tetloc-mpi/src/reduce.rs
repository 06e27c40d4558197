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

use tetloc_core::OUTSIDE;

/// The chosen answers for a batch.
#[derive(Debug, Default)]
pub struct Reduced {
    /// Global cell id per point, -1 where no rank claimed it.
    pub ids: Vec<i64>,
    /// `k` values per point, NaN where no rank claimed it.
    pub values: Vec<f32>,
    /// Points claimed by more than one rank.
    pub ties: usize,
}

/// Picks, for each of `n` points, the claim with the lowest global id. `index[s]` is the
/// batch index of the `s`-th answer, `ids[s]` its global id (< 0: not claimed) and
/// `values[s·k..(s+1)·k]` its values.
pub fn reduce(n: usize, index: &[u32], ids: &[i64], values: &[f32], k: usize) -> Reduced {
    let mut out = Reduced { ids: vec![OUTSIDE as i64; n], values: vec![f32::NAN; n * k], ties: 0 };
    let mut claims = vec![0u8; n];
    for (s, (&i, &id)) in index.iter().zip(ids).enumerate() {
        if id < 0 {
            continue;
        }
        let i = i as usize;
        claims[i] = claims[i].saturating_add(1);
        if out.ids[i] < 0 || id < out.ids[i] {
            out.ids[i] = id;
            out.values[i * k..(i + 1) * k].copy_from_slice(&values[s * k..(s + 1) * k]);
        }
    }
    out.ties = claims.iter().filter(|&&c| c > 1).count();
    out
}

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
    }
}
