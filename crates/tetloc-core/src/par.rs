//! Small parallel helpers that rayon's own adapters make slow for cheap per-item tests.

use rayon::prelude::*;

/// Items a block of [`first_position`] holds.
const BLOCK: usize = 1 << 14;

/// The index of the first item for which `bad` holds: blocks tested in parallel, then the
/// first bad block searched in order. rayon's `position_first` synchronises at every item,
/// which costs more than a range check: validating a 10M-tet mesh's ids with it took longer
/// than reading them.
pub fn first_position<T: Sync>(items: &[T], bad: impl Fn(&T) -> bool + Sync) -> Option<usize> {
    let block = items.par_chunks(BLOCK).position_first(|c| c.iter().any(&bad))?;
    let start = block * BLOCK;
    items[start..].iter().position(&bad).map(|i| start + i)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The same index as a sequential search, for bad items anywhere (none, one, many,
        /// at block edges).
        #[test]
        fn first_position_is_the_first(len in 0usize..3 * BLOCK + 5, bad in prop::collection::vec(0usize..3 * BLOCK + 5, 0..4)) {
            let items: Vec<bool> = (0..len).map(|i| bad.contains(&i)).collect();
            prop_assert_eq!(first_position(&items, |&b| b), items.iter().position(|&b| b));
        }
    }

    #[test]
    fn block_edges() {
        for at in [0, BLOCK - 1, BLOCK, 2 * BLOCK + 1] {
            let mut items = vec![0u8; 3 * BLOCK];
            items[at] = 1;
            items[3 * BLOCK - 1] = 1;
            assert_eq!(first_position(&items, |&x| x == 1), Some(at));
        }
    }
}
