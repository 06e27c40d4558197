//! A particle's hint: the tet its last lookup found, with that tet's barycentric map
//! ([`TetMap`]). Between two lookups a particle usually stays in its tet (a tracer's step is a
//! fraction of an edge, and each step asks for four to seven points). A lookup in the same
//! tet then costs the map's product (nine multiply-adds in f64) and a comparison with the
//! map's static error bound: no exact test and no walk. Where the map cannot decide (the
//! point is outside the tet's box, or within the bound of a face, or the tet is too flat for
//! a map) the locator walks from the tet as before ([`super::CpuLocator::locate_from`]).
//!
//! **The same answers.** A point that the map puts strictly inside the hint's tet is strictly
//! inside it for the exact test too (the bound covers the exact test's own f32 path), so the
//! walk, whose first test is in that tet, answers that tet. The weights are the map's,
//! rounded to f32: the exact test's to a few f32 ulps (`tet_map`'s tests: 1e-6).
//!
//! **Memory and when it pays.** One map a particle, not one a tet of the mesh: 15 f64 for the
//! map and 6 for the box, about 170 bytes, built when the particle enters a tet (three cross
//! products and a division, about the cost of one exact test). It pays from the second
//! lookup in a tet; an RK4 tracer at a tenth of an edge a step makes about forty.

use super::tet_map::{bounds_of, Side, TetMap};
use crate::geom::{Bary, Vec3};
use crate::mesh::Mesh;
use crate::prefetch::line_of;

/// The tet of a particle's last lookup, and what the next lookup needs to stay in it
/// cheaply. `Hint::default()` knows no tet: the first lookup searches.
#[derive(Clone, Debug, Default)]
pub struct Hint {
    /// Where the walk starts when the map cannot decide.
    pub(super) tet: Option<u32>,
    held: Option<Held>,
}

/// A tet's box (file coordinates) and map.
#[derive(Clone, Debug)]
struct Held {
    tet: u32,
    lo: [f64; 3],
    hi: [f64; 3],
    map: Option<TetMap>,
    /// Whether the neighbours' rows were asked for ([`Hint::look_around`]).
    looked_around: bool,
}

impl Hint {
    /// The tet of the last lookup that found one.
    pub fn tet(&self) -> Option<u32> {
        self.tet
    }

    /// The weights of `p` in the held tet when its map puts `p` strictly inside; `None`
    /// when the map cannot decide (or there is no held tet).
    #[inline]
    pub(super) fn inside(&self, p: Vec3) -> Option<(u32, Bary)> {
        let h = self.held.as_ref()?;
        let p = p.map(f64::from);
        // The bound holds within the box (the map's reach); outside it the point is not in the tet.
        if (0..3).any(|k| !(p[k] >= h.lo[k] && p[k] <= h.hi[k])) {
            return None;
        }
        match h.map.as_ref()?.at(p) {
            Side::Inside(w) => Some((h.tet, w.map(|x| x as f32))),
            Side::Outside | Side::Near => None,
        }
    }

    /// Asks the caches, once a held tet, for what the walk out of it reads: the rows of its
    /// face neighbours in the tets and in the neighbour table. A particle leaves its tet
    /// after a few lookups, and the walk's first step was two misses in each table (fusion
    /// 1.4M: 45 MB of them), most of the tracer's time; by then these lines have arrived.
    /// Called after a lookup the map answered, when the tet's own neighbour row (asked for
    /// on entering it, [`Self::found`]) is likely in cache.
    #[inline]
    pub(super) fn look_around(&mut self, mesh: &Mesh) {
        let Some(h) = self.held.as_mut().filter(|h| !h.looked_around) else { return };
        h.looked_around = true;
        let neighbors = mesh.neighbors();
        for n in neighbors[h.tet as usize] {
            if n >= 0 {
                line_of(&mesh.tets[n as usize]);
                line_of(&neighbors[n as usize]);
            }
        }
    }

    /// Remembers `tet` (found by a search), building its map if it is not the held one.
    pub(super) fn found(&mut self, mesh: &Mesh, tet: u32, bound_scale: f64) {
        self.tet = Some(tet);
        if self.held.as_ref().is_some_and(|h| h.tet == tet) {
            return;
        }
        line_of(&mesh.neighbors()[tet as usize]);
        let v = mesh.tets[tet as usize].map(|i| mesh.vertex64(i));
        let (lo, hi) = bounds_of(&v);
        let map = TetMap::over_box(v, (lo, hi), bound_scale);
        self.held = Some(Held { tet, lo, hi, map, looked_around: false });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::locate::grid_raster::tests::{kuhn_on_faces, ON_FACES};
    use crate::locate::CpuLocator;
    use rand::{Rng, SeedableRng};

    /// A particle's lookups at `points` in order through [`CpuLocator::locate_near_with`],
    /// each against the walk from the same start ([`CpuLocator::locate_from`]): the same
    /// tet, weights within 1e-6, and none answered by the map where the exact test finds a
    /// weight of zero (a point on a face, whose tet the tie rule picks). The number answered
    /// by the map, or the first disagreement.
    /// Every lookup starts from `from` when given (else from the one before).
    fn follow(loc: &CpuLocator, points: &[Vec3], from: Option<&Hint>, bound_scale: f64) -> Result<usize, String> {
        let (mut hint, mut by_map) = (from.cloned().unwrap_or_default(), 0);
        for (i, &p) in points.iter().enumerate() {
            if let Some(h) = from {
                hint = h.clone();
            }
            let mut start = hint.tet();
            let want = loc.locate_from(p, &mut start);
            let mapped = hint.inside(p).is_some();
            by_map += usize::from(mapped);
            let got = loc.locate_near_with(p, &mut hint, bound_scale);
            match (got, want) {
                (None, None) => {}
                (Some((a, wa)), Some((b, wb))) if a == b => {
                    if wa.iter().zip(wb).any(|(x, y)| (x - y).abs() > 1e-6) {
                        return Err(format!("point {i} {p:?} in tet {a}: weights {wa:?}, not {wb:?}"));
                    }
                    if mapped && wb.contains(&0.0) {
                        return Err(format!("point {i} {p:?}: on a face of tet {a} ({wb:?}), claimed by its map"));
                    }
                }
                _ => return Err(format!("point {i} {p:?}: {got:?}, not {want:?}")),
            }
        }
        Ok(by_map)
    }

    /// Points exactly on faces, edges and vertices (the grids of sheared Kuhn meshes, from
    /// ~1e-6 to ~1e6 and 1e7 from the origin), each looked up from every tet whose box holds
    /// it: the held tet's map answers as the walk from that tet does. With the bound taken
    /// away (a zero factor) some point on a face is claimed by the map of a tet it only
    /// touches, where the walk leaves the tie to the search.
    #[test]
    fn a_held_tet_answers_as_the_walk_and_a_tighter_bound_fails() {
        let check = |loc: &CpuLocator, points: &[Vec3], bound_scale: f64| -> Result<usize, String> {
            let mesh = loc.mesh();
            let mut by_map = 0;
            for t in 0..mesh.tets.len() as u32 {
                let mut held = Hint::default();
                held.found(mesh, t, bound_scale);
                let Held { lo, hi, .. } = held.held.clone().unwrap();
                let inside_box = |p: &&Vec3| (0..3).all(|k| (lo[k]..=hi[k]).contains(&f64::from(p[k])));
                let near: Vec<Vec3> = points.iter().filter(inside_box).copied().collect();
                // From the held tet: the map, or the walk where it cannot decide.
                by_map += follow(loc, &near, Some(&held), bound_scale)?;
            }
            Ok(by_map)
        };
        let mut failures = Vec::new();
        for (unit, corner) in ON_FACES {
            let (mesh, grid) = kuhn_on_faces(unit, corner);
            let loc = CpuLocator::new(mesh);
            let points: Vec<Vec3> = (0..grid.n_points()).map(|i| grid.point(i)).collect();
            let by_map = check(&loc, &points, 1.0).unwrap_or_else(|e| panic!("unit {unit}: {e}"));
            assert!(by_map > points.len() / 4, "unit {unit}: the map answered {by_map}");
            if let Err(e) = check(&loc, &points, 0.0) {
                failures.push(e);
            }
        }
        assert_eq!(failures.len(), ON_FACES.len(), "a zero bound failed only {failures:#?}");
    }

    /// Particles taking small random steps through a jittered mesh (some tets folded over
    /// their neighbours) and the same mesh far from the origin: the map answers most lookups,
    /// every one as the walk would.
    #[test]
    fn wandering_particles_get_the_walks_answers() {
        let raws = [
            crate::test_support::jittered_grid(6, 0.3, 5),
            crate::test_support::mixed::moved(
                crate::test_support::jittered_grid(6, 0.3, 6),
                [5000.0, -3000.0, 10000.0],
            ),
        ];
        for raw in raws {
            let mesh = std::sync::Arc::new(Mesh::new(raw, "jittered").unwrap());
            let (lo, hi) = mesh.file_bounds();
            let loc = CpuLocator::new(mesh.clone());
            let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
            let (mut by_map, mut total) = (0, 0);
            for _ in 0..50 {
                let mut x: [f64; 3] = std::array::from_fn(|k| rng.gen_range(lo[k]..hi[k]));
                let step = 0.02 * (hi[0] - lo[0]) / 6.0;
                let points: Vec<Vec3> = (0..400)
                    .map(|_| {
                        x = x.map(|c| c + rng.gen_range(-step..step));
                        x.map(|c| c as f32)
                    })
                    .collect();
                by_map += follow(&loc, &points, None, 1.0).unwrap();
                total += points.len();
            }
            assert!(by_map * 2 > total, "{by_map} of {total} by the map");
        }
    }
}
