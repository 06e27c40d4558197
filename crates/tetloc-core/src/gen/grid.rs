//! The machinery every shape shares: a structured grid of `ni × nj` columns of `nk` cubes,
//! some columns kept, each kept cube split into the 6 Kuhn tets of its cube, or made into
//! other cells ([`CellKind`]): a hexahedron, two wedges, or, in the hybrid, layers of both with
//! a pyramid transition into Kuhn tets (see [`cube_cells`] for why those are conforming too).
//!
//! **Why it is conforming.** The Kuhn split (all six tets share the cube's main diagonal) is
//! the same in every cell, so the diagonal it puts on a cube face is the same one the
//! neighbour puts there: every interior face is shared by exactly two tets, whatever the
//! mask of kept columns, and also across a periodic wrap of `k` (the split is invariant
//! under integer translation).
//!
//! **Why no tet inverts.** Every Kuhn tet steps through `k` exactly once, so it has one edge
//! between two levels of the *same* vertex column, and its projection along the columns is
//! a Kuhn triangle of the 2D grid. Shapes jitter a whole vertex column in-plane (by at most
//! [`XY_JITTER`] of the spacing, small enough that no 2D triangle flips) and jitter its
//! levels independently but keep them strictly increasing in `k`; then each tet's volume
//! is (edge length × projected triangle area)/3 in the straight-column shapes and close to
//! it in the gently swept torus, so it stays positive.

use super::{CellKind, Phase, Progress};
use crate::cell::{CellBlock, CellType};
use crate::geom::Vec3;
use crate::mesh::{Field, FieldLocation, RawMesh};
use rayon::prelude::*;

/// In-plane jitter of a vertex column, as a fraction of the column spacing. Each vertex of a
/// 2D Kuhn triangle then moves by at most 0.12·√2 of the spacing, which changes twice the
/// triangle's area (1) by at most 2·(2·0.17) + (2·0.17)² < 0.8: it cannot flip.
pub(super) const XY_JITTER: f64 = 0.12;

/// Plan position of vertex column `(i, j)` of a layer with spacing `h`, jittered sideways.
pub(super) fn column_xy(seed: u64, i: usize, j: usize, h: f64) -> (f64, f64) {
    let (jx, jy) = super::noise::column_jitter(seed, i, j);
    ((i as f64 + XY_JITTER * jx) * h, (j as f64 + XY_JITTER * jy) * h)
}

/// Jitter of a level inside its column, as a fraction of the level spacing: levels stay at
/// least 0.4 spacings apart, so they keep their order.
pub(super) const LEVEL_JITTER: f64 = 0.3;

/// Columns handled per parallel task: amortises scheduling and progress updates.
const BLOCK: usize = 64;

/// The 6 Kuhn tets of a cube, as corners `c = dx | dy << 1 | dz << 2`. Tet `(a, b, c)` walks
/// 0 → e_a → e_a + e_b → 7 for a permutation of the axes; for odd permutations the last two
/// are swapped so that every tet is right-handed (`geom::tet_volume6 > 0`, as VTK expects).
const KUHN: [[usize; 4]; 6] = [
    [0, 1, 3, 7], // x y z (even)
    [0, 1, 7, 5], // x z y
    [0, 2, 7, 3], // y x z
    [0, 2, 6, 7], // y z x (even)
    [0, 4, 5, 7], // z x y (even)
    [0, 4, 7, 6], // z y x
];

/// A cell of a cube: its VTK type code and its corners (`c = dx | dy << 1 | dz << 2`) in VTK's
/// node order, right-handed.
type CubeCell = (u8, &'static [usize]);

const HEX: &[CubeCell] = &[(12, &[0, 1, 3, 2, 4, 5, 7, 6])];
/// Two wedges over the plan triangles of the Kuhn diagonal (plan corners 0–3), so that their
/// top and bottom triangles match the Kuhn tets' faces on a cube's top and bottom.
const WEDGES: &[CubeCell] = &[(13, &[0, 1, 3, 4, 5, 7]), (13, &[0, 3, 2, 4, 7, 6])];
/// From a quad below to Kuhn tets above: a pyramid on the bottom quad with its apex at corner
/// 4, and the cone from corner 4 over the two far side faces. Its side faces carry the
/// diagonals 1–4, 2–4 (its own pyramid) and 3–5, 3–6 (the cones), which are the same faces
/// of the neighbouring transition cubes seen from the other side; its top carries 4–7, the
/// Kuhn diagonal of the cube above.
const TRANSITION: &[CubeCell] =
    &[(14, &[0, 1, 3, 2, 4]), (10, &[4, 1, 3, 5]), (10, &[4, 3, 7, 5]), (10, &[4, 3, 2, 6]), (10, &[4, 7, 3, 6])];
/// [`TRANSITION`] upside down (corners `c ^ 4`, orientation restored): from Kuhn tets below to a
/// quad above, for the wrap of periodic columns.
const TRANSITION_DOWN: &[CubeCell] =
    &[(14, &[4, 6, 7, 5, 0]), (10, &[0, 5, 1, 7]), (10, &[0, 7, 1, 3]), (10, &[0, 7, 2, 6]), (10, &[0, 3, 2, 7])];
const KUHN_CELLS: &[CubeCell] =
    &[(10, &KUHN[0]), (10, &KUHN[1]), (10, &KUHN[2]), (10, &KUHN[3]), (10, &KUHN[4]), (10, &KUHN[5])];

/// The cells of the cube at level `k` of a column of `nk` (`periodic`: level `nk` is level 0).
///
/// The hybrid stacks, bottom to top: hexahedra (the lowest quarter), one transition layer,
/// Kuhn tets, and wedges (the top quarter: a prism boundary layer). Every interface is
/// conforming: hex and transition share a quad, transition and Kuhn the diagonal 4–7, Kuhn and
/// wedges the diagonal 0–3 of the plan, and cells of one layer repeat by translation. Periodic
/// columns end with [`TRANSITION_DOWN`] instead of wedges, back to the hexes at level 0.
pub(super) fn cube_cells(kind: CellKind, k: usize, nk: usize, periodic: bool) -> &'static [CubeCell] {
    match kind {
        CellKind::Tets => KUHN_CELLS,
        // The octree's coarse grid (gen::octree builds those meshes itself).
        CellKind::Hexes | CellKind::Octree => HEX,
        CellKind::Wedges => WEDGES,
        CellKind::Hybrid => {
            let hexes = (nk / 4).max(1);
            let wedges_from = if periodic { nk } else { (nk - nk / 4).max(hexes + 1) };
            match k {
                k if k < hexes => HEX,
                k if k == hexes => TRANSITION,
                k if periodic && k + 1 == nk => TRANSITION_DOWN,
                k if k >= wedges_from => WEDGES,
                _ => KUHN_CELLS,
            }
        }
    }
}

/// How a thin layer over a `width × length` rectangle is cut into columns: `n_keep` kept
/// columns (a `kept_fraction` of all) of `nk` cubes each, square in plan with side `h`, so that
/// the cube count is about `cells` when a column is `thickness / h` cubes deep on average.
pub(super) struct LayerPlan {
    pub ni: usize,
    pub nj: usize,
    pub nk: usize,
    pub n_keep: usize,
    pub h: f64,
}

impl LayerPlan {
    /// cells = K · thickness / h with h = √(kept area / K)  ⇒  K = (cells · √area / thickness)^⅔.
    pub fn new(cells: usize, kept_fraction: f64, width: f64, length: f64, thickness: f64) -> LayerPlan {
        let area = kept_fraction * width * length;
        let k_est = (cells as f64 * area.sqrt() / thickness).powf(2.0 / 3.0);
        let nk = ((cells as f64 / k_est.max(1.0)).round() as usize).max(2);
        let n_keep = ((cells as f64 / nk as f64).round() as usize).max(1);
        let n_cols = n_keep as f64 / kept_fraction;
        let ni = ((n_cols * width / length).sqrt().round() as usize).max(2);
        let nj = ((n_cols / ni as f64).ceil() as usize).max(2);
        LayerPlan { ni, nj, nk, n_keep, h: width / ni as f64 }
    }

    /// The plan-view centre of column `c` (row-major, `i` fastest).
    pub fn centre(&self, c: usize) -> (f64, f64) {
        (((c % self.ni) as f64 + 0.5) * self.h, ((c / self.ni) as f64 + 0.5) * self.h)
    }
}

/// The grid: which of the `ni × nj` columns (row-major, `i` fastest) are kept, and how many
/// cells each column has.
pub(super) struct Columns {
    pub ni: usize,
    pub nj: usize,
    pub nk: usize,
    /// Level `nk` is level 0 again (the torus' toroidal direction).
    pub periodic_k: bool,
    pub keep: Vec<bool>,
}

impl Columns {
    pub fn full(ni: usize, nj: usize, nk: usize) -> Columns {
        Columns { ni, nj, nk, periodic_k: false, keep: vec![true; ni * nj] }
    }

    /// Vertices per vertex column.
    pub fn levels(&self) -> usize {
        if self.periodic_k {
            self.nk
        } else {
            self.nk + 1
        }
    }

    pub fn n_kept(&self) -> usize {
        self.keep.iter().filter(|&&k| k).count()
    }

    /// Kept columns over the columns of their bounding rectangle: the footprint's share of
    /// the bounding box in the column plane.
    pub fn kept_box_fraction(&self) -> f64 {
        let (mut i0, mut i1, mut j0, mut j1) = (usize::MAX, 0, usize::MAX, 0);
        for j in 0..self.nj {
            for i in 0..self.ni {
                if self.keep[j * self.ni + i] {
                    (i0, i1, j0, j1) = (i0.min(i), i1.max(i), j0.min(j), j1.max(j));
                }
            }
        }
        if i0 > i1 {
            return 0.0;
        }
        self.n_kept() as f64 / ((i1 - i0 + 1) * (j1 - j0 + 1)) as f64
    }
}

/// Marks the `k` smallest of `values`; ties go to the lower index, so the choice is
/// deterministic. Used to cut exactly as many columns as the tet count needs.
pub(super) fn keep_lowest(values: &[f64], k: usize) -> Vec<bool> {
    let k = k.min(values.len());
    let mut keep = vec![false; values.len()];
    if k == 0 {
        return keep;
    }
    let mut idx: Vec<u32> = (0..values.len() as u32).collect();
    idx.select_nth_unstable_by(k - 1, |&a, &b| values[a as usize].total_cmp(&values[b as usize]).then(a.cmp(&b)));
    for &i in &idx[..k] {
        keep[i as usize] = true;
    }
    keep
}

/// What a shape provides: the grid, and where the vertices of a vertex column go.
pub(super) trait ColumnShape: Sync {
    fn columns(&self) -> &Columns;
    /// Positions of the `levels()` vertices of vertex column `(i, j)`, `0 ≤ i ≤ ni`,
    /// `0 ≤ j ≤ nj`, in order of `k`.
    fn column_points(&self, i: usize, j: usize, out: &mut [Vec3]);
}

/// The smooth per-vertex field `f`, the same formula as the shared test data's.
#[inline]
fn field_f(p: Vec3) -> f32 {
    let (x, y, z) = (p[0] as f64, p[1] as f64, p[2] as f64);
    ((3.0 * x + 1.0).sin() * (2.0 * y).cos() + 0.5 * (4.0 * z).sin() + 0.3 * x * y) as f32
}

/// The per-cell field `cellval`: ((id · 2654435761) mod 2³²) / 2³², as in the shared data.
#[inline]
fn cellval(id: usize) -> f32 {
    ((id as u32).wrapping_mul(2_654_435_761) as f64 / 4_294_967_296.0) as f32
}

/// Builds the mesh: only the vertex columns that a kept column touches get vertices;
/// vertices are numbered column by column, cells kept column by kept column.
pub(super) fn build(shape: &dyn ColumnShape, kind: CellKind, progress: &Progress) -> RawMesh {
    let g = shape.columns();
    let (ni, nj, nk) = (g.ni, g.nj, g.nk);
    let levels = g.levels();
    let vni = ni + 1;
    let kept = |i: usize, j: usize| g.keep[j * ni + i];

    // Vertex columns in use and the index of each among them.
    let mut vindex = vec![u32::MAX; vni * (nj + 1)];
    let mut used: Vec<(u32, u32)> = Vec::new();
    for vj in 0..=nj {
        for vi in 0..=ni {
            let (i0, i1) = (vi.saturating_sub(1), vi.min(ni - 1));
            let (j0, j1) = (vj.saturating_sub(1), vj.min(nj - 1));
            if kept(i0, j0) || kept(i1, j0) || kept(i0, j1) || kept(i1, j1) {
                vindex[vj * vni + vi] = used.len() as u32;
                used.push((vi as u32, vj as u32));
            }
        }
    }
    let cells: Vec<(u32, u32)> = (0..nj)
        .flat_map(|j| (0..ni).map(move |i| (i as u32, j as u32)))
        .filter(|&(i, j)| kept(i as usize, j as usize))
        .collect();

    let n_points = used.len() * levels;
    let n_tets = cells.len() * nk * 6;
    // Progress: weighted by the bytes each phase writes.
    let (p_end, t_end) = (0.05 + 0.9 * n_points as f64 * 16.0 / (n_points as f64 * 16.0 + n_tets as f64 * 20.0), 0.95);

    let mut points = vec![[0f32; 3]; n_points];
    let mut f = vec![0f32; n_points];
    let phase = Phase::new(progress, 0.05, p_end, used.len());
    points.par_chunks_mut(levels * BLOCK).zip(f.par_chunks_mut(levels * BLOCK)).enumerate().for_each(
        |(b, (pts, vals))| {
            for (c, (p, v)) in pts.chunks_mut(levels).zip(vals.chunks_mut(levels)).enumerate() {
                let (i, j) = used[b * BLOCK + c];
                shape.column_points(i as usize, j as usize, p);
                for (v, &q) in v.iter_mut().zip(p.iter()) {
                    *v = field_f(q);
                }
            }
            phase.advance(pts.len() / levels);
        },
    );

    let fields = |f: Vec<f32>, n_cells: usize| {
        let mut cv = vec![0f32; n_cells];
        cv.par_iter_mut().enumerate().for_each(|(t, v)| *v = cellval(t));
        vec![Field::new("f", FieldLocation::Vertex, f), Field::new("cellval", FieldLocation::Cell, cv)]
    };
    // First vertex id of each corner's vertex column of column (i, j), corners as in KUHN (dx, dy).
    let bases = |i: usize, j: usize| -> [u32; 4] {
        std::array::from_fn(|c| {
            let (vi, vj) = (i + (c & 1), j + (c >> 1));
            vindex[vj * vni + vi] * levels as u32
        })
    };
    let corner_at = |base: &[u32; 4], k: usize, c: usize| {
        let k1 = if k + 1 == levels { 0 } else { k + 1 }; // periodic wrap
        base[c & 3] + if c & 4 == 0 { k as u32 } else { k1 as u32 }
    };
    if kind != CellKind::Tets {
        let block = cell_block(g, kind, &cells, &bases, &corner_at, &Phase::new(progress, p_end, t_end, cells.len()));
        progress.report(1.0);
        let n = block.len();
        return RawMesh {
            points,
            points64: None,
            tets: Vec::new(),
            fields: fields(f, n),
            higher_order: None,
            cells: Some(block),
        };
    }

    let mut tets = vec![[0u32; 4]; n_tets];
    let phase = Phase::new(progress, p_end, t_end, cells.len());
    tets.par_chunks_mut(6 * nk * BLOCK).enumerate().for_each(|(b, out)| {
        for (c, col) in out.chunks_mut(6 * nk).enumerate() {
            let (i, j) = (cells[b * BLOCK + c].0 as usize, cells[b * BLOCK + c].1 as usize);
            let base = bases(i, j);
            for k in 0..nk {
                for (t, tet) in KUHN.iter().enumerate() {
                    col[6 * k + t] = tet.map(|c| corner_at(&base, k, c));
                }
            }
        }
        phase.advance(out.len() / (6 * nk));
    });
    progress.report(1.0);
    RawMesh { points, points64: None, tets, fields: fields(f, n_tets), higher_order: None, cells: None }
}

/// The cells of every kept column, as a cell block: every column has the same cells (by
/// level), so each column's share of the arrays has a fixed size and columns fill in parallel.
fn cell_block(
    g: &Columns,
    kind: CellKind,
    columns: &[(u32, u32)],
    bases: &(dyn Fn(usize, usize) -> [u32; 4] + Sync),
    corner_at: &(dyn Fn(&[u32; 4], usize, usize) -> u32 + Sync),
    phase: &Phase,
) -> CellBlock {
    let layers: Vec<&[CubeCell]> = (0..g.nk).map(|k| cube_cells(kind, k, g.nk, g.periodic_k)).collect();
    let per_col: usize = layers.iter().map(|l| l.len()).sum();
    let nodes_per_col: usize = layers.iter().flat_map(|l| l.iter()).map(|c| c.1.len()).sum();
    let types_of = |code: u8, n: usize| CellType::from_vtk(code, n).expect("linear cells are known");
    let col_types: Vec<CellType> = layers.iter().flat_map(|l| l.iter()).map(|c| types_of(c.0, c.1.len())).collect();
    // Ends within a column, then shifted by the column's start.
    let col_ends: Vec<u64> = layers
        .iter()
        .flat_map(|l| l.iter())
        .scan(0u64, |e, c| {
            *e += c.1.len() as u64;
            Some(*e)
        })
        .collect();
    let n = columns.len();
    let mut types = vec![CellType::tet(); n * per_col];
    types.par_chunks_mut(per_col).for_each(|t| t.copy_from_slice(&col_types));
    let mut ends = vec![0u64; n * per_col];
    ends.par_chunks_mut(per_col).enumerate().for_each(|(c, e)| {
        let start = (c * nodes_per_col) as u64;
        e.iter_mut().zip(&col_ends).for_each(|(e, &ce)| *e = start + ce);
    });
    let mut conn = vec![0u32; n * nodes_per_col];
    conn.par_chunks_mut(nodes_per_col * BLOCK).enumerate().for_each(|(b, out)| {
        for (c, col) in out.chunks_mut(nodes_per_col).enumerate() {
            let (i, j) = columns[b * BLOCK + c];
            let base = bases(i as usize, j as usize);
            let mut at = 0;
            for (k, layer) in layers.iter().enumerate() {
                for cell in layer.iter() {
                    for &corner in cell.1 {
                        col[at] = corner_at(&base, k, corner);
                        at += 1;
                    }
                }
            }
        }
        phase.advance(out.len() / nodes_per_col);
    });
    CellBlock { types, ends, conn, ..CellBlock::default() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::tet_volume6;

    #[test]
    fn kuhn_tets_are_positive_and_fill_the_cube() {
        let corner = |c: usize| [(c & 1) as f32, ((c >> 1) & 1) as f32, ((c >> 2) & 1) as f32];
        let mut total = 0.0;
        for tet in KUHN {
            let v = tet_volume6(tet.map(corner));
            assert!(v > 0.0, "{tet:?} has volume×6 {v}");
            total += v;
        }
        assert_eq!(total, 6.0, "the six tets do not fill the unit cube");
    }

    /// Every cube pattern's cells are right-handed and fill the unit cube exactly.
    #[test]
    fn cube_cells_are_positive_and_fill_the_cube() {
        use crate::cell::decompose;
        let corner = |c: usize| [(c & 1) as f32, ((c >> 1) & 1) as f32, ((c >> 2) & 1) as f32];
        for (name, cells) in [
            ("hex", HEX),
            ("wedges", WEDGES),
            ("transition", TRANSITION),
            ("down", TRANSITION_DOWN),
            ("kuhn", KUHN_CELLS),
        ] {
            let mut total = 0.0;
            for &(code, corners) in cells {
                let ty = CellType::from_vtk(code, corners.len()).unwrap();
                let ids: Vec<u32> = corners.iter().map(|&c| c as u32).collect();
                for t in decompose(ty.shape(), &ids).tets() {
                    let v = tet_volume6(t.map(|k| corner(corners[usize::from(k)])));
                    assert!(v > 0.0, "{name}: a {code} cell {corners:?} has a tet of volume×6 {v}");
                    total += v;
                }
            }
            assert_eq!(total, 6.0, "{name} does not fill the unit cube");
        }
    }

    #[test]
    fn keep_lowest_picks_exactly_k_with_ties_by_index() {
        let v = [3.0, 1.0, 2.0, 1.0, 5.0];
        assert_eq!(keep_lowest(&v, 2), vec![false, true, false, true, false]);
        assert_eq!(keep_lowest(&v, 0), vec![false; 5]);
        assert_eq!(keep_lowest(&[1.0, 1.0, 1.0], 1), vec![true, false, false]);
        assert_eq!(keep_lowest(&v, 9).iter().filter(|&&k| k).count(), 5);
    }

    #[test]
    fn cellval_matches_the_shared_data_formula() {
        for id in [0usize, 1, 2, 12345, 70_000_000] {
            let want = ((id as u64 * 2_654_435_761) % (1u64 << 32)) as f64 / (1u64 << 32) as f64;
            assert_eq!(cellval(id), want as f32);
        }
    }
}
