//! The cell geometry against VTK's own answers on `../shared/data/mixed` (warped hexes, wedges,
//! and a hybrid of all four shapes, made by gmsh and answered by VTK's `EvaluatePosition`), and
//! a first check of the location design ([`Design`]) on them.

use super::brute_force::{compare, Design, Mismatches, Mixed};
use super::*;
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

/// Issue 9 item 8 on the shared data's higher-order files (quadratic, cubic and quartic tets
/// from VTK and Gmsh): f = x² + y² + z² given at every node is sampled by the CPU locator
/// exactly (to f32 rounding) at random points of the straight-sided tets (nodes on their
/// lattices: the isoparametric map is affine there), and 0.5-ish off with the corners alone.
///
/// Curved tets are measured, not asserted: the locator's value (the tet's shape functions at
/// the *corner* barycentrics) against VTK's (at the isoparametric preimage, by Newton with all
/// nodes), relative to the field's range.
#[test]
fn higher_order_files_sample_quadratics_exactly() {
    use crate::locate::{BatchLocator, CpuLocator};
    use crate::mesh::{Field, FieldLocation, Mesh};
    use rand::{Rng, SeedableRng};
    use std::sync::Arc;
    let Some(dir) = require_data("higher_order_files_sample_quadratics_exactly") else { return };
    let f = |x: Point| x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
    let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
    for file in ["real/quadratic_tetra.vtu", "real/kiefer.vtu", "real/P3.msh", "real/ArmadilloP4.msh"] {
        let mut raw = crate::test_support::read_raw(&dir.join(file), None).unwrap();
        let values: Vec<f32> = raw.points.iter().map(|p| f(p.map(f64::from)) as f32).collect();
        raw.fields = vec![Field { values64: None, name: "f".into(), location: FieldLocation::Vertex, values }];
        let m = Arc::new(Mesh::new(raw, file).unwrap());
        let nodes = m.tet_nodes.as_ref().unwrap_or_else(|| panic!("{file}: no higher-order nodes"));
        let def = nodes.cell_type().def();
        let p = f64::from(def.order());
        let lattice = barycentric_lattice(def);
        let x = |i: u32| m.points[i as usize].map(f64::from);
        let max_f = m.field("f").unwrap().values.iter().fold(0f32, |a, &v| a.max(v.abs())) as f64;
        let (mut straight, mut curved) = (Vec::new(), Vec::new());
        for (t, &c) in m.tets.iter().enumerate() {
            let off = lattice
                .iter()
                .zip(nodes.nodes(t, c))
                .map(|(a, id)| {
                    let want: Point =
                        std::array::from_fn(|k| (0..4).map(|j| f64::from(a[j]) * x(c[j])[k]).sum::<f64>() / p);
                    (0..3).map(|k| (x(id)[k] - want[k]).abs()).fold(0.0, f64::max)
                })
                .fold(0.0, f64::max);
            let edge =
                (1..4).map(|j| (0..3).map(|k| (x(c[j])[k] - x(c[0])[k]).abs()).fold(0.0, f64::max)).fold(0.0, f64::max);
            if off <= 1e-6 * edge.max(1e-30) + 1e-6 * x(c[0]).iter().fold(0.0f64, |a, v| a.max(v.abs())) {
                straight.push(t);
            } else {
                curved.push(t);
            }
        }
        // Random points well inside straight tets: exact.
        let sample: Vec<(usize, [f64; 4])> = (0..4000.min(20 * straight.len()))
            .map(|_| {
                let w: [f64; 4] = std::array::from_fn(|_| rng.gen_range(0.05..1.0));
                let s: f64 = w.iter().sum();
                (straight[rng.gen_range(0..straight.len())], w.map(|v| v / s))
            })
            .collect();
        let points: Vec<[f32; 3]> = sample
            .iter()
            .map(|&(t, w)| std::array::from_fn(|k| (0..4).map(|j| w[j] * x(m.tets[t][j])[k]).sum::<f64>() as f32))
            .collect();
        let (mut ids, mut got) = (vec![0; points.len()], vec![0f32; points.len()]);
        CpuLocator::new(m.clone()).locate_and_sample(&points, "f", &mut ids, &mut got).unwrap();
        let (mut worst, mut linear_worst) = (0.0f64, 0.0f64);
        for ((pt, &id), &v) in points.iter().zip(&ids).zip(&got) {
            assert!(id >= 0, "{file}: {pt:?} is inside a tet");
            let want = f(pt.map(f64::from));
            worst = worst.max((f64::from(v) - want).abs() / max_f);
            let b = crate::geom::point_in_tet(m.tets[id as usize], &m.points, *pt).unwrap();
            let lin = crate::geom::interpolate(m.tets[id as usize], b, &m.field("f").unwrap().values);
            linear_worst = linear_worst.max((f64::from(lin) - want).abs() / max_f);
        }
        // Curved tets: corner barycentrics against the isoparametric preimage.
        let (mut diffs, mut outside, mut failed) = (Vec::new(), 0, 0);
        let fv = &m.field("f").unwrap().values;
        for &t in curved.iter().take(2000) {
            let c = m.tets[t];
            let all: Vec<Point> = nodes.nodes(t, c).map(x).collect();
            let pc: PCoords = std::array::from_fn(|_| rng.gen_range(0.0..1.0));
            let s = pc[0] + pc[1] + pc[2];
            let pc = if s > 1.0 { pc.map(|v| v / (s + 0.1)) } else { pc };
            let q = forward(def, &all, pc);
            let Ok(corner_pc) = invert(def.shape().linear, &all[..4], q) else {
                failed += 1; // a degenerate corner tet
                continue;
            };
            let ids: Vec<u32> = nodes.nodes(t, c).collect();
            let value = |pc| interpolate(def, pc, |i| f64::from(fv[ids[i] as usize]));
            // Points of the curved cell outside its corner tet are located in another tet.
            if !def.shape().contains(corner_pc) {
                outside += 1;
                continue;
            }
            match invert(def, &all, q) {
                Ok(iso) => diffs.push((value(corner_pc) - value(iso)).abs() / max_f),
                Err(_) => failed += 1,
            }
        }
        diffs.sort_by(f64::total_cmp);
        let (median, max) = (diffs.get(diffs.len() / 2).copied().unwrap_or(0.0), diffs.last().copied().unwrap_or(0.0));
        eprintln!(
            "{file}: {} {} tets, {} straight, {} curved; straight: error {worst:.1e} of max|f| \
             (corners only {linear_worst:.1e}); curved, corner vs isoparametric coordinates over {} points: \
             median {median:.1e}, max {max:.1e} of max|f| ({outside} points of the curved cells outside \
             their corner tets skipped, {failed} Newton failures)",
            m.n_tets(),
            def.name(),
            straight.len(),
            curved.len(),
            diffs.len()
        );
        // Gmsh's P3 and P4 meshes are curved throughout (every node off its lattice point).
        if file.ends_with(".vtu") {
            assert!(!straight.is_empty(), "{file}: no straight-sided tets to check");
        }
        assert!(worst < 4e-7, "{file}: quadratic missed by {worst} of max|f|");
        assert!(straight.is_empty() || linear_worst > 1e-4, "{file}: the corners alone should miss it");
    }
}
