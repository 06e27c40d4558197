//! Stream tracing (vtkStreamTracer): lines through a vector field from seed points, by
//! Runge–Kutta steps in the normalized field, as VTK integrates them with
//! `IntegrationStepUnit` = length: RK4 with a fixed step, or an adaptive step (Dormand–Prince
//! 5(4), or Cash–Karp 5(4), the tableau of VTK's vtkRungeKutta45) with vtkRungeKutta45's step
//! control. The step arithmetic is one state machine per particle (`particle`), driven two
//! ways: [`trace`] answers each particle's lookups at once from the tet of its last lookup (a
//! walk through face neighbours; the BVH when the walk fails), so a step costs a few
//! point-in-tet tests instead of a traversal; [`trace_with`] advances every live particle
//! together, one batched `sample_many` per Runge–Kutta stage, on any backend (or hands the
//! lines to the backend's own tracer).
//!
//! VTK's loop, reproduced step for step: a seed outside the mesh, or whose first step
//! already leaves it, gives no line; a line stops when a step (any stage) or its end point
//! leaves the mesh (OUT_OF_DOMAIN), when the speed drops to the terminal speed
//! (STAGNATION), after `max_steps` + 1 steps (OUT_OF_STEPS), or when its length reaches
//! `max_length` (OUT_OF_LENGTH; the last step is shortened to land on it). The integration
//! time advances by each step's length over the speed at its start; backward lines count
//! it negative. Beyond VTK: `max_time` ends a line when its integration time reaches it
//! (the last step shortened to land on it), with reason 7, the first code VTK leaves to
//! custom criteria. Where VTK's adaptive loop counts the *proposed* next step into the
//! propagation, and refuses a last step shorter than the minimum step (UNEXPECTED_VALUE),
//! lines here count the length travelled and land on `max_length` with a fixed last step.

use crate::error::{Error, Result};
use crate::geom::Vec3;
use crate::locate::{BatchLocator, Hint};
use crate::ops::ImageGrid;
use rayon::prelude::*;

mod particle;
mod pathline;
mod vorticity;
pub use particle::Particle;
pub use pathline::{
    pathline_run, pathline_run_batch, pathlines, pathlines_batch, Leg, PathJob, PathOptions, PathParticle, PathRun,
};
pub use vorticity::{vorticity, VorticityArrays};

pub use crate::streamline::{Direction, Integrator, Line, Reason, TraceOptions, BATCH_POINTS};

/// The field being traced: the vector at a point, the search starting from `hint` (the tet
/// of the previous lookup, updated to this one's); `None` outside the mesh.
pub trait VectorField: Sync {
    fn at(&self, p: Vec3, hint: &mut Hint) -> Option<[f32; 3]>;
}

impl<F: Fn(Vec3, &mut Hint) -> Option<[f32; 3]> + Sync> VectorField for F {
    fn at(&self, p: Vec3, hint: &mut Hint) -> Option<[f32; 3]> {
        self(p, hint)
    }
}

fn to_f32(p: [f64; 3]) -> Vec3 {
    p.map(|x| x as f32)
}

/// The line from `seed` (the `seed`-th) one way, or `None` when VTK makes none (the seed is
/// outside, or no step stays inside): each lookup answered at once, from the last one's tet.
pub fn integrate(seed: u32, point: Vec3, backward: bool, o: &TraceOptions, field: &impl VectorField) -> Option<Line> {
    let mut p = Particle::new(seed, point, backward);
    let mut hint = Hint::default();
    while let Some(q) = p.query() {
        p.answer(field.at(q, &mut hint), o);
    }
    p.finish()
}

/// Every line from `seeds`, in VTK's order (with `Both`: the forward lines, then the
/// backward ones), traced in parallel, particle by particle. `progress` gets the number of
/// lines done so far (from any thread; an error from it stops the tracing).
pub fn trace(
    seeds: &[Vec3],
    o: &TraceOptions,
    field: &impl VectorField,
    progress: &(impl Fn(usize) -> Result<()> + Sync),
) -> Result<Vec<Line>> {
    o.check()?;
    let done = std::sync::atomic::AtomicUsize::new(0);
    let lines: Vec<Option<Line>> = o
        .jobs(seeds.len())
        .par_iter()
        .with_min_len(16)
        .map(|&(seed, backward)| {
            let line = integrate(seed, seeds[seed as usize], backward, o, field);
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1)?;
            Ok(line)
        })
        .collect::<Result<_>>()?;
    Ok(lines.into_iter().flatten().collect())
}

/// [`trace`] on the CPU locator, returning the line arrays with `fields` sampled at the
/// line points from the integrator's own lookups: each recorded point (the seed, each step's
/// end) is the point of the lookup just answered, so its tet and weights are already known,
/// and the values equal those [`LineArrays::new`] gets by locating every point again (the
/// same tie rule: a walk's answer only strictly inside a tet, else the BVH's).
pub fn trace_sampled(
    seeds: &[Vec3],
    o: &TraceOptions,
    loc: &crate::CpuLocator,
    vector: [&str; 3],
    fields: &[super::FieldGroup],
    progress: &(impl Fn(usize) -> Result<()> + Sync),
) -> Result<LineArrays> {
    o.check()?;
    loc.ready_for_particles(false);
    let mesh = loc.mesh();
    let [vx, vy, vz] = vector.map(|c| mesh.field(c));
    let xyz = [vx?, vy?, vz?];
    // The vector a vertex at a time (one read a corner), where it is a per-vertex field.
    let vectors = crate::mesh::VertexVectors::<f32>::new(mesh, xyz);
    let names: Vec<&str> = fields.iter().flat_map(|g| g.component_refs()).collect();
    // The line fields other than the vector's components, which the step has at hand.
    let out: Vec<&crate::Field> =
        names.iter().filter(|c| !vector.contains(*c)).map(|c| mesh.field(c)).collect::<Result<_>>()?;
    // Where each line component comes from in `here` (below): the others, then the vector.
    let mut rest = 0;
    let source: Vec<usize> = names
        .iter()
        .map(|c| match vector.iter().position(|v| v == c) {
            Some(k) => out.len() + k,
            None => {
                rest += 1;
                rest - 1
            }
        })
        .collect();
    let done = std::sync::atomic::AtomicUsize::new(0);
    // Each line with the tets of its points and the fields' values there, the lines run in
    // the Morton order of their seeds and put back in the jobs' order.
    type Sampled = (Line, Vec<i32>, Vec<f32>);
    let jobs = o.jobs(seeds.len());
    let order = spatial_order(&jobs.iter().map(|&(s, _)| seeds[s as usize]).collect::<Vec<_>>());
    let mut lines: Vec<(u32, Option<Sampled>)> = order
        .par_iter()
        .with_min_len(16)
        .map(|&j| {
            let (seed, backward) = jobs[j as usize];
            let mut p = Particle::new(seed, seeds[seed as usize], backward);
            let room = (o.steps_bound() + 2).min(LINE_ROOM);
            p.reserve(room);
            let (mut hint, mut ids, mut values) =
                (Hint::default(), Vec::with_capacity(room), Vec::with_capacity(room * source.len()));
            // The other fields' values, then the vector's, at the last lookup.
            let mut here = vec![0f32; out.len() + 3];
            while let Some(q) = p.query() {
                let found = loc.locate_near(q, &mut hint);
                let at = found.map(|(t, b)| (t as usize, b));
                let (rest, v) = here.split_at_mut(out.len());
                match (&vectors, at) {
                    (Some(vectors), Some((t, b))) => v.copy_from_slice(&vectors.at(mesh, t, b)),
                    _ => mesh.values_at(&xyz, at, v),
                }
                let before = p.n_points();
                p.answer(found.map(|_| [v[0], v[1], v[2]]), o);
                // A point recorded by this answer is the point just looked up.
                if let (true, Some((t, _))) = (p.n_points() > before, found) {
                    mesh.values_at(&out, at, rest);
                    ids.push(t as i32);
                    values.extend(source.iter().map(|&s| here[s]));
                }
            }
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1)?;
            ids.shrink_to_fit();
            values.shrink_to_fit();
            Ok((j, p.finish().map(|l| (l, ids, values))))
        })
        .collect::<Result<_>>()?;
    lines.sort_unstable_by_key(|&(j, _)| j);
    let sampled: Vec<Sampled> = lines.into_iter().filter_map(|(_, l)| l).collect();
    let (lines, (ids, values)): (Vec<Line>, (Vec<_>, Vec<_>)) =
        sampled.into_iter().map(|(l, i, v)| (l, (i, v))).unzip();
    let lens: Vec<usize> = lines.iter().map(|l| l.points.len()).collect();
    let ids = super::concat(&lens, |i, out| out.copy_from_slice(&ids[i]));
    let widths: Vec<usize> = values.iter().map(Vec::len).collect();
    let values = super::concat(&widths, |i, out| out.copy_from_slice(&values[i]));
    Ok(LineArrays::of(&lines, super::probe::Probed::from_values(ids, fields, &values)))
}

/// The most points a CPU line makes room for at its start (more grow as they come).
const LINE_ROOM: usize = 4096;

/// The order in which a CPU tracer visits particles: the Morton order of their points (over
/// the points' own box). Particles close in the order are close in space, so one finds the
/// tets, corners and maps of the one before it in cache: streamlines from nearby seeds run
/// alongside, and a pathline leg revisits every particle. Lines are independent: the order
/// changes no answer, and the lines are put back in the seeds' order.
pub(super) fn spatial_order(points: &[Vec3]) -> Vec<u32> {
    let finite = points.iter().filter(|p| p.iter().all(|c| c.is_finite()));
    let (lo, hi) = finite.fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), p| {
        (std::array::from_fn(|k| lo[k].min(p[k])), std::array::from_fn(|k| hi[k].max(p[k])))
    });
    crate::bvh::morton::order(points, lo, hi)
}

/// The lines of [`trace`] through `loc`, the vector's three components being `vector`: by
/// the backend's own tracer where it has one for these options (soft-bvh with RK4: every
/// particle run to its end in one GPU kernel, [`crate::locate::LineTracer`]), else
/// step-synchronous on any backend: every live particle asks for its next velocity, and all
/// of them are answered by one `sample_many` through `loc`, a round per Runge–Kutta stage
/// (`progress` gets the number of lines done after each round). `fields` are the line
/// fields the caller then samples ([`LineArrays::sample`]): a backend's own tracer samples
/// them as it goes where it can (f32 data only: f64 values are computed on the host).
pub fn trace_with(
    seeds: &[Vec3],
    o: &TraceOptions,
    loc: &mut dyn BatchLocator,
    vector: [&str; 3],
    fields: &[super::FieldGroup],
    mut progress: impl FnMut(usize) -> Result<()>,
) -> Result<Vec<Line>> {
    o.check()?;
    let names: Vec<&str> = match fields.iter().any(|g| g.f64) {
        true => Vec::new(),
        false => fields.iter().flat_map(|g| g.component_refs()).collect(),
    };
    if let Some(lines) = crate::locate::trace_lines(loc, seeds, o, vector, &names, &mut progress)? {
        return Ok(lines);
    }
    let jobs = o.jobs(seeds.len());
    let mut live: Vec<(usize, Particle)> =
        jobs.iter().enumerate().map(|(j, &(s, b))| (j, Particle::new(s, seeds[s as usize], b))).collect();
    let mut done: Vec<(usize, Particle)> = Vec::with_capacity(live.len());
    let (mut points, mut ids, mut values) = (Vec::new(), Vec::new(), Vec::new());
    while !live.is_empty() {
        for batch in live.chunks_mut(super::CHUNK) {
            points.clear();
            points.par_extend(batch.par_iter().map(|(_, p)| p.query().unwrap_or([f32::NAN; 3])));
            ids.resize(points.len(), 0);
            values.resize(3 * points.len(), 0.0);
            loc.sample_many(&points, &vector, &mut ids, &mut values)?;
            batch.par_iter_mut().zip(&ids).zip(values.par_chunks(3)).for_each(|(((_, p), &id), v)| {
                p.answer((id >= 0).then_some([v[0], v[1], v[2]]), o);
            });
        }
        let (finished, rest): (Vec<_>, Vec<_>) = live.into_par_iter().partition(|(_, p)| p.is_done());
        done.extend(finished);
        live = rest;
        progress(done.len())?;
    }
    done.sort_unstable_by_key(|(j, _)| *j);
    Ok(done.into_iter().filter_map(|(_, p)| p.finish()).collect())
}

/// Lines as vtkStreamTracer outputs them: the points (float32, line after line), where each
/// line ends, `IntegrationTime` per point, `ReasonForTermination` and `SeedIds` per line, and
/// `fields` sampled at the points (point data).
pub struct LineArrays {
    pub points: Vec<Vec3>,
    /// One past the last point of each line.
    pub ends: Vec<usize>,
    pub time: Vec<f64>,
    /// What `time` is, as the writers name it: "IntegrationTime" (streamlines: the time
    /// along the line; pathlines: the simulation time), or "ParticleAge" (streaklines).
    pub time_name: &'static str,
    pub reasons: Vec<i32>,
    pub seeds: Vec<i32>,
    pub fields: super::probe::Probed,
    /// Pathlines and streaklines: each point's particle (`None` for streamlines).
    pub particles: Option<ParticleArrays>,
    /// vtkStreamTracer's `ComputeVorticity` arrays, where asked for ([`vorticity`]).
    pub vorticity: Option<VorticityArrays>,
}

/// Each point's particle, as vtkParticlePathFilter and vtkStreaklineFilter write them (point
/// data): ParaView's names, types and numbering.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParticleArrays {
    /// `ParticleId` (Int32): the particle's index among those its injection put inside the
    /// mesh, in the seeds' order. As VTK's, it starts again at each injection: with
    /// reinjection, (`ParticleId`, `InjectionStepId`) names a particle.
    pub particle_id: Vec<i32>,
    /// `InjectedPointId` (Int64, VTK's id type): its seed's index.
    pub injected_point_id: Vec<i64>,
    /// `InjectionStepId` (Int32): the output time it was injected at (0: the start time, k:
    /// the k-th output time after it).
    pub injection_step_id: Vec<i32>,
    /// `ParticleAge` (Float32, as VTK's): the time since its injection. `None` for
    /// streaklines, whose time array is already their age in f64.
    pub age: Option<Vec<f32>>,
}

impl LineArrays {
    /// The arrays of `lines`, with `fields` sampled through `loc`.
    pub fn new(lines: &[Line], loc: &mut dyn BatchLocator, fields: &[super::FieldGroup]) -> Result<LineArrays> {
        let mut arrays = Self::of(lines, super::probe::Probed::default());
        arrays.fields = super::probe::probe(loc, &arrays.points, fields, |_| Ok(()))?;
        Ok(arrays)
    }

    /// The arrays of `lines` with `fields`: as the tracer sampled them ([`Self::from_tracer`]:
    /// the GPU's stream kernel), else at the tets the tracer found the points in
    /// ([`Self::at_tets`]), else sampled through `loc` ([`Self::new`]).
    pub fn sample(
        lines: &[Line],
        mesh: &crate::Mesh,
        loc: &mut dyn BatchLocator,
        fields: &[super::FieldGroup],
    ) -> Result<LineArrays> {
        if let Some(arrays) = Self::from_tracer(lines, fields) {
            return Ok(arrays);
        }
        match Self::at_tets(lines, mesh, fields)? {
            Some(arrays) => Ok(arrays),
            None => Self::new(lines, loc, fields),
        }
    }

    /// The arrays of `lines` whose points all carry their tets and the values of `fields`
    /// (f32 data: [`Line::values`], as [`trace_with`] asks the tracer for them); `None`
    /// otherwise.
    pub fn from_tracer(lines: &[Line], fields: &[super::FieldGroup]) -> Option<LineArrays> {
        let k: usize = fields.iter().map(|g| g.n_components()).sum();
        let complete = |l: &Line| l.tets.len() == l.points.len() && l.values.len() == k * l.points.len();
        if fields.iter().any(|g| g.f64) || !lines.iter().all(complete) {
            return None;
        }
        let lens: Vec<usize> = lines.iter().map(|l| l.points.len()).collect();
        let ids = super::concat(&lens, |i, out| out.copy_from_slice(&lines[i].tets));
        let widths: Vec<usize> = lens.iter().map(|n| n * k).collect();
        let values = super::concat(&widths, |i, out| out.copy_from_slice(&lines[i].values));
        Some(Self::of(lines, super::probe::Probed::from_values(ids, fields, &values)))
    }

    /// The arrays of `lines` whose points all carry their tets ([`Line::tets`]), with the
    /// values of `fields` computed there on the host, in f64 on the file's data
    /// ([`crate::Mesh::values_along64`]): no second search. `None` when some line has none.
    pub fn at_tets(lines: &[Line], mesh: &crate::Mesh, fields: &[super::FieldGroup]) -> Result<Option<LineArrays>> {
        if lines.iter().any(|l| l.tets.len() != l.points.len()) {
            return Ok(None);
        }
        let ids: Vec<i32> = lines.par_iter().flat_map_iter(|l| l.tets.iter().copied()).collect();
        let components =
            fields.iter().flat_map(|g| g.component_refs()).map(|c| mesh.field(c)).collect::<Result<Vec<_>>>()?;
        // Line by line into their slices of the values (no flat copy of the points); in f64
        // only where some field has f64 data to keep.
        fn fill<T: crate::geom::Real + Default>(
            lines: &[Line],
            mesh: &crate::Mesh,
            fields: &[&crate::Field],
        ) -> Vec<T> {
            let lens: Vec<usize> = lines.iter().map(|l| l.points.len() * fields.len()).collect();
            super::concat(&lens, |i, part| mesh.values_along64(&lines[i].points, &lines[i].tets, fields, part))
        }
        let probed = if fields.iter().any(|g| g.f64) {
            super::probe::Probed::from_values64(ids, fields, &fill::<f64>(lines, mesh, &components))
        } else {
            super::probe::Probed::from_values(ids, fields, &fill::<f32>(lines, mesh, &components))
        };
        Ok(Some(Self::of(lines, probed)))
    }

    /// These arrays with [`vorticity`]'s, where `through` gives the mesh and the traced
    /// vector (`None`: as they are).
    pub fn with_vorticity(mut self, through: Option<(&crate::Mesh, &super::FieldGroup)>) -> Result<LineArrays> {
        if let Some((mesh, vector)) = through {
            self.vorticity = Some(vorticity(mesh, vector, &self)?);
        }
        Ok(self)
    }

    /// The arrays of `lines` (points as float32, line after line) with `fields`.
    pub(super) fn of(lines: &[Line], fields: super::probe::Probed) -> LineArrays {
        let lens: Vec<usize> = lines.iter().map(|l| l.points.len()).collect();
        let ends = lens
            .iter()
            .scan(0, |end, n| {
                *end += n;
                Some(*end)
            })
            .collect();
        LineArrays {
            points: super::concat(&lens, |i, out| {
                for (o, &p) in out.iter_mut().zip(&lines[i].points) {
                    *o = to_f32(p);
                }
            }),
            ends,
            time: super::concat(&lens, |i, out| out.copy_from_slice(&lines[i].time)),
            time_name: "IntegrationTime",
            reasons: lines.iter().map(|l| l.reason as i32).collect(),
            seeds: lines.iter().map(|l| l.seed as i32).collect(),
            fields,
            particles: None,
            vorticity: None,
        }
    }
}

/// The vector field `name` of `mesh`, which must have 3 components.
pub fn vector_field(mesh: &crate::Mesh, name: &str) -> Result<super::FieldGroup> {
    let g = super::fields::resolve(mesh, name)?;
    let whole =
        super::fields::groups(mesh).into_iter().find(|w| w.components.len() > 1 && w.components.contains(&g.name));
    if let (1, Some(whole)) = (g.n_components(), whole) {
        return Err(Error::Invalid(format!(
            "'{name}' is one component of the vector '{}': name the whole vector, '{}'",
            whole.name, whole.name
        )));
    }
    if g.n_components() != 3 {
        return Err(Error::Invalid(format!(
            "'{name}' is not a vector field: a vector field has 3 components, '{}' has {}",
            g.name,
            g.n_components()
        )));
    }
    Ok(g)
}

/// The fields lines carry, as vtkStreamTracer interpolates them: every point field, and the
/// traced vector wherever it lives.
pub fn line_fields(mesh: &crate::Mesh, vector: &super::FieldGroup) -> Vec<super::FieldGroup> {
    let mut out: Vec<_> =
        super::fields::groups(mesh).into_iter().filter(|g| g.location == crate::FieldLocation::Vertex).collect();
    if !out.contains(vector) {
        out.push(vector.clone());
    }
    out
}

/// Most seeds a trace takes: `SeedIds` are written as Int32.
pub const MAX_SEEDS: usize = i32::MAX as usize;

/// Seeds from a specification: `line:X0,Y0,Z0,X1,Y1,Z1,N` (N points from P0 to P1, both
/// included) or `grid:X0,X1,Y0,Y1,Z0,Z1,NX,NY,NZ` (a regular grid as `resample` lays it
/// out); `None` when `spec` is neither (a file of points, then).
pub fn seeds_from_spec(spec: &str) -> Option<Result<Vec<Vec3>>> {
    // The seeds are held at once (12 bytes each) and numbered by Int32 `SeedIds`.
    let bounded = |n: usize| -> Result<usize> {
        if n > MAX_SEEDS {
            return Err(Error::Invalid(format!("{spec}: {n} seeds; at most {MAX_SEEDS} (SeedIds are 32-bit)")));
        }
        crate::memory::check(n as u128 * std::mem::size_of::<Vec3>() as u128, || format!("{spec}: {n} seeds"))?;
        Ok(n)
    };
    Some(SeedSpec::parse(spec)?.and_then(|s| {
        let n = bounded(s.len())?;
        Ok(match s {
            SeedSpec::Line(a, b, _) => (0..n)
                .map(|i| {
                    let s = if n == 1 { 0.0 } else { i as f64 / (n - 1) as f64 };
                    std::array::from_fn(|k| (a[k] + s * (b[k] - a[k])) as f32)
                })
                .collect(),
            SeedSpec::Grid(g) => (0..n).map(|i| g.point(i)).collect(),
        })
    }))
}

/// How many seeds [`seeds_from_spec`] makes of `spec`, without making them (a caller checks
/// the memory the trace will take first); `None` when `spec` is not a specification.
pub fn seed_spec_count(spec: &str) -> Option<Result<usize>> {
    Some(SeedSpec::parse(spec)?.map(|s| s.len()))
}

/// A parsed seed specification ([`seeds_from_spec`]): a line's ends and its count, or a grid.
enum SeedSpec {
    Line([f64; 3], [f64; 3], usize),
    Grid(ImageGrid),
}

impl SeedSpec {
    fn parse(spec: &str) -> Option<Result<SeedSpec>> {
        let (kind, args) = spec.split_once(':')?;
        let nums = || -> Result<Vec<f64>> {
            args.split(',')
                .map(|s| s.trim().parse::<f64>().map_err(|_| Error::Invalid(format!("{spec}: '{s}' is not a number"))))
                .collect()
        };
        // A count is said back as it was written: an f64 prints 2^64 as 18446744073709552000.
        let count = |x: f64| -> Result<usize> {
            if x >= 1.0 && x.fract() == 0.0 && x < 1e12 {
                Ok(x as usize)
            } else {
                let written = args.split(',').map(str::trim).find(|s| s.parse::<f64>().ok() == Some(x));
                Err(Error::Invalid(format!("{spec}: '{}' is not a count of at least 1", written.unwrap_or("?"))))
            }
        };
        match kind {
            "line" => Some(nums().and_then(|v| {
                let [x0, y0, z0, x1, y1, z1, n] = v[..] else {
                    return Err(Error::Invalid(format!("{spec}: line:X0,Y0,Z0,X1,Y1,Z1,N takes 7 numbers")));
                };
                Ok(SeedSpec::Line([x0, y0, z0], [x1, y1, z1], count(n)?))
            })),
            "grid" => Some(nums().and_then(|v| {
                let [x0, x1, y0, y1, z0, z1, nx, ny, nz] = v[..] else {
                    return Err(Error::Invalid(format!("{spec}: grid:X0,X1,Y0,Y1,Z0,Z1,NX,NY,NZ takes 9 numbers")));
                };
                let dims = [count(nx)?, count(ny)?, count(nz)?];
                Ok(SeedSpec::Grid(ImageGrid::spanning([x0, y0, z0], [x1, y1, z1], dims)?))
            })),
            _ => None,
        }
    }

    fn len(&self) -> usize {
        match self {
            SeedSpec::Line(_, _, n) => *n,
            SeedSpec::Grid(g) => g.n_points(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Batches go through the lines in VTK's order (every forward line, then every backward
    /// one), each seed once a direction, at least 1024 lines a batch.
    #[test]
    fn batches_keep_the_line_order() {
        for (direction, max_steps, points, n) in [
            (Direction::Both, 10, 12 * 100, 2500),
            (Direction::Forward, 1 << 30, 1 << 20, 3000),
            (Direction::Backward, 1000, 1 << 25, 10),
            (Direction::Both, 1000, 1 << 25, 0),
        ] {
            let o = TraceOptions { direction, max_steps, ..Default::default() };
            let batches = o.batches(n, points);
            let jobs: Vec<(u32, bool)> = batches
                .iter()
                .flat_map(|(b, seeds)| {
                    assert_ne!(b.direction, Direction::Both);
                    assert!(seeds.len() <= (points / (max_steps + 2)).max(1));
                    b.jobs(seeds.len()).into_iter().map(move |(s, back)| (s + seeds.start as u32, back))
                })
                .collect();
            assert_eq!(jobs, o.jobs(n), "{direction:?} {n}");
        }
        let o = TraceOptions { direction: Direction::Both, max_steps: 10, ..Default::default() };
        assert_eq!(o.batches(2500, 12 * 100).len(), 50);
        // Lines longer than a batch's points: one a batch.
        let long = TraceOptions { max_steps: 1 << 40, ..Default::default() };
        assert!(long.batches(3, 1 << 25).iter().all(|(_, s)| s.len() == 1));
    }

    /// An analytic field over a box, for the closed-form tests.
    struct Analytic<F: Fn([f64; 3]) -> [f64; 3] + Sync> {
        lo: [f32; 3],
        hi: [f32; 3],
        v: F,
    }
    impl<F: Fn([f64; 3]) -> [f64; 3] + Sync> VectorField for Analytic<F> {
        fn at(&self, p: Vec3, _: &mut Hint) -> Option<[f32; 3]> {
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
        let lines = trace(&[[0.1, 0.5, 0.5]], &o, &f, &|_| Ok(())).unwrap();
        let l = &lines[0];
        assert_eq!(l.reason, Reason::OutOfLength);
        let end = l.points.last().unwrap();
        assert!((end[0] - 0.6).abs() < 1e-6 && (end[1] - 0.5).abs() < 1e-7, "{end:?}");
        // Time = length / speed.
        assert!((l.time.last().unwrap() - 0.25).abs() < 1e-7);
        // To the boundary: the last point is within a step of it; backward goes the other way.
        let o = TraceOptions { step: 0.03, direction: Direction::Both, ..Default::default() };
        let lines = trace(&[[0.1, 0.5, 0.5]], &o, &f, &|_| Ok(())).unwrap();
        assert_eq!(lines.len(), 2);
        let (fw, bw) = (&lines[0], &lines[1]);
        assert_eq!((fw.reason, bw.reason, bw.backward), (Reason::OutOfDomain, Reason::OutOfDomain, true));
        assert!(fw.points.last().unwrap()[0] > 1.0 - 0.03 && bw.points.last().unwrap()[0] < 0.03);
        assert!(*bw.time.last().unwrap() < 0.0);
        // Steps: VTK takes max_steps + 1.
        let o = TraceOptions { step: 0.01, max_steps: 10, ..Default::default() };
        let l = &trace(&[[0.1, 0.5, 0.5]], &o, &f, &|_| Ok(())).unwrap()[0];
        assert_eq!((l.reason, l.points.len()), (Reason::OutOfSteps, 12));
        // Zero velocity: no step, no line; a seed outside: no line either.
        let zero = Analytic { lo: [0.0; 3], hi: [1.0; 3], v: |_| [0.0; 3] };
        assert!(trace(&[[0.5; 3]], &o, &zero, &|_| Ok(())).unwrap().is_empty());
        assert!(trace(&[[2.0, 0.5, 0.5]], &o, &f, &|_| Ok(())).unwrap().is_empty());
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
            let l = &trace(&[[r as f32, 0.0, 0.0]], &o, &f, &|_| Ok(())).unwrap()[0];
            let end = l.points.last().unwrap();
            let gap = ((end[0] - r).powi(2) + end[1].powi(2)).sqrt();
            // f32 lookups add about 1e-7 per step.
            let bound = h.powi(4) / r.powi(3) + 1e-7 * turn / h;
            assert!(gap < bound, "h = {h}: the circle misses its start by {gap:e} (bound {bound:e})");
            // The time of one turn at unit angular speed is 2π.
            assert!((l.time.last().unwrap() - turn).abs() < 1e-4, "{:?}", l.time.last());
        }
    }

    /// The adaptive integrators on a constant field: straight lines landing exactly on the
    /// length or the time limit (the last step shortened), whatever the steps taken before.
    #[test]
    fn adaptive_steps_land_on_the_length_and_time_limits() {
        let f = Analytic { lo: [0.0; 3], hi: [1.0; 3], v: |_| [2.0, 0.0, 0.0] };
        for integrator in [Integrator::Rk45, Integrator::CashKarp, Integrator::Rk4] {
            let o = TraceOptions { step: 0.03, max_length: 0.5, integrator, ..Default::default() };
            let l = &trace(&[[0.1, 0.5, 0.5]], &o, &f, &|_| Ok(())).unwrap()[0];
            let end = l.points.last().unwrap();
            assert_eq!(l.reason, Reason::OutOfLength, "{integrator:?}");
            assert!((end[0] - (0.1f32 as f64 + 0.5)).abs() < 1e-12 && end[1] == 0.5, "{integrator:?}: {end:?}");
            assert!((l.time.last().unwrap() - 0.25).abs() < 1e-12);
            // The time limit: 0.1 time units at speed 2 are 0.2 long; backward too.
            let o = TraceOptions { max_time: 0.1, direction: Direction::Both, ..o };
            let lines = trace(&[[0.5, 0.5, 0.5]], &o, &f, &|_| Ok(())).unwrap();
            for (l, want) in lines.iter().zip([0.7, 0.3]) {
                assert_eq!(l.reason, Reason::OutOfTime, "{integrator:?}");
                assert!((l.points.last().unwrap()[0] - want).abs() < 1e-12, "{integrator:?}: {:?}", l.points.last());
                assert_eq!(l.time.last().unwrap().abs(), 0.1);
            }
        }
        // The step bounds: the adaptive step grows to the maximum on a constant field.
        let o = TraceOptions { step: 0.01, max_step: Some(0.04), integrator: Integrator::Rk45, ..Default::default() };
        let l = &trace(&[[0.1, 0.5, 0.5]], &o, &f, &|_| Ok(())).unwrap()[0];
        let gaps: Vec<f64> = l.points.windows(2).map(|w| w[1][0] - w[0][0]).collect();
        assert!(gaps[..gaps.len() - 1].iter().all(|&g| (g - 0.04).abs() < 1e-12), "{:?}", &gaps[..gaps.len().min(5)]);
        for bad in [
            TraceOptions { min_step: Some(0.1), max_step: Some(0.05), integrator: Integrator::Rk45, ..o.clone() },
            TraceOptions { max_error: 0.0, integrator: Integrator::CashKarp, ..o.clone() },
            TraceOptions { max_time: -1.0, ..o.clone() },
            TraceOptions { step: f64::NAN, ..o.clone() },
        ] {
            assert!(trace(&[[0.5; 3]], &bad, &f, &|_| Ok(())).is_err(), "{bad:?}");
        }
    }

    /// A rigid rotation with the adaptive step: one turn closes within the error allowed per
    /// step times the number of steps (rotation neither damps nor amplifies an error), plus
    /// the f32 lookups' 1e-7 per step; a smaller maximum error gives a closer circle.
    #[test]
    fn adaptive_rotation_closes_within_the_error_budget() {
        let f = Analytic { lo: [-2.0; 3], hi: [2.0; 3], v: |p| [-p[1], p[0], 0.0] };
        let turn = 2.0 * std::f64::consts::PI;
        for integrator in [Integrator::Rk45, Integrator::CashKarp] {
            let mut gaps = Vec::new();
            for max_error in [1e-5, 1e-8] {
                let o = TraceOptions {
                    step: 0.1,
                    max_step: Some(0.5),
                    max_length: turn,
                    max_steps: 100_000,
                    integrator,
                    max_error,
                    ..Default::default()
                };
                let l = &trace(&[[1.0, 0.0, 0.0]], &o, &f, &|_| Ok(())).unwrap()[0];
                assert_eq!(l.reason, Reason::OutOfLength);
                let end = l.points.last().unwrap();
                let gap = ((end[0] - 1.0).powi(2) + end[1].powi(2)).sqrt();
                let steps = (l.points.len() - 1) as f64;
                let bound = steps * (max_error + 1e-7);
                assert!(gap < bound, "{integrator:?} {max_error:e}: gap {gap:e} after {steps} steps (bound {bound:e})");
                assert!((l.time.last().unwrap() - turn).abs() < 1e-4);
                gaps.push((gap, steps));
            }
            assert!(gaps[1].0 < gaps[0].0 && gaps[1].1 > gaps[0].1, "{integrator:?}: {gaps:?}");
        }
    }

    /// A unit cube of n³ Kuhn cubes with its field `f` and a swirling vector field `v`.
    pub(super) fn swirl_cube(n: usize) -> std::sync::Arc<crate::Mesh> {
        let m = crate::test_support::KuhnGrid::new(n).mesh("cube");
        let mut fields = m.fields.clone();
        let swirl = |p: Vec3| [-(p[1] - 0.5) + 0.1, (p[0] - 0.5) + 0.05 * p[2], 0.2 - 0.1 * p[0]];
        for c in 0..3 {
            let values = m.points.iter().map(|&p| swirl(p)[c]).collect();
            fields.push(crate::Field {
                values64: None,
                name: format!("v[{c}]"),
                location: crate::FieldLocation::Vertex,
                values,
            });
        }
        let raw = crate::RawMesh { points: m.points.to_vec(), tets: m.tets.to_vec(), fields, ..Default::default() };
        std::sync::Arc::new(crate::Mesh::new(raw, "cube+v").unwrap())
    }

    /// Lines both ways from every seed, by `integrator`.
    fn both_ways(integrator: Integrator, step: f64, max_steps: usize) -> TraceOptions {
        TraceOptions { step, max_steps, direction: Direction::Both, integrator, ..Default::default() }
    }

    /// The step-synchronous batch driver (`trace_with` on the CPU locator, which has no
    /// tracer of its own) gives the per-particle driver's lines (the same tets, the same f64
    /// arithmetic), for every integrator. (The particles here take the exact test's weights,
    /// as the batch's lookups do: the held tets' maps, whose weights differ in the last f32
    /// bits, are off.)
    #[test]
    fn batch_tracing_matches_particle_tracing() {
        use crate::CpuLocator;
        let m = swirl_cube(6);
        let mut cpu = CpuLocator::new(m.clone());
        let seeds = seeds_from_spec("grid:0.1,0.9,0.1,0.9,0.2,0.8,3,3,2").unwrap().unwrap();
        let mut outside = seeds.clone();
        outside.push([3.0, 0.5, 0.5]);
        for integrator in Integrator::ALL {
            let o = both_ways(integrator, 0.02, 300);
            let one = {
                let exact = cpu.vector_field_with(["v[0]", "v[1]", "v[2]"], f64::INFINITY).unwrap();
                trace(&outside, &o, &exact, &|_| Ok(())).unwrap()
            };
            let mut rounds = 0;
            let all = trace_with(&outside, &o, &mut cpu, ["v[0]", "v[1]", "v[2]"], &[], |_| {
                rounds += 1;
                Ok(())
            })
            .unwrap();
            assert_eq!(one.len(), all.len(), "{integrator:?}");
            assert!(one.len() >= 2 * seeds.len() - 2 && rounds > 10, "{integrator:?}: {} lines", one.len());
            for (a, b) in one.iter().zip(&all) {
                assert_eq!(
                    (a.seed, a.backward, a.reason, a.points.len()),
                    (b.seed, b.backward, b.reason, b.points.len())
                );
                assert_eq!(a.points, b.points, "{integrator:?}");
                assert_eq!(a.time, b.time);
            }
            let reasons: std::collections::BTreeSet<i32> = one.iter().map(|l| l.reason as i32).collect();
            assert!(reasons.contains(&(Reason::OutOfDomain as i32)), "{integrator:?}: {reasons:?}");
        }
    }

    /// The line arrays from the integrator's own lookups equal those of locating every line
    /// point again: the same points and tets bit for bit, the values within 1e-6 of the
    /// fields' largest (the held tets' map weights against the exact test's), for every
    /// integrator, with seeds on the mesh's vertices, edges and faces (a grid aligned with a
    /// KuhnGrid's).
    #[test]
    fn sampled_tracing_matches_probing_the_lines() {
        use crate::CpuLocator;
        let m = swirl_cube(4);
        let vector = vector_field(&m, "v").unwrap();
        let out = line_fields(&m, &vector);
        assert!(out.len() >= 2);
        let cpu = CpuLocator::new(m.clone());
        let mut seeds = seeds_from_spec("grid:0,1,0,1,0,1,9,9,9").unwrap().unwrap();
        seeds.push([3.0, 0.5, 0.5]);
        for integrator in Integrator::ALL {
            let o = both_ways(integrator, 0.03, 200);
            let xyz = ["v[0]", "v[1]", "v[2]"];
            let lines = trace(&seeds, &o, &cpu.vector_field(xyz).unwrap(), &|_| Ok(())).unwrap();
            let mut again = crate::locate::FiniteOnly::new(CpuLocator::new(m.clone()));
            let want = LineArrays::new(&lines, &mut again, &out).unwrap();
            let got = trace_sampled(&seeds, &o, &cpu, xyz, &out, &|_| Ok(())).unwrap();
            // Through the bins alone (no BVH built): the same lines, tets and values, bit for bit.
            let deferred = CpuLocator::deferred(m.clone(), crate::bvh::BuildPreset::Fast);
            let by_bins = trace_sampled(&seeds, &o, &deferred, xyz, &out, &|_| Ok(())).unwrap();
            assert!(!deferred.index_built(), "{integrator:?}: the BVH was built");
            assert_eq!((&by_bins.points, &by_bins.ends, &by_bins.time), (&got.points, &got.ends, &got.time));
            assert_eq!((&by_bins.reasons, &by_bins.fields.ids), (&got.reasons, &got.fields.ids));
            for ((_, a), (_, b)) in by_bins.fields.arrays.iter().zip(&got.fields.arrays) {
                assert_eq!(
                    a.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                    b.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
                );
            }
            assert!(want.points.len() > 1000, "{}", want.points.len());
            assert_eq!((&got.points, &got.ends, &got.time), (&want.points, &want.ends, &want.time));
            assert_eq!((&got.reasons, &got.seeds), (&want.reasons, &want.seeds));
            assert_eq!(got.fields.ids, want.fields.ids, "{integrator:?}");
            assert_eq!(got.fields.arrays.len(), want.fields.arrays.len());
            for ((g, a), (h, b)) in got.fields.arrays.iter().zip(&want.fields.arrays) {
                assert_eq!((&g.name, a.len()), (&h.name, b.len()));
                let largest = b.iter().fold(0f32, |m, x| m.max(x.abs()));
                let worst = a.iter().zip(b).fold(0f32, |m, (x, y)| m.max((x - y).abs()));
                assert!(worst <= 1e-6 * largest, "{integrator:?} {}: off by {worst} of {largest}", g.name);
            }
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
        // Issue 29 item 19: a step too small to move a point is said to be so.
        let o = TraceOptions { step: 1e-30, ..Default::default() };
        let e = o.check_scale(1.0).unwrap_err().to_string();
        assert!(e.contains("step 1e-30 is too small"), "{e}");
        assert!(TraceOptions { step: 1e-3, ..Default::default() }.check_scale(1.0).is_ok());
        // Issue 29 item 19: a count beyond u64 is said back exactly as written.
        let e = seeds_from_spec("grid:0,1,0,1,0,1,18446744073709551617,2,2").unwrap().unwrap_err().to_string();
        assert!(e.contains("'18446744073709551617' is not a count") && !e.contains("552000"), "{e}");
        // Counts beyond SeedIds or memory are refused before any seed is made (issue 29, item 7).
        let e = seeds_from_spec("grid:0,1,0,1,0,2,100000,100000,100000").unwrap().unwrap_err().to_string();
        assert!(e.contains("1000000000000000 seeds") && e.contains("at most 2147483647"), "{e}");
        let e = seeds_from_spec("line:0,0,0,1,1,1,100000000000").unwrap().unwrap_err().to_string();
        assert!(e.contains("100000000000 seeds"), "{e}");
    }
}
