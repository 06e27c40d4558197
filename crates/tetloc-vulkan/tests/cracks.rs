//! No cracks: points exactly on vertices, edges and faces inside the mesh (where rays start
//! on triangles and boxes) must come back inside, in every kernel, and in the tet the tie rule
//! names (the lowest id that holds the point: `tetloc_core::geom::lowest_claim`), the CPU's.

mod common;

use std::collections::HashSet;
use std::sync::Arc;
use tetloc_core::geom::Vec3;
use tetloc_core::{BatchLocator, CpuLocator, Mesh};
use tetloc_vulkan::{Kernel, LocatorOptions, VulkanLocator};

/// Every vertex, every edge midpoint and every face centroid of the mesh, each marked when
/// it lies on the mesh's boundary surface.
fn probe_points(mesh: &Mesh) -> (Vec<Vec3>, Vec<bool>) {
    let faces = &mesh.faces().faces;
    let mut boundary_vertex = vec![false; mesh.points.len()];
    let mut boundary_edges = HashSet::new();
    for f in faces.iter().filter(|f| f.front < 0 || f.back < 0) {
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            boundary_vertex[f.v[a] as usize] = true;
            boundary_edges.insert((f.v[a], f.v[b]));
        }
    }
    let mut pts: Vec<Vec3> = mesh.points.to_vec();
    let mut on_boundary = boundary_vertex;
    for f in faces {
        let [a, b, c] = f.v.map(|i| mesh.points[i as usize]);
        pts.push(std::array::from_fn(|k| (a[k] + b[k]) * 0.5));
        on_boundary.push(boundary_edges.contains(&(f.v[0], f.v[1])));
        pts.push(std::array::from_fn(|k| (a[k] + b[k] + c[k]) / 3.0));
        on_boundary.push(f.front < 0 || f.back < 0);
    }
    (pts, on_boundary)
}

fn check_mesh(name: &str, mesh: Arc<Mesh>) {
    let Some(ctx) = common::context(name) else { return };
    let (points, on_boundary) = probe_points(&mesh);
    let mut cpu = vec![0; points.len()];
    CpuLocator::new(mesh.clone()).locate(&points, &mut cpu).unwrap();
    assert!(cpu[..mesh.points.len()].iter().all(|&t| t >= 0), "{name}: the CPU lost a vertex");
    for k in common::kernels(&ctx, name) {
        let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), k, LocatorOptions::default()).unwrap();
        let mut ids = vec![0; points.len()];
        loc.locate(&points, &mut ids).unwrap();
        // The face kernels may lose points on the boundary surface when both rays leave the
        // mesh at once (hits at t = 0 are not reported); interior points must all be found.
        let boundary_ok = |i: usize| on_boundary[i] && matches!(k, Kernel::RtRepFaces | Kernel::RtSharedFaces);
        common::check_ids_allowing(&format!("{name} {k}"), &mesh, &points, &ids, &cpu, boundary_ok);
        let lost = (0..points.len()).filter(|&i| ids[i] < 0 && cpu[i] >= 0).count();
        // The tie rule: every point found is in the CPU's tet.
        let elsewhere = (0..points.len()).filter(|&i| ids[i] >= 0 && ids[i] != cpu[i]).count();
        assert!(elsewhere == 0, "{name} {k}: {elsewhere} points found in another tet than the CPU's");
        // The linear field is reproduced wherever a point is found.
        if let Ok(f) = mesh.field("f") {
            let mut v = vec![0f32; points.len()];
            loc.sample(&points, "f", &mut v).unwrap();
            for (i, &p) in points.iter().enumerate().filter(|&(i, _)| ids[i] >= 0) {
                let want = tetloc_testdata::exact_value(&mesh, ids[i] as usize, p, &f.values);
                assert!(
                    (v[i] as f64 - want).abs() <= 1e-5 * want.abs().max(1.0),
                    "{name} {k}: f at {p:?}: {} vs {want}",
                    v[i]
                );
            }
        }
        println!(
            "{name} {k}: {} probe points, all found in the CPU's tet, {lost} on the boundary reported outside",
            points.len()
        );
    }
    common::assert_no_validation_errors(&ctx);
}

/// Axis-aligned faces and cube diagonals shared by six tets: rays from vertices run along
/// edges and faces.
#[test]
fn regular_grid_vertices_edges_and_faces() {
    check_mesh("regular_grid_vertices_edges_and_faces", common::regular_grid(6));
}

#[test]
fn jittered_mesh_vertices_edges_and_faces() {
    check_mesh("jittered_mesh_vertices_edges_and_faces", common::jets(6000, 7));
}

/// f64 data far from the origin (a jittered grid ×1000, shifted to UTM-like coordinates, no
/// vertex exact in f32), queried in f64 within 1e-7 of faces: every kernel gives the ids of
/// the CPU's exact arithmetic on the f64 data (the kernels search the centred working copy;
/// the host checks each answer exactly and corrects the rare one within rounding of a face).
#[test]
fn f64_points_near_faces_far_from_the_origin_are_exact() {
    const TEST: &str = "f64_points_near_faces_far_from_the_origin_are_exact";
    let shift = [512_345.037_5, 4_123_456.062_5, 0.3];
    near_face_points_are_exact(TEST, |p| std::array::from_fn(|k| p[k] * 1000.0 + shift[k] + 1e-7 * p[k]));
}

/// The same, on the grid turned about a skew axis first: its boundary faces are no longer
/// axis-aligned, so points inside the file's mesh within rounding of its boundary can fall
/// outside the working copy, which the kernels search (they must still come back inside).
#[test]
fn f64_points_near_tilted_boundary_faces_are_exact() {
    const TEST: &str = "f64_points_near_tilted_boundary_faces_are_exact";
    let (c, s) = (0.6f64, 0.8f64); // a rotation by atan(4/3) about z, then about x
    let shift = [512_345.037_5, 4_123_456.062_5, 0.3];
    near_face_points_are_exact(TEST, |p| {
        let q = [c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]];
        let r = [q[0], c * q[1] - s * q[2], s * q[1] + c * q[2]];
        std::array::from_fn(|k| r[k] * 1000.0 + shift[k] + 1e-7 * p[k])
    });
}

/// A jittered grid placed in the file's f64 coordinates by `place`, queried in f64 within
/// 1e-7 of its faces (3000 points, inside and outside): every kernel equals the CPU.
fn near_face_points_are_exact(test: &str, place: impl Fn([f64; 3]) -> [f64; 3]) {
    let Some(ctx) = common::context(test) else { return };
    let raw = tetloc_testdata::KuhnGrid::new(4).jitter(0.25, 3).vertex_field(|p| p[0] + 2.0 * p[1]).raw();
    let file: Vec<[f64; 3]> = raw.points.iter().map(|p| place(p.map(f64::from))).collect();
    let raw = tetloc_core::RawMesh {
        points: file.iter().map(|p| p.map(|c| c as f32)).collect(),
        points64: Some(file.clone()),
        ..raw
    };
    let mesh = Arc::new(Mesh::new(raw, "shifted grid").unwrap());
    // A small xorshift: uniform in [0, 1).
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut unit = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let queries: Vec<[f64; 3]> = (0..3000)
        .map(|_| {
            let t = mesh.tets[(unit() * mesh.n_tets() as f64) as usize];
            let f = tetloc_core::geom::ascending_faces(t)[(unit() * 4.0) as usize].0;
            let w: [f64; 3] = std::array::from_fn(|_| 0.05 + unit());
            let s: f64 = w.iter().sum();
            let on: [f64; 3] = std::array::from_fn(|k| (0..3).map(|i| w[i] / s * file[f[i] as usize][k]).sum::<f64>());
            on.map(|c| c + (unit() - 0.5) * 2e-7)
        })
        .collect();
    let run = |loc: &mut dyn BatchLocator| {
        let (mut ids, mut values) = (vec![0i32; queries.len()], vec![0f64; queries.len()]);
        loc.sample_many64(&queries, &["f"], &mut ids, &mut values).unwrap();
        (ids, values)
    };
    let (cpu_ids, cpu_values) = run(&mut CpuLocator::new(mesh.clone()));
    for k in common::kernels(&ctx, test) {
        let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), k, LocatorOptions::default()).unwrap();
        let (ids, values) = run(&mut loc);
        let wrong = ids.iter().zip(&cpu_ids).filter(|(a, b)| a != b).count();
        assert_eq!(wrong, 0, "{}: {wrong} ids differ from exact arithmetic", k.name());
        for (i, (a, b)) in values.iter().zip(&cpu_values).enumerate() {
            assert!(
                (a - b).abs() <= 1e-5 * b.abs().max(1.0) || (a.is_nan() && b.is_nan()),
                "{} point {i}: {a} vs {b}",
                k.name()
            );
        }
    }
    common::assert_no_validation_errors(&ctx);
}
