//! Properties every cell type must have, checked over the whole table of types: codes and node
//! orders, shape functions (Kronecker, partition of unity, derivatives, polynomial
//! reproduction), the inverse map on warped cells, and the decomposition.

use super::*;
use proptest::prelude::*;
use rand::{Rng, SeedableRng};

/// Every type with a reference shape (the polyhedron has none: `polyhedron.rs` tests it).
fn shaped() -> impl Iterator<Item = CellType> {
    CellType::all().filter(|t| !t.is_polyhedron())
}

type Rng64 = rand_pcg::Pcg64;

/// A uniform random point of `shape`'s domain, at least `inset` inside every side.
fn random_pc(shape: &Shape, rng: &mut Rng64, inset: f64) -> PCoords {
    loop {
        let pc: PCoords = std::array::from_fn(|_| rng.gen_range(0.0..1.0));
        if shape.margin(pc) >= inset {
            return pc;
        }
    }
}

/// The nodes of `cell` with straight sides, under the affine map x = A·y + b of the
/// reference corners.
fn affine_nodes(cell: &dyn CellDef, a: [[f64; 3]; 3], b: Point) -> Vec<Point> {
    let shape = cell.shape();
    let corners: Vec<Point> = reference_corners(shape)
        .iter()
        .map(|y| std::array::from_fn(|i| b[i] + (0..3).map(|k| a[i][k] * y[k]).sum::<f64>()))
        .collect();
    cell.node_pcoords().iter().map(|pc| forward(shape.linear, &corners, *pc)).collect()
}

/// A random well-shaped affine map with dyadic coefficients (multiples of 1/8) and an integer
/// shift: the images of dyadic points are exact in f64, so planar stays exactly planar.
fn random_affine(rng: &mut Rng64) -> ([[f64; 3]; 3], Point) {
    loop {
        let s = f64::from(rng.gen_range(1..=3));
        let a: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|k| s * (f64::from(u8::from(i == k)) + f64::from(rng.gen_range(-2i8..=2)) / 8.0))
        });
        let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
        if det > 0.25 * s * s * s {
            return (a, std::array::from_fn(|_| f64::from(rng.gen_range(-100i8..=100))));
        }
    }
}

/// Where a shape's corners sit in space for the tests: its parametric corners, except the
/// pyramid's apex, which stands over the base's centre (in parametric space it is the whole
/// top face).
fn reference_corners(shape: &Shape) -> Vec<Point> {
    let mut c = shape.corners.to_vec();
    if shape.name == "pyramid" {
        c[4] = [0.5, 0.5, 1.0];
    }
    c
}

fn jacobian_det(cell: &dyn CellDef, nodes: &[Point], pc: PCoords) -> f64 {
    let mut d = vec![[0.0; 3]; nodes.len()];
    cell.shape_derivatives(pc, &mut d);
    let mut j = [[0.0; 3]; 3];
    for (n, di) in nodes.iter().zip(&d) {
        for r in 0..3 {
            for c in 0..3 {
                j[r][c] += n[r] * di[c];
            }
        }
    }
    j[0][0] * (j[1][1] * j[2][2] - j[1][2] * j[2][1]) - j[0][1] * (j[1][0] * j[2][2] - j[1][2] * j[2][0])
        + j[0][2] * (j[1][0] * j[2][1] - j[1][1] * j[2][0])
}

#[test]
fn every_type_is_found_by_its_codes() {
    let mut names = Vec::new();
    for t in shaped() {
        let def = t.def();
        assert_eq!(CellType::from_vtk(def.vtk_type(), def.n_nodes()), Some(t), "{def:?}");
        for g in def.gmsh_types() {
            let (found, gt) = CellType::from_gmsh(g.code).unwrap();
            assert_eq!((found, gt.code), (t, g.code), "{def:?}");
            assert_eq!(g.vtk_from_gmsh.len(), def.n_nodes(), "{def:?}: Gmsh {}", g.code);
            assert!(g.vtk_from_gmsh.iter().all(|&k| usize::from(k) < g.n_nodes), "{def:?}: Gmsh {}", g.code);
        }
        assert_eq!(&def.node_pcoords()[..def.shape().n_corners()], def.shape().corners, "{def:?}: corners first");
        names.push((def.vtk_type(), def.n_nodes()));
    }
    let n = names.len();
    names.sort_unstable();
    names.dedup();
    assert_eq!(names.len(), n, "two types share a VTK code and node count");
    assert_eq!(CellType::from_vtk(12, 9), None);
    assert_eq!(CellType::from_vtk(42, 8), None, "polyhedra are not cell types");
    assert_eq!(CellType::from_gmsh(4).unwrap().0, CellType::tet());
    assert_eq!(CellType::from_vtk(24, 10).unwrap().def().order(), 2);
    assert_eq!(CellType::from_vtk(71, 20).unwrap().def().order(), 3);
    assert_eq!(CellType::from_vtk(72, 64).unwrap().def().order(), 3);
    assert_eq!(CellType::from_vtk(73, 40).unwrap().def().order(), 3);
}

#[test]
fn kronecker_partition_of_unity_and_polynomial_reproduction() {
    let mut rng = Rng64::seed_from_u64(1);
    for t in shaped() {
        let def = t.def();
        let n = def.n_nodes();
        let (mut w, mut d) = (vec![0.0; n], vec![[0.0; 3]; n]);
        if def.interpolates_nodes() {
            for (j, pc) in def.node_pcoords().iter().enumerate() {
                def.shape_functions(*pc, &mut w);
                for (i, wi) in w.iter().enumerate() {
                    let want = if i == j { 1.0 } else { 0.0 };
                    assert!((wi - want).abs() < 1e-12, "{def:?}: N{i} at node {j} is {wi}");
                }
            }
        }
        for _ in 0..50 {
            let pc = random_pc(def.shape(), &mut rng, 0.0);
            def.shape_functions(pc, &mut w);
            def.shape_derivatives(pc, &mut d);
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{def:?}: Σ N = {} at {pc:?}", w.iter().sum::<f64>());
            for k in 0..3 {
                let s: f64 = d.iter().map(|di| di[k]).sum();
                assert!(s.abs() < 1e-10, "{def:?}: Σ ∂N/∂pc{k} = {s}");
            }
            // On the straight-sided reference cell, linear fields of the position are
            // reproduced by every type (Bezier included: its control points are the lattice).
            let nodes = affine_nodes(def, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [0.0; 3]);
            let x = forward(def.shape().linear, &reference_corners(def.shape()), pc);
            for k in 0..3 {
                let got: f64 = nodes.iter().zip(&w).map(|(q, wi)| wi * q[k]).sum();
                assert!((got - x[k]).abs() < 1e-11, "{def:?}: x{k} is not reproduced at {pc:?}");
            }
        }
    }
}

#[test]
fn derivatives_match_finite_differences() {
    let mut rng = Rng64::seed_from_u64(2);
    let h = 1e-6;
    for t in shaped() {
        let def = t.def();
        let n = def.n_nodes();
        let (mut d, mut wp, mut wm) = (vec![[0.0; 3]; n], vec![0.0; n], vec![0.0; n]);
        for _ in 0..10 {
            let pc = random_pc(def.shape(), &mut rng, 0.01);
            def.shape_derivatives(pc, &mut d);
            for k in 0..3 {
                let (mut p, mut m) = (pc, pc);
                p[k] += h;
                m[k] -= h;
                def.shape_functions(p, &mut wp);
                def.shape_functions(m, &mut wm);
                for i in 0..n {
                    let fd = (wp[i] - wm[i]) / (2.0 * h);
                    assert!(
                        (fd - d[i][k]).abs() < 1e-5 * (1.0 + fd.abs()),
                        "{def:?}: ∂N{i}/∂pc{k} {} vs {fd}",
                        d[i][k]
                    );
                }
            }
        }
    }
}

/// f = x² + y² + z² is reproduced exactly by every cell type of order ≥ 2 with straight sides
/// (the defect of issue 9 item 8: linear interpolation misses it by 0.5).
#[test]
fn quadratic_fields_are_exact_on_quadratic_cells() {
    let mut rng = Rng64::seed_from_u64(3);
    let f = |x: Point| x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
    // VTK's 13-node pyramid has polynomial shape functions in (r, s, t), where a quadratic of the
    // position is rational (the apex collapses a face): it is exact for linear fields only.
    let exact = |t: &CellType| t.def().order() >= 2 && t.def().interpolates_nodes() && t.shape().name != "pyramid";
    for t in shaped().filter(exact) {
        let def = t.def();
        for _ in 0..20 {
            let (a, b) = random_affine(&mut rng);
            let nodes = affine_nodes(def, a, b);
            let values: Vec<f64> = nodes.iter().map(|&x| f(x)).collect();
            let pc = random_pc(def.shape(), &mut rng, 0.0);
            let x = forward(def, &nodes, pc);
            // Located by the corners (the linear cell), then interpolated with every node.
            let located = invert(def.shape().linear, &nodes[..def.shape().n_corners()], x).unwrap();
            let got = interpolate(def, located, |i| values[i]);
            assert!((got - f(x)).abs() <= 1e-9 * f(x).max(1.0), "{def:?}: {got} vs {}", f(x));
        }
    }
}

/// Gmsh's node orders, rebuilt from Gmsh's own tables of edges and faces (MHexahedron.h,
/// MPrism.h, MPyramid.h, MTetrahedron.h): corners, edge midpoints, face centres, centre.
#[test]
fn gmsh_node_orders_follow_gmsh_tables() {
    let hex_edges: &[[usize; 2]] =
        &[[0, 1], [0, 3], [0, 4], [1, 2], [1, 5], [2, 3], [2, 6], [3, 7], [4, 5], [4, 7], [5, 6], [6, 7]];
    let hex_faces: &[&[usize]] =
        &[&[0, 3, 2, 1], &[0, 1, 5, 4], &[0, 4, 7, 3], &[1, 2, 6, 5], &[2, 3, 7, 6], &[4, 5, 6, 7]];
    let prism_edges: &[[usize; 2]] = &[[0, 1], [0, 2], [0, 3], [1, 2], [1, 4], [2, 5], [3, 4], [3, 5], [4, 5]];
    let prism_quads: &[&[usize]] = &[&[0, 1, 4, 3], &[0, 3, 5, 2], &[1, 2, 5, 4]];
    let pyramid_edges: &[[usize; 2]] = &[[0, 1], [0, 3], [0, 4], [1, 2], [1, 4], [2, 3], [2, 4], [3, 4]];
    let tet_edges: &[[usize; 2]] = &[[0, 1], [1, 2], [2, 0], [3, 0], [3, 2], [3, 1]];
    let mean = |c: &[PCoords], idx: &[usize]| -> PCoords {
        std::array::from_fn(|k| idx.iter().map(|&i| c[i][k]).sum::<f64>() / idx.len() as f64)
    };
    let build = |corners: &[PCoords], edges: &[[usize; 2]], faces: &[&[usize]], centre: bool| {
        let mut v: Vec<PCoords> = corners.to_vec();
        v.extend(edges.iter().map(|e| mean(corners, e)));
        v.extend(faces.iter().map(|f| mean(corners, f)));
        if centre {
            v.push(mean(corners, &(0..corners.len()).collect::<Vec<_>>()));
        }
        v
    };
    let (h, w, p, t) =
        (hex::SHAPE.corners, wedge::SHAPE.corners, &reference_corners(&pyramid::SHAPE), tet::SHAPE.corners);
    let mut pyramid14 = build(p, pyramid_edges, &[], false);
    pyramid14.push([0.5, 0.5, 0.0]);
    let cases: [(u8, Vec<PCoords>); 7] = [
        (11, build(t, tet_edges, &[], false)),
        (17, build(h, hex_edges, &[], false)),
        (12, build(h, hex_edges, hex_faces, true)),
        (18, build(w, prism_edges, &[], false)),
        (13, build(w, prism_edges, prism_quads, false)),
        (19, build(p, pyramid_edges, &[], false)),
        (14, pyramid14),
    ];
    for (code, gmsh_nodes) in cases {
        let (t, g) = CellType::from_gmsh(code).unwrap();
        assert_eq!(g.n_nodes, gmsh_nodes.len(), "Gmsh {code}");
        let corners = reference_corners(t.shape());
        for (i, pc) in t.def().node_pcoords().iter().enumerate() {
            let x = forward(t.shape().linear, &corners, *pc);
            assert_eq!(x, gmsh_nodes[usize::from(g.vtk_from_gmsh[i])], "Gmsh {code}: VTK node {i}");
        }
    }
}

/// A random cell: an affine image of the reference with its corners moved by up to `warp`
/// (relative), higher-order nodes following the warped linear map plus a little curvature.
fn warped_nodes(def: &dyn CellDef, rng: &mut Rng64, warp: f64) -> Vec<Point> {
    let (a, b) = random_affine(rng);
    let shape = def.shape();
    let mut corners = affine_nodes(shape.linear, a, b);
    let scale = a[0][0].abs();
    for c in &mut corners {
        for x in c.iter_mut() {
            *x += rng.gen_range(-warp..=warp) * scale;
        }
    }
    def.node_pcoords()
        .iter()
        .enumerate()
        .map(|(i, pc)| {
            let x = forward(shape.linear, &corners, *pc);
            if i < corners.len() {
                x
            } else {
                x.map(|c| c + rng.gen_range(-0.02..=0.02) * scale)
            }
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Newton's method inverts the forward map on warped cells of every type, from anywhere in
    /// the domain (the pyramid up to near its apex, where the map degenerates).
    #[test]
    fn newton_inverts_the_forward_map(seed in any::<u64>(), warp in 0.0f64..0.15) {
        let mut rng = Rng64::seed_from_u64(seed);
        for t in shaped().filter(|t| t.def().order() <= 3) {
            let def = t.def();
            let nodes = warped_nodes(def, &mut rng, warp);
            let mut pc = random_pc(def.shape(), &mut rng, 0.0);
            if def.shape().name == "pyramid" {
                pc[2] = pc[2].min(0.95);
            }
            if jacobian_det(def, &nodes, pc) <= 0.0 {
                continue; // folded by the warp: no unique inverse
            }
            let x = forward(def, &nodes, pc);
            let got = invert(def, &nodes, x).map_err(|e| TestCaseError::fail(format!("{def:?}: {e} at {pc:?}")))?;
            let back = forward(def, &nodes, got);
            let size = nodes.iter().flatten().fold(0.0f64, |m, c| m.max(c.abs()));
            prop_assert!((0..3).all(|k| (back[k] - x[k]).abs() <= 1e-12 * size), "{def:?}: x({got:?}) = {back:?}, not {x:?}");
            // A warped cell can fold elsewhere in its domain: then another preimage inside it
            // is as right as `pc` (one outside is not).
            let same = (0..3).all(|k| (got[k] - pc[k]).abs() <= 1e-8);
            prop_assert!(same || def.shape().margin(got) >= -1e-12, "{def:?}: {got:?} vs {pc:?}");
        }
    }

    /// Decompositions: positive tets for valid cells with planar faces, whose volumes sum to
    /// the cell's (the integral of its Jacobian), whatever the global ids.
    #[test]
    fn decompositions_fill_planar_cells(seed in any::<u64>()) {
        let mut rng = Rng64::seed_from_u64(seed);
        for shape in [&tet::SHAPE, &pyramid::SHAPE, &wedge::SHAPE, &hex::SHAPE] {
            let (a, b) = random_affine(&mut rng);
            let mut corners = affine_nodes(shape.linear, a, b);
            if shape.name == "hexahedron" || shape.name == "wedge" {
                // A frustum: the top face scaled about its first corner keeps every face planar
                // (dyadic scales keep it exact).
                let k = f64::from(rng.gen_range(4..=12)) / 8.0;
                let n = corners.len() / 2;
                let centre = corners[n];
                for p in &mut corners[n..] {
                    *p = std::array::from_fn(|c| centre[c] + k * (p[c] - centre[c]));
                }
            }
            prop_assert_eq!(warped_faces(shape, &corners), 0, "{} should have planar faces", shape.name);
            let want = volume(shape.linear, &corners);
            for _ in 0..4 {
                let ids: Vec<u32> = (0..shape.n_corners()).map(|_| rng.gen_range(0..12)).collect();
                let mut ids = ids;
                ids.sort_unstable();
                ids.dedup();
                if ids.len() < shape.n_corners() {
                    continue;
                }
                let mut ids: Vec<u32> = ids;
                for i in (1..ids.len()).rev() {
                    ids.swap(i, rng.gen_range(0..=i));
                }
                let mut sum = 0.0;
                for tet in decompose(shape, &ids).tets() {
                    let v = crate::geom::tet_volume6(tet.map(|k| corners[usize::from(k)].map(|c| c as f32))) / 6.0;
                    let v64 = tet_volume(tet.map(|k| corners[usize::from(k)]));
                    prop_assert!(v64 > 0.0 && v > 0.0, "{}: tet {tet:?} has volume {v64}", shape.name);
                    sum += v64;
                }
                prop_assert!((sum - want).abs() <= 1e-10 * want, "{}: {sum} vs {want}", shape.name);
            }
        }
    }

    /// Two cells that share a quad face split it into the same two triangles, whatever their
    /// shapes and the face's rotation in each.
    #[test]
    fn neighbours_split_shared_faces_alike(seed in any::<u64>()) {
        let mut rng = Rng64::seed_from_u64(seed);
        let quads = |s: &'static Shape| (0..s.faces.len()).filter(move |&f| s.faces[f].len() == 4);
        let shapes = [&pyramid::SHAPE, &wedge::SHAPE, &hex::SHAPE];
        let (sa, sb) = (shapes[rng.gen_range(0..3)], shapes[rng.gen_range(0..3)]);
        let fa = quads(sa).nth(rng.gen_range(0..quads(sa).count())).unwrap();
        let fb = quads(sb).nth(rng.gen_range(0..quads(sb).count())).unwrap();
        // Distinct random ids, then cell b takes a's face ids on its face, reversed (seen from
        // the other side) and rotated.
        let mut pool: Vec<u32> = (0..40).collect();
        for i in (1..pool.len()).rev() {
            pool.swap(i, rng.gen_range(0..=i));
        }
        let ids_a: Vec<u32> = pool[..sa.n_corners()].to_vec();
        let mut ids_b: Vec<u32> = pool[20..20 + sb.n_corners()].to_vec();
        let face_ids: Vec<u32> = sa.faces[fa].iter().map(|&k| ids_a[usize::from(k)]).collect();
        let rot = rng.gen_range(0..4);
        for (j, &k) in sb.faces[fb].iter().enumerate() {
            ids_b[usize::from(k)] = face_ids[(4 + rot - j) % 4];
        }
        let on_face = |s: &Shape, ids: &[u32], f: usize| {
            let mut tris: Vec<[u32; 3]> = Vec::new();
            for tet in decompose(s, ids).tets() {
                for (i, face) in tet_faces(s, *tet).iter().enumerate() {
                    if *face == Some(f as u8) {
                        let mut tri: Vec<u32> = (0..4).filter(|&k| k != i).map(|k| ids[usize::from(tet[k])]).collect();
                        tri.sort_unstable();
                        tris.push([tri[0], tri[1], tri[2]]);
                    }
                }
            }
            tris.sort_unstable();
            tris
        };
        let (ta, tb) = (on_face(sa, &ids_a, fa), on_face(sb, &ids_b, fb));
        prop_assert_eq!(ta.len(), 2, "a quad face is covered by two triangles");
        prop_assert_eq!(ta, tb);
    }
}

fn tet_volume(v: [Point; 4]) -> f64 {
    let d = |k: usize| [v[k][0] - v[0][0], v[k][1] - v[0][1], v[k][2] - v[0][2]];
    let (a, b, c) = (d(1), d(2), d(3));
    (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6.0
}

/// The volume of a cell, ∫ det J over its domain, by 5-point Gauss–Legendre rules on the cube
/// mapped onto the domain (collapsed for the simplex directions).
fn volume(def: &dyn CellDef, nodes: &[Point]) -> f64 {
    const X: [f64; 5] = [0.046910077030668, 0.2307653449471585, 0.5, 0.7692346550528415, 0.953089922969332];
    const W: [f64; 5] =
        [0.1184634425280945, 0.2393143352496832, 0.2844444444444444, 0.2393143352496832, 0.1184634425280945];
    let mut sum = 0.0;
    for (i, &a) in X.iter().enumerate() {
        for (j, &b) in X.iter().enumerate() {
            for (k, &c) in X.iter().enumerate() {
                let (pc, jac) = match def.shape().name {
                    "tetra" => ([a, (1.0 - a) * b, (1.0 - a) * (1.0 - b) * c], (1.0 - a) * (1.0 - a) * (1.0 - b)),
                    "wedge" => ([a, (1.0 - a) * b, c], 1.0 - a),
                    _ => ([a, b, c], 1.0),
                };
                sum += W[i] * W[j] * W[k] * jac * jacobian_det(def, nodes, pc);
            }
        }
    }
    sum
}

#[test]
fn decomposition_tets_know_their_cell_faces() {
    for shape in [&tet::SHAPE, &pyramid::SHAPE, &wedge::SHAPE, &hex::SHAPE] {
        let ids: Vec<u32> = (0..shape.n_corners() as u32).rev().collect();
        let mut per_face = vec![0; shape.faces.len()];
        for tet in decompose(shape, &ids).tets() {
            for f in tet_faces(shape, *tet).into_iter().flatten() {
                per_face[usize::from(f)] += 1;
            }
        }
        let want: Vec<usize> = shape.faces.iter().map(|f| f.len() - 2).collect();
        assert_eq!(per_face, want, "{}: boundary triangles per face", shape.name);
    }
}

#[test]
fn pyramid_apex_and_singular_cells() {
    let p = pyramid::SHAPE.corners.to_vec();
    // At the apex itself the residual vanishes on the way: any (r, s, 1) is the answer.
    let pc = invert(&pyramid::Pyramid, &p, [0.0, 0.0, 1.0]).unwrap();
    assert!((pc[2] - 1.0).abs() < 1e-12 && pyramid::SHAPE.contains(pc), "{pc:?}");
    let near = invert(&pyramid::Pyramid, &p, [0.3e-6, 0.2e-6, 1.0 - 1e-6]).unwrap();
    assert!(pyramid::SHAPE.contains(near), "{near:?}");
    // Above the apex: t > 1, outside through no face.
    let above = invert(&pyramid::Pyramid, &p, [0.0, 0.0, 1.5]).unwrap();
    assert_eq!(pyramid::SHAPE.violated(above).first().map(|v| v.0), Some(None), "{above:?}");
    // A flat hex has no inverse map.
    let flat: Vec<Point> = hex::SHAPE.corners.iter().map(|c| [c[0], c[1], 0.0]).collect();
    assert_eq!(invert(&hex::Hex, &flat, [0.3, 0.6, 0.0]), Err(InverseError::Singular));
}

#[test]
fn violated_faces_name_the_way_out() {
    let h = &hex::SHAPE;
    assert!(h.violated([0.5, 0.5, 0.5]).is_empty());
    assert_eq!(h.violated([1.2, 0.5, -0.1]).iter().map(|v| v.0).collect::<Vec<_>>(), vec![Some(1), Some(4)]);
    assert_eq!(wedge::SHAPE.violated([0.7, 0.6, 0.5])[0].0, Some(3));
    assert_eq!(tet::SHAPE.violated([0.2, -0.1, 0.3])[0].0, Some(0));
    assert!(h.contains([1.0, 0.0, 0.5]), "the boundary is inside");
}

#[test]
fn cell_blocks() {
    let hex = CellType::from_vtk(12, 8).unwrap();
    let mut b = CellBlock::default();
    b.push(CellType::tet(), &[0, 1, 2, 3]);
    b.push(hex, &[0, 1, 2, 3, 4, 5, 6, 7]);
    b.push(CellType::from_vtk(24, 10).unwrap(), &(10..20).collect::<Vec<_>>());
    assert_eq!((b.len(), b.nodes(1).len(), b.corners(2)), (3, 8, &[10, 11, 12, 13][..]));
    assert_eq!(b.non_tet_counts(), Some(vec![("hexahedron".to_string(), 1)]));
    let mut c = CellBlock::default();
    c.append(&b, 100);
    assert_eq!(c.nodes(2)[0], 110);
    let tets_only = CellBlock {
        types: vec![b.types[0], b.types[2]],
        ends: vec![4, 14],
        conn: (0..14).collect(),
        ..CellBlock::default()
    };
    assert_eq!(tets_only.non_tet_counts(), None);
}
