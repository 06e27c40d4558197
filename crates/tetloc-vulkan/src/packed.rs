//! Packed id arrays: fields of `bits` bits each, back to back from bit 0, least significant
//! bit first, in 32-bit words (field j holds bits j·bits .. (j+1)·bits). Ids that need fewer
//! than 32 bits (jets 62M: 24-bit vertex ids, 26-bit tet ids) take that much and no more; the
//! `compact` and `small` layouts pack the tets, the neighbours and the leaf prims this way
//! (BENCHMARKS.md). The shaders read them with `TL_PACKED_READER` (a field) and
//! `TL_PACKED4_READER` (a tet's four) in shaders/common/packed.glsl; the GPU build writes them
//! with shaders/build/pack.comp.

use crate::device::Device;
use crate::error::VkResult;
use crate::memory::{Buffer, MemKind};
use ash::vk;
use rayon::prelude::*;

/// Bits that hold every value in `0..=max` (at least 1).
pub(crate) fn bits_for(max: u64) -> u32 {
    (64 - max.leading_zeros()).max(1)
}

/// Bits a field of a packed array of `fields` values up to `max`, at least `min_bits` (a test
/// hook: wider fields hold the same values), or 0 where packing is not worth it (32 bits) or
/// the packed array would not fit one buffer of `max_buffer` bytes (the readers take one).
pub(crate) fn width(max: u64, fields: u64, min_bits: u32, max_buffer: u64) -> u32 {
    let bits = bits_for(max).max(min_bits);
    if bits >= 32 || 4 * words(fields, bits) > max_buffer {
        0
    } else {
        bits
    }
}

/// Words of a packed array of `n` fields of `bits` bits: the fields, 4 words of padding (the
/// shaders read a record's five words at once), rounded up to whole uvec4 (some arrays are
/// read as uvec4).
pub(crate) fn words(n: u64, bits: u32) -> u64 {
    ((n * bits as u64).div_ceil(32) + 4).div_ceil(4) * 4
}

/// `values` packed at `bits` bits each; every value must fit.
pub(crate) fn pack(values: &[u32], bits: u32) -> Vec<u32> {
    assert!((1..=32).contains(&bits), "packed fields hold 1 to 32 bits, not {bits}");
    let mut out = vec![0u32; words(values.len() as u64, bits) as usize];
    // 32 fields take exactly `bits` words, so each such group packs on its own.
    out.par_chunks_mut(bits as usize).zip(values.par_chunks(32)).for_each(|(group_words, group)| {
        let (mut acc, mut filled, mut at) = (0u64, 0u32, 0usize);
        for &v in group {
            debug_assert!(bits == 32 || v >> bits == 0, "{v} does not fit {bits} bits");
            acc |= (v as u64) << filled;
            filled += bits;
            if filled >= 32 {
                group_words[at] = acc as u32;
                (acc, filled, at) = (acc >> 32, filled - 32, at + 1);
            }
        }
        if filled > 0 {
            group_words[at] = acc as u32;
        }
    });
    out
}

/// `values` packed at `bits` bits each, uploaded as one storage buffer named `name` (the
/// packed readers take one buffer).
pub(crate) fn upload(dev: &mut Device, name: &str, kind: MemKind, values: &[u32], bits: u32) -> VkResult<Buffer> {
    dev.upload(name, kind, vk::BufferUsageFlags::STORAGE_BUFFER, bytemuck::cast_slice(&pack(values, bits)))
}

/// Field `j` of a packed array (what `TL_PACKED_READER` computes on the GPU; the tests read
/// the GPU's packed arrays back with it).
#[cfg(test)]
pub(crate) fn get(words: &[u32], j: u64, bits: u32) -> u32 {
    let bit = j * bits as u64;
    let (w, s) = ((bit / 32) as usize, (bit % 32) as u32);
    let mut v = words[w] as u64 >> s;
    if s + bits > 32 {
        v |= (words[w + 1] as u64) << (32 - s);
    }
    (v & ((1u64 << bits) - 1)) as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn bit_counts() {
        assert_eq!([0, 1, 2, 255, 256].map(bits_for), [1, 1, 2, 8, 9]);
        assert_eq!(bits_for(u32::MAX as u64), 32);
        // jets 62M: 10.5M vertices, 62M tets and their neighbours + 1
        assert_eq!((bits_for(10_500_000 - 1), bits_for(62_000_000)), (24, 26));
        assert_eq!(words(5, 24), 8);
        assert_eq!(words(17, 32), 24);
        assert_eq!(words(0, 7), 4);
        assert_eq!(width(10_499_999, 4 * 62_000_000, 0, 4 << 30), 24);
        assert_eq!(width(10_499_999, 4 * 62_000_000, 27, 4 << 30), 27);
        assert_eq!(width(u32::MAX as u64, 4, 0, 4 << 30), 0);
        assert_eq!(width(1000, 4 * 62_000_000, 0, 1 << 20), 0);
    }

    proptest! {
        /// Every field reads back, whatever the width and the length (groups of 32 fields
        /// and a partial last one), and the words past the last field stay zero.
        #[test]
        fn fields_read_back(bits in 1u32..=32, raw in proptest::collection::vec(any::<u32>(), 0..300)) {
            let mask = if bits == 32 { u32::MAX } else { (1 << bits) - 1 };
            let values: Vec<u32> = raw.iter().map(|v| v & mask).collect();
            let packed = pack(&values, bits);
            prop_assert_eq!(packed.len() as u64, words(values.len() as u64, bits));
            for (j, &v) in values.iter().enumerate() {
                prop_assert_eq!(get(&packed, j as u64, bits), v);
            }
            let used = (values.len() as u64 * bits as u64).div_ceil(32) as usize;
            prop_assert!(packed[used..].iter().all(|&w| w == 0));
        }
    }
}
