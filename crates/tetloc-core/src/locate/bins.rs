//! Uniform bins over the tets' boxes: the CPU batches' cheap index (one pass to count, one
//! to fill), in place of a BVH. A query starts its walk from its bin's start tet (the tet
//! whose centroid is nearest the bin's centre: a step or two away), and where the walk cannot finish (it leaves the mesh, runs long, or ends on a
//! face) it tests every tet of its bin: the bin lists every tet whose box meets it, so one
//! tet holding the point strictly is the answer, none means outside, and anything else (a
//! weight of zero, two tets) is a tie that the BVH's search decides by the tie rule.
//!
//! Bin indices are monotone in the coordinate (a subtraction, a product and a floor, each
//! rounding monotonically, as in the occupancy grid), so a point inside a tet's box (working
//! coordinates) has its bin within the box's bins on each axis. The same holds at eighths of
//! a bin ("parts"): each tet's box is kept as its first and last part on each axis, so that a
//! scan of a bin culls its tets by one small load each, and computes the box of the few left.

use crate::buckets::Buckets;
use crate::geom::{self, Vec3};
use crate::mesh::Mesh;
use rayon::prelude::*;

/// Bins at most (4 bytes each for the offsets).
const MAX_BINS: usize = 1 << 24;
/// Bins a side at most: with [`SUB`] parts each, a box's parts fit a u16.
const MAX_SIDE: usize = 1 << 12;
/// Parts of a bin on each axis in the tets' kept boxes.
const SUB: usize = 8;

pub(super) struct Bins {
    lo: Vec3,
    scale: Vec3,
    n: [usize; 3],
    /// The last part ([`SUB`] a bin) on each axis, as a float (`SUB n - 1`, exact: below 2^15).
    last: Vec3,
    /// Each tet's box in parts: the first part on each axis, then the last.
    spans: Vec<[u16; 6]>,
    /// The tets of bin `b` are `tets[offsets[b]..offsets[b + 1]]`, ascending.
    offsets: Vec<u32>,
    tets: Vec<u32>,
    /// Each bin's walks start here: the tet whose centroid is nearest the bin's centre among
    /// those whose centroid is in the bin (else the bin's first tet; [`NONE`] for an empty bin).
    start: Vec<u32>,
}

/// The bins of a box of bins (first and last on each axis), x fastest, each with a tet.
struct BoxBins {
    span: [u16; 6],
    n: [usize; 3],
    at: [u16; 3],
    tet: u32,
}

impl BoxBins {
    /// The bins of a box given in parts.
    fn new(parts: [u16; 6], n: [usize; 3], tet: u32) -> BoxBins {
        let span = parts.map(|p| p / SUB as u16);
        BoxBins { span, n, at: [span[0], span[1], span[2]], tet }
    }
}

impl Iterator for BoxBins {
    type Item = (usize, u32);

    #[inline]
    fn next(&mut self) -> Option<(usize, u32)> {
        let [x, y, z] = self.at;
        if z > self.span[5] {
            return None;
        }
        if x < self.span[3] {
            self.at[0] += 1;
        } else if y < self.span[4] {
            self.at = [self.span[0], y + 1, z];
        } else {
            self.at = [self.span[0], self.span[1], z + 1];
        }
        Some(((z as usize * self.n[1] + y as usize) * self.n[0] + x as usize, self.tet))
    }
}

/// No tet.
const NONE: u32 = u32::MAX;

impl Bins {
    /// Bins of about `edges` mean edge lengths a side.
    pub(super) fn build(mesh: &Mesh, edges: f64) -> Bins {
        let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
        let ext: [f64; 3] = std::array::from_fn(|k| (hi[k] - lo[k]) as f64);
        let mut cell = (edges * mesh.info.mean_edge_length as f64).max(1e-30);
        let count = |cell: f64| -> [usize; 3] { ext.map(|e| ((e / cell).ceil() as usize).clamp(1, MAX_SIDE)) };
        while count(cell).iter().product::<usize>() > MAX_BINS {
            cell *= 1.25;
        }
        let n = count(cell);
        let scale = std::array::from_fn(|k| if ext[k] > 0.0 { (n[k] as f64 / ext[k]) as f32 } else { 0.0 });
        let last = n.map(|c| (c * SUB - 1) as f32);
        let mut bins =
            Bins { lo, scale, n, last, spans: Vec::new(), offsets: Vec::new(), tets: Vec::new(), start: Vec::new() };
        // In one pass over the tets: each one's first and last part on each axis (below
        // 2^15), kept, its centroid's bin and the centroid's squared distance to that bin's
        // centre (for the start tets). Then the tets grouped by the bins their boxes meet.
        let n_bins = n[0] * n[1] * n[2];
        // Each axis' bin centres, computed once (not a division per tet).
        let centres: [Vec<f32>; 3] = std::array::from_fn(|k| {
            (0..n[k]).map(|i| if scale[k] > 0.0 { lo[k] + (i as f32 + 0.5) / scale[k] } else { lo[k] }).collect()
        });
        let (spans, centroids): (Vec<[u16; 6]>, Vec<(u32, f32)>) = (0..mesh.tets.len())
            .into_par_iter()
            .map(|t| {
                let (a, b) = geom::tet_bounds(mesh.tets[t], &mesh.points);
                let (a, b) = (bins.parts(a), bins.parts(b));
                let c = mesh.tet_center(t);
                let (bin, at) = bins.bin_of(c);
                let d2 = (0..3).map(|k| (c[k] - centres[k][at[k]]) * (c[k] - centres[k][at[k]])).sum::<f32>();
                ([a[0], a[1], a[2], b[0], b[1], b[2]].map(|c| c as u16), (bin as u32, d2))
            })
            .unzip();
        let mut start = vec![NONE; n_bins];
        let mut nearest = vec![f32::INFINITY; n_bins];
        for (t, &(b, d2)) in centroids.iter().enumerate() {
            // Strictly nearer: among equals the lowest id, so the choice is deterministic.
            if d2 < nearest[b as usize] {
                (nearest[b as usize], start[b as usize]) = (d2, t as u32);
            }
        }
        drop((nearest, centroids));
        // SAFETY: a tet's bins are a function of `spans`, which nothing changes meanwhile.
        let grouped = unsafe { Buckets::build(n_bins, mesh.tets.len(), |t| BoxBins::new(spans[t], n, t as u32)) };
        let (offsets, tets) = (grouped.offsets, grouped.entries);
        for (b, s) in start.iter_mut().enumerate() {
            if *s == NONE && offsets[b] < offsets[b + 1] {
                *s = tets[offsets[b] as usize];
            }
        }
        bins.spans = spans;
        bins.offsets = offsets;
        bins.tets = tets;
        bins.start = start;
        bins
    }

    /// The part coordinates of a point ([`SUB`] parts a bin), clamped to the grid on each
    /// axis (monotone; on values clamped at 0 the truncation is the floor). Clamped as floats
    /// (NaN to 0), so the conversion needs no range checks: this runs for every tet's box and
    /// every query. A part's bin is the part over [`SUB`]: the product times SUB is exact, so
    /// that is the floor of the bin coordinate.
    #[inline]
    fn parts(&self, p: Vec3) -> [usize; 3] {
        std::array::from_fn(|k| {
            let x = ((p[k] - self.lo[k]) * self.scale[k] * SUB as f32).max(0.0).min(self.last[k]);
            // SAFETY: `x` is finite and within 0..=last (a NaN becomes 0 at `max`), and
            // `last` is below 2^15: the value truncated fits a u32.
            unsafe { x.to_int_unchecked::<u32>() as usize }
        })
    }

    /// The bin coordinates of a point, clamped to the grid on each axis (monotone).
    #[inline]
    fn coords(&self, p: Vec3) -> [usize; 3] {
        self.parts(p).map(|c| c / SUB)
    }

    /// The bin of a point (working coordinates) of the mesh's box, and its coordinates.
    #[inline]
    pub(super) fn bin_of(&self, p: Vec3) -> (usize, [usize; 3]) {
        let c @ [x, y, z] = self.coords(p);
        ((z * self.n[1] + y) * self.n[0] + x, c)
    }

    /// Where bin `b`'s walks start; `None` when no tet's box meets the bin.
    #[inline]
    pub(super) fn start(&self, b: usize) -> Option<u32> {
        let s = self.start[b];
        (s != NONE).then_some(s)
    }

    /// The tets whose boxes meet bin `b`, ascending.
    #[inline]
    pub(super) fn tets(&self, b: usize) -> &[u32] {
        &self.tets[self.offsets[b] as usize..self.offsets[b + 1] as usize]
    }

    /// The tets of bin `b` (`p`'s) whose boxes hold `p`, ascending: most of a bin's tets are
    /// culled by their kept boxes in parts, the rest by their boxes, before any test. Every
    /// tet that holds `p` is among them (working coordinates: a box of rounded vertices holds
    /// the rounded point whenever the file's box holds the file's point, as in the BVH; and a
    /// point in the box is in the box's parts, the parts being monotone).
    #[inline]
    pub(super) fn boxes_holding<'a>(&'a self, mesh: &'a Mesh, b: usize, p: Vec3) -> impl Iterator<Item = u32> + 'a {
        let at = self.parts(p).map(|c| c as u16);
        let in_parts = move |s: &[u16; 6]| (0..3).all(|k| s[k] <= at[k] && at[k] <= s[3 + k]);
        self.tets(b).iter().copied().filter(move |&t| in_parts(&self.spans[t as usize])).filter(move |&t| {
            let (lo, hi) = geom::tet_bounds(mesh.tets[t as usize], &mesh.points);
            (0..3).all(|k| lo[k] <= p[k] && p[k] <= hi[k])
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::KuhnGrid;
    use proptest::prelude::*;

    proptest! {
        /// Bin coordinates are monotone on each axis and within the grid, whatever the value
        /// (below or above the box, infinite, NaN): a point in a tet's box has its bin within
        /// the bins of the box's corners.
        #[test]
        fn coords_are_monotone_and_clamped(p in prop::array::uniform3(-2f32..3.0), d in 0f32..2.0, axis in 0usize..3) {
            let bins = Bins::build(&KuhnGrid::new(3).mesh("cube"), 0.7);
            let mut q = p;
            q[axis] += d;
            let (a, b) = (bins.coords(p), bins.coords(q));
            prop_assert!(a[axis] <= b[axis]);
            prop_assert!((0..3).all(|k| a[k] < bins.n[k] && b[k] < bins.n[k]));
            for x in [f32::NAN, f32::NEG_INFINITY, -1e30] {
                prop_assert_eq!(bins.coords([x; 3]), [0; 3]);
            }
            for x in [f32::INFINITY, 1e30] {
                prop_assert_eq!(bins.coords([x; 3]), bins.n.map(|n| n - 1));
            }
        }

        /// The parts' cull keeps every tet whose box holds the point: a scan of the point's
        /// bin gives exactly the tets of the bin whose boxes hold it, for points on the boxes'
        /// faces (the mesh's vertices and the midpoints of its edges, on jittered and
        /// Kuhn-aligned meshes, in bins of several sizes) and between them.
        #[test]
        fn parts_keep_every_box_holding_the_point(jitter in prop_oneof![Just(0f32), 0f32..0.3], seed in any::<u64>(),
                                                   edges in prop_oneof![Just(0.7), Just(1.5), 0.2f64..4.0],
                                                   extra in prop::collection::vec(prop::array::uniform3(-0.1f32..1.1), 50)) {
            let mesh = KuhnGrid::new(4).jitter(jitter, seed).mesh("cube");
            let bins = Bins::build(&mesh, edges);
            let mut points = mesh.points.to_vec();
            points.extend(mesh.tets.iter().map(|t| {
                let (a, b) = (mesh.points[t[0] as usize], mesh.points[t[3] as usize]);
                std::array::from_fn(|k| 0.5 * (a[k] + b[k]))
            }));
            points.extend(extra);
            let mut culled = 0;
            for p in points {
                let b = bins.bin_of(p).0;
                let want: Vec<u32> = bins
                    .tets(b)
                    .iter()
                    .copied()
                    .filter(|&t| {
                        let (lo, hi) = geom::tet_bounds(mesh.tets[t as usize], &mesh.points);
                        (0..3).all(|k| lo[k] <= p[k] && p[k] <= hi[k])
                    })
                    .collect();
                let got: Vec<u32> = bins.boxes_holding(&mesh, b, p).collect();
                prop_assert_eq!(&got, &want, "at {:?}", p);
                let at = bins.parts(p);
                let outside_parts = |s: [u16; 6]| (0..3).any(|k| at[k] < s[k] as usize || (s[3 + k] as usize) < at[k]);
                culled += bins.tets(b).iter().filter(|&&t| outside_parts(bins.spans[t as usize])).count();
            }
            // The parts do cull (else the test above would hold whatever the spans were).
            prop_assert!(culled > 0);
        }
    }

    /// Each bin's start tet is, among the tets whose centroid falls in the bin, the one
    /// nearest the bin's centre (the lowest id among equals); else the bin's first tet.
    #[test]
    fn start_tets_are_the_nearest_centroids() {
        let mesh = KuhnGrid::new(5).jitter(0.2, 7).mesh("cube");
        let bins = Bins::build(&mesh, 1.5);
        let centre =
            |at: [usize; 3]| -> Vec3 { std::array::from_fn(|k| bins.lo[k] + (at[k] as f32 + 0.5) / bins.scale[k]) };
        let n_bins = bins.n.iter().product::<usize>();
        for b in 0..n_bins {
            let at = [b % bins.n[0], b / bins.n[0] % bins.n[1], b / (bins.n[0] * bins.n[1])];
            let d2 = |t: usize| {
                let c = mesh.tet_center(t);
                (0..3).map(|k| (c[k] - centre(at)[k]) * (c[k] - centre(at)[k])).sum::<f32>()
            };
            let mut want = None;
            for t in (0..mesh.tets.len()).filter(|&t| bins.bin_of(mesh.tet_center(t)).0 == b) {
                if want.is_none_or(|w| d2(t) < d2(w)) {
                    want = Some(t);
                }
            }
            let want = want.map(|t| t as u32).or_else(|| bins.tets(b).first().copied());
            assert_eq!(bins.start(b), want, "bin {b}");
        }
    }
}
