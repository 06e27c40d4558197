//! The one point-in-tet and interpolation definition of tetloc.
//!
//! `shaders/common/tet.glsl` in the Vulkan backend mirrors this file line by line; the CPU
//! and every GPU kernel must give the same answer for the same point.
//!
//! **Watertight by construction.** Tets are stored in *canonical order* (see
//! [`canonical_tet`]): vertex ids ascending, except that the last two are swapped when that
//! is needed to make the tet positively oriented. So every face of every tet is evaluated
//! with its three vertex ids in ascending order, `orient(a, b, c, p)` with `a < b < c`:
//! two tets sharing a face compute bit-identical determinants for it, and only the sign
//! they expect differs. A point on a shared face is therefore accepted by at least one of
//! the two tets, never by neither.
//!
//! **Exact where it matters.** Each face determinant is first evaluated in f32 together with
//! a forward error bound (Shewchuk's orient3d stage-A bound). Only when the f32 value is
//! within that bound of zero (the point is within rounding of the face, or the tet is a
//! sliver) is it recomputed in f64, where the products of f32 differences are exact.
//!
//! **Mixed cells: the tie rule on warped faces.** A mesh of pyramids, wedges and hexes is
//! located in its conforming tet decomposition (`cell::decompose`), with this same test, so
//! every point is first in at most one decomposition tet, by the rule above. Where a quad face
//! is warped (bilinear), VTK's cells meet on the bilinear patch, not on its two triangles; the
//! answer moves from the decomposition's cell `C` to the neighbour `N` across that face only
//! when `C`'s converged f64 parametric coordinates (Newton from the shape's centre, no fused
//! multiply-adds) are strictly outside `C` through that face (margin < 0) *and* `N`'s are
//! inside `N` (margin ≥ 0). A point on a shared warped face is therefore `C`'s when `C`'s
//! coordinates put it on the face, and each point has exactly one answer. Points of a warped
//! boundary face that bulges outward are the cell's; points of the decomposition outside a
//! warped boundary face that dents inward are outside. (`locate::CellLocator` does this for
//! every backend.)

mod frame;
mod image_grid;
pub mod predicates;

pub use frame::Frame;
pub use image_grid::ImageGrid;

pub type Vec3 = [f32; 3];

/// Shewchuk's orient3d stage-A error bound `(7 + 56ε)ε` for f32 (ε = 2⁻²⁴), rounded up.
pub const ORIENT_ERR_BOUND_F32: f32 = 4.2e-7;

/// f32 barycentrics are trusted when the tet's volume exceeds the summed face-error
/// bounds by this factor; otherwise they are recomputed in f64 (slivers).
pub const BARY_F32_TRUST: f32 = 1024.0;

/// Determinant of (a-p, b-p, c-p) in f32, and its error bound.
#[inline(always)]
pub fn orient_f32(a: Vec3, b: Vec3, c: Vec3, p: Vec3) -> (f32, f32) {
    let (adx, ady, adz) = (a[0] - p[0], a[1] - p[1], a[2] - p[2]);
    let (bdx, bdy, bdz) = (b[0] - p[0], b[1] - p[1], b[2] - p[2]);
    let (cdx, cdy, cdz) = (c[0] - p[0], c[1] - p[1], c[2] - p[2]);
    let (bc_yz, cb_yz) = (bdy * cdz, cdy * bdz);
    let (ca_yz, ac_yz) = (cdy * adz, ady * cdz);
    let (ab_yz, ba_yz) = (ady * bdz, bdy * adz);
    let det = adx * (bc_yz - cb_yz) + bdx * (ca_yz - ac_yz) + cdx * (ab_yz - ba_yz);
    let permanent = (bc_yz.abs() + cb_yz.abs()) * adx.abs()
        + (ca_yz.abs() + ac_yz.abs()) * bdx.abs()
        + (ab_yz.abs() + ba_yz.abs()) * cdx.abs();
    (det, ORIENT_ERR_BOUND_F32 * permanent)
}

/// [`orient_f32`] of the four faces of `SORTED_FACES` at once, bit for bit the same
/// values: the faces share the differences `v_i - p` and the six 2×2 minors of their y and z
/// components (a minor with its vertices swapped is its exact negation: rounding is
/// symmetric), and each face's sums keep `orient_f32`'s order. About two thirds of four
/// separate calls' arithmetic.
#[inline]
pub fn orient_faces_f32(v: [Vec3; 4], p: Vec3) -> ([f32; 4], [f32; 4]) {
    let d = v.map(|u| [u[0] - p[0], u[1] - p[1], u[2] - p[2]]);
    // m(i, j) = d_i.y d_j.z - d_j.y d_i.z, and the sum of the two products' magnitudes.
    let m = |i: usize, j: usize| {
        let (ij, ji) = (d[i][1] * d[j][2], d[j][1] * d[i][2]);
        (ij - ji, ij.abs() + ji.abs())
    };
    let (m01, m02, m03, m12, m13, m23) = (m(0, 1), m(0, 2), m(0, 3), m(1, 2), m(1, 3), m(2, 3));
    // orient_f32(a, b, c) = a.x m(b, c) + b.x m(c, a) + c.x m(a, b), with m(c, a) = -m(a, c).
    let face = |a: usize, b: usize, c: usize, bc: (f32, f32), ac: (f32, f32), ab: (f32, f32)| {
        let det = d[a][0] * bc.0 + d[b][0] * -ac.0 + d[c][0] * ab.0;
        let permanent = bc.1 * d[a][0].abs() + ac.1 * d[b][0].abs() + ab.1 * d[c][0].abs();
        (det, ORIENT_ERR_BOUND_F32 * permanent)
    };
    let f = [
        face(1, 2, 3, m23, m13, m12),
        face(0, 2, 3, m23, m03, m02),
        face(0, 1, 3, m13, m03, m01),
        face(0, 1, 2, m12, m02, m01),
    ];
    (f.map(|x| x.0), f.map(|x| x.1))
}

/// A walk's step towards `p` from tet `ids` (canonical) in plain f32, without error bounds:
/// the stored index of the vertex opposite the face with the most negative orientation, or
/// `None` when none is negative. Only a direction (a wrong one near a face costs steps, not
/// answers): answers come from the exact test.
#[inline]
pub fn walk_face(ids: [u32; 4], points: &[Vec3], p: Vec3) -> Option<usize> {
    let swapped = ids[3] < ids[2];
    let asc = if swapped { [ids[0], ids[1], ids[3], ids[2]] } else { ids };
    let orientation = if swapped { 1.0f32 } else { -1.0 };
    let d = asc.map(|i| points[i as usize]).map(|u| [u[0] - p[0], u[1] - p[1], u[2] - p[2]]);
    let m = |i: usize, j: usize| d[i][1] * d[j][2] - d[j][1] * d[i][2];
    let (m01, m02, m03, m12, m13, m23) = (m(0, 1), m(0, 2), m(0, 3), m(1, 2), m(1, 3), m(2, 3));
    // SORTED_FACES' orientations times their parities (-1, 1, -1, 1).
    let signed = [
        -(d[1][0] * m23 - d[2][0] * m13 + d[3][0] * m12),
        d[0][0] * m23 - d[2][0] * m03 + d[3][0] * m02,
        -(d[0][0] * m13 - d[1][0] * m03 + d[3][0] * m01),
        d[0][0] * m12 - d[1][0] * m02 + d[2][0] * m01,
    ]
    .map(|x| orientation * x);
    let (mut best, mut low) = (None, 0.0f32);
    for (i, &x) in signed.iter().enumerate() {
        if x < low {
            (best, low) = (Some(i), x);
        }
    }
    best.map(|i| if swapped && i >= 2 { 5 - i } else { i })
}

/// The same determinant in f64 (differences and products of f32 inputs are exact there).
#[inline]
pub fn orient_f64(a: Vec3, b: Vec3, c: Vec3, p: Vec3) -> f64 {
    let d = |u: Vec3, i: usize| u[i] as f64 - p[i] as f64;
    let (adx, ady, adz) = (d(a, 0), d(a, 1), d(a, 2));
    let (bdx, bdy, bdz) = (d(b, 0), d(b, 1), d(b, 2));
    let (cdx, cdy, cdz) = (d(c, 0), d(c, 1), d(c, 2));
    adx * (bdy * cdz - cdy * bdz) + bdx * (cdy * adz - ady * cdz) + cdx * (ady * bdz - bdy * adz)
}

/// Signed volume ×6 of a tet in f64, right-handed: `((v1-v0) × (v2-v0)) · (v3-v0)`,
/// positive for a tet as VTK and Gmsh expect it. Equals `-orient(v0, v1, v2, v3)`.
#[inline]
pub fn tet_volume6(v: [Vec3; 4]) -> f64 {
    -orient_f64(v[0], v[1], v[2], v[3])
}

/// Puts a tet into canonical order: ids ascending, then the last two swapped if that makes
/// it positively oriented (right-handed, [`tet_volume6`] > 0). Returns the canonical ids
/// and the f64 volume×6 of the *input* order (negative: the input was inverted; zero:
/// degenerate).
pub fn canonical_tet(ids: [u32; 4], points: &[Vec3]) -> ([u32; 4], f64) {
    let p = |i: u32| points[i as usize];
    let input_vol = tet_volume6([p(ids[0]), p(ids[1]), p(ids[2]), p(ids[3])]);
    let mut s = ids;
    s.sort_unstable();
    let sorted_vol = tet_volume6([p(s[0]), p(s[1]), p(s[2]), p(s[3])]);
    if sorted_vol < 0.0 {
        s.swap(2, 3);
    }
    (s, input_vol)
}

/// Faces of a canonical tet `[x, y, z, w]` with `z, w` possibly swapped: for the face opposite
/// local vertex `i`, the three local indices in ascending global-id order, and the sign with
/// which `orient` of that face is positive towards vertex `i` when the ascending order has
/// `orient(v0, v1, v2, v3) > 0` (that is, when it is left-handed, and the canonical order
/// swapped the last two to make it right-handed).
/// Opposite 3: (0,1,2) even; opposite 2: (0,1,3) odd; opposite 1: (0,2,3) even; opposite 0: (1,2,3) odd.
const SORTED_FACES: [([usize; 3], f32); 4] = [([1, 2, 3], -1.0), ([0, 2, 3], 1.0), ([0, 1, 3], -1.0), ([0, 1, 2], 1.0)];

/// The four faces of a canonical tet, face `i` opposite ascending vertex `i`, each with its
/// vertex ids ascending and the sign `s` such that `s · orient(face, x) > 0` for `x` inside
/// the tet. Everything that builds faces (shared faces, ray-tracing triangles) uses this.
pub fn ascending_faces(ids: [u32; 4]) -> [([u32; 3], f32); 4] {
    let swapped = ids[3] < ids[2];
    let a = if swapped { [ids[0], ids[1], ids[3], ids[2]] } else { ids };
    // The ascending order is left-handed (orient > 0) exactly when canonical order swapped it.
    let orientation = if swapped { 1.0f32 } else { -1.0 };
    SORTED_FACES.map(|(f, parity)| ([a[f[0]], a[f[1]], a[f[2]]], parity * orientation))
}

/// Result of the point-in-tet test: the four barycentric coordinates (weights of v0..v3).
pub type Bary = [f32; 4];

/// What the point-in-tet test found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TetTest {
    /// Inside or on the boundary: the barycentric weights of the stored vertices. A weight of
    /// exactly 0 means the point is on the face opposite that vertex (shared with a neighbour).
    Inside(Bary),
    /// Outside: the stored-order index of the vertex opposite the first face that separates
    /// the point from the tet (the way to walk towards the point).
    Outside { face: usize },
}

/// **The tie rule.** A search that finds a tet holding the point with a zero weight (the
/// point on one of its faces, edges or vertices, which other tets may hold too) keeps the
/// lowest such id and searches on; a tet holding the point strictly inside ends the search.
/// So the answer does not depend on the order a search visits the tets in: the CPU's BVH,
/// soft-bvh's wide BVH (`tl_traverse`) and rt-bvh's hardware traversal give the same id.
/// This records one such claim.
#[inline]
pub fn lowest_claim<T: Copy>(tie: &mut Option<(u32, T)>, claim: (u32, T)) {
    if tie.is_none_or(|(t, _)| claim.0 < t) {
        *tie = Some(claim);
    }
}

/// The point-in-tet test. `ids` must be canonical (see [`canonical_tet`]).
#[inline]
pub fn test_point(ids: [u32; 4], points: &[Vec3], p: Vec3) -> TetTest {
    // Ascending order of the four vertices: swap back the last two if canonical order swapped them.
    let swapped = ids[3] < ids[2];
    let asc = if swapped { [ids[0], ids[1], ids[3], ids[2]] } else { ids };
    // The ascending order is left-handed (orient > 0) exactly when canonical order swapped it.
    let orientation = if swapped { 1.0f32 } else { -1.0 };
    // Ascending index -> stored index.
    let stored = |i: usize| if swapped && i >= 2 { 5 - i } else { i };
    let v = [points[asc[0] as usize], points[asc[1] as usize], points[asc[2] as usize], points[asc[3] as usize]];
    let mut d = [0f32; 4];
    let mut bound_sum = 0f32;
    let mut exact = false;
    let (dets, bounds) = orient_faces_f32(v, p);
    for (i, &(f, parity)) in SORTED_FACES.iter().enumerate() {
        let sign = parity * orientation;
        let (det, bound) = (dets[i], bounds[i]);
        let signed = if det.abs() > bound {
            sign * det
        } else {
            exact = true;
            let signed64 = sign as f64 * orient_f64(v[f[0]], v[f[1]], v[f[2]], p);
            if signed64 < 0.0 {
                return TetTest::Outside { face: stored(i) };
            }
            signed64 as f32
        };
        // `signed` may be -0.0 or +0.0 on the face: both count as inside.
        if signed < 0.0 {
            return TetTest::Outside { face: stored(i) };
        }
        d[i] = signed;
        bound_sum += bound;
    }
    let mut bary = [0f32; 4];
    let total: f32 = d.iter().sum();
    if !exact && total > BARY_F32_TRUST * bound_sum {
        for i in 0..4 {
            bary[i] = d[i] / total;
        }
    } else {
        // Sliver or point near a face: barycentrics in f64.
        let mut d64 = [0f64; 4];
        for (i, &(f, parity)) in SORTED_FACES.iter().enumerate() {
            d64[i] = (parity * orientation) as f64 * orient_f64(v[f[0]], v[f[1]], v[f[2]], p);
        }
        let total64: f64 = d64.iter().sum();
        if total64 <= 0.0 {
            return TetTest::Outside { face: 0 }; // zero-volume tet: contains no point
        }
        for i in 0..4 {
            bary[i] = (d64[i].max(0.0) / total64) as f32;
        }
    }
    // Map weights from ascending order back to the stored (canonical) order.
    if swapped {
        bary.swap(2, 3);
    }
    TetTest::Inside(bary)
}

/// What [`test_point_with`] needs beyond the working f32 vertices: the file's f64
/// coordinates (`None`: the working copy is them) and the frame between the two.
#[derive(Clone, Copy, Debug)]
pub struct Exact<'a> {
    pub file: Option<&'a [[f64; 3]]>,
    pub frame: &'a Frame,
}

impl Exact<'_> {
    #[inline]
    fn vertex(&self, points: &[Vec3], i: u32) -> [f64; 3] {
        match self.file {
            Some(f) => f[i as usize],
            None => self.frame.to_file(points[i as usize]),
        }
    }

    /// A query point given in the file's coordinates, with its working coordinates.
    #[inline]
    pub fn query(&self, file: [f64; 3]) -> predicates::Query {
        predicates::Query { local: self.frame.to_working(file), file }
    }
}

/// The point-in-tet test on the file's data: [`test_point`] when the working copy and the
/// point are exactly the file's (the f32 path every backend shares); otherwise each face is
/// decided in f32 with a bound that also covers the rounding of vertices and point to the
/// working copy ([`Frame`]), and where that bound cannot decide, by the exact
/// sign of orient3d on the f64 coordinates. The tie rule is [`test_point`]'s: a point on a
/// face (exact zero) is inside, and the search takes the lowest id among the tets that claim
/// it ([`lowest_claim`]).
/// Barycentrics are computed in f64 on the file's coordinates.
pub fn test_point_with(ids: [u32; 4], points: &[Vec3], exact: &Exact, q: &predicates::Query) -> TetTest {
    let exact_query = exact.frame.is_identity() && q.local.map(f64::from) == q.file;
    if exact.file.is_none() && exact_query {
        return test_point(ids, points, q.local);
    }
    let swapped = ids[3] < ids[2];
    let asc = if swapped { [ids[0], ids[1], ids[3], ids[2]] } else { ids };
    let orientation = if swapped { 1.0f64 } else { -1.0 };
    let stored = |i: usize| if swapped && i >= 2 { 5 - i } else { i };
    let v = asc.map(|i| points[i as usize]);
    let mut v64: Option<[[f64; 3]; 4]> = None;
    for (i, &(f, parity)) in SORTED_FACES.iter().enumerate() {
        let sign = parity as f64 * orientation;
        let (det, bound) = predicates::orient3d_local(v[f[0]], v[f[1]], v[f[2]], q.local, exact.frame.delta);
        let signed = if det.abs() > bound {
            sign * det as f64
        } else {
            let w = *v64.get_or_insert_with(|| asc.map(|i| exact.vertex(points, i)));
            sign * predicates::orient3d(w[f[0]], w[f[1]], w[f[2]], q.file)
        };
        if signed < 0.0 {
            return TetTest::Outside { face: stored(i) };
        }
    }
    // Inside: barycentrics in f64 on the file's coordinates.
    let w = v64.unwrap_or_else(|| asc.map(|i| exact.vertex(points, i)));
    match bary64_of(w, swapped, q.file) {
        Some(b) => TetTest::Inside(b.map(|x| x as f32)),
        None => TetTest::Outside { face: 0 }, // zero-volume tet: contains no point
    }
}

/// Whether [`test_point_with`] would find `q` strictly inside tet `ids` (no weight zero),
/// known from its f32 filter alone: `false` where some face's sign is not certain there (or
/// is not positive), and the full test decides. Signs only, no barycentrics: the check of an
/// answer that certification makes for every point (`locate::certify`), several times
/// cheaper than the test's f64 weights.
#[inline]
pub fn holds_strictly_by_filter(ids: [u32; 4], points: &[Vec3], exact: &Exact, q: &predicates::Query) -> bool {
    let swapped = ids[3] < ids[2];
    let asc = if swapped { [ids[0], ids[1], ids[3], ids[2]] } else { ids };
    let orientation = if swapped { 1.0f32 } else { -1.0 };
    let v = asc.map(|i| points[i as usize]);
    SORTED_FACES.iter().all(|&(f, parity)| {
        let (det, bound) = predicates::orient3d_local(v[f[0]], v[f[1]], v[f[2]], q.local, exact.frame.delta);
        det.abs() > bound && parity * orientation * det > 0.0
    })
}

/// f64 barycentric weights (of the stored vertices v0..v3).
pub type Bary64 = [f64; 4];

/// The barycentrics of `p` (the file's coordinates) in tet `w` (its vertices in ascending id
/// order, `swapped` as in canonical order) from f64 orientations on the file's coordinates,
/// clamped to 0 and normalised; `None` for a zero-volume tet. [`test_point_with`]'s weights.
#[inline]
fn bary64_of(w: [[f64; 3]; 4], swapped: bool, p: [f64; 3]) -> Option<Bary64> {
    let orientation = if swapped { 1.0f64 } else { -1.0 };
    let mut d = [0f64; 4];
    for (i, &(f, parity)) in SORTED_FACES.iter().enumerate() {
        d[i] = (parity as f64 * orientation * predicates::orient3d(w[f[0]], w[f[1]], w[f[2]], p)).max(0.0);
    }
    let total: f64 = d.iter().sum();
    if total <= 0.0 {
        return None;
    }
    let mut bary = d.map(|x| x / total);
    if swapped {
        bary.swap(2, 3);
    }
    Some(bary)
}

/// The f64 barycentrics of `p` (the file's coordinates) in the canonical tet `ids`, on the
/// file's coordinates (`exact`): the weights of every f64 value, computed once the tet is
/// known (by any backend). `None` for a zero-volume tet. For a point outside the tet the
/// weights are clamped to it.
#[inline]
pub fn bary64(ids: [u32; 4], points: &[Vec3], exact: &Exact, p: [f64; 3]) -> Option<Bary64> {
    Corners64::of(ids, points, exact).bary64(p)
}

/// A tet's corners on the file's coordinates as [`bary64`] reads them, read once for every
/// point that falls in the tet.
#[derive(Clone, Copy, Debug)]
pub struct Corners64 {
    /// The vertices in ascending id order.
    w: [[f64; 3]; 4],
    /// Whether canonical order has the last two swapped.
    swapped: bool,
}

impl Corners64 {
    #[inline]
    pub fn of(ids: [u32; 4], points: &[Vec3], exact: &Exact) -> Corners64 {
        let swapped = ids[3] < ids[2];
        let asc = if swapped { [ids[0], ids[1], ids[3], ids[2]] } else { ids };
        Corners64 { w: asc.map(|i| exact.vertex(points, i)), swapped }
    }

    /// [`bary64`] of `p` in this tet.
    #[inline]
    pub fn bary64(&self, p: [f64; 3]) -> Option<Bary64> {
        bary64_of(self.w, self.swapped, p)
    }
}

/// The barycentrics with which the GPU kernels interpolate on a mesh stored in f64 (tet.glsl
/// `tl_refined_bary` mirrors this line by line): those of `p` (working coordinates, taken as
/// exact) in the tet whose vertices are the working copy `v` plus the residuals `r`
/// ([`crate::mesh::Mesh::working_residuals`]: together the file's coordinates to about 2⁻⁴⁸
/// of their size, where the f32 copy alone is off by 2⁻²⁵, a visible part of a sliver's
/// height). In f64, from sub-volumes relative to vertex 0 (differences first, so a sliver
/// far from the origin keeps its digits), clamped to 0 and normalised as in [`bary64`];
/// `v`, `r` and the weights in stored (canonical) order. `None` for a tet of no volume.
#[inline]
pub fn refined_bary(v: [Vec3; 4], r: [Vec3; 4], p: Vec3, p_residual: Vec3) -> Option<Bary> {
    let w: [[f64; 3]; 4] = std::array::from_fn(|i| std::array::from_fn(|k| f64::from(v[i][k]) + f64::from(r[i][k])));
    let from0 = |x: [f64; 3]| -> [f64; 3] { std::array::from_fn(|k| x[k] - w[0][k]) };
    let p: [f64; 3] = std::array::from_fn(|k| f64::from(p[k]) + f64::from(p_residual[k]));
    let (e1, e2, e3, q) = (from0(w[1]), from0(w[2]), from0(w[3]), from0(p));
    // det(a, b, c) = a · (b × c): the canonical order makes det(e1, e2, e3) positive.
    let det = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| {
        a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2]) + a[2] * (b[0] * c[1] - b[1] * c[0])
    };
    let total = det(e1, e2, e3);
    let (d1, d2, d3) = (det(q, e2, e3), det(e1, q, e3), det(e1, e2, q));
    let d = [total - d1 - d2 - d3, d1, d2, d3].map(|x| x.max(0.0));
    let sum = d[0] + d[1] + d[2] + d[3];
    if total <= 0.0 || sum <= 0.0 {
        return None;
    }
    Some(d.map(|x| (x / sum) as f32))
}

/// Puts a tet into canonical order like [`canonical_tet`], with orientations decided exactly
/// on the file's f64 coordinates.
pub fn canonical_tet_exact(ids: [u32; 4], file: &[[f64; 3]]) -> ([u32; 4], f64) {
    let p = ids.map(|i| file[i as usize]);
    let input_vol = -predicates::orient3d(p[0], p[1], p[2], p[3]);
    let mut s = ids;
    s.sort_unstable();
    // The sorted order's volume has the input's exact sign, flipped by each swap the sort
    // makes (an odd number of inversions): one orientation, not a second for the sorted order.
    let inversions = (0..4).flat_map(|i| (i + 1..4).map(move |j| (i, j))).filter(|&(i, j)| ids[i] > ids[j]).count();
    let sorted_vol = if inversions % 2 == 1 { -input_vol } else { input_vol };
    if sorted_vol < 0.0 {
        s.swap(2, 3);
    }
    (s, input_vol)
}

/// The point-in-tet test: the barycentric coordinates when `p` is inside or on the
/// boundary of the (canonical) tet `ids`.
#[inline]
pub fn point_in_tet(ids: [u32; 4], points: &[Vec3], p: Vec3) -> Option<Bary> {
    match test_point(ids, points, p) {
        TetTest::Inside(b) => Some(b),
        TetTest::Outside { .. } => None,
    }
}

/// Barycentric interpolation of a per-vertex scalar.
#[inline]
pub fn interpolate(ids: [u32; 4], bary: Bary, values: &[f32]) -> f32 {
    interpolate_with(ids, bary, |i| values[i])
}

/// The float types values are computed in: f32 (what the GPU kernels compute, on the f32
/// copy of the values) and f64 (on the file's values). The value definitions are generic over
/// it, so that both precisions share one code path.
pub trait Real:
    Copy
    + Send
    + Sync
    + std::ops::Mul<Output = Self>
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + 'static
{
    const NAN: Self;
    fn abs(self) -> Self;
    fn from_f64(x: f64) -> Self;
    fn to_f64(self) -> f64;
    /// This precision's copy of a value kept in both (a field's value: `Field::value_in`):
    /// the f32 one or the file's f64 one, only the one asked for computed.
    fn pick(f32_copy: impl FnOnce() -> f32, file: impl FnOnce() -> f64) -> Self;
}

impl Real for f32 {
    const NAN: f32 = f32::NAN;
    #[inline(always)]
    fn abs(self) -> f32 {
        f32::abs(self)
    }
    #[inline(always)]
    fn from_f64(x: f64) -> f32 {
        x as f32
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    #[inline(always)]
    fn pick(f32_copy: impl FnOnce() -> f32, _file: impl FnOnce() -> f64) -> f32 {
        f32_copy()
    }
}

impl Real for f64 {
    const NAN: f64 = f64::NAN;
    #[inline(always)]
    fn abs(self) -> f64 {
        f64::abs(self)
    }
    #[inline(always)]
    fn from_f64(x: f64) -> f64 {
        x
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline(always)]
    fn pick(_f32_copy: impl FnOnce() -> f32, file: impl FnOnce() -> f64) -> f64 {
        file()
    }
}

/// Barycentric interpolation of a per-vertex scalar (`value` of a vertex id) in any float
/// type: f32 for [`interpolate`], f64 for the file's f64 values. One definition, one order.
#[inline(always)]
pub fn interpolate_with<T: Real>(ids: [u32; 4], bary: [T; 4], value: impl Fn(usize) -> T) -> T {
    bary[0] * value(ids[0] as usize)
        + bary[1] * value(ids[1] as usize)
        + bary[2] * value(ids[2] as usize)
        + bary[3] * value(ids[3] as usize)
}

#[inline]
pub fn tet_bounds(ids: [u32; 4], points: &[Vec3]) -> ([f32; 3], [f32; 3]) {
    let mut lo = points[ids[0] as usize];
    let mut hi = lo;
    for &i in &ids[1..] {
        let q = points[i as usize];
        for k in 0..3 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
    }
    (lo, hi)
}

#[cfg(test)]
mod tests;
