//! The one test-mesh builder of every crate ([`KuhnGrid`]).
//!
//! One source for two crates: core's unit tests compile it into `test_support`, and
//! `tetloc-testdata` includes this same file (`#[path]`) for every other crate's tests. Each
//! includer supplies the mesh types through its own imports (`super::`), so core's tests get
//! core's own types and nothing is written twice.

use super::{barycentric_lattice, CellBlock, CellType, Field, FieldLocation, Mesh, RawMesh, Vec3};

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
    order: u8,
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
            order: 1,
        }
    }

    /// Makes every tet a straight-sided Lagrange tet of order `p` (2: VTK's quadratic tet,
    /// 3 and up: VTK's Lagrange tet): nodes on each tet's lattice, shared between the tets
    /// that share the edge or face, appended after the grid's vertices, in `cells`.
    pub fn order(mut self, p: u8) -> Self {
        self.order = p;
        self
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
        let cell = tets.iter().enumerate().map(|(t, ids)| (self.cell_field)(t, centroid(ids))).collect();
        let cells = (self.order > 1).then(|| elevate(&mut points, &tets, self.order));
        let f = points.iter().map(|&p| (self.vertex_field)(p)).collect();
        RawMesh {
            fields: vec![
                Field::new("f", FieldLocation::Vertex, f),
                Field::new(self.cell_name.clone(), FieldLocation::Cell, cell),
            ],
            points,
            points64: None,
            tets,
            higher_order: (self.order > 1).then_some(self.order),
            cells,
        }
    }

    /// The mesh, named `name`.
    pub fn mesh(&self, name: &str) -> Mesh {
        Mesh::new(self.raw(), name).expect("Kuhn grids are valid meshes")
    }
}

/// The tets as straight-sided Lagrange tets of order `p`: each node at `Σ α_j v_j / p` for its
/// barycentric lattice index `α`, one vertex per distinct (corner ids, α) so that neighbours
/// share their edge and face nodes; new vertices are appended to `points`.
fn elevate(points: &mut Vec<Vec3>, tets: &[[u32; 4]], p: u8) -> CellBlock {
    let ty = if p == 2 {
        CellType::from_vtk(24, 10)
    } else {
        CellType::from_vtk(71, usize::from(p + 1) * usize::from(p + 2) * usize::from(p + 3) / 6)
    }
    .expect("a Lagrange tet of this order");
    let lattice = barycentric_lattice(ty.def());
    let mut shared: std::collections::HashMap<Vec<(u32, u8)>, u32> = std::collections::HashMap::new();
    let mut block = CellBlock::default();
    let mut nodes = Vec::with_capacity(lattice.len());
    for t in tets {
        nodes.clear();
        for alpha in &lattice {
            let mut key: Vec<(u32, u8)> = (0..4).filter(|&j| alpha[j] > 0).map(|j| (t[j], alpha[j])).collect();
            if key.len() == 1 {
                nodes.push(key[0].0); // a corner
                continue;
            }
            key.sort_unstable();
            let id = *shared.entry(key).or_insert_with(|| {
                let x = std::array::from_fn(|k| {
                    (0..4).map(|j| f64::from(alpha[j]) * f64::from(points[t[j] as usize][k])).sum::<f64>()
                        / f64::from(p)
                });
                points.push(x.map(|c: f64| c as f32));
                (points.len() - 1) as u32
            });
            nodes.push(id);
        }
        block.push(ty, &nodes);
    }
    block
}

/// The usual jittered test grid: `n`³ cubes on `[0, 1]³`, interior vertices jittered by up to
/// `jitter` × spacing, with a smooth vertex field `f` and the tet ids as cell field `cellval`.
pub fn jittered_grid(n: usize, jitter: f32, seed: u64) -> RawMesh {
    KuhnGrid::new(n)
        .jitter(jitter, seed)
        .vertex_field(|p| (3.0 * p[0]).sin() + p[1] * p[2])
        .cell_field("cellval", |t, _| t as f32)
        .raw()
}
