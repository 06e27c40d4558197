use super::*;
use crate::geom::Vec3;
use crate::locate::CpuLocator;
use crate::mesh::{FieldLocation, Mesh};
use std::sync::Arc;

const SIZES: [usize; 2] = [8_000, 60_000];

fn mesh(shape: Shape, tets: usize, seed: u64) -> Mesh {
    Mesh::new(generate(shape, tets, seed), format!("gen {shape} {tets}")).unwrap()
}

fn occupancy(m: &Mesh) -> f64 {
    let (lo, hi) = (m.info.bounds_min, m.info.bounds_max);
    let box_volume: f64 = (0..3).map(|k| hi[k] as f64 - lo[k] as f64).product();
    m.info.total_volume / box_volume
}

#[test]
fn shape_names_round_trip() {
    for s in Shape::ALL {
        assert_eq!(s.to_string().parse::<Shape>().unwrap(), s);
    }
    assert_eq!(" Fusion".parse::<Shape>().unwrap(), Shape::Fusion);
    let err = "torus".parse::<Shape>().unwrap_err().to_string();
    assert!(err.contains("torus") && err.contains("agulhas"), "{err}");
}

#[test]
fn tet_counts_land_near_the_target() {
    for shape in Shape::ALL {
        for target in [5_000, 8_000, 13_000, 30_000, 60_000, 150_000, 400_000] {
            let n = generate(shape, target, 1).tets.len();
            let err = (n as f64 / target as f64 - 1.0).abs();
            assert!(err < 0.05, "{shape} {target}: {n} tets ({:.1} % off)", 100.0 * err);
        }
    }
}

#[test]
fn deterministic_for_a_seed_different_for_another() {
    for shape in Shape::ALL {
        let (a, b, c) = (generate(shape, 5_000, 7), generate(shape, 5_000, 7), generate(shape, 5_000, 8));
        assert_eq!(a.points, b.points, "{shape}");
        assert_eq!(a.tets, b.tets, "{shape}");
        assert_eq!(a.fields[0].values, b.fields[0].values, "{shape}");
        assert_ne!(a.points, c.points, "{shape}: seeds 7 and 8 give the same vertices");
    }
}

/// Every interior face shared by exactly two tets, and every boundary face really on the
/// boundary: just outside it (outwards, a thousandth of its size away) there is no tet. A
/// crack or a hanging node leaves boundary faces inside the mesh.
#[test]
fn conforming_with_a_true_boundary() {
    for shape in Shape::ALL {
        for target in SIZES {
            let m = Arc::new(mesh(shape, target, 3));
            assert_eq!(m.faces().stats.n_non_manifold, 0, "{shape} {target}");
            let inside = boundary_faces_inside(&m);
            assert!(inside.is_empty(), "{shape} {target}: boundary faces with a tet beyond: {inside:?}");
        }
    }
}

/// Boundary faces (up to 5) that have a tet just beyond them.
fn boundary_faces_inside(m: &Arc<Mesh>) -> Vec<[u32; 3]> {
    let loc = CpuLocator::new(m.clone());
    let p = |i: u32| m.points[i as usize].map(|c| c as f64);
    m.faces()
        .faces
        .iter()
        .filter(|f| f.front < 0 || f.back < 0)
        .filter(|f| {
            let (a, b, c) = (p(f.v[0]), p(f.v[1]), p(f.v[2]));
            let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
            // (v1-v0)×(v2-v0) points away from `front`: outwards when the tet is in front.
            let s = if f.front >= 0 { 1.0 } else { -1.0 };
            let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]].map(|x| s * x);
            let len = |w: [f64; 3]| (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
            let step = 1e-3 * len(u).max(len(v)) / len(n);
            let q: Vec3 = std::array::from_fn(|k| ((a[k] + b[k] + c[k]) / 3.0 + step * n[k]) as f32);
            loc.locate_point(q).is_some()
        })
        .map(|f| f.v)
        .take(5)
        .collect()
}

/// The boundary check catches a hanging node (one tet against two that split the shared
/// face at the midpoint of an edge) and a crack (two cubes whose splits put different
/// diagonals on their shared face).
#[test]
fn boundary_check_sees_hanging_nodes_and_cracks() {
    let check = |points: Vec<Vec3>, tets: Vec<[u32; 4]>| {
        boundary_faces_inside(&Arc::new(Mesh::new(RawMesh { points, tets, ..Default::default() }, "t").unwrap())).len()
    };
    let points: Vec<Vec3> =
        vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.5, 0.5, 1.0], [0.5, 0.5, -1.0], [1.0, 0.0, 0.0]];
    let (a, b, c, top, bottom, mid) = (0, 1, 2, 3, 4, 5);
    assert!(check(points.clone(), vec![[a, b, c, top], [a, mid, c, bottom], [mid, b, c, bottom]]) > 0);
    assert_eq!(check(points, vec![[a, b, c, top], [a, b, c, bottom]]), 0);

    // A 3×2×2 lattice of points, id = x + 3y + 6z, holding two unit cubes side by side.
    let points: Vec<Vec3> = (0..12).map(|i| [(i % 3) as f32, ((i / 3) % 2) as f32, (i / 6) as f32]).collect();
    let kuhn = [[0, 1, 7, 3], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 7, 6], [0, 4, 7, 5], [0, 4, 6, 7]];
    let cube = |x0: u32, mirror: u32| {
        kuhn.map(|t| t.map(|c| c ^ mirror).map(|c| x0 + (c & 1) + 3 * ((c >> 1) & 1) + 6 * (c >> 2)))
    };
    // Cube B (x in [1, 2]) mirrored in y: the diagonal of its face x = 1 crosses cube A's.
    assert!(check(points.clone(), [cube(0, 0), cube(1, 2)].concat()) > 0);
    assert_eq!(check(points, [cube(0, 0), cube(1, 0)].concat()), 0);
}

#[test]
fn independent_of_the_number_of_threads() {
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    for shape in Shape::ALL {
        let (a, b) = (one.install(|| generate(shape, 30_000, 5)), generate(shape, 30_000, 5));
        assert_eq!((a.points, a.tets), (b.points, b.tets), "{shape}");
    }
}

#[test]
fn no_degenerate_or_inverted_tets_and_no_unused_vertices() {
    for shape in Shape::ALL {
        for (target, seed) in [(SIZES[0], 11), (SIZES[1], 12), (300_000, 13)] {
            let m = mesh(shape, target, seed);
            assert_eq!(m.info.n_degenerate, 0, "{shape} {target}");
            assert_eq!(m.info.n_reoriented, 0, "{shape} {target}");
            let mut used = vec![false; m.points.len()];
            for t in m.tets.iter() {
                for &v in t {
                    used[v as usize] = true;
                }
            }
            assert!(used.iter().all(|&u| u), "{shape} {target}: unused vertices");
        }
    }
}

/// Coarse grids are where the torus' sweep and warp are least affine: many seeds there.
#[test]
fn no_inverted_tets_on_coarse_grids_for_many_seeds() {
    for shape in Shape::ALL {
        for target in [0, 2_000, 10_000] {
            for seed in 0..20 {
                let m = mesh(shape, target, seed);
                assert_eq!((m.info.n_degenerate, m.info.n_reoriented), (0, 0), "{shape} {target} seed {seed}");
            }
        }
    }
}

#[test]
fn occupancy_matches_the_papers_data_sets() {
    for shape in Shape::ALL {
        for (target, seed) in [(SIZES[0], 1), (SIZES[1], 2), (SIZES[1], 3)] {
            let occ = occupancy(&mesh(shape, target, seed));
            let want = shape.target_occupancy();
            assert!((occ - want).abs() < 0.05, "{shape} {target} seed {seed}: occupancy {occ:.3}, want {want}");
        }
    }
}

/// Jitter leaves no face with an exactly axis-aligned normal, except where `jets` must lie
/// flat on its box.
#[test]
fn no_axis_aligned_faces() {
    for shape in Shape::ALL {
        let m = mesh(shape, SIZES[0], 5);
        let p = |i: u32| m.points[i as usize].map(|c| c as f64);
        for f in &m.faces().faces {
            if shape == Shape::Jets && (f.front < 0 || f.back < 0) {
                continue;
            }
            let (a, b, c) = (p(f.v[0]), p(f.v[1]), p(f.v[2]));
            let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
            let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
            let zeros = n.iter().filter(|&&x| x == 0.0).count();
            assert!(zeros < 2, "{shape}: face {:?} has normal {n:?}", f.v);
        }
    }
}

#[test]
fn jets_box_faces_are_flat_and_full() {
    let m = mesh(Shape::Jets, SIZES[0], 9);
    assert_eq!(m.info.bounds_min, [0.0, 0.0, 0.0]);
    assert_eq!(m.info.bounds_max, [1.0, 1.0, 2.0]);
    assert!((occupancy(&m) - 1.0).abs() < 1e-9);
}

#[test]
fn fields_are_there_and_finite() {
    for shape in Shape::ALL {
        let m = mesh(shape, SIZES[0], 4);
        let f = m.field("f").unwrap();
        assert_eq!((f.location, f.values.len()), (FieldLocation::Vertex, m.points.len()));
        assert!(f.values.iter().all(|v| v.is_finite()));
        // Smooth: the same formula as the shared data, at each vertex.
        let p = m.points[m.points.len() / 2].map(|c| c as f64);
        let want = (3.0 * p[0] + 1.0).sin() * (2.0 * p[1]).cos() + 0.5 * (4.0 * p[2]).sin() + 0.3 * p[0] * p[1];
        assert!((f.values[m.points.len() / 2] as f64 - want).abs() < 1e-5);
        let c = m.field("cellval").unwrap();
        assert_eq!((c.location, c.values.len()), (FieldLocation::Cell, m.n_tets()));
        assert!(c.values.iter().all(|v| (0.0..=1.0).contains(v)));
        assert_eq!(c.values[1], (2_654_435_761.0f64 / 4_294_967_296.0) as f32);
    }
}

#[test]
fn the_cpu_locator_finds_every_tet_centre_in_its_tet() {
    for shape in Shape::ALL {
        let m = Arc::new(mesh(shape, 20_000, 6));
        let loc = CpuLocator::new(m.clone());
        let wrong: Vec<(usize, Option<u32>)> = (0..m.n_tets())
            .filter_map(|t| {
                let got = loc.locate_point(m.tet_center(t)).map(|(id, _)| id);
                (got != Some(t as u32)).then_some((t, got))
            })
            .take(5)
            .collect();
        assert!(wrong.is_empty(), "{shape}: centres found elsewhere (tet, found): {wrong:?}");
    }
}

#[test]
fn tiny_and_zero_targets_still_give_valid_meshes() {
    for shape in Shape::ALL {
        for target in [0, 1, 100] {
            let m = mesh(shape, target, 0);
            assert!(m.n_tets() > 0);
            assert_eq!(m.info.n_degenerate + m.info.n_reoriented, 0, "{shape} {target}");
            assert_eq!(m.faces().stats.n_non_manifold, 0);
        }
    }
}

#[test]
fn progress_increases_to_one() {
    let seen = std::sync::Mutex::new(Vec::<f64>::new());
    let mesh = generate_with_progress(Shape::Agulhas, 50_000, 1, &|f| seen.lock().unwrap().push(f));
    assert!(!mesh.tets.is_empty());
    let seen = seen.into_inner().unwrap();
    assert!(seen.len() >= 3, "{seen:?}");
    assert!(seen.windows(2).all(|w| w[0] < w[1]), "{seen:?}");
    assert_eq!((seen[0], *seen.last().unwrap()), (0.0, 1.0));
}

/// `fusion` is graded: much finer at the centre line than at the surface.
#[test]
fn fusion_is_finer_near_the_centre_line() {
    let m = mesh(Shape::Fusion, 300_000, 2);
    // Distance from the centre line (major radius 1 in the plane z = 0) of a point.
    let d = |p: Vec3| (((p[0] as f64).hypot(p[1] as f64) - 1.0).powi(2) + (p[2] as f64 / 1.4).powi(2)).sqrt();
    let (mut inner, mut outer) = ((0.0, 0usize), (0.0, 0usize));
    for t in 0..m.n_tets() {
        let r = d(m.tet_center(t)) / 0.4786;
        let v = m.tets[t].map(|i| m.points[i as usize]);
        let vol = crate::geom::tet_volume6(v) / 6.0;
        if r < 0.1 {
            inner = (inner.0 + vol, inner.1 + 1);
        } else if r > 0.8 {
            outer = (outer.0 + vol, outer.1 + 1);
        }
    }
    let ratio = (outer.0 / outer.1 as f64) / (inner.0 / inner.1 as f64);
    eprintln!("fusion: outer/inner tet volume {ratio:.1}");
    assert!(ratio > 8.0, "outer tets only {ratio:.1}× larger than inner ones");
}

/// Sizes, occupancy and speed; run with
/// `cargo test --release -p tetloc-core --lib gen::tests::report -- --ignored --nocapture`
/// (`TETLOC_GEN_SIZES=1000000,12000000` to choose sizes).
#[test]
#[ignore]
fn report() {
    let sizes: Vec<usize> = std::env::var("TETLOC_GEN_SIZES")
        .map(|s| s.split(',').map(|x| x.trim().parse().unwrap()).collect())
        .unwrap_or_else(|_| vec![1_000_000]);
    for &target in &sizes {
        for shape in Shape::ALL {
            let t0 = std::time::Instant::now();
            let raw = generate(shape, target, 1);
            let secs = t0.elapsed().as_secs_f64();
            let (np, nt) = (raw.points.len(), raw.tets.len());
            let m = Mesh::new(raw, "report").unwrap();
            let (mut emin, mut emax) = (f64::MAX, 0f64);
            for t in m.tets.iter() {
                let v = t.map(|i| m.points[i as usize].map(|c| c as f64));
                for (a, b) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                    let e = (0..3).map(|k| (v[a][k] - v[b][k]).powi(2)).sum::<f64>().sqrt();
                    (emin, emax) = (emin.min(e), emax.max(e));
                }
            }
            eprintln!(
                "{shape:8} target {target:>10}: {nt:>10} tets ({:+.2} %), {np:>9} points, occupancy {:.3}, edges {emin:.2e}..{emax:.2e} (×{:.0}), reoriented {}, degenerate {}, {:.2} s = {:.1} M tets/s",
                100.0 * (nt as f64 / target as f64 - 1.0),
                occupancy(&m),
                emax / emin,
                m.info.n_reoriented,
                m.info.n_degenerate,
                secs,
                nt as f64 / secs / 1e6
            );
        }
    }
}

#[test]
fn agulhas_terrain_lies_under_the_sea_and_rises_into_land() {
    for shape in Shape::ALL {
        assert_eq!(terrain(shape, 20_000, 1).is_some(), shape.has_terrain(), "{shape}");
    }
    let m = mesh(Shape::Agulhas, 60_000, 3);
    let t = terrain(Shape::Agulhas, 60_000, 3).unwrap();
    // Mesh vertex columns share their plan position: the lowest level is the sea floor.
    let mut floor = std::collections::HashMap::new();
    for p in m.points.iter() {
        let z = floor.entry((p[0].to_bits(), p[1].to_bits())).or_insert(f32::INFINITY);
        *z = z.min(p[2]);
    }
    let (mut wet, mut highest) = (0, f32::MIN);
    for p in &t.positions {
        assert!(p.iter().all(|c| c.is_finite()));
        highest = highest.max(p[2]);
        if let Some(&z) = floor.get(&(p[0].to_bits(), p[1].to_bits())) {
            assert!(p[2] <= z + 1e-6, "terrain {p:?} above the sea floor {z}");
            wet += 1;
        }
    }
    assert!(wet > t.positions.len() / 3, "{wet} of {} terrain nodes under the sea", t.positions.len());
    assert!(highest > 0.02, "no land above the sea: highest {highest}");
    // Every triangle faces up (counter-clockwise seen from +z).
    for tri in &t.triangles {
        let [a, b, c] = tri.map(|v| t.positions[v as usize]);
        let cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        assert!(cross > 0.0, "{tri:?}");
    }
    let mut obj = Vec::new();
    t.write_obj(&mut obj).unwrap();
    let text = String::from_utf8(obj).unwrap();
    assert_eq!(text.lines().filter(|l| l.starts_with("v ")).count(), t.positions.len());
    assert_eq!(text.lines().filter(|l| l.starts_with("f ")).count(), t.triangles.len());
}

/// Hex, wedge and hybrid meshes of every shape: valid (no inverted, degenerate or tangled
/// cells), conforming (the decomposition has a true boundary and the tet mesh's boundary face
/// count on the same grid), the same volume as the tets of the same grid, near the target
/// count, and every cell's vertex centroid located in that cell through the cell wrapper.
#[test]
fn mixed_shapes_are_valid_conforming_and_located() {
    use crate::locate::{BatchLocator, CellLocator};
    for shape in Shape::ALL {
        for kind in [CellKind::Hexes, CellKind::Wedges, CellKind::Hybrid] {
            let spec = Spec { shape, cells: kind };
            assert_eq!(spec.to_string().parse::<Spec>().unwrap(), spec);
            let target = 6_000;
            let m = Arc::new(Mesh::new(generate_spec(spec, target, 5, &|_| {}), spec.to_string()).unwrap());
            let cells = m.cells.as_ref().expect("a mixed mesh");
            let (i, label) = (&m.info, format!("{spec} {target}"));
            assert_eq!((i.n_reoriented, i.n_degenerate), (0, 0), "{label}");
            let n = m.n_cells() as f64;
            assert!((n / target as f64 - 1.0).abs() < 0.35, "{label}: {n} cells");
            if kind == CellKind::Hybrid {
                assert!(i.cell_types.len() >= 3, "{label}: {:?}", i.cell_types);
            }
            assert_eq!(m.faces().stats.n_non_manifold, 0, "{label}");
            assert!(boundary_faces_inside(&m).is_empty(), "{label}: cracks in the decomposition");
            // The tets of the same grid: same boundary (split the same way or not), same volume.
            let cubes = (target as f64 / kind.cells_per_cube()) as usize;
            let tets = mesh(shape, cubes * 6, 5);
            assert_eq!(m.points.len(), tets.points.len(), "{label}: the same grid");
            assert_eq!(m.faces().stats.n_boundary, tets.faces().stats.n_boundary, "{label}");
            let dv = (i.total_volume / tets.info.total_volume - 1.0).abs();
            assert!(dv < 1e-3, "{label}: volume {} vs the tets' {}", i.total_volume, tets.info.total_volume);
            // Vertex centroids through the wrapper: in their own cell.
            let centres: Vec<Vec3> = (0..cells.len())
                .map(|c| {
                    let ids = cells.block.corners(c);
                    std::array::from_fn(|k| {
                        ids.iter().map(|&v| m.points[v as usize][k]).sum::<f32>() / ids.len() as f32
                    })
                })
                .collect();
            let mut loc = CellLocator::new(CpuLocator::new(m.clone()), m.clone());
            let mut ids = vec![0; centres.len()];
            loc.locate(&centres, &mut ids).unwrap();
            let wrong = ids.iter().enumerate().filter(|&(c, &id)| id != c as i32).count();
            assert_eq!(wrong, 0, "{label}: {wrong} centroids not in their cell");
        }
    }
}
