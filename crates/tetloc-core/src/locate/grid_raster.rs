//! Locating an image grid's points by rasterizing the tets (the CPU's `resample`): each tet
//! visits the grid points of its box, row by row, and the exact point-in-tet test
//! (`geom::test_point_with`, the locator's own) decides each candidate. No BVH, no face
//! neighbours and no walk: a grid's points are all known in advance, so the search runs
//! from the tets to the points.
//!
//! The answers are the locator's. A point strictly inside one tet (no zero weight) and in no
//! other tet has one answer, which this finds. Every other point a tet claims (on a face, an
//! edge or a vertex, or claimed twice on a mesh whose tets overlap) is marked a tie and left
//! to the locator's search, whose traversal order is the tie rule. A point that no tet
//! claims is in no tet: each tet tests every grid point of its box that its faces' planes do
//! not exclude by a wide margin (below).
//!
//! The grid is done a slab of z planes at a time, so memory stays bounded for any grid.

use crate::geom::ImageGrid;
use crate::geom::{self, predicates::Query, Bary, TetTest};
use crate::mesh::Mesh;
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering::Relaxed};

/// No tet holds the point.
const EMPTY: u32 = u32::MAX;
/// More than one tet claims the point, or one claims it with a zero weight: the search decides.
const TIE: u32 = u32::MAX - 1;
/// Meshes with more tets than this are not rasterized (ids meet the markers above).
pub(super) const MAX_TETS: usize = TIE as usize;
/// Grid points a slab holds at most (ids and weights: 20 bytes each), unless one z plane is more.
pub(super) const SLAB_POINTS: usize = 1 << 22;

/// What one grid point of the current slab got.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Cell {
    Outside,
    /// Strictly inside this tet and no other, with these weights.
    Inside(u32, Bary),
    /// The locator's search decides (the tie rule).
    Tie,
}

/// The grid, its tets ordered by their first z plane, and the slab of z planes rasterized last.
pub(super) struct GridRaster {
    grid: ImageGrid,
    axes: [Axis; 3],
    /// Tets ordered by their box's first z plane, `first_at[k]` the first with plane >= k,
    /// each with the plane after its box's last.
    by_plane: Vec<(u32, u32)>,
    first_at: Vec<usize>,
    /// The most z planes a tet's box covers, minus one.
    max_extent: usize,
    slab_points: usize,
    planes: Range<usize>,
    ids: Vec<AtomicU32>,
    weights: Vec<[AtomicU32; 4]>,
    /// Whether the slab has a tie.
    tied: AtomicBool,
}

impl GridRaster {
    /// `slab_points`: grid points rasterized at once (whole z planes, at least one).
    pub(super) fn new(mesh: &Mesh, grid: &ImageGrid, slab_points: usize) -> GridRaster {
        let axes: [Axis; 3] = std::array::from_fn(|k| Axis::new(grid, k));
        let nz = grid.dims[2];
        // Each tet's first and last z plane (empty ranges: no plane in its box).
        let z_ranges: Vec<(u32, u32)> = (0..mesh.n_tets())
            .into_par_iter()
            .map(|t| {
                let (lo, hi) = file_bounds(mesh, t);
                let r = axes[2].span(lo[2], hi[2]);
                (r.start as u32, r.end as u32)
            })
            .collect();
        // A counting sort by first plane; tets with no plane are left out.
        let mut first_at = vec![0usize; nz + 1];
        let mut max_extent = 0;
        for &(a, b) in &z_ranges {
            if a < b {
                first_at[a as usize + 1] += 1;
                max_extent = max_extent.max((b - a - 1) as usize);
            }
        }
        for k in 0..nz {
            first_at[k + 1] += first_at[k];
        }
        let mut next = first_at.clone();
        let mut by_plane = vec![(0, 0); first_at[nz]];
        for (t, &(a, b)) in z_ranges.iter().enumerate() {
            if a < b {
                by_plane[next[a as usize]] = (t as u32, b);
                next[a as usize] += 1;
            }
        }
        GridRaster {
            grid: grid.clone(),
            axes,
            by_plane,
            first_at,
            max_extent,
            slab_points,
            planes: 0..0,
            ids: Vec::new(),
            weights: Vec::new(),
            tied: AtomicBool::new(false),
        }
    }

    pub(super) fn grid(&self) -> &ImageGrid {
        &self.grid
    }

    /// Points of one z plane.
    fn plane_points(&self) -> usize {
        self.grid.dims[0] * self.grid.dims[1]
    }

    /// Makes the current slab hold grid point `i` (rasterizing the slab of planes that
    /// starts at its plane if it does not), and returns the grid points it holds.
    pub(super) fn hold(&mut self, mesh: &Mesh, i: usize) -> Range<usize> {
        let per_plane = self.plane_points();
        let k = i / per_plane;
        if !self.planes.contains(&k) {
            let n_planes = (self.slab_points / per_plane).max(1);
            self.rasterize(mesh, k..(k + n_planes).min(self.grid.dims[2]));
        }
        self.planes.start * per_plane..self.planes.end * per_plane
    }

    /// Whether some point of the current slab is a tie.
    pub(super) fn tied(&self) -> bool {
        self.tied.load(Relaxed)
    }

    /// Grid point `i`'s answer; the current slab must hold it ([`Self::hold`]).
    #[inline]
    pub(super) fn cell(&self, i: usize) -> Cell {
        let j = i - self.planes.start * self.plane_points();
        match self.ids[j].load(Relaxed) {
            EMPTY => Cell::Outside,
            TIE => Cell::Tie,
            t => Cell::Inside(t, self.weights[j].each_ref().map(|w| f32::from_bits(w.load(Relaxed)))),
        }
    }

    /// Claims every point of planes `planes` for the tets that hold it.
    fn rasterize(&mut self, mesh: &Mesh, planes: Range<usize>) {
        let n = planes.len() * self.plane_points();
        if self.ids.len() < n {
            self.ids = (0..n).map(|_| AtomicU32::new(EMPTY)).collect();
            self.weights = (0..n).map(|_| Default::default()).collect();
        } else {
            self.ids[..n].par_iter().for_each(|a| a.store(EMPTY, Relaxed));
        }
        self.planes = planes.clone();
        self.tied.store(false, Relaxed);
        let from = self.first_at[planes.start.saturating_sub(self.max_extent)];
        let to = self.first_at[planes.end];
        let first = planes.start as u32;
        self.by_plane[from..to].par_iter().with_min_len(256).for_each(|&(t, end)| {
            if end > first {
                self.claim(mesh, t)
            }
        });
    }

    /// Tests the points of tet `t`'s box in the current slab and claims those it holds.
    fn claim(&self, mesh: &Mesh, t: u32) {
        let (lo, hi) = file_bounds(mesh, t as usize);
        let [ax, ay, az] = &self.axes;
        let (xs, ys) = (ax.span(lo[0], hi[0]), ay.span(lo[1], hi[1]));
        let zs = az.span(lo[2], hi[2]);
        let zs = zs.start.max(self.planes.start)..zs.end.min(self.planes.end);
        if xs.is_empty() || ys.is_empty() || zs.is_empty() {
            return;
        }
        let tet = mesh.tets[t as usize];
        let v = tet.map(|v| mesh.vertex64(v));
        let rows = RowClip::new(v, lo, hi, self.grid.spacing[0]);
        for k in zs {
            let z = az.at[k];
            for j in ys.clone() {
                // (Every row of the box: stopping at the first empty row after others would
                // rest on the rows' convexity, which rounding does not promise.)
                let Some((x0, x1)) = rows.x_range(ay.at[j], z) else { continue };
                for i in xs.start.max(ax.at_or_above(x0))..xs.end.min(ax.above(x1)) {
                    self.try_point(mesh, t, tet, [i, j, k]);
                }
            }
        }
    }

    /// The exact test of grid point (i, j, k) in tet `t`, and its claim.
    #[inline]
    fn try_point(&self, mesh: &Mesh, t: u32, tet: [u32; 4], [i, j, k]: [usize; 3]) {
        let file = [self.axes[0].at[i], self.axes[1].at[j], self.axes[2].at[k]];
        let p = file.map(|c| c as f32);
        let q = Query { local: mesh.info.frame.to_working_f32(p), file };
        let TetTest::Inside(w) = geom::test_point_with(tet, &mesh.points, &mesh.exact(), &q) else { return };
        let at = ((k - self.planes.start) * self.grid.dims[1] + j) * self.grid.dims[0] + i;
        if w.contains(&0.0) {
            self.ids[at].store(TIE, Relaxed);
            self.tied.store(true, Relaxed);
        } else if self.ids[at].compare_exchange(EMPTY, t, Relaxed, Relaxed).is_ok() {
            for (slot, x) in self.weights[at].iter().zip(w) {
                slot.store(x.to_bits(), Relaxed);
            }
        } else {
            // A second tet holds the point: overlapping tets, the search decides.
            self.ids[at].store(TIE, Relaxed);
            self.tied.store(true, Relaxed);
        }
    }
}

/// Tet `t`'s box in the file's coordinates.
fn file_bounds(mesh: &Mesh, t: usize) -> ([f64; 3], [f64; 3]) {
    let v = mesh.tets[t].map(|i| mesh.vertex64(i));
    let lo = std::array::from_fn(|k| v.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min));
    let hi = std::array::from_fn(|k| v.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max));
    (lo, hi)
}

/// One axis of the grid: its points' coordinates as the locator gets them (the f32 point,
/// in f64), increasing, and the index guess that finds a coordinate's place in O(1).
struct Axis {
    at: Vec<f64>,
    origin: f64,
    /// 1 / spacing; 0 for an axis of one point.
    per_unit: f64,
}

impl Axis {
    fn new(grid: &ImageGrid, k: usize) -> Axis {
        let at = (0..grid.dims[k]).map(|i| (grid.origin[k] + i as f64 * grid.spacing[k]) as f32 as f64).collect();
        let per_unit = if grid.spacing[k] > 0.0 { 1.0 / grid.spacing[k] } else { 0.0 };
        Axis { at, origin: grid.origin[k], per_unit }
    }

    /// The indices of the points within [lo, hi].
    fn span(&self, lo: f64, hi: f64) -> Range<usize> {
        self.at_or_above(lo)..self.above(hi)
    }

    /// The first index whose point is >= x.
    #[inline]
    fn at_or_above(&self, x: f64) -> usize {
        self.first(|a| a >= x, x)
    }

    /// The first index whose point is > x.
    #[inline]
    fn above(&self, x: f64) -> usize {
        self.first(|a| a > x, x)
    }

    /// The first index whose point passes `past` (false, then true along the axis), from a
    /// guess that rounding leaves a step or two off.
    #[inline]
    fn first(&self, past: impl Fn(f64) -> bool, x: f64) -> usize {
        let n = self.at.len();
        // Truncated (the loops below finish the rounding); NaN and negatives become 0.
        let mut i = (((x - self.origin) * self.per_unit) as usize).min(n);
        while i > 0 && past(self.at[i - 1]) {
            i -= 1;
        }
        while i < n && !past(self.at[i]) {
            i += 1;
        }
        i
    }
}

/// A tet's faces as planes, to narrow each grid row to the part that can be inside: a filter
/// only (the exact test decides every point it lets through), so it errs wide. A face bounds
/// the row only when its plane is well defined (its corner's sine above 1e-3) and crosses the
/// row at an angle (the normal's x above 1e-3 of its length). Then f64 rounding tilts the
/// plane by at most ~1e3 ε and moves the row's bound by ~1e3 × that over the tet's size, plus
/// ~1e3 ε of the distance from the origin: about 1e-9 of both. The bound is widened by 1e-8
/// of both and a hundredth of the grid's spacing.
struct RowClip {
    /// For the faces that bound rows (at most four): the inward normal n over n.x, and
    /// n·a over n.x, and whether n.x > 0 (the face bounds the row from below).
    planes: [([f64; 3], f64, bool); 4],
    n: usize,
    margin: f64,
}

impl RowClip {
    fn new(v: [[f64; 3]; 4], lo: [f64; 3], hi: [f64; 3], spacing_x: f64) -> RowClip {
        let sub = |a: [f64; 3], b: [f64; 3]| -> [f64; 3] { std::array::from_fn(|k| a[k] - b[k]) };
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
        };
        let size = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        let far = (0..3).map(|k| lo[k].abs().max(hi[k].abs())).fold(0.0, f64::max);
        let mut clip =
            RowClip { planes: [([0.0; 3], 0.0, false); 4], n: 0, margin: 0.01 * spacing_x + 1e-8 * (size + far) };
        for f in [[1, 2, 3, 0], [0, 3, 2, 1], [0, 1, 3, 2], [0, 2, 1, 3]] {
            let (a, b, c, d) = (v[f[0]], v[f[1]], v[f[2]], v[f[3]]);
            let (e1, e2) = (sub(b, a), sub(c, a));
            let mut n = cross(e1, e2);
            let nn = dot(n, n);
            // A sliver face, or a flat tet: no bound from this face.
            if nn.is_nan()
                || nn <= 1e-6 * dot(e1, e1) * dot(e2, e2)
                || dot(sub(d, a), n).abs() < 1e-9 * nn.sqrt() * size
            {
                continue;
            }
            if dot(sub(d, a), n) < 0.0 {
                n = n.map(|x| -x);
            }
            // Nearly parallel to the rows: no bound.
            if n[0].abs() < 1e-3 * nn.sqrt() {
                continue;
            }
            clip.planes[clip.n] = (n.map(|c| c / n[0]), dot(n, a) / n[0], n[0] > 0.0);
            clip.n += 1;
        }
        clip
    }

    /// The x range of the row at (y, z) that the bounding faces leave, widened; `None` if empty.
    fn x_range(&self, y: f64, z: f64) -> Option<(f64, f64)> {
        let (mut x0, mut x1) = (f64::NEG_INFINITY, f64::INFINITY);
        for &(n, d, below) in &self.planes[..self.n] {
            // n·(x, y, z) >= d, divided by n.x
            let x = d - n[1] * y - n[2] * z;
            if below {
                x0 = x0.max(x);
            } else {
                x1 = x1.min(x);
            }
        }
        let (x0, x1) = (x0 - self.margin, x1 + self.margin);
        (x0 <= x1).then_some((x0, x1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::BuildPreset;
    use crate::locate::GridSampler;
    use crate::test_support::{self, KuhnGrid};
    use crate::{BatchLocator, CpuLocator};
    use std::sync::Arc;

    /// Every grid point's answer against the search's, a slab of two planes at a time: a
    /// point inside gets the search's tet and weights, a point outside is outside, and ties
    /// are points on faces (or claimed twice). Returns the number of ties.
    fn agrees_with_the_search(mesh: Mesh, grid: &ImageGrid) -> usize {
        let mesh = Arc::new(mesh);
        let loc = CpuLocator::new(mesh.clone());
        let mut raster = GridRaster::new(&mesh, grid, 2 * grid.dims[0] * grid.dims[1]);
        let mut ties = 0;
        for i in 0..grid.n_points() {
            let found = loc.locate_point(grid.point(i));
            raster.hold(&mesh, i);
            match raster.cell(i) {
                Cell::Outside => assert_eq!(found, None, "point {i} {:?}", grid.point(i)),
                Cell::Inside(t, b) => assert_eq!(found, Some((t, b)), "point {i} {:?}", grid.point(i)),
                Cell::Tie => {
                    assert!(found.is_some(), "point {i}: a tie outside");
                    ties += 1;
                }
            }
        }
        ties
    }

    #[test]
    fn jittered_meshes_need_no_search() {
        for seed in 0..4 {
            let grid = ImageGrid::spanning([-0.1, 0.03, 0.0], [1.1, 0.97, 1.0], [23, 17, 9]).unwrap();
            let ties = agrees_with_the_search(test_support::grid_mesh(6, 0.3, seed), &grid);
            // The grid's z = 0 and z = 1 planes lie on the mesh's boundary faces.
            assert!(ties <= 2 * 23 * 17, "seed {seed}: {ties} ties");
        }
    }

    /// A grid through a Kuhn grid's vertices, edges and faces: ties everywhere, each one
    /// the search's.
    #[test]
    fn points_on_faces_are_ties() {
        let grid = ImageGrid::spanning([0.0; 3], [1.0; 3], [9, 9, 9]).unwrap();
        let ties = agrees_with_the_search(KuhnGrid::new(4).mesh("kuhn"), &grid);
        assert!(ties > 9 * 9 * 9 / 2, "{ties} ties");
    }

    /// Far from the origin (the f64 file coordinates rounded to a working frame) and on a
    /// mesh whose tets overlap (every tet twice: every point inside claimed twice).
    #[test]
    fn far_meshes_and_overlapping_tets() {
        let raw = test_support::mixed::moved(test_support::jittered_grid(5, 0.3, 7), [512345.0, 4123456.0, -2.5e6]);
        let grid =
            ImageGrid::spanning([512344.9, 4123456.1, -2.5e6], [512346.1, 4123456.9, -2.5e6 + 1.0], [19, 13, 11]);
        agrees_with_the_search(Mesh::new(raw, "far").unwrap(), &grid.unwrap());
        let mut raw = test_support::jittered_grid(3, 0.2, 1);
        raw.fields.clear();
        raw.tets.extend(raw.tets.clone());
        let twice = Mesh::new(raw, "twice").unwrap();
        let grid = ImageGrid::spanning([0.0; 3], [1.0; 3], [7, 8, 9]).unwrap();
        let ties = agrees_with_the_search(twice, &grid);
        assert!(ties >= 5 * 6 * 7, "{ties} ties");
    }

    /// Through the locator: `sample_grid` equals `sample_many` at the grid's points bit for
    /// bit, in chunks that straddle slabs (a jittered grid whose jitter folds a few tets over
    /// their neighbours, and a generated torus); on the torus, whose tets do not overlap, it
    /// builds no BVH.
    #[test]
    fn sample_grid_is_sample_many() {
        let torus = Mesh::new(crate::gen::generate(crate::gen::Shape::Fusion, 20_000, 3), "fusion").unwrap();
        let grid = ImageGrid::over_bounds(
            torus.info.bounds_min.map(f64::from),
            torus.info.bounds_max.map(f64::from),
            [41, 37, 23],
        );
        for (torus_mesh, mesh, grid, fields) in [
            (
                false,
                test_support::grid_mesh(6, 0.3, 2),
                ImageGrid::spanning([-0.05, 0.0, 0.01], [1.05, 1.0, 0.99], [31, 29, 27]).unwrap(),
                ["f", "cellval"],
            ),
            (true, torus, grid.unwrap(), ["f", "cellval"]),
        ] {
            let mesh = Arc::new(mesh);
            let n = grid.n_points();
            let mut rasterized = CpuLocator::deferred(mesh.clone(), BuildPreset::Fast);
            let (mut ids, mut values) = (vec![0; n], vec![0f32; 2 * n]);
            let slab = 2 * grid.dims[0] * grid.dims[1] + 5;
            for start in (0..n).step_by(slab) {
                let end = (start + slab).min(n);
                rasterized
                    .sample_grid(&grid, start..end, &fields, &mut ids[start..end], &mut values[2 * start..2 * end])
                    .unwrap();
            }
            if torus_mesh {
                assert!(!rasterized.index_built(), "a BVH was built");
            }
            let (mut ids2, mut values2) = (vec![0; n], vec![0f32; 2 * n]);
            let points = crate::locate::grid_points(&grid, 0..n);
            CpuLocator::new(mesh).sample_many(&points, &fields, &mut ids2, &mut values2).unwrap();
            assert_eq!(ids, ids2);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&values), bits(&values2));
            assert!(ids.iter().any(|&i| i < 0) && ids.iter().any(|&i| i >= 0));
        }
    }
}
