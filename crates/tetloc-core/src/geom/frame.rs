//! The working frame: where the f32 copy of the vertices that every backend searches lives
//! relative to the file's f64 coordinates.
//!
//! `working(x) = f32((x − origin) · scale)`, the subtraction and the power-of-two scaling in
//! f64, then rounded to the nearest f32. For almost every mesh the frame is the identity
//! (`origin` 0, `scale` 1): its working copy is the file's coordinates rounded to f32, as
//! everywhere before. A mesh far from the origin relative to its size (UTM-like coordinates:
//! 10 km of mesh at 4000 km from the origin) gets its bounds' centre as origin, so that its
//! f32 copy keeps f32's relative precision with respect to the mesh's size instead of its
//! distance from the origin: a shift by 1e7 would otherwise collapse small tets to zero volume.
//! A file stored in f32 gets the same frame when it is far from the origin: its coordinates
//! widen to f64 exactly and are its f64 data (`Mesh::points64`), so that f64 query points are
//! decided as given, not rounded to f32 steps of its distance from the origin.
//! `scale` is not 1 only for meshes whose extent is outside [2⁻²⁰, 2⁴⁰] (f32 products of
//! coordinate differences would underflow or overflow).
//!
//! **Why the answers stay exact.** Rounding is monotone, so a point inside a tet's f64 box is
//! inside the f32 box of the rounded vertices: box culling (BVH, entry grid) never loses a
//! tet. Each face sign is first decided in f32 with a bound that covers the f32 arithmetic
//! *and* the rounding of vertices and point to the working copy ([`Frame::delta`], the Δ' of
//! `geom::predicates::local`); where the bound cannot decide, the exact sign on the file's f64
//! coordinates does (`geom::test_point_with`).

use crate::geom::Vec3;

/// See the module's documentation.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Frame {
    pub origin: [f64; 3],
    /// A power of two.
    pub scale: f64,
    /// Δ' of the f32 filter: a bound on the rounding of one coordinate difference (vertex
    /// minus point, both rounded to the working copy), with the slack that pays for the
    /// bound's own f32 evaluation; 0 when the working copy is the file's data exactly.
    pub delta: f32,
}

impl Frame {
    /// The identity: working coordinates are the file's, which are f32 already.
    pub const IDENTITY: Frame = Frame { origin: [0.0; 3], scale: 1.0, delta: 0.0 };

    /// The frame of f64 vertices whose bounds are `lo`, `hi` (finite).
    pub fn for_bounds(lo: [f64; 3], hi: [f64; 3]) -> Frame {
        let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f64, f64::max);
        let far = (0..3).map(|k| lo[k].abs().max(hi[k].abs())).fold(0.0f64, f64::max);
        // Near the origin (the box reaches no farther than 4 times its size from it) the
        // identity loses at most 3 bits of f32 precision against the best frame.
        let origin =
            if far <= 4.0 * extent { [0.0; 3] } else { std::array::from_fn(|k| lo[k] + 0.5 * (hi[k] - lo[k])) };
        let radius = (0..3).map(|k| (lo[k] - origin[k]).abs().max((hi[k] - origin[k]).abs())).fold(0.0f64, f64::max);
        let mut scale = 1.0f64;
        if radius > 0.0 {
            while radius * scale > (1u64 << 40) as f64 {
                scale *= 0.5;
            }
            while radius * scale < 1.0 / (1u64 << 20) as f64 {
                scale *= 2.0;
            }
        }
        // Working coordinates of points inside the box are at most 2^e in magnitude, with
        // 2^e the power of two at or above the scaled radius: each rounds by at most 2^(e−25)
        // (half an f32 ulp below 2^e), plus 2^(e−53) for the f64 subtraction. A coordinate
        // difference is then off by Δ = 2^(e−24)(1 + 2⁻²⁸); Δ' = Δ(1 + 2⁻¹⁹) pays for the
        // bound's own 13 f32 roundings (geom::predicates::local): Δ' ≤ 2^(e−24)(1 + 2⁻¹⁸).
        let e = (radius * scale).max(f64::MIN_POSITIVE).log2().ceil();
        let delta = (2f64.powf(e - 24.0) * (1.0 + 1.0 / 262_144.0)) as f32;
        Frame { origin, scale, delta }
    }

    pub fn is_identity(&self) -> bool {
        self.origin == [0.0; 3] && self.scale == 1.0
    }

    /// The working f32 coordinates of a point given in the file's coordinates.
    #[inline]
    pub fn to_working(&self, x: [f64; 3]) -> Vec3 {
        self.to_working64(x).map(|c| c as f32)
    }

    /// [`Self::to_working`] before the rounding to f32.
    #[inline]
    pub fn to_working64(&self, x: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| (x[k] - self.origin[k]) * self.scale)
    }

    /// [`Frame::to_working`] of a point given in f32 (exact when the frame is the identity).
    #[inline]
    pub fn to_working_f32(&self, x: Vec3) -> Vec3 {
        if self.is_identity() {
            x
        } else {
            self.to_working(x.map(f64::from))
        }
    }

    /// A working point back in the file's coordinates (rounded in f64).
    #[inline]
    pub fn to_file(&self, w: Vec3) -> [f64; 3] {
        self.to_file64(w.map(f64::from))
    }

    /// [`Frame::to_file`] of a working point held in f64 (a point computed from the copy).
    #[inline]
    pub fn to_file64(&self, w: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| w[k] / self.scale + self.origin[k])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_the_origin_the_frame_is_the_identity() {
        let f = Frame::for_bounds([0.0, -1.0, 2.0], [1.0, 1.0, 3.0]);
        assert!(f.is_identity());
        assert_eq!(f.to_working([0.1, 0.2, 0.3]), [0.1f32, 0.2, 0.3]);
    }

    #[test]
    fn far_from_the_origin_the_frame_is_centred_and_keeps_precision() {
        let (lo, hi) = ([512_345.0, 4_123_456.0, 0.0], [522_345.0, 4_133_456.0, 10_000.0]);
        let f = Frame::for_bounds(lo, hi);
        assert_eq!(f.origin, [517_345.0, 4_128_456.0, 5_000.0]);
        assert_eq!(f.scale, 1.0);
        // 1 mm at the corner survives (f32 of 4.1e6 has a spacing of 0.5 m).
        let (a, b) = (f.to_working([522_345.0, 4_133_456.0, 0.0]), f.to_working([522_345.001, 4_133_456.0, 0.0]));
        assert!(b[0] > a[0]);
        // delta = 2^(13-24)(1 + 2^-18): the radius 5000 lies in (2^12, 2^13].
        assert!(f.delta > 0.0 && f.delta < 2f32.powi(13 - 23));
        let back = f.to_file(a);
        assert!((back[0] - 522_345.0).abs() < 1e-3);
    }

    #[test]
    fn tiny_and_huge_meshes_are_scaled_by_powers_of_two() {
        let tiny = Frame::for_bounds([0.0; 3], [1e-9; 3]);
        assert!(tiny.scale > 1.0 && tiny.scale.log2().fract() == 0.0);
        let huge = Frame::for_bounds([0.0; 3], [1e15; 3]);
        assert!(huge.scale < 1.0 && huge.scale.log2().fract() == 0.0);
        assert!(huge.to_working([1e15; 3])[0] <= (1u64 << 40) as f32);
    }
}
