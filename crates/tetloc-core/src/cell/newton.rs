//! The map from parametric coordinates to space, its inverse by Newton's method, and
//! interpolation: written once for every cell type.
//!
//! Like VTK's `EvaluatePosition`: start at the parametric centre, solve `x(pc) = p` with the
//! Jacobian by Cramer's rule. Unlike it, iterate to full f64 convergence (VTK stops at steps
//! below 1e-3 and then tests the domain with a 1e-3 slack) and report the failures.

use super::scalar::with_scratch;
use super::{CellDef, PCoords, Point};

/// Why the inverse map has no answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum InverseError {
    /// The Jacobian is singular (a degenerate cell, or the pyramid's apex on the way).
    #[error("the Jacobian is singular")]
    Singular,
    /// The iterates left every reasonable neighbourhood of the cell.
    #[error("Newton's method diverged")]
    Diverged,
    /// No convergence within the iteration limit.
    #[error("Newton's method did not converge in {MAX_ITERATIONS} iterations")]
    NoConvergence,
}

const MAX_ITERATIONS: usize = 50;
/// Converged when a step moves every coordinate by less than this.
const STEP_TOL: f64 = 1e-13;
/// Diverged beyond this (VTK's bound).
const DIVERGED: f64 = 1e6;

/// The point at parametric coordinates `pc` of the cell with the given nodes (in VTK order,
/// `nodes.len() == cell.n_nodes()`).
pub fn forward(cell: &dyn CellDef, nodes: &[Point], pc: PCoords) -> Point {
    with_scratch(nodes.len(), 0.0, |w| {
        cell.shape_functions(pc, w);
        combine(nodes, w)
    })
}

fn combine(nodes: &[Point], w: &[f64]) -> Point {
    let mut x = [0.0; 3];
    for (n, &wi) in nodes.iter().zip(w) {
        for k in 0..3 {
            x[k] += wi * n[k];
        }
    }
    x
}

fn det3(a: Point, b: Point, c: Point) -> f64 {
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])
}

/// The parametric coordinates of `p` in the cell with the given nodes: the solution of
/// `x(pc) = p` by Newton's method from the shape's centre, fully converged in f64. The answer
/// may lie outside the domain (then `p` is outside the cell): test it with
/// [`Shape::contains`](super::Shape::contains).
///
/// A curved cell's map can have a second preimage just outside the domain, which Newton from
/// the centre may find first (a cubic hex with nodes moved by 2 % does). So for higher-order
/// cells an answer outside the domain is tried again from the midpoints between the centre and
/// each corner, and a preimage inside wins.
///
/// To locate a higher-order cell by its corners, pass `cell.shape().linear` and the corners.
pub fn invert(cell: &dyn CellDef, nodes: &[Point], p: Point) -> Result<PCoords, InverseError> {
    let shape = cell.shape();
    let first = newton(cell, nodes, p, shape.center);
    if cell.order() == 1 || first.is_ok_and(|pc| shape.contains(pc)) {
        return first;
    }
    let inside = shape.corners.iter().find_map(|corner| {
        let start = std::array::from_fn(|k| 0.5 * (shape.center[k] + corner[k]));
        newton(cell, nodes, p, start).ok().filter(|&pc| shape.contains(pc))
    });
    inside.map_or(first, Ok)
}

/// Newton's method for `x(pc) = p` from `start`.
fn newton(cell: &dyn CellDef, nodes: &[Point], p: Point, start: PCoords) -> Result<PCoords, InverseError> {
    let n = nodes.len();
    debug_assert_eq!(n, cell.n_nodes());
    // Rounding in x(pc) is relative to the coordinates' size: a residual below it is converged.
    let scale = nodes.iter().chain([&p]).flat_map(|x| x.iter()).fold(0.0f64, |m, c| m.max(c.abs()));
    let residual_tol = 8.0 * f64::EPSILON * scale;
    with_scratch(n, 0.0, |w| {
        with_scratch(n, [0.0; 3], |d| {
            let mut pc = start;
            for _ in 0..MAX_ITERATIONS {
                cell.shape_functions(pc, w);
                cell.shape_derivatives(pc, d);
                let x = combine(nodes, w);
                let f = [x[0] - p[0], x[1] - p[1], x[2] - p[2]];
                if f.iter().all(|v| v.abs() <= residual_tol) {
                    return Ok(pc);
                }
                // Columns of the Jacobian: ∂x/∂r, ∂x/∂s, ∂x/∂t.
                let mut cols = [[0.0; 3]; 3];
                for (node, di) in nodes.iter().zip(d.iter()) {
                    for (col, &dk) in cols.iter_mut().zip(di) {
                        for c in 0..3 {
                            col[c] += dk * node[c];
                        }
                    }
                }
                let det = det3(cols[0], cols[1], cols[2]);
                if det == 0.0 || !det.is_finite() {
                    return Err(InverseError::Singular);
                }
                let step =
                    [det3(f, cols[1], cols[2]) / det, det3(cols[0], f, cols[2]) / det, det3(cols[0], cols[1], f) / det];
                for k in 0..3 {
                    pc[k] -= step[k];
                }
                if pc.iter().any(|v| v.is_nan() || v.abs() > DIVERGED) {
                    return Err(InverseError::Diverged);
                }
                if step.iter().all(|s| s.abs() < STEP_TOL) {
                    return Ok(pc);
                }
            }
            Err(InverseError::NoConvergence)
        })
    })
}

/// A per-node field at parametric coordinates `pc`: `Σ N_i(pc) · value(i)` over all the
/// cell's nodes (`value(i)` is the field at node `i` in VTK order).
pub fn interpolate(cell: &dyn CellDef, pc: PCoords, value: impl Fn(usize) -> f64) -> f64 {
    with_scratch(cell.n_nodes(), 0.0, |w| {
        cell.shape_functions(pc, w);
        w.iter().enumerate().map(|(i, wi)| wi * value(i)).sum()
    })
}
