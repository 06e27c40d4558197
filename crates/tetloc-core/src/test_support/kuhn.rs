//! The one test-mesh builder of every crate ([`KuhnGrid`]).
//!
//! One source for two crates: core's unit tests compile it into `test_support`, and
//! `tetloc-testdata` includes this same file (`#[path]`) for every other crate's tests. Each
//! includer supplies the mesh types through its own imports (`super::`), so core's tests get
//! core's own types and nothing is written twice.

use super::{Field, FieldLocation, Mesh, RawMesh, Vec3};

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
    pub fn raw(&self) -> RawMesh {
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
        RawMesh {
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
    pub fn mesh(&self, name: &str) -> Mesh {
        Mesh::new(self.raw(), name).expect("Kuhn grids are valid meshes")
    }
}
