//! The cell geometry against VTK's own answers on `../shared/data/mixed` (warped hexes, wedges,
//! and a hybrid of all four shapes, made by gmsh and answered by VTK's `EvaluatePosition`), and
//! a first check of the location design ([`Design`]) on them.

use super::brute_force::{compare, Design, Mismatches, Mixed};
use super::*;
use crate::io::vtk::vtu;
use crate::test_support::{query_sets, require_data, QuerySet};
use std::collections::HashMap;

/// The oracle sets of `mixed/`, each with its mesh.
fn mixed_sets(test: &str) -> Vec<(QuerySet, std::path::PathBuf)> {
    let Some(dir) = require_data(test) else { return Vec::new() };
    let sets = query_sets(&dir.join("mixed"));
    assert!(sets.len() >= 9, "{test}: expected the 9 sets of mixed/, found {}", sets.len());
    sets.into_iter()
        .map(|s| {
            let mesh = s.label.split('.').next().unwrap().to_string();
            (s, dir.join("mixed").join(format!("{mesh}.zlib.vtu")))
        })
        .collect()
}

/// For every query point VTK places in a cell c: p's parametric coordinates in c (by Newton)
/// lie in c's domain, unless VTK flagged the point as within 1e-6 of c's boundary; and `f`
/// interpolated there with c's shape functions matches VTK's value.
#[test]
fn oracle_cells_hold_their_points_with_their_values() {
    let mut meshes: HashMap<std::path::PathBuf, Mixed> = HashMap::new();
    for (set, path) in mixed_sets("oracle_cells_hold_their_points_with_their_values") {
        let m = meshes.entry(path.clone()).or_insert_with(|| Mixed::load(&path));
        let max_f = m.f.iter().fold(0.0f64, |a, &v| a.max(f64::from(v).abs()));
        let values = set.value.as_ref().expect("mixed sets carry values");
        let (mut checked, mut outside, mut failed, mut wrong_value, mut worst) = (0, 0, 0, 0, 0.0f64);
        for (i, &c) in set.cell.iter().enumerate() {
            let Ok(c) = usize::try_from(c) else { continue };
            checked += 1;
            let p = set.points[i].map(f64::from);
            let Ok(pc) = m.pcoords(c, p) else {
                failed += 1;
                continue;
            };
            if !m.cells.types[c].shape().contains(pc) && !set.ambiguous(i) {
                outside += 1;
            }
            let (got, want) = (m.value(c, pc), values[i]);
            let tol = 1e-5 * want.abs() + 2e-6 * max_f;
            worst = worst.max((got - want).abs() / tol);
            if (got - want).abs() > tol {
                wrong_value += 1;
            }
        }
        eprintln!(
            "{}: {checked} points in cells: {failed} Newton failures, {outside} outside their cell, \
             {wrong_value} wrong values (worst error {worst:.3} of the tolerance)",
            set.label
        );
        assert!(checked > 0, "{}", set.label);
        assert_eq!((failed, outside, wrong_value), (0, 0, 0), "{}", set.label);
    }
}

/// The brute-force check of the design on every mixed oracle set: the refined answers match
/// VTK's everywhere outside the ambiguous points; the bare decomposition, for comparison, does
/// not on warped meshes.
#[test]
fn decomposition_with_refinement_matches_vtk() {
    let mut meshes: HashMap<std::path::PathBuf, (Mixed, Design)> = HashMap::new();
    let mut fixed = 0;
    for (set, path) in mixed_sets("decomposition_with_refinement_matches_vtk") {
        let (m, design) = meshes.entry(path.clone()).or_insert_with(|| {
            let m = Mixed::load(&path);
            let d = Design::build(&m);
            (m, d)
        });
        let bare = compare(&set, |p| design.partition(m, p).map_or(-1, |c| c as i32));
        let refined = compare(&set, |p| design.locate(m, p));
        // How often the parametric check runs: points whose decomposition cell has a warped face.
        let checked =
            set.points.iter().filter(|&&p| design.partition(m, p).is_some_and(|c| design.warped[c] != 0)).count();
        eprintln!(
            "{}: {} points, {checked} in cells with a warped face; decomposition alone {bare:?}; refined {refined:?}",
            set.label,
            set.points.len()
        );
        assert_eq!(refined, Mismatches::default(), "{}: the refined design disagrees with VTK", set.label);
        fixed += bare.total();
    }
    if !meshes.is_empty() {
        assert!(fixed > 0, "warped faces should make the bare decomposition differ from VTK somewhere");
    }
}

/// Issue 9 item 8 on a real file: f = x² + y² + z² given at the nodes of straight-sided
/// quadratic tets is interpolated exactly at any point, located by the corners.
#[test]
fn quadratic_tets_interpolate_quadratics_exactly() {
    use rand::{Rng, SeedableRng};
    let Some(dir) = require_data("quadratic_tets_interpolate_quadratics_exactly") else { return };
    let raw = vtu::read(&dir.join("real/quadratic_tetra.vtu")).unwrap();
    let cells = raw.cells.as_ref().unwrap();
    let points: Vec<Point> = raw.points.iter().map(|p| p.map(f64::from)).collect();
    let f = |x: Point| x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
    let values: Vec<f64> = points.iter().map(|&x| f(x)).collect();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
    let (mut worst, mut linear_worst) = (0.0f64, 0.0f64);
    for c in 0..cells.len() {
        let def = cells.types[c].def();
        assert_eq!(def.name(), "quadratic tetra");
        let nodes: Vec<Point> = cells.nodes(c).iter().map(|&i| points[i as usize]).collect();
        for _ in 0..20 {
            let pc: PCoords = loop {
                let pc = std::array::from_fn(|_| rng.gen_range(0.0..1.0));
                if def.shape().contains(pc) {
                    break pc;
                }
            };
            let x = forward(def, &nodes, pc);
            let located = invert(def.shape().linear, &nodes[..4], x).unwrap();
            let got = interpolate(def, located, |k| values[cells.nodes(c)[k] as usize]);
            let linear = interpolate(def.shape().linear, located, |k| values[cells.nodes(c)[k] as usize]);
            worst = worst.max((got - f(x)).abs());
            linear_worst = linear_worst.max((linear - f(x)).abs());
        }
    }
    eprintln!("quadratic_tetra.vtu: error {worst:.2e} with all nodes, {linear_worst:.2e} with the corners only");
    assert!(worst < 1e-9, "quadratic interpolation misses x² + y² + z² by {worst}");
    assert!(linear_worst > 1e-3, "the linear interpolation should miss it (the test would not tell)");
}
