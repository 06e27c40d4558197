//! The arrays vtkStreamTracer adds with `ComputeVorticity` (ParaView's Stream Tracer has it on):
//! at each line point, `Vorticity` (the curl of the traced vector in the cell that holds the
//! point), `AngularVelocity` (the vorticity along the unit velocity: `ω·v/|v|`), `Rotation`
//! (the angular velocity integrated along the line by the trapezoid rule in
//! `IntegrationTime`), and `Normals` (vtkPolyLine's sliding normals, turned about the line by
//! the rotation), which ribbon and tube filters orient themselves by.
//!
//! The derivatives are those of the cell's own interpolation at the point
//! ([`crate::ops::gradients`]: constant in a linear tet), in f64 on the file's data, as
//! VTK's `vtkCell::Derivatives`. A vector stored per cell has no derivatives: its vorticity
//! is zero, as VTK's. One difference: VTK divides by the speed at every point after the seed,
//! so a point where the flow stops gets a NaN angular velocity (and rotation); here it gets 0,
//! as VTK's seed point does.

use super::LineArrays;
use crate::error::Result;
use crate::mesh::{FieldLocation, Mesh};
use crate::ops::gradients::PointWeights;
use crate::ops::FieldGroup;
use rayon::prelude::*;

/// See the module's documentation: one entry a line point, in the lines' order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VorticityArrays {
    pub vorticity: Vec<[f64; 3]>,
    pub rotation: Vec<f64>,
    pub angular_velocity: Vec<f64>,
    /// Streamlines only: vtkParticlePathFilter writes no normals.
    pub normals: Option<Vec<[f64; 3]>>,
}

/// The vorticity arrays of `lines` traced through `vector` (a 3-component field of `mesh`).
/// Each point's cell is the one its line fields were sampled in (`lines.fields.ids`).
pub fn vorticity(mesh: &Mesh, vector: &FieldGroup, lines: &LineArrays) -> Result<VorticityArrays> {
    let xyz: Vec<&crate::Field> = vector.component_refs().iter().map(|c| mesh.field(c)).collect::<Result<_>>()?;
    let field = Vector { mesh, xyz: [xyz[0], xyz[1], xyz[2]] };
    let starts: Vec<usize> = std::iter::once(0).chain(lines.ends.iter().copied()).collect();
    let n = lines.points.len();
    let mut out = VorticityArrays {
        vorticity: vec![[0.0; 3]; n],
        rotation: vec![0.0; n],
        angular_velocity: vec![0.0; n],
        normals: Some(vec![[0.0; 3]; n]),
    };
    let normals = out.normals.as_mut().expect("just made");
    let line = |l: usize| LinePoints {
        points: lines.points[starts[l]..starts[l + 1]].iter().map(|p| p.map(f64::from)).collect(),
        ids: &lines.fields.ids[starts[l]..starts[l + 1]],
        time: &lines.time[starts[l]..starts[l + 1]],
    };
    // One task a line, each writing its slices; a line whose points all coincide has no
    // segment to slide a normal along: VTK's one pass over the lines gives it the last normal
    // of the line before ((0, 0, 1) before the first), so those few are done again after.
    let slices = split_by(flat(&mut out.vorticity), &starts, 3)
        .into_iter()
        .zip(split_by(flat(normals), &starts, 3))
        .zip(split_by(&mut out.rotation, &starts, 1).into_iter().zip(split_by(&mut out.angular_velocity, &starts, 1)))
        .map(|((vorticity, normals), (rotation, omega))| Slices { vorticity, normals, rotation, omega });
    let lasts: Vec<Option<[f64; 3]>> = slices
        .enumerate()
        .collect::<Vec<_>>()
        .into_par_iter()
        .map_init(|| PointWeights::new(mesh), |weights, (l, mut at)| field.line(weights, &line(l), &mut at, None))
        .collect();
    let mut carried = [0.0, 0.0, 1.0];
    let mut weights = PointWeights::new(mesh);
    for (l, last) in lasts.into_iter().enumerate() {
        carried = match last {
            Some(n) => n,
            None => {
                let r = starts[l]..starts[l + 1];
                let mut at = Slices {
                    vorticity: &mut flat(&mut out.vorticity)[3 * r.start..3 * r.end],
                    normals: &mut flat(normals)[3 * r.start..3 * r.end],
                    rotation: &mut out.rotation[r.clone()],
                    omega: &mut out.angular_velocity[r],
                };
                field.line(&mut weights, &line(l), &mut at, Some(carried)).unwrap_or(carried)
            }
        };
    }
    Ok(out)
}

/// Vectors as 3 values each.
fn flat(a: &mut [[f64; 3]]) -> &mut [f64] {
    bytemuck::cast_slice_mut(a)
}

/// One line's points (f64), the cells that hold them and their integration times.
struct LinePoints<'a> {
    points: Vec<[f64; 3]>,
    ids: &'a [i32],
    time: &'a [f64],
}

/// One line's slices of the output arrays (vectors as 3 values a point).
struct Slices<'a> {
    vorticity: &'a mut [f64],
    normals: &'a mut [f64],
    rotation: &'a mut [f64],
    omega: &'a mut [f64],
}

/// `all` cut at `starts` (a line's first point; the last entry the end), `k` values a point.
fn split_by<'a>(mut all: &'a mut [f64], starts: &[usize], k: usize) -> Vec<&'a mut [f64]> {
    starts
        .windows(2)
        .map(|w| {
            let (line, rest) = std::mem::take(&mut all).split_at_mut((w[1] - w[0]) * k);
            all = rest;
            line
        })
        .collect()
}

/// The traced vector's components.
struct Vector<'a> {
    mesh: &'a Mesh,
    xyz: [&'a crate::Field; 3],
}

impl Vector<'_> {
    /// One line's arrays into `at`. Returns its last sliding normal; `None` when it has no
    /// segment and no `carried` normal was given (its normals are then left unwritten).
    fn line(
        &self,
        weights: &mut PointWeights,
        line: &LinePoints<'_>,
        at: &mut Slices<'_>,
        carried: Option<[f64; 3]>,
    ) -> Option<[f64; 3]> {
        let mut velocity = vec![[0.0; 3]; line.points.len()];
        // In a linear tet the gradients are constant: a run of a line's points in one tet
        // takes the curl of its first (the same numbers) and interpolates the velocity alone.
        let linear_tets = self.mesh.cells.is_none() && self.mesh.tet_nodes.is_none();
        let mut held: Option<(i32, [f64; 3])> = None;
        for (i, (&p, &id)) in line.points.iter().zip(line.ids).enumerate() {
            let (v, w) = match held {
                Some((tet, curl)) if linear_tets && tet == id => (self.velocity_in_tet(id, p), curl),
                _ => self.velocity_and_curl(weights, id, p),
            };
            held = Some((id, w));
            velocity[i] = v;
            at.vorticity[3 * i..3 * i + 3].copy_from_slice(&w);
            at.omega[i] = angular_velocity(w, v);
        }
        at.rotation[0] = 0.0;
        for i in 1..line.points.len() {
            let step = (at.omega[i - 1] + at.omega[i]) / 2.0 * (line.time[i] - line.time[i - 1]);
            at.rotation[i] = at.rotation[i - 1] + step;
        }
        let last = match (sliding_normals(&line.points, at.normals), carried) {
            (Some(last), _) => last,
            (None, Some(n)) => {
                at.normals.chunks_exact_mut(3).for_each(|o| o.copy_from_slice(&n));
                n
            }
            (None, None) => return None,
        };
        turn_normals(at.normals, &velocity, at.rotation);
        Some(last)
    }

    /// [`Self::velocity_and_curl`]'s velocity at point `p` of tet `id` of a mesh of linear
    /// tets, with the same arithmetic (the tet's shape functions at the point's barycentrics).
    fn velocity_in_tet(&self, id: i32, p: [f64; 3]) -> [f64; 3] {
        if id < 0 || id as usize >= self.mesh.n_tets() {
            return [f64::NAN; 3];
        }
        if self.xyz.iter().any(|f| f.location != FieldLocation::Vertex) {
            return self.xyz.map(|f| f.value64(id as usize));
        }
        let Some(b) = self.mesh.bary64(id as usize, p) else { return [f64::NAN; 3] };
        let mut w = [0.0; 4];
        crate::cell::CellType::tet().def().shape_functions([b[1], b[2], b[3]], &mut w);
        let mut v = [0.0; 3];
        for (&node, w) in self.mesh.tets[id as usize].iter().zip(w) {
            for (c, f) in self.xyz.iter().enumerate() {
                v[c] += w * f.value64(node as usize);
            }
        }
        v
    }

    /// The velocity at point `p` of cell (or tet) `id`, and its curl there: a vector stored
    /// per vertex interpolated, with its derivatives; one stored per cell, the cell's value
    /// and no curl (see the module). NaN and no curl where the point has no cell (`id`: a
    /// cell of a mixed mesh, else a tet, as the locators answer).
    fn velocity_and_curl(&self, weights: &mut PointWeights, id: i32, p: [f64; 3]) -> ([f64; 3], [f64; 3]) {
        let cells = self.mesh.cells.as_ref().map_or(self.mesh.n_tets(), |c| c.len());
        if id < 0 || id as usize >= cells {
            return ([f64::NAN; 3], [0.0; 3]);
        }
        if self.xyz.iter().any(|f| f.location != FieldLocation::Vertex) {
            return (self.xyz.map(|f| f.value64(id as usize)), [0.0; 3]);
        }
        let Some((nodes, w, g)) = weights.at(self.mesh, id as usize, p) else { return ([f64::NAN; 3], [0.0; 3]) };
        let mut v = [0.0; 3];
        for (&node, &w) in nodes.iter().zip(w) {
            for (c, f) in self.xyz.iter().enumerate() {
                v[c] += w * f.value64(node as usize);
            }
        }
        (v, curl_of(self.xyz, nodes, g))
    }
}

/// The curl of the vector whose components are `xyz` at a point with these `nodes` and
/// shape-function gradients `g` (as [`PointWeights::at`] gives them).
fn curl_of(xyz: [&crate::Field; 3], nodes: &[u32], g: &[[f64; 3]]) -> [f64; 3] {
    // d[c][k] = ∂v_c/∂x_k
    let mut d = [[0.0f64; 3]; 3];
    for (&node, g) in nodes.iter().zip(g) {
        for (c, f) in xyz.iter().enumerate() {
            let value = f.value64(node as usize);
            for k in 0..3 {
                d[c][k] += g[k] * value;
            }
        }
    }
    [d[2][1] - d[1][2], d[0][2] - d[2][0], d[1][0] - d[0][1]]
}

/// The curls at point `p` of cell (or tet) `id`, as the locators answer (a cell of a mixed
/// mesh), of two steps' vectors (`steps`, each its components: fields of `mesh`), by the
/// cell's own derivatives as [`vorticity`] takes them, its weights made once for both;
/// `None` (no curl) for a vector stored per cell or a point without weights. Pathlines'.
pub(super) fn curls_at(
    mesh: &Mesh,
    steps: [[&crate::Field; 3]; 2],
    weights: &mut PointWeights,
    id: usize,
    p: [f64; 3],
) -> Option<[[f64; 3]; 2]> {
    let cells = mesh.cells.as_ref().map_or(mesh.n_tets(), |c| c.len());
    if id >= cells || steps.iter().flatten().any(|f| f.location != FieldLocation::Vertex) {
        return None;
    }
    let (nodes, _, g) = weights.at(mesh, id, p)?;
    Some(steps.map(|xyz| curl_of(xyz, nodes, g)))
}

/// The angular velocity for vorticity `w` at velocity `v`: `w` along the unit velocity, 0
/// where the flow stops (see the module).
pub(super) fn angular_velocity(w: [f64; 3], v: [f64; 3]) -> f64 {
    let speed = norm(v);
    if speed != 0.0 && speed.is_finite() {
        dot(w, v) / speed
    } else {
        0.0
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// `a` over its length (zero stays zero), and the length.
fn unit(a: [f64; 3]) -> ([f64; 3], f64) {
    let n = norm(a);
    (if n == 0.0 { a } else { a.map(|x| x / n) }, n)
}

/// vtkPolyLine's sliding normals along one line: the first normal across its first two
/// segments that are not parallel (one perpendicular to the first segment when all are), each
/// next one turned with the line by as little as it can, segments between coincident points
/// skipped. Written to `normals` (3 values a point); returns the last normal, or `None` when
/// the line has no segment (its normals are left for the caller).
fn sliding_normals(points: &[[f64; 3]], normals: &mut [f64]) -> Option<[f64; 3]> {
    let m = points.len();
    let sub = |a: [f64; 3], b: [f64; 3]| [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    // The first segment from point `s` on that joins two distinct points: its first point.
    let next_valid = |s: usize| (s + 1..m).find(|&e| points[e] != points[s]).map(|e| e - 1);
    let direction = |s: usize| unit(sub(points[s], points[s + 1])).0;
    let mut s = next_valid(0)?;
    let mut previous = direction(s);
    let mut normal = None;
    let mut s_next = s;
    while s_next + 1 < m {
        let Some(v) = next_valid(s_next + 1) else {
            s_next = m;
            break;
        };
        s_next = v;
        let next = direction(v);
        let n = cross(previous, next);
        if norm(n) > 1e-3 {
            normal = Some(n);
            previous = next;
            break;
        }
    }
    s = s_next;
    let mut normal = unit(normal.unwrap_or_else(|| perpendicular(previous))).0;
    let mut written = 0;
    let put = |from: usize, to: usize, n: [f64; 3], normals: &mut [f64]| {
        for i in from..to {
            normals[3 * i..3 * i + 3].copy_from_slice(&n);
        }
    };
    while s + 1 < m {
        let Some(v) = next_valid(s + 1) else { break };
        s = v;
        let next = direction(s);
        // VTK's turn needs both: the plane of the line and its normal, and the segments'.
        let w_len = norm(cross(previous, normal));
        let (q, q_len) = unit(cross(next, previous));
        if w_len == 0.0 || q_len == 0.0 {
            continue;
        }
        let f1 = dot(q, normal);
        let mut f2 = if 1.0 - f1 * f1 > 0.0 { (1.0 - f1 * f1).sqrt() } else { 0.0 };
        let c = unit([next[0] + previous[0], next[1] + previous[1], next[2] + previous[2]]).0;
        let w = cross(c, q);
        let c = cross(previous, q);
        if dot(normal, c) * dot(w, c) < 0.0 {
            f2 = -f2;
        }
        put(written, s, normal, normals);
        written = s;
        previous = next;
        normal = std::array::from_fn(|k| f1 * q[k] + f2 * w[k]);
    }
    put(written, m, normal, normals);
    Some(normal)
}

/// A vector perpendicular to `d` (not zero), as vtkPolyLine picks it for a straight line.
fn perpendicular(d: [f64; 3]) -> [f64; 3] {
    let mut n = [0.0; 3];
    if let Some(i) = (0..3).find(|&i| d[i] != 0.0) {
        n[(i + 2) % 3] = 0.0;
        n[(i + 1) % 3] = 1.0;
        n[i] = -d[(i + 1) % 3] / d[i];
    }
    n
}

/// vtkStreamTracer's normals: each sliding normal turned about the line by the point's
/// rotation, in the plane of the normal and normal × velocity, its length kept.
fn turn_normals(normals: &mut [f64], velocity: &[[f64; 3]], rotation: &[f64]) {
    for ((n, &v), &theta) in normals.chunks_exact_mut(3).zip(velocity).zip(rotation) {
        let (local1, length) = unit([n[0], n[1], n[2]]);
        let (local2, _) = unit(cross(local1, v));
        let (sin, cos) = theta.sin_cos();
        for k in 0..3 {
            n[k] = length * (cos * local1[k] + sin * local2[k]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::swirl_cube;
    use super::super::{line_fields, seeds_from_spec, trace_sampled, vector_field, Direction, TraceOptions};
    use super::*;

    /// Lines both ways through the swirl of a 4³ cube, with their vorticity arrays.
    fn swirl_lines() -> (std::sync::Arc<Mesh>, FieldGroup, LineArrays) {
        let m = swirl_cube(4);
        let vector = vector_field(&m, "v").unwrap();
        let cpu = crate::CpuLocator::new(m.clone());
        let seeds = seeds_from_spec("grid:0.1,0.9,0.1,0.9,0.1,0.9,4,4,4").unwrap().unwrap();
        let o = TraceOptions { step: 0.02, max_steps: 300, direction: Direction::Both, ..Default::default() };
        let lines = trace_sampled(&seeds, &o, &cpu, ["v[0]", "v[1]", "v[2]"], &line_fields(&m, &vector), &|_| Ok(()))
            .unwrap()
            .with_vorticity(Some((&m, &vector)))
            .unwrap();
        (m, vector, lines)
    }

    /// The swirl is affine, so its vorticity is one vector everywhere, the curl of its matrix:
    /// (-0.05, 0.1, 2) (within the f32 rounding of its vertex values); the angular velocity is
    /// that along the unit velocity; the rotation its trapezoid integral in time; the normals
    /// unit vectors across the line.
    #[test]
    fn an_affine_fields_vorticity_is_its_curl() {
        let (_, _, lines) = swirl_lines();
        let v = lines.vorticity.as_ref().unwrap();
        assert!(lines.points.len() > 1000 && v.vorticity.len() == lines.points.len());
        let curl = [-0.05, 0.1, 2.0];
        let swirl = |p: [f64; 3]| [-(p[1] - 0.5) + 0.1, (p[0] - 0.5) + 0.05 * p[2], 0.2 - 0.1 * p[0]];
        let mut start = 0;
        for &end in &lines.ends {
            for i in start..end {
                let w = v.vorticity[i];
                assert!((0..3).all(|k| (w[k] - curl[k]).abs() < 1e-5), "point {i}: {w:?}");
                let u = swirl(lines.points[i].map(f64::from));
                assert!((v.angular_velocity[i] - dot(w, u) / norm(u)).abs() < 1e-5, "point {i}");
                let n = v.normals.as_ref().unwrap()[i];
                assert!((norm(n) - 1.0).abs() < 1e-9, "point {i}: |n| = {}", norm(n));
                // Across the segments, which turn from the velocity by half a step's angle.
                let across = dot(n, u).abs() / norm(u);
                assert!(across < 0.1, "point {i}: the normal is not across the line ({across})");
                if i > start {
                    let dt = lines.time[i] - lines.time[i - 1];
                    let step = (v.angular_velocity[i - 1] + v.angular_velocity[i]) / 2.0 * dt;
                    assert!((v.rotation[i] - v.rotation[i - 1] - step).abs() < 1e-12, "point {i}");
                }
            }
            assert_eq!(v.rotation[start], 0.0);
            start = end;
        }
        // Backward lines turn the other way in time.
        assert!(v.rotation.iter().any(|&r| r > 0.1) && v.rotation.iter().any(|&r| r < -0.1));
    }

    /// The curl held through a run of points in one tet and the velocity interpolated alone
    /// there are what the full computation gives at every point, bit for bit.
    #[test]
    fn a_tets_held_curl_is_every_points_curl() {
        let (m, vector, lines) = swirl_lines();
        let v = lines.vorticity.as_ref().unwrap();
        let xyz: Vec<&crate::Field> = vector.component_refs().iter().map(|c| m.field(c).unwrap()).collect();
        let field = Vector { mesh: &m, xyz: [xyz[0], xyz[1], xyz[2]] };
        let mut weights = PointWeights::new(&m);
        let ids = &lines.fields.ids;
        let repeats = ids.windows(2).filter(|w| w[0] == w[1]).count();
        assert!(repeats > ids.len() / 2, "{repeats} of {} points share their tet with the one before", ids.len());
        for (i, (p, &id)) in lines.points.iter().zip(ids).enumerate() {
            let p = p.map(f64::from);
            let (velocity, curl) = field.velocity_and_curl(&mut weights, id, p);
            assert_eq!(v.vorticity[i].map(f64::to_bits), curl.map(f64::to_bits), "point {i}");
            assert_eq!(field.velocity_in_tet(id, p).map(f64::to_bits), velocity.map(f64::to_bits), "point {i}");
            assert_eq!(v.angular_velocity[i].to_bits(), angular_velocity(curl, velocity).to_bits(), "point {i}");
        }
    }

    /// vtkPolyLine's sliding normals: along a planar curve the plane's normal; along a straight
    /// line one perpendicular to it; coincident points skipped; no segment, no normal.
    #[test]
    fn sliding_normals_follow_vtk_polyline() {
        let normals_of = |points: &[[f64; 3]]| {
            let mut out = vec![0.0; 3 * points.len()];
            let last = sliding_normals(points, &mut out);
            (last, out.chunks(3).map(|c| [c[0], c[1], c[2]]).collect::<Vec<_>>())
        };
        let circle: Vec<[f64; 3]> = (0..20).map(|i| f64::from(i) * 0.2).map(|a| [a.cos(), a.sin(), 0.5]).collect();
        let (last, n) = normals_of(&circle);
        assert!(n.iter().all(|n| (n[2].abs() - 1.0).abs() < 1e-12 && n[0].abs() < 1e-12 && n[1].abs() < 1e-12));
        assert_eq!(last, Some(n[19]));
        let mut doubled = circle.clone();
        doubled.insert(7, circle[7]);
        let (_, m) = normals_of(&doubled);
        assert!(m.iter().all(|m| (m[2] - n[0][2]).abs() < 1e-12), "{m:?}");
        let straight: Vec<[f64; 3]> = (0..5).map(|i| [f64::from(i), 2.0 * f64::from(i), 0.0]).collect();
        let (_, s) = normals_of(&straight);
        assert!(s
            .iter()
            .all(|n| (norm(*n) - 1.0).abs() < 1e-12 && dot(*n, [1.0, 2.0, 0.0]).abs() < 1e-12 && *n == s[0]));
        assert_eq!(normals_of(&[[1.0, 2.0, 3.0]; 3]).0, None);
        assert_eq!(normals_of(&[[1.0, 2.0, 3.0]]).0, None);
    }
}
