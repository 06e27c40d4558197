//! Items grouped by key in compressed rows: a counting sort, counted and scattered on every
//! core. Each chunk of items counts into its own row of counters; the scan over (key, chunk)
//! then gives every chunk its own places in every key's row, so the scatter writes disjoint
//! places in parallel and a key's entries keep the items' order (ascending item, then the
//! order an item gives them). The bins of the CPU batches, the tets around each vertex and
//! the resample raster's planes are grouped this way (each was a serial counting sort).

use rayon::prelude::*;

/// Entries grouped by key: key `k`'s are `entries[offsets[k]..offsets[k + 1]]`.
pub(crate) struct Buckets<T> {
    pub(crate) offsets: Vec<u32>,
    pub(crate) entries: Vec<T>,
}

/// Items a chunk counts, at the least (fewer chunks than threads below it).
const MIN_CHUNK: usize = 1 << 14;
/// Counters of all chunks together (4 bytes each) past which fewer chunks count (one, at
/// the least, whatever the number of keys).
const MAX_COUNTERS: usize = 1 << 25;
/// Keys a task of the scan takes.
const KEY_BLOCK: usize = 1 << 14;

impl<T: Copy + Send + Sync> Buckets<T> {
    /// Groups the entries that `entries_of(i)` gives for each item `i` in `0..n_items`, as
    /// (key, value). `entries_of` is called twice an item (to count, then to place). Panics
    /// on a key not below `n_keys` and past 2³² entries.
    ///
    /// # Safety
    /// `entries_of` gives the same keys, in the same order, both times it is called for an
    /// item (a function of the item over data nobody changes meanwhile): the places of the
    /// scatter are counted by the first call, and two tasks would write one place if the
    /// second gave more of a key than the first.
    pub(crate) unsafe fn build<I: IntoIterator<Item = (usize, T)>>(
        n_keys: usize,
        n_items: usize,
        entries_of: impl Fn(usize) -> I + Sync,
    ) -> Buckets<T> {
        let chunks = rayon::current_num_threads().min(n_items / MIN_CHUNK).min(MAX_COUNTERS / n_keys.max(1)).max(1);
        let per = n_items.div_ceil(chunks).max(1);
        let items = |c: usize| c * per..((c + 1) * per).min(n_items);
        // counts[c * n_keys + k]: chunk c's entries of key k; after the scan, where they go.
        let mut counts = vec![0u32; chunks * n_keys];
        counts.par_chunks_mut(n_keys.max(1)).enumerate().for_each(|(c, row)| {
            for i in items(c) {
                for (k, _) in entries_of(i) {
                    row[k] = row[k].checked_add(1).expect("more than 2^32 grouped entries");
                }
            }
        });
        // The scan in key order, chunks within a key: blocks of keys summed in parallel, the
        // blocks' starts in order, then each block's places in parallel.
        let block_total = |b: usize| -> u64 {
            let keys = b * KEY_BLOCK..((b + 1) * KEY_BLOCK).min(n_keys);
            keys.map(|k| (0..chunks).map(|c| counts[c * n_keys + k] as u64).sum::<u64>()).sum()
        };
        let n_blocks = n_keys.div_ceil(KEY_BLOCK);
        let totals: Vec<u64> = (0..n_blocks).into_par_iter().map(block_total).collect();
        let mut block_start = Vec::with_capacity(n_blocks);
        let mut total = 0u64;
        for t in totals {
            block_start.push(total);
            total += t;
        }
        assert!(total <= u32::MAX as u64, "more than 2^32 grouped entries");
        let mut offsets = vec![0u32; n_keys + 1];
        offsets[n_keys] = total as u32;
        // Each block writes its keys' offsets and its keys' counters (turned into places):
        // the counters of one key in every chunk row, reached through a shared pointer.
        let places = SharedSlice::new(&mut counts);
        offsets[..n_keys].par_chunks_mut(KEY_BLOCK).enumerate().for_each(|(b, offs)| {
            let mut at = block_start[b] as u32;
            for (j, o) in offs.iter_mut().enumerate() {
                let k = b * KEY_BLOCK + j;
                *o = at;
                for c in 0..chunks {
                    // SAFETY: counts has chunks * n_keys elements and k < n_keys; key k's
                    // counters belong to the block holding k alone, so no two tasks touch
                    // one element, and `counts` is not otherwise used until the loop ends.
                    unsafe {
                        let p = places.at(c * n_keys + k);
                        let n = *p;
                        *p = at;
                        at += n;
                    }
                }
            }
        });
        let mut entries: Vec<T> = Vec::with_capacity(total as usize);
        let out = SharedSlice(entries.as_mut_ptr());
        counts.par_chunks_mut(n_keys.max(1)).enumerate().for_each(|(c, next)| {
            for i in items(c) {
                for (k, v) in entries_of(i) {
                    let at = next[k] as usize;
                    assert!(at < total as usize, "grouped entries changed between the two passes");
                    // SAFETY: chunk c's entries of key k go to next[k].. (its own range of
                    // `count` places, disjoint from every other (chunk, key)'s by the scan,
                    // as the caller promises the same entries as counted), below `total`,
                    // the capacity (checked); each place is written once.
                    unsafe { out.at(at).write(v) };
                    next[k] += 1;
                }
            }
        });
        // SAFETY: every place below `total` was written once above (the ranges tile 0..total).
        unsafe { entries.set_len(total as usize) };
        Buckets { offsets, entries }
    }

    /// Key `k`'s entries.
    #[inline]
    pub fn of(&self, k: usize) -> &[T] {
        &self.entries[self.offsets[k] as usize..self.offsets[k + 1] as usize]
    }

    pub fn n_keys(&self) -> usize {
        self.offsets.len() - 1
    }
}

/// A pointer that parallel tasks share, each writing places no other task writes (here and
/// in the CPU locator's sorted batches).
pub(crate) struct SharedSlice<T>(*mut T);

impl<T> SharedSlice<T> {
    /// The slice's first place (the caller keeps the slice borrowed while the places are used).
    pub(crate) fn new(slice: &mut [T]) -> SharedSlice<T> {
        SharedSlice(slice.as_mut_ptr())
    }

    /// Place `i` (a method, so that closures capture the whole wrapper, not its pointer).
    ///
    /// # Safety
    /// `i` is within the allocation the pointer came from.
    #[inline]
    pub(crate) unsafe fn at(&self, i: usize) -> *mut T {
        // SAFETY: the caller keeps `i` within the allocation.
        unsafe { self.0.add(i) }
    }
}
// SAFETY: used only as described at each use: disjoint places per task.
unsafe impl<T: Send> Sync for SharedSlice<T> {}
// SAFETY: as above.
unsafe impl<T: Send> Send for SharedSlice<T> {}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The same rows as a serial counting sort, for items with zero, one and many entries,
    /// keys repeated within an item, and sizes on both sides of the chunking.
    #[test]
    fn grouped_as_a_serial_counting_sort() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        for (n_items, n_keys) in [(0usize, 1usize), (1, 1), (10, 3), (100_000, 7), (70_000, 40_000), (5, 0)] {
            let items: Vec<Vec<(usize, u32)>> = (0..n_items)
                .map(|i| {
                    let m = if n_keys == 0 { 0 } else { rng.gen_range(0..5) };
                    (0..m).map(|_| (rng.gen_range(0..n_keys), i as u32)).collect()
                })
                .collect();
            // SAFETY: the items are fixed: the same entries on both calls.
            let got = unsafe { Buckets::build(n_keys, n_items, |i| items[i].iter().copied()) };
            let mut rows = vec![Vec::new(); n_keys];
            for item in &items {
                for &(k, v) in item {
                    rows[k].push(v);
                }
            }
            assert_eq!(got.n_keys(), n_keys);
            for (k, row) in rows.iter().enumerate() {
                assert_eq!(got.of(k), &row[..], "key {k} of {n_keys}, {n_items} items");
            }
            assert_eq!(got.entries.len(), rows.iter().map(Vec::len).sum::<usize>());
        }
    }
}
