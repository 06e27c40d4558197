//! The exact brute-force reference for tests: which tets of a mesh hold a point, under the
//! tie rule, in exact rational arithmetic on the file's f64 coordinates.
//!
//! Deliberately independent of the code it checks: no expansions, no filters, no BVH or
//! walk; every f64 becomes an exact dyadic rational `m · 2^e` on `num_bigint::BigInt`, the
//! determinants are formed from differences (the predicates use the points directly), the
//! tie rule from the cross product (the predicates use three orient2d), and barycentrics
//! from volume ratios. It depends on nothing of this crate, so it can move as it is into a
//! dev-only test-support crate.

use num_bigint::{BigInt, Sign as BigSign};
use num_traits::ToPrimitive;
use std::ops::{Add, Mul, Sub};

/// The exact value `m · 2^e`.
#[derive(Clone, Debug)]
pub struct Dyadic {
    m: BigInt,
    e: i64,
}

impl Dyadic {
    /// The exact value of a finite f64.
    pub fn from_f64(x: f64) -> Dyadic {
        assert!(x.is_finite(), "reference: {x} is not finite");
        let bits = x.to_bits();
        let negative = bits >> 63 == 1;
        let exponent = ((bits >> 52) & 0x7ff) as i64;
        let fraction = bits & ((1u64 << 52) - 1);
        let (m, e) = if exponent == 0 { (fraction, -1074) } else { (fraction | (1u64 << 52), exponent - 1075) };
        let m = BigInt::from(m);
        Dyadic { m: if negative { -m } else { m }, e }
    }

    pub fn from_f32(x: f32) -> Dyadic {
        Dyadic::from_f64(x as f64)
    }

    /// -1, 0 or 1.
    pub fn sign(&self) -> i32 {
        match self.m.sign() {
            BigSign::Minus => -1,
            BigSign::NoSign => 0,
            BigSign::Plus => 1,
        }
    }

    pub fn abs(&self) -> Dyadic {
        Dyadic { m: self.m.magnitude().clone().into(), e: self.e }
    }

    /// `self / other` to about 60 bits (for comparing barycentrics): the integer quotient
    /// of the mantissas, one of them shifted so that it has 64 bits or so.
    pub fn ratio(&self, other: &Dyadic) -> f64 {
        assert!(other.sign() != 0, "reference: ratio over zero");
        let shift = 64 + other.m.bits() as i64 - self.m.bits() as i64;
        let q =
            if shift >= 0 { (&self.m << shift as usize) / &other.m } else { &self.m / (&other.m << -shift as usize) };
        // Scale by 2^(e_self − e_other − shift) in steps that cannot overflow on the way.
        let mut x = q.to_f64().unwrap();
        let mut e = self.e - other.e - shift;
        while e != 0 {
            let step = e.clamp(-1000, 1000);
            x *= 2f64.powi(step as i32);
            e -= step;
        }
        x
    }

    /// Both mantissas over the smaller exponent.
    fn aligned(&self, other: &Dyadic) -> (BigInt, BigInt, i64) {
        let e = self.e.min(other.e);
        (&self.m << (self.e - e) as usize, &other.m << (other.e - e) as usize, e)
    }
}

impl Add for &Dyadic {
    type Output = Dyadic;
    fn add(self, other: &Dyadic) -> Dyadic {
        let (a, b, e) = self.aligned(other);
        Dyadic { m: a + b, e }
    }
}

impl Sub for &Dyadic {
    type Output = Dyadic;
    fn sub(self, other: &Dyadic) -> Dyadic {
        let (a, b, e) = self.aligned(other);
        Dyadic { m: a - b, e }
    }
}

impl Mul for &Dyadic {
    type Output = Dyadic;
    fn mul(self, other: &Dyadic) -> Dyadic {
        Dyadic { m: &self.m * &other.m, e: self.e + other.e }
    }
}

pub type Exact3 = [Dyadic; 3];

pub fn exact3(p: [f64; 3]) -> Exact3 {
    p.map(Dyadic::from_f64)
}

fn diff(a: &Exact3, b: &Exact3) -> Exact3 {
    std::array::from_fn(|k| &a[k] - &b[k])
}

fn cross(u: &Exact3, v: &Exact3) -> Exact3 {
    [&(&u[1] * &v[2]) - &(&u[2] * &v[1]), &(&u[2] * &v[0]) - &(&u[0] * &v[2]), &(&u[0] * &v[1]) - &(&u[1] * &v[0])]
}

fn dot(u: &Exact3, v: &Exact3) -> Dyadic {
    &(&(&u[0] * &v[0]) + &(&u[1] * &v[1])) + &(&u[2] * &v[2])
}

/// det[a − d; b − d; c − d], exactly.
pub fn orient3d_exact(a: &Exact3, b: &Exact3, c: &Exact3, d: &Exact3) -> Dyadic {
    let (ad, bd, cd) = (diff(a, d), diff(b, d), diff(c, d));
    dot(&ad, &cross(&bd, &cd))
}

/// The sign of orient3d on f64 points.
pub fn orient3d(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> i32 {
    orient3d_exact(&exact3(a), &exact3(b), &exact3(c), &exact3(d)).sign()
}

/// The sign of orient2d: (a − c) × (b − c).
pub fn orient2d(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> i32 {
    let d = |p: [f64; 2], k: usize| &Dyadic::from_f64(p[k]) - &Dyadic::from_f64(c[k]);
    (&(&d(a, 0) * &d(b, 1)) - &(&d(a, 1) * &d(b, 0))).sign()
}

/// The tie rule: the sign of orient3d(a, b, c, p + (ε, ε², ε³)) for small ε > 0, from the
/// normal n = (b − a) × (c − a): orient3d = n · (a − p) − (ε n.x + ε² n.y + ε³ n.z).
pub fn orient3d_sos(a: [f64; 3], b: [f64; 3], c: [f64; 3], p: [f64; 3]) -> i32 {
    let (a, b, c, p) = (exact3(a), exact3(b), exact3(c), exact3(p));
    let n = cross(&diff(&b, &a), &diff(&c, &a));
    let on_plane = dot(&n, &diff(&a, &p)).sign();
    if on_plane != 0 {
        return on_plane;
    }
    n.iter().map(|x| -x.sign()).find(|&s| s != 0).unwrap_or(0)
}

/// Faces of a tet in any order of its vertices: the three others, ascending.
const FACE_OF: [[usize; 3]; 4] = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]];

/// Whether tet `v` (either orientation) holds `p` under the tie rule: for each face, the
/// perturbed point is on the side of the opposite vertex. Zero-volume tets hold nothing.
pub fn contains(v: [[f64; 3]; 4], p: [f64; 3]) -> bool {
    if orient3d(v[0], v[1], v[2], v[3]) == 0 {
        return false;
    }
    FACE_OF.iter().enumerate().all(|(i, f)| {
        let inner = orient3d(v[f[0]], v[f[1]], v[f[2]], v[i]);
        orient3d_sos(v[f[0]], v[f[1]], v[f[2]], p) == inner
    })
}

/// Every tet of the mesh that holds `p` (at most one for a conforming mesh). Tets whose
/// bounding box excludes `p` are skipped first: exact comparisons, so nothing is lost.
pub fn locate_all(tets: &[[u32; 4]], points: &[[f64; 3]], p: [f64; 3]) -> Vec<usize> {
    (0..tets.len())
        .filter(|&t| {
            let v = tets[t].map(|i| points[i as usize]);
            let in_box = (0..3).all(|k| {
                let (lo, hi) =
                    v.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| (lo.min(q[k]), hi.max(q[k])));
                lo <= p[k] && p[k] <= hi
            });
            in_box && contains(v, p)
        })
        .collect()
}

/// Barycentric weights of `p` in tet `v`, as volume ratios: weight i is the volume with
/// vertex i replaced by `p` over the tet's volume.
pub fn barycentrics(v: [[f64; 3]; 4], p: [f64; 3]) -> [f64; 4] {
    let e = v.map(exact3);
    let volume = orient3d_exact(&e[0], &e[1], &e[2], &e[3]);
    let ep = exact3(p);
    std::array::from_fn(|i| {
        let mut w = e.clone();
        w[i] = ep.clone();
        orient3d_exact(&w[0], &w[1], &w[2], &w[3]).ratio(&volume)
    })
}
