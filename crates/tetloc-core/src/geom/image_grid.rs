//! The regular grid of `resample`, as vtkResampleToImage lays it out: `dims` points per axis
//! spanning the bounds, with points on both ends of each axis, x fastest, then y, then z.

use crate::error::{Error, Result};
use crate::geom::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct ImageGrid {
    /// Points per axis (NX, NY, NZ), each at least 1.
    pub dims: [usize; 3],
    /// The first point: the bounds' low corner.
    pub origin: [f64; 3],
    /// The distance between neighbouring points per axis; 0 on an axis with one point.
    pub spacing: [f64; 3],
    /// Whether the samplers locate the points in f64, as the image's origin and spacing place
    /// them ([`Self::point64`]), or their f32 rounding ([`Self::point`]): set it for a mesh
    /// whose file coordinates are not its f32 copy (`Mesh::wants_f64_points`: f64 data, or
    /// far from the origin, where f32 moves a point by up to half a metre at UTM coordinates),
    /// as the f64 path of a query is taken there.
    pub f64_points: bool,
}

impl ImageGrid {
    /// `dims` points per axis from `lo` to `hi` (both included). An axis of one point sits
    /// at `lo` (spacing 0, as VTK). Errors on a zero dimension, on bounds that are not finite
    /// or not ordered, and on more points than this machine can count.
    pub fn spanning(lo: [f64; 3], hi: [f64; 3], dims: [usize; 3]) -> Result<ImageGrid> {
        if dims.contains(&0) {
            return Err(Error::Invalid(format!(
                "grid dimensions must be at least 1 on every axis, got {}x{}x{}",
                dims[0], dims[1], dims[2]
            )));
        }
        if dims.iter().try_fold(1usize, |n, &d| n.checked_mul(d)).is_none() {
            return Err(Error::Invalid(format!("a grid of {}x{}x{} points is too large", dims[0], dims[1], dims[2])));
        }
        if (0..3).any(|k| !(lo[k].is_finite() && hi[k].is_finite() && lo[k] <= hi[k])) {
            return Err(Error::Invalid(format!("grid bounds {lo:?} .. {hi:?} are not finite, ordered bounds")));
        }
        let spacing = std::array::from_fn(|k| if dims[k] > 1 { (hi[k] - lo[k]) / (dims[k] - 1) as f64 } else { 0.0 });
        Ok(ImageGrid { dims, origin: lo, spacing, f64_points: false })
    }

    /// The grid over a mesh's bounds as vtkResampleToImage makes it (`UseInputBounds`): the
    /// bounds scaled about their centre by 1 − 1e-6, so that rounding does not put the
    /// outermost points outside the mesh.
    pub fn over_bounds(lo: [f64; 3], hi: [f64; 3], dims: [usize; 3]) -> Result<ImageGrid> {
        const EPSILON: f64 = 1e-6;
        let half: [f64; 3] = std::array::from_fn(|k| 0.5 * (hi[k] - lo[k]) * (1.0 - EPSILON));
        let mid: [f64; 3] = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
        Self::spanning(std::array::from_fn(|k| mid[k] - half[k]), std::array::from_fn(|k| mid[k] + half[k]), dims)
    }

    /// This grid with its points located in f64 (`wide`) or as their f32 rounding.
    pub fn with_f64_points(self, wide: bool) -> ImageGrid {
        ImageGrid { f64_points: wide, ..self }
    }

    pub fn n_points(&self) -> usize {
        self.dims.iter().product()
    }

    /// The `i`-th point (x fastest), computed in f64 as VTK does and rounded to f32.
    #[inline]
    pub fn point(&self, i: usize) -> Vec3 {
        let idx = self.index(i);
        std::array::from_fn(|k| self.coordinate(k, idx[k]) as f32)
    }

    /// The `i`-th point as the samplers locate it, in f64: the image's own point where
    /// [`Self::f64_points`], else its f32 rounding ([`Self::point`]) widened.
    #[inline]
    pub fn point64(&self, i: usize) -> [f64; 3] {
        let idx = self.index(i);
        std::array::from_fn(|k| self.axis64(k, idx[k]))
    }

    /// Coordinate `i` of axis `k` as the samplers locate it ([`Self::point64`]'s).
    #[inline]
    pub fn axis64(&self, k: usize, i: usize) -> f64 {
        let x = self.coordinate(k, i);
        if self.f64_points {
            x
        } else {
            x as f32 as f64
        }
    }

    /// Coordinate `i` of axis `k` as the image's origin and spacing place it, in f64.
    #[inline]
    fn coordinate(&self, k: usize, i: usize) -> f64 {
        self.origin[k] + i as f64 * self.spacing[k]
    }

    /// The axis indices of point `i` (x fastest).
    #[inline]
    fn index(&self, i: usize) -> [usize; 3] {
        let [nx, ny, _] = self.dims;
        [i % nx, i / nx % ny, i / (nx * ny)]
    }

    /// The high corner.
    pub fn end(&self) -> [f64; 3] {
        std::array::from_fn(|k| self.coordinate(k, self.dims[k] - 1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_span_the_bounds_x_fastest() {
        let g = ImageGrid::spanning([0.0, -1.0, 2.0], [1.0, 1.0, 2.0], [3, 2, 1]).unwrap();
        assert_eq!(g.n_points(), 6);
        assert_eq!(g.spacing, [0.5, 2.0, 0.0]);
        let pts: Vec<Vec3> = (0..6).map(|i| g.point(i)).collect();
        assert_eq!(pts[0], [0.0, -1.0, 2.0]);
        assert_eq!(pts[2], [1.0, -1.0, 2.0]);
        assert_eq!(pts[3], [0.0, 1.0, 2.0]);
        assert_eq!(pts[5], [1.0, 1.0, 2.0]);
        assert_eq!(g.end(), [1.0, 1.0, 2.0]);
    }

    /// Far from the origin the f64 points are the image's own (origin + index × spacing), and
    /// without `f64_points` their f32 rounding (up to an eighth of a metre away at 4e6).
    #[test]
    fn f64_points_are_the_images_own() {
        let g = ImageGrid::spanning([512345.1, 4123456.3, 0.1], [512355.1, 4123466.3, 10.1], [11, 11, 11]).unwrap();
        let wide = g.clone().with_f64_points(true);
        let i = 5 + 11 * 7 + 121 * 3;
        let own: [f64; 3] = std::array::from_fn(|k| g.origin[k] + [5.0, 7.0, 3.0][k] * g.spacing[k]);
        assert_eq!(wide.point64(i), own);
        assert_eq!(g.point64(i), g.point(i).map(f64::from));
        assert!((g.point64(i)[1] - own[1]).abs() > 0.04, "{:?} against {own:?}", g.point64(i));
        assert_eq!((0..3).map(|k| wide.axis64(k, [5, 7, 3][k])).collect::<Vec<_>>(), wide.point64(i));
        assert_eq!((0..3).map(|k| g.axis64(k, [5, 7, 3][k])).collect::<Vec<_>>(), g.point64(i));
    }

    #[test]
    fn bad_grids_are_refused() {
        let e = ImageGrid::spanning([0.0; 3], [1.0; 3], [4, 0, 4]).unwrap_err().to_string();
        assert!(e.contains("at least 1") && e.contains("4x0x4"), "{e}");
        assert!(ImageGrid::spanning([0.0; 3], [1.0; 3], [usize::MAX, 2, 2]).is_err());
        assert!(ImageGrid::spanning([0.0, 2.0, 0.0], [1.0; 3], [2; 3]).is_err());
        assert!(ImageGrid::spanning([f64::NAN, 0.0, 0.0], [1.0; 3], [2; 3]).is_err());
    }
}
