//! One tet's barycentric coordinates as an affine map of the point, in f64, with a static
//! forward-error bound: a filter in front of the exact test (`geom::test_point_with`).
//!
//! λ_k(p) = ∇λ_k · (p − v₀) for the stored vertices 1..3 and λ₀ = 1 − λ₁ − λ₂ − λ₃, where
//! ∇λ₁ = (e₂ × e₃)/det, ∇λ₂ = (e₃ × e₁)/det, ∇λ₃ = (e₁ × e₂)/det, eₖ = vₖ − v₀ and
//! det = e₁ · (e₂ × e₃). Along a grid row (y, z fixed) each λ is affine in x: one multiply and
//! one add a coordinate once the row's part is known ([`TetMap::row`]).
//!
//! **The bound.** With u = f64::EPSILON (twice the unit roundoff, for margin), every eₖ
//! component carries a relative error u, each cross-product component c = ab − cd an
//! absolute error ≤ 4u(|ab| + |cd|) =: 4u·P_c, det an error ≤ 8u·P_det with
//! P_det = Σ|e₁ᵢ|·P_c₁ᵢ, so with ρ = P_det/det each gradient component g = c/det is off by
//! ≤ (5 + 9ρ)u·M, M = P_c/det (≥ |g|) (one u of it for multiplying by the rounded 1/det).
//! Evaluating Σⱼ gⱼ(pⱼ − v₀ⱼ) adds u|q| for the difference q and 5u for the products and sums
//! (the row form's extra term g_x·(x − x₀) counts the x reach twice):
//! |λ̂ₖ − λₖ| ≤ (11 + 9ρ)u·Sₖ, Sₖ = Mₖₓ·2reachₓ + Mₖ_y·reach_y + Mₖ_z·reach_z,
//! for every point within `reach` of v₀ on each axis (ρ ≥ 1 absorbs the constants); λ₀ adds
//! its three terms and 3u(1 + ΣSₖ).
//! Twice that covers the second-order terms. One more term covers the exact test's own f32
//! path (`geom::test_point`), whose last resort `orient_f64` is not exact: its sign is right
//! whenever |det·λₖ| exceeds Shewchuk's (7 + 56u)u times a permanent of at most 6H³ (H the
//! largest reach). A point whose every λ̂ exceeds the bound is strictly inside for the exact
//! test too (every weight positive); one with a λ̂ below minus the bound is outside; the rest
//! (within the bound of a face) take the exact test and the tie rule.
//!
//! **A row's part.** Along a row each λ̂ₖ is base + slope·(x − x₀), so the x where it falls
//! below −bound is one multiply by the precomputed 1/slope, and across rows and planes that x
//! moves linearly with y and z ([`TetMap::parts`]: two multiply-adds a weight a row, one of
//! them once a plane). Rounding moves that crossing, and the evaluation's λ̂, by at most 16u·S
//! in λ (S = 1 + Σ|base| + Σ|slope|·2reach on each axis bounds every term the forms add) and
//! by a few u of the x terms' sizes; the part is widened by 1e-9 of S/|slope| plus those
//! sizes, so every point left out of it has some λ̂ below −bound: the map would call it
//! outside.

/// f64's machine epsilon (2⁻⁵², twice the unit roundoff).
const U: f64 = f64::EPSILON;
/// A tet whose volume is this ill-conditioned (ρ·u above it) gets no map: its points all
/// take the exact test.
const MAX_RHO_U: f64 = 1e-6;
/// The smallest bound: a weight above it stays nonzero in f32 (the exact test's weights are
/// f32, where 1e-45 is the smallest).
const MIN_BOUND: f64 = 1e-30;

/// What the map says of a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Side {
    /// Strictly inside (every weight positive for the exact test), with these weights.
    Inside([f64; 4]),
    /// Outside (some weight negative for the exact test).
    Outside,
    /// Within the bound of a face: the exact test decides.
    Near,
}

/// One tet's barycentric map (see the module documentation).
#[derive(Clone, Copy, Debug)]
pub(super) struct TetMap {
    origin: [f64; 3],
    /// ∇λ₁, ∇λ₂, ∇λ₃.
    grad: [[f64; 3]; 3],
    bound: f64,
    /// Along a row (x): 1/slope of λ₀..λ₃ (0 for a slope of 0: that weight bounds no part
    /// of a row), Σ|slope|, and the x reach of the row form (twice the box's).
    inv_slope: [f64; 4],
    slope_sum: f64,
    row_reach: f64,
    /// The box's reach on each axis.
    reach: [f64; 3],
}

/// The parts of a box's rows: for each weight with a slope along rows, the x where it
/// reaches −bound (widened) on the corner's row, how it moves with the row's y and the
/// plane's z, and whether it bounds the part from below (1) or above (−1).
#[derive(Clone, Copy, Debug)]
pub(super) struct TetParts {
    y: f64,
    z: f64,
    ends: [(f64, f64, f64, i8); 4],
}

impl TetParts {
    /// The parts of plane z's rows.
    #[inline]
    pub(super) fn plane(&self, z: f64) -> PlaneParts {
        let dz = z - self.z;
        PlaneParts { y: self.y, ends: self.ends.map(|(at, per_y, per_z, side)| (at + per_z * dz, per_y, side)) }
    }
}

/// The parts of one plane's rows: [`TetParts`] at the plane's z.
#[derive(Clone, Copy, Debug)]
pub(super) struct PlaneParts {
    y: f64,
    ends: [(f64, f64, i8); 4],
}

impl PlaneParts {
    /// The part of the row at `y` where the map may call a point inside or near a face, as
    /// (x₀, x₁); `None` if empty. Every point left out has some λ̂ below −bound (see the
    /// module documentation): a filter that changes no answer.
    #[inline]
    pub(super) fn row(&self, y: f64) -> Option<(f64, f64)> {
        let dy = y - self.y;
        let (mut x0, mut x1) = (f64::NEG_INFINITY, f64::INFINITY);
        for &(at, per_y, side) in &self.ends {
            // (NaN from an overflow leaves the part as it is: max and min.)
            let x = at + per_y * dy;
            if side > 0 {
                x0 = x0.max(x);
            } else if side < 0 {
                x1 = x1.min(x);
            }
        }
        (x0 <= x1).then_some((x0, x1))
    }
}

/// A map restricted to one row (y, z fixed): λₖ = base[k] + slope[k]·(x − x₀).
#[derive(Clone, Copy, Debug)]
pub(super) struct RowMap {
    x0: f64,
    base: [f64; 3],
    slope: [f64; 3],
    bound: f64,
}

impl TetMap {
    /// The map of the tet with stored vertices `v` (file coordinates, canonical order),
    /// valid for points within `reach` of `v[0]` on each axis (for the points of the tet's
    /// box: the box's extent), its bound multiplied by `bound_scale` (1 but in tests).
    /// `None` for a flat or badly conditioned tet.
    fn new(v: [[f64; 3]; 4], reach: [f64; 3], bound_scale: f64) -> Option<TetMap> {
        let e: [[f64; 3]; 3] = std::array::from_fn(|k| std::array::from_fn(|j| v[k + 1][j] - v[0][j]));
        // Cross products with their permanents: (value, |ab| + |cd|) per component.
        let cross = |a: [f64; 3], b: [f64; 3]| -> [(f64, f64); 3] {
            std::array::from_fn(|i| {
                let (j, k) = ((i + 1) % 3, (i + 2) % 3);
                let (p, q) = (a[j] * b[k], a[k] * b[j]);
                (p - q, p.abs() + q.abs())
            })
        };
        let c = [cross(e[1], e[2]), cross(e[2], e[0]), cross(e[0], e[1])];
        let det: f64 = (0..3).map(|i| e[0][i] * c[0][i].0).sum();
        let p_det: f64 = (0..3).map(|i| e[0][i].abs() * c[0][i].1).sum();
        let rho = p_det / det;
        if !(det > 0.0 && det.is_finite() && rho * U <= MAX_RHO_U) {
            return None;
        }
        // One division: the bound's (5 + 9ρ) counts the product's extra rounding.
        let inv_det = 1.0 / det;
        let grad = c.map(|ck| ck.map(|(x, _)| x * inv_det));
        // The row form evaluates g_x twice: at the row's start and along it.
        let reach2 = [2.0 * reach[0], reach[1], reach[2]];
        let s = c.map(|ck| (0..3).map(|j| ck[j].1 * reach2[j]).sum::<f64>() * inv_det);
        let e_k = s.map(|sk| (11.0 + 9.0 * rho) * U * sk);
        let e_0 = e_k.iter().sum::<f64>() + 3.0 * U * (1.0 + s.iter().sum::<f64>());
        let h = reach.iter().fold(0.0f64, |a, &b| a.max(b));
        let f32_path = 8.0 * U * 6.0 * h * h * h * inv_det;
        let bound = 2.0 * e_k.iter().fold(e_0, |a, &b| a.max(b)) + f32_path;
        let slope = [-(grad[0][0] + grad[1][0] + grad[2][0]), grad[0][0], grad[1][0], grad[2][0]];
        Some(TetMap {
            origin: v[0],
            grad,
            bound: (bound * bound_scale).max(MIN_BOUND * bound_scale),
            inv_slope: slope.map(|x| if x != 0.0 { 1.0 / x } else { 0.0 }),
            slope_sum: slope.iter().map(|x| x.abs()).sum(),
            row_reach: reach2[0],
            reach,
        })
    }

    /// The map of the tet with vertices `v` over its own box `(lo, hi)` ([`bounds_of`]): its
    /// points are within the box's extent of any vertex on each axis.
    #[inline]
    pub(super) fn over_box(v: [[f64; 3]; 4], (lo, hi): ([f64; 3], [f64; 3]), bound_scale: f64) -> Option<TetMap> {
        TetMap::new(v, std::array::from_fn(|k| hi[k] - lo[k]), bound_scale)
    }

    /// The parts of the rows of the box whose corner is (x, y, z) (its lowest grid point on
    /// each axis, within this map's reach): asked plane by plane ([`TetParts::plane`]),
    /// then row by row ([`PlaneParts::row`]).
    #[inline]
    pub(super) fn parts(&self, x: f64, y: f64, z: f64) -> TetParts {
        self.parts_widened(x, y, z, 1e-9)
    }

    /// [`Self::parts`] widened by `widen` (1e-9 but in the test that shows less fails).
    fn parts_widened(&self, x: f64, y: f64, z: f64, widen: f64) -> TetParts {
        let b = self.row(x, y, z).base;
        let base = [1.0 - b[0] - b[1] - b[2], b[0], b[1], b[2]];
        let g = &self.grad;
        let slope_along = |c: usize| [-(g[0][c] + g[1][c] + g[2][c]), g[0][c], g[1][c], g[2][c]];
        let (y_slope, z_slope) = (slope_along(1), slope_along(2));
        // Twice the reach across rows and planes: points on either side of the corner.
        let (y_reach, z_reach) = (2.0 * self.reach[1], 2.0 * self.reach[2]);
        let sum = |v: [f64; 4]| v.iter().map(|x| x.abs()).sum::<f64>();
        let s = 1.0 + sum(base) + self.slope_sum * self.row_reach + sum(y_slope) * y_reach + sum(z_slope) * z_reach;
        let mut parts = TetParts { y, z, ends: [(0.0, 0.0, 0.0, 0); 4] };
        for (k, end) in parts.ends.iter_mut().enumerate() {
            let inv = self.inv_slope[k];
            // Where λₖ = −bound on the corner's row, and how that moves across rows and planes.
            let cross = x + (-self.bound - base[k]) * inv;
            let (per_y, per_z) = (-y_slope[k] * inv, -z_slope[k] * inv);
            let size = s * inv.abs() + x.abs() + cross.abs() + per_y.abs() * y_reach + per_z.abs() * z_reach;
            let w = widen * (size + self.row_reach);
            *end = match inv.partial_cmp(&0.0) {
                Some(std::cmp::Ordering::Greater) => (cross - w, per_y, per_z, 1),
                Some(std::cmp::Ordering::Less) => (cross + w, per_y, per_z, -1),
                _ => (0.0, 0.0, 0.0, 0),
            };
        }
        parts
    }

    /// The map along the row at (y, z), from `x0`.
    #[inline]
    pub(super) fn row(&self, x0: f64, y: f64, z: f64) -> RowMap {
        let q = [x0 - self.origin[0], y - self.origin[1], z - self.origin[2]];
        RowMap {
            x0,
            base: self.grad.map(|g| g[0] * q[0] + g[1] * q[1] + g[2] * q[2]),
            slope: self.grad.map(|g| g[0]),
            bound: self.bound,
        }
    }

    /// The weights at `p`, classified: the row form from `p` itself (`x − x₀` = 0), so the
    /// same bound holds for a point within `reach` of `v[0]`.
    #[inline]
    pub(super) fn at(&self, p: [f64; 3]) -> Side {
        let q = [p[0] - self.origin[0], p[1] - self.origin[1], p[2] - self.origin[2]];
        classify(self.grad.map(|g| g[0] * q[0] + g[1] * q[1] + g[2] * q[2]), self.bound)
    }
}

/// The box of a tet's vertices.
pub(super) fn bounds_of(v: &[[f64; 3]; 4]) -> ([f64; 3], [f64; 3]) {
    let lo = std::array::from_fn(|k| v.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min));
    let hi = std::array::from_fn(|k| v.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max));
    (lo, hi)
}

/// λ₁..λ₃ (λ₀ from them) against the bound.
#[inline]
fn classify(l: [f64; 3], bound: f64) -> Side {
    let w = [1.0 - l[0] - l[1] - l[2], l[0], l[1], l[2]];
    if w.iter().all(|&x| x > bound) {
        Side::Inside(w)
    } else if w.iter().any(|&x| x < -bound) {
        Side::Outside
    } else {
        Side::Near
    }
}

impl RowMap {
    /// The weights of the row's point at `x`, classified.
    #[inline]
    pub(super) fn at(&self, x: f64) -> Side {
        let dx = x - self.x0;
        classify(std::array::from_fn(|k| self.base[k] + self.slope[k] * dx), self.bound)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{self, predicates::Query, TetTest};
    use crate::mesh::Mesh;
    use rand::{Rng, SeedableRng};

    /// On every tet of a jittered grid (some folded into slivers) and points of its box,
    /// points near its faces and its vertices: what the map decides, the exact test says
    /// (inside with every weight positive, or outside), and the map's weights are the exact
    /// test's to 1e-6.
    #[test]
    fn the_map_decides_as_the_exact_test() {
        let mesh = Mesh::new(crate::test_support::jittered_grid(4, 0.35, 3), "jittered").unwrap();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
        let (mut decided, mut near) = (0, 0);
        for (t, &tet) in mesh.tets.iter().enumerate() {
            let v = tet.map(|i| mesh.vertex64(i));
            let (lo, hi) = bounds_of(&v);
            let Some(map) = TetMap::over_box(v, (lo, hi), 1.0) else { continue };
            let mut points: Vec<[f64; 3]> =
                (0..200).map(|_| std::array::from_fn(|k| rng.gen_range(lo[k]..=hi[k]))).collect();
            // Points on edges and faces (rounded to f32: a hair either side).
            for _ in 0..50 {
                let (a, b, c) = (rng.gen_range(0..4), rng.gen_range(0..4), rng.gen_range(0f64..1.0));
                let s = rng.gen_range(0f64..1.0);
                points.push(std::array::from_fn(|k| {
                    let e = v[a][k] + c * (v[b][k] - v[a][k]);
                    e + s * (v[(a + 1) % 4][k] - e)
                }));
            }
            points.extend(v);
            for p in points {
                let p = p.map(|c| c as f32 as f64);
                let q = Query { local: mesh.info.frame.to_working_f32(p.map(|c| c as f32)), file: p };
                let test = geom::test_point_with(tet, &mesh.points, &mesh.exact(), &q);
                match (map.at(p), test) {
                    (Side::Inside(w), TetTest::Inside(b)) => {
                        assert!(!b.contains(&0.0), "tet {t} {p:?}: {b:?}");
                        for (x, y) in w.iter().zip(b) {
                            assert!((*x as f32 - y).abs() <= 1e-6, "tet {t} {p:?}: {w:?} {b:?}");
                        }
                        decided += 1;
                    }
                    (Side::Outside, TetTest::Outside { .. }) => decided += 1,
                    (Side::Near, _) => near += 1,
                    (side, test) => panic!("tet {t} {p:?}: the map says {side:?}, the test {test:?}"),
                }
            }
        }
        // (A fifth of the points are built on edges and faces.)
        assert!(decided > 10 * near, "{decided} decided, {near} near");
    }

    /// A row's part leaves out only points the map calls outside: on the rows of planes
    /// through jittered tets (slivers among them) scaled by 1e-6 and 1e6 and moved 1e7 away,
    /// at the computed ends of each weight's part and the few f64s either side. Without the
    /// widening some point left out is one the map does not call outside.
    #[test]
    fn a_rows_part_leaves_out_only_what_the_map_calls_outside() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(4);
        let base = Mesh::new(crate::test_support::jittered_grid(4, 0.35, 5), "jittered").unwrap();
        let (mut checked, mut unwidened_wrong) = (0, 0);
        for (scale, shift) in [(1.0, 0.0), (1e-6, 0.0), (1e6, 0.0), (1.0, 1e7), (1e-3, -1e7)] {
            for &tet in base.tets.iter() {
                let v = tet.map(|i| base.vertex64(i).map(|c| c * scale + shift));
                let (lo, hi) = bounds_of(&v);
                let Some(map) = TetMap::over_box(v, (lo, hi), 1.0) else { continue };
                for _ in 0..8 {
                    let (y, z) = (rng.gen_range(lo[1]..=hi[1]), rng.gen_range(lo[2]..=hi[2]));
                    let row = map.row(lo[0], y, z);
                    let part = map.parts(lo[0], lo[1], lo[2]).plane(z).row(y);
                    let tight = map.parts_widened(lo[0], lo[1], lo[2], 0.0).plane(z).row(y);
                    // The ends of the unwidened part and the f64s around them, inside the box.
                    let mut xs = Vec::new();
                    for end in tight.into_iter().flat_map(|(a, b)| [a, b]) {
                        let mut x = end;
                        for _ in 0..6 {
                            x = x.next_down();
                        }
                        for _ in 0..12 {
                            xs.push(x);
                            x = x.next_up();
                        }
                    }
                    for x in xs.into_iter().filter(|x| (lo[0]..=hi[0]).contains(x)) {
                        let outside = row.at(x) == Side::Outside;
                        let left_out = |p: Option<(f64, f64)>| p.is_none_or(|(a, b)| x < a || x > b);
                        assert!(!left_out(part) || outside, "{v:?} row ({y}, {z}) x {x}: {:?}", row.at(x));
                        unwidened_wrong += usize::from(left_out(tight) && !outside);
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 10_000, "{checked} points");
        assert!(unwidened_wrong > 0, "the unwidened part left out only outside points ({checked})");
    }
}
