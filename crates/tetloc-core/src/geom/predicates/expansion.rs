//! Exact f64 arithmetic on *expansions*: a number held as a sum of f64 components whose
//! significant bits do not overlap (Shewchuk, "Adaptive Precision Floating-Point Arithmetic
//! and Fast Robust Geometric Predicates", 1997, sections 2.4–2.6).
//!
//! Only three error-free transformations are used, each exact under round-to-nearest and
//! without underflow or overflow (the domain of [`super`]): the sum of two f64 (Knuth's
//! two-sum), the product of two f64 (Dekker's two-product, with Veltkamp's splitting, so
//! no fused multiply-add is needed and the same code runs in GLSL on `precise` doubles),
//! and growing an expansion by one f64 (GROW-EXPANSION, with zero components dropped).

/// `a + b = x + y` exactly, with `x = fl(a + b)` (Knuth's two-sum: no order of magnitude needed).
#[inline]
pub fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let x = a + b;
    let b_virtual = x - a;
    let a_virtual = x - b_virtual;
    let y = (a - a_virtual) + (b - b_virtual);
    (x, y)
}

/// 2²⁷ + 1: multiplying by it splits an f64's 53-bit significand into two halves of at most
/// 26 bits, whose pairwise products are exact.
const SPLITTER: f64 = 134_217_729.0;

/// `a = hi + lo` exactly, each with at most 26 significant bits (Veltkamp).
#[inline]
pub fn split(a: f64) -> (f64, f64) {
    let c = SPLITTER * a;
    let big = c - a;
    let hi = c - big;
    (hi, a - hi)
}

/// `a · b = x + y` exactly, with `x = fl(a · b)` (Dekker; no FMA).
#[inline]
pub fn two_product(a: f64, b: f64) -> (f64, f64) {
    let x = a * b;
    let (a_hi, a_lo) = split(a);
    let (b_hi, b_lo) = split(b);
    let err1 = x - a_hi * b_hi;
    let err2 = err1 - a_lo * b_hi;
    let err3 = err2 - a_hi * b_lo;
    (x, a_lo * b_lo - err3)
}

/// An exact sum of up to `N` f64 components, nonoverlapping and in increasing magnitude,
/// no component zero. The exact determinants sum their terms into one of these.
#[derive(Clone, Copy, Debug)]
pub struct Expansion<const N: usize> {
    c: [f64; N],
    n: usize,
}

impl<const N: usize> Expansion<N> {
    pub fn new() -> Self {
        Expansion { c: [0.0; N], n: 0 }
    }

    /// The components, smallest first.
    pub fn components(&self) -> &[f64] {
        &self.c[..self.n]
    }

    /// Adds `b` exactly (GROW-EXPANSION): `b` is carried up through the components by
    /// two-sum; the round-off left at each step is a component of the result. The
    /// round-offs are written back in place (index `m <= i`), zeros dropped.
    #[inline]
    pub fn add(&mut self, b: f64) {
        let mut q = b;
        let mut m = 0;
        for i in 0..self.n {
            let (sum, round_off) = two_sum(q, self.c[i]);
            q = sum;
            if round_off != 0.0 {
                self.c[m] = round_off;
                m += 1;
            }
        }
        if q != 0.0 {
            // N is the most components the caller's terms can produce: each add grows by one.
            self.c[m] = q;
            m += 1;
        }
        self.n = m;
    }

    /// Adds `sign · x · y` exactly (two components).
    #[inline]
    pub fn add_product(&mut self, sign: f64, x: f64, y: f64) {
        let (h, l) = two_product(sign * x, y);
        self.add(l);
        self.add(h);
    }

    /// Adds `sign · x · y · z` exactly (four components: `(h + l) · z`).
    #[inline]
    pub fn add_triple_product(&mut self, sign: f64, x: f64, y: f64, z: f64) {
        let (h, l) = two_product(sign * x, y);
        let (hh, hl) = two_product(h, z);
        let (lh, ll) = two_product(l, z);
        self.add(ll);
        self.add(lh);
        self.add(hl);
        self.add(hh);
    }

    /// The exact sign: that of the largest component (the smaller ones, nonoverlapping,
    /// add up to less than it). 0.0 for zero.
    pub fn sign(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            self.c[self.n - 1].signum()
        }
    }

    /// An f64 approximation of the value (the components summed smallest first) that has
    /// the exact sign. If rounding in that sum ever cancelled the largest component, the
    /// largest component itself is returned, so the sign holds by construction.
    pub fn value(&self) -> f64 {
        let sum = self.components().iter().fold(0.0, |sum, &c| sum + c);
        if sum * self.sign() > 0.0 || self.n == 0 {
            sum
        } else {
            self.c[self.n - 1]
        }
    }
}

impl<const N: usize> Default for Expansion<N> {
    fn default() -> Self {
        Self::new()
    }
}
