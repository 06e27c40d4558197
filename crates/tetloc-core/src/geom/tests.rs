use super::*;
use proptest::prelude::*;

fn pts(v: &[[f32; 3]]) -> Vec<Vec3> {
    v.to_vec()
}

fn arb_point() -> impl Strategy<Value = Vec3> {
    prop::array::uniform3(-10.0f32..10.0)
}

/// A point from barycentric weights, computed in f64 and rounded once.
fn from_bary(v: [Vec3; 4], w: [f64; 4]) -> Vec3 {
    std::array::from_fn(|k| (0..4).map(|i| w[i] * v[i][k] as f64).sum::<f64>() as f32)
}

#[test]
fn canonical_order_is_sorted_and_positive() {
    let p = pts(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]]);
    for perm in [[0, 1, 2, 3], [1, 0, 2, 3], [3, 2, 1, 0], [2, 3, 0, 1], [0, 1, 3, 2]] {
        let (c, vol) = canonical_tet(perm, &p);
        assert!(c[0] < c[1] && c[1] < c[2].min(c[3]), "{c:?}");
        assert!(tet_volume6([p[c[0] as usize], p[c[1] as usize], p[c[2] as usize], p[c[3] as usize]]) > 0.0);
        assert_eq!(vol.abs(), 1.0);
    }
    // The two orientations of the input are reported as such.
    assert!(canonical_tet([0, 1, 2, 3], &p).1 * canonical_tet([1, 0, 2, 3], &p).1 < 0.0);
}

#[test]
fn centroid_is_inside_with_equal_weights() {
    let p = pts(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]]);
    let (c, _) = canonical_tet([3, 1, 0, 2], &p);
    let b = point_in_tet(c, &p, [0.25, 0.25, 0.25]).expect("inside");
    for w in b {
        assert!((w - 0.25).abs() < 1e-6);
    }
    assert!(point_in_tet(c, &p, [0.5, 0.5, 0.5]).is_none());
    assert!(point_in_tet(c, &p, [-1e-3, 0.2, 0.2]).is_none());
}

#[test]
fn vertices_and_faces_are_inside() {
    let p = pts(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]]);
    let (c, _) = canonical_tet([0, 1, 2, 3], &p);
    for q in &p {
        assert!(point_in_tet(c, &p, *q).is_some(), "{q:?}");
    }
    assert!(point_in_tet(c, &p, [0.3, 0.3, 0.0]).is_some());
}

#[test]
fn zero_volume_tet_contains_nothing() {
    let p = pts(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [1., 1., 0.]]);
    let (c, vol) = canonical_tet([0, 1, 2, 3], &p);
    assert_eq!(vol, 0.0);
    assert!(point_in_tet(c, &p, [0.3, 0.3, 0.0]).is_none());
}

#[test]
fn sliver_barycentrics_are_accurate() {
    // A sliver: the fourth vertex 1e-6 above the opposite face; its centroid must be found
    // with weights 1/4 although the f32 determinants are pure rounding noise.
    let p = pts(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0.3, 0.3, 1e-6]]);
    let (c, _) = canonical_tet([0, 1, 2, 3], &p);
    let v = [p[0], p[1], p[2], p[3]];
    let q = from_bary(v, [0.25; 4]);
    let b = point_in_tet(c, &p, q).expect("sliver centroid inside");
    for w in b {
        assert!((w - 0.25).abs() < 0.02, "{b:?}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// One exact orientation and the sort's parity give the order that orienting the sorted
    /// tet again gives: any vertex order, flat and repeated-vertex tets included (the points
    /// on a small integer lattice, so coplanar ones are common).
    #[test]
    fn canonical_exact_needs_one_orientation(c in prop::array::uniform4(prop::array::uniform3(-2i32..3)),
                                             order in Just([0u32, 1, 2, 3]).prop_shuffle(),
                                             repeat in any::<bool>()) {
        let file: Vec<[f64; 3]> = c.iter().map(|p| p.map(f64::from)).collect();
        let mut ids = order;
        if repeat {
            ids[3] = ids[0];
        }
        let (got, vol) = canonical_tet_exact(ids, &file);
        let vol6 = |t: [u32; 4]| -predicates::orient3d(file[t[0] as usize], file[t[1] as usize], file[t[2] as usize], file[t[3] as usize]);
        let mut want = ids;
        want.sort_unstable();
        if vol6(want) < 0.0 {
            want.swap(2, 3);
        }
        prop_assert_eq!(got, want);
        prop_assert_eq!(vol, vol6(ids));
        prop_assert!(vol6(got) >= 0.0);
    }

    /// The four faces' determinants and bounds at once are orient_f32's, face by face (the
    /// bounds bit for bit; a zero determinant may differ in its sign, which no test reads: a
    /// zero is never above its bound), for points anywhere, on a vertex, an edge or a face.
    #[test]
    fn four_faces_at_once_are_orient_f32(a in arb_point(), b in arb_point(), c in arb_point(), d in arb_point(),
                                         q in arb_point(), w in prop::array::uniform4(0.0f64..1.0), which in 0usize..4) {
        let v = [a, b, c, d];
        let mut w = w;
        w[which] = 0.0; // on the face opposite `which` (or an edge or vertex when more are 0)
        let s: f64 = w.iter().sum();
        let on = if s > 0.0 { from_bary(v, w.map(|x| x / s)) } else { v[which] };
        for p in [q, on, v[which]] {
            let (dets, bounds) = orient_faces_f32(v, p);
            for (i, &(f, _)) in SORTED_FACES.iter().enumerate() {
                let (det, bound) = orient_f32(v[f[0]], v[f[1]], v[f[2]], p);
                prop_assert!(dets[i] == det && bounds[i].to_bits() == bound.to_bits(), "face {i}: {p:?}");
            }
        }
    }

    /// Points built from positive barycentrics are found, with those weights.
    #[test]
    fn inside_points_are_found(a in arb_point(), b in arb_point(), c in arb_point(), d in arb_point(),
                               w in prop::array::uniform4(0.02f64..1.0)) {
        let p = vec![a, b, c, d];
        let (canon, vol) = canonical_tet([0, 1, 2, 3], &p);
        // Skip nearly flat tets: there, rounding the point to f32 can move it out.
        let scale = (0..4).flat_map(|i| (0..3).map(move |k| (i, k))).map(|(i, k)| p[i][k].abs() as f64).fold(1.0, f64::max);
        prop_assume!(vol.abs() > 1e-3 * scale.powi(3));
        let s: f64 = w.iter().sum();
        let w = w.map(|x| x / s);
        let q = from_bary([a, b, c, d], w);
        let bary = point_in_tet(canon, &p, q);
        prop_assert!(bary.is_some());
        let bary = bary.unwrap();
        for (slot, &id) in canon.iter().enumerate() {
            prop_assert!((bary[slot] as f64 - w[id as usize]).abs() < 1e-3, "{bary:?} vs {w:?}");
        }
    }

    /// Watertight: a point on (or within rounding of) a face shared by two tets is accepted
    /// by at least one of them, whatever the orientation the tets came in.
    #[test]
    fn shared_faces_have_no_cracks(a in arb_point(), b in arb_point(), c in arb_point(),
                                   up in arb_point(), w in prop::array::uniform3(0.0f64..1.0),
                                   swap in any::<bool>(), nudge in -2i32..=2) {
        let n = {
            let (u, v) = ([b[0]-a[0], b[1]-a[1], b[2]-a[2]], [c[0]-a[0], c[1]-a[1], c[2]-a[2]]);
            [u[1]*v[2]-u[2]*v[1], u[2]*v[0]-u[0]*v[2], u[0]*v[1]-u[1]*v[0]]
        };
        let n2 = n.iter().map(|x| x * x).sum::<f32>();
        prop_assume!(n2 > 1e-2);
        // The two apexes on either side of the face: the sideways shift 0.1·up must not carry
        // one across the face's plane (then both tets lie on one side, the face is on the
        // boundary, and the tie rule may rightly leave its points outside both).
        let up_n = 0.1 * (up[0] * n[0] + up[1] * n[1] + up[2] * n[2]);
        prop_assume!(up_n.abs() < 0.5 * n2);
        let d = [a[0] + n[0] + 0.1 * up[0], a[1] + n[1] + 0.1 * up[1], a[2] + n[2] + 0.1 * up[2]];
        let e = [a[0] - n[0] + 0.1 * up[0], a[1] - n[1] + 0.1 * up[1], a[2] - n[2] + 0.1 * up[2]];
        let p = vec![a, b, c, d, e];
        let t1 = canonical_tet(if swap { [1, 0, 2, 3] } else { [0, 1, 2, 3] }, &p).0;
        let t2 = canonical_tet([0, 1, 2, 4], &p).0;
        let s: f64 = w.iter().sum::<f64>().max(1e-9);
        let mut q = from_bary([a, b, c, a], [w[0] / s, w[1] / s, w[2] / s, 0.0]);
        // Move the point a few ulps off the face in x.
        for _ in 0..nudge.abs() {
            q[0] = if nudge > 0 { f32::from_bits(q[0].to_bits() + 1) } else { f32::from_bits(q[0].to_bits().wrapping_sub(1)) };
        }
        let in1 = point_in_tet(t1, &p, q).is_some();
        let in2 = point_in_tet(t2, &p, q).is_some();
        // Only points inside the triangle (not its edges' outside) are claimed.
        let strictly_in_triangle = w.iter().all(|&x| x / s > 1e-3);
        prop_assume!(strictly_in_triangle);
        prop_assert!(in1 || in2, "point {q:?} fell through the shared face");
    }
}

/// Issue 29.12 without a GPU: on flat tets stored in f64 (`test_support::slivers`, 1.25e-6
/// high, 0.125 wide), values interpolated with [`refined_bary`] on the working copy and its
/// residuals (what the GPU kernels compute) are within 1e-6 of the field's range of the f64
/// values on the file's data (`Mesh::value_at64`, the CPU's), at f64 points in random tets
/// given as their f32 rounding and its residual (a grid's f64 points on the GPU);
/// the working copy's own barycentrics ([`test_point`] on the f32 vertices, what the kernels
/// used before) are off by more than 1e-5 of it.
#[test]
fn refined_barycentrics_on_flat_tets_match_the_file_values() {
    use rand::{Rng, SeedableRng};
    let m = crate::Mesh::new(crate::test_support::slivers::flat_layers(8, 1e-5), "flat layers").unwrap();
    assert!(m.info.frame.is_identity(), "near the origin: the points below are working points");
    let residuals = m.working_residuals().expect("stored in f64");
    let f = m.field("f").unwrap();
    let file_values = f.values64.as_ref().expect("f64 values");
    let range = file_values.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b))
        - file_values.iter().fold(f64::INFINITY, |a, &b| a.min(b));
    let mut rng = rand_pcg::Pcg64::seed_from_u64(12);
    let (mut worst_refined, mut worst_working, mut tested) = (0f64, 0f64, 0);
    for _ in 0..20_000 {
        let t = rng.gen_range(0..m.n_tets());
        let ids = m.tets[t];
        let w: [f64; 4] = std::array::from_fn(|_| rng.gen_range(0.05..1.0));
        let s: f64 = w.iter().sum();
        // An f64 point (a grid's), its f32 rounding and what that lacks (the residual).
        let exact: [f64; 3] = std::array::from_fn(|k| (0..4).map(|i| w[i] / s * m.vertex64(ids[i])[k]).sum::<f64>());
        let p: Vec3 = exact.map(|c| c as f32);
        let p_residual: Vec3 = std::array::from_fn(|k| (exact[k] - f64::from(p[k])) as f32);
        let want = m.value_at64(f, m.bary64(t, exact).map(|b| (t, b)));
        let v = ids.map(|i| m.points[i as usize]);
        let refined = refined_bary(v, ids.map(|i| residuals[i as usize]), p, p_residual).expect("a tet with volume");
        worst_refined = worst_refined.max((m.value_at(f, Some((t, refined))) as f64 - want).abs());
        if let TetTest::Inside(b) = test_point(ids, &m.points, p) {
            worst_working = worst_working.max((m.value_at(f, Some((t, b))) as f64 - want).abs());
            tested += 1;
        }
    }
    assert!(tested > 10_000, "most points are inside their tet on the working copy too: {tested}");
    assert!(worst_refined <= 1e-6 * range, "refined: {:e} of the range", worst_refined / range);
    assert!(worst_working > 1e-5 * range, "the working copy should be off here: {:e}", worst_working / range);
}

/// [`holds_strictly_by_filter`] never claims what the full test does not give: on a mesh
/// stored in f64 (the flat slivers, vertices off their f32 copies by a visible share of a
/// tet's height) and a far-from-origin f32 mesh, at points inside tets, at their rounded
/// vertices and just off their faces, every point it passes is `Inside` with no zero weight
/// by [`test_point_with`]; and it passes points well inside (most of them off the slivers:
/// the cheap path is taken).
#[test]
fn the_sign_filter_passes_only_points_strictly_inside() {
    use rand::{Rng, SeedableRng};
    let flat = crate::Mesh::new(crate::test_support::slivers::flat_layers(8, 1e-5), "flat layers").unwrap();
    let mut far = crate::test_support::jittered_grid(5, 0.3, 3);
    for p in &mut far.points {
        *p = p.map(|c| c * 1000.0 + 4.0e6);
    }
    let far = crate::Mesh::new(far, "far").unwrap();
    assert!(flat.points64.is_some() && !far.info.frame.is_identity());
    let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
    for (m, share) in [(&flat, 0.1), (&far, 0.9)] {
        let exact = m.exact();
        let (mut passed, mut deep) = (0, 0);
        for _ in 0..20_000 {
            let t = rng.gen_range(0..m.n_tets());
            let ids = m.tets[t];
            let kind = rng.gen_range(0..3);
            let w: [f64; 4] = match kind {
                0 => std::array::from_fn(|_| rng.gen_range(0.05..1.0)),
                1 => std::array::from_fn(|i| f64::from(i == rng.gen_range(0..4))),
                _ => std::array::from_fn(|i| if i == 0 { rng.gen_range(-1e-7..1e-7) } else { rng.gen_range(0.1..1.0) }),
            };
            let s: f64 = w.iter().sum();
            let p: [f64; 3] = std::array::from_fn(|k| (0..4).map(|i| w[i] / s * m.vertex64(ids[i])[k]).sum::<f64>());
            let p = p.map(|c| f64::from(c as f32));
            let q = exact.query(p);
            if holds_strictly_by_filter(ids, &m.points, &exact, &q) {
                passed += 1;
                match test_point_with(ids, &m.points, &exact, &q) {
                    TetTest::Inside(b) => assert!(!b.contains(&0.0), "{}: tet {t}, {p:?}: on a face", m.info.source),
                    TetTest::Outside { .. } => panic!("{}: tet {t}, {p:?}: outside", m.info.source),
                }
            }
            deep += usize::from(kind == 0);
        }
        let enough = passed as f64 > share * deep as f64;
        assert!(enough, "{}: the filter passed {passed} of {deep} points well inside", m.info.source);
    }
}
