use super::*;
use crate::geom;
use crate::test_support::grid_mesh;
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use std::sync::Arc;

/// Brute force over all tets: the reference for the BVH traversal.
fn brute_force(m: &crate::Mesh, p: Vec3) -> Option<u32> {
    (0..m.n_tets()).find(|&t| geom::point_in_tet(m.tets[t], &m.points, p).is_some()).map(|t| t as u32)
}

fn random_inside(m: &crate::Mesh, rng: &mut impl Rng) -> (usize, Vec3) {
    let t = rng.gen_range(0..m.n_tets());
    let w: [f64; 4] = std::array::from_fn(|_| rng.gen_range(0.01..1.0));
    let s: f64 = w.iter().sum();
    let v = m.tets[t].map(|i| m.points[i as usize]);
    (t, std::array::from_fn(|k| (0..4).map(|i| w[i] / s * v[i][k] as f64).sum::<f64>() as f32))
}

/// `n` points drawn inside random tets of `m` (the draw seeded by `seed`).
fn points_inside(m: &crate::Mesh, n: usize, seed: u64) -> Vec<Vec3> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    (0..n).map(|_| random_inside(m, &mut rng).1).collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Points drawn inside random tets of random jittered meshes are found in that tet;
    /// points outside the hull give -1; every query agrees with brute force.
    #[test]
    fn finds_inside_points_and_rejects_outside(n in 1usize..7, jitter in 0.0f32..0.3, seed in any::<u64>()) {
        let m = Arc::new(grid_mesh(n, jitter, seed));
        let mut loc = CpuLocator::new(m.clone());
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let mut pts = Vec::new();
        let mut want = Vec::new();
        for _ in 0..300 {
            let (t, p) = random_inside(&m, &mut rng);
            pts.push(p);
            want.push(t as i32);
        }
        // Outside the unit cube (the hull of the grid).
        for _ in 0..100 {
            let mut p: Vec3 = std::array::from_fn(|_| rng.gen_range(-0.5f32..1.5));
            p[rng.gen_range(0..3)] = if rng.gen() { -1e-3 - rng.gen_range(0.0..0.5) } else { 1.001 + rng.gen_range(0.0..0.5) };
            pts.push(p);
            want.push(OUTSIDE);
        }
        let mut ids = vec![0; pts.len()];
        loc.locate(&pts, &mut ids).unwrap();
        for (i, (&got, &w)) in ids.iter().zip(&want).enumerate() {
            let p = pts[i];
            if w == OUTSIDE {
                prop_assert_eq!(got, OUTSIDE, "point {} {:?}", i, p);
                prop_assert_eq!(brute_force(&m, p), None);
                continue;
            }
            // Found, and in a tet that holds it: rounding the point to f32 can move it out of
            // a sliver it was drawn in (jitter 0.3 makes some), into the neighbour.
            prop_assert!(got >= 0, "point {} {:?} inside tet {} not found", i, p, w);
            prop_assert!(geom::point_in_tet(m.tets[got as usize], &m.points, p).is_some(), "point {} {:?}: tet {}", i, p, got);
            // Well inside the tet it was drawn in (every weight ≥ 1e-3 after rounding) of a
            // mesh without folds: the containing tet is unique, so the locator and brute force
            // both name it. (Jitter 0.3 can invert tets; reoriented, they overlap neighbours.)
            let clear = m.info.n_reoriented == 0
                && geom::point_in_tet(m.tets[w as usize], &m.points, p).is_some_and(|b| b.iter().all(|&x| x >= 1e-3));
            if clear {
                prop_assert_eq!(got, w, "point {} {:?}", i, p);
                prop_assert_eq!(got, brute_force(&m, p).map_or(OUTSIDE, |t| t as i32));
            }
        }
    }

    /// No cracks: points on interior shared faces and edges are always found.
    #[test]
    fn no_cracks_on_shared_faces(n in 2usize..6, seed in any::<u64>()) {
        let m = Arc::new(grid_mesh(n, 0.3, seed));
        let loc = CpuLocator::new(m.clone());
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed ^ 0x5eed);
        for f in m.faces().faces.iter().filter(|f| f.front >= 0 && f.back >= 0) {
            let [a, b, c] = f.v.map(|i| m.points[i as usize]);
            for _ in 0..4 {
                let mut w: [f64; 3] = std::array::from_fn(|_| rng.gen_range(0.0..1.0));
                if rng.gen_bool(0.2) { w[rng.gen_range(0..3)] = 0.0; } // on an edge
                let s: f64 = w.iter().sum::<f64>().max(1e-12);
                let p: Vec3 = std::array::from_fn(|k| ((w[0] * a[k] as f64 + w[1] * b[k] as f64 + w[2] * c[k] as f64) / s) as f32);
                prop_assert!(loc.locate_point(p).is_some(), "crack at {:?} on face {:?}", p, f.v);
            }
        }
    }
}

#[test]
fn sample_interpolates_vertex_fields_and_looks_up_cell_fields() {
    let m = Arc::new(grid_mesh(4, 0.25, 9));
    let mut loc = CpuLocator::new(m.clone());
    let mut pts = points_inside(&m, 500, 3);
    pts.push([2.0, 2.0, 2.0]);
    let mut ids = vec![0; pts.len()];
    let mut f = vec![0.0; pts.len()];
    let mut cell = vec![0.0; pts.len()];
    loc.locate(&pts, &mut ids).unwrap();
    loc.sample(&pts, "f", &mut f).unwrap();
    loc.sample(&pts, "cellval", &mut cell).unwrap();
    let fv = &m.field("f").unwrap().values;
    for i in 0..pts.len() - 1 {
        let t = ids[i] as usize;
        let b = geom::point_in_tet(m.tets[t], &m.points, pts[i]).unwrap();
        assert_eq!(f[i], geom::interpolate(m.tets[t], b, fv));
        assert_eq!(cell[i], t as f32);
    }
    assert!(f.last().unwrap().is_nan() && cell.last().unwrap().is_nan());
    // One pass for both gives the same ids and values as two.
    let (mut ids2, mut f2) = (vec![0; pts.len()], vec![0.0; pts.len()]);
    loc.locate_and_sample(&pts, "f", &mut ids2, &mut f2).unwrap();
    assert_eq!(ids2, ids);
    assert!(f2.iter().zip(&f).all(|(a, b)| a.to_bits() == b.to_bits()));
    assert!(loc.sample(&pts, "nope", &mut f).is_err());
    assert!(loc.locate(&pts, &mut ids[1..]).is_err());
}

/// The batch answer (Morton order, walks) equals the per-point BVH answer, also for points
/// exactly on faces, edges and vertices, and whatever order the batch comes in.
#[test]
fn batch_answers_do_not_depend_on_order() {
    let m = Arc::new(grid_mesh(6, 0.3, 11));
    let mut loc = CpuLocator::new(m.clone());
    let mut pts = points_inside(&m, 2000, 5);
    pts.extend(m.points.iter().copied());
    for f in m.faces().faces.iter().take(500) {
        let [a, b, c] = f.v.map(|i| m.points[i as usize]);
        pts.push(std::array::from_fn(|k| (a[k] + b[k] + c[k]) / 3.0));
        pts.push(std::array::from_fn(|k| (a[k] + b[k]) / 2.0));
    }
    let want: Vec<i32> = pts.iter().map(|&p| loc.locate_point(p).map_or(OUTSIDE, |(t, _)| t as i32)).collect();
    let mut ids = vec![0; pts.len()];
    loc.locate(&pts, &mut ids).unwrap();
    assert_eq!(ids, want);
    // Reversed batch, same answers.
    pts.reverse();
    loc.locate(&pts, &mut ids).unwrap();
    ids.reverse();
    assert_eq!(ids, want);
    assert!(want.iter().all(|&i| i >= 0), "a point of the mesh came back outside");
}

/// Coherent batches (tet centres and face points in mesh order) skip the Morton sort and
/// walk in the given order: the answers are still the per-point BVH answers.
#[test]
fn coherent_batches_give_the_same_answers() {
    // Small jitter: no tet folds over, so every interior point has one containing tet.
    let m = Arc::new(grid_mesh(8, 0.1, 12));
    assert_eq!(m.info.n_reoriented, m.n_tets() / 2, "Kuhn tets alternate orientation; none folded");
    let mut loc = CpuLocator::new(m.clone());
    let mut pts: Vec<Vec3> = (0..m.n_tets()).map(|t| m.tet_center(t)).collect();
    for f in &m.faces().faces {
        let [a, b, c] = f.v.map(|i| m.points[i as usize]);
        pts.push(std::array::from_fn(|k| (a[k] + b[k] + c[k]) / 3.0));
    }
    assert!(super::is_coherent(&pts, m.info.mean_edge_length), "the test must exercise the unsorted path");
    let want: Vec<i32> = pts.iter().map(|&p| loc.locate_point(p).map_or(OUTSIDE, |(t, _)| t as i32)).collect();
    let mut ids = vec![0; pts.len()];
    loc.locate(&pts, &mut ids).unwrap();
    assert_eq!(ids, want);
    assert!((0..m.n_tets()).all(|t| ids[t] == t as i32), "every centre in its own tet");
    let mut shuffled = pts.clone();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
    use rand::seq::SliceRandom;
    let mut perm: Vec<usize> = (0..pts.len()).collect();
    perm.shuffle(&mut rng);
    for (k, &i) in perm.iter().enumerate() {
        shuffled[k] = pts[i];
    }
    assert!(!super::is_coherent(&shuffled, m.info.mean_edge_length));
    loc.locate(&shuffled, &mut ids).unwrap();
    assert!(perm.iter().enumerate().all(|(k, &i)| ids[k] == want[i]));
}

/// Issue 9 item 8: f = x² + y² + z² (and a cubic, on cubic tets) given at the nodes of
/// straight-sided higher-order tets is sampled exactly (to f32 rounding) by the CPU locator,
/// alone and with the tolerance post-pass; the corners alone would miss it.
#[test]
fn higher_order_tets_interpolate_their_polynomials_exactly() {
    use crate::test_support::KuhnGrid;
    fn quadratic(p: [f64; 3]) -> f64 {
        p[0] * p[0] + p[1] * p[1] + p[2] * p[2]
    }
    fn cubic(p: [f64; 3]) -> f64 {
        p[0] * p[0] * p[0] - 2.0 * p[0] * p[1] * p[2] + p[2] * p[2] + p[1]
    }
    type Field = fn([f64; 3]) -> f64;
    let cases: [(u8, Field); 3] = [(2, quadratic), (3, cubic), (4, cubic)];
    let mut rng = rand_pcg::Pcg64::seed_from_u64(8);
    for (order, f) in cases {
        let f32_of = |p: Vec3| f(p.map(f64::from)) as f32;
        let m = Arc::new(KuhnGrid::new(3).jitter(0.15, 3).order(order).vertex_field(f32_of).mesh("elevated"));
        let points: Vec<Vec3> = (0..4000).map(|_| std::array::from_fn(|_| rng.gen_range(0.0..1.0f32))).collect();
        let (mut ids, mut values) = (vec![0; points.len()], vec![0.0; points.len()]);
        let mut loc = CpuLocator::new(m.clone());
        loc.locate_and_sample(&points, "f", &mut ids, &mut values).unwrap();
        let (mut worst, mut linear_worst) = (0.0f64, 0.0f64);
        for ((p, &t), &v) in points.iter().zip(&ids).zip(&values) {
            assert!(t >= 0, "{p:?} is inside the unit cube");
            let want = f(p.map(f64::from));
            worst = worst.max((f64::from(v) - want).abs());
            let b = geom::point_in_tet(m.tets[t as usize], &m.points, *p).unwrap();
            let linear = geom::interpolate(m.tets[t as usize], b, &m.field("f").unwrap().values);
            linear_worst = linear_worst.max((f64::from(linear) - want).abs());
        }
        eprintln!("order {order}: worst error {worst:.2e} (corners only: {linear_worst:.2e})");
        assert!(worst < 2e-6, "order {order}: the tet's polynomial is missed by {worst}");
        assert!(linear_worst > 1e-3, "order {order}: the corners alone should miss it");

        // Just outside the face x = 1: the tolerance post-pass gives f at the closest point.
        let outside: Vec<Vec3> = points.iter().map(|p| [1.0 + 1e-3, p[1], p[2]]).collect();
        let mut tol = WithTolerance::new(CpuLocator::new(m.clone()), m.clone(), Tolerance::Absolute(0.01));
        let mut values = vec![0.0; outside.len()];
        tol.sample(&outside, "f", &mut values).unwrap();
        for (p, &v) in outside.iter().zip(&values) {
            let want = f([1.0, f64::from(p[1]), f64::from(p[2])]);
            assert!((f64::from(v) - want).abs() < 2e-6, "order {order}: {p:?} gives {v}, closest point {want}");
        }
    }
}

/// Exact on the file's f64 data, from a fresh clone (no oracle files): a jittered grid mapped
/// in f64 to UTM-like coordinates (×1000, then shifted by (512345.0375, 4123456.0625, 0.3)),
/// so that no vertex rounds to f32 exactly, queried at points within 1e-7 of faces and at
/// random, through the f64 path. Every answer equals the exact brute-force reference's
/// (`geom::predicates::reference`, rational arithmetic).
#[test]
fn f64_points_far_from_the_origin_follow_exact_arithmetic() {
    use crate::geom::predicates::reference;
    let raw = crate::test_support::jittered_grid(4, 0.25, 7);
    let shift = [512_345.037_5, 4_123_456.062_5, 0.3];
    let file: Vec<[f64; 3]> = raw
        .points
        .iter()
        .map(|p| std::array::from_fn(|k| p[k] as f64 * 1000.0 + shift[k] + 1e-7 * p[k] as f64))
        .collect();
    let raw =
        crate::RawMesh { points: file.iter().map(|p| p.map(|c| c as f32)).collect(), points64: Some(file), ..raw };
    let m = Arc::new(crate::Mesh::new(raw, "shifted grid").unwrap());
    assert!(!m.info.frame.is_identity());
    let file = m.points64.clone().unwrap();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let mut queries: Vec<[f64; 3]> = Vec::new();
    for _ in 0..400 {
        // A point on a random face (random weights of its three vertices), nudged off it by
        // up to 1e-7 m along a random direction (the mesh is 4 km wide: 1e-11 relative).
        let t = m.tets[rng.gen_range(0..m.n_tets())];
        let f = geom::ascending_faces(t)[rng.gen_range(0..4)].0;
        let w: [f64; 3] = std::array::from_fn(|_| rng.gen_range(0.05..1.0));
        let s: f64 = w.iter().sum();
        let on: [f64; 3] = std::array::from_fn(|k| (0..3).map(|i| w[i] / s * file[f[i] as usize][k]).sum());
        queries.push(std::array::from_fn(|k| on[k] + rng.gen_range(-1e-7..1e-7)));
    }
    let (lo, hi) = (m.info.frame.to_file(m.info.bounds_min), m.info.frame.to_file(m.info.bounds_max));
    for _ in 0..200 {
        queries.push(std::array::from_fn(|k| rng.gen_range(lo[k] - 10.0..hi[k] + 10.0)));
    }
    let mut loc = CpuLocator::new(m.clone());
    let (mut ids, mut values) = (vec![0i32; queries.len()], vec![0f64; queries.len()]);
    loc.sample_many64(&queries, &["f"], &mut ids, &mut values).unwrap();
    let mut near_face_hits = 0;
    for (i, q) in queries.iter().enumerate() {
        let want = reference::locate_all(&m.tets, &file, *q);
        assert!(want.len() <= 1, "point {i} in several tets: {want:?}");
        let want = want.first().map_or(-1, |&t| t as i32);
        assert_eq!(ids[i], want, "point {i} {q:?}");
        near_face_hits += (i < 400 && want >= 0) as usize;
    }
    assert!(near_face_hits > 300, "most near-face points are inside: {near_face_hits}");
    // The same points through the f32 path lose them: the f64 path is what makes them exact.
    let rounded: Vec<Vec3> = queries.iter().map(|q| q.map(|c| c as f32)).collect();
    let mut ids32 = vec![0i32; rounded.len()];
    loc.locate(&rounded, &mut ids32).unwrap();
    assert!(ids32.iter().zip(&ids).filter(|(a, b)| a != b).count() > 10, "f32 points are rounded by up to 0.25 m");
}

/// The exact barycentrics of `p` in tet `ids` (rational arithmetic on the file's
/// coordinates, each weight rounded once to f64): the reference of every f64 value.
fn exact_bary(m: &crate::Mesh, ids: [u32; 4], p: [f64; 3]) -> [f64; 4] {
    use crate::geom::predicates::reference::{exact3, orient3d_exact};
    let v = ids.map(|i| exact3(m.vertex64(i)));
    let q = exact3(p);
    let total = orient3d_exact(&v[0], &v[1], &v[2], &v[3]);
    std::array::from_fn(|i| {
        let mut w = v.clone();
        w[i] = q.clone();
        orient3d_exact(&w[0], &w[1], &w[2], &w[3]).ratio(&total)
    })
}

/// A field of f64 values near zero where the points are (`1e-3 (x − x0) + 1e-12 y`, x0 not an
/// f32), from a fresh clone: the f32 path (f32 values, f32 barycentrics, f32 points) is off
/// by more than 1e-5 relative there, while `sample_many64` matches the independent reference
/// (exact rational barycentrics times the f64 values, `geom::predicates::reference`) to 1e-12
/// relative, and `F64Values` around the CPU gives the CPU's values bit for bit.
#[test]
fn f64_values_near_zero_match_exact_barycentrics() {
    use crate::geom::predicates::reference;
    use crate::mesh::{Field, FieldLocation};
    let mut raw = crate::test_support::jittered_grid(4, 0.25, 5);
    let x0 = 0.5 + 1e-9 / 3.0;
    let g: Vec<f64> = raw.points.iter().map(|p| 1e-3 * (p[0] as f64 - x0) + 1e-12 * p[1] as f64).collect();
    raw.fields.push(Field::from_f64("g", FieldLocation::Vertex, g));
    let m = Arc::new(crate::Mesh::new(raw, "near zero").unwrap());
    assert!(m.field("g").unwrap().values64.is_some());
    let file: Vec<[f64; 3]> = (0..m.points.len() as u32).map(|i| m.vertex64(i)).collect();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
    let points: Vec<[f64; 3]> = (0..300)
        .map(|i| {
            let dx = rng.gen_range(1e-4..1e-3) * if i % 2 == 0 { 1.0 } else { -1.0 };
            [x0 + dx, rng.gen_range(0.1..0.9), rng.gen_range(0.1..0.9)]
        })
        .collect();
    let mut loc = CpuLocator::new(m.clone());
    let (mut ids, mut values) = (vec![0i32; points.len()], vec![0f64; points.len()]);
    loc.sample_many64(&points, &["g"], &mut ids, &mut values).unwrap();
    let rounded: Vec<Vec3> = points.iter().map(|p| p.map(|c| c as f32)).collect();
    let mut values32 = vec![0f32; points.len()];
    loc.sample(&rounded, "g", &mut values32).unwrap();
    let f = m.field("g").unwrap();
    let (mut worst64, mut worst32) = (0f64, 0f64);
    for (i, p) in points.iter().enumerate() {
        let want_tet = reference::locate_all(&m.tets, &file, *p);
        assert_eq!(want_tet.len(), 1, "point {i}: {want_tet:?}");
        let t = want_tet[0];
        assert_eq!(ids[i], t as i32, "point {i}");
        let b = exact_bary(&m, m.tets[t], *p);
        let want: f64 = (0..4).map(|k| b[k] * f.value64(m.tets[t][k] as usize)).sum();
        assert!(want.abs() > 1e-8, "point {i}: the value is small but not lost: {want}");
        worst64 = worst64.max((values[i] - want).abs() / want.abs());
        worst32 = worst32.max((values32[i] as f64 - want).abs() / want.abs());
    }
    assert!(worst64 <= 1e-12, "f64 path: {worst64:e} relative");
    assert!(worst32 > 1e-5, "the f32 path should not be this close: {worst32:e}");
    // Any backend's ids with F64Values: the same values, bit for bit.
    let mut wrapped = F64Values::new(CpuLocator::new(m.clone()), m.clone());
    let (mut ids2, mut values2) = (vec![0i32; points.len()], vec![0f64; points.len()]);
    wrapped.sample_many64(&points, &["g"], &mut ids2, &mut values2).unwrap();
    assert_eq!(ids2, ids);
    assert!(values2.iter().zip(&values).all(|(a, b)| a.to_bits() == b.to_bits()));
}

/// Issue 29.11 at CI scale: jets (20k tets) ×1000, offset by (512345.25, 4012345.5, 100) and
/// stored in f32, as a Float32 file far from the origin would be. Its f32 values are the
/// file's coordinates exactly, so the mesh must answer f64 query points exactly on them:
/// the mesh gets a centred working frame (its f32 copy would round a query by up to 0.25 m
/// at y ≈ 4e6), and every answer of the f64 path is the exact rational reference's
/// (`geom::predicates::reference`) on the stored coordinates, points as given.
#[test]
fn f32_mesh_far_from_the_origin_answers_f64_points_exactly() {
    use crate::geom::predicates::reference;
    let (n, offset) = (20_000, [512_345.25, 4_012_345.5, 100.0]);
    let mut raw = crate::gen::generate(crate::gen::Shape::Jets, n, 3);
    for p in &mut raw.points {
        *p = std::array::from_fn(|k| (p[k] as f64 * 1000.0 + offset[k]) as f32);
    }
    assert!(raw.points64.is_none(), "stored in f32");
    let stored: Vec<[f64; 3]> = raw.points.iter().map(|p| p.map(f64::from)).collect();
    let m = Arc::new(crate::Mesh::new(raw, "far f32 jets").unwrap());
    assert!(!m.info.frame.is_identity(), "a far f32 mesh gets a centred working frame");
    assert!(m.wants_f64_points(), "f64 query points keep their precision");
    assert!((0..stored.len()).all(|i| m.vertex64(i as u32) == stored[i]), "the stored f32 values, exactly");
    let (lo, hi) = m.file_box();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(29);
    let queries: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            if i % 2 == 0 {
                // Inside a random tet, at random f64 weights of its stored vertices.
                let t = m.tets[rng.gen_range(0..m.n_tets())];
                let w: [f64; 4] = std::array::from_fn(|_| rng.gen_range(0.0..1.0));
                let s: f64 = w.iter().sum();
                std::array::from_fn(|k| (0..4).map(|j| w[j] / s * stored[t[j] as usize][k]).sum())
            } else {
                std::array::from_fn(|k| rng.gen_range(lo[k]..hi[k]))
            }
        })
        .collect();
    assert!(queries.iter().filter(|q| q.map(|c| c as f32 as f64) != **q).count() > n / 2, "most need f64");
    for name in ["cpu", "cpu --precision f64"] {
        let mut loc: Box<dyn BatchLocator> = match name {
            "cpu" => Box::new(CpuLocator::new(m.clone())),
            _ => Box::new(F64Values::new(CpuLocator::new(m.clone()), m.clone())),
        };
        let (mut ids, mut values) = (vec![0i32; n], vec![0f64; n]);
        loc.sample_many64(&queries, &["f"], &mut ids, &mut values).unwrap();
        let wrong: Vec<usize> = (0..n)
            .filter(|&i| match ids[i] {
                t if t >= 0 => !reference::contains(m.tets[t as usize].map(|v| stored[v as usize]), queries[i]),
                _ => !reference::locate_all(&m.tets, &stored, queries[i]).is_empty(),
            })
            .collect();
        assert!(
            wrong.is_empty(),
            "{name}: {} of {n} answers wrong, e.g. {:?}",
            wrong.len(),
            wrong.first().map(|&i| (queries[i], ids[i]))
        );
        assert_eq!(ids.iter().filter(|&&t| t < 0).count(), 0, "{name}: jets fills its box");
    }
    // What the f32 copy answered before (the points rounded to f32 steps of 0.25 m at y ≈ 4e6):
    // tets that do not hold the points as given.
    let rounded: Vec<Vec3> = queries.iter().map(|q| q.map(|c| c as f32)).collect();
    let mut ids32 = vec![0i32; n];
    CpuLocator::new(m.clone()).locate(&rounded, &mut ids32).unwrap();
    let wrong32 = (0..n)
        .filter(|&i| {
            ids32[i] >= 0 && !reference::contains(m.tets[ids32[i] as usize].map(|v| stored[v as usize]), queries[i])
        })
        .count();
    assert!(wrong32 > 0, "rounded points should land in wrong tets");
}

/// A particle's searches through the bins alone (a deferred locator readied for particles:
/// no BVH is built) answer as the BVH's, tet and weights bit for bit: on points exactly on
/// faces, edges and vertices (the tie rule taken from the bin's tets), between them and
/// outside, each looked up from no tet and from tets near and far (the walk from a tet, then
/// the bins' search where it fails), on the sheared Kuhn grids from ~1e-6 to ~1e6 and 1e7
/// from the origin.
#[test]
fn particles_searching_the_bins_get_the_bvhs_answers() {
    use super::grid_raster::tests::{kuhn_on_faces, ON_FACES};
    for (unit, corner) in ON_FACES {
        let (mesh, grid) = kuhn_on_faces(unit, corner);
        let bvh = CpuLocator::new(mesh.clone());
        let bins = CpuLocator::deferred(mesh.clone(), crate::bvh::BuildPreset::Fast);
        bins.ready_for_particles(false);
        let mut points: Vec<Vec3> = (0..grid.n_points()).map(|i| grid.point(i)).collect();
        // Between the grid points, and beyond the mesh on every side.
        let (lo, hi) = mesh.file_bounds();
        let mid: Vec<Vec3> = points.windows(2).map(|w| std::array::from_fn(|k| 0.5 * (w[0][k] + w[1][k]))).collect();
        points.extend(mid);
        points.extend((0..3).flat_map(|k| {
            let out = |x: f64| -> Vec3 {
                std::array::from_fn(|j| if j == k { x as f32 } else { (0.5 * (lo[j] + hi[j])) as f32 })
            };
            [out(lo[k] - 0.1 * (hi[k] - lo[k])), out(hi[k] + 0.1 * (hi[k] - lo[k]))]
        }));
        let (mut ties, mut outside) = (0, 0);
        for (i, &p) in points.iter().enumerate() {
            let starts = [None, Some(0), Some((i * 7 % mesh.n_tets()) as u32), Some(mesh.n_tets() as u32 - 1)];
            for start in starts {
                let (mut a, mut b) = (Hint::default(), Hint::default());
                (a.tet, b.tet) = (start, start);
                let (want, got) = (bvh.locate_near(p, &mut a), bins.locate_near(p, &mut b));
                let bits = |f: Option<(u32, geom::Bary)>| f.map(|(t, w)| (t, w.map(f32::to_bits)));
                assert_eq!(bits(got), bits(want), "unit {unit}, point {i} {p:?} from {start:?}");
                ties += usize::from(want.is_some_and(|(_, w)| w.contains(&0.0)));
                outside += usize::from(want.is_none());
            }
        }
        assert!(ties > 1000 && outside >= 24, "unit {unit}: {ties} ties, {outside} outside");
        assert!(!bins.index_built(), "unit {unit}: the bins' locator built its BVH");
    }
}

/// A built locator takes another time step's fields (`Mesh::with_fields`), its search kept:
/// its answers are then a fresh locator's on that mesh, bit for bit, for points (f32 and
/// f64) and for a rasterized grid whose slab held the old step's values; through the
/// layers that hold the mesh too. A mesh of another geometry is refused, nothing changed.
#[test]
fn a_built_locator_takes_another_steps_fields() {
    let first = Arc::new(grid_mesh(5, 0.25, 4));
    let flipped = |f: &crate::mesh::Field| {
        crate::mesh::Field::from_f64(
            f.name.clone(),
            f.location,
            (0..f.values.len()).map(|i| 2.5 - f.value64(i)).collect(),
        )
    };
    let step = Arc::new(first.with_fields(first.fields.iter().map(flipped).collect()).unwrap());
    let grid = ImageGrid::spanning([-0.05, 0.0, 0.01], [1.05, 1.0, 0.99], [17, 15, 13]).unwrap();
    let points = points_inside(&first, 300, 9);
    let points64: Vec<[f64; 3]> = points.iter().map(|p| p.map(|c| f64::from(c) + 1e-9)).collect();
    let fields = ["f", "cellval"];
    let answers = |loc: &mut dyn BatchLocator| {
        let n = grid.n_points();
        let (mut ids, mut values) = (vec![0; n], vec![0f32; 2 * n]);
        sample_grid(loc, &grid, 0..n, &fields, &mut ids, &mut values).unwrap();
        let (mut ids32, mut v32) = (vec![0; points.len()], vec![0f32; 2 * points.len()]);
        loc.sample_many(&points, &fields, &mut ids32, &mut v32).unwrap();
        let (mut ids64, mut v64) = (vec![0; points.len()], vec![0f64; 2 * points.len()]);
        loc.sample_many64(&points64, &fields, &mut ids64, &mut v64).unwrap();
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        (ids, bits(&values), ids32, bits(&v32), ids64, v64.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
    };
    let layered = |m: &Arc<crate::Mesh>| -> Box<dyn BatchLocator> {
        let cpu = cells::CellLocator::new(FiniteOnly::new(CpuLocator::new(m.clone())), m.clone());
        let f64_values = precision::F64Values::new(cpu, m.clone());
        Box::new(tolerance::WithTolerance::new(f64_values, m.clone(), tolerance::Tolerance::PercentOfMeanEdge(1.0)))
    };
    for build in [|m: &Arc<crate::Mesh>| -> Box<dyn BatchLocator> { Box::new(CpuLocator::new(m.clone())) }, layered] {
        let mut loc = build(&first);
        let before = answers(&mut *loc);
        assert!(loc.take_fields(&step));
        let taken = answers(&mut *loc);
        assert_eq!(taken, answers(&mut *build(&step)), "a fresh locator's answers on the step");
        assert_ne!(taken.1, before.1, "the step's values show");
        let other = Arc::new(grid_mesh(5, 0.25, 4));
        assert!(!loc.take_fields(&other), "another geometry (the same numbers, read anew)");
        assert_eq!(answers(&mut *loc), taken, "nothing changed");
    }
    // A mixed mesh through the layers: values from its cells' shape functions.
    use crate::gen::{generate_spec, CellKind, Shape, Spec};
    let raw = generate_spec(Spec { shape: Shape::Jets, cells: CellKind::Hybrid }, 400, 3, &|_| ());
    let first = Arc::new(crate::Mesh::new(raw, "hybrid").unwrap());
    let step = Arc::new(first.with_fields(first.fields.iter().map(flipped).collect()).unwrap());
    let names: Vec<&str> = first.fields.iter().map(|f| f.name.as_str()).collect();
    let points = points_inside(&first, 300, 9);
    let sampled = |loc: &mut dyn BatchLocator| {
        let (mut ids, mut values) = (vec![0; points.len()], vec![0f32; names.len() * points.len()]);
        loc.sample_many(&points, &names, &mut ids, &mut values).unwrap();
        (ids, values.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
    };
    let mut loc = layered(&first);
    let before = sampled(&mut *loc);
    assert!(first.cells.is_some() && loc.take_fields(&step));
    let taken = sampled(&mut *loc);
    assert!(taken == sampled(&mut *layered(&step)) && taken.1 != before.1, "a mixed mesh's step");
}
