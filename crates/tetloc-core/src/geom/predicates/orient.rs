//! orient3d and orient2d on f64 inputs, exact in sign, and the tie rule's perturbed orient3d.
//!
//! Each is staged: an f64 evaluation with a forward error bound (stage A, [`super`] derives
//! the bound) decides almost every call; only when the value is within the bound of zero is
//! the determinant summed exactly as an [`Expansion`].

use super::expansion::Expansion;
use super::{Sign, EPS64};

pub type Point = [f64; 3];

/// Stage-A error bound factor of orient3d: `|computed − exact| ≤ ORIENT3D_BOUND · permanent`
/// (derivation in [`super`]: 8 roundings per term, 9ε covers them and the bound's own).
pub const ORIENT3D_BOUND: f64 = 9.0 * EPS64;

/// Stage-A error bound factor of orient2d (4 roundings per term; 5ε).
pub const ORIENT2D_BOUND: f64 = 5.0 * EPS64;

/// orient3d(a, b, c, d) = det[a − d; b − d; c − d]: positive when d lies below the plane
/// through a, b, c (a, b, c counter-clockwise seen from above), negative above, zero on it.
/// The sign is exact; the magnitude is approximate (relative error below 1 where stage A
/// decides, a few ulps where the exact stage does).
pub fn orient3d(a: Point, b: Point, c: Point, d: Point) -> f64 {
    let (det, bound) = orient3d_stage_a(a, b, c, d);
    if det.abs() > bound {
        det
    } else {
        orient3d_exact(a, b, c, d).value()
    }
}

/// Stage A: the determinant in f64 from the differences, and its error bound.
#[inline]
pub fn orient3d_stage_a(a: Point, b: Point, c: Point, d: Point) -> (f64, f64) {
    let (det, permanent, _) = super::det_and_permanent(a, b, c, d);
    (det, ORIENT3D_BOUND * permanent)
}

/// The exact stage: det[a 1; b 1; c 1; d 1] (equal to orient3d) expanded along the column of
/// ones into four 3×3 determinants of the points themselves, `−|bcd| + |acd| − |abd| + |abc|`,
/// each the sum of six signed triple products. No differences are formed (they would round);
/// every triple product enters the expansion exactly as four components: at most 96.
pub fn orient3d_exact(a: Point, b: Point, c: Point, d: Point) -> Expansion<96> {
    let pts = [a, b, c, d];
    let mut sum = Expansion::<96>::new();
    for (omitted, rows) in [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]].iter().enumerate() {
        // Cofactor sign of the omitted row in the column of ones: −, +, −, +.
        let cofactor = if omitted % 2 == 0 { -1.0 } else { 1.0 };
        let [p, q, r] = rows.map(|i| pts[i]);
        // |pqr| = Σ over permutations σ of the axes: sgn(σ) p[σ0] q[σ1] r[σ2].
        for (sign, [i, j, k]) in PERMUTATIONS_3 {
            sum.add_triple_product(cofactor * sign, p[i], q[j], r[k]);
        }
    }
    sum
}

/// The six permutations of three axes with their signs.
const PERMUTATIONS_3: [(f64, [usize; 3]); 6] =
    [(1.0, [0, 1, 2]), (-1.0, [0, 2, 1]), (-1.0, [1, 0, 2]), (1.0, [1, 2, 0]), (1.0, [2, 0, 1]), (-1.0, [2, 1, 0])];

/// orient2d(a, b, c) = (a − c) × (b − c): positive when a, b, c turn counter-clockwise.
/// Exact in sign, like [`orient3d`].
pub fn orient2d(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    let (acx, acy) = (a[0] - c[0], a[1] - c[1]);
    let (bcx, bcy) = (b[0] - c[0], b[1] - c[1]);
    let (left, right) = (acx * bcy, acy * bcx);
    let det = left - right;
    if det.abs() > ORIENT2D_BOUND * (left.abs() + right.abs()) {
        return det;
    }
    // det[a 1; b 1; c 1] = ax·by − ax·cy − bx·ay + bx·cy + cx·ay − cx·by, exactly.
    let mut sum = Expansion::<12>::new();
    for (sign, p, q) in [(1.0, a, b), (-1.0, a, c), (-1.0, b, a), (1.0, b, c), (1.0, c, a), (-1.0, c, b)] {
        sum.add_product(sign, p[0], q[1]);
    }
    sum.value()
}

/// **The tie rule**: the sign of orient3d(a, b, c, p + (ε, ε², ε³)) for every small enough
/// ε > 0 (see [`super`]). With n = (b − a) × (c − a), orient3d(a, b, c, p) = n · (a − p), so
/// the perturbed value is `orient3d(a, b, c, p) − ε n.x − ε² n.y − ε³ n.z`: when the point is
/// exactly on the plane, the first non-zero of −n.x, −n.y, −n.z decides. Each component of n
/// is an orient2d of the face projected on the other two axes, evaluated exactly.
/// `Zero` only for a degenerate face (collinear a, b, c), which no perturbation of p resolves.
pub fn orient3d_sos(a: Point, b: Point, c: Point, p: Point) -> Sign {
    let det = orient3d(a, b, c, p);
    if det != 0.0 {
        return Sign::of(det);
    }
    // n.x on (y, z), n.y on (z, x), n.z on (x, y).
    for (u, v) in [(1, 2), (2, 0), (0, 1)] {
        let n = orient2d([a[u], a[v]], [b[u], b[v]], [c[u], c[v]]);
        if n != 0.0 {
            return Sign::of(-n);
        }
    }
    Sign::Zero
}
