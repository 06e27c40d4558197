//! The cell wrapper on the CPU locator: VTK's answers on the mixed oracle sets, no cracks
//! across warped faces, hex/tet agreement, and the wrapper's pass-through on tet meshes.

use super::*;
use crate::cell::{CellBlock, CellType};
use crate::locate::{CpuLocator, FiniteOnly};
use crate::test_support::mixed::{compare, compare_far, far_mesh, mixed_sets, Mismatch};
use std::path::Path;

fn load(path: &Path) -> Arc<Mesh> {
    Arc::new(crate::test_support::read_mesh(path).unwrap_or_else(|e| panic!("{e}")))
}

/// Every mixed oracle set, from both files of each mesh, through the CPU locator: VTK's ids
/// and values everywhere outside the ambiguous points.
#[test]
fn cpu_matches_vtk_on_the_mixed_sets() {
    for (name, (files, sets)) in mixed_sets("cpu_matches_vtk_on_the_mixed_sets") {
        for file in files {
            let mesh = load(&file);
            assert!(mesh.cells.is_some(), "{name}: a mixed mesh");
            let mut loc = CellLocator::new(FiniteOnly::new(CpuLocator::new(mesh.clone())), mesh.clone());
            for set in &sets {
                let m = compare(&mut loc, &mesh, set);
                eprintln!("{} ({}): {m:?}", set.label, file.file_name().unwrap().to_string_lossy());
                assert_eq!(m, Mismatch::default(), "{} from {}", set.label, file.display());
            }
        }
    }
}

/// The mixed sets moved far from the origin (`mixed::FAR`: there f32 cannot hold their
/// cells, which would collapse) and queried in f64: VTK's answers, as at the origin.
#[test]
fn cpu_matches_vtk_far_from_the_origin() {
    for (name, (files, sets)) in mixed_sets("cpu_matches_vtk_far_from_the_origin") {
        let mesh = Arc::new(far_mesh(&files[0]));
        assert!(!mesh.info.frame.is_identity(), "{name}: a centred working frame");
        let mut loc = CellLocator::new(FiniteOnly::new(CpuLocator::new(mesh.clone())), mesh.clone());
        for set in &sets {
            let m = compare_far(&mut loc, &mesh, set);
            eprintln!("{} far: {m:?}", set.label);
            assert_eq!(m, Mismatch::default(), "{} far", set.label);
        }
    }
}

/// A warped hex grid (interior vertices jittered, ids shuffled; `brute_force::Mixed`) as a mesh.
fn warped_grid(n: usize, jitter: f64, seed: u64) -> (crate::cell::brute_force::Mixed, Arc<Mesh>) {
    let m = crate::cell::brute_force::Mixed::warped_hex_grid(n, jitter, seed);
    let f =
        crate::mesh::Field { values64: None, name: "f".into(), location: FieldLocation::Vertex, values: m.f.clone() };
    let raw = crate::RawMesh {
        points: m.points32.clone(),
        cells: Some(m.cells.clone()),
        fields: vec![f],
        ..Default::default()
    };
    let mesh = Arc::new(Mesh::new(raw, "warped grid").unwrap());
    (m, mesh)
}

mod properties {
    use super::*;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(8))]

        /// No cracks across warped faces, through the real locator (CPU BVH and walk, then the
        /// wrapper): every point of the open cube is in a cell that holds it by VTK's
        /// definition (to 1e-6), points on the interior warped faces too, and points outside
        /// the cube are outside; the answers are the brute-force design's.
        #[test]
        fn no_cracks_across_warped_faces(seed in any::<u64>()) {
            let (m, mesh) = warped_grid(4, 0.2, seed);
            prop_assert!(mesh.info.n_warped_cells > 32);
            let design = crate::cell::brute_force::Design::build(&m);
            let mut loc = CellLocator::new(CpuLocator::new(mesh.clone()), mesh.clone());
            let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
            let mut points: Vec<Vec3> = (0..2000).map(|_| std::array::from_fn(|_| rng.gen_range(1e-4f32..1.0 - 1e-4))).collect();
            // Points on the faces, through the cells' bilinear maps (then rounded to f32).
            for c in 0..m.cells.len() {
                let shape = m.cells.types[c].shape();
                for bound in shape.domain {
                    let mut pc: [f64; 3] = std::array::from_fn(|_| rng.gen_range(0.0..1.0));
                    let k = bound.normal.iter().position(|&x| x != 0.0).unwrap();
                    pc[k] = bound.offset;
                    let p = crate::cell::forward(shape.linear, &m.corners(c), pc).map(|x| x as f32);
                    if p.iter().all(|&x| x > 0.0 && x < 1.0) {
                        points.push(p);
                    }
                }
            }
            let mut ids = vec![0; points.len()];
            loc.locate(&points, &mut ids).unwrap();
            for (&p, &c) in points.iter().zip(&ids) {
                prop_assert!(c >= 0, "a crack at {:?}", p);
                let held = m.pcoords(c as usize, p.map(f64::from)).is_ok_and(|pc| m.cells.types[c as usize].shape().margin(pc) >= -1e-6);
                prop_assert!(held, "cell {} does not hold {:?}", c, p);
            }
            // Off the faces the answer is unique: the brute force's.
            let differ = points[..2000].iter().zip(&ids).filter(|&(&p, &c)| design.locate(&m, p) != c).count();
            prop_assert!(differ == 0, "{} points differ from the brute-force design", differ);
            let outside = [[1.0001f32, 0.5, 0.5], [0.5, -1e-4, 0.5], [0.3, 0.6, 1.2]];
            let mut ids = vec![0; 3];
            loc.locate(&outside, &mut ids).unwrap();
            prop_assert_eq!(ids, vec![-1; 3]);
        }
    }
}

/// Hex/tet agreement: a hex mesh with planar faces (a rectilinear grid, shuffled ids) answers
/// as its conforming tet split does, mapped back to hex ids, and a linear field has the same
/// values in both.
#[test]
fn planar_hexes_answer_as_their_tet_split() {
    use rand::{Rng, SeedableRng};
    let (m, hexes) = warped_grid(5, 0.0, 11);
    assert_eq!(hexes.info.n_warped_cells, 0, "a planar grid");
    // The split as a plain tet mesh, with its parent map.
    let cells = hexes.cells.as_ref().unwrap();
    let f = |p: Vec3| p[0] + 2.0 * p[1] - p[2];
    let field = |points: &[Vec3]| crate::mesh::Field {
        values64: None,
        name: "f".into(),
        location: FieldLocation::Vertex,
        values: points.iter().map(|&p| f(p)).collect(),
    };
    let tets_raw = crate::RawMesh {
        points: m.points32.clone(),
        tets: hexes.tets.to_vec(),
        fields: vec![field(&m.points32)],
        ..Default::default()
    };
    let tets = Arc::new(Mesh::new(tets_raw, "split").unwrap());
    let hexes_raw = crate::RawMesh {
        points: m.points32.clone(),
        cells: Some(m.cells.clone()),
        fields: vec![field(&m.points32)],
        ..Default::default()
    };
    let hexes = Arc::new(Mesh::new(hexes_raw, "hexes").unwrap());
    let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
    let points: Vec<Vec3> = (0..5000).map(|_| std::array::from_fn(|_| rng.gen_range(-0.1f32..1.1))).collect();
    let (mut a, mut va) = (vec![0; points.len()], vec![0f32; points.len()]);
    let (mut b, mut vb) = (vec![0; points.len()], vec![0f32; points.len()]);
    CellLocator::new(CpuLocator::new(hexes.clone()), hexes.clone())
        .locate_and_sample(&points, "f", &mut a, &mut va)
        .unwrap();
    CpuLocator::new(tets.clone()).locate_and_sample(&points, "f", &mut b, &mut vb).unwrap();
    for i in 0..points.len() {
        let mapped = if b[i] < 0 { -1 } else { cells.cell_of(b[i] as usize) as i32 };
        assert_eq!(a[i], mapped, "point {:?}", points[i]);
        if a[i] >= 0 {
            assert!((va[i] - vb[i]).abs() < 1e-5, "f at {:?}: {} vs {}", points[i], va[i], vb[i]);
        }
    }
    assert!(a.iter().filter(|&&c| c >= 0).count() > 2500);
}

/// Bad cells: repeated vertices are kept (their zero-volume tets hold nothing; a hex collapsed
/// to a wedge still holds its points), inverted hexes are located as they are (VTK's
/// definition does not depend on orientation) and counted, tangled hexes are kept and
/// counted, and vertex ids out of range are an error naming the cell. (Cell types tetloc does
/// not read: tetloc-io's `unsupported_cells_are_refused_counted_by_type`.)
#[test]
fn bad_cells_are_repaired_or_refused() {
    let hex = CellType::from_vtk(12, 8).unwrap();
    let cube: Vec<Vec3> = (0..8).map(|c| [(c & 1) as f32, ((c >> 1) & 1) as f32, ((c >> 2) & 1) as f32]).collect();
    let vtk_order = [0u32, 1, 3, 2, 4, 5, 7, 6];
    let mesh_of = |nodes: [u32; 8]| {
        let mut cells = CellBlock::default();
        cells.push(hex, &nodes);
        let f = crate::mesh::Field {
            values64: None,
            name: "f".into(),
            location: FieldLocation::Vertex,
            values: cube.iter().map(|p| p[0] + p[2]).collect(),
        };
        Mesh::new(
            crate::RawMesh { points: cube.clone(), cells: Some(cells), fields: vec![f], ..Default::default() },
            "bad.vtu",
        )
        .map(Arc::new)
    };
    let inside = [[0.3f32, 0.6, 0.2], [0.9, 0.1, 0.5]];
    let run = |m: &Arc<Mesh>| {
        let (mut ids, mut v) = (vec![0; 2], vec![0f32; 2]);
        CellLocator::new(CpuLocator::new(m.clone()), m.clone())
            .locate_and_sample(&inside, "f", &mut ids, &mut v)
            .unwrap();
        (ids, v)
    };
    let good = mesh_of(vtk_order).unwrap();
    assert_eq!((good.info.n_reoriented, good.info.n_degenerate), (0, 0));
    let (ids, v) = run(&good);
    assert_eq!(ids, [0, 0]);
    assert!((v[0] - 0.5).abs() < 1e-6 && (v[1] - 1.4).abs() < 1e-6, "{v:?}");
    // Inverted: top and bottom swapped.
    let inverted = mesh_of([4, 5, 7, 6, 0, 1, 3, 2]).unwrap();
    assert_eq!(inverted.info.n_reoriented, 1);
    assert_eq!(run(&inverted), run(&good));
    // Repeated vertices: the top face's back edge collapsed onto its front edge (a wedge).
    let collapsed = mesh_of([0, 1, 3, 2, 4, 5, 5, 4]).unwrap();
    assert_eq!(collapsed.info.n_degenerate, 0, "the cell still has volume");
    let (ids, _) = run(&collapsed);
    assert_eq!(ids, [0, 0], "points of the wedge");
    // All corners on one point: zero volume, counted, holds nothing.
    let flat = mesh_of([0; 8]).unwrap();
    assert_eq!(flat.info.n_degenerate, 1);
    assert_eq!(run(&flat).0, [-1, -1]);
    // Tangled: one corner pushed through the cell.
    let mut points = cube.clone();
    points[3] = [-0.5, -0.5, 0.5];
    let mut cells = CellBlock::default();
    cells.push(hex, &vtk_order);
    let tangled = Mesh::new(crate::RawMesh { points, cells: Some(cells), ..Default::default() }, "bad.vtu").unwrap();
    assert_eq!((tangled.info.n_tangled, tangled.info.n_reoriented), (1, 0));
    // Out of range.
    let mut cells = CellBlock::default();
    cells.push(hex, &[0, 1, 3, 2, 4, 5, 7, 9]);
    let e = Mesh::new(crate::RawMesh { points: cube.clone(), cells: Some(cells), ..Default::default() }, "bad.vtu")
        .unwrap_err()
        .to_string();
    assert!(e.contains("cell 0 references vertex 9"), "{e}");
}
