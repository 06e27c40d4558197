//! Locating an image grid's points by rasterizing the tets (the CPU's `resample`): each tet
//! visits the grid points of its box, row by row. Its barycentric map ([`TetMap`]: affine in
//! the point, so a multiply and an add a weight along a row) decides the points it holds
//! by a margin, those it misses by a margin, and leaves the rest (within its static error
//! bound of a face) to the exact point-in-tet test (`geom::test_point_with`, the locator's
//! own). A point a tet holds gets its values there and then, while the tet's vertex values
//! are at hand. No BVH, no face neighbours and no walk: a grid's points are all known in
//! advance, so the search runs from the tets to the points.
//!
//! The answers are the locator's. A point strictly inside one tet (no zero weight) and in no
//! other tet has one answer, which this finds. Every other point a tet claims (on a face, an
//! edge or a vertex, or claimed twice on a mesh whose tets overlap) is marked a tie and left
//! to the locator's search, which applies the tie rule (the lowest id among the tets that
//! hold the point: `geom::lowest_claim`). A point that no tet
//! claims is in no tet: each tet tests every grid point of its box that its map does not put
//! beyond a face on a row ([`TetMap::parts`]).
//!
//! The grid is done a slab of z planes at a time, so memory stays bounded for any grid.

use super::tet_map::{bounds_of, Side, TetMap};
use crate::buckets::Buckets;
use crate::geom::ImageGrid;
use crate::geom::{self, Bary, TetTest};
use crate::mesh::{Field, Mesh};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering::Relaxed};

/// No tet holds the point.
const EMPTY: u32 = u32::MAX;
/// More than one tet claims the point, or one claims it with a zero weight: the search decides.
const TIE: u32 = u32::MAX - 1;
/// Tets a rasterizing task visits.
const TETS_A_TASK: usize = 2048;
/// Meshes with more tets than this are not rasterized (ids meet the markers above).
pub(super) const MAX_TETS: usize = TIE as usize;
/// Grid points a slab holds at most (an id and each field's value: 4 bytes each), unless one
/// z plane is more.
pub(super) const SLAB_POINTS: usize = 1 << 22;

/// What one grid point of the current slab got.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Cell {
    Outside,
    /// Strictly inside this tet and no other (its values: [`GridRaster::copy_values`]).
    Inside(u32),
    /// The locator's search decides (the tie rule).
    Tie,
}

/// The grid, its tets ordered by their first z plane, and the slab of z planes rasterized last
/// with the values of its fields.
pub(super) struct GridRaster {
    grid: ImageGrid,
    /// The fields whose values the slab holds, by name.
    field_names: Vec<String>,
    axes: [Axis; 3],
    /// Tets ordered by their box's first z plane, then its first row, each with the plane
    /// after its box's last: consecutive tets write to nearby grid points (so the slab's
    /// lines stay in cache). `first_at[k·rows + j]` is the first with (plane, row) >= (k, j).
    by_plane: Vec<(u32, u32)>,
    first_at: Vec<u32>,
    /// Rows in the sort's key: the grid's, or 1 (planes only) for grids of very many rows.
    rows: usize,
    /// The most z planes a tet's box covers, minus one.
    max_extent: usize,
    slab_points: usize,
    planes: Range<usize>,
    ids: Vec<AtomicU32>,
    /// Each point's values (f32 bits), `field_names.len()` a point: set where `ids` is a tet.
    values: Vec<AtomicU32>,
    /// Whether the slab has a tie.
    tied: AtomicBool,
    /// The factor on every [`TetMap`]'s error bound: 1, but in the tests that show a tighter
    /// bound fails.
    bound_scale: f64,
}

impl GridRaster {
    /// `slab_points`: grid points rasterized at once (whole z planes, at least one);
    /// `field_names`: the fields whose values [`Self::copy_values`] gives.
    pub(super) fn new(mesh: &Mesh, grid: &ImageGrid, slab_points: usize, field_names: &[&str]) -> GridRaster {
        let axes: [Axis; 3] = std::array::from_fn(|k| Axis::new(grid, k));
        let nz = grid.dims[2];
        let ny = if grid.dims[1].saturating_mul(nz) <= 1 << 24 { grid.dims[1] } else { 1 };
        // Each tet's first and last z plane and first row (empty ranges: no grid point in
        // its box).
        let z_ranges: Vec<(u32, u32, u32)> = (0..mesh.n_tets())
            .into_par_iter()
            .map(|t| {
                let (lo, hi) = file_bounds(mesh, t);
                let (x, y) = (axes[0].span(lo[0], hi[0]), axes[1].span(lo[1], hi[1]));
                let r = axes[2].span(lo[2], hi[2]);
                if x.is_empty() || y.is_empty() {
                    return (0, 0, 0);
                }
                (r.start as u32, r.end as u32, y.start as u32)
            })
            .collect();
        // Grouped by (first plane, first row); tets with no grid point are left out.
        let key = |a: u32, y: u32| a as usize * ny + (y as usize).min(ny - 1);
        let max_extent = z_ranges.par_iter().map(|&(a, b, _)| if a < b { (b - a - 1) as usize } else { 0 }).max();
        let max_extent = max_extent.unwrap_or(0);
        // SAFETY: a tet's key is a function of `z_ranges`, which nothing changes meanwhile.
        let grouped = unsafe {
            Buckets::build(nz * ny, z_ranges.len(), |t| {
                let (a, b, y) = z_ranges[t];
                (a < b).then(|| (key(a, y), (t as u32, b)))
            })
        };
        let (first_at, by_plane) = (grouped.offsets, grouped.entries);
        GridRaster {
            grid: grid.clone(),
            field_names: field_names.iter().map(|f| f.to_string()).collect(),
            axes,
            by_plane,
            first_at,
            rows: ny,
            max_extent,
            slab_points,
            planes: 0..0,
            ids: Vec::new(),
            values: Vec::new(),
            tied: AtomicBool::new(false),
            bound_scale: 1.0,
        }
    }

    /// Whether this raster is of `grid` with the values of `fields`.
    pub(super) fn is_for(&self, grid: &ImageGrid, fields: &[&str]) -> bool {
        self.grid == *grid && self.field_names.iter().map(String::as_str).eq(fields.iter().copied())
    }

    /// Points of one z plane.
    fn plane_points(&self) -> usize {
        self.grid.dims[0] * self.grid.dims[1]
    }

    /// Makes the current slab hold grid point `i` (rasterizing the slab of planes that
    /// starts at its plane if it does not), and returns the grid points it holds. `fields`
    /// are the fields of [`Self::new`]'s names.
    pub(super) fn hold(&mut self, mesh: &Mesh, fields: &[&Field], i: usize) -> Range<usize> {
        debug_assert_eq!(fields.len(), self.field_names.len());
        let per_plane = self.plane_points();
        let k = i / per_plane;
        if !self.planes.contains(&k) {
            let n_planes = (self.slab_points / per_plane).max(1);
            self.rasterize(mesh, fields, k..(k + n_planes).min(self.grid.dims[2]));
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
            t => Cell::Inside(t),
        }
    }

    /// The values of grid point `i`, a [`Cell::Inside`] of the current slab.
    #[inline]
    pub(super) fn copy_values(&self, i: usize, out: &mut [f32]) {
        let nf = self.field_names.len();
        let j = (i - self.planes.start * self.plane_points()) * nf;
        for (o, v) in out.iter_mut().zip(&self.values[j..j + nf]) {
            *o = f32::from_bits(v.load(Relaxed));
        }
    }

    /// Claims every point of planes `planes` for the tets that hold it.
    fn rasterize(&mut self, mesh: &Mesh, fields: &[&Field], planes: Range<usize>) {
        let n = planes.len() * self.plane_points();
        if self.ids.len() < n {
            // (On every core: the first touch of each page is most of the cost.)
            self.ids = (0..n).into_par_iter().map(|_| AtomicU32::new(EMPTY)).collect();
            self.values = (0..n * fields.len()).into_par_iter().map(|_| AtomicU32::new(0)).collect();
        } else {
            self.ids[..n].par_iter().for_each(|a| a.store(EMPTY, Relaxed));
        }
        self.planes = planes.clone();
        self.tied.store(false, Relaxed);
        // The slab's tets in runs (each a rayon task; consecutive tets write nearby points),
        // each tet visited once a slab: a claim is a compare-and-swap, which only tets that
        // overlap contend for.
        let ny = self.rows;
        let from = self.first_at[planes.start.saturating_sub(self.max_extent) * ny] as usize;
        let to = self.first_at[planes.end * ny] as usize;
        self.by_plane[from..to].par_chunks(TETS_A_TASK).for_each(|run| {
            for &(t, end) in run {
                if end as usize > planes.start {
                    self.claim(mesh, fields, t, planes.clone());
                }
            }
        });
    }

    /// Tests the points of tet `t`'s box in planes `own` of the current slab and claims those
    /// it holds.
    fn claim(&self, mesh: &Mesh, fields: &[&Field], t: u32, own: Range<usize>) {
        let tet = mesh.tets[t as usize];
        let v = tet.map(|v| mesh.vertex64(v));
        let (lo, hi) = bounds_of(&v);
        let [ax, ay, az] = &self.axes;
        let (xs, ys) = (ax.span(lo[0], hi[0]), ay.span(lo[1], hi[1]));
        let box_zs = az.span(lo[2], hi[2]);
        let zs = box_zs.start.max(own.start)..box_zs.end.min(own.end);
        if xs.is_empty() || ys.is_empty() || zs.is_empty() {
            return;
        }
        let map = TetMap::over_box(v, (lo, hi), self.bound_scale);
        let corner = (ax.at[xs.start], ay.at[ys.start], az.at[box_zs.start]);
        let box_parts = map.as_ref().map(|m| m.parts(corner.0, corner.1, corner.2));
        for k in zs {
            let z = az.at[k];
            let parts = box_parts.map(|p| p.plane(z));
            for j in ys.clone() {
                let at = ((k - self.planes.start) * self.grid.dims[1] + j) * self.grid.dims[0];
                let (Some(map), Some(parts)) = (&map, &parts) else {
                    // A flat or ill-conditioned tet: the exact test at every point of its box.
                    for i in xs.clone() {
                        self.try_point(mesh, fields, t, tet, [i, j, k]);
                    }
                    continue;
                };
                // (Every row of the box: stopping at the first empty row after others would
                // rest on the rows' convexity, which rounding does not promise.)
                let Some((x0, x1)) = parts.row(ay.at[j]) else { continue };
                let part = ax.loose_span(x0, x1);
                let part = xs.start.max(part.start)..xs.end.min(part.end);
                if part.is_empty() {
                    continue;
                }
                let row = map.row(ax.at[xs.start], ay.at[j], z);
                for i in part {
                    match row.at(ax.at[i]) {
                        Side::Inside(w) => self.claim_point(mesh, fields, t, at + i, w.map(|x| x as f32)),
                        Side::Outside => {}
                        Side::Near => self.try_point(mesh, fields, t, tet, [i, j, k]),
                    }
                }
            }
        }
    }

    /// The exact test of grid point (i, j, k) in tet `t`, and its claim.
    #[inline]
    fn try_point(&self, mesh: &Mesh, fields: &[&Field], t: u32, tet: [u32; 4], [i, j, k]: [usize; 3]) {
        // The point as the grid gives it (`ImageGrid::point64`), taken to the working frame.
        let q = mesh.exact().query([self.axes[0].at[i], self.axes[1].at[j], self.axes[2].at[k]]);
        let TetTest::Inside(w) = geom::test_point_with(tet, &mesh.points, &mesh.exact(), &q) else { return };
        let at = ((k - self.planes.start) * self.grid.dims[1] + j) * self.grid.dims[0] + i;
        if w.contains(&0.0) {
            self.ids[at].store(TIE, Relaxed);
            self.tied.store(true, Relaxed);
        } else {
            self.claim_point(mesh, fields, t, at, w);
        }
    }

    /// Slab point `at` for tet `t`, strictly inside it at weights `w`: its values, or a tie
    /// if another tet holds it too (whichever claims it first: the point is a tie either
    /// way, and a tie's values are the search's).
    #[inline]
    fn claim_point(&self, mesh: &Mesh, fields: &[&Field], t: u32, at: usize, w: Bary) {
        if self.ids[at].compare_exchange(EMPTY, t, Relaxed, Relaxed).is_ok() {
            let nf = fields.len();
            for (slot, f) in self.values[at * nf..(at + 1) * nf].iter().zip(fields) {
                slot.store(mesh.value_at(f, Some((t as usize, w))).to_bits(), Relaxed);
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
    bounds_of(&mesh.tets[t].map(|i| mesh.vertex64(i)))
}

/// One axis of the grid: its points' coordinates as the samplers locate them
/// ([`ImageGrid::axis64`]: the f64 point, or its f32 rounding), increasing, and the index guess
/// that finds a coordinate's place in O(1).
struct Axis {
    at: Vec<f64>,
    origin: f64,
    /// 1 / spacing; 0 for an axis of one point.
    per_unit: f64,
    /// The most that a point's index computed from its coordinate is off (the f32 rounding
    /// of the coordinates and of the arithmetic), with a margin.
    slack: f64,
}

impl Axis {
    fn new(grid: &ImageGrid, k: usize) -> Axis {
        let at: Vec<f64> = (0..grid.dims[k]).map(|i| grid.axis64(k, i)).collect();
        let per_unit = if grid.spacing[k] > 0.0 { 1.0 / grid.spacing[k] } else { 0.0 };
        let origin = grid.origin[k];
        let off = at.iter().enumerate().map(|(i, &x)| ((x - origin) * per_unit - i as f64).abs()).fold(0.0, f64::max);
        Axis { slack: off + 1e-6 + 1e-9 * at.len() as f64, at, origin, per_unit }
    }

    /// A range of indices that holds every point within [lo, hi], and at most a point or so
    /// more at each end (more where the f32 coordinates are coarser than the spacing): no
    /// search, for the rows' parts.
    #[inline]
    fn loose_span(&self, lo: f64, hi: f64) -> Range<usize> {
        // Rounded up and down by truncating conversions (one instruction each, where `ceil`
        // and `floor` are calls on the baseline x86-64: this runs twice a row).
        let n = self.at.len();
        let a = (lo - self.origin) * self.per_unit - self.slack;
        let b = (hi - self.origin) * self.per_unit + self.slack;
        // (NaN: no bound at that end.)
        let start = if a > 0.0 {
            let up = a as usize;
            (up + usize::from((up as f64) < a)).min(n)
        } else {
            0
        };
        let end = if b < n as f64 { (b.max(-1.0) + 1.0) as usize } else { n };
        start..end
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

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::bvh::BuildPreset;
    use crate::locate::GridSampler;
    use crate::mesh::{FieldLocation, RawMesh};
    use crate::test_support::{self, KuhnGrid};
    use crate::CpuLocator;
    use std::sync::Arc;

    /// `raw` with three more vertex fields: the coordinates less the box's corner (so that
    /// they keep their digits in f32 far from the origin). Their values are the weights'
    /// witnesses: interpolated, they give the point back.
    fn with_coordinates(mut raw: RawMesh) -> RawMesh {
        let p64: Vec<[f64; 3]> = match &raw.points64 {
            Some(p) => p.clone(),
            None => raw.points.iter().map(|p| p.map(f64::from)).collect(),
        };
        for (k, name) in ["x", "y", "z"].into_iter().enumerate() {
            let lo = p64.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min);
            let values = p64.iter().map(|p| (p[k] - lo) as f32).collect();
            raw.fields.push(Field::new(name, FieldLocation::Vertex, values));
        }
        raw
    }

    /// Every grid point's answer against the search's at the point as the grid gives it
    /// ([`ImageGrid::point64`]: f64, or its f32 rounding), a slab of two planes at a time, the
    /// maps' bounds times `bound_scale`: a point inside gets the search's tet and, for every
    /// field, its value within 1e-5 of the field's range; a point outside is outside; ties
    /// are points on faces (or claimed twice). The number of ties, or the first disagreement.
    fn check_against_the_search(mesh: &Arc<Mesh>, grid: &ImageGrid, bound_scale: f64) -> Result<usize, String> {
        let loc = CpuLocator::new(mesh.clone());
        let names: Vec<&str> = mesh.fields.iter().map(|f| f.name.as_str()).collect();
        let fields: Vec<&Field> = mesh.fields.iter().collect();
        let range = |f: &Field| {
            let (lo, hi) = f.values.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
            hi - lo
        };
        let tolerance: Vec<f32> = fields.iter().map(|f| 1e-5 * range(f)).collect();
        let mut raster = GridRaster::new(mesh, grid, 2 * grid.dims[0] * grid.dims[1], &names);
        raster.bound_scale = bound_scale;
        let (mut ties, mut got, mut want) = (0, vec![0f32; fields.len()], vec![0f32; fields.len()]);
        for i in 0..grid.n_points() {
            let p = grid.point64(i);
            let found = loc.locate_point64(p);
            raster.hold(mesh, &fields, i);
            match raster.cell(i) {
                Cell::Outside if found.is_some() => return Err(format!("point {i} {p:?}: outside, not {found:?}")),
                Cell::Outside => {}
                Cell::Inside(t) => {
                    if found.map(|f| f.0) != Some(t) {
                        return Err(format!("point {i} {p:?}: in tet {t}, not {found:?}"));
                    }
                    raster.copy_values(i, &mut got);
                    mesh.values_at(&fields, found.map(|(t, b)| (t as usize, b)), &mut want);
                    for ((g, w), (tol, name)) in got.iter().zip(&want).zip(tolerance.iter().zip(&names)) {
                        if (g - w).abs() > *tol {
                            return Err(format!("point {i} {p:?}: {name} = {g}, not {w}"));
                        }
                    }
                }
                Cell::Tie if found.is_none() => return Err(format!("point {i} {p:?}: a tie outside")),
                Cell::Tie => ties += 1,
            }
        }
        Ok(ties)
    }

    fn agrees_with_the_search(raw: RawMesh, grid: &ImageGrid) -> usize {
        check_against_the_search(&Arc::new(Mesh::new(with_coordinates(raw), "test").unwrap()), grid, 1.0).unwrap()
    }

    #[test]
    fn jittered_meshes_need_no_search() {
        for seed in 0..4 {
            let grid = ImageGrid::spanning([-0.1, 0.03, 0.0], [1.1, 0.97, 1.0], [23, 17, 9]).unwrap();
            let ties = agrees_with_the_search(test_support::jittered_grid(6, 0.3, seed), &grid);
            // The grid's z = 0 and z = 1 planes lie on the mesh's boundary faces.
            assert!(ties <= 2 * 23 * 17, "seed {seed}: {ties} ties");
        }
    }

    /// A grid through a Kuhn grid's vertices, edges and faces: ties everywhere, each one
    /// the search's.
    #[test]
    fn points_on_faces_are_ties() {
        let grid = ImageGrid::spanning([0.0; 3], [1.0; 3], [9, 9, 9]).unwrap();
        let ties = agrees_with_the_search(KuhnGrid::new(4).raw(), &grid);
        assert!(ties > 9 * 9 * 9 / 2, "{ties} ties");
    }

    /// Far from the origin (the f64 file coordinates rounded to a working frame), with the
    /// grid's f64 points and with their f32 rounding (a quarter of the cells' size away), and
    /// on a mesh whose tets overlap (every tet twice: every point inside claimed twice).
    #[test]
    fn far_meshes_and_overlapping_tets() {
        let raw = test_support::mixed::moved(test_support::jittered_grid(5, 0.3, 7), [512345.0, 4123456.0, -2.5e6]);
        let grid =
            ImageGrid::spanning([512344.9, 4123456.1, -2.5e6], [512346.1, 4123456.9, -2.5e6 + 1.0], [19, 13, 11]);
        let grid = grid.unwrap();
        for wide in [true, false] {
            agrees_with_the_search(raw.clone(), &grid.clone().with_f64_points(wide));
        }
        let mut raw = test_support::jittered_grid(3, 0.2, 1);
        raw.fields.clear();
        raw.tets.extend(raw.tets.clone());
        let grid = ImageGrid::spanning([0.0; 3], [1.0; 3], [7, 8, 9]).unwrap();
        let ties = agrees_with_the_search(raw, &grid);
        assert!(ties >= 5 * 6 * 7, "{ties} ties");
    }

    /// A Kuhn grid of 4³ cubes of side 2 mapped by the integer matrix A = [[2, 1, 0], [0, 3,
    /// 1], [1, 0, 2]] (determinant 13), times `unit` (a power of two) from `corner` (all exact
    /// in f32, so the vertices are the file's), and the grid of spacing 1 unit over its box.
    /// A maps the unsheared grid's integer points (vertices, edge midpoints, face and cube
    /// centres: all on faces) onto grid points, so about 9³ grid points lie exactly on
    /// faces; the maps' gradients are thirteenths, so their weights of 0 come out a few
    /// ulps either side.
    pub(in crate::locate) fn kuhn_on_faces(unit: f64, corner: [f64; 3]) -> (Arc<Mesh>, ImageGrid) {
        let mut raw = KuhnGrid::new(4).raw();
        let a = |p: [f64; 3]| [2.0 * p[0] + p[1], 3.0 * p[1] + p[2], p[0] + 2.0 * p[2]];
        let p64: Vec<[f64; 3]> = raw
            .points
            .iter()
            .map(|p| {
                let q = a(p.map(|c| 8.0 * f64::from(c)));
                std::array::from_fn(|k| corner[k] + unit * q[k])
            })
            .collect();
        raw.points = p64.iter().map(|p| p.map(|c| c as f32)).collect();
        assert!(raw.points.iter().zip(&p64).all(|(a, b)| a.map(f64::from) == *b), "unit {unit}: not exact in f32");
        raw.points64 = Some(p64);
        let mesh = Arc::new(Mesh::new(with_coordinates(raw), "kuhn on faces").unwrap());
        let hi = a([8.0; 3]);
        let dims = hi.map(|h| h as usize + 1);
        let grid = ImageGrid::spanning(corner, std::array::from_fn(|k| corner[k] + unit * hi[k]), dims);
        (mesh, grid.unwrap())
    }

    /// The sheared Kuhn grids of [`kuhn_on_faces`] (unit, corner): scaled by ~1e-6 (2⁻²⁰)
    /// and ~1e6 (2¹⁸, 2¹⁶), and moved 1e7 away.
    pub(in crate::locate) const ON_FACES: [(f64, [f64; 3]); 6] = [
        (1.0, [0.0; 3]),
        (9.5367431640625e-7, [0.0; 3]),
        (262144.0, [0.0; 3]),
        (9.5367431640625e-7, [1.0, -2.0, 0.5]),
        (1.0, [1e7, -1e7, 1e7]),
        (65536.0, [1e7, 1e7, -1e7]),
    ];

    /// The bound is tested adversarially: grids whose points lie exactly on the faces of
    /// sheared Kuhn grids scaled by ~1e-6 and ~1e6 and moved 1e7 away agree with the search,
    /// and the same grids with the bound taken away (a zero factor) do not: some point on a
    /// face is then claimed by a tet the tie rule does not pick, or a point on the boundary
    /// is lost.
    #[test]
    fn the_error_bound_holds_on_faces_and_a_tighter_one_fails() {
        let cases = ON_FACES;
        let mut failures = Vec::new();
        for (unit, corner) in cases {
            let (mesh, grid) = kuhn_on_faces(unit, corner);
            let ties = check_against_the_search(&mesh, &grid, 1.0).unwrap_or_else(|e| panic!("unit {unit}: {e}"));
            assert!(ties > 9 * 9 * 9 / 2, "unit {unit}: {ties} ties");
            if let Err(e) = check_against_the_search(&mesh, &grid, 0.0) {
                failures.push(e);
            }
        }
        assert_eq!(failures.len(), cases.len(), "a zero bound failed only {failures:#?}");
    }

    /// An axis's loose span holds every point within [lo, hi], and at most 2·slack + 1 more at
    /// each end (where rounded f32 coordinates skip past the bounds), on axes near and far from
    /// the origin (1e7 away, with spacings down to where f32 coordinates repeat), for random
    /// bounds and bounds exactly on the points and an ulp either side; with no slack some
    /// point is left out.
    #[test]
    fn loose_spans_hold_every_point_in_their_bounds() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(6);
        let mut lost_without_slack = 0;
        for (origin, spacing, n) in
            [(0.0, 0.1, 50), (-3.7, 1e-3, 300), (1e7, 1.0, 40), (1e7, 0.3, 60), (-2.5e6, 0.01, 90)]
        {
            let grid = ImageGrid::spanning([origin; 3], [origin + spacing * (n - 1) as f64; 3], [n; 3]).unwrap();
            let mut axis = Axis::new(&grid, 0);
            let (first, last) = (axis.at[0], axis.at[n - 1]);
            let mut bounds: Vec<(f64, f64)> = (0..2000)
                .map(|_| {
                    let (a, b) = (rng.gen_range(first - spacing..=last + spacing), rng.gen_range(first..=last));
                    (a.min(b), a.max(b))
                })
                .collect();
            for i in 0..n {
                let x = axis.at[i];
                for (a, b) in [(x, x), (x.next_up(), x.next_up()), (x.next_down(), x), (x, x.next_up())] {
                    bounds.push((a, b));
                    bounds.push((a, last));
                }
            }
            for scale in [1.0, 0.0] {
                let slack = axis.slack;
                axis.slack = slack * scale;
                for &(lo, hi) in &bounds {
                    let span = axis.loose_span(lo, hi);
                    let exact = axis.span(lo, hi);
                    if scale == 1.0 {
                        assert!(
                            exact.is_empty() || (span.start <= exact.start && exact.end <= span.end),
                            "{lo} {hi}: {span:?} {exact:?}"
                        );
                        assert!(
                            span.len() <= exact.len() + 2 * (2 * slack.ceil() as usize + 1),
                            "{lo} {hi}: {span:?} {exact:?}"
                        );
                    } else if !exact.is_empty() && (span.start > exact.start || exact.end > span.end) {
                        lost_without_slack += 1;
                    }
                }
                axis.slack = slack;
            }
        }
        assert!(lost_without_slack > 0, "no point was lost without the slack");
    }

    /// A jittered grid of 10 m cells at UTM coordinates (f64 data): f32 rounds its
    /// coordinates to a quarter or half of a metre.
    fn far_mesh() -> Mesh {
        let mut raw = test_support::jittered_grid(6, 0.3, 2);
        raw.points.iter_mut().for_each(|p| *p = p.map(|c| 60.0 * c));
        Mesh::new(test_support::mixed::moved(raw, FAR), "far").unwrap()
    }

    const FAR: [f64; 3] = [512345.0, 4123456.0, 39.0];

    /// A grid over [`far_mesh`] and beyond it, its points in f64.
    fn far_grid() -> ImageGrid {
        let lo = [FAR[0] - 3.0, FAR[1] + 0.1, FAR[2] + 0.6];
        let hi = [FAR[0] + 63.0, FAR[1] + 59.9, FAR[2] + 59.4];
        ImageGrid::spanning(lo, hi, [31, 29, 27]).unwrap().with_f64_points(true)
    }

    /// Through the locator: `sample_grid` equals a query of the grid's points (ids bit for
    /// bit, values within rounding), in chunks that straddle slabs (a jittered grid whose jitter
    /// folds a few tets over their neighbours, a generated torus, and a mesh far from the
    /// origin whose grid asks for its f64 points, which its f32 points do not give); on the
    /// torus, whose tets do not overlap, it builds no BVH.
    #[test]
    fn sample_grid_is_a_query_of_its_points() {
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
            (false, far_mesh(), far_grid(), ["f", "cellval"]),
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
            let mut searched = CpuLocator::new(mesh.clone());
            crate::locate::query_grid_points(&mut searched, &grid, 0..n, &fields, &mut ids2, &mut values2).unwrap();
            assert_eq!(ids, ids2);
            if grid.f64_points {
                // The f32 rounding of the points is another grid: some of its points change cell.
                let rounded = grid.clone().with_f64_points(false);
                let (mut ids3, mut values3) = (vec![0; n], vec![0f32; 2 * n]);
                rasterized.sample_grid(&rounded, 0..n, &fields, &mut ids3, &mut values3).unwrap();
                assert!(ids3.iter().zip(&ids).any(|(a, b)| a != b), "the f32 points are in the same cells");
            }
            // Values: NaN at the same points, the cell field's bit for bit, the vertex field's
            // within 1e-5 of its range (the map's weights against the exact test's).
            let f = mesh.field("f").unwrap();
            let f_range = f.values.iter().fold(0f32, |a, &x| a.max(x.abs())) * 2.0;
            let (mut differ, mut worst) = (0, 0f32);
            for (k, (a, b)) in values.iter().zip(&values2).enumerate() {
                assert_eq!(a.is_nan(), b.is_nan(), "value {k}");
                if k % 2 == 1 || a.is_nan() {
                    assert!(a.to_bits() == b.to_bits() || a.is_nan(), "cellval {k}: {a} {b}");
                } else {
                    differ += usize::from(a != b);
                    worst = worst.max((a - b).abs());
                }
            }
            assert!(worst <= 1e-5 * f_range, "worst {worst} of {f_range}; {differ} differ");
            assert!(ids.iter().any(|&i| i < 0) && ids.iter().any(|&i| i >= 0));
        }
    }
}
