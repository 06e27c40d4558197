//! Stream tracing (vtkStreamTracer): lines through a vector field from seed points, by
//! Runge–Kutta steps of a fixed arc length (RK4) in the normalized field, as VTK integrates
//! them with `IntegrationStepUnit` = length. Each particle keeps the tet of its last lookup
//! as the start of the next one (a walk through face neighbours; the BVH when the walk
//! fails), so a step costs a few point-in-tet tests instead of a traversal.
//!
//! VTK's loop, reproduced step for step: a seed outside the mesh, or whose first step
//! already leaves it, gives no line; a line stops when a step (any RK stage) or its end
//! point leaves the mesh (OUT_OF_DOMAIN), when the speed drops to the terminal speed
//! (STAGNATION), after `max_steps` + 1 steps (OUT_OF_STEPS), or when its length reaches
//! `max_length` (OUT_OF_LENGTH; the last step is shortened to land on it). The integration
//! time advances by each step's length over the speed at its start; backward lines count
//! it negative.

use crate::error::{Error, Result};
use crate::geom::Vec3;
use crate::ops::ImageGrid;
use rayon::prelude::*;

/// Why a line ended: VTK's `ReasonForTermination` codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(i32)]
pub enum Reason {
    OutOfDomain = 1,
    NotInitialized = 2,
    UnexpectedValue = 3,
    OutOfLength = 4,
    OutOfSteps = 5,
    Stagnation = 6,
}

/// Which way lines go from their seeds. `Both` gives two lines per seed: all the forward
/// lines, then all the backward ones (VTK's order).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    Forward,
    Backward,
    Both,
}

impl std::str::FromStr for Direction {
    type Err = Error;
    fn from_str(s: &str) -> Result<Direction> {
        match s {
            "forward" => Ok(Direction::Forward),
            "backward" => Ok(Direction::Backward),
            "both" => Ok(Direction::Both),
            _ => Err(Error::Invalid(format!("direction '{s}': forward, backward or both"))),
        }
    }
}

#[derive(Clone, Debug)]
pub struct TraceOptions {
    /// Arc length of one step (mesh units), > 0.
    pub step: f64,
    /// Steps per line (VTK takes one more before it stops with OUT_OF_STEPS).
    pub max_steps: usize,
    /// Longest line (VTK's MaximumPropagation).
    pub max_length: f64,
    /// Speeds at or below this stop a line (STAGNATION).
    pub terminal_speed: f64,
    pub direction: Direction,
}

impl Default for TraceOptions {
    fn default() -> Self {
        TraceOptions {
            step: 0.01,
            max_steps: 2000,
            max_length: f64::INFINITY,
            terminal_speed: 1e-12,
            direction: Direction::Forward,
        }
    }
}

impl TraceOptions {
    pub fn check(&self) -> Result<()> {
        if !(self.step.is_finite() && self.step > 0.0) {
            return Err(Error::Invalid(format!("the step must be a positive length, got {}", self.step)));
        }
        if self.max_length.is_nan() || self.max_length <= 0.0 {
            return Err(Error::Invalid(format!("the maximum length must be positive, got {}", self.max_length)));
        }
        Ok(())
    }
}

/// One streamline.
#[derive(Clone, Debug, PartialEq)]
pub struct Line {
    /// Index of its seed.
    pub seed: u32,
    pub backward: bool,
    pub points: Vec<[f64; 3]>,
    /// Integration time at each point (0 at the seed).
    pub time: Vec<f64>,
    pub reason: Reason,
}

/// The field being traced: the vector at a point, the search starting from `hint` (the tet
/// of the previous lookup, updated to this one's); `None` outside the mesh.
pub trait VectorField: Sync {
    fn at(&self, p: Vec3, hint: &mut Option<u32>) -> Option<[f32; 3]>;
}

impl<F: Fn(Vec3, &mut Option<u32>) -> Option<[f32; 3]> + Sync> VectorField for F {
    fn at(&self, p: Vec3, hint: &mut Option<u32>) -> Option<[f32; 3]> {
        self(p, hint)
    }
}

fn to_f32(p: [f64; 3]) -> Vec3 {
    p.map(|x| x as f32)
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// The unit vector (zero stays zero, as vtkMath::Normalize leaves it).
fn normalized(v: [f64; 3]) -> [f64; 3] {
    let n = norm(v);
    if n == 0.0 {
        v
    } else {
        v.map(|x| x / n)
    }
}

/// One classical Runge–Kutta step of signed length `h` from `x` through the unit field
/// `f`; `None` when a stage point is outside the mesh. vtkRungeKutta4's stages and weights.
pub fn rk4_step(x: [f64; 3], h: f64, f: &mut impl FnMut([f64; 3]) -> Option<[f64; 3]>) -> Option<[f64; 3]> {
    let at = |k: [f64; 3], s: f64| std::array::from_fn(|i| x[i] + s * k[i]);
    let k1 = f(x)?;
    let k2 = f(at(k1, h / 2.0))?;
    let k3 = f(at(k2, h / 2.0))?;
    let k4 = f(at(k3, h))?;
    Some(std::array::from_fn(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])))
}

/// The line from `seed` in direction `sign` (±1), or `None` when VTK makes none (the seed is
/// outside, or no step stays inside).
pub fn integrate(
    seed: Vec3,
    sign: f64,
    o: &TraceOptions,
    field: &impl VectorField,
) -> Option<(Vec<[f64; 3]>, Vec<f64>, Reason)> {
    let mut hint = None;
    let velocity = |p: [f64; 3], hint: &mut Option<u32>| field.at(to_f32(p), hint).map(|v| v.map(f64::from));
    let mut x = seed.map(f64::from);
    let v0 = velocity(x, &mut hint)?;
    let (mut points, mut time) = (vec![x], vec![0.0]);
    let (mut speed, mut t, mut length, mut steps) = (norm(v0), 0.0, 0.0, 0usize);
    let mut reason = Reason::OutOfLength;
    while length < o.max_length {
        if steps > o.max_steps {
            reason = Reason::OutOfSteps;
            break;
        }
        steps += 1;
        if speed == 0.0 || speed <= o.terminal_speed {
            reason = Reason::Stagnation;
            break;
        }
        let h = sign * o.step.min(o.max_length - length);
        let Some(next) = rk4_step(x, h, &mut |p| velocity(p, &mut hint).map(normalized)) else {
            reason = Reason::OutOfDomain;
            break;
        };
        let moved = norm(std::array::from_fn(|i| next[i] - x[i]));
        if h == 0.0 || moved / h.abs() <= o.terminal_speed {
            reason = Reason::Stagnation;
            break;
        }
        t += h / speed;
        length += h.abs();
        x = next;
        let Some(v) = velocity(x, &mut hint) else {
            reason = Reason::OutOfDomain;
            break;
        };
        points.push(x);
        time.push(t);
        speed = norm(v);
        if speed == 0.0 || speed <= o.terminal_speed {
            reason = Reason::Stagnation;
            break;
        }
    }
    (points.len() > 1).then_some((points, time, reason))
}

/// Every line from `seeds`, in VTK's order (with `Both`: the forward lines, then the
/// backward ones), traced in parallel. `progress` gets the number of lines done so far
/// (from any thread).
pub fn trace(
    seeds: &[Vec3],
    o: &TraceOptions,
    field: &impl VectorField,
    progress: &(impl Fn(usize) + Sync),
) -> Result<Vec<Line>> {
    o.check()?;
    let dirs: &[bool] = match o.direction {
        Direction::Forward => &[false],
        Direction::Backward => &[true],
        Direction::Both => &[false, true],
    };
    let jobs: Vec<(u32, bool)> = dirs.iter().flat_map(|&b| (0..seeds.len() as u32).map(move |s| (s, b))).collect();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let lines: Vec<Option<Line>> = jobs
        .par_iter()
        .with_min_len(16)
        .map(|&(seed, backward)| {
            let sign = if backward { -1.0 } else { 1.0 };
            let line = integrate(seeds[seed as usize], sign, o, field).map(|(points, time, reason)| Line {
                seed,
                backward,
                points,
                time,
                reason,
            });
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
            line
        })
        .collect();
    Ok(lines.into_iter().flatten().collect())
}

/// Writes lines as VTK polydata (`.vtp`), as vtkStreamTracer gives them: the points (float32),
/// `fields` sampled at them through `loc` (point data), `IntegrationTime` (Float64 point
/// data), `ReasonForTermination` and `SeedIds` (Int32 cell data).
pub fn write_lines(
    path: &std::path::Path,
    lines: &[Line],
    loc: &mut dyn crate::BatchLocator,
    fields: &[super::FieldGroup],
    zlib: bool,
) -> Result<()> {
    use crate::io::vtk::write::{write_polylines, ArrayData, NamedArray};
    let points: Vec<Vec3> = lines.iter().flat_map(|l| l.points.iter().map(|&p| to_f32(p))).collect();
    let ends: Vec<usize> = lines
        .iter()
        .scan(0, |end, l| {
            *end += l.points.len();
            Some(*end)
        })
        .collect();
    let time: Vec<f64> = lines.iter().flat_map(|l| l.time.iter().copied()).collect();
    let reasons: Vec<i32> = lines.iter().map(|l| l.reason as i32).collect();
    let seeds: Vec<i32> = lines.iter().map(|l| l.seed as i32).collect();
    let probed = super::probe::probe(loc, &points, fields, |_| {})?;
    let mut point_data: Vec<NamedArray> = probed
        .arrays
        .iter()
        .map(|(g, v)| NamedArray { name: g.name.clone(), n_components: g.n_components(), data: ArrayData::F32(v) })
        .collect();
    point_data.push(NamedArray { name: "IntegrationTime".into(), n_components: 1, data: ArrayData::F64(&time) });
    let cell_data = [
        NamedArray { name: "ReasonForTermination".into(), n_components: 1, data: ArrayData::I32(&reasons) },
        NamedArray { name: "SeedIds".into(), n_components: 1, data: ArrayData::I32(&seeds) },
    ];
    write_polylines(path, &points, &ends, &point_data, &cell_data, zlib)
}

/// Seeds from a specification: `line:X0,Y0,Z0,X1,Y1,Z1,N` (N points from P0 to P1, both
/// included) or `grid:X0,X1,Y0,Y1,Z0,Z1,NX,NY,NZ` (a regular grid as `resample` lays it
/// out); `None` when `spec` is neither (a file of points, then).
pub fn seeds_from_spec(spec: &str) -> Option<Result<Vec<Vec3>>> {
    let (kind, args) = spec.split_once(':')?;
    let nums = || -> Result<Vec<f64>> {
        args.split(',')
            .map(|s| s.trim().parse::<f64>().map_err(|_| Error::Invalid(format!("{spec}: '{s}' is not a number"))))
            .collect()
    };
    let count = |x: f64| -> Result<usize> {
        if x >= 1.0 && x.fract() == 0.0 && x < 1e12 {
            Ok(x as usize)
        } else {
            Err(Error::Invalid(format!("{spec}: '{x}' is not a count of at least 1")))
        }
    };
    match kind {
        "line" => Some(nums().and_then(|v| {
            let [x0, y0, z0, x1, y1, z1, n] = v[..] else {
                return Err(Error::Invalid(format!("{spec}: line:X0,Y0,Z0,X1,Y1,Z1,N takes 7 numbers")));
            };
            let n = count(n)?;
            let (a, b) = ([x0, y0, z0], [x1, y1, z1]);
            Ok((0..n)
                .map(|i| {
                    let s = if n == 1 { 0.0 } else { i as f64 / (n - 1) as f64 };
                    std::array::from_fn(|k| (a[k] + s * (b[k] - a[k])) as f32)
                })
                .collect())
        })),
        "grid" => Some(nums().and_then(|v| {
            let [x0, x1, y0, y1, z0, z1, nx, ny, nz] = v[..] else {
                return Err(Error::Invalid(format!("{spec}: grid:X0,X1,Y0,Y1,Z0,Z1,NX,NY,NZ takes 9 numbers")));
            };
            let g = ImageGrid::spanning([x0, y0, z0], [x1, y1, z1], [count(nx)?, count(ny)?, count(nz)?])?;
            Ok((0..g.n_points()).map(|i| g.point(i)).collect())
        })),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An analytic field over a box, for the closed-form tests.
    struct Analytic<F: Fn([f64; 3]) -> [f64; 3] + Sync> {
        lo: [f32; 3],
        hi: [f32; 3],
        v: F,
    }
    impl<F: Fn([f64; 3]) -> [f64; 3] + Sync> VectorField for Analytic<F> {
        fn at(&self, p: Vec3, _: &mut Option<u32>) -> Option<[f32; 3]> {
            (0..3)
                .all(|k| p[k] >= self.lo[k] && p[k] <= self.hi[k])
                .then(|| (self.v)(p.map(f64::from)).map(|x| x as f32))
        }
    }

    /// A constant field: straight lines of exactly `max_length`, or up to the boundary.
    #[test]
    fn constant_field_gives_straight_lines_of_the_right_length() {
        let f = Analytic { lo: [0.0; 3], hi: [1.0; 3], v: |_| [2.0, 0.0, 0.0] };
        let o = TraceOptions { step: 0.03, max_length: 0.5, max_steps: 1000, ..Default::default() };
        let lines = trace(&[[0.1, 0.5, 0.5]], &o, &f, &|_| {}).unwrap();
        let l = &lines[0];
        assert_eq!(l.reason, Reason::OutOfLength);
        let end = l.points.last().unwrap();
        assert!((end[0] - 0.6).abs() < 1e-6 && (end[1] - 0.5).abs() < 1e-7, "{end:?}");
        // Time = length / speed.
        assert!((l.time.last().unwrap() - 0.25).abs() < 1e-7);
        // To the boundary: the last point is within a step of it; backward goes the other way.
        let o = TraceOptions { step: 0.03, direction: Direction::Both, ..Default::default() };
        let lines = trace(&[[0.1, 0.5, 0.5]], &o, &f, &|_| {}).unwrap();
        assert_eq!(lines.len(), 2);
        let (fw, bw) = (&lines[0], &lines[1]);
        assert_eq!((fw.reason, bw.reason, bw.backward), (Reason::OutOfDomain, Reason::OutOfDomain, true));
        assert!(fw.points.last().unwrap()[0] > 1.0 - 0.03 && bw.points.last().unwrap()[0] < 0.03);
        assert!(*bw.time.last().unwrap() < 0.0);
        // Steps: VTK takes max_steps + 1.
        let o = TraceOptions { step: 0.01, max_steps: 10, ..Default::default() };
        let l = &trace(&[[0.1, 0.5, 0.5]], &o, &f, &|_| {}).unwrap()[0];
        assert_eq!((l.reason, l.points.len()), (Reason::OutOfSteps, 12));
        // Zero velocity: no step, no line; a seed outside: no line either.
        let zero = Analytic { lo: [0.0; 3], hi: [1.0; 3], v: |_| [0.0; 3] };
        assert!(trace(&[[0.5; 3]], &o, &zero, &|_| {}).unwrap().is_empty());
        assert!(trace(&[[2.0, 0.5, 0.5]], &o, &f, &|_| {}).unwrap().is_empty());
    }

    /// A rigid rotation: circles that close. RK4's local error is O(h⁵), so one turn of
    /// 2πr/h steps ends within C·h⁴ of its start (C of order r⁻³: the curvature terms).
    #[test]
    fn rotation_gives_closing_circles() {
        let f = Analytic { lo: [-2.0; 3], hi: [2.0; 3], v: |p| [-p[1], p[0], 0.0] };
        for h in [0.1, 0.05] {
            let r = 1.0;
            let turn = 2.0 * std::f64::consts::PI * r;
            let o = TraceOptions { step: h, max_length: turn, max_steps: 100_000, ..Default::default() };
            let l = &trace(&[[r as f32, 0.0, 0.0]], &o, &f, &|_| {}).unwrap()[0];
            let end = l.points.last().unwrap();
            let gap = ((end[0] - r).powi(2) + end[1].powi(2)).sqrt();
            // f32 lookups add about 1e-7 per step.
            let bound = h.powi(4) / r.powi(3) + 1e-7 * turn / h;
            assert!(gap < bound, "h = {h}: the circle misses its start by {gap:e} (bound {bound:e})");
            // The time of one turn at unit angular speed is 2π.
            assert!((l.time.last().unwrap() - turn).abs() < 1e-4, "{:?}", l.time.last());
        }
    }

    #[test]
    fn seed_specifications() {
        let l = seeds_from_spec("line:0,0,0,1,2,3,3").unwrap().unwrap();
        assert_eq!(l, vec![[0.0, 0.0, 0.0], [0.5, 1.0, 1.5], [1.0, 2.0, 3.0]]);
        let g = seeds_from_spec("grid:0,1,0,1,0,0,2,3,1").unwrap().unwrap();
        assert_eq!(g.len(), 6);
        assert_eq!(g[5], [1.0, 1.0, 0.0]);
        assert!(seeds_from_spec("seeds.npy").is_none());
        assert!(seeds_from_spec("line:0,0,0,1,1,1").unwrap().is_err());
        assert!(seeds_from_spec("grid:0,1,0,1,0,1,0,2,2").unwrap().is_err());
        assert!(seeds_from_spec("line:0,0,0,1,1,x,2").unwrap().is_err());
    }
}
