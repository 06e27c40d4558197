//! Morton codes: a point's cell in a 2^bits grid over a box, its three coordinates'
//! bits interleaved (x in bit 0), so that sorting by code makes a Z-order curve. The one
//! encoding of tetloc: the BVH builder (21 bits an axis), the CPU locator's batch order and
//! the ray-tracing kernels' primitive order (10 bits an axis) all use it.

use crate::geom::Vec3;
use rayon::prelude::*;

/// Quantizes points of a box to `bits` per axis (at most 21: the code fits 63 bits).
#[derive(Clone, Copy, Debug)]
pub struct Morton {
    lo: Vec3,
    scale: Vec3,
    max: u32,
}

impl Morton {
    pub fn new(lo: Vec3, hi: Vec3, bits: u32) -> Morton {
        assert!((1..=21).contains(&bits), "{bits} bits an axis: Morton codes take 1 to 21");
        let max = (1u32 << bits) - 1;
        let scale = std::array::from_fn(|k| if hi[k] > lo[k] { max as f32 / (hi[k] - lo[k]) } else { 0.0 });
        Morton { lo, scale, max }
    }

    /// The box's minimum and the factor from it to cell units, per axis (for the GPU build,
    /// which computes the same codes with the same two operations).
    pub fn lo_scale(&self) -> (Vec3, Vec3) {
        (self.lo, self.scale)
    }

    /// The code of `p`; points outside the box (and NaN) get the nearest cell's.
    #[inline]
    pub fn code(&self, p: Vec3) -> u64 {
        // `as u32` saturates (negative and NaN to 0), then the grid's last cell caps it.
        let q = |k: usize| (((p[k] - self.lo[k]) * self.scale[k]) as u32).min(self.max) as u64;
        spread(q(0)) | spread(q(1)) << 1 | spread(q(2)) << 2
    }
}

/// Spreads the low 21 bits of `v` to every third bit.
#[inline]
pub fn spread(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | x << 32) & 0x1f_0000_0000_ffff;
    x = (x | x << 16) & 0x1f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// Indices `0..points.len()` in Morton order (10 bits an axis) of the points in the box
/// `lo..hi`; equal codes keep index order, so the order is deterministic.
pub fn order(points: &[Vec3], lo: Vec3, hi: Vec3) -> Vec<u32> {
    let m = Morton::new(lo, hi, 10);
    // Code and index in one u64: a plain integer sort orders by code, then index.
    let mut keyed: Vec<u64> = points.par_iter().enumerate().map(|(i, &p)| m.code(p) << 32 | i as u64).collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|k| k as u32).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Bit by bit: bit b of axis k goes to bit 3b + k.
    fn spread_slow(v: u64) -> u64 {
        (0..21).map(|b| ((v >> b) & 1) << (3 * b)).fold(0, |a, x| a | x)
    }

    proptest! {
        #[test]
        fn spread_interleaves_every_bit(v in 0u64..(1 << 21)) {
            prop_assert_eq!(spread(v), spread_slow(v));
        }

        /// Codes grow with each coordinate (the Z-order curve is monotone per axis).
        #[test]
        fn codes_are_monotone_per_axis(p in prop::array::uniform3(0f32..1.0), d in 0f32..1.0, axis in 0usize..3) {
            let m = Morton::new([0.0; 3], [1.0; 3], 10);
            let mut q = p;
            q[axis] = (p[axis] + d).min(1.0);
            prop_assert!(m.code(q) >= m.code(p));
        }
    }

    #[test]
    fn corners_outside_and_flat_axes() {
        let m = Morton::new([0.0; 3], [1.0, 1.0, 0.0], 10);
        assert_eq!(m.code([0.0; 3]), 0);
        // The far corner of the two used axes: all x and y bits set, no z bits.
        assert_eq!(m.code([1.0, 1.0, 0.0]), spread(1023) | spread(1023) << 1);
        assert_eq!(m.code([-5.0, f32::NAN, 7.0]), 0, "below the box and NaN clamp to 0; a flat axis is 0");
        assert_eq!(m.code([9.0, 0.0, 0.0]), spread(1023), "above the box clamps to the last cell");
    }

    #[test]
    fn order_is_a_deterministic_permutation() {
        let c: Vec<Vec3> = (0..1000).map(|i| [(i % 10) as f32, (i / 10 % 10) as f32, (i / 100) as f32]).collect();
        let mut o = order(&c, [0.0; 3], [9.0; 3]);
        assert_eq!(o[0], 0);
        assert_eq!(o[1], 1, "x varies fastest along the curve");
        let twice = [c.clone(), c].concat();
        let o2 = order(&twice, [0.0; 3], [9.0; 3]);
        assert_eq!(&o2[..2], &[0, 1000], "equal codes keep index order");
        o.sort();
        assert!(o.iter().enumerate().all(|(i, &v)| i as u32 == v));
    }
}
