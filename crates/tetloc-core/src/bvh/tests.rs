use super::*;
use crate::test_support::grid_mesh;

#[test]
fn builds_valid_trees_for_every_preset() {
    for n in [1, 2, 5, 12] {
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
