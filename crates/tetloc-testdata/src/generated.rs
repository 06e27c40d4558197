//! A small oracle data folder made at test time, in the layout of `../shared/data`: the
//! fresh-clone counterpart of the shared data for the tests that compare with an oracle.
//!
//! Three meshes from the project's own generators, written by its VTU writer, stand in for
//! the shared meshes under their names, so a test's body runs unchanged over either folder:
//! `torus_s` a torus (`fusion`, major radius 1 around the z axis), `part_s` a non-convex
//! solid with holes (`agulhas`: an ocean over bathymetry, around continents), `delaunay_s` a
//! jittered block (`jets`; unlike the shared one, without inverted tets or slivers). Each has the shared data's fields (`f`, `cellval`) and
//! query sets (`centers`, `random`, `bbox`), whose answers come from exact arithmetic:
//! the containing tet by exact orientation signs on the file's coordinates (the lowest id
//! when several contain a point), the value by f64 barycentric interpolation (as
//! `tetloc_testdata::exact_value`), and flags bit0 where a point lies within 1e-6 (in
//! barycentric terms) of a face of a tet near it.
//!
//! One source for two crates: core's unit tests compile it into `test_support`, and
//! `tetloc-testdata` includes this same file (`#[path]`) for every other crate's tests.

use super::{generate, orient3d, read_mesh, write_mesh_vtu, Field, FieldLocation, Mesh, Shape};
use rand::{Rng, SeedableRng};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The meshes: name, shape, about how many tets.
const MESHES: [(&str, Shape, usize); 3] =
    [("torus_s", Shape::Fusion, 12_000), ("part_s", Shape::Agulhas, 8_000), ("delaunay_s", Shape::Jets, 6_000)];
/// Points of each query set.
const SET_SIZE: usize = 3_000;

/// The folder, made once per test process (in the temporary directory).
pub fn generated_data() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("tetloc-generated-data-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (k, (name, shape, tets)) in MESHES.into_iter().enumerate() {
            write_mesh_and_sets(&dir, name, shape, tets, k as u64);
        }
        dir
    })
}

/// Files for the readers' robustness tests (truncations, corruptions, the fuzz targets' seed
/// corpus), made once per test process: a small generated mesh with both fields, written by
/// the project's VTU writer (appended raw and zlib) and as a Gmsh 2.2 ASCII `.msh` and a
/// legacy binary `.vtk` (the project writes neither format, so the few lines below do).
pub fn written_files() -> &'static [PathBuf] {
    static FILES: OnceLock<Vec<PathBuf>> = OnceLock::new();
    FILES.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("tetloc-written-files-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut raw = generate(Shape::Jets, 150, 5);
        let f_values: Vec<f32> = raw.points.iter().map(|p| f(p.map(f64::from)) as f32).collect();
        let cellval: Vec<f32> = (0..raw.tets.len()).map(|id| id as f32 / raw.tets.len() as f32).collect();
        raw.fields =
            vec![Field::new("f", FieldLocation::Vertex, f_values), Field::new("cellval", FieldLocation::Cell, cellval)];
        let mesh = Mesh::new(raw, "written").unwrap();
        let files: Vec<PathBuf> =
            ["written.vtu", "written.zlib.vtu", "written.msh", "written.vtk"].map(|n| dir.join(n)).into();
        write_mesh_vtu(&files[0], &mesh, false).unwrap();
        write_mesh_vtu(&files[1], &mesh, true).unwrap();
        std::fs::write(&files[2], gmsh22_ascii(&mesh)).unwrap();
        std::fs::write(&files[3], legacy_vtk_binary(&mesh)).unwrap();
        files
    })
}

/// `mesh` as a Gmsh 2.2 ASCII file: nodes and tets (element type 4), 1-based.
fn gmsh22_ascii(mesh: &Mesh) -> String {
    let mut s = format!("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n{}\n", mesh.points.len());
    for i in 0..mesh.points.len() {
        let p = mesh.vertex64(i as u32);
        s += &format!("{} {} {} {}\n", i + 1, p[0], p[1], p[2]);
    }
    s += &format!("$EndNodes\n$Elements\n{}\n", mesh.tets.len());
    for (i, t) in mesh.tets.iter().enumerate() {
        s += &format!("{} 4 2 0 1 {} {} {} {}\n", i + 1, t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1);
    }
    s + "$EndElements\n"
}

/// `mesh` as a legacy VTK 3.0 binary file (big-endian): points, tets and the field `f`.
fn legacy_vtk_binary(mesh: &Mesh) -> Vec<u8> {
    let (n, m) = (mesh.points.len(), mesh.tets.len());
    let mut b = format!("# vtk DataFile Version 3.0\nwritten\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS {n} double\n")
        .into_bytes();
    for i in 0..n {
        b.extend(mesh.vertex64(i as u32).iter().flat_map(|c| c.to_be_bytes()));
    }
    b.extend(format!("\nCELLS {m} {}\n", 5 * m).bytes());
    for t in mesh.tets.iter() {
        b.extend([4, t[0], t[1], t[2], t[3]].iter().flat_map(|&i| (i as i32).to_be_bytes()));
    }
    b.extend(format!("\nCELL_TYPES {m}\n").bytes());
    b.extend((0..m).flat_map(|_| 10i32.to_be_bytes()));
    b.extend(format!("\nPOINT_DATA {n}\nSCALARS f float 1\nLOOKUP_TABLE default\n").bytes());
    b.extend(mesh.field("f").unwrap().values.iter().flat_map(|v| v.to_be_bytes()));
    b.push(b'\n');
    b
}

/// The shared data's point field `f` (see its README).
fn f(p: [f64; 3]) -> f64 {
    (3.0 * p[0] + 1.0).sin() * (2.0 * p[1]).cos() + 0.5 * (4.0 * p[2]).sin() + 0.3 * p[0] * p[1]
}

fn write_mesh_and_sets(dir: &Path, name: &str, shape: Shape, tets: usize, seed: u64) {
    let mut raw = generate(shape, tets, seed);
    let cellval = (0..raw.tets.len()).map(|id| ((id as u64 * 2_654_435_761) % (1 << 32)) as f32 / 2f32.powi(32));
    raw.fields = vec![
        Field::new("f", FieldLocation::Vertex, raw.points.iter().map(|p| f(p.map(f64::from)) as f32).collect()),
        Field::new("cellval", FieldLocation::Cell, cellval.collect()),
    ];
    let path = dir.join(format!("{name}.vtu"));
    write_mesh_vtu(&path, &Mesh::new(raw, name).unwrap(), false).unwrap();
    // The answers refer to the file as any reader sees it.
    let mesh = read_mesh(&path, None).unwrap();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let n = mesh.n_tets();
    // Points in the file's coordinates, rounded to f32 (the answers are for those values).
    let corner = |t: usize, j: usize| mesh.vertex64(mesh.tets[t][j]);
    let centers: Vec<[f32; 3]> = (0..SET_SIZE)
        .map(|i| {
            let t = i * n / SET_SIZE;
            std::array::from_fn(|a| ((0..4).map(|j| corner(t, j)[a]).sum::<f64>() / 4.0) as f32)
        })
        .collect();
    let random: Vec<[f32; 3]> = (0..SET_SIZE)
        .map(|_| {
            let t = rng.gen_range(0..n);
            let mut cuts = [0.0, rng.gen::<f64>(), rng.gen::<f64>(), rng.gen::<f64>(), 1.0];
            cuts.sort_by(f64::total_cmp);
            std::array::from_fn(|a| (0..4).map(|j| (cuts[j + 1] - cuts[j]) * corner(t, j)[a]).sum::<f64>() as f32)
        })
        .collect();
    let (lo, hi) = bounds((0..mesh.points.len() as u32).map(|i| mesh.vertex64(i)));
    let bbox: Vec<[f32; 3]> =
        (0..SET_SIZE).map(|_| std::array::from_fn(|a| (lo[a] + (hi[a] - lo[a]) * rng.gen::<f64>()) as f32)).collect();
    let reference = Reference::new(&mesh);
    for (set, points) in [("centers", centers), ("random", random), ("bbox", bbox)] {
        write_set(dir, name, set, &mesh, &reference, &points);
    }
}

fn bounds(points: impl Iterator<Item = [f64; 3]>) -> ([f64; 3], [f64; 3]) {
    points.fold(([f64::MAX; 3], [f64::MIN; 3]), |(lo, hi), p| {
        (std::array::from_fn(|a| lo[a].min(p[a])), std::array::from_fn(|a| hi[a].max(p[a])))
    })
}

/// Writes `NAME.SET.json` and its arrays, as the shared data has them.
fn write_set(dir: &Path, name: &str, set: &str, mesh: &Mesh, reference: &Reference, points: &[[f32; 3]]) {
    let f = &mesh.field("f").unwrap().values;
    let (mut cell, mut value, mut flags) = (Vec::new(), Vec::new(), Vec::new());
    for &p in points {
        let (t, near_face) = reference.locate(mesh, p.map(f64::from));
        cell.push(t.map_or(-1, |t| t as i32));
        value.push(t.map_or(f64::NAN, |t| exact_value(mesh, t, p.map(f64::from), f)));
        flags.push(u8::from(near_face));
    }
    let file = |what: &str| format!("{name}.{set}.{what}.bin");
    let write = |what: &str, bytes: &[u8]| std::fs::write(dir.join(file(what)), bytes).unwrap();
    write("points", bytemuck::cast_slice(points));
    write("cell", bytemuck::cast_slice(&cell));
    write("value", bytemuck::cast_slice(&value));
    write("flags", &flags);
    let arrays: serde_json::Map<String, serde_json::Value> = ["points", "cell", "value", "flags"]
        .iter()
        .map(|w| (w.to_string(), serde_json::json!({ "file": file(w) })))
        .collect();
    let meta = serde_json::json!({ "mesh": name, "set": set, "count": points.len(), "arrays": arrays });
    std::fs::write(dir.join(format!("{name}.{set}.json")), meta.to_string()).unwrap();
}

/// `values` (per vertex) interpolated at `p` with f64 barycentrics in tet `t` on the file's
/// coordinates (`tetloc_testdata::exact_value`, which this file cannot reach from core).
fn exact_value(mesh: &Mesh, t: usize, p: [f64; 3], values: &[f32]) -> f64 {
    let ids = mesh.tets[t];
    let v = ids.map(|i| mesh.vertex64(i));
    let vol = orient3d(v[0], v[1], v[2], v[3]);
    (0..4)
        .map(|i| {
            let mut w = v;
            w[i] = p;
            orient3d(w[0], w[1], w[2], w[3]) / vol * f64::from(values[ids[i] as usize])
        })
        .sum()
}

/// Brute-force exact point location: the tets whose bounding box holds a point, found through
/// a uniform grid of buckets, tested with exact orientation signs.
struct Reference {
    lo: [f64; 3],
    cell: [f64; 3],
    dims: [usize; 3],
    buckets: Vec<Vec<u32>>,
    boxes: Vec<([f64; 3], [f64; 3])>,
}

impl Reference {
    fn new(mesh: &Mesh) -> Reference {
        let boxes: Vec<([f64; 3], [f64; 3])> = mesh
            .tets
            .iter()
            .map(|ids| {
                let v = ids.map(|i| mesh.vertex64(i));
                (
                    std::array::from_fn(|a| v.iter().map(|p| p[a]).fold(f64::MAX, f64::min)),
                    std::array::from_fn(|a| v.iter().map(|p| p[a]).fold(f64::MIN, f64::max)),
                )
            })
            .collect();
        let lo: [f64; 3] = std::array::from_fn(|a| boxes.iter().map(|b| b.0[a]).fold(f64::MAX, f64::min));
        let hi: [f64; 3] = std::array::from_fn(|a| boxes.iter().map(|b| b.1[a]).fold(f64::MIN, f64::max));
        let side = (boxes.len() as f64).cbrt().ceil() as usize;
        let dims = [side; 3];
        let cell: [f64; 3] = std::array::from_fn(|a| (hi[a] - lo[a]).max(f64::MIN_POSITIVE) / side as f64);
        let mut buckets = vec![Vec::new(); side * side * side];
        let mut reference = Reference { lo, cell, dims, buckets: Vec::new(), boxes };
        for (t, b) in reference.boxes.iter().enumerate() {
            let (b0, b1) = (reference.index(b.0), reference.index(b.1));
            for z in b0[2]..=b1[2] {
                for y in b0[1]..=b1[1] {
                    for x in b0[0]..=b1[0] {
                        buckets[x + side * (y + side * z)].push(t as u32);
                    }
                }
            }
        }
        reference.buckets = buckets;
        reference
    }

    fn index(&self, p: [f64; 3]) -> [usize; 3] {
        std::array::from_fn(|a| (((p[a] - self.lo[a]) / self.cell[a]).max(0.0) as usize).min(self.dims[a] - 1))
    }

    /// The lowest-id tet containing `p` (exactly), and whether `p` lies within 1e-6 of a face
    /// of a tet whose box holds it (in that tet's barycentric coordinates).
    fn locate(&self, mesh: &Mesh, p: [f64; 3]) -> (Option<usize>, bool) {
        let i = self.index(p);
        let (mut found, mut near_face) = (None, false);
        for &t in &self.buckets[i[0] + self.dims[0] * (i[1] + self.dims[1] * i[2])] {
            let (lo, hi) = self.boxes[t as usize];
            if (0..3).any(|a| p[a] < lo[a] - 1e-6 * (hi[a] - lo[a]) || p[a] > hi[a] + 1e-6 * (hi[a] - lo[a])) {
                continue;
            }
            let v = mesh.tets[t as usize].map(|i| mesh.vertex64(i));
            let vol = orient3d(v[0], v[1], v[2], v[3]);
            let sub: [f64; 4] = std::array::from_fn(|j| {
                let mut w = v;
                w[j] = p;
                orient3d(w[0], w[1], w[2], w[3])
            });
            // Exact signs: inside (or on the boundary) when no sub-volume has the other sign.
            if found.is_none() && sub.iter().all(|&s| s == 0.0 || s.signum() == vol.signum()) {
                found = Some(t as usize);
            }
            let bary_min = sub.iter().map(|s| s / vol).fold(f64::MAX, f64::min);
            near_face |= bary_min.abs() <= 1e-6;
        }
        (found, near_face)
    }
}
