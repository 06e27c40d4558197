//! Shape functions are written once, generic over [`Scalar`]: evaluated on `f64` they give the
//! weights, on [`Dual`] (forward-mode differentiation) their derivatives. So a cell's
//! derivatives can never disagree with its functions.

use super::PCoords;
use std::ops::{Add, Mul, Neg, Sub};

/// What shape functions compute with: `f64`, or [`Dual`] for derivatives.
pub(crate) trait Scalar:
    Copy
    + From<f64>
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Mul<f64, Output = Self>
    + Neg<Output = Self>
{
}

impl Scalar for f64 {}

/// A value with its gradient with respect to the parametric coordinates (r, s, t).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Dual {
    pub v: f64,
    pub d: [f64; 3],
}

impl Scalar for Dual {}

impl From<f64> for Dual {
    fn from(v: f64) -> Dual {
        Dual { v, d: [0.0; 3] }
    }
}

impl Add for Dual {
    type Output = Dual;
    fn add(self, o: Dual) -> Dual {
        Dual { v: self.v + o.v, d: [self.d[0] + o.d[0], self.d[1] + o.d[1], self.d[2] + o.d[2]] }
    }
}

impl Sub for Dual {
    type Output = Dual;
    fn sub(self, o: Dual) -> Dual {
        Dual { v: self.v - o.v, d: [self.d[0] - o.d[0], self.d[1] - o.d[1], self.d[2] - o.d[2]] }
    }
}

impl Mul for Dual {
    type Output = Dual;
    // The product rule: (u·v)' = u'·v + u·v'.
    #[allow(clippy::suspicious_arithmetic_impl)]
    fn mul(self, o: Dual) -> Dual {
        Dual { v: self.v * o.v, d: std::array::from_fn(|k| self.d[k] * o.v + self.v * o.d[k]) }
    }
}

impl Mul<f64> for Dual {
    type Output = Dual;
    fn mul(self, c: f64) -> Dual {
        Dual { v: self.v * c, d: self.d.map(|x| x * c) }
    }
}

impl Neg for Dual {
    type Output = Dual;
    fn neg(self) -> Dual {
        Dual { v: -self.v, d: self.d.map(|x| -x) }
    }
}

/// Runs `f` with scratch space for `n` values: on the stack for the cells of up to 27 nodes.
pub(crate) fn with_scratch<T: Copy, R>(n: usize, zero: T, f: impl FnOnce(&mut [T]) -> R) -> R {
    if n <= 27 {
        let mut buf = [zero; 27];
        f(&mut buf[..n])
    } else {
        f(&mut vec![zero; n])
    }
}

/// The derivatives of the functions that `functions` computes, at `pc`: `d[i][k] = ∂N_i/∂pc_k`.
pub(crate) fn derivatives(pc: PCoords, d: &mut [[f64; 3]], functions: impl FnOnce([Dual; 3], &mut [Dual])) {
    let var = |k: usize| {
        let mut d = [0.0; 3];
        d[k] = 1.0;
        Dual { v: pc[k], d }
    };
    with_scratch(d.len(), Dual::from(0.0), |w| {
        functions([var(0), var(1), var(2)], w);
        for (di, wi) in d.iter_mut().zip(w.iter()) {
            *di = wi.d;
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dual_numbers_differentiate_products() {
        // f = r·s² − 3t at (2, 3, 5): ∇f = (s², 2rs, −3) = (9, 12, −3).
        let mut d = [[0.0; 3]];
        derivatives([2.0, 3.0, 5.0], &mut d, |[r, s, t], w| w[0] = r * s * s - t * 3.0);
        assert_eq!(d[0], [9.0, 12.0, -3.0]);
        let x = Dual::from(4.0);
        assert_eq!((-x * 0.5).v, -2.0);
    }
}
