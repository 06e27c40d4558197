//! Gmsh tags (any u64, possibly sparse and unordered) mapped to dense 0-based indices in
//! file order, for nodes and for elements.

use std::collections::HashMap;

/// Maps Gmsh tags (any u64, possibly sparse) to dense 0-based indices.
pub(super) enum TagMap {
    /// Tags `min, min + 1, ...` in file order (what gmsh writes): no table at all.
    Sequential {
        min: u64,
        len: u64,
    },
    /// Tags within a span not much larger than their count: a direct lookup table.
    Dense {
        min: u64,
        index: Vec<u32>,
    },
    Sparse(HashMap<u64, u32>),
}

impl TagMap {
    /// `Err(tag)` names a tag that appears twice.
    pub fn new(tags: &[u64]) -> Result<TagMap, u64> {
        let (Some(&min), Some(&max)) = (tags.iter().min(), tags.iter().max()) else {
            return Ok(TagMap::Sequential { min: 0, len: 0 });
        };
        if tags.iter().enumerate().all(|(i, &t)| t == min + i as u64) {
            return Ok(TagMap::Sequential { min, len: tags.len() as u64 });
        }
        let span = max - min;
        if span < 2 * tags.len() as u64 + 1024 {
            let mut index = vec![u32::MAX; span as usize + 1];
            for (i, &t) in tags.iter().enumerate() {
                let slot = &mut index[(t - min) as usize];
                if *slot != u32::MAX {
                    return Err(t);
                }
                *slot = i as u32;
            }
            Ok(TagMap::Dense { min, index })
        } else {
            let mut map = HashMap::with_capacity(tags.len());
            for (i, &t) in tags.iter().enumerate() {
                if map.insert(t, i as u32).is_some() {
                    return Err(t);
                }
            }
            Ok(TagMap::Sparse(map))
        }
    }

    #[inline]
    pub fn get(&self, tag: u64) -> Option<u32> {
        match self {
            TagMap::Sequential { min, len } => tag.checked_sub(*min).filter(|i| i < len).map(|i| i as u32),
            TagMap::Dense { min, index } => {
                let i = usize::try_from(tag.checked_sub(*min)?).ok()?;
                index.get(i).copied().filter(|&v| v != u32::MAX)
            }
            TagMap::Sparse(map) => map.get(&tag).copied(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_layout_maps_tags_to_file_order() {
        let sequential = [5, 6, 7, 8];
        let dense = [9, 3, 4, 12, 10];
        let sparse = [1 << 40, 7, 1 << 20];
        assert!(matches!(TagMap::new(&sequential), Ok(TagMap::Sequential { .. })));
        assert!(matches!(TagMap::new(&dense), Ok(TagMap::Dense { .. })));
        assert!(matches!(TagMap::new(&sparse), Ok(TagMap::Sparse(_))));
        for tags in [&sequential[..], &dense, &sparse, &[]] {
            let map = TagMap::new(tags).unwrap();
            for (i, &t) in tags.iter().enumerate() {
                assert_eq!(map.get(t), Some(i as u32), "{tags:?}");
            }
            for missing in [0, 2, 11, 13, u64::MAX] {
                assert_eq!(map.get(missing), None, "{tags:?}: {missing}");
            }
        }
        assert_eq!(TagMap::new(&[4, 5, 4]).err(), Some(4));
        assert_eq!(TagMap::new(&[1 << 40, 3, 1 << 40]).err(), Some(1 << 40));
    }
}
