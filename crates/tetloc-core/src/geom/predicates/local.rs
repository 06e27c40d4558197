//! The f32 filter for f64 data: vertices and query points stored as f32 *local* coordinates,
//! and an orient3d in f32 whose error bound covers both the f32 arithmetic and the rounding
//! of the file's f64 coordinates to the local f32 ones. Where the bound cannot decide, the
//! caller turns to [`super::orient3d_sos`] on the file's coordinates.
//!
//! # The local frame
//!
//! `local(x) = round((x − o) · s)` per axis, where `o` is the centre of the mesh's bounds,
//! `s` a power of two such that every vertex satisfies `|fl(x − o) · s| ≤ 1/4`, and `round`
//! rounds to the nearest multiple of 2⁻²⁵ (a 25-bit fixed point; such a number of magnitude
//! at most 1/2 is an f32). Query points with some `|fl(x − o) · s| > 1/2` lie outside the
//! vertices' bounding box, so outside every tet, and get no local coordinates.
//!
//! Why fixed point rather than the nearest f32: every local coordinate is a multiple of
//! q = 2⁻²⁵ and at most 1/2 in magnitude, so every nonzero difference is at least q, every
//! product of two at least q², every rounded product a multiple of q²·2⁻²³, every term of
//! the determinant at least 2⁻⁹⁸: no f32 operation of the filter underflows (nor
//! overflows), and the textbook error model `fl(x ∘ y) = (x ∘ y)(1 + θ)` holds throughout. The
//! rounding error is the same for every coordinate: with the nearest f32 it would be as
//! large at the edge of the box anyway.
//!
//! **Rounding of the inputs.** The true local coordinate is `X = (x − o) · s` (real
//! arithmetic: orient3d's sign on X equals its sign on the file's x, the map being a
//! translation and a positive scaling). The stored one differs by at most
//! `δ₀ = 2⁻²⁶` (the fixed-point rounding) `+ 2⁻⁵²` (the f64 subtraction, in any rounding
//! mode, as `|X| < 1`; the scaling is exact) — for vertices and query points alike, so there
//! is nothing to measure per mesh or per point. Each row `v − p` of the determinant is then
//! off by `η` with `|η_k| ≤ Δ = 2δ₀ = 2⁻²⁵ + 2⁻⁵¹` per coordinate.
//!
//! # The bound
//!
//! Let `α` be the exact differences of the stored f32 inputs, `D̂ = det α` (exact), `D` the
//! exact determinant of the true local coordinates, `det` the f32 result and ε = 2⁻²³ (f32
//! machine epsilon: any correctly rounded mode, round-to-nearest or toward zero,
//! has `|fl(x) − x| ≤ ε|x|`). Then `|det − D| ≤ |det − D̂| + |D̂ − D|`:
//!
//! 1. **Arithmetic.** Each of the six terms `α·α·α` of `D̂` passes through at most 8
//!    roundings in `det` (3 differences, the 2×2 product, its subtraction, the product with
//!    the third difference, 2 sums), so `|det − D̂| ≤ ((1+ε)⁸ − 1)·P` with `P` the exact
//!    permanent `Σ|α·α·α|`. The computed permanent has the same 8 roundings per term, each
//!    at least `(1 − ε)`, so `P ≤ P̂ / (1−ε)⁸`. With `C₁ = 9ε`: `C₁(1−ε)¹⁰ ≥ (1+ε)⁸ − 1` (as
//!    `113ε ≤ 1`), which also pays for rounding `C₁·P̂` and the final sum of the bound.
//! 2. **Inputs.** `D = det(α − η)` is trilinear in the rows: expanding, the terms with one
//!    row of η are `|η · (y × z)| ≤ Δ‖y‖₁‖z‖₁`, with two rows `≤ 2Δ²‖z‖₁`, with three
//!    `≤ 6Δ³`. With `m_i = ‖α_i‖₁`: `|D̂ − D| ≤ Δ(m_a m_b + m_b m_c + m_c m_a) + 2Δ²(m_a +
//!    m_b + m_c) + 6Δ³ ≤ Δ · Σ_{i<j} (m_i + 2Δ)(m_j + 2Δ)`. Computed in f32 from the
//!    computed differences this takes at most 13 roundings (3 for each `m̂_i`, which is
//!    at least `(1−ε)³ m_i`, then `+ 2Δ`, the product, 2 sums, `· Δ`, and the final sum of
//!    the bound), so the constant used is `Δ' = Δ(1 + 2⁻¹⁹) ≥ Δ/(1−ε)¹³`:
//!    [`FILTER_DELTA`] = 2⁻²⁵(1 + 2⁻¹⁸) ≥ (2⁻²⁵ + 2⁻⁵¹)(1 + 2⁻¹⁹).
//!
//! So `bound = C₁·P̂ + Δ'·Σ_{i<j}(m̂_i + 2Δ')(m̂_j + 2Δ')`, computed in f32, satisfies
//! `|det − D| ≤ bound`, and `|det| > bound` proves `sign(det) = sign(D)`. Property tests
//! check both claims with rational arithmetic on adversarial inputs.
//!
//! The input term is of order Δ·L² for a tet of size L, the arithmetic one ε·L³: with local
//! units, a point is decided by f32 unless it is within about `4Δ·L²/|n|`, a few 2⁻²⁵ of the
//! box size, of a face plane, or the tet is a sliver.

use super::EPS32;

pub type Vec3 = [f32; 3];

/// Steps of the local fixed point per local unit, 2²⁵, and the step, 2⁻²⁵ (multiplications by
/// either are exact).
const STEPS: f64 = 33_554_432.0;
const QUANTUM: f64 = 1.0 / STEPS;

/// Δ' of the derivation above: per-coordinate bound on the rounding of `vertex − point` in
/// local units (both rounded by at most 2⁻²⁶ + 2⁻⁵³), with the slack that pays for the
/// bound's own f32 evaluation. Exactly 2⁻²⁵ · (1 + 2⁻¹⁸).
pub const FILTER_DELTA: f32 = (1.0 + 1.0 / 262_144.0) / 33_554_432.0;

/// C₁ of the derivation above: 9ε for the f32 arithmetic.
pub const LOCAL_ORIENT_BOUND: f32 = 9.0 * EPS32;

/// The map from the file's f64 coordinates to f32 local ones: `round((x − origin) · scale)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalFrame {
    pub origin: [f64; 3],
    /// A power of two.
    pub scale: f64,
}

impl LocalFrame {
    /// The frame of a set of vertices: the centre of their bounds, and the largest scale
    /// that maps them into [−1/4, 1/4]. `None` for no vertices, or a coordinate outside
    /// [`super::in_domain`].
    pub fn for_vertices(vertices: &[[f64; 3]]) -> Option<Self> {
        if !vertices.iter().flatten().all(|&x| super::in_domain(x)) {
            return None;
        }
        let first = *vertices.first()?;
        let (mut lo, mut hi) = (first, first);
        for v in vertices {
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
        let origin: [f64; 3] = std::array::from_fn(|k| lo[k] + 0.5 * (hi[k] - lo[k]));
        let radius = vertices.iter().flat_map(|v| (0..3).map(move |k| (v[k] - origin[k]).abs())).fold(0.0, f64::max);
        // Halving and doubling are exact: `radius * scale` below is what `to_local` computes.
        let mut scale = 1.0f64;
        while radius * scale > 0.25 {
            scale *= 0.5;
        }
        while radius > 0.0 && radius * scale <= 0.125 {
            scale *= 2.0;
        }
        Some(LocalFrame { origin, scale })
    }

    /// The local f32 coordinates of `x`, or `None` when `x` is outside the box
    /// `|fl(x − origin) · scale| ≤ 1/2` (and so outside every tet of the mesh: the vertices
    /// lie within 1/4 of the origin in local units).
    pub fn to_local(&self, x: [f64; 3]) -> Option<Vec3> {
        let mut local = [0f32; 3];
        for k in 0..3 {
            let y = (x[k] - self.origin[k]) * self.scale;
            if y.is_nan() || y.abs() > 0.5 {
                return None;
            }
            // An integer of magnitude ≤ 2²⁴ times 2⁻²⁵: the conversion to f32 is exact.
            local[k] = ((y * STEPS).round_ties_even() * QUANTUM) as f32;
        }
        Some(local)
    }
}

/// orient3d(a, b, c, p) (see [`super::orient3d`]) on local coordinates, in f32, with the bound
/// derived above: when `|det| > bound`, `det` has the sign of orient3d on the file's f64
/// coordinates of the same four points. `delta` is Δ': [`FILTER_DELTA`] for coordinates
/// from [`LocalFrame::to_local`], 0 for inputs that are the exact points (fixed-point
/// numbers of the local grid).
#[inline(always)]
pub fn orient3d_local(a: Vec3, b: Vec3, c: Vec3, p: Vec3, delta: f32) -> (f32, f32) {
    let (det, permanent, [[adx, ady, adz], [bdx, bdy, bdz], [cdx, cdy, cdz]]) = super::det_and_permanent(a, b, c, p);
    // Row norms, widened by the rounding of the inputs.
    let two_delta = 2.0 * delta;
    let ma = adx.abs() + ady.abs() + adz.abs() + two_delta;
    let mb = bdx.abs() + bdy.abs() + bdz.abs() + two_delta;
    let mc = cdx.abs() + cdy.abs() + cdz.abs() + two_delta;
    let inputs = delta * (ma * mb + mb * mc + mc * ma);
    (det, LOCAL_ORIENT_BOUND * permanent + inputs)
}
