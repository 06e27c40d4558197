//! The CPU locator, parallel over points with rayon.
//!
//! Large batches are visited in Morton order of their points, so consecutive queries are
//! close in space; small ones (where no two points are close) in their own order, in a task
//! or two a thread, or on the calling thread, with no per-batch buffer. Each query first
//! *walks* through face neighbours, from the previous answer when the previous point was in
//! the same or a touching bin ([`Bins`]: uniform bins over the tets' boxes), else from its
//! bin's start tet (the one whose centroid is nearest the bin's centre), so that sparse
//! batches walk a tet or two as dense ones do. Where the walk leaves the mesh, runs long, or
//! ends exactly on a face, the bin's tets whose boxes hold the point are tested: one holding
//! it strictly is the answer, none means outside, and the rest (ties) go to BVH traversal,
//! built only then.
//! Answers do not depend on the order: a point strictly inside a tet has exactly one
//! containing tet, which the walk, the bin and the BVH agree on, and a point on a face
//! always gets the BVH's answer.

use super::bins::Bins;
use super::grid_raster::{self, Cell, GridRaster};
use super::hint::Hint;
use super::occupancy::Occupancy;
use super::{check_sample_lengths, BatchLocator, GridSampler, Points, Values, OUTSIDE};
use crate::buckets::SharedSlice;
use crate::bvh::{morton, BuildPreset, Bvh};
use crate::error::Result;
use crate::geom::predicates::Query;
use crate::geom::ImageGrid;
use crate::geom::{self, Bary, TetTest, Vec3};
use crate::mesh::Mesh;
use rayon::prelude::*;
use std::ops::Range;
use std::sync::{Arc, OnceLock};

/// Points handed to one rayon task: large enough to amortise scheduling, small enough to balance.
const CHUNK: usize = 4096;
/// Batches from this size on are visited in Morton order (smaller ones in their own)...
const SORTED: usize = 8192;
/// ...and from one point per this many tets: sparser sorted points are still too far apart
/// for a walk from the one before (fusion 1.4M, 2 cores: 10k random points took 1.04 µs a
/// point sorted, against 0.80 µs for 1k in their order).
const TETS_A_SORTED_POINT: usize = 32;
/// The fewest points a task of a small batch gets (fewer stay on the calling thread): rayon's
/// hand-over costs about as much as walking them.
const MIN_TASK: usize = 128;
/// The points a batch should hold at most ([`BatchLocator::preferred_batch`]), but never too
/// few to be sorted.
const BATCH: usize = 1 << 16;
/// Walk steps before giving up and traversing the BVH.
const MAX_WALK: usize = 24;
/// The batches' bins, in mean edge lengths a side.
pub(super) const BIN_EDGES: f64 = 1.5;

/// One batch point's answer before the ties are decided.
#[derive(Clone, Copy)]
enum Answer {
    Found(u32, Bary),
    Outside,
    /// On a face, or held by two tets: the BVH's search decides (the tie rule).
    Tie,
}

pub struct CpuLocator {
    mesh: Arc<Mesh>,
    preset: BuildPreset,
    /// The BVH and the occupancy grid: built by [`Self::new`], or on first need by
    /// [`Self::deferred`] (a resample on the CPU needs neither: [`GridRaster`]; a batch only
    /// for its points on faces).
    index: OnceLock<Index>,
    /// The batches' index: built on the first batch (with the face neighbours).
    bins: OnceLock<Bins>,
    /// The grid `sample_grid` rasterized last.
    raster: Option<GridRaster>,
}

struct Index {
    bvh: Bvh,
    occupancy: Occupancy,
}

impl CpuLocator {
    pub fn new(mesh: Arc<Mesh>) -> CpuLocator {
        Self::with_preset(mesh, BuildPreset::Fast)
    }

    pub fn with_preset(mesh: Arc<Mesh>, preset: BuildPreset) -> CpuLocator {
        let loc = Self::deferred(mesh, preset);
        loc.index();
        loc
    }

    /// A locator that builds its BVH, occupancy grid and face neighbours when a query first
    /// needs them: nothing is built for a resample whose grid points all fall strictly
    /// inside one tet or outside, and a batch (a probe) builds the bins and neighbours, the
    /// BVH only for points on faces. The batch calls build before they go parallel; a caller of
    /// [`Self::locate_point`] or [`Self::locate_from`] from parallel code builds first
    /// ([`Self::bvh`]), so that no rayon task waits on a build its own thread is running.
    pub fn deferred(mesh: Arc<Mesh>, preset: BuildPreset) -> CpuLocator {
        CpuLocator { mesh, preset, index: OnceLock::new(), bins: OnceLock::new(), raster: None }
    }

    fn index(&self) -> &Index {
        self.index.get_or_init(|| {
            let (bvh, occupancy) = rayon::join(
                || Bvh::build(&self.mesh.points, &self.mesh.tets, self.preset),
                || {
                    self.mesh.neighbors(); // build the adjacency now, not inside the first batch
                    Occupancy::of_tets(&self.mesh)
                },
            );
            Index { bvh, occupancy }
        })
    }

    /// The batches' bins and the face neighbours, built on first need.
    fn bins(&self) -> &Bins {
        self.bins.get_or_init(|| rayon::join(|| Bins::build(&self.mesh, BIN_EDGES), || self.mesh.neighbors().len()).0)
    }

    pub fn bvh(&self) -> &Bvh {
        &self.index().bvh
    }

    /// Whether the BVH and occupancy grid exist yet.
    pub fn index_built(&self) -> bool {
        self.index.get().is_some()
    }

    pub fn mesh(&self) -> &Arc<Mesh> {
        &self.mesh
    }

    /// The tet containing `p` and the barycentric coordinates of `p` in it, by BVH traversal
    /// (the canonical answer: the tet that holds `p` strictly inside, or, for a point on
    /// faces, edges or vertices, the lowest id among the tets that hold it: the tie rule).
    #[inline]
    pub fn locate_point(&self, p: Vec3) -> Option<(u32, Bary)> {
        self.find(&self.query_at(p))
    }

    /// [`Self::locate_point`] of a point given in f64.
    pub fn locate_point64(&self, p: [f64; 3]) -> Option<(u32, Bary)> {
        self.find(&self.mesh.exact().query(p))
    }

    /// A point given in f32 file coordinates, with its working coordinates.
    #[inline]
    fn query_at(&self, p: Vec3) -> Query {
        Query { local: self.mesh.info.frame.to_working_f32(p), file: p.map(f64::from) }
    }

    /// The point-in-tet test on the file's data (`geom::test_point_with`).
    #[inline]
    fn test(&self, t: u32, q: &Query) -> TetTest {
        geom::test_point_with(self.mesh.tets[t as usize], &self.mesh.points, &self.mesh.exact(), q)
    }

    /// BVH traversal in the working frame (boxes of rounded vertices hold the rounded point
    /// whenever the file's box holds the file's point: rounding is monotone). A tet that holds
    /// the point strictly inside ends the search (no other holds it); one that holds it on its
    /// boundary does not: the search goes on, and the lowest such id is the answer, whatever
    /// the order of the traversal (`geom::lowest_claim`, the rule every kernel shares).
    fn find(&self, q: &Query) -> Option<(u32, Bary)> {
        let p = q.local;
        let Index { bvh, occupancy } = self.index();
        let nodes = &bvh.nodes;
        if nodes.is_empty() || !nodes[0].contains(p) || !occupancy.may_hold(p) {
            return None;
        }
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        let mut i = 0u32;
        let mut tie = None;
        loop {
            let n = &nodes[i as usize];
            if n.is_leaf() {
                for &t in &bvh.prim_ids[n.first as usize..(n.first + n.count) as usize] {
                    if let TetTest::Inside(b) = self.test(t, q) {
                        if !b.contains(&0.0) {
                            return Some((t, b));
                        }
                        geom::lowest_claim(&mut tie, (t, b));
                    }
                }
            } else {
                let (l, r) = (i + 1, n.first);
                let (in_l, in_r) = (nodes[l as usize].contains(p), nodes[r as usize].contains(p));
                if in_l {
                    if in_r {
                        stack[sp] = r;
                        sp += 1;
                    }
                    i = l;
                    continue;
                } else if in_r {
                    i = r;
                    continue;
                }
            }
            if sp == 0 {
                return tie;
            }
            sp -= 1;
            i = stack[sp];
        }
    }

    /// Walks from tet `start` towards `p`. Returns the tet only when `p` is strictly inside
    /// it (no zero weight), so that the answer is the unique one. `first_exact`: the exact
    /// test at the start tet (usually the answer for a particle); else every step, the first
    /// included, goes by plain f32 (`geom::walk_face`) until no face points onwards, and only
    /// there the exact test (a batch's next point is usually in another tet).
    #[inline]
    fn walk(&self, start: u32, q: &Query, first_exact: bool) -> Option<(u32, Bary)> {
        let neighbors = self.mesh.neighbors();
        let mut t = start;
        for step in 0..MAX_WALK {
            if step > 0 || !first_exact {
                if let Some(face) = geom::walk_face(self.mesh.tets[t as usize], &self.mesh.points, q.local) {
                    let next = neighbors[t as usize][face];
                    if next < 0 {
                        return None;
                    }
                    t = next as u32;
                    continue;
                }
            }
            match self.test(t, q) {
                TetTest::Inside(b) => return (!b.contains(&0.0)).then_some((t, b)),
                TetTest::Outside { face } => {
                    let next = neighbors[t as usize][face];
                    if next < 0 {
                        return None;
                    }
                    t = next as u32;
                }
            }
        }
        None
    }

    /// Locates every point, walking from the previous answer, and writes `f(i, answer)` to
    /// `out[i]` (`f` is called once for each point, and again for a point the BVH decides).
    /// Incoherent batches of [`SORTED`] points or more are visited in Morton order so
    /// that consecutive points are close; batches that already are (tet centres in mesh
    /// order, points along rays or particle paths) keep their order and skip the sort, and so
    /// do smaller ones, whose points are too far apart for the order to pay. Points of any
    /// precision, `query` giving their two forms.
    fn locate_batch_of<P: Sync, T: Send + Copy>(
        &self,
        points: &[P],
        query: impl Fn(&P) -> Query + Sync,
        out: &mut [T],
        f: impl Fn(usize, Option<(u32, Bary)>) -> T + Sync,
    ) {
        let bins = self.bins();
        // Point i's value for `out`, its index kept in `ties` where the BVH decides.
        let value = |i: usize, hint: &mut Near, ties: &mut Vec<usize>| -> T {
            match self.search(bins, &query(&points[i]), hint) {
                Answer::Found(t, b) => f(i, Some((t, b))),
                Answer::Outside => f(i, None),
                Answer::Tie => {
                    ties.push(i);
                    f(i, None)
                }
            }
        };
        // Morton orders hold 32-bit indices: a larger batch keeps its order.
        let sortable =
            points.len() >= SORTED.max(self.mesh.n_tets() / TETS_A_SORTED_POINT) && points.len() as u64 <= 1 << 32;
        let ties = if sortable {
            let working: Vec<Vec3> = points.par_iter().map(|p| query(p).local).collect();
            if is_coherent(&working, self.mesh.info.mean_edge_length) {
                in_order(out, CHUNK, &value)
            } else {
                self.in_morton_order(working, out, &value)
            }
        } else {
            // Small batches: chunks of at least [`MIN_TASK`] points, one a thread or two,
            // with no sort and no buffer.
            in_order(out, points.len().div_ceil(2 * rayon::current_num_threads()).max(MIN_TASK), &value)
        };
        if !ties.is_empty() {
            // Built here, not inside the parallel loop (where a rayon task could be run by
            // the thread that is building it).
            self.index();
            let found: Vec<T> = ties.par_iter().map(|&i| f(i, self.find(&query(&points[i])))).collect();
            for (&i, v) in ties.iter().zip(found) {
                out[i] = v;
            }
        }
    }

    /// Every point's `value` written straight to its place in `out`, the points visited in
    /// the Morton order of `working` (their working coordinates), [`CHUNK`] a task. The
    /// ties' indices are returned.
    fn in_morton_order<T: Send>(&self, working: Vec<Vec3>, out: &mut [T], value: &impl WalkValue<T>) -> Vec<usize> {
        let order = morton::order(&working, self.mesh.info.bounds_min, self.mesh.info.bounds_max);
        drop(working);
        // What the writes below stand on: one place for each point, each index once.
        assert!(order.len() == out.len());
        let places = SharedSlice::new(out);
        order
            .par_chunks(CHUNK)
            .flat_map_iter(|chunk| {
                let (mut hint, mut ties) = (None, Vec::new());
                for &i in chunk {
                    let v = value(i as usize, &mut hint, &mut ties);
                    // SAFETY: `order` is a permutation of 0..out.len() (morton::order gives
                    // each index once), so each place is written by one task, once, while
                    // `out` is borrowed here and read by no one.
                    unsafe { places.at(i as usize).write(v) };
                }
                ties
            })
            .collect()
    }

    /// One batch point: a walk from the previous answer (`hint`, when it was in the same or
    /// a touching bin) or from the bin's start tet, then the bin's tets (see the module
    /// documentation).
    #[inline]
    fn search(&self, bins: &Bins, q: &Query, hint: &mut Near) -> Answer {
        let (lo, hi) = (self.mesh.info.bounds_min, self.mesh.info.bounds_max);
        // A NaN or infinite coordinate is in no tet (and would lead a walk astray).
        if !q.file.iter().all(|c| c.is_finite()) || !(0..3).all(|k| q.local[k] >= lo[k] && q.local[k] <= hi[k]) {
            return Answer::Outside;
        }
        let (b, at) = bins.bin_of(q.local);
        let Some(first) = bins.start(b) else { return Answer::Outside };
        let start = match *hint {
            Some((t, near)) if (0..3).all(|k| near[k].abs_diff(at[k]) <= 1) => t,
            _ => first,
        };
        let found = match self.walk(start, q, false) {
            Some(found) => found,
            None => {
                let mut found = None;
                for t in bins.boxes_holding(&self.mesh, b, q.local) {
                    if let TetTest::Inside(w) = self.test(t, q) {
                        if w.contains(&0.0) || found.is_some() {
                            return Answer::Tie;
                        }
                        found = Some((t, w));
                    }
                }
                let Some(found) = found else { return Answer::Outside };
                found
            }
        };
        *hint = Some((found.0, at));
        Answer::Found(found.0, found.1)
    }
}

/// A batch walk's previous answer and its bin's coordinates: where the next walk starts.
type Near = Option<(u32, [usize; 3])>;

/// Point `i`'s answer in a batch, walking from `Near` and keeping `i` in the ties where the
/// BVH decides (`locate_batch_of`'s `value`).
trait WalkValue<T>: Fn(usize, &mut Near, &mut Vec<usize>) -> T + Sync {}
impl<T, F: Fn(usize, &mut Near, &mut Vec<usize>) -> T + Sync> WalkValue<T> for F {}

/// Every point's `value` written straight to `out`, in the points' order, `chunk` points a
/// task (a batch of one chunk stays on the calling thread). The ties' indices are returned.
fn in_order<T: Send>(out: &mut [T], chunk: usize, value: &impl WalkValue<T>) -> Vec<usize> {
    let each = |c: usize, out: &mut [T]| {
        let (mut hint, mut ties) = (None, Vec::new());
        for (k, o) in out.iter_mut().enumerate() {
            *o = value(c * chunk + k, &mut hint, &mut ties);
        }
        ties
    };
    if out.len() <= chunk {
        return each(0, out);
    }
    out.par_chunks_mut(chunk).enumerate().flat_map_iter(|(c, o)| each(c, o)).collect()
}

/// Whether consecutive points are, on average, within a few tet sizes of each other, so
/// that walking in the given order beats sorting first.
pub(super) fn is_coherent(points: &[Vec3], mean_edge: f32) -> bool {
    if points.len() < 2 {
        return true;
    }
    let step: f64 =
        points.par_windows(2).map(|w| (0..3).map(|k| ((w[1][k] - w[0][k]) as f64).abs()).sum::<f64>()).sum::<f64>()
            / (points.len() - 1) as f64;
    step < 3.0 * mean_edge as f64
}

impl CpuLocator {
    /// The tet containing `p`, searched from `hint` (a walk through neighbours, the BVH when
    /// the walk fails), which becomes the answer: one particle's lookups, each near the last.
    #[inline]
    pub fn locate_from(&self, p: Vec3, hint: &mut Option<u32>) -> Option<(u32, Bary)> {
        self.walk_then(p, hint, |q| self.find(q))
    }

    /// The walk from `hint`'s tet, else `search`; the tet found becomes the hint.
    #[inline]
    fn walk_then(
        &self,
        p: Vec3,
        hint: &mut Option<u32>,
        search: impl FnOnce(&Query) -> Option<(u32, Bary)>,
    ) -> Option<(u32, Bary)> {
        if !super::is_finite(p) {
            return None;
        }
        let q = self.query_at(p);
        let found = hint.and_then(|h| self.walk(h, &q, true)).or_else(|| search(&q));
        if let Some((t, _)) = found {
            *hint = Some(t);
        }
        found
    }

    /// [`Self::locate_from`] for a particle: a point that stays in the hint's tet is answered
    /// by the tet's barycentric map, without the exact test or the walk
    /// ([`Hint`]); the same tet, with the map's weights.
    #[inline]
    pub fn locate_near(&self, p: Vec3, hint: &mut Hint) -> Option<(u32, Bary)> {
        self.locate_near_with(p, hint, 1.0)
    }

    /// [`Self::locate_near`] with the maps' bounds times `bound_scale` (1 but in tests).
    /// The map's answer is inlined into the tracer's loop (the point stays in registers; a
    /// call took it through memory, a stall on every lookup), the search is not.
    #[inline(always)]
    pub(crate) fn locate_near_with(&self, p: Vec3, hint: &mut Hint, bound_scale: f64) -> Option<(u32, Bary)> {
        if let Some(found) = hint.inside(p) {
            hint.look_around(&self.mesh);
            return Some(found);
        }
        self.search_near(p, hint, bound_scale)
    }

    /// [`Self::locate_near_with`] where the hint's map cannot decide: the walk from its tet,
    /// then the BVH's search, or the bins' where only they are built
    /// ([`Self::ready_for_particles`]).
    #[inline(never)]
    fn search_near(&self, p: Vec3, hint: &mut Hint, bound_scale: f64) -> Option<(u32, Bary)> {
        let found = match (self.index.get(), self.bins.get()) {
            (None, Some(bins)) => self.locate_from_bins(bins, p, &mut hint.tet),
            _ => self.locate_from(p, &mut hint.tet),
        };
        if let Some((t, _)) = found {
            hint.found(&self.mesh, t, bound_scale);
        }
        found
    }

    /// Readies the particles' lookups ([`Self::locate_near`]) before a parallel loop runs
    /// them (a search built inside one could wait on itself). A tracer needs a search only
    /// for its seeds and where a particle's walk fails: for streamlines, whose steps are a
    /// fraction of an edge, mostly where they leave the mesh, and the bins serve (one
    /// counting pass over the tets, a third of the BVH's build); nothing is built when the
    /// BVH is. `long_steps`: particles that cross many tets a step (pathlines, a step half a
    /// time interval) fail their walks more often, and the BVH's search is the faster
    /// fallback for them (measured: BENCHMARKS.md).
    pub fn ready_for_particles(&self, long_steps: bool) {
        if long_steps {
            self.index();
        } else if !self.index_built() {
            self.bins();
        }
    }

    /// [`Self::locate_from`] without the BVH: the walk from the hint, else the bins' search
    /// (a walk from the bin's start, then the bin's tets). A point neither decides (on a
    /// face) gets the tie rule from its bin, whose tets include every one that can hold it.
    /// The same answers as the BVH's where tets do not overlap (a point strictly inside two
    /// folded tets gets the lower id here, the first the BVH's traversal meets there).
    fn locate_from_bins(&self, bins: &Bins, p: Vec3, hint: &mut Option<u32>) -> Option<(u32, Bary)> {
        self.walk_then(p, hint, |q| match self.search(bins, q, &mut None) {
            Answer::Found(t, b) => Some((t, b)),
            Answer::Outside => None,
            Answer::Tie => self.tie_in_bin(bins, q),
        })
    }

    /// The tie rule ([`geom::lowest_claim`]) over the tets of `q`'s bin whose boxes hold it:
    /// a tet holding it strictly inside, else the lowest id among those holding it on their
    /// boundary.
    fn tie_in_bin(&self, bins: &Bins, q: &Query) -> Option<(u32, Bary)> {
        let (b, _) = bins.bin_of(q.local);
        let mut tie = None;
        for t in bins.boxes_holding(&self.mesh, b, q.local) {
            if let TetTest::Inside(w) = self.test(t, q) {
                if !w.contains(&0.0) {
                    return Some((t, w));
                }
                geom::lowest_claim(&mut tie, (t, w));
            }
        }
        tie
    }

    /// The three fields `components` as one vector at a point, looked up from a hint (see
    /// [`Self::locate_near`]): the field a particle tracer follows.
    pub fn vector_field(
        &self,
        components: [&str; 3],
    ) -> Result<impl Fn(Vec3, &mut Hint) -> Option<[f32; 3]> + Sync + '_> {
        self.vector_field_with(components, 1.0)
    }

    /// [`Self::vector_field`] with the maps' bounds times `bound_scale`: infinity gives every
    /// lookup the exact test's weights, as the batch drivers get them (tests).
    pub(crate) fn vector_field_with(
        &self,
        components: [&str; 3],
        bound_scale: f64,
    ) -> Result<impl Fn(Vec3, &mut Hint) -> Option<[f32; 3]> + Sync + '_> {
        let [x, y, z] = components.map(|c| self.mesh.field(c));
        let xyz = [x?, y?, z?];
        self.index();
        Ok(move |p: Vec3, hint: &mut Hint| {
            let found = self.locate_near_with(p, hint, bound_scale)?;
            let mut v = [0f32; 3];
            self.mesh.values_at(&xyz, Some((found.0 as usize, found.1)), &mut v);
            Some(v)
        })
    }
}

impl BatchLocator for CpuLocator {
    fn name(&self) -> &str {
        "cpu"
    }

    /// The BVH, occupancy grid and bins kept; a rasterized grid's values dropped.
    fn take_fields(&mut self, mesh: &Arc<Mesh>) -> bool {
        if !self.mesh.same_geometry(mesh) {
            return false;
        }
        self.mesh = mesh.clone();
        self.raster = None;
        true
    }

    /// A batch's values in cache until they are copied out: the probe of fusion 1.4M at
    /// 983k points (five values a point) ran 4–5 % faster in batches of 2^16 than in one.
    fn preferred_batch(&self) -> Option<usize> {
        Some(BATCH.max(self.mesh.n_tets() / TETS_A_SORTED_POINT))
    }

    /// f32 points: one lookup per point for every field. f64 points: exact on the file's
    /// data (every face sign that the f32 filter cannot decide is decided on the f64
    /// coordinates of the mesh and the point), values in f64 on the file's values, at f64
    /// barycentrics ([`Mesh::values_at_ids64`]).
    fn query(&mut self, points: Points<'_>, fields: &[&str], ids: &mut [i32], values: Values<'_>) -> Result<()> {
        check_sample_lengths(points.len(), fields.len(), ids.len(), values.len())?;
        match points {
            Points::F32(p) => values.via_f32(|v| self.sample_many_of(p, |p| self.query_at(*p), fields, ids, v)),
            Points::F64(p) => {
                let fields = fields.iter().map(|f| self.mesh.field(f)).collect::<Result<Vec<_>>>()?;
                let exact = self.mesh.exact();
                self.locate_batch_of(p, |p| exact.query(*p), ids, |_, found| found.map_or(OUTSIDE, |(t, _)| t as i32));
                match values {
                    Values::F32(v) => self.mesh.values_at_ids64(p, ids, &fields, v),
                    Values::F64(v) => self.mesh.values_at_ids64(p, ids, &fields, v),
                }
                Ok(())
            }
        }
    }

    fn grid_sampler(&mut self) -> Option<&mut dyn GridSampler> {
        Some(self)
    }
}

impl GridSampler for CpuLocator {
    /// The grid's points located by rasterizing the tets (`GridRaster`), the ties by the
    /// search: the same ids as a query of the grid's points ([`super::query_grid_points`]), bit
    /// for bit, and values within rounding of its (the weights of an affine map, not of the
    /// exact test, where a tet holds a point by more than the map's error bound).
    fn sample_grid(
        &mut self,
        grid: &ImageGrid,
        range: Range<usize>,
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [f32],
    ) -> Result<()> {
        check_sample_lengths(range.len(), fields.len(), ids.len(), values.len())?;
        // Rasterized a slab of z planes at a time: a grid whose one plane (or whose count of
        // planes) exceeds a slab's points is searched point by point instead, in the
        // caller's chunks, so memory stays bounded for any grid.
        let huge = grid.dims[0].saturating_mul(grid.dims[1]) > grid_raster::SLAB_POINTS
            || grid.dims[2] > grid_raster::SLAB_POINTS;
        if self.mesh.n_tets() >= grid_raster::MAX_TETS || huge {
            return super::query_grid_points(self, grid, range, fields, ids, values);
        }
        let names = fields;
        let fields = fields.iter().map(|f| self.mesh.field(f)).collect::<Result<Vec<_>>>()?;
        let mut raster = match self.raster.take() {
            Some(r) if r.is_for(grid, names) => r,
            _ => GridRaster::new(&self.mesh, grid, grid_raster::SLAB_POINTS, names),
        };
        // The search applies the tie rule.
        let exact = self.mesh.exact();
        let tie = |k: usize| self.find(&exact.query(grid.point64(k)));
        let nf = fields.len();
        let mut i = range.start;
        while i < range.end {
            let end = raster.hold(&self.mesh, &fields, i).end.min(range.end);
            if raster.tied() {
                // Built here, not inside the parallel loop (where a rayon task could be run
                // by the thread that is building it).
                self.index();
            }
            let (raster, part) = (&raster, i - range.start..end - range.start);
            let ids = ids[part.clone()].par_iter_mut().zip(i..end);
            if nf == 0 {
                ids.for_each(|(id, k)| {
                    *id = match raster.cell(k) {
                        Cell::Outside => OUTSIDE,
                        Cell::Inside(t) => t as i32,
                        Cell::Tie => tie(k).map_or(OUTSIDE, |(t, _)| t as i32),
                    }
                });
            } else {
                let values = values[part.start * nf..part.end * nf].par_chunks_mut(nf);
                ids.zip(values).for_each(|((id, k), out)| match raster.cell(k) {
                    Cell::Outside => {
                        *id = OUTSIDE;
                        out.fill(f32::NAN);
                    }
                    Cell::Inside(t) => {
                        *id = t as i32;
                        raster.copy_values(k, out);
                    }
                    Cell::Tie => {
                        let found = tie(k);
                        *id = found.map_or(OUTSIDE, |(t, _)| t as i32);
                        self.mesh.values_at(&fields, found.map(|(t, b)| (t as usize, b)), out);
                    }
                });
            }
            i = end;
        }
        self.raster = Some(raster);
        Ok(())
    }
}

impl CpuLocator {
    fn sample_many_of<P: Sync>(
        &self,
        points: &[P],
        query: impl Fn(&P) -> Query + Sync,
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [f32],
    ) -> Result<()> {
        check_sample_lengths(points.len(), fields.len(), ids.len(), values.len())?;
        let fields = fields.iter().map(|f| self.mesh.field(f)).collect::<Result<Vec<_>>>()?;
        if fields.is_empty() {
            // Ids only: no answers kept beside them.
            self.locate_batch_of(points, query, ids, |_, f| f.map_or(OUTSIDE, |(t, _)| t as i32));
            return Ok(());
        }
        // Each point's values written as it is located (its tet's corners still in cache),
        // not from a second pass over kept answers.
        let nf = fields.len();
        let rows = SharedSlice::new(values);
        self.locate_batch_of(points, query, ids, |i, found| {
            // SAFETY: `values` holds `nf` values for each of the points (checked above), and
            // `locate_batch_of` calls this for point `i` on one task at a time: once in its
            // parallel part (each index once) and, for a tie, again after that part has ended.
            let out = unsafe { std::slice::from_raw_parts_mut(rows.at(i * nf), nf) };
            self.mesh.values_at(&fields, found.map(|(t, b)| (t as usize, b)), out);
            found.map_or(OUTSIDE, |(t, _)| t as i32)
        });
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gen::{generate, Shape};
    use rand::{Rng, SeedableRng};

    /// A grid one of whose z planes holds more points than a raster slab (issue 29, item 6:
    /// `resample --dims 100000,100000,...` allocated the whole plane) is searched in the
    /// caller's chunks instead, with the same answers; a grid of many planes likewise.
    #[test]
    fn grids_beyond_a_slab_are_searched_in_chunks() {
        let m = Arc::new(crate::test_support::grid_mesh(4, 0.2, 3));
        let wide = grid_raster::SLAB_POINTS + 1;
        for (lo, hi, dims) in
            [([-0.01, 0.5, 0.5], [1.2, 0.5, 0.5], [wide, 1, 1]), ([0.5, 0.5, -0.01], [0.5, 0.5, 1.2], [1, 1, wide])]
        {
            let grid = ImageGrid::spanning(lo, hi, dims).unwrap();
            let mut loc = CpuLocator::new(m.clone());
            let range = 0..100_000;
            let (mut ids, mut values) = (vec![0; range.len()], vec![0f32; range.len()]);
            loc.sample_grid(&grid, range.clone(), &["f"], &mut ids, &mut values).unwrap();
            assert!(loc.raster.is_none(), "{dims:?}: a slab was rasterized");
            let points = super::super::grid_points(&grid, range);
            let (mut ids2, mut values2) = (vec![0; points.len()], vec![0f32; points.len()]);
            loc.sample_many(&points, &["f"], &mut ids2, &mut values2).unwrap();
            assert_eq!(ids, ids2);
            assert!(ids.iter().any(|&i| i >= 0) && ids.iter().any(|&i| i < 0), "{dims:?}");
            assert_eq!(
                values.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                values2.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            );
        }
    }

    /// Batches (walks from the previous answer, f32 steps, the exact test at the end) give
    /// the BVH's own answer for every point: a grid aligned with a KuhnGrid's vertices (points
    /// on vertices, edges and faces, where the tie rule decides), its rows in both directions,
    /// and random points of a jittered mesh.
    #[test]
    fn walks_give_the_bvh_answers_on_faces_and_vertices() {
        let kuhn = Arc::new(crate::test_support::KuhnGrid::new(4).mesh("cube"));
        let jittered = Arc::new(crate::test_support::grid_mesh(5, 0.25, 7));
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        for m in [kuhn, jittered] {
            let mut loc = CpuLocator::new(m.clone());
            // 1/8 steps from -1/8 to 9/8: every vertex, edge midpoint and face centre, and beyond.
            let g: Vec<f32> = (-1..=9).map(|i| i as f32 / 8.0).collect();
            let mut points: Vec<Vec3> = Vec::new();
            for &z in &g {
                for &y in &g {
                    points.extend(g.iter().map(|&x| [x, y, z]));
                }
            }
            let back: Vec<Vec3> = points.iter().rev().copied().collect();
            points.extend(back);
            let (lo, hi) = (m.info.bounds_min, m.info.bounds_max);
            points.extend((0..3000).map(|_| -> Vec3 { std::array::from_fn(|k| rng.gen_range(lo[k]..=hi[k])) }));
            let mut ids = vec![0i32; points.len()];
            loc.locate(&points, &mut ids).unwrap();
            let (mut inside, mut ties) = (0, 0);
            for (p, &id) in points.iter().zip(&ids) {
                let want = loc.locate_point(*p).map_or(OUTSIDE, |(t, _)| t as i32);
                assert_eq!(id, want, "{p:?}");
                inside += usize::from(id >= 0);
                // The tie rule: the lowest id among the tets that hold the point.
                let holders: Vec<i32> = (0..m.n_tets())
                    .filter(|&t| matches!(loc.test(t as u32, &loc.query_at(*p)), TetTest::Inside(_)))
                    .map(|t| t as i32)
                    .collect();
                assert_eq!(id, holders.first().copied().unwrap_or(OUTSIDE), "{p:?}: holders {holders:?}");
                ties += usize::from(holders.len() > 1);
            }
            assert!(inside > points.len() / 2 && ties >= 50, "{inside} inside, {ties} ties");
        }
    }

    /// Sparse batches (a few random points of the torus' box, where each walk starts from
    /// its bin's first tet and the bins decide where the walk fails) give the BVH's answers;
    /// a batch with no point on a face builds no BVH.
    #[test]
    fn sparse_batches_give_the_bvh_answers() {
        let m = Arc::new(Mesh::new(generate(Shape::Fusion, 20_000, 3), "fusion").unwrap());
        let (lo, hi) = (m.info.bounds_min, m.info.bounds_max);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let reference = CpuLocator::new(m.clone());
        let mut loc = CpuLocator::deferred(m.clone(), BuildPreset::Fast);
        for n in [1, 10, 1000, 20_000] {
            let points: Vec<Vec3> =
                (0..n).map(|_| -> Vec3 { std::array::from_fn(|k| rng.gen_range(lo[k]..=hi[k])) }).collect();
            let mut ids = vec![0i32; n];
            loc.locate(&points, &mut ids).unwrap();
            for (p, &id) in points.iter().zip(&ids) {
                assert_eq!(id, reference.locate_point(*p).map_or(OUTSIDE, |(t, _)| t as i32), "{p:?}");
            }
        }
        assert!(!loc.index_built(), "random points built a BVH");
    }

    /// Small batches (in their own order, on the calling thread or in a few tasks) give the
    /// same ids as one large batch (Morton order, [`CHUNK`] a task) and as the BVH: points on
    /// the vertices, edges and faces of a Kuhn-aligned grid (ties), outside points, points
    /// with NaN, random points of a jittered mesh and of the fusion torus (sparse: each walk
    /// from its bin's start tet).
    #[test]
    fn small_batches_give_the_large_batch_ids() {
        let kuhn = Arc::new(crate::test_support::KuhnGrid::new(4).mesh("cube"));
        let jittered = Arc::new(crate::test_support::grid_mesh(5, 0.25, 7));
        let fusion = Arc::new(Mesh::new(generate(Shape::Fusion, 20_000, 3), "fusion").unwrap());
        let mut rng = rand_pcg::Pcg64::seed_from_u64(17);
        for m in [kuhn, jittered, fusion] {
            let (lo, hi) = (m.info.bounds_min, m.info.bounds_max);
            let at = |f: Vec3| -> Vec3 { std::array::from_fn(|k| lo[k] + f[k] * (hi[k] - lo[k])) };
            // 1/8 steps from -1/8 to 9/8 of the box: on the Kuhn grid, every vertex, edge
            // midpoint and face centre, and points outside.
            let mut points: Vec<Vec3> = Vec::new();
            for z in -1..=9 {
                for y in -1..=9 {
                    points.extend((-1..=9).map(|x| at([x as f32 / 8.0, y as f32 / 8.0, z as f32 / 8.0])));
                }
            }
            points.extend((0..8000).map(|_| -> Vec3 { std::array::from_fn(|k| rng.gen_range(lo[k]..=hi[k])) }));
            points.push([f32::NAN, 0.0, 0.0]);
            // Shuffled: no order for the large batch's sort or the small ones' hints to lean on.
            for i in (1..points.len()).rev() {
                points.swap(i, rng.gen_range(0..=i));
            }
            assert!(points.len() >= SORTED, "the whole batch takes the Morton path");
            let large = {
                let mut loc = CpuLocator::deferred(m.clone(), BuildPreset::Fast);
                let mut ids = vec![0i32; points.len()];
                loc.locate(&points, &mut ids).unwrap();
                ids
            };
            let reference = CpuLocator::new(m.clone());
            let want: Vec<i32> =
                points.iter().map(|&p| reference.locate_point(p).map_or(OUTSIDE, |(t, _)| t as i32)).collect();
            assert_eq!(large, want);
            let ties = points
                .iter()
                .filter(|&&p| {
                    let q = reference.query_at(p);
                    let (b, _) = reference.bins().bin_of(q.local);
                    let inside = |&t: &u32| matches!(reference.test(t, &q), TetTest::Inside(_));
                    p[0].is_finite() && reference.bins().tets(b).iter().filter(|t| inside(t)).count() > 1
                })
                .count();
            assert!(ties > 0 || m.info.source != "cube", "no point on a shared face");
            assert!(want.iter().any(|&i| i < 0) && want.iter().filter(|&&i| i >= 0).count() > points.len() / 4);
            // One point a call, a few, one task, a task or more a thread.
            for size in [1, 7, MIN_TASK, 3 * MIN_TASK + 5, SORTED - 1] {
                let mut loc = CpuLocator::deferred(m.clone(), BuildPreset::Fast);
                let mut ids = vec![0i32; points.len()];
                for (p, o) in points.chunks(size).zip(ids.chunks_mut(size)) {
                    loc.locate(p, o).unwrap();
                }
                assert_eq!(ids, large, "batches of {size}");
            }
        }
    }

    /// The occupancy grid never refuses a point of a tet (vertices, centroids, points on
    /// edges and faces), and refuses points of the fusion torus' hole; the locator's answers
    /// there agree with brute force over every tet.
    #[test]
    fn occupancy_keeps_every_point_of_a_tet() {
        let m = Arc::new(Mesh::new(generate(Shape::Fusion, 20_000, 3), "fusion").unwrap());
        let loc = CpuLocator::new(m.clone());
        let occ = &loc.index().occupancy;
        for &t in m.tets.iter() {
            let v = t.map(|i| m.points[i as usize]);
            let mid = |a: Vec3, b: Vec3| -> Vec3 { std::array::from_fn(|k| 0.5 * (a[k] + b[k])) };
            let c: Vec3 = std::array::from_fn(|k| 0.25 * v.iter().map(|p| p[k]).sum::<f32>());
            let points = [v[0], v[1], v[2], v[3], c, mid(v[0], v[1]), mid(v[2], v[3]), mid(mid(v[0], v[1]), v[2])];
            for p in points {
                assert!(occ.may_hold(p), "{p:?} of tet {t:?}");
            }
        }
        let (lo, hi) = (m.info.bounds_min, m.info.bounds_max);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let (mut refused, mut n) = (0, 0);
        for _ in 0..4000 {
            let p: Vec3 = std::array::from_fn(|k| rng.gen_range(lo[k]..=hi[k]));
            refused += usize::from(!occ.may_hold(p));
            let brute = (0..m.tets.len() as u32).find(|&t| matches!(loc.test(t, &loc.query_at(p)), TetTest::Inside(_)));
            assert_eq!(loc.locate_point(p).map(|(t, _)| t), brute, "{p:?}");
            n += 1;
        }
        assert!(refused > n / 10, "{refused} of {n} refused");
    }
}
