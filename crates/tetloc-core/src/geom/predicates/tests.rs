//! The predicates against the exact rational reference (`reference.rs`), on adversarial
//! inputs: points on and within rounding of planes and lines, exact lattices (many exact
//! zeros), slivers, f64 coordinates that do not round to f32, offsets of 1e6–1e7.

use super::expansion::{two_product, two_sum, Expansion};
use super::local::{orient3d_local, LocalFrame, Vec3};
use super::orient::{orient3d_exact, Point};
use super::reference::{self as r, Dyadic};
use super::*;
use proptest::prelude::*;

// ---------------------------------------------------------------- input generators

/// A finite f64 of either sign with a random exponent in `[-e, e]`, or zero.
fn wide_f64(e: i32) -> impl Strategy<Value = f64> {
    prop_oneof![
        1 => Just(0.0),
        20 => (1.0f64..2.0, -e..=e, any::<bool>()).prop_map(|(m, k, neg)| if neg { -m } else { m } * 2f64.powi(k)),
    ]
}

/// A frame offset: the origin, or UTM-like (1e6–1e7 per axis).
fn offset() -> impl Strategy<Value = Point> {
    prop_oneof![Just([0.0; 3]), prop::array::uniform3(1e6f64..1e7)]
}

/// A size: 1e-3 to 1e3.
fn size() -> impl Strategy<Value = f64> {
    (-3.0f64..3.0).prop_map(|e| 10f64.powf(e))
}

/// Nudges each non-zero coordinate by a few ulps (signed count per axis; zeros stay, as
/// their neighbours are outside the domain).
fn nudge(p: Point, ulps: [i32; 3]) -> Point {
    std::array::from_fn(|k| {
        let mut x = p[k];
        for _ in 0..ulps[k].unsigned_abs() {
            if x != 0.0 {
                // Away from zero adds one to the bits, towards zero takes one.
                x = f64::from_bits(if (ulps[k] > 0) == (x > 0.0) { x.to_bits() + 1 } else { x.to_bits() - 1 });
            }
        }
        x
    })
}

/// Four points of one of the hard kinds, plus a label for failure messages:
/// - `random`: a random tet-like configuration around an offset;
/// - `plane`: the fourth point on the plane of the first three (rounded), nudged by ulps;
/// - `near`: the fourth point within 1e-7 (relative to the size) of that plane;
/// - `lattice`: all on a small exact lattice (exact coplanarity and collinearity are common);
/// - `sliver`: the fourth point 1e-9 of the size above the plane of the first three.
fn configuration() -> impl Strategy<Value = (&'static str, [Point; 4])> {
    let unit = || prop::array::uniform3(-1.0f64..1.0);
    let scaled = |o: Point, s: f64, u: Point| -> Point { std::array::from_fn(|k| o[k] + s * u[k]) };
    prop_oneof![
        (offset(), size(), unit(), unit(), unit(), unit())
            .prop_map(move |(o, s, a, b, c, d)| ("random", [a, b, c, d].map(|u| scaled(o, s, u)))),
        (offset(), size(), unit(), unit(), unit(), -1.0f64..2.0, -1.0f64..2.0, prop::array::uniform3(-3i32..=3))
            .prop_map(move |(o, sz, a, b, c, s, t, ulps)| {
                let [a, b, c] = [a, b, c].map(|u| scaled(o, sz, u));
                let p = std::array::from_fn(|k| a[k] + s * (b[k] - a[k]) + t * (c[k] - a[k]));
                ("plane", [a, b, c, nudge(p, ulps)])
            }),
        (offset(), size(), unit(), unit(), unit(), -1.0f64..2.0, -1.0f64..2.0, unit(), -1.0f64..1.0).prop_map(
            move |(o, sz, a, b, c, s, t, dir, h)| {
                let [a, b, c] = [a, b, c].map(|u| scaled(o, sz, u));
                let p = std::array::from_fn(|k| a[k] + s * (b[k] - a[k]) + t * (c[k] - a[k]) + h * 1e-7 * sz * dir[k]);
                ("near", [a, b, c, p])
            }
        ),
        (offset(), -12i32..4, prop::array::uniform4(prop::array::uniform3(-3i32..=3))).prop_map(|(o, e, pts)| {
            // Offsets rounded to the lattice's spacing keep every sum exact.
            let h = 2f64.powi(e);
            let o = o.map(|x| (x / h).round() * h);
            ("lattice", pts.map(|q| std::array::from_fn(|k| o[k] + h * q[k] as f64)))
        }),
        (offset(), size(), unit(), unit(), unit(), 0.0f64..1.0, 0.0f64..1.0).prop_map(move |(o, sz, a, b, c, s, t)| {
            let [a, b, c] = [a, b, c].map(|u| scaled(o, sz, u));
            let n = normal(a, b, c);
            let p = std::array::from_fn(|k| a[k] + s * (b[k] - a[k]) + t * (c[k] - a[k]) + 1e-9 * sz * n[k]);
            ("sliver", [a, b, c, p])
        }),
    ]
}

/// The unit normal of the plane through a, b, c (f64, approximate), or zero.
fn normal(a: Point, b: Point, c: Point) -> Point {
    let (u, v) = (std::array::from_fn::<f64, 3, _>(|k| b[k] - a[k]), std::array::from_fn::<f64, 3, _>(|k| c[k] - a[k]));
    let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    let len = n.iter().map(|x| x * x).sum::<f64>().sqrt();
    if len > 0.0 {
        n.map(|x| x / len)
    } else {
        [0.0; 3]
    }
}

fn sign_i32(s: Sign) -> i32 {
    match s {
        Sign::Negative => -1,
        Sign::Zero => 0,
        Sign::Positive => 1,
    }
}

fn sum_exact(components: &[f64]) -> Dyadic {
    components.iter().fold(Dyadic::from_f64(0.0), |acc, &c| &acc + &Dyadic::from_f64(c))
}

fn same(a: &Dyadic, b: &Dyadic) -> bool {
    (a - b).sign() == 0
}

// ---------------------------------------------------------------- arithmetic

#[test]
fn domain_limits_are_the_powers_of_two() {
    assert!(in_domain(2f64.powi(-240)) && in_domain(2f64.powi(240)) && in_domain(0.0) && in_domain(-1.5));
    assert!(!in_domain(2f64.powi(-240) * (1.0 - f64::EPSILON)) && !in_domain(2f64.powi(240) * (1.0 + f64::EPSILON)));
    assert!(!in_domain(f64::NAN) && !in_domain(f64::INFINITY) && !in_domain(1e-300));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    #[test]
    fn two_sum_and_two_product_are_exact(a in wide_f64(200), b in wide_f64(200)) {
        let (x, y) = two_sum(a, b);
        prop_assert_eq!(x, a + b);
        prop_assert!(same(&(&Dyadic::from_f64(x) + &Dyadic::from_f64(y)), &(&Dyadic::from_f64(a) + &Dyadic::from_f64(b))));
        let (x, y) = two_product(a, b);
        prop_assert_eq!(x, a * b);
        prop_assert!(same(&(&Dyadic::from_f64(x) + &Dyadic::from_f64(y)), &(&Dyadic::from_f64(a) * &Dyadic::from_f64(b))));
    }

    /// Growing an expansion keeps the exact sum, nonoverlapping components in increasing
    /// magnitude, and the exact sign in `sign` and `value`.
    #[test]
    fn expansions_sum_exactly(terms in prop::collection::vec(wide_f64(120), 0..40)) {
        let mut e = Expansion::<40>::new();
        for &t in &terms {
            e.add(t);
        }
        let exact = sum_exact(&terms);
        prop_assert!(same(&sum_exact(e.components()), &exact));
        for w in e.components().windows(2) {
            prop_assert!(w[0] != 0.0 && w[0].abs() < w[1].abs(), "{:?}", e.components());
        }
        prop_assert_eq!(Sign::of(e.sign()), Sign::of(exact.sign() as f64));
        prop_assert_eq!(Sign::of(e.value()), Sign::of(exact.sign() as f64));
    }
}

// ---------------------------------------------------------------- orient3d, orient2d, the tie rule

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    #[test]
    fn orient3d_sign_is_exact((kind, [a, b, c, d]) in configuration()) {
        let want = r::orient3d(a, b, c, d);
        prop_assert_eq!(sign_i32(Sign::of(orient3d(a, b, c, d))), want, "{} {:?}", kind, [a, b, c, d]);
        // The exact stage alone, bypassing stage A, sums to the exact value.
        let e = orient3d_exact(a, b, c, d);
        let value = r::orient3d_exact(&r::exact3(a), &r::exact3(b), &r::exact3(c), &r::exact3(d));
        prop_assert!(same(&sum_exact(e.components()), &value), "{} {:?}", kind, [a, b, c, d]);
        prop_assert_eq!(sign_i32(Sign::of(e.value())), want);
    }

    #[test]
    fn orient2d_sign_is_exact((kind, [a, b, c, _]) in configuration(), axes in 0usize..3) {
        let (u, v) = (axes, (axes + 1) % 3);
        let (a, b, c) = ([a[u], a[v]], [b[u], b[v]], [c[u], c[v]]);
        prop_assert_eq!(sign_i32(Sign::of(orient2d(a, b, c))), r::orient2d(a, b, c), "{} {:?}", kind, [a, b, c]);
    }

    /// The tie rule as the predicates compute it (exact orient3d, then three orient2d) equals
    /// the reference's (cross product): zero only for degenerate faces.
    #[test]
    fn tie_rule_matches_reference((kind, [a, b, c, p]) in configuration(), which in 0usize..4) {
        // Also on faces through the query point's own plane: take p as a vertex sometimes.
        let (a, p) = if which == 0 { (a, a) } else { (a, p) };
        let got = sign_i32(orient3d_sos(a, b, c, p));
        prop_assert_eq!(got, r::orient3d_sos(a, b, c, p), "{} {:?}", kind, [a, b, c, p]);
        let degenerate = r::orient2d([a[0], a[1]], [b[0], b[1]], [c[0], c[1]]) == 0
            && r::orient2d([a[1], a[2]], [b[1], b[2]], [c[1], c[2]]) == 0
            && r::orient2d([a[2], a[0]], [b[2], b[0]], [c[2], c[0]]) == 0;
        prop_assert_eq!(got == 0, degenerate);
    }
}

#[test]
fn tie_rule_examples() {
    // The plane z = 0 through (0,0,0), (1,0,0), (0,1,0): n = (0, 0, 1), so a point on it is
    // moved by +ε³ in z, above the plane, where orient3d is negative.
    let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    assert_eq!(orient3d_sos(a, b, c, [0.3, 0.3, 0.0]), Sign::Negative);
    assert_eq!(orient3d(a, b, c, [0.3, 0.3, -1.0]), 1.0);
    // The plane x = 5 (n along −x for this order): the +ε in x decides.
    let (a, b, c) = ([5.0, 0.0, 0.0], [5.0, 1.0, 0.0], [5.0, 0.0, 1.0]);
    assert_eq!(orient3d_sos(a, b, c, [5.0, 7.0, -3.0]), Sign::of(orient3d(a, b, c, [5.5, 0.0, 0.0])));
    // A degenerate face ties whatever the point.
    let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]);
    assert_eq!(orient3d_sos(a, b, c, [3.0, 3.0, 3.0]), Sign::Zero);
    assert_eq!(orient3d_sos(a, b, c, [3.0, 0.0, 1.0]), Sign::Zero);
}

// ---------------------------------------------------------------- the local frame and the f32 filter

/// The exact local coordinate (x − o) · s.
fn exact_local(frame: &LocalFrame, x: Point) -> r::Exact3 {
    std::array::from_fn(|k| {
        &(&Dyadic::from_f64(x[k]) - &Dyadic::from_f64(frame.origin[k])) * &Dyadic::from_f64(frame.scale)
    })
}

/// A mesh-like frame for four points: the box of the points and of two far corners `ratio`
/// times the points' spread away, so that the points are a small part of the mesh (0: the
/// points' own box). Points that all coincide get far corners at `ratio` (their corners
/// would otherwise lie a denormal's width away, outside the predicates' domain).
fn frame_for(pts: &[Point], ratio: f64) -> LocalFrame {
    let c = pts[0];
    let spread = pts.iter().flat_map(|p| (0..3).map(move |k| (p[k] - c[k]).abs())).fold(0.0, f64::max);
    let spread = if spread > 0.0 { spread } else { 1.0 };
    let far = |s: f64| std::array::from_fn(|k| c[k] + s * ratio * spread * [1.0, 0.7, 0.4][k]);
    let mut all = pts.to_vec();
    all.extend([far(1.0), far(-1.3)]);
    LocalFrame::for_vertices(&all).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    /// Every local coordinate is within δ₀ = 2⁻²⁶ + 2⁻⁵² of the exact (x − o) · s; vertices
    /// lie within 1/4; points refused lie outside the vertices' bounding box.
    #[test]
    fn local_coordinates_are_within_the_rounding_bound((_, pts) in configuration(), ratio in 1.0f64..1e4,
                                                       probe in prop::array::uniform3(-3.0f64..3.0)) {
        let frame = frame_for(&pts, ratio);
        let delta0 = Dyadic::from_f64(2f64.powi(-26) + 2f64.powi(-52));
        for v in pts {
            let local = frame.to_local(v).expect("a vertex is always inside the point box");
            for (k, x) in exact_local(&frame, v).iter().enumerate() {
                prop_assert!(local[k].abs() <= 0.25);
                prop_assert!((&(&Dyadic::from_f32(local[k]) - x).abs() - &delta0).sign() <= 0);
            }
        }
        // A probe point around the box: refused only when outside every vertex's box.
        let (lo, hi) = (pts.iter().fold([f64::INFINITY; 3], |m, p| std::array::from_fn(|k| m[k].min(p[k]))),
                        pts.iter().fold([f64::NEG_INFINITY; 3], |m, p| std::array::from_fn(|k| m[k].max(p[k]))));
        let q: Point = std::array::from_fn(|k| frame.origin[k] + probe[k] * 0.25 / frame.scale);
        if frame.to_local(q).is_none() {
            prop_assert!((0..3).any(|k| q[k] < lo[k] || q[k] > hi[k]));
        }
    }

    /// The filter's claim: |det − D| ≤ bound, exactly, with D the exact determinant of the
    /// true local coordinates; so when |det| > bound the sign is that of orient3d on the
    /// file's f64 coordinates.
    #[test]
    fn local_filter_bound_holds((kind, [a, b, c, p]) in configuration(), ratio in prop_oneof![Just(0.0), 1.0f64..1e4]) {
        let frame = frame_for(&[a, b, c, p], ratio);
        let local = [a, b, c, p].map(|x| frame.to_local(x).unwrap());
        let (det, bound) = orient3d_local(local[0], local[1], local[2], local[3], FILTER_DELTA);
        let [ea, eb, ec, ep] = [a, b, c, p].map(|x| exact_local(&frame, x));
        let exact = r::orient3d_exact(&ea, &eb, &ec, &ep);
        let error = (&Dyadic::from_f32(det) - &exact).abs();
        prop_assert!((&error - &Dyadic::from_f32(bound)).sign() <= 0, "{} {:?} det {det} bound {bound}", kind, [a, b, c, p]);
        if det.abs() > bound {
            prop_assert_eq!(Sign::of(det as f64), Sign::of(r::orient3d(a, b, c, p) as f64));
        }
    }

    /// The arithmetic half of the bound alone (delta 0), on inputs that are exact local
    /// coordinates (multiples of 2⁻²⁵ within 1/2), near-coplanar and spanning the box, where
    /// rounding errors are largest.
    #[test]
    fn local_filter_arithmetic_bound_holds(pts in prop::array::uniform3(prop::array::uniform3(-0.5f64..0.5)),
                                           s in -1.0f64..2.0, t in -1.0f64..2.0, grid_steps in prop::array::uniform3(-3i32..=3)) {
        let grid = |x: f64| ((x * 33_554_432.0).round() / 33_554_432.0).clamp(-0.5, 0.5) as f32;
        let [a, b, c] = pts.map(|q| q.map(grid));
        let p: Vec3 = std::array::from_fn(|k| {
            let on_plane = a[k] as f64 + s * (b[k] - a[k]) as f64 + t * (c[k] - a[k]) as f64;
            grid(on_plane + grid_steps[k] as f64 / 33_554_432.0)
        });
        let (det, bound) = orient3d_local(a, b, c, p, 0.0);
        let e = |v: Vec3| v.map(Dyadic::from_f32);
        let exact = r::orient3d_exact(&e(a), &e(b), &e(c), &e(p));
        let error = (&Dyadic::from_f32(det) - &exact).abs();
        prop_assert!((&error - &Dyadic::from_f32(bound)).sign() <= 0, "{:?} det {det} bound {bound}", [a, b, c, p]);
    }

    /// The filter is worth having: for a tet at most 10 times smaller than the mesh box and
    /// a point at barycentric distance ≥ 1e-3 from every face plane it decides every face.
    /// (It decides points farther than about 1e-6 of the box size from a face plane.)
    #[test]
    fn local_filter_decides_clear_cases(o in offset(), sz in size(), ratio in 1.0f64..10.0,
                                        w in prop::array::uniform4(1e-3f64..1.0)) {
        let v: [Point; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
            .map(|u| std::array::from_fn(|k| o[k] + sz * u[k]));
        let s: f64 = w.iter().sum();
        let p: Point = std::array::from_fn(|k| (0..4).map(|i| w[i] / s * v[i][k]).sum());
        let frame = frame_for(&v, ratio);
        let l = v.map(|x| frame.to_local(x).unwrap());
        let lp = frame.to_local(p).unwrap();
        for f in FACES {
            let (det, bound) = orient3d_local(l[f[0]], l[f[1]], l[f[2]], lp, FILTER_DELTA);
            prop_assert!(det > bound, "undecided: det {det} bound {bound} weights {w:?}");
        }
    }
}

// ---------------------------------------------------------------- point in tet

/// Four reference-oriented (right-handed) vertices: `None` when degenerate.
fn right_handed(v: [Point; 4]) -> Option<[Point; 4]> {
    match r::orient3d(v[0], v[1], v[2], v[3]) {
        0 => None,
        1 => Some([v[0], v[1], v[3], v[2]]),
        _ => Some(v),
    }
}

/// A point relative to a tet: a vertex, an edge or face point with dyadic weights (exact
/// when the coordinates allow), a point near a face, or a random point around the tet.
fn point_for(v: [Point; 4], pick: u8, w: [u8; 4], t: f64, dir: Point, ulps: [i32; 3]) -> Point {
    let comb = |w: [f64; 4]| -> Point {
        let s: f64 = w.iter().sum();
        std::array::from_fn(|k| (0..4).map(|i| w[i] * v[i][k]).sum::<f64>() / s)
    };
    let w = w.map(|x| (x % 4) as f64);
    let on_face = comb([w[0] + 1.0, w[1] + 1.0, w[2] + 1.0, 0.0]);
    match pick % 6 {
        0 => v[(w[0] as usize) % 4],
        1 => comb([w[0] + 1.0, w[1] + 1.0, 0.0, 0.0]),
        2 => on_face,
        3 => nudge(on_face, ulps),
        4 => {
            let size = (0..3).map(|k| (v[1][k] - v[0][k]).abs()).fold(0.0, f64::max);
            std::array::from_fn(|k| on_face[k] + t * 1e-7 * size * dir[k])
        }
        _ => comb([w[0] + t.abs(), w[1] + 0.5, w[2] + 1.0 - t.abs(), w[3] + t]),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    /// The staged test (f32 local filter, exact f64 stages, tie rule) and the f64-only test
    /// agree with the reference for every kind of tet and point, including the exit face.
    #[test]
    fn staged_test_matches_reference((kind, v) in configuration(), pick in any::<u8>(), w in any::<[u8; 4]>(),
                                     t in -1.0f64..1.0, dir in prop::array::uniform3(-1.0f64..1.0),
                                     ulps in prop::array::uniform3(-2i32..=2), ratio in 1.0f64..1e3) {
        let Some(v) = right_handed(v) else { return Ok(()) };
        let p = point_for(v, pick, w, t, dir, ulps);
        let frame = frame_for(&v, ratio);
        let file: Vec<Point> = v.to_vec();
        let local: Vec<_> = file.iter().map(|&x| frame.to_local(x).unwrap()).collect();
        let want = r::contains(v, p);
        let exact = side_of_tet(v, p);
        prop_assert_eq!(exact == Side::Inside, want, "{} {:?} {:?}", kind, v, p);
        // The exit face is the first face (FACES order) the perturbed point is beyond.
        if let Side::Outside { face } = exact {
            let beyond = |f: [usize; 3]| r::orient3d_sos(v[f[0]], v[f[1]], v[f[2]], p) != 1;
            prop_assert!(beyond(FACES[face]) && FACES[..face].iter().all(|&f| !beyond(f)));
        }
        match frame.to_local(p) {
            Some(lp) => {
                let q = Query { local: lp, file: p };
                prop_assert_eq!(side_of_tet_staged([0, 1, 2, 3], &local, &file, &q), exact, "{} {:?} {:?}", kind, v, p);
                if let ExactTest::Inside(b) = test_point_exact([0, 1, 2, 3], &local, &file, &q) {
                    let want = r::barycentrics(v, p);
                    // Each face value is off by at most 9ε times its permanent: the weights by
                    // about twice the summed permanents over the volume (the condition κ).
                    let (permanents, total) = FACES.iter().fold((0.0, 0.0), |(sp, st), f| {
                        let (det, bound) = orient::orient3d_stage_a(v[f[0]], v[f[1]], v[f[2]], p);
                        (sp + bound / orient::ORIENT3D_BOUND, st + det)
                    });
                    let tolerance = 32.0 * EPS64 * permanents / total.abs() + 4.0 * EPS64;
                    for i in 0..4 {
                        prop_assert!(b[i] >= 0.0);
                        // Exactly zero on a face, close elsewhere.
                        prop_assert_eq!(b[i] == 0.0, want[i] == 0.0, "{:?} vs {:?}", b, want);
                        prop_assert!((b[i] - want[i]).abs() <= tolerance, "{} {:?} vs {:?} ({})", kind, b, want, tolerance);
                    }
                }
            }
            None => prop_assert!(!want, "a refused point must be outside"),
        }
    }

    /// Flat tets contain no point, perturbed or not.
    #[test]
    fn degenerate_tets_contain_nothing(o in -4i32..4, pts in prop::array::uniform3(prop::array::uniform2(-3i32..=3)),
                                       plane in prop::array::uniform3(-2i32..=2), q in prop::array::uniform3(-3i32..=3),
                                       on_plane in any::<bool>()) {
        // Four points on the lattice plane z = plane · (x, y, 1); the query on it or anywhere.
        let z = |x: i32, y: i32| plane[0] * x + plane[1] * y + plane[2];
        let lift = |[x, y]: [i32; 2]| [(x + o) as f64, y as f64, z(x, y) as f64];
        let v = [lift(pts[0]), lift(pts[1]), lift(pts[2]), lift([pts[0][0] + pts[1][0], pts[2][1]])];
        let p = if on_plane { lift([q[0], q[1]]) } else { q.map(|x| x as f64) };
        prop_assert_eq!(r::orient3d(v[0], v[1], v[2], v[3]), 0);
        prop_assert!(!r::contains(v, p));
        for order in [[0, 1, 2, 3], [0, 1, 3, 2], [3, 2, 1, 0]] {
            prop_assert_eq!(side_of_tet(order.map(|i| v[i]), p) == Side::Inside, false);
        }
    }
}

// ---------------------------------------------------------------- a conforming mesh: one tet per point

/// A Kuhn grid of `n`³ cubes (the topology of `testdata::KuhnGrid`, vertices numbered x
/// fastest) on `[origin, origin + n·h]³` in f64: interior vertices jittered by up to 0.2 h
/// in steps of 2⁻²⁰ h, so the coordinates do not round to f32 but dyadic combinations of
/// them stay exact; the boundary stays flat. Tets are made right-handed by the reference.
fn f64_kuhn_grid(n: usize, origin: Point, h: f64, seed: u64) -> (Vec<Point>, Vec<[u32; 4]>) {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut points = Vec::new();
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                let g = [i, j, k];
                points.push(std::array::from_fn(|a| {
                    let jitter = if g[a] > 0 && g[a] < n { rng.gen_range(-209_715i32..=209_715) } else { 0 };
                    origin[a] + h * (g[a] as f64 + jitter as f64 / 1_048_576.0)
                }));
            }
        }
    }
    let tets = right_handed_ids(&points, &crate::test_support::KuhnGrid::new(n).raw().tets);
    (points, tets)
}

/// Tets with the last two ids swapped where the reference finds them left-handed.
fn right_handed_ids(points: &[Point], tets: &[[u32; 4]]) -> Vec<[u32; 4]> {
    tets.iter()
        .map(|&t| {
            let v = t.map(|i| points[i as usize]);
            if r::orient3d(v[0], v[1], v[2], v[3]) > 0 {
                [t[0], t[1], t[3], t[2]]
            } else {
                t
            }
        })
        .collect()
}

/// Query points for a mesh: every vertex, every tet's edge midpoints and dyadic face points
/// (exactly on shared edges and faces), those nudged by an ulp, points within 1e-7 of the
/// size of faces, and points inside every tet.
fn mesh_samples(points: &[Point], tets: &[[u32; 4]], h: f64, seed: u64) -> Vec<Point> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut out: Vec<Point> = points.to_vec();
    for t in tets {
        let v = t.map(|i| points[i as usize]);
        let comb = |w: [f64; 4]| -> Point { std::array::from_fn(|k| (0..4).map(|i| w[i] * v[i][k]).sum::<f64>()) };
        for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
            let mut w = [0.0; 4];
            (w[i], w[j]) = (0.5, 0.5);
            out.push(comb(w));
        }
        for f in 0..4 {
            let mut w = [0.25, 0.25, 0.5, 0.0];
            w.rotate_right(f);
            let on_face = comb(w);
            out.push(on_face);
            out.push(nudge(on_face, [rng.gen_range(-1..=1), rng.gen_range(-1..=1), rng.gen_range(-1..=1)]));
            out.push(std::array::from_fn(|k| on_face[k] + rng.gen_range(-1.0..1.0) * 1e-7 * h));
        }
        let w: [f64; 4] = std::array::from_fn(|_| rng.gen_range(0.01..1.0));
        let s: f64 = w.iter().sum();
        out.push(comb(w.map(|x| x / s)));
    }
    out
}

/// The partition property, on f32-exact and non-f32 meshes at the origin and far from it:
/// the staged test claims a point in exactly the tets the reference does, and that is one
/// tet when the point is in the half-open box [lo, hi)³ (the tie rule on an axis-aligned box
/// mesh), none otherwise.
#[test]
fn every_point_of_a_kuhn_grid_has_exactly_one_tet() {
    // The KuhnGrid of the other tests (f32 vertices), and f64 grids at the origin and far from it.
    let f32_grid = {
        let raw = crate::test_support::KuhnGrid::new(3).jitter(0.2, 7).raw();
        let points: Vec<Point> = raw.points.iter().map(|p| p.map(f64::from)).collect();
        let tets = right_handed_ids(&points, &raw.tets);
        (points, tets, 1.0 / 3.0)
    };
    let f64_grid = |n, origin, h, seed| {
        let (points, tets) = f64_kuhn_grid(n, origin, h, seed);
        (points, tets, h)
    };
    let grids = [
        f32_grid,
        f64_grid(3, [0.0; 3], 0.25, 1),
        f64_grid(3, [512_345.0, 4_123_456.0, 0.0], 8.0, 2),
        f64_grid(2, [1e7, -3e6, 2.5e6], 1.0, 3),
    ];
    for (g, (points, tets, h)) in grids.iter().enumerate() {
        // The boundary is flat: the box of the vertices is the mesh's domain.
        let lo = points.iter().fold([f64::INFINITY; 3], |m, p| std::array::from_fn(|k| m[k].min(p[k])));
        let hi = points.iter().fold([f64::NEG_INFINITY; 3], |m, p| std::array::from_fn(|k| m[k].max(p[k])));
        let frame = LocalFrame::for_vertices(points).unwrap();
        let local: Vec<_> = points.iter().map(|&x| frame.to_local(x).unwrap()).collect();
        let samples = mesh_samples(points, tets, *h, g as u64);
        let (mut on_boundary, mut undecided_by_f32) = (0, 0);
        for &p in &samples {
            let want = r::locate_all(tets, points, p);
            let got: Vec<usize> = match frame.to_local(p) {
                None => vec![],
                Some(lp) => {
                    let q = Query { local: lp, file: p };
                    (0..tets.len())
                        .filter(|&t| side_of_tet_staged(tets[t], &local, points, &q) == Side::Inside)
                        .collect()
                }
            };
            assert_eq!(got, want, "grid {g}: point {p:?}");
            let in_half_open_box = (0..3).all(|k| lo[k] <= p[k] && p[k] < hi[k]);
            assert_eq!(want.len(), usize::from(in_half_open_box), "grid {g}: point {p:?} claimed by {want:?}");
            on_boundary += usize::from((0..3).any(|k| p[k] == lo[k] || p[k] == hi[k]));
            if let Some(lp) = frame.to_local(p) {
                undecided_by_f32 += tets
                    .iter()
                    .filter(|t| {
                        let v = t.map(|i| local[i as usize]);
                        FACES.iter().any(|f| {
                            let (det, bound) = orient3d_local(v[f[0]], v[f[1]], v[f[2]], lp, FILTER_DELTA);
                            det.abs() <= bound
                        })
                    })
                    .count();
            }
        }
        // The samples did exercise the hard cases.
        assert!(
            on_boundary > 50 && undecided_by_f32 > 100,
            "grid {g}: {on_boundary} boundary, {undecided_by_f32} undecided"
        );
    }
}
