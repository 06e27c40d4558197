//! Access to the oracle data in `../shared/data` (made with VTK, scipy and gmsh) for the
//! tests of every crate. `TETLOC_DATA` overrides the folder. When the data is absent the
//! tests say so and skip — except in CI (`CI` set), where that is a failure.

use crate::geom::Vec3;
use std::path::{Path, PathBuf};

/// The data folder, if it exists.
pub fn data_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("TETLOC_DATA") {
        Some(d) => PathBuf::from(d),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
    };
    dir.is_dir().then(|| dir.canonicalize().unwrap_or(dir))
}

/// True when running in CI, where nothing may be skipped.
pub fn in_ci() -> bool {
    std::env::var("CI").map(|v| !v.is_empty() && v != "false" && v != "0").unwrap_or(false)
}

/// The data folder for a test, or `None` (after saying so) when a user's clone lacks it.
/// Panics in CI.
pub fn require_data(test: &str) -> Option<PathBuf> {
    match data_dir() {
        Some(d) => Some(d),
        None if in_ci() => {
            panic!("{test}: oracle data not found (set TETLOC_DATA or lay out ../shared/data); CI must not skip")
        }
        None => {
            eprintln!("SKIPPED {test}: oracle data not found (set TETLOC_DATA to ../shared/data)");
            None
        }
    }
}

/// One oracle query set: points and the expected answers.
pub struct QuerySet {
    /// e.g. `torus_s.random`
    pub label: String,
    /// The mesh file the answers refer to.
    pub mesh_path: PathBuf,
    pub points: Vec<Vec3>,
    /// Expected tet id, -1 outside.
    pub cell: Vec<i32>,
    /// Expected interpolated value of point field `f` (generated meshes only), NaN outside.
    pub value: Option<Vec<f64>>,
    /// bit0: within rounding of a face, so another answer is also right.
    pub flags: Vec<u8>,
}

impl QuerySet {
    pub fn ambiguous(&self, i: usize) -> bool {
        self.flags[i] & 1 != 0
    }
}

fn read_le<T: bytemuck::Pod>(path: &Path) -> Vec<T> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    bytemuck::pod_collect_to_vec(&bytes)
}

/// Every query set in `dir` and `dir/real`, each with the mesh file it belongs to.
pub fn query_sets(dir: &Path) -> Vec<QuerySet> {
    let mut out = Vec::new();
    for folder in [dir.to_path_buf(), dir.join("real")] {
        let Ok(rd) = std::fs::read_dir(&folder) else { continue };
        let mut jsons: Vec<PathBuf> = rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                let n = p.file_name().unwrap().to_string_lossy().to_string();
                n.ends_with(".json") && !n.ends_with(".mesh.json") && n.matches('.').count() == 2
            })
            .collect();
        jsons.sort();
        for j in jsons {
            let meta: serde_json::Value = serde_json::from_slice(&std::fs::read(&j).unwrap()).unwrap();
            let mesh = meta["mesh"].as_str().unwrap().to_string();
            let set = meta["set"].as_str().unwrap().to_string();
            let mesh_path = ["vtu", "msh", "vtk"]
                .iter()
                .map(|ext| folder.join(format!("{mesh}.{ext}")))
                .find(|p| p.exists())
                .unwrap_or_else(|| panic!("{}: no mesh file named {mesh}.vtu/.msh/.vtk", j.display()));
            // Real meshes list a `value` array but ship none (ids only): take only files that exist.
            let arr = |key: &str| meta["arrays"][key]["file"].as_str().map(|f| folder.join(f)).filter(|p| p.exists());
            let points: Vec<f32> = read_le(&arr("points").unwrap());
            out.push(QuerySet {
                label: format!("{mesh}.{set}"),
                mesh_path,
                points: points.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
                cell: read_le(&arr("cell").unwrap()),
                value: arr("value").map(|p| read_le(&p)),
                flags: read_le(&arr("flags").unwrap()),
            });
        }
    }
    out
}

/// The value of a per-vertex field at `p` by barycentric interpolation in tet `t`, with the
/// barycentrics computed in f64 on the stored (f32) vertices: the reference a locator's
/// value must match. The oracle's own values use the file's f64 vertices; in slivers the
/// rounding of the vertices to f32 alone moves them by more than 1e-5.
pub fn exact_value(mesh: &crate::Mesh, t: usize, p: Vec3, values: &[f32]) -> f64 {
    let ids = mesh.tets[t];
    let v: [Vec3; 4] = ids.map(|i| mesh.points[i as usize]);
    let vol = crate::geom::tet_volume6(v);
    (0..4)
        .map(|i| {
            let mut w = v;
            w[i] = p;
            crate::geom::tet_volume6(w) / vol * values[ids[i] as usize] as f64
        })
        .sum()
}

/// The one test-mesh builder of every crate: a grid of `n`³ cubes, each split into the 6
/// Kuhn tets `[v0, v0 + e_a, v0 + e_a + e_b, v7]` (one per axis order, all sharing the
/// cube's diagonal v0 = (0,0,0) → v7 = (1,1,1), so neighbouring cubes share faces exactly).
/// Tets are left as the split gives them (half are inverted; `Mesh::new` reorients them).
///
/// Vertices are numbered `x` fastest, tets cube by cube (`x` fastest) in axis-order order.
/// Defaults: the unit cube (spacing `1/n`), no jitter, every tet kept, vertex field `f` =
/// x + 2y + 3z (linear, so interpolation is exact) and cell field `c` = tet id.
///
/// ```ignore
/// let raw = KuhnGrid::new(4).jitter(0.2, 1).cell_field("cellval", |t, _| t as f32).raw();
/// ```
pub struct KuhnGrid<'a> {
    n: usize,
    spacing: Vec3,
    jitter: f32,
    seed: u64,
    jitter_boundary: bool,
    keep: Box<dyn Fn(Vec3) -> bool + 'a>,
    vertex_field: Box<dyn Fn(Vec3) -> f32 + 'a>,
    cell_name: String,
    cell_field: Box<dyn Fn(usize, Vec3) -> f32 + 'a>,
}

impl<'a> KuhnGrid<'a> {
    /// `n`³ cubes on [0, 1]³, regular, with the default fields.
    pub fn new(n: usize) -> Self {
        assert!(n >= 1, "a Kuhn grid needs at least one cube");
        KuhnGrid {
            n,
            spacing: [1.0 / n as f32; 3],
            jitter: 0.0,
            seed: 0,
            jitter_boundary: false,
            keep: Box::new(|_| true),
            vertex_field: Box::new(|p| p[0] + 2.0 * p[1] + 3.0 * p[2]),
            cell_name: "c".into(),
            cell_field: Box::new(|t, _| t as f32),
        }
    }

    /// Cube edge length per axis: the grid spans `[0, n · spacing[a]]` along axis `a`.
    pub fn spacing(mut self, spacing: Vec3) -> Self {
        self.spacing = spacing;
        self
    }

    /// Moves every interior vertex coordinate by a uniform random amount in
    /// `[-jitter, jitter]` cube widths, deterministically per `seed`; boundary vertices
    /// move only along their boundary faces, which stay flat.
    pub fn jitter(mut self, jitter: f32, seed: u64) -> Self {
        (self.jitter, self.seed) = (jitter, seed);
        self
    }

    /// Jitters the boundary vertices too (the boundary is then no longer flat).
    pub fn jitter_boundary(mut self) -> Self {
        self.jitter_boundary = true;
        self
    }

    /// Keeps only the tets whose centroid satisfies `keep` (all vertices are kept).
    pub fn keep(mut self, keep: impl Fn(Vec3) -> bool + 'a) -> Self {
        self.keep = Box::new(keep);
        self
    }

    /// The per-vertex field `f` as a function of the vertex position.
    pub fn vertex_field(mut self, f: impl Fn(Vec3) -> f32 + 'a) -> Self {
        self.vertex_field = Box::new(f);
        self
    }

    /// The per-cell field, named `name`, as a function of the tet id and centroid.
    pub fn cell_field(mut self, name: &str, f: impl Fn(usize, Vec3) -> f32 + 'a) -> Self {
        (self.cell_name, self.cell_field) = (name.into(), Box::new(f));
        self
    }

    /// The raw mesh, fields included.
    pub fn raw(&self) -> crate::RawMesh {
        use crate::mesh::{Field, FieldLocation};
        use rand::{Rng, SeedableRng};
        let (n, h) = (self.n, self.spacing);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(self.seed);
        let mut points = Vec::with_capacity((n + 1).pow(3));
        for k in 0..=n {
            for j in 0..=n {
                for i in 0..=n {
                    let g = [i, j, k];
                    points.push(std::array::from_fn(|a| {
                        let mut c = g[a] as f32 * h[a];
                        if self.jitter > 0.0 && (self.jitter_boundary || (g[a] > 0 && g[a] < n)) {
                            c += rng.gen_range(-self.jitter..=self.jitter) * h[a];
                        }
                        c
                    }));
                }
            }
        }
        const AXIS_ORDERS: [[usize; 3]; 6] = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
        let id = |c: [usize; 3]| (c[0] + (n + 1) * (c[1] + (n + 1) * c[2])) as u32;
        let centroid = |t: &[u32; 4]| -> Vec3 {
            std::array::from_fn(|a| t.iter().map(|&v| points[v as usize][a]).sum::<f32>() / 4.0)
        };
        let mut tets = Vec::with_capacity(6 * n * n * n);
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    for order in AXIS_ORDERS {
                        let mut c = [i, j, k];
                        let mut t = [id(c); 4];
                        for (s, &axis) in order.iter().enumerate() {
                            c[axis] += 1;
                            t[s + 1] = id(c);
                        }
                        if (self.keep)(centroid(&t)) {
                            tets.push(t);
                        }
                    }
                }
            }
        }
        let f = points.iter().map(|&p| (self.vertex_field)(p)).collect();
        let cell = tets.iter().enumerate().map(|(t, ids)| (self.cell_field)(t, centroid(ids))).collect();
        crate::RawMesh {
            fields: vec![
                Field { name: "f".into(), location: FieldLocation::Vertex, values: f },
                Field { name: self.cell_name.clone(), location: FieldLocation::Cell, values: cell },
            ],
            points,
            tets,
            higher_order: None,
            cells: None,
        }
    }

    /// The mesh, named `name`.
    pub fn mesh(&self, name: &str) -> crate::Mesh {
        crate::Mesh::new(self.raw(), name).expect("Kuhn grids are valid meshes")
    }
}
