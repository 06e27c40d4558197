use super::*;
use crate::test_support::{grid_mesh, jittered_grid};

#[test]
fn grid_is_conforming_and_counted() {
    let m = grid_mesh(4, 0.2, 1);
    assert_eq!(m.n_tets(), 6 * 64);
    assert!((m.info.total_volume - 1.0).abs() < 1e-5, "{}", m.info.total_volume);
    assert_eq!(m.info.n_degenerate, 0);
    let fs = m.faces();
    // Closed surface of a cube: 6 sides × 16 squares × 2 triangles.
    assert_eq!(fs.stats.n_boundary, 6 * 16 * 2);
    assert_eq!(fs.stats.n_non_manifold, 0);
    // Euler-style count: every tet has 4 faces, interior ones counted twice.
    assert_eq!(4 * m.n_tets(), 2 * fs.stats.n_faces - fs.stats.n_boundary);
}

#[test]
fn front_and_back_follow_the_orientation_convention() {
    let m = grid_mesh(3, 0.25, 2);
    for f in &m.faces().faces {
        let [a, b, c] = f.v.map(|i| m.points[i as usize]);
        for (tet, want_positive) in [(f.front, true), (f.back, false)] {
            if tet < 0 {
                continue;
            }
            let centre = m.tet_center(tet as usize);
            let o = crate::geom::orient_f64(a, b, c, centre);
            assert_eq!(o > 0.0, want_positive, "face {:?} tet {tet}", f.v);
        }
    }
}

#[test]
fn inverted_tets_are_reoriented_not_dropped() {
    let mut raw = jittered_grid(2, 0.2, 3);
    // Make every tet positive, then invert every second one.
    for (i, t) in raw.tets.iter_mut().enumerate() {
        *t = crate::geom::canonical_tet(*t, &raw.points).0;
        if i % 2 == 0 {
            t.swap(0, 1);
        }
    }
    let n = raw.tets.len();
    let m = Mesh::new(raw, "inverted").unwrap();
    assert_eq!(m.n_tets(), n);
    assert_eq!(m.info.n_reoriented, n / 2);
    for &t in m.tets.iter() {
        let v = t.map(|i| m.points[i as usize]);
        assert!(crate::geom::tet_volume6(v) > 0.0);
    }
}

#[test]
fn bad_meshes_are_errors_naming_the_problem() {
    let good = jittered_grid(1, 0.0, 0);
    let mut e = good.clone();
    e.tets.clear();
    assert!(Mesh::new(e, "empty.vtu").unwrap_err().to_string().contains("empty.vtu: the mesh has no tetrahedra"));
    let mut e = good.clone();
    e.tets[3][2] = 999;
    let msg = Mesh::new(e, "range.vtu").unwrap_err().to_string();
    assert!(msg.contains("tet 3 references vertex 999"), "{msg}");
    let mut e = good.clone();
    e.points[5][1] = f32::NAN;
    let msg = Mesh::new(e, "nan.vtu").unwrap_err().to_string();
    assert!(msg.contains("vertex 5 has a non-finite coordinate"), "{msg}");
    let mut e = good.clone();
    e.fields[0].values.pop();
    let msg = Mesh::new(e, "field.vtu").unwrap_err().to_string();
    assert!(msg.contains("field 'f' has 7 values, expected 8"), "{msg}");
}

#[test]
fn degenerate_tets_are_counted() {
    let mut raw = jittered_grid(1, 0.0, 0);
    raw.tets.push([0, 1, 1, 2]);
    raw.fields.retain(|f| f.location == FieldLocation::Vertex);
    let m = Mesh::new(raw, "degenerate").unwrap();
    assert_eq!(m.info.n_degenerate, 1);
}

#[test]
fn missing_field_lists_the_available_ones() {
    let m = grid_mesh(1, 0.0, 0);
    let msg = m.field("pressure").unwrap_err().to_string();
    assert!(msg.contains("'f', 'cellval'"), "{msg}");
}

#[test]
fn neighbors_are_symmetric_and_match_the_faces() {
    let m = grid_mesh(3, 0.3, 4);
    let nb = m.neighbors();
    let mut boundary = 0;
    for (t, n) in nb.iter().enumerate() {
        for (i, &o) in n.iter().enumerate() {
            if o < 0 {
                boundary += 1;
                continue;
            }
            assert!(nb[o as usize].contains(&(t as i32)), "tet {t} face {i} -> {o} not symmetric");
            // The shared face is the one without vertex i.
            let face: Vec<u32> = m.tets[t].iter().enumerate().filter(|(j, _)| *j != i).map(|(_, &v)| v).collect();
            assert!(face.iter().all(|v| m.tets[o as usize].contains(v)));
        }
    }
    assert_eq!(boundary, m.faces().stats.n_boundary);
}

#[test]
fn first_tets_bound_each_cells_tets() {
    use crate::gen::{generate_spec, CellKind, Shape, Spec};
    for cells in [CellKind::Hexes, CellKind::Hybrid] {
        let raw = generate_spec(Spec { shape: Shape::Fusion, cells }, 500, 3, &|_| {});
        let mesh = Mesh::new(raw, "mixed").unwrap();
        let c = mesh.cells.as_ref().unwrap();
        let first = c.first_tets();
        assert_eq!(first.len(), c.len() + 1);
        assert_eq!(first[c.len()] as usize, mesh.n_tets());
        for i in 0..c.len() {
            assert_eq!(first[i] as usize..first[i + 1] as usize, c.tets_of(i), "{cells:?} cell {i}");
        }
    }
}

#[test]
fn values_along_a_line_are_the_values_at_its_ids() {
    // A line of points through a few tets (runs of points in one tet, some outside, a tet
    // revisited), on a mesh with f64 vertices and an f64 vertex field, a vertex and a cell field.
    let mut raw = crate::test_support::jittered_grid(4, 0.2, 7);
    let n = raw.points.len();
    raw.points64 = Some(raw.points.iter().map(|p| p.map(|c| f64::from(c) + 1e-9)).collect());
    raw.fields.push(Field::from_f64("g", FieldLocation::Vertex, (0..n).map(|i| 1.0 / (1.0 + i as f64)).collect()));
    let m = Mesh::new(raw, "line").unwrap();
    let fields: Vec<&Field> = ["f", "g", "cellval"].iter().map(|c| m.field(c).unwrap()).collect();
    let mut points = Vec::new();
    let mut ids = Vec::new();
    for (k, &t) in [5usize, 5, 5, 9, 9, 5, 200, 200, 17].iter().enumerate() {
        let c = m.tet_center(t).map(f64::from);
        points.push([c[0] + 1e-4 * k as f64, c[1], c[2]]);
        ids.push(t as i32);
        if k % 4 == 1 {
            points.push(c);
            ids.push(-1);
        }
    }
    let k = fields.len();
    for f64_out in [false, true] {
        if f64_out {
            let (mut want, mut got) = (vec![0f64; k * points.len()], vec![1f64; k * points.len()]);
            m.values_at_ids64(&points, &ids, &fields, &mut want);
            m.values_along64(&points, &ids, &fields, &mut got);
            assert!(want.iter().zip(&got).all(|(a, b)| a.to_bits() == b.to_bits()), "{want:?}\n{got:?}");
        } else {
            let (mut want, mut got) = (vec![0f32; k * points.len()], vec![1f32; k * points.len()]);
            m.values_at_ids64(&points, &ids, &fields, &mut want);
            m.values_along64(&points, &ids, &fields, &mut got);
            assert!(want.iter().zip(&got).all(|(a, b)| a.to_bits() == b.to_bits()), "{want:?}\n{got:?}");
        }
    }
    assert!(ids.contains(&-1));
}

/// Another time step's fields on a mesh's geometry: the mesh that `Mesh::new` makes of the
/// raw mesh with those fields, sharing the geometry (its neighbours and a mixed mesh's cells),
/// on linear and quadratic tets, a hybrid of hexes, pyramids, wedges and tets, and an octree
/// with polyhedra (whose centroids get the means of the point data); fields of the wrong
/// length are refused naming the file, as `Mesh::new` refuses them.
#[test]
fn a_mesh_takes_another_steps_fields_on_its_geometry() {
    use crate::gen::{generate_spec, CellKind, Shape, Spec};
    let mixed = |cells| generate_spec(Spec { shape: Shape::Jets, cells }, 400, 3, &|_| ());
    let raws = [
        jittered_grid(3, 0.2, 5),
        crate::test_support::KuhnGrid::new(2).jitter(0.1, 7).order(2).raw(),
        mixed(CellKind::Hybrid),
        mixed(CellKind::Octree),
    ];
    let (mut with_cells, mut with_centroids) = (0, 0);
    for raw in raws {
        let first = Mesh::new(raw.clone(), "s.pvd").unwrap();
        with_cells += usize::from(first.cells.is_some());
        with_centroids += usize::from(first.info.n_centroids > 0);
        first.neighbors();
        let (n, cells) = (first.info.n_points, first.n_cells());
        let fields = vec![
            Field::new("p", FieldLocation::Vertex, (0..n).map(|i| i as f32 * 0.5).collect()),
            Field::from_f64("q", FieldLocation::Cell, (0..cells).map(|i| 1.0 + i as f64 / 3.0).collect()),
        ];
        let step = first.with_fields(fields.clone()).unwrap();
        let read = Mesh::new(RawMesh { fields, ..raw }, "s.pvd").unwrap();
        assert!(step.same_geometry(&first) && first.same_geometry(&step));
        assert!(!read.same_geometry(&first), "a mesh read anew is a geometry of its own");
        assert_eq!((&step.points, &step.points64, &step.tets), (&read.points, &read.points64, &read.tets));
        assert_eq!(format!("{:?}", step.tet_nodes), format!("{:?}", read.tet_nodes));
        assert_eq!(format!("{:?}", step.cells), format!("{:?}", read.cells));
        assert_eq!(format!("{:?}", step.info), format!("{:?}", read.info));
        assert_eq!(format!("{:?}", step.fields), format!("{:?}", read.fields));
        assert!(Arc::ptr_eq(&step.points, &first.points) && Arc::ptr_eq(&step.tets, &first.tets), "shared");
        assert!(Arc::ptr_eq(&step.neighbors, &first.neighbors), "the neighbours are shared");
        let table = |m: &Mesh| m.tet_nodes.as_ref().map(|n| n.table().as_ptr());
        assert!(table(&step) == table(&first), "the higher-order nodes are shared");
        let short = vec![Field::new("p", FieldLocation::Vertex, vec![0.0; n - 1])];
        let e = first.with_fields(short).unwrap_err().to_string();
        assert!(e.contains("s.pvd") && e.contains(&format!("field 'p' has {} values, expected {n}", n - 1)), "{e}");
    }
    assert_eq!((with_cells, with_centroids), (2, 1), "the mixed meshes and the polyhedra are there");
}
