use super::*;
use crate::geom::{self, Vec3};
use crate::test_support::grid_mesh;

#[test]
fn builds_valid_trees_for_every_preset() {
    // 20^3 cubes (48,000 tets): ranges built in parallel, then laid out together.
    for n in [1, 2, 5, 12, 20] {
        let m = grid_mesh(n, 0.3, n as u64);
        for preset in [BuildPreset::Fast, BuildPreset::SingleTetLeaves] {
            let bvh = Bvh::build(&m.points, &m.tets, preset);
            bvh.validate(&m.points, &m.tets).unwrap();
            assert_eq!(bvh.stats.n_prims, m.n_tets());
            assert!(bvh.nodes.iter().filter(|n| n.is_leaf()).all(|n| n.count as usize <= preset.max_leaf_size()));
            assert!(bvh.stats.report().contains(&format!("{} tets", m.n_tets())));
        }
    }
}

#[test]
fn validate_catches_broken_trees() {
    let m = grid_mesh(3, 0.3, 7);
    let good = Bvh::build(&m.points, &m.tets, BuildPreset::Fast);
    let mut b = good.clone();
    b.nodes[0].max[0] -= 0.5;
    assert!(b.validate(&m.points, &m.tets).is_err());
    let mut b = good.clone();
    let leaf = b.nodes.iter().position(|n| n.is_leaf()).unwrap();
    b.nodes[leaf].count -= 1;
    assert!(b.validate(&m.points, &m.tets).unwrap_err().contains("in no leaf"));
    let mut b = good;
    b.prim_ids[0] = b.prim_ids[1];
    assert!(b.validate(&m.points, &m.tets).is_err());
}

/// n^3 cubes, 6 tets each (Kuhn), taller than wide, every vertex jittered, as a mesh
/// (canonical tets, neighbours).
fn tall_grid(n: usize) -> crate::Mesh {
    crate::test_support::KuhnGrid::new(n).spacing([1.0, 1.0, 1.5]).jitter(0.05, n as u64).jitter_boundary().mesh("grid")
}

fn inside(m: &crate::Mesh, t: u32, p: Vec3) -> bool {
    matches!(geom::test_point(m.tets[t as usize], &m.points, p), geom::TetTest::Inside(_))
}

/// Whether tet `t` holds `p`: `Some(true)` strictly inside, `Some(false)` on its boundary.
fn claim(m: &crate::Mesh, t: u32, p: Vec3) -> Option<bool> {
    match geom::test_point(m.tets[t as usize], &m.points, p) {
        geom::TetTest::Inside(b) => Some(!b.contains(&0.0)),
        geom::TetTest::Outside { .. } => None,
    }
}

/// The CPU mirror of soft-bvh's `tl_walk` (shaders/common/walk.glsl) with the walk-start
/// rule of `tl_locate`: the walk's answer counts only when the point is strictly inside.
fn walk(m: &crate::Mesh, start: u32, p: Vec3, max_steps: u32) -> Option<u32> {
    let mut tet = start as i32; // EMPTY is -1: no walk
    for _ in 0..max_steps {
        if tet < 0 {
            break;
        }
        match geom::test_point(m.tets[tet as usize], &m.points, p) {
            geom::TetTest::Inside(b) if b.iter().all(|&w| w != 0.0) => return Some(tet as u32),
            geom::TetTest::Inside(_) => break,
            geom::TetTest::Outside { face } => tet = m.neighbors()[tet as usize][face],
        }
    }
    None
}

/// `n` [`scattered`] points, then the mesh's vertices and an edge midpoint of each tet: on
/// faces shared by many tets.
fn scattered_and_on_faces(m: &crate::Mesh, n: usize, seed: u64) -> Vec<Vec3> {
    let mut points = scattered(m.info.bounds_min, m.info.bounds_max, n, seed);
    points.extend(m.points.iter().copied());
    points.extend(
        m.tets.iter().map(|t| std::array::from_fn(|k| 0.5 * (m.points[t[0] as usize][k] + m.points[t[1] as usize][k]))),
    );
    points
}

/// Points around and in a mesh's box, 5 % beyond each side.
fn scattered(lo: Vec3, hi: Vec3, n: usize, mut s: u64) -> Vec<Vec3> {
    (0..n)
        .map(|_| {
            std::array::from_fn(|a| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                lo[a] + (hi[a] - lo[a]) * ((s >> 40) as f32 / (1u64 << 24) as f32 * 1.1 - 0.05)
            })
        })
        .collect()
}

/// Every leaf of the wide tree, walked on the CPU: each primitive with the dequantized box of
/// the reference that led to it.
fn wide_leaves(q: &WideBvh) -> Vec<(u32, Aabb)> {
    let mut out = vec![];
    let mut stack = vec![0u32];
    while let Some(i) = stack.pop() {
        let n = &q.nodes[i as usize];
        for c in 0..4 {
            let r = n.child[c];
            if r == wide::EMPTY {
                continue;
            }
            if r & wide::LEAF != 0 {
                let (first, count) = wide::leaf_range(r, q.direct);
                if q.direct {
                    out.push((first, n.child_box(c)));
                    continue;
                }
                out.extend((first..first + count).map(|k| (q.prims[k as usize], n.child_box(c))));
            } else {
                stack.push(r);
            }
        }
    }
    out
}

#[test]
fn wide_tree_holds_every_prim_once_inside_its_conservative_box() {
    let m = tall_grid(7);
    for preset in [BuildPreset::Fast, BuildPreset::SingleTetLeaves] {
        let bvh = Bvh::build(&m.points, &m.tets, preset);
        let q = WideBvh::collapse(&bvh).unwrap();
        assert!(q.nodes.len() < bvh.nodes.len() / 2, "{} 4-wide nodes for {} binary", q.nodes.len(), bvh.nodes.len());
        let mut seen = vec![0; m.n_tets()];
        for (t, b) in wide_leaves(&q) {
            seen[t as usize] += 1;
            let tb = Aabb::of_tet(m.tets[t as usize], &m.points);
            assert!(b.holds(&tb), "tet {t}: box {b:?} vs {tb:?}");
        }
        assert!(seen.iter().all(|&s| s == 1));
        assert_eq!(q.direct, preset == BuildPreset::SingleTetLeaves);
        assert!(q.depth >= 3 && q.depth < bvh.stats.max_depth + 1);
    }
}

#[test]
fn single_prim_tree() {
    let pts = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let tets = vec![geom::canonical_tet([0, 1, 2, 3], &pts).0];
    let q = WideBvh::collapse(&Bvh::build(&pts, &tets, BuildPreset::Fast)).unwrap();
    assert_eq!(wide_leaves(&q).len(), 1);
    let hit = q.traverse([0.1, 0.1, 0.1], 0, &mut vec![], |_| true);
    assert_eq!(hit, Traversal { prim: Some(0), nodes: 1 });
    assert!(WideBvh::collapse(&Bvh::default()).is_err());
}

/// The wide traversal (the shader's reference) and the binary BVH agree: the same points are
/// found, in the same tet wherever the point is strictly inside one; on a shared face each
/// finds a tet that holds the point.
#[test]
fn wide_traversal_agrees_with_the_binary_bvh() {
    let m = tall_grid(6);
    let points = scattered_and_on_faces(&m, 20_000, 3);
    for preset in [BuildPreset::Fast, BuildPreset::SingleTetLeaves] {
        let bvh = Bvh::build(&m.points, &m.tets, preset);
        let q = WideBvh::collapse(&bvh).unwrap();
        let mut stack = vec![];
        let (mut found, mut faces) = (0, 0);
        for &p in &points {
            let wide = q.traverse(p, 0, &mut stack, |t| inside(&m, t, p));
            let mut binary = FirstInside { mesh: &m, p, found: None };
            bvh.traverse(&mut binary);
            assert_eq!(wide.prim.is_some(), binary.found.is_some(), "{p:?}: wide {wide:?}, binary {:?}", binary.found);
            let (Some(w), Some(b)) = (wide.prim, binary.found) else { continue };
            found += 1;
            match geom::test_point(m.tets[b as usize], &m.points, p) {
                geom::TetTest::Inside(bary) if bary.iter().all(|&x| x != 0.0) => assert_eq!(w, b, "{p:?}"),
                _ => {
                    faces += 1;
                    assert!(inside(&m, w, p), "{p:?}: wide answer {w} does not hold it");
                }
            }
            assert!(wide.nodes >= 1 && wide.nodes as usize <= q.nodes.len());
        }
        assert!(found > 10_000 && faces > 300, "{found} found, {faces} on faces");
    }
}

/// The tie rule: whatever the tree's shape, the wide search answers the lowest id among the
/// tets that hold a point on faces, edges or vertices (every tet tested, by brute force), and
/// the one tet that holds any other point.
#[test]
fn wide_locate_answers_the_lowest_holder() {
    let m = tall_grid(4);
    let points = scattered_and_on_faces(&m, 3_000, 5);
    let mut ties = 0;
    for preset in [BuildPreset::Fast, BuildPreset::SingleTetLeaves] {
        let q = WideBvh::collapse(&Bvh::build(&m.points, &m.tets, preset)).unwrap();
        let mut stack = vec![];
        for &p in &points {
            let holders: Vec<u32> = (0..m.n_tets() as u32).filter(|&t| inside(&m, t, p)).collect();
            ties += (holders.len() > 1) as usize;
            let got = q.locate(p, 0, &mut stack, |t| claim(&m, t, p)).prim;
            assert_eq!(got, holders.first().copied(), "{p:?}: holders {holders:?}");
        }
    }
    assert!(ties > 200, "only {ties} points held by several tets");
}

/// The binary BVH's point query through its visitor.
struct FirstInside<'a> {
    mesh: &'a crate::Mesh,
    p: Vec3,
    found: Option<u32>,
}

impl Visitor for FirstInside<'_> {
    fn enter(&mut self, b: &Aabb) -> bool {
        b.holds(&Aabb { min: self.p, max: self.p })
    }
    fn prim(&mut self, id: u32) -> bool {
        let hit = inside(self.mesh, id, self.p);
        if hit {
            self.found = Some(id);
        }
        hit
    }
}

/// Every tet lies in the subtree of the entry of every cell its box overlaps.
#[test]
fn entry_grid_subtrees_hold_their_prims() {
    let m = tall_grid(6);
    let boxes = Aabb::of_tets(&m.tets, &m.points);
    for preset in [BuildPreset::Fast, BuildPreset::SingleTetLeaves] {
        let q = WideBvh::collapse(&Bvh::build(&m.points, &m.tets, preset)).unwrap();
        let bounds = (m.info.bounds_min, m.info.bounds_max);
        let g = EntryGrid::new(&q, boxes.len(), |t| boxes[t as usize], bounds, 4, None);
        assert!(g.cells.len() > 100 && g.cells.iter().all(|&c| c != wide::EMPTY));
        assert_eq!(g.words()[3], 0, "no walk starts");
        let below = |mut n: u32, anc: u32| loop {
            if n == anc {
                return true;
            }
            if q.parent[n as usize] == n {
                return false;
            }
            n = q.parent[n as usize];
        };
        for (t, b) in boxes.iter().enumerate() {
            for corner in [b.min, b.max] {
                let c = g.cell_of(corner);
                assert!(below(q.home[t], g.cells[c]), "tet {t} not under the entry of cell {c}");
            }
        }
        // Most cells start below the root (a 1M-tet jets mesh: median level 6-7 of 13).
        let deep = g.cells.iter().filter(|&&c| q.level[c as usize] > 1).count();
        assert!(deep * 2 > g.cells.len(), "{deep} of {} cells start below the root", g.cells.len());
    }
}

/// Walk starts hold their cell's centre (or at least overlap the cell), and the reference
/// location (walk from the start, traversal from the cell's node) finds what the traversal
/// from the root finds, for points anywhere.
#[test]
fn walk_starts_lead_to_the_traversal_answer() {
    let m = tall_grid(6);
    let q = WideBvh::collapse(&Bvh::build(&m.points, &m.tets, BuildPreset::SingleTetLeaves)).unwrap();
    let (lo, hi) = (m.info.bounds_min, m.info.bounds_max);
    let claims = |t: u32, p: Vec3| claim(&m, t, p);
    let g = EntryGrid::new(&q, m.n_tets(), |t| Aabb::of_tet(m.tets[t as usize], &m.points), (lo, hi), 1, Some(&claims));
    assert_eq!(g.starts.len(), g.cells.len());
    assert_eq!(g.words()[3] as usize, g.cells.len());
    let mut held = 0;
    for i in 0..g.cells.len() {
        let t = g.starts[i];
        assert!(t != wide::EMPTY && (t as usize) < m.n_tets());
        held += inside(&m, t, g.centre(i)) as usize;
    }
    assert!(held * 10 >= g.cells.len() * 9, "only {held} of {} starts hold their cell's centre", g.cells.len());
    let (mut walked, mut stack) = (0, vec![]);
    for p in scattered(lo, hi, 20_000, 7) {
        let want = q.traverse(p, 0, &mut stack, |t| inside(&m, t, p)).prim;
        let mut settled = false;
        let got = g.locate(
            &q,
            p,
            &mut stack,
            |start| {
                let w = walk(&m, start, p, 32);
                settled = w.is_some();
                w
            },
            |t| claim(&m, t, p),
        );
        assert_eq!(got.is_some(), want.is_some(), "{p:?}");
        if settled {
            assert_eq!(got, want, "walk to {p:?}");
            walked += 1;
        } else if let Some(t) = got {
            assert!(inside(&m, t, p));
        }
    }
    assert!(walked > 10_000, "only {walked} walks settled their point");
}
