//! Exact geometric predicates on the file's f64 coordinates, and **the tie rule**.
//!
//! Which tet holds a point is decided by signs of orient3d: on which side of each face
//! plane the point lies. Here those signs are exact for f64 inputs, computed in stages,
//! each taken only when the one before cannot decide:
//!
//! 1. [`local`]: f32 on *local* coordinates (a fixed-point f32 copy of the vertices and the
//!    point, relative to the mesh's centre), with an error bound that covers both the f32
//!    arithmetic and the rounding of the f64 coordinates to local f32. The hot path.
//! 2. [`orient`]: f64 on the file's coordinates with Shewchuk-style stage-A bound.
//! 3. [`expansion`]: the exact value as a sum of f64 components (two-sum, Dekker's
//!    two-product with Veltkamp splitting: no FMA).
//! 4. The tie rule below, when the exact value is zero.
//!
//! The kernels run only the f32 filter of these predicates (tet.glsl `tl_orient3d_local`);
//! what it cannot decide the host decides with these (`locate::certify`).
//!
//! # The tie rule
//!
//! **A point p belongs to the tet that p + (ε, ε², ε³) lies in, for every small enough
//! ε > 0** (Simulation of Simplicity with one fixed perturbation of the query point; the
//! vertices are not perturbed). Face by face: when orient3d(a, b, c, p) is exactly zero, it
//! takes the sign of −n.x, or if n.x = 0 of −n.y, or if that is 0 too of −n.z, where
//! n = (b − a) × (c − a) is the face normal, each component an exact orient2d
//! ([`orient3d_sos`]). Consequences:
//!
//! - **A partition.** The perturbed point lies on no face plane (every non-degenerate face
//!   has a non-zero normal component), so in a conforming mesh it is in the interior of
//!   exactly one tet, or outside: every point of the mesh's interior belongs to exactly one
//!   tet, and none to two. A point on a shared face goes to the tet on the +x side of the
//!   face (+y for faces parallel to x, +z for faces normal to z); on edges and vertices
//!   likewise, to the tet the perturbation moves it into.
//! - **Every kernel the same id.** The rule is geometric: it depends neither on the order
//!   in which a tet lists its vertices, nor on ids, nor on which tets were tested first.
//! - **Boundary points** are inside or outside by the same rule: a boundary point is
//!   claimed (by exactly one tet) when the perturbation points into the mesh, otherwise by
//!   none. For an axis-aligned box mesh [lo, hi]³ this is the half-open box [lo, hi)³: the
//!   faces at lo belong to the mesh, those at hi do not.
//! - **Degenerate tets contain nothing**: a tet of exactly zero volume (exact orient3d of
//!   its vertices) claims no point, and [`tet`]'s test says so without a volume check.
//! - **Walks** get a definite exit face: no face of a non-degenerate tet ties.
//!
//! # Domain
//!
//! Every coordinate (vertices and query points) must be finite with `|x|` zero or in
//! [2⁻²⁴⁰, 2²⁴⁰] ([`in_domain`]). Then each is a multiple of 2⁻²⁹², and every value that
//! any stage forms is zero or of magnitude in [2⁻⁹⁷⁷, 2⁷³⁰] (the smallest: a stage-A bound,
//! 9ε times a triple product of differences, each rounded product a multiple of its ulp):
//! no stage underflows or overflows, so the error-free transformations are exact and the
//! error bounds hold (and GPUs that flush denormals give the same answers). Other
//! coordinates must be rejected as input errors before they reach these predicates.
//!
//! # Rounding
//!
//! The error bounds use ε = the machine epsilon (2⁻⁵² for f64, 2⁻²³ for f32), twice the unit
//! roundoff, so they hold in any correctly rounded mode (Vulkan leaves the mode to the
//! device unless a shader asks for one). The exact stage needs round-to-nearest: Rust's f64
//! always is; shaders must declare `RoundingModeRTE` for 64-bit floats.
//!
//! # Stage-A bound (f64)
//!
//! orient3d's six terms `α·α·α` (α a coordinate difference) each pass through at most 8
//! roundings (3 differences, the 2×2 product, its subtraction, the product with the third
//! difference, 2 sums), so `|det − D| ≤ ((1+ε)⁸ − 1) · P` with P the exact permanent; the
//! computed permanent is at least `(1−ε)⁸ P`; `9ε` covers both and the rounding of the bound
//! itself (`9ε(1−ε)⁹ ≥ (1+ε)⁸ − 1` as `113ε ≤ 1`). orient2d: 4 roundings per term, `5ε`.
//! [`local`] derives the f32 filter's bound the same way.

pub mod expansion;
pub mod local;
pub mod orient;
pub mod tet;

#[cfg(test)]
pub(crate) mod reference;
#[cfg(test)]
mod tests;

pub use local::{orient3d_local, LocalFrame, FILTER_DELTA};

/// orient3d's first stage in either precision: the 3×3 determinant of the rows a − d, b − d,
/// c − d, its permanent (the sum of its products' magnitudes, which the error bounds scale)
/// and the rows. The f64 filter ([`orient::orient3d_stage_a`]) and the f32 one on local
/// coordinates ([`orient3d_local`]) share it: one order of operations.
#[inline(always)]
pub(crate) fn det_and_permanent<T: crate::geom::Real>(
    a: [T; 3],
    b: [T; 3],
    c: [T; 3],
    d: [T; 3],
) -> (T, T, [[T; 3]; 3]) {
    let rows @ [[adx, ady, adz], [bdx, bdy, bdz], [cdx, cdy, cdz]] =
        [a, b, c].map(|u| [u[0] - d[0], u[1] - d[1], u[2] - d[2]]);
    let (bc, cb) = (bdy * cdz, cdy * bdz);
    let (ca, ac) = (cdy * adz, ady * cdz);
    let (ab, ba) = (ady * bdz, bdy * adz);
    let det = adx * (bc - cb) + bdx * (ca - ac) + cdx * (ab - ba);
    let permanent =
        (bc.abs() + cb.abs()) * adx.abs() + (ca.abs() + ac.abs()) * bdx.abs() + (ab.abs() + ba.abs()) * cdx.abs();
    (det, permanent, rows)
}
pub use orient::{orient2d, orient3d, orient3d_sos};
pub use tet::{barycentrics, side_of_tet, side_of_tet_staged, test_point_exact, ExactTest, Query, Side, FACES};

/// ε for f64 bounds: the machine epsilon 2⁻⁵² (see "Rounding" above).
pub const EPS64: f64 = f64::EPSILON;
/// ε for f32 bounds: 2⁻²³.
pub const EPS32: f32 = f32::EPSILON;

/// True when `x` may be a coordinate of a vertex or query point (see "Domain" above).
pub fn in_domain(x: f64) -> bool {
    const LO: f64 = 5.659799424266695e-73; // 2⁻²⁴⁰
    const HI: f64 = 1.7668470647783843e72; // 2²⁴⁰
    x == 0.0 || (LO..=HI).contains(&x.abs())
}

/// The sign of a predicate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sign {
    Negative,
    Zero,
    Positive,
}

impl Sign {
    pub fn of(x: f64) -> Sign {
        if x > 0.0 {
            Sign::Positive
        } else if x < 0.0 {
            Sign::Negative
        } else {
            Sign::Zero
        }
    }
}
