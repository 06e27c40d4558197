//! Pathlines (vtkParticlePathFilter): particles injected at a start time and carried through
//! an unsteady field, time being the integration variable: dx/dt = v(x, t), where v(x, t) is
//! the linear interpolation in time of the two bracketing steps' velocities, each
//! interpolated in space in the cell holding x. As VTK, the run goes leg by leg between the
//! output times (the start time, every step time between, the end time): each leg is
//! integrated with steps of half the leg (VTK's IntegrationStep 0.5) or `step` time units,
//! the last one shortened to land on the leg's end, where the particle's point is recorded.
//! Only the two steps bracketing the leg are held in memory, and the step the next leg adds,
//! read on another thread while the leg is traced. A particle whose lookup leaves
//! the mesh stops there (reason 1); one at or below the terminal speed at a leg's end stops
//! (6); the others reach the end time (7, the code `trace --max-time` uses). With
//! `reinject_every` N, the seeds are injected again at every N-th output time after the start
//! (ParaView's "Force Reinjection Every NSteps"), each injection's particles lines of their own.
//! With `streaklines`, the output is instead one line a seed through its particles at the end
//! time (ParaView's Streak Line filter, vtkStreaklineFilter: dye released at the seed).
//!
//! Two drivers share one state machine per particle ([`PathParticle`]): [`pathlines`]
//! answers each particle's lookups at once on the CPU, walking from its last tet;
//! [`pathlines_batch`] advances every live particle together, one batched `locate` per
//! Runge–Kutta stage on any backend, and interpolates on the host. A mixed mesh takes the
//! second: its locators answer cells, interpolated with the cells' own shape functions (as
//! vtkParticlePathFilter does), where the first walks the tets of their decomposition.

use super::particle::{combine, norm, MAX_STAGES};
use super::vorticity::{self, VorticityArrays};
use super::{Integrator, LineArrays, ParticleArrays, Reason};
use crate::error::{Error, Result};
use crate::geom::{Bary64, Vec3};
use crate::locate::BatchLocator;
use crate::mesh::{Field, FieldLocation, TimeSteps, VertexVectors};
use crate::ops::gradients::PointWeights;
use crate::ops::FieldGroup;
use crate::Mesh;
use rayon::prelude::*;

#[derive(Clone, Debug)]
pub struct PathOptions {
    pub integrator: Integrator,
    /// The integration step (time units); `None`: half of each leg (VTK's IntegrationStep
    /// 0.5). With an adaptive integrator, the first step.
    pub step: Option<f64>,
    /// Adaptive integrators: the largest error estimate of a step (mesh units), and the step
    /// bounds (time units; by default step / 50 and 2 step).
    pub max_error: f64,
    pub min_step: Option<f64>,
    pub max_step: Option<f64>,
    /// A particle at or below this speed at a leg's end stops (STAGNATION).
    pub terminal_speed: f64,
    /// Injection time (by default the first step's) and end time (by default the last's).
    pub start_time: Option<f64>,
    pub end_time: Option<f64>,
    /// Injects the seeds again at every `reinject_every`-th output time after the start
    /// (ParaView's "Force Reinjection Every NSteps"; 0: once, at the start time, or at every
    /// output time with `streaklines`). Each injection's particles are new lines.
    pub reinject_every: usize,
    /// Streaklines instead of pathlines: for each seed, the line through its particles' points
    /// at the end time, the oldest first and the one injected at the end time (at the seed)
    /// last; the line's time array is each point's particle age (the end time less its
    /// injection time).
    pub streaklines: bool,
    /// ParaView's "Compute Vorticity" (vtkParticleTracerBase's arrays) at each recorded point:
    /// `Vorticity`, the curl of the vector in the cell holding the point, interpolated in
    /// time as the vector is; `AngularVelocity`, the vorticity along the unit velocity; and
    /// `Rotation`, the angular velocity integrated along the particle's points in time by
    /// the trapezoid rule (0 at its injection). VTK takes the curl of the later step alone,
    /// so at a time between two steps (the injection point, a start or end time off the
    /// steps) its vorticity is the later step's; at a step's time the two agree.
    pub vorticity: bool,
}

/// Most steps a pathline's particle may need from the start time to the end time (about 20
/// minutes of one core at 100 ns a step).
pub const MAX_PATH_STEPS: f64 = 1e10;

impl Default for PathOptions {
    fn default() -> Self {
        PathOptions {
            integrator: Integrator::Rk4,
            step: None,
            max_error: 1e-6,
            min_step: None,
            max_step: None,
            terminal_speed: 1e-12,
            start_time: None,
            end_time: None,
            reinject_every: 0,
            streaklines: false,
            vorticity: false,
        }
    }
}

/// One leg of the run: from time `from` to `to`, inside the steps `bracket` and `bracket + 1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Leg {
    pub from: f64,
    pub to: f64,
    pub bracket: usize,
}

impl PathOptions {
    pub fn check(&self) -> Result<()> {
        let positive = |x: f64| x.is_finite() && x > 0.0;
        for (name, v) in [("step", self.step), ("minimum step", self.min_step), ("maximum step", self.max_step)] {
            if let Some(v) = v.filter(|&v| !positive(v)) {
                return Err(Error::Invalid(format!("the {name} must be a positive time, got {v}")));
            }
        }
        if let (Some(min), Some(max)) = (self.min_step, self.max_step) {
            if min > max {
                return Err(Error::Invalid(format!("the step bounds need min <= max, got min {min}, max {max}")));
            }
        }
        if self.integrator.is_adaptive() && !positive(self.max_error) {
            return Err(Error::Invalid(format!("the maximum error must be positive, got {}", self.max_error)));
        }
        if self.terminal_speed.is_nan() || self.terminal_speed < 0.0 {
            return Err(Error::Invalid(format!("the terminal speed must be 0 or more, got {}", self.terminal_speed)));
        }
        Ok(())
    }

    /// An error when a particle could take more than [`MAX_PATH_STEPS`] steps from `t0` to
    /// `t1`, or a step f64 cannot add to the times: pathlines have no step limit but the end
    /// time, so such a step would run for hours, or for ever (`t + h == t`).
    fn check_step_count(&self, t0: f64, t1: f64) -> Result<()> {
        let step = self.step.unwrap_or(f64::INFINITY);
        let smallest = match self.integrator.is_adaptive() {
            true => self.min_step.unwrap_or(step / 50.0).min(step),
            false => step,
        };
        let resolution = 4.0 * f64::EPSILON * t0.abs().max(t1.abs());
        if smallest < resolution || (t1 - t0) / smallest > MAX_PATH_STEPS {
            return Err(Error::Invalid(format!(
                "the step {smallest:e} is too small for the times {t0} to {t1}: a particle could take \
                 {:.1e} steps (at most {MAX_PATH_STEPS:.0e}), or f64 cannot add it to times of that size; \
                 use a larger step",
                (t1 - t0) / smallest
            )));
        }
        Ok(())
    }

    /// Every `reinjection`-th output time injects the seeds (the start time's always).
    fn reinjection(&self) -> usize {
        if self.streaklines && self.reinject_every == 0 {
            1
        } else {
            self.reinject_every
        }
    }

    /// The seeds' injections over `legs`: each at the start of a leg (its index and time), in
    /// time order. Streaklines also inject at the end time when it is an injection's (a
    /// point at the seed: the streak's newest); a pathline from there would have one point.
    fn injections_over(&self, legs: &[Leg]) -> Vec<(usize, f64)> {
        let every = self.reinjection();
        let mut out: Vec<(usize, f64)> =
            (0..legs.len()).filter(|&n| injects_at(n, every)).map(|n| (n, legs[n].from)).collect();
        if let (true, true, Some(last)) = (self.streaklines, injects_at(legs.len(), every), legs.last()) {
            out.push((legs.len() - 1, last.to));
        }
        out
    }

    /// How many particles a run over `legs` injects a seed as (1 without reinjection).
    pub fn injections(&self, legs: &[Leg]) -> usize {
        self.injections_over(legs).len()
    }

    /// The legs through `steps` (named `source` in errors): from the start time to the end
    /// time, cut at every step time between.
    pub fn legs(&self, source: &str, times: &[f64]) -> Result<Vec<Leg>> {
        let n = times.len();
        if n < 2 {
            return Err(Error::Invalid(format!(
                "{source} has {n} time step{}: pathlines (--unsteady) need a series of at least two steps",
                if n == 1 { "" } else { "s" }
            )));
        }
        let (first, last) = (times[0], times[n - 1]);
        let t0 = self.start_time.unwrap_or(first);
        let t1 = self.end_time.unwrap_or(last);
        for (name, t) in [("start", t0), ("end", t1)] {
            if !(t >= first && t <= last) {
                return Err(Error::Invalid(format!(
                    "the {name} time {t} is outside the time steps of {source} ({first} to {last})"
                )));
            }
        }
        if t0 >= t1 {
            return Err(Error::Invalid(format!("the end time {t1} must come after the start time {t0} ({source})")));
        }
        self.check_step_count(t0, t1)?;
        let mut stops = vec![t0];
        stops.extend(times.iter().copied().filter(|&t| t > t0 && t < t1));
        stops.push(t1);
        Ok(stops
            .windows(2)
            .map(|w| Leg {
                from: w[0],
                to: w[1],
                bracket: times.partition_point(|&t| t <= w[0]).saturating_sub(1).min(n - 2),
            })
            .collect())
    }
}

/// Whether the seeds are injected at the start of leg `n` (the start time, and every
/// `every`-th output time after it when reinjecting). `n` = the number of legs is the end
/// time: a pathline from there would have one point, so only streaklines inject there
/// ([`PathOptions::injections_over`]).
fn injects_at(n: usize, every: usize) -> bool {
    n == 0 || (every > 0 && n.is_multiple_of(every))
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum State {
    /// The velocity at the injection point.
    Start,
    /// The velocity at stage `i` (from 1) of the step being tried.
    Stage(usize),
    /// The velocity at the end of the accepted step.
    End,
    /// At the leg's end, waiting for the next leg.
    Idle,
    Done(Reason),
}

/// One particle: asks for the velocity at a point and time ([`Self::query`]), is told it
/// ([`Self::answer`]).
#[derive(Clone, Debug)]
pub struct PathParticle {
    pub id: u32,
    x: [f64; 3],
    t: f64,
    /// The leg's end, and the leg's step and step bounds.
    target: f64,
    h0: f64,
    min: f64,
    max: f64,
    /// The step the next step starts from, the step being tried, and whether it lands on
    /// the leg's end.
    h: f64,
    trial: f64,
    landing: bool,
    /// Stage velocities (k[0] at `x`, `t`).
    k: [[f64; 3]; MAX_STAGES],
    at: [f64; 3],
    at_t: f64,
    last: [f64; 3],
    state: State,
}

impl PathParticle {
    pub fn new(id: u32, point: Vec3, time: f64) -> PathParticle {
        let x = point.map(f64::from);
        PathParticle {
            id,
            x,
            t: time,
            target: time,
            h0: 0.0,
            min: 0.0,
            max: 0.0,
            h: 0.0,
            trial: 0.0,
            landing: false,
            k: [[0.0; 3]; MAX_STAGES],
            at: x,
            at_t: time,
            last: [0.0; 3],
            state: State::Start,
        }
    }

    /// The point (file coordinates) and time whose velocity the particle needs next; `None`
    /// at a leg's end or when it has stopped.
    #[inline]
    pub fn query(&self) -> Option<([f64; 3], f64)> {
        match self.state {
            State::Idle | State::Done(_) => None,
            _ => Some((self.at, self.at_t)),
        }
    }

    pub fn is_done(&self) -> bool {
        matches!(self.state, State::Done(_))
    }

    /// Why it stopped (`None` while it runs).
    pub fn reason(&self) -> Option<Reason> {
        match self.state {
            State::Done(r) => Some(r),
            _ => None,
        }
    }

    /// Sets out on the leg ending at `to` (the injection query first, if not yet answered).
    pub fn start_leg(&mut self, leg: &Leg, o: &PathOptions) {
        if self.is_done() {
            return;
        }
        self.target = leg.to;
        self.h0 = o.step.unwrap_or(0.5 * (leg.to - leg.from));
        self.min = o.min_step.unwrap_or(self.h0 / 50.0);
        self.max = o.max_step.unwrap_or(2.0 * self.h0).max(self.min);
        // A fixed step restarts each leg (as VTK's); an adaptive one keeps its proposal.
        self.h = if o.integrator.is_adaptive() && self.h > 0.0 { self.h.clamp(self.min, self.max) } else { self.h0 };
        if self.state == State::Idle {
            self.begin_step(o);
        }
    }

    /// The velocity at [`Self::query`]'s point and time (`None`: outside the mesh). True when
    /// that point is one to record: the injection point, or a leg's end.
    pub fn answer(&mut self, v: Option<[f64; 3]>, o: &PathOptions) -> bool {
        let Some(v) = v else {
            if !self.is_done() {
                self.state = State::Done(Reason::OutOfDomain);
            }
            return false;
        };
        match self.state {
            State::Start => {
                self.k[0] = v;
                self.begin_step(o);
                true
            }
            State::Stage(i) => {
                self.k[i] = v;
                self.last = v;
                self.stage(i + 1, o)
            }
            State::End => {
                self.k[0] = v;
                self.arrived(o)
            }
            State::Idle | State::Done(_) => false,
        }
    }

    /// The first stage of the next step, or idle at the leg's end.
    fn begin_step(&mut self, o: &PathOptions) {
        if self.t >= self.target {
            self.state = State::Idle;
            return;
        }
        self.trial = self.h;
        self.landing = false;
        // A step that would pass the leg's end (or stop a hair short of it) lands on it.
        if self.t + self.trial * (1.0 + 1e-9) >= self.target {
            self.trial = self.target - self.t;
            self.landing = true;
        }
        self.stage(1, o);
    }

    /// Asks for stage `i` of the step being tried, or ends the trial after the last stage.
    fn stage(&mut self, i: usize, o: &PathOptions) -> bool {
        let tab = o.integrator.tableau();
        if i <= tab.a.len() {
            let c: f64 = tab.a[i - 1].iter().sum();
            self.at = combine(self.x, self.trial, tab.a[i - 1], &self.k[..i]);
            self.at_t = self.t + c * self.trial;
            self.state = State::Stage(i);
            return false;
        }
        let stages = tab.b.len();
        let next = if tab.fsal { self.at } else { combine(self.x, self.trial, tab.b, &self.k[..stages]) };
        let mut h = self.h;
        if o.integrator.is_adaptive() && self.trial > self.min {
            // vtkRungeKutta45's control, in time: retry a step whose error estimate is too
            // large, propose the next one from the accepted one's.
            let ratio = norm(combine([0.0; 3], self.trial, tab.e, &self.k[..stages])) / o.max_error;
            if ratio > 1.0 {
                self.trial = (0.9 * self.trial * ratio.powf(-0.25)).max(self.min);
                self.landing = false;
                return self.stage(1, o);
            }
            h = if ratio == 0.0 { self.max } else { (0.9 * self.trial * ratio.powf(-0.2)).clamp(self.min, self.max) };
            // A landing step was shortened by the leg, not by the error: keep the longer.
            if self.landing {
                h = h.max(self.h);
            }
        }
        self.x = next;
        self.t = if self.landing { self.target } else { self.t + self.trial };
        self.h = h;
        if tab.fsal {
            // The last stage sampled here: its velocity is the end point's.
            self.k[0] = self.last;
            self.arrived(o)
        } else {
            (self.at, self.at_t) = (self.x, self.t);
            self.state = State::End;
            false
        }
    }

    /// At the end of an accepted step with its velocity in k[0]: the leg's end (recorded;
    /// the speed checked there, as VTK does), or the next step.
    fn arrived(&mut self, o: &PathOptions) -> bool {
        if self.t >= self.target {
            let speed = norm(self.k[0]);
            self.state =
                if speed == 0.0 || speed <= o.terminal_speed { State::Done(Reason::Stagnation) } else { State::Idle };
            return true;
        }
        self.begin_step(o);
        false
    }
}

/// The two steps bracketing a leg: the fields the run needs (`names`, in order) at each.
struct Bracket {
    times: [f64; 2],
    steps: [usize; 2],
    fields: [Vec<Field>; 2],
    /// The vector (the first three fields) at each step a vertex at a time, where
    /// [`VertexVectors`] takes it.
    vectors: [Option<VertexVectors<f64>>; 2],
}

/// Values `a` of the earlier step and `b` of the later one blended at the later one's weight
/// `w`: `a` at 0 and `b` at 1 exactly (`b` read only when needed), `a + w (b − a)` between.
#[inline]
fn blend<const N: usize>(w: f64, a: [f64; N], b: impl FnOnce() -> [f64; N]) -> [f64; N] {
    if w == 0.0 {
        return a;
    }
    let b = b();
    if w == 1.0 {
        b
    } else {
        std::array::from_fn(|k| a[k] + w * (b[k] - a[k]))
    }
}

/// Where a lookup found a particle: barycentrics in a tet (a tetrahedral mesh), or a cell of
/// a mixed mesh with its nodes and their shape functions' weights at the point, by which
/// the cell's values are interpolated, as VTK's filter interpolates them.
#[derive(Clone, Copy, Debug)]
enum Spot<'a> {
    Tet(usize, Bary64),
    Cell(usize, &'a [u32], &'a [f64]),
}

impl Spot<'_> {
    /// The tet, or the cell: the id the line points record.
    fn id(&self) -> usize {
        match *self {
            Spot::Tet(id, _) | Spot::Cell(id, _, _) => id,
        }
    }
}

/// A thread's buffers for the cells' weights and the vorticity's derivatives.
struct Scratch {
    weights: PointWeights,
    nodes: Vec<u32>,
    w: Vec<f64>,
}

impl Scratch {
    fn new(mesh: &Mesh) -> Scratch {
        Scratch { weights: PointWeights::new(mesh), nodes: Vec::new(), w: Vec::new() }
    }
}

/// The spot of point `p` in cell `cell` of a mixed mesh (`None`: it has no weights there, a
/// degenerate cell), its nodes and weights copied into `nodes` and `w`.
fn cell_spot<'a>(
    mesh: &Mesh,
    weights: &mut PointWeights,
    (nodes, w): (&'a mut Vec<u32>, &'a mut Vec<f64>),
    cell: usize,
    p: [f64; 3],
) -> Option<Spot<'a>> {
    let (n, ws, _) = weights.at(mesh, cell, p)?;
    nodes.clear();
    nodes.extend_from_slice(n);
    w.clear();
    w.extend_from_slice(ws);
    Some(Spot::Cell(cell, nodes, w))
}

/// The vector of a step's fields (its first three) a vertex at a time.
fn vertex_vectors(mesh: &Mesh, fields: &[Field]) -> Option<VertexVectors<f64>> {
    let [x, y, z] = fields.get(..3)? else { return None };
    VertexVectors::new(mesh, [x, y, z])
}

impl Bracket {
    /// The weight of the later step at time `t`.
    fn weight(&self, t: f64) -> f64 {
        let [t0, t1] = self.times;
        if t1 > t0 {
            ((t - t0) / (t1 - t0)).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// Field `k` at `spot`, at the later step's weight `w`.
    #[inline]
    fn value(&self, mesh: &Mesh, k: usize, spot: Spot<'_>, w: f64) -> f64 {
        let at = |step: usize| {
            let field = &self.fields[step][k];
            [match spot {
                Spot::Tet(tet, bary) => mesh.value_of::<f64>(field, Some((tet, bary))),
                Spot::Cell(cell, _, _) if field.location != FieldLocation::Vertex => field.value64(cell),
                Spot::Cell(_, nodes, weights) => {
                    nodes.iter().zip(weights).map(|(&n, &w)| w * field.value64(n as usize)).sum()
                }
            }]
        };
        blend(w, at(0), || at(1))[0]
    }

    fn velocity(&self, mesh: &Mesh, spot: Spot<'_>, t: f64) -> [f64; 3] {
        let w = self.weight(t);
        let (Spot::Tet(tet, bary), [Some(a), Some(b)]) = (spot, &self.vectors) else {
            return std::array::from_fn(|k| self.value(mesh, k, spot, w));
        };
        // What `value` computes (Mesh::value_of's interpolation, then the blend in time),
        // from one read of each corner's three components.
        blend(w, a.at(mesh, tet, bary), || b.at(mesh, tet, bary))
    }
}

/// One step's fields (the run's names, in order) and its vector a vertex at a time.
type Step = (Vec<Field>, Option<VertexVectors<f64>>);

/// Reads the steps a leg needs, holding two at a time, and reads the step the next leg adds
/// while this one is traced ([`Self::leg`]).
struct StepReader<'a> {
    steps: &'a TimeSteps,
    names: Vec<String>,
    held: Option<Bracket>,
    /// A step read ahead (its index, and the read's outcome, an error kept until needed).
    ahead: Option<(usize, Result<Step>)>,
}

/// Step `k`'s fields named `names`, in that order (a name may come twice: the vector is also
/// a line field), with its vector a vertex at a time.
fn read_step(steps: &TimeSteps, names: &[String], mesh: &Mesh, k: usize) -> Result<Step> {
    let all = steps.fields_named(k, names)?;
    let fields: Vec<Field> = names
        .iter()
        .map(|n| {
            all.iter()
                .find(|f| &f.name == n)
                .cloned()
                .ok_or_else(|| Error::Invalid(format!("{}: step {k} has no field '{n}'", steps.source)))
        })
        .collect::<Result<_>>()?;
    let vectors = vertex_vectors(mesh, &fields);
    Ok((fields, vectors))
}

impl StepReader<'_> {
    fn new<'a>(steps: &'a TimeSteps, names: Vec<String>) -> StepReader<'a> {
        StepReader { steps, names, held: None, ahead: None }
    }

    /// Step `k`: the one read ahead if it is `k`, else read now.
    fn read(&mut self, mesh: &Mesh, k: usize) -> Result<Step> {
        match self.ahead.take() {
            Some((j, step)) if j == k => step,
            _ => read_step(self.steps, &self.names, mesh, k),
        }
    }

    /// The bracket of steps `j`, `j + 1` (the later step of the previous bracket kept).
    fn bracket(&mut self, mesh: &Mesh, j: usize) -> Result<&Bracket> {
        let held = self.held.take();
        let b = match held {
            Some(b) if b.steps[0] == j => b,
            Some(b) if b.steps[1] == j => {
                let ([_, keep], [_, keep_vectors]) = (b.fields, b.vectors);
                let (next, next_vectors) = self.read(mesh, j + 1)?;
                Bracket {
                    times: [b.times[1], self.steps.times[j + 1]],
                    steps: [j, j + 1],
                    fields: [keep, next],
                    vectors: [keep_vectors, next_vectors],
                }
            }
            _ => {
                let (first, second) = (self.read(mesh, j)?, self.read(mesh, j + 1)?);
                let times = [self.steps.times[j], self.steps.times[j + 1]];
                Bracket { times, steps: [j, j + 1], fields: [first.0, second.0], vectors: [first.1, second.1] }
            }
        };
        Ok(self.held.insert(b))
    }

    /// `trace` run on the bracket of steps `j`, `j + 1` while another thread reads the step
    /// the next leg's bracket (`next`) adds, if it adds one: a series' reads (a file a step)
    /// then overlap the tracing instead of stopping it. Three steps are held meanwhile.
    fn leg<R>(&mut self, mesh: &Mesh, j: usize, next: Option<usize>, trace: impl FnOnce(&Bracket) -> R) -> Result<R> {
        self.bracket(mesh, j)?;
        let (steps, names, held) = (self.steps, &self.names, self.held.as_ref().expect("the bracket just made"));
        let k = (next == Some(j + 1) && j + 2 < steps.len()).then_some(j + 2);
        let (out, ahead) = std::thread::scope(|s| {
            let reading = k.map(|k| s.spawn(move || read_step(steps, names, mesh, k)));
            let out = trace(held);
            (out, reading.map(|r| r.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic))))
        });
        self.ahead = k.zip(ahead);
        Ok(out)
    }
}

/// One particle with what it has recorded, and the tet of its last lookup.
struct Track {
    p: PathParticle,
    /// Its seed's index (`p.id` counts the particles of every injection).
    seed: u32,
    /// The most points it can record (allocated at its first: no reallocation after).
    room: usize,
    hint: crate::locate::Hint,
    points: Vec<[f64; 3]>,
    time: Vec<f64>,
    tets: Vec<i32>,
    values: Vec<f32>,
    /// With vorticity: at each point, the vorticity, the angular velocity and the rotation.
    turning: Vec<([f64; 3], f64, f64)>,
}

impl Track {
    /// Asks the cache for the places of the point the particle records next, ahead of the
    /// leg's lookups. A leg visits every particle once, so these lines went cold since the
    /// last; each of a point's stores into them waited a memory round trip (a quarter of a
    /// pathline run's time, 100k particles of fusion 200k over 100 steps).
    fn prefetch_record(&self, n_values: usize) {
        use crate::prefetch::next_pushes;
        next_pushes(&self.points, 1);
        next_pushes(&self.time, 1);
        next_pushes(&self.tets, 1);
        next_pushes(&self.values, n_values);
        next_pushes(&self.turning, 1);
    }

    /// Records the particle's point at `spot`, with the line fields (indices 3.. of the
    /// bracket, after the vector) there at its time. `velocity`: the vector there at time
    /// `.1` (the lookup's), which a line field that is one of its components (`alias`) takes.
    /// `weights`: the vorticity's buffers, when it is asked for.
    fn record(
        &mut self,
        mesh: &Mesh,
        br: &Bracket,
        spot: Spot<'_>,
        alias: &[Option<usize>],
        velocity: ([f64; 3], f64),
        weights: Option<&mut PointWeights>,
    ) {
        let (x, t) = (self.p.x, self.p.t);
        let w = br.weight(t);
        if self.points.is_empty() {
            // (Here, on the core that traces it, not where it is injected.)
            self.points.reserve_exact(self.room);
            self.time.reserve_exact(self.room);
            self.tets.reserve_exact(self.room);
            self.values.reserve_exact(self.room * alias.len());
            if weights.is_some() {
                self.turning.reserve_exact(self.room);
            }
        }
        if let Some(weights) = weights {
            let v = if velocity.1 == t { velocity.0 } else { br.velocity(mesh, spot, t) };
            let xyz = |step: usize| {
                let [x0, x1, x2, ..] = &br.fields[step][..] else { unreachable!("the vector comes first") };
                [x0, x1, x2]
            };
            let curls = vorticity::curls_at(mesh, [xyz(0), xyz(1)], weights, spot.id(), x);
            let curl = curls.map_or([0.0; 3], |[c0, c1]| blend(w, c0, || c1));
            let omega = vorticity::angular_velocity(curl, v);
            let rotation = match (self.turning.last(), self.time.last()) {
                (Some(&(_, omega0, rotation0)), Some(&t0)) => rotation0 + (omega0 + omega) / 2.0 * (t - t0),
                _ => 0.0,
            };
            self.turning.push((curl, omega, rotation));
        }
        debug_assert!(self.points.len() < self.room, "a particle records more points than its legs allow");
        self.points.push(x);
        self.time.push(t);
        self.tets.push(spot.id() as i32);
        self.values.extend(alias.iter().enumerate().map(|(k, a)| match a {
            // The same field at the same point and time: the value `value` would compute.
            Some(c) if velocity.1 == t => velocity.0[*c] as f32,
            _ => br.value(mesh, 3 + k, spot, w) as f32,
        }));
    }
}

/// What both drivers set up: the legs, the step reader of the vector and line fields.
struct Run<'a> {
    legs: Vec<Leg>,
    reader: StepReader<'a>,
    /// A line field a component of the vector: that component's index, else None.
    alias: Vec<Option<usize>>,
    seeds: &'a [Vec3],
    /// The injections: the leg each comes at the start of (or during, for one at the end
    /// time), and its time.
    injections: Vec<(usize, f64)>,
    /// The particles injected so far, an injection after another.
    tracks: Vec<Track>,
}

fn setup<'a>(job: PathJob<'a>) -> Result<Run<'a>> {
    let PathJob { seeds, options: o, steps, vector, fields } = job;
    o.check()?;
    let legs = o.legs(&steps.source, &steps.times)?;
    let injections = o.injections_over(&legs);
    let particles = injections.len().saturating_mul(seeds.len());
    if particles > super::MAX_SEEDS {
        return Err(Error::Invalid(format!(
            "{} seeds injected {} times make {particles} particles; at most {} (their ids are 32-bit)",
            seeds.len(),
            injections.len(),
            super::MAX_SEEDS
        )));
    }
    let line: Vec<String> = fields.iter().flat_map(|g| g.components.iter().cloned()).collect();
    check_memory(&legs, &injections, seeds.len(), line.len(), o.vorticity)?;
    let names: Vec<String> = vector.iter().map(|s| s.to_string()).chain(line.iter().cloned()).collect();
    let alias = line.iter().map(|n| vector.iter().position(|v| v == n)).collect();
    let reader = StepReader::new(steps, names);
    Ok(Run { legs, reader, alias, seeds, injections, tracks: Vec::new() })
}

/// The most points a particle injected at time `t` of leg `n` records: its injection point,
/// then each remaining leg's end (none after the end time).
fn room(legs: &[Leg], (n, t): (usize, f64)) -> usize {
    if t < legs[n].to {
        legs.len() - n + 1
    } else {
        1
    }
}

/// Bytes a recorded point takes while the output is made from the tracks: the track's
/// copy (its point in f64, time, tet, `values` line values, with vorticity its three
/// arrays) and the output's (the point in f32, time, id, values, the four particle arrays,
/// the vorticity's).
fn point_bytes(values: usize, vorticity: bool) -> u128 {
    let turning = if vorticity { 40 } else { 0 };
    let track = 24 + 8 + 4 + 4 * values + turning;
    let output = 12 + 8 + 4 + 4 * values + 20 + turning;
    (track + output) as u128
}

/// Refuses a run whose particles and points cannot fit, before any step is read: every
/// particle is held to the end with every point it can record (`room`).
fn check_memory(legs: &[Leg], injections: &[(usize, f64)], seeds: usize, values: usize, vorticity: bool) -> Result<()> {
    let seeds = seeds as u128;
    let particles = injections.len() as u128 * seeds;
    let points = seeds * injections.iter().map(|&i| room(legs, i) as u128).sum::<u128>();
    let need = particles * std::mem::size_of::<Track>() as u128 + points.saturating_mul(point_bytes(values, vorticity));
    crate::memory::check(need, || {
        format!("{particles} particles over {} output times ({points} line points at most)", legs.len())
    })
}

impl Run<'_> {
    /// Injects the seeds (in `order`) for leg `n` if they are injected in it: new particles,
    /// numbered after those before. (One injected at the leg's end is answered in it and
    /// waits there.)
    fn inject(&mut self, n: usize, order: &[u32]) {
        let times: Vec<f64> = self.injections.iter().filter(|i| i.0 == n).map(|i| i.1).collect();
        for t in times {
            self.inject_at(t, room(&self.legs, (n, t)), order);
        }
    }

    fn inject_at(&mut self, t: f64, room: usize, order: &[u32]) {
        let first = self.tracks.len() as u32;
        self.tracks.extend(order.iter().map(|&i| Track {
            p: PathParticle::new(first + i, self.seeds[i as usize], t),
            seed: i,
            room,
            hint: Default::default(),
            points: Vec::new(),
            time: Vec::new(),
            tets: Vec::new(),
            values: Vec::new(),
            turning: Vec::new(),
        }));
    }
}

/// A finished run: its particles, in particle order (injections in time order, each in the
/// seeds' order), each with the points it recorded (its injection point and every output
/// time it reached). Its output can be taken at any output time ([`Self::frame`]: what
/// ParaView's filter shows at that time) or at the end time ([`Self::output`]).
pub struct PathRun {
    tracks: Vec<Track>,
    legs: Vec<Leg>,
    n_seeds: usize,
    streaklines: bool,
    vorticity: bool,
    fields: Vec<FieldGroup>,
}

/// An output line: its seed, its reason, and the runs of track points it joins (a range of
/// [`Cuts::runs`]).
struct Cut {
    seed: u32,
    reason: Reason,
    runs: std::ops::Range<usize>,
}

/// The lines of an output as runs of the tracks' points: each run a track and a range of its
/// points (a pathline is one run; a streakline one point of each of its particles).
#[derive(Default)]
struct Cuts {
    lines: Vec<Cut>,
    runs: Vec<(usize, std::ops::Range<usize>)>,
}

impl Cuts {
    fn push(&mut self, seed: u32, reason: Reason, runs: impl IntoIterator<Item = (usize, std::ops::Range<usize>)>) {
        let from = self.runs.len();
        self.runs.extend(runs);
        self.lines.push(Cut { seed, reason, runs: from..self.runs.len() });
    }

    /// A line's runs: each a track's index and a range of its points.
    fn runs(&self, c: &Cut) -> impl Iterator<Item = (usize, std::ops::Range<usize>)> + '_ {
        self.runs[c.runs.clone()].iter().cloned()
    }
}

impl PathRun {
    /// The output times after the start: each leg's end, the end time last.
    pub fn frame_times(&self) -> Vec<f64> {
        self.legs.iter().map(|l| l.to).collect()
    }

    /// The output at the `k`-th of [`Self::frame_times`], as a run ending there gives it:
    /// the pathlines up to that time (a particle that goes on after it ends there with
    /// reason 7, as at the end time), or the streaklines at that time.
    pub fn frame(&self, k: usize) -> LineArrays {
        let at = self.legs[k].to;
        let mut cuts = Cuts::default();
        if self.streaklines {
            // For each seed, the point at `at` of each of its particles there, oldest first.
            let mut by_seed: Vec<Vec<(usize, usize)>> = vec![Vec::new(); self.n_seeds];
            for (i, t) in self.tracks.iter().enumerate() {
                if let Ok(j) = t.time.binary_search_by(|x| x.total_cmp(&at)) {
                    by_seed[t.seed as usize].push((i, j));
                }
            }
            for (seed, points) in by_seed.iter().enumerate().filter(|(_, ps)| ps.len() > 1) {
                cuts.push(seed as u32, Reason::OutOfTime, points.iter().map(|&(i, j)| (i, j..j + 1)));
            }
            let mut arrays = self.arrays(&cuts, |t, _| at - t.time[0]);
            arrays.time_name = "ParticleAge";
            return arrays;
        }
        // A track with two points or more by then (a particle injected outside the mesh, or
        // gone before the next output time, makes no line).
        for (i, t) in self.tracks.iter().enumerate() {
            let n = t.time.partition_point(|&x| x <= at);
            if n > 1 {
                // Its reason when it stopped before `at`, or at it for its speed (checked at
                // a leg's end); one that leaves the mesh after `at` was still going there.
                let last = t.time[t.time.len() - 1];
                let reason = match t.p.reason() {
                    Some(r) if last < at || (last == at && r == Reason::Stagnation) => r,
                    _ => Reason::OutOfTime,
                };
                cuts.push(t.seed, reason, [(i, 0..n)]);
            }
        }
        self.arrays(&cuts, |_, time| time)
    }

    /// The output at the end time: pathlines, or streaklines at the end time.
    pub fn output(self) -> LineArrays {
        self.frame(self.legs.len() - 1)
    }

    /// The line arrays of `cuts`, each point's time `time(track, its time)`. Copied on every
    /// core: with reinjection a run can record tens of millions of points.
    fn arrays(&self, cuts: &Cuts, time: impl Fn(&Track, f64) -> f64 + Sync) -> LineArrays {
        let k: usize = self.fields.iter().map(|g| g.n_components()).sum();
        let lens: Vec<usize> = cuts.lines.iter().map(|c| cuts.runs(c).map(|(_, r)| r.len()).sum()).collect();
        let points = self.gather(cuts, &lens, 1, |t, r, out: &mut [Vec3]| {
            for (o, p) in out.iter_mut().zip(&t.points[r]) {
                *o = p.map(|c| c as f32);
            }
        });
        let times = self.gather(cuts, &lens, 1, |t, r, out: &mut [f64]| {
            for (o, &x) in out.iter_mut().zip(&t.time[r]) {
                *o = time(t, x);
            }
        });
        let ids = self.gather(cuts, &lens, 1, |t, r, out| out.copy_from_slice(&t.tets[r]));
        let values = self.gather(cuts, &lens, k, |t, r, out| out.copy_from_slice(&t.values[r.start * k..r.end * k]));
        // Each point's particle: constant along a track's run.
        let numbers = self.particle_numbers();
        let number = |t: &Track| numbers[t.p.id as usize];
        let particles = ParticleArrays {
            particle_id: self.gather(cuts, &lens, 1, |t, _, out| out.fill(number(t).0)),
            injected_point_id: self.gather(cuts, &lens, 1, |t, _, out| out.fill(i64::from(t.seed))),
            injection_step_id: self.gather(cuts, &lens, 1, |t, _, out| out.fill(number(t).1)),
            age: (!self.streaklines).then(|| {
                self.gather(cuts, &lens, 1, |t, r, out: &mut [f32]| {
                    for (o, &x) in out.iter_mut().zip(&t.time[r]) {
                        *o = (x - t.time[0]) as f32;
                    }
                })
            }),
        };
        let turning = |pick: fn(&([f64; 3], f64, f64)) -> f64| {
            self.gather(cuts, &lens, 1, |t, r, out: &mut [f64]| {
                out.iter_mut().zip(&t.turning[r]).for_each(|(o, x)| *o = pick(x))
            })
        };
        let vorticity = self.vorticity.then(|| VorticityArrays {
            vorticity: self.gather(cuts, &lens, 1, |t, r, out: &mut [[f64; 3]]| {
                out.iter_mut().zip(&t.turning[r]).for_each(|(o, x)| *o = x.0)
            }),
            rotation: turning(|x| x.2),
            angular_velocity: turning(|x| x.1),
            normals: None,
        });
        LineArrays {
            points,
            ends: lens
                .iter()
                .scan(0, |end, n| {
                    *end += n;
                    Some(*end)
                })
                .collect(),
            time: times,
            time_name: "IntegrationTime",
            reasons: cuts.lines.iter().map(|c| c.reason as i32).collect(),
            seeds: cuts.lines.iter().map(|c| c.seed as i32).collect(),
            fields: super::super::probe::Probed::from_values(ids, &self.fields, &values),
            particles: Some(particles),
            vorticity,
        }
    }

    /// Each particle's `ParticleId` and `InjectionStepId`, by its id (injection after
    /// injection, each in the seeds' order): its index among the particles its injection put
    /// inside the mesh (those that recorded a point; -1 for the others), and the index of its
    /// injection time among the output times (the start time's 0), as VTK numbers them.
    fn particle_numbers(&self) -> Vec<(i32, i32)> {
        let times: Vec<f64> = self.legs.first().map(|l| l.from).into_iter().chain(self.frame_times()).collect();
        let mut numbers = vec![(-1, -1); self.tracks.len()];
        let mut inside = 0;
        for (k, t) in self.tracks.iter().enumerate() {
            if k % self.n_seeds.max(1) == 0 {
                inside = 0;
            }
            if let Some(&t0) = t.time.first() {
                numbers[t.p.id as usize] = (inside, times.partition_point(|&x| x < t0) as i32);
                inside += 1;
            }
        }
        numbers
    }

    /// Each line's `width` items a point (`lens` points a line), filled run after run by
    /// `put(track, its points' range, out)`.
    fn gather<T: Copy + Default + Send + Sync>(
        &self,
        cuts: &Cuts,
        lens: &[usize],
        width: usize,
        put: impl Fn(&Track, std::ops::Range<usize>, &mut [T]) + Sync,
    ) -> Vec<T> {
        let widths: Vec<usize> = lens.iter().map(|n| n * width).collect();
        super::super::concat(&widths, |line, out| {
            let mut at = 0;
            for (i, r) in cuts.runs(&cuts.lines[line]) {
                let n = r.len() * width;
                put(&self.tracks[i], r, &mut out[at..at + n]);
                at += n;
            }
        })
    }
}

impl Run<'_> {
    /// The finished run (its tracks in particle order).
    fn finished(self, o: &PathOptions, fields: &[FieldGroup]) -> PathRun {
        PathRun {
            tracks: self.tracks,
            legs: self.legs,
            n_seeds: self.seeds.len(),
            streaklines: o.streaklines,
            vorticity: o.vorticity,
            fields: fields.to_vec(),
        }
    }
}

/// What a pathline run traces: particles from `seeds` through the vector `vector` (its three
/// component fields) of the time steps `steps`, with `options`; `fields` (of the mesh) are
/// recorded at the line points, interpolated in time as the vector is.
#[derive(Clone, Copy)]
pub struct PathJob<'a> {
    pub seeds: &'a [Vec3],
    pub options: &'a PathOptions,
    pub steps: &'a TimeSteps,
    pub vector: [&'a str; 3],
    pub fields: &'a [FieldGroup],
}

/// The pathlines (or streaklines) of `job` on the CPU at the end time: [`pathline_run`]'s
/// output.
pub fn pathlines(
    job: PathJob,
    loc: &crate::CpuLocator,
    progress: impl FnMut(usize) -> Result<()>,
) -> Result<LineArrays> {
    Ok(pathline_run(job, loc, progress)?.output())
}

/// The run of `job` on the CPU: each particle walks from its last tet. `progress` gets the
/// number of legs done.
pub fn pathline_run(
    job: PathJob,
    loc: &crate::CpuLocator,
    mut progress: impl FnMut(usize) -> Result<()>,
) -> Result<PathRun> {
    let (seeds, o) = (job.seeds, job.options);
    if loc.mesh().cells.is_some() {
        return Err(Error::Invalid(format!(
            "{}: the per-particle walk runs on tets; a mixed mesh's pathlines go through its cell locator \
             (pathline_run_batch)",
            loc.mesh().info.source
        )));
    }
    let mut run = setup(job)?;
    loc.ready_for_particles(true);
    // Each leg visits an injection's particles in the Morton order of their seeds (they move
    // little in a leg): see `spatial_order`. Back in the particles' order at the end.
    let order = super::spatial_order(seeds);
    let mesh = loc.mesh().clone();
    for n in 0..run.legs.len() {
        run.inject(n, &order);
        let (leg, next) = (run.legs[n], run.legs.get(n + 1).map(|l| l.bracket));
        let (alias, tracks) = (&run.alias, &mut run.tracks);
        run.reader.leg(&mesh, leg.bracket, next, |br| {
            let buffers = || o.vorticity.then(|| PointWeights::new(&mesh));
            tracks.par_iter_mut().with_min_len(64).for_each_init(buffers, |weights, tr| {
                tr.prefetch_record(alias.len());
                tr.p.start_leg(&leg, o);
                while let Some((q, t)) = tr.p.query() {
                    let found = loc.locate_near(q.map(|c| c as f32), &mut tr.hint);
                    let spot = found.map(|(tet, b)| Spot::Tet(tet as usize, b.map(f64::from)));
                    let v = spot.map(|s| br.velocity(&mesh, s, t));
                    if tr.p.answer(v, o) {
                        if let (Some(s), Some(v)) = (spot, v) {
                            tr.record(&mesh, br, s, alias, (v, t), weights.as_mut());
                        }
                    }
                }
            })
        })?;
        progress(n + 1)?;
    }
    run.tracks.sort_unstable_by_key(|t| t.p.id);
    Ok(run.finished(o, job.fields))
}

/// [`pathline_run_batch`]'s output at the end time.
pub fn pathlines_batch(
    job: PathJob,
    loc: &mut dyn BatchLocator,
    mesh: &Mesh,
    progress: impl FnMut(usize) -> Result<()>,
) -> Result<LineArrays> {
    Ok(pathline_run_batch(job, loc, mesh, progress)?.output())
}

/// [`pathline_run`] step-synchronous: every live particle's lookup answered by one `locate`
/// through `loc` (any backend) per Runge–Kutta stage, each from the particle's last tet where
/// the backend walks from one ([`crate::locate::locate_from`]: soft-bvh), the values
/// interpolated on the host in f64 at the tets found (the cells, with their shape functions,
/// on a mixed mesh, whose locators answer cells).
pub fn pathline_run_batch(
    job: PathJob,
    loc: &mut dyn BatchLocator,
    mesh: &Mesh,
    mut progress: impl FnMut(usize) -> Result<()>,
) -> Result<PathRun> {
    let o = job.options;
    let mut run = setup(job)?;
    // A mixed mesh's locators answer cells, interpolated with the cells' shape functions.
    let cells = mesh.cells.is_some();
    let seeds_order: Vec<u32> = (0..job.seeds.len() as u32).collect();
    let (mut points, mut ids, mut hints): (Vec<Vec3>, Vec<i32>, Vec<i32>) = (Vec::new(), Vec::new(), Vec::new());
    let mut live: Vec<usize> = Vec::new();
    // Each particle's last tet, where its next lookup starts.
    let mut last = Vec::new();
    for n in 0..run.legs.len() {
        run.inject(n, &seeds_order);
        last.resize(run.tracks.len(), crate::locate::OUTSIDE);
        let (leg, next) = (run.legs[n], run.legs.get(n + 1).map(|l| l.bracket));
        let (alias, tracks) = (&run.alias, &mut run.tracks);
        run.reader.leg(mesh, leg.bracket, next, |br| -> Result<()> {
            tracks.par_iter_mut().for_each(|tr| tr.p.start_leg(&leg, o));
            loop {
                live.clear();
                live.extend(tracks.iter().enumerate().filter(|(_, t)| t.p.query().is_some()).map(|(i, _)| i));
                if live.is_empty() {
                    break;
                }
                for part in live.chunks(super::super::CHUNK) {
                    points.clear();
                    points.extend(
                        part.iter().map(|&i| tracks[i].p.query().map_or([f32::NAN; 3], |(q, _)| q.map(|c| c as f32))),
                    );
                    hints.clear();
                    hints.extend(part.iter().map(|&i| last[i]));
                    ids.resize(points.len(), -1);
                    crate::locate::locate_from(loc, &points, &hints, &mut ids)?;
                    for (&i, &id) in part.iter().zip(&ids) {
                        if id >= 0 {
                            last[i] = id;
                        }
                    }
                    // The answers, on every core: each track of `part` once.
                    let mut chosen: Vec<&mut Track> = Vec::with_capacity(part.len());
                    let mut rest = tracks.iter_mut().enumerate();
                    for &i in part {
                        let (_, t) = rest.by_ref().find(|(j, _)| *j == i).expect("live indices ascend");
                        chosen.push(t);
                    }
                    let buffers = || Scratch::new(mesh);
                    chosen.into_par_iter().zip(ids.par_iter()).for_each_init(buffers, |scratch, (tr, &id)| {
                        let Some((q, t)) = tr.p.query() else { return };
                        let Scratch { weights, nodes, w } = scratch;
                        let spot = match (id >= 0, cells) {
                            (false, _) => None,
                            (true, true) => cell_spot(mesh, weights, (nodes, w), id as usize, q),
                            (true, false) => mesh.bary64(id as usize, q).map(|b| Spot::Tet(id as usize, b)),
                        };
                        let v = spot.map(|s| br.velocity(mesh, s, t));
                        if tr.p.answer(v, o) {
                            if let (Some(s), Some(v)) = (spot, v) {
                                tr.record(mesh, br, s, alias, (v, t), o.vorticity.then_some(&mut *weights));
                            }
                        }
                    });
                }
            }
            Ok(())
        })??;
        progress(n + 1)?;
    }
    Ok(run.finished(o, job.fields))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::StepFields;
    use crate::CpuLocator;
    use rand::{Rng, SeedableRng};
    use std::sync::Arc;

    /// Rotation about the axis x = y = 0.5 at the angular speed ω(t) = 1 + t: the field is
    /// linear in space and in time, so the mesh and the time interpolation reproduce it
    /// exactly, and a particle at radius r turns by θ(t) = (t - t0) + (t² - t0²)/2. With a
    /// `lift` a, the z component a (x - 0.5) adds (0, -a, 0) to the curl (0, 0, 2ω(t)).
    struct Spin {
        points: Vec<[f64; 3]>,
        times: Vec<f64>,
        lift: f64,
    }
    fn omega(t: f64) -> f64 {
        1.0 + t
    }
    impl StepFields for Spin {
        fn read(&self, k: usize) -> Result<Vec<Field>> {
            let w = omega(self.times[k]);
            let a = self.lift;
            let mut out: Vec<Field> = (0..3)
                .map(|c| {
                    let v64: Vec<f64> = self.points.iter().map(|p| spin_at(*p, w, a)[c]).collect();
                    Field {
                        name: format!("v[{c}]"),
                        location: FieldLocation::Vertex,
                        values: v64.iter().map(|&v| v as f32).collect(),
                        values64: Some(v64),
                    }
                })
                .collect();
            // A scalar that is the time itself, to check the recorded fields' interpolation.
            out.push(Field::new("clock", FieldLocation::Vertex, vec![self.times[k] as f32; self.points.len()]));
            Ok(out)
        }
    }

    /// [`Spin`]'s velocity at `p` for the angular speed `w`.
    fn spin_at(p: [f64; 3], w: f64, lift: f64) -> [f64; 3] {
        [-w * (p[1] - 0.5), w * (p[0] - 0.5), lift * (p[0] - 0.5)]
    }

    fn spin_series(n: usize, times: Vec<f64>) -> (Arc<Mesh>, TimeSteps) {
        lifted_spin_series(n, times, 0.0)
    }

    fn lifted_spin_series(n: usize, times: Vec<f64>, lift: f64) -> (Arc<Mesh>, TimeSteps) {
        let m = crate::test_support::KuhnGrid::new(n).mesh("cube");
        let points: Vec<[f64; 3]> = m.points.iter().map(|p| p.map(f64::from)).collect();
        let spin = Spin { points, times: times.clone(), lift };
        let raw = crate::RawMesh {
            points: m.points.to_vec(),
            tets: m.tets.to_vec(),
            fields: spin.read(0).unwrap(),
            ..Default::default()
        };
        let mesh = Arc::new(Mesh::new(raw, "spin").unwrap());
        (mesh, TimeSteps::new("spin.pvd", times, Box::new(spin)))
    }

    fn groups(m: &Mesh) -> Vec<FieldGroup> {
        crate::ops::fields::groups(m)
    }

    const XYZ: [&str; 3] = ["v[0]", "v[1]", "v[2]"];

    /// An n × n × 2 grid of seeds over the cube (the corners' circles leave it) and one seed
    /// outside it.
    fn leaving_seeds(n: usize) -> Vec<Vec3> {
        let spec = format!("grid:0.05,0.95,0.05,0.95,0.3,0.7,{n},{n},2");
        let mut seeds = crate::ops::trace::seeds_from_spec(&spec).unwrap().unwrap();
        seeds.push([3.0, 0.5, 0.5]);
        seeds
    }

    /// The tests' jobs: the vector `v`.
    fn job<'a>(
        seeds: &'a [Vec3],
        options: &'a PathOptions,
        steps: &'a TimeSteps,
        fields: &'a [FieldGroup],
    ) -> PathJob<'a> {
        PathJob { seeds, options, steps, vector: XYZ, fields }
    }

    /// The largest distance of a line's points from the closed-form path, and its last time.
    fn miss(arrays: &LineArrays, line: usize, seed: [f64; 3], t0: f64) -> f64 {
        let start = if line == 0 { 0 } else { arrays.ends[line - 1] };
        (start..arrays.ends[line])
            .map(|i| {
                let t = arrays.time[i];
                let theta = (t - t0) + 0.5 * (t * t - t0 * t0);
                let (dx, dy) = (seed[0] - 0.5, seed[1] - 0.5);
                let (c, s) = (theta.cos(), theta.sin());
                let want = [0.5 + c * dx - s * dy, 0.5 + s * dx + c * dy, seed[2]];
                let p = arrays.points[i].map(f64::from);
                (0..3).map(|k| (p[k] - want[k]).powi(2)).sum::<f64>().sqrt()
            })
            .fold(0.0, f64::max)
    }

    /// RK4 in time on the closed-form path, within the bound its order gives. For this
    /// rotation RK4's step multiplies the phase by 1 + z + z²/2 + z³/6 + z⁴/24 (z = iωh)
    /// instead of e^z: an error of r|ωh|⁵/120 per step; the time dependence of ω adds terms
    /// of the same order (ω' = 1 ≤ ω²), hence a factor 10 over the sum of the steps' errors.
    /// The f32 lookups (positions rounded to f32, barycentrics in f32) add ~1e-7 · ωt.
    #[test]
    fn rotation_with_growing_speed_follows_the_closed_form_path() {
        let (m, steps) = spin_series(8, vec![0.0, 0.5, 1.0, 1.5, 2.0]);
        let cpu = CpuLocator::new(m.clone());
        let fields = groups(&m);
        let seeds: Vec<Vec3> = vec![[0.8, 0.5, 0.3], [0.5, 0.2, 0.7], [0.65, 0.6, 0.5]];
        let mut gaps = Vec::new();
        for h in [0.1, 0.05] {
            let o = PathOptions { step: Some(h), ..Default::default() };
            let a = pathlines(job(&seeds, &o, &steps, &fields), &cpu, |_| Ok(())).unwrap();
            assert_eq!(a.ends.len(), 3);
            assert_eq!(a.reasons, [Reason::OutOfTime as i32; 3]);
            // One point per output time: the start, each step, the end.
            assert_eq!(a.ends[0], 5);
            assert_eq!(a.time[..5], [0.0, 0.5, 1.0, 1.5, 2.0]);
            let clock = &a.fields.arrays.iter().find(|(g, _)| g.name == "clock").unwrap().1;
            assert_eq!(clock[..5], [0.0, 0.5, 1.0, 1.5, 2.0]);
            let mut worst: f64 = 0.0;
            for (i, s) in seeds.iter().enumerate() {
                let r = ((s[0] as f64 - 0.5).powi(2) + (s[1] as f64 - 0.5).powi(2)).sqrt();
                // Sum over the steps of r |ω h|⁵ / 120, ω at the step's end.
                let n = (2.0 / h).round() as usize;
                let bound: f64 =
                    (1..=n).map(|j| r * (omega(j as f64 * h) * h).powi(5) / 120.0).sum::<f64>() * 10.0 + 1e-7 * 4.0;
                let gap = miss(&a, i, s.map(f64::from), 0.0);
                assert!(gap < bound, "h = {h}, seed {i}: {gap:e} off the closed form (bound {bound:e})");
                worst = worst.max(gap);
            }
            gaps.push(worst);
        }
        // Fourth order: halving the step divides the error by about 16.
        assert!(gaps[0] / gaps[1] > 8.0, "{gaps:?}");
        // The default step (half of each leg) and the adaptive integrators, with a start and
        // end between steps: within their error budgets.
        for integrator in [Integrator::Rk4, Integrator::Rk45, Integrator::CashKarp] {
            let o = PathOptions {
                integrator,
                max_error: 1e-9,
                start_time: Some(0.25),
                end_time: Some(1.75),
                ..Default::default()
            };
            let a = pathlines(job(&seeds, &o, &steps, &fields), &cpu, |_| Ok(())).unwrap();
            assert_eq!(a.time[..a.ends[0]], [0.25, 0.5, 1.0, 1.5, 1.75], "{integrator:?}");
            let clock = &a.fields.arrays.iter().find(|(g, _)| g.name == "clock").unwrap().1;
            assert!((clock[0] - 0.25).abs() < 1e-6 && (clock[4] - 1.75).abs() < 1e-6, "{:?}", &clock[..5]);
            let gap = (0..3).map(|i| miss(&a, i, seeds[i].map(f64::from), 0.25)).fold(0.0, f64::max);
            let bound = if integrator.is_adaptive() {
                1000.0 * 1e-9 + 1e-6 // at most ~1000 steps of error 1e-9 each, and the f32 floor
            } else {
                // Legs of 0.25 and 0.5, steps of half a leg (h ≤ 0.25, ω ≤ 2.75): ≤ 10 steps.
                10.0 * 10.0 * 0.3 * (2.75f64 * 0.25).powi(5) / 120.0
            };
            assert!(gap < bound, "{integrator:?}: {gap:e} off the closed form (bound {bound:e})");
        }
    }

    /// Reinjection (ParaView's "Force Reinjection Every NSteps"): the seeds are injected again
    /// at every N-th output time; each injection's particles are lines of their own, in
    /// injection order, that follow the closed-form path from their injection time. The first
    /// injection's lines are those of a run without reinjection, bit for bit, and the batch
    /// driver gives the same lines.
    #[test]
    fn reinjected_particles_are_new_lines_from_their_injection_times() {
        let (m, steps) = spin_series(8, vec![0.0, 0.5, 1.0, 1.5, 2.0, 2.5]);
        let mut cpu = CpuLocator::new(m.clone());
        let fields = groups(&m);
        let seeds: Vec<Vec3> = vec![[0.8, 0.5, 0.3], [0.5, 0.2, 0.7], [0.65, 0.6, 0.5]];
        let once = PathOptions { step: Some(0.05), start_time: Some(0.25), ..Default::default() };
        let base = pathlines(job(&seeds, &once, &steps, &fields), &cpu, |_| Ok(())).unwrap();
        // Output times 0.25, 0.5, 1.0, 1.5, 2.0, 2.5: legs 0..5.
        for (every, starts) in [(1, vec![0.25, 0.5, 1.0, 1.5, 2.0]), (2, vec![0.25, 1.0, 2.0]), (4, vec![0.25, 2.0])] {
            let o = PathOptions { reinject_every: every, ..once.clone() };
            let a = pathlines(job(&seeds, &o, &steps, &fields), &cpu, |_| Ok(())).unwrap();
            assert_eq!(a.ends.len(), starts.len() * seeds.len(), "every {every}");
            let want_seeds: Vec<i32> = starts.iter().flat_map(|_| 0..seeds.len() as i32).collect();
            assert_eq!(a.seeds, want_seeds, "every {every}");
            assert_eq!(a.reasons, vec![Reason::OutOfTime as i32; a.ends.len()]);
            for (line, &t0) in starts.iter().flat_map(|t| std::iter::repeat_n(t, seeds.len())).enumerate() {
                let start = if line == 0 { 0 } else { a.ends[line - 1] };
                assert_eq!(a.time[start], t0, "every {every}, line {line}");
                assert_eq!(*a.time[..a.ends[line]].last().unwrap(), 2.5);
                let seed = seeds[line % seeds.len()].map(f64::from);
                let gap = miss(&a, line, seed, t0);
                // RK4 at 0.05 (ω ≤ 3.5): as the first test's bound over ≤ 45 steps.
                let bound = 45.0 * 10.0 * 0.3 * (3.5f64 * 0.05).powi(5) / 120.0 + 1e-6;
                assert!(gap < bound, "every {every}, line {line}: {gap:e} off (bound {bound:e})");
            }
            // The first injection is the run without reinjection.
            let n0 = base.ends[seeds.len() - 1];
            assert_eq!(
                (&a.ends[..seeds.len()], &a.points[..n0], &a.time[..n0]),
                (&base.ends[..], &base.points[..], &base.time[..])
            );
            for ((g, x), (_, y)) in a.fields.arrays.iter().zip(&base.fields.arrays) {
                assert_eq!(x[..n0 * g.n_components()], y[..], "{}", g.name);
            }
            let all = pathlines_batch(job(&seeds, &o, &steps, &fields), &mut cpu, &m, |_| Ok(())).unwrap();
            assert_eq!((&a.ends, &a.seeds, &a.reasons, &a.time), (&all.ends, &all.seeds, &all.reasons, &all.time));
            for (p, q) in a.points.iter().zip(&all.points) {
                assert!((0..3).all(|k| (p[k] - q[k]).abs() < 1e-5), "every {every}: {p:?} {q:?}");
            }
        }
    }

    /// Streaklines: per seed, its particles (injected at every output time) at the end time,
    /// oldest first and the seed itself last, aged; each point is the last point of that
    /// particle's pathline bit for bit, and on the closed form from its injection time.
    #[test]
    fn streaklines_join_each_seeds_particles_at_the_end_time() {
        let (m, steps) = spin_series(8, vec![0.0, 0.5, 1.0, 1.5, 2.0]);
        let mut cpu = CpuLocator::new(m.clone());
        let fields = groups(&m);
        let seeds: Vec<Vec3> = vec![[0.8, 0.5, 0.3], [0.5, 0.2, 0.7], [3.0, 0.5, 0.5], [0.65, 0.6, 0.5]];
        let o = PathOptions { step: Some(0.05), streaklines: true, ..Default::default() };
        let streaks = pathlines(job(&seeds, &o, &steps, &fields), &cpu, |_| Ok(())).unwrap();
        assert_eq!(streaks.time_name, "ParticleAge");
        // The seed outside makes none; the others a point an injection (0, 0.5, 1, 1.5, 2).
        assert_eq!(streaks.seeds, [0, 1, 3]);
        assert_eq!(streaks.ends, [5, 10, 15]);
        assert_eq!(streaks.time, [2.0, 1.5, 1.0, 0.5, 0.0].repeat(3));
        let paths = PathOptions { streaklines: false, reinject_every: 1, ..o.clone() };
        let paths = pathlines(job(&seeds, &paths, &steps, &fields), &cpu, |_| Ok(())).unwrap();
        let clock = &streaks.fields.arrays.iter().find(|(g, _)| g.name == "clock").unwrap().1;
        for (line, &seed) in [0usize, 1, 3].iter().enumerate() {
            for j in 0..5 {
                let at = 5 * line + j;
                let (age, p) = (streaks.time[at], streaks.points[at]);
                assert_eq!(clock[at], 2.0);
                if j == 4 {
                    assert_eq!(p, seeds[seed], "the newest particle is at its seed");
                    continue;
                }
                // Injection j's particle of this seed: its pathline's last point.
                let path = (0..paths.ends.len())
                    .find(|&i| {
                        let start = if i == 0 { 0 } else { paths.ends[i - 1] };
                        paths.seeds[i] == seed as i32 && paths.time[start] == 2.0 - age
                    })
                    .expect("the particle's pathline");
                assert_eq!(p, paths.points[paths.ends[path] - 1]);
                let gap = (0..3)
                    .map(|k| {
                        let t0 = 2.0 - age;
                        let theta = (2.0 - t0) + 0.5 * (4.0 - t0 * t0);
                        let (dx, dy) = (seeds[seed][0] as f64 - 0.5, seeds[seed][1] as f64 - 0.5);
                        let want = [
                            0.5 + theta.cos() * dx - theta.sin() * dy,
                            0.5 + theta.sin() * dx + theta.cos() * dy,
                            seeds[seed][2] as f64,
                        ];
                        (p[k] as f64 - want[k]).abs()
                    })
                    .fold(0.0, f64::max);
                assert!(gap < 1e-4, "seed {seed}, age {age}: {gap:e} off the closed form");
            }
        }
        let all = pathlines_batch(job(&seeds, &o, &steps, &fields), &mut cpu, &m, |_| Ok(())).unwrap();
        assert_eq!((&streaks.ends, &streaks.seeds, &streaks.time), (&all.ends, &all.seeds, &all.time));
        for (p, q) in streaks.points.iter().zip(&all.points) {
            assert!((0..3).all(|k| (p[k] - q[k]).abs() < 1e-5), "{p:?} {q:?}");
        }
    }

    /// Every output time's frame of a run is the run that ends there, bit for bit:
    /// pathlines (reinjected, with particles leaving the cube between output times, so some
    /// frames cut a line that goes on and some keep one that has stopped) and streaklines,
    /// on both drivers. The last frame is the run's output.
    #[test]
    fn each_frame_is_the_run_that_ends_at_its_time() {
        let (m, steps) = spin_series(6, vec![0.0, 0.5, 1.0, 1.5, 2.0, 2.5]);
        let mut cpu = CpuLocator::new(m.clone());
        let fields = groups(&m);
        let seeds = leaving_seeds(5);
        let paths = PathOptions { step: Some(0.05), start_time: Some(0.25), reinject_every: 2, ..Default::default() };
        let streaks = PathOptions { streaklines: true, reinject_every: 0, ..paths.clone() };
        let same = |a: &LineArrays, b: &LineArrays, what: &str| {
            assert_eq!((&a.ends, &a.seeds, &a.reasons), (&b.ends, &b.seeds, &b.reasons), "{what}");
            assert_eq!((&a.points, &a.time, a.time_name), (&b.points, &b.time, b.time_name), "{what}");
            assert_eq!(a.fields.ids, b.fields.ids, "{what}");
            assert_eq!(a.fields.arrays, b.fields.arrays, "{what}");
            assert_eq!(a.particles, b.particles, "{what}");
        };
        for (o, name) in [(&paths, "pathlines"), (&streaks, "streaklines")] {
            for batch in [false, true] {
                let mut run = |o: &PathOptions| match batch {
                    true => pathline_run_batch(job(&seeds, o, &steps, &fields), &mut cpu, &m, |_| Ok(())).unwrap(),
                    false => pathline_run(job(&seeds, o, &steps, &fields), &cpu, |_| Ok(())).unwrap(),
                };
                let whole = run(o);
                assert_eq!(whole.frame_times(), [0.5, 1.0, 1.5, 2.0, 2.5]);
                // Lines gone out of the mesh by each frame.
                let mut gone = Vec::new();
                for (k, t) in whole.frame_times().into_iter().enumerate() {
                    let what = format!("{name}, batch {batch}, frame {k} at {t}");
                    let frame = whole.frame(k);
                    same(&frame, &run(&PathOptions { end_time: Some(t), ..o.clone() }).output(), &what);
                    gone.push(frame.reasons.iter().filter(|&&r| r == Reason::OutOfDomain as i32).count());
                }
                let last = whole.frame(4);
                same(&last, &whole.output(), &format!("{name}, batch {batch}: the output"));
                if !o.streaklines {
                    // Lines cut at frame 0 (reason 7) that have left by frame 1, and frames
                    // before the last holding lines that have stopped.
                    assert!(gone[0] < gone[1], "{name}, batch {batch}: {gone:?} gone by each frame");
                }
            }
        }
    }

    /// Each point carries its particle as vtkParticlePathFilter numbers it: `ParticleId` its
    /// index among the particles its injection put inside the mesh (a seed outside takes
    /// none; it starts again at each injection), `InjectedPointId` its seed,
    /// `InjectionStepId` its injection's output time, `ParticleAge` the time since (f32);
    /// streaklines too, their time array being their age. On both drivers.
    #[test]
    fn particles_are_numbered_as_vtk_numbers_them() {
        let (m, steps) = spin_series(6, vec![0.0, 0.5, 1.0, 1.5, 2.0, 2.5]);
        let mut cpu = CpuLocator::new(m.clone());
        let fields = groups(&m);
        // The seed outside first: the others' ParticleIds are their seed's index less one.
        let mut seeds = leaving_seeds(3);
        seeds.rotate_right(1);
        let output_times = [0.25, 0.5, 1.0, 1.5, 2.0, 2.5];
        let paths = PathOptions { step: Some(0.05), start_time: Some(0.25), reinject_every: 2, ..Default::default() };
        let streaks = PathOptions { streaklines: true, reinject_every: 0, ..paths.clone() };
        for batch in [false, true] {
            let mut run = |o: &PathOptions| match batch {
                true => pathline_run_batch(job(&seeds, o, &steps, &fields), &mut cpu, &m, |_| Ok(())).unwrap(),
                false => pathline_run(job(&seeds, o, &steps, &fields), &cpu, |_| Ok(())).unwrap(),
            };
            let out = run(&paths).output();
            let p = out.particles.as_ref().unwrap();
            let age = p.age.as_ref().unwrap();
            let mut injections = std::collections::BTreeSet::new();
            for (line, &end) in out.ends.iter().enumerate() {
                let (seed, start) = (out.seeds[line], if line == 0 { 0 } else { out.ends[line - 1] });
                assert_ne!(seed, 0, "the seed outside makes no line");
                for i in start..end {
                    assert_eq!(p.particle_id[i], seed - 1, "batch {batch}, line {line}");
                    assert_eq!(p.injected_point_id[i], i64::from(seed));
                    assert_eq!(
                        output_times[p.injection_step_id[i] as usize], out.time[start],
                        "injected at its first time"
                    );
                    assert_eq!(age[i], (out.time[i] - out.time[start]) as f32);
                }
                injections.insert(p.injection_step_id[start]);
            }
            assert_eq!(
                injections.into_iter().collect::<Vec<_>>(),
                [0, 2, 4],
                "batch {batch}: every second output time"
            );
            let out = run(&streaks).output();
            assert_eq!(out.time_name, "ParticleAge");
            let p = out.particles.as_ref().unwrap();
            assert!(p.age.is_none(), "the time array is the age");
            for (line, &end) in out.ends.iter().enumerate() {
                let start = if line == 0 { 0 } else { out.ends[line - 1] };
                for i in start..end {
                    assert_eq!(
                        (p.particle_id[i], p.injected_point_id[i]),
                        (out.seeds[line] - 1, i64::from(out.seeds[line]))
                    );
                    let injected = output_times[p.injection_step_id[i] as usize];
                    assert!(
                        (injected + out.time[i] - 2.5).abs() < 1e-12,
                        "batch {batch}: injected {injected}, age {}",
                        out.time[i]
                    );
                }
            }
        }
    }

    /// The batch driver (one `locate` per stage) gives the per-particle driver's lines, up to
    /// the f32 barycentrics of the walk; particles leaving the mesh stop.
    #[test]
    fn batch_pathlines_match_particle_pathlines() {
        let (m, steps) = spin_series(6, vec![0.0, 0.5, 1.0, 1.5, 2.0, 2.5]);
        let mut cpu = CpuLocator::new(m.clone());
        let fields = groups(&m);
        let seeds = leaving_seeds(7);
        for integrator in [Integrator::Rk4, Integrator::Rk45] {
            let o = PathOptions { integrator, step: Some(0.05), max_error: 1e-7, ..Default::default() };
            let one = pathlines(job(&seeds, &o, &steps, &fields), &cpu, |_| Ok(())).unwrap();
            let mut legs = 0;
            let all = pathlines_batch(job(&seeds, &o, &steps, &fields), &mut cpu, &m, |n| {
                legs = n;
                Ok(())
            })
            .unwrap();
            assert_eq!(legs, 5);
            assert_eq!((&one.ends, &one.seeds, &one.reasons), (&all.ends, &all.seeds, &all.reasons), "{integrator:?}");
            // The corner seeds' circles leave the cube: those particles are gone (no line, or
            // a line ending with reason 1); the others reach the end time (7).
            assert!(one.reasons.contains(&7) && one.ends.len() < seeds.len() - 1, "{:?}", one.reasons);
            // Seeds on the axis do not move: stagnation (6), as VTK's terminal speed.
            assert!(
                one.reasons.iter().all(|&r| r == 7 || r == 6 || r == Reason::OutOfDomain as i32),
                "{:?}",
                one.reasons
            );
            assert!(one.reasons.contains(&6), "{:?}", one.reasons);
            assert!(!one.seeds.contains(&(seeds.len() as i32 - 1)), "the seed outside makes no line");
            for (a, b) in one.points.iter().zip(&all.points) {
                assert!((0..3).all(|k| (a[k] - b[k]).abs() < 1e-5), "{integrator:?}: {a:?} {b:?}");
            }
            assert_eq!(one.time, all.time);
        }
    }

    /// Pathlines' vorticity on the lifted spin, linear in space and time: at every recorded
    /// point (the start time between two steps included) the curl (0, -a, 2ω(t)), the angular
    /// velocity along the field there, the rotation the trapezoid sum of those from 0 at the
    /// injection; on both drivers, for pathlines and streaklines, and in each frame.
    #[test]
    fn pathline_vorticity_is_the_curl_in_time_and_its_integral() {
        let lift = 0.3;
        let (m, steps) = lifted_spin_series(6, vec![0.0, 0.5, 1.0, 1.5], lift);
        let mut cpu = CpuLocator::new(m.clone());
        let fields = groups(&m);
        let seeds: Vec<Vec3> = vec![[0.7, 0.5, 0.4], [0.5, 0.3, 0.45], [0.62, 0.6, 0.5], [0.5, 0.5, 0.5]];
        let check = |arrays: &LineArrays, what: &str| {
            let v = arrays.vorticity.as_ref().unwrap_or_else(|| panic!("{what}: no vorticity"));
            assert!(v.normals.is_none(), "{what}: pathlines have no normals");
            let n = arrays.points.len();
            assert!(n > 10 && v.vorticity.len() == n && v.rotation.len() == n && v.angular_velocity.len() == n);
            let mut start = 0;
            for &end in &arrays.ends {
                for i in start..end {
                    // (A streakline's times are its particles' ages at the end time.)
                    let t = if what == "streaklines" { 1.5 } else { arrays.time[i] };
                    let want = [0.0, -lift, 2.0 * omega(t)];
                    let w = v.vorticity[i];
                    assert!((0..3).all(|k| (w[k] - want[k]).abs() < 1e-9), "{what} point {i} at {t}: {w:?}");
                    let u = spin_at(arrays.points[i].map(f64::from), omega(t), lift);
                    // (0 where the flow stops: the seed on the axis.)
                    let along = if norm(u) == 0.0 { 0.0 } else { (want[1] * u[1] + want[2] * u[2]) / norm(u) };
                    assert!((v.angular_velocity[i] - along).abs() < 1e-6, "{what} point {i}");
                    if what == "streaklines" {
                        continue;
                    }
                    if i == start {
                        assert_eq!(v.rotation[i], 0.0, "{what}: a line starts unturned");
                    } else {
                        let dt = t - arrays.time[i - 1];
                        let step = (v.angular_velocity[i - 1] + v.angular_velocity[i]) / 2.0 * dt;
                        assert!((v.rotation[i] - v.rotation[i - 1] - step).abs() < 1e-12, "{what} point {i}");
                    }
                }
                start = end;
            }
            assert!(v.rotation.iter().any(|r| r.abs() > 0.01), "{what}: nothing turned");
        };
        let o = PathOptions { vorticity: true, start_time: Some(0.25), step: Some(0.05), ..Default::default() };
        let run = pathline_run(job(&seeds, &o, &steps, &fields), &cpu, |_| Ok(())).unwrap();
        check(&run.frame(1), "a frame");
        check(&run.output(), "pathlines");
        check(&pathlines_batch(job(&seeds, &o, &steps, &fields), &mut cpu, &m, |_| Ok(())).unwrap(), "batch");
        let streak = PathOptions { streaklines: true, ..o.clone() };
        let lines = pathlines(job(&seeds, &streak, &steps, &fields), &cpu, |_| Ok(())).unwrap();
        check(&lines, "streaklines");
        // A streakline's points are its particles' at the end time, each turned since its
        // own injection: the oldest turned most.
        let v = lines.vorticity.as_ref().unwrap();
        assert!(v.rotation[0].abs() > v.rotation[lines.ends[0] - 1].abs());
        assert_eq!(v.rotation[lines.ends[0] - 1], 0.0);
        let plain = PathOptions { vorticity: false, ..o };
        assert!(pathlines(job(&seeds, &plain, &steps, &fields), &cpu, |_| Ok(())).unwrap().vorticity.is_none());
    }

    /// The lifted spin's series on an n³ grid of hexahedra over the unit cube, the inner
    /// vertices jittered (trilinear cells with curved faces, which still reproduce a linear
    /// field exactly), with a cell field `id` (each cell's index).
    fn hex_spin_series(n: usize, times: Vec<f64>, lift: f64) -> (Arc<Mesh>, TimeSteps) {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let at = |i: usize, j: usize, k: usize| ((k * (n + 1) + j) * (n + 1) + i) as u32;
        let mut points = Vec::new();
        for k in 0..=n {
            for j in 0..=n {
                for i in 0..=n {
                    let inner = |c: usize| c > 0 && c < n;
                    let jitter = |c: usize, rng: &mut rand_pcg::Pcg64| match inner(c) {
                        true => rng.gen_range(-0.2..0.2) / n as f64,
                        false => 0.0,
                    };
                    let (a, b, c) = (jitter(i, &mut rng), jitter(j, &mut rng), jitter(k, &mut rng));
                    points.push([
                        (i as f64 / n as f64 + a) as f32,
                        (j as f64 / n as f64 + b) as f32,
                        (k as f64 / n as f64 + c) as f32,
                    ]);
                }
            }
        }
        let hex = crate::cell::CellType::from_vtk(12, 8).unwrap();
        let mut block = crate::cell::CellBlock::default();
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    block.conn.extend([
                        at(i, j, k),
                        at(i + 1, j, k),
                        at(i + 1, j + 1, k),
                        at(i, j + 1, k),
                        at(i, j, k + 1),
                        at(i + 1, j, k + 1),
                        at(i + 1, j + 1, k + 1),
                        at(i, j + 1, k + 1),
                    ]);
                    block.types.push(hex);
                    block.ends.push(block.conn.len() as u64);
                }
            }
        }
        let n_cells = block.len();
        let pts64: Vec<[f64; 3]> = points.iter().map(|p| p.map(f64::from)).collect();
        let spin = Spin { points: pts64, times: times.clone(), lift };
        let mut fields = spin.read(0).unwrap();
        fields.push(Field::new("id", FieldLocation::Cell, (0..n_cells).map(|c| c as f32).collect()));
        let raw = crate::RawMesh { points, cells: Some(block), fields, ..Default::default() };
        let mesh = Arc::new(Mesh::new(raw, "hexes").unwrap());
        (mesh, TimeSteps::new("hexes.pvd", times, Box::new(HexSpin { spin, n_cells })))
    }

    /// [`Spin`]'s steps with the hex grid's cell field.
    struct HexSpin {
        spin: Spin,
        n_cells: usize,
    }

    impl StepFields for HexSpin {
        fn read(&self, k: usize) -> Result<Vec<Field>> {
            let mut fields = self.spin.read(k)?;
            fields.push(Field::new("id", FieldLocation::Cell, (0..self.n_cells).map(|c| c as f32).collect()));
            Ok(fields)
        }
    }

    /// Pathlines through a mesh of hexahedra, by its cell locator (each answer a cell,
    /// interpolated with its trilinear shape functions): the spin's closed-form path, the
    /// vector recorded as the field there, the cell field that of the cell each point is in,
    /// and the lifted spin's vorticity; the per-particle walk refuses the mesh, naming it.
    #[test]
    fn pathlines_through_hexahedra_follow_the_closed_form() {
        let (m, steps) = hex_spin_series(6, vec![0.0, 0.5, 1.0, 1.5, 2.0], 0.0);
        let fields = groups(&m);
        let mut loc = crate::locate::CellLocator::new(CpuLocator::new(m.clone()), m.clone());
        let seeds: Vec<Vec3> = vec![[0.8, 0.5, 0.3], [0.5, 0.2, 0.7], [0.65, 0.6, 0.5]];
        let o = PathOptions { step: Some(0.05), ..Default::default() };
        let lines = pathlines_batch(job(&seeds, &o, &steps, &fields), &mut loc, &m, |_| Ok(())).unwrap();
        assert_eq!(lines.ends, [5, 10, 15]);
        for (line, seed) in seeds.iter().enumerate() {
            let worst = miss(&lines, line, seed.map(f64::from), 0.0);
            assert!(worst < 1e-4, "line {line}: {worst:e} from the closed form");
        }
        let value = |name: &str| &lines.fields.arrays.iter().find(|(g, _)| g.name == name).unwrap().1;
        let (v, ids) = (value("v"), &lines.fields.ids);
        for (i, p) in lines.points.iter().enumerate() {
            let want = spin_at(p.map(f64::from), omega(lines.time[i]), 0.0);
            assert!((0..3).all(|k| (f64::from(v[3 * i + k]) - want[k]).abs() < 1e-5), "point {i}");
            // The cell answered holds the point (its `id` is the cell's index).
            assert_eq!(value("id")[i], ids[i] as f32, "point {i}");
            assert!(ids[i] >= 0 && (ids[i] as usize) < m.cells.as_ref().unwrap().len());
        }
        let lift = 0.3;
        let (m, steps) = hex_spin_series(6, vec![0.0, 0.5, 1.0], lift);
        let mut loc = crate::locate::CellLocator::new(CpuLocator::new(m.clone()), m.clone());
        let o = PathOptions { step: Some(0.05), vorticity: true, ..Default::default() };
        let lines = pathlines_batch(job(&seeds, &o, &steps, &groups(&m)), &mut loc, &m, |_| Ok(())).unwrap();
        let turning = lines.vorticity.as_ref().unwrap();
        for (i, w) in turning.vorticity.iter().enumerate() {
            let want = [0.0, -lift, 2.0 * omega(lines.time[i])];
            assert!((0..3).all(|k| (w[k] - want[k]).abs() < 1e-9), "point {i}: {w:?}");
        }
        let e = pathline_run(job(&seeds, &o, &steps, &groups(&m)), &CpuLocator::new(m.clone()), |_| Ok(()));
        assert!(e.is_err_and(|e| e.to_string().contains("hexes")));
    }

    /// The velocity from the vector a vertex at a time is the per-field path's, bit for bit,
    /// at the steps, between them and at the bracket's ends.
    #[test]
    fn vertex_vectors_give_the_fields_velocity_bit_for_bit() {
        let (m, steps) = spin_series(6, vec![0.0, 0.5, 1.0]);
        let names = XYZ.iter().map(|s| s.to_string()).collect();
        let mut reader = StepReader::new(&steps, names);
        let fast = reader.bracket(&m, 0).unwrap();
        assert!(fast.vectors.iter().all(Option::is_some), "per-vertex components are interleaved");
        let slow = Bracket { times: fast.times, steps: fast.steps, fields: fast.fields.clone(), vectors: [None, None] };
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let mut moving = 0;
        for tet in (0..m.n_tets()).step_by(7) {
            let raw: [f64; 4] = std::array::from_fn(|_| rng.gen_range(0.0..1.0));
            let sum: f64 = raw.iter().sum();
            let bary = raw.map(|r| r / sum);
            for t in [0.0, rng.gen_range(0.0..0.5), 0.25, 0.5] {
                let spot = Spot::Tet(tet, bary);
                let (a, b) = (fast.velocity(&m, spot, t), slow.velocity(&m, spot, t));
                assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "tet {tet}, t {t}");
                moving += (a != [0.0; 3]) as usize;
            }
        }
        assert!(moving > 0, "some velocity is not zero");
    }

    /// Steps that count their reads (in a count the test keeps), one of them failing.
    struct Counted {
        spin: Spin,
        reads: Arc<Vec<std::sync::atomic::AtomicUsize>>,
        fail: Option<usize>,
    }
    impl StepFields for Counted {
        fn read(&self, k: usize) -> Result<Vec<Field>> {
            self.reads[k].fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            if self.fail == Some(k) {
                return Err(Error::Invalid(format!("step {k} is torn")));
            }
            self.spin.read(k)
        }
    }

    /// Each step is read once (the next leg's step read ahead while a leg is traced), only the
    /// steps the legs need, by both drivers; a step that cannot be read is the run's error,
    /// whether it was read ahead or not.
    #[test]
    fn steps_are_read_once_ahead_and_their_errors_kept() {
        let times = vec![0.0, 0.5, 1.0, 1.5, 2.0, 2.5];
        let (m, _) = spin_series(4, times.clone());
        let points: Vec<[f64; 3]> = m.points.iter().map(|p| p.map(f64::from)).collect();
        // The series, and its count of reads a step.
        let series = |fail: Option<usize>| {
            let reads: Arc<Vec<std::sync::atomic::AtomicUsize>> =
                Arc::new((0..times.len()).map(|_| Default::default()).collect());
            let spin = Spin { points: points.clone(), times: times.clone(), lift: 0.0 };
            let steps =
                TimeSteps::new("spin.pvd", times.clone(), Box::new(Counted { spin, reads: reads.clone(), fail }));
            (steps, reads)
        };
        let reads = |c: &[std::sync::atomic::AtomicUsize]| {
            c.iter().map(|r| r.load(std::sync::atomic::Ordering::Relaxed)).collect::<Vec<_>>()
        };
        let mut cpu = CpuLocator::new(m.clone());
        let fields = groups(&m);
        let seeds: Vec<Vec3> = vec![[0.6, 0.5, 0.5], [0.5, 0.3, 0.2]];
        let within = PathOptions { start_time: Some(0.25), end_time: Some(1.75), ..Default::default() };
        for (o, want) in [(PathOptions::default(), [1, 1, 1, 1, 1, 1]), (within, [1, 1, 1, 1, 1, 0])] {
            for batch in [false, true] {
                let (steps, c) = series(None);
                let j = job(&seeds, &o, &steps, &fields);
                let a =
                    if batch { pathlines_batch(j, &mut cpu, &m, |_| Ok(())) } else { pathlines(j, &cpu, |_| Ok(())) };
                assert_eq!(a.unwrap().ends.len(), 2);
                assert_eq!(reads(&c), want, "batch {batch}, {o:?}");
            }
        }
        // Step 0 and 1 read together, 3 read ahead during the leg of bracket 1.
        for (fail, batch) in [(1, false), (3, false), (3, true), (5, true)] {
            let (steps, _) = series(Some(fail));
            let o = PathOptions::default();
            let j = job(&seeds, &o, &steps, &fields);
            let mut legs = 0;
            let progress = |n| {
                legs = n;
                Ok(())
            };
            let e = match batch {
                true => pathlines_batch(j, &mut cpu, &m, progress),
                false => pathlines(j, &cpu, progress),
            };
            let e = e.err().expect("a torn step fails the run").to_string();
            assert!(e.contains(&format!("step {fail} is torn")), "{e}");
            // The legs before the one that needs the step were traced.
            assert_eq!(legs, fail - 1, "step {fail}, batch {batch}");
        }
    }

    /// A run whose particles and their points cannot fit is refused before any step is
    /// read, by both drivers: 200k seeds injected again at every one of 2,000 output times
    /// would record 4e11 points (tens of TB). The run held every track to the end unchecked,
    /// so it read and traced until an allocation failed (an abort).
    #[cfg(target_os = "linux")]
    #[test]
    fn runs_beyond_memory_are_refused_before_any_step_is_read() {
        let times: Vec<f64> = (0..2001).map(f64::from).collect();
        let (m, _) = spin_series(2, times.clone());
        let points: Vec<[f64; 3]> = m.points.iter().map(|p| p.map(f64::from)).collect();
        let reads: Arc<Vec<std::sync::atomic::AtomicUsize>> =
            Arc::new((0..times.len()).map(|_| Default::default()).collect());
        let spin = Spin { points, times: times.clone(), lift: 0.0 };
        let steps = TimeSteps::new("spin.pvd", times, Box::new(Counted { spin, reads: reads.clone(), fail: None }));
        let seeds = vec![[0.6f32, 0.5, 0.5]; 200_000];
        let o = PathOptions { reinject_every: 1, ..Default::default() };
        let fields = groups(&m);
        let mut cpu = CpuLocator::new(m.clone());
        for batch in [false, true] {
            let j = job(&seeds, &o, &steps, &fields);
            let e = match batch {
                true => pathlines_batch(j, &mut cpu, &m, |_| Ok(())),
                false => pathlines(j, &cpu, |_| Ok(())),
            };
            let e = e.err().expect("refused");
            assert!(matches!(e, Error::OutOfMemory { .. }), "{e}");
            let e = e.to_string();
            assert!(e.contains("400000000 particles over 2000 output times") && e.contains("GB of memory"), "{e}");
        }
        assert!(reads.iter().all(|r| r.load(std::sync::atomic::Ordering::Relaxed) == 0));
    }

    /// A single snapshot, and times outside the series, are refused naming the file.
    #[test]
    fn bad_times_are_refused_naming_the_file() {
        let o = PathOptions::default();
        let e = o.legs("one.vtu", &[0.0]).unwrap_err().to_string();
        assert!(e.contains("one.vtu has 1 time step") && e.contains("at least two"), "{e}");
        let times = [0.0, 1.0, 2.0];
        for (start, end, want) in [
            (Some(-1.0), None, "the start time -1 is outside the time steps of s.pvd (0 to 2)"),
            (None, Some(2.5), "the end time 2.5 is outside"),
            (Some(1.5), Some(0.5), "must come after the start time"),
            (Some(f64::NAN), None, "outside"),
        ] {
            let o = PathOptions { start_time: start, end_time: end, ..Default::default() };
            let e = o.legs("s.pvd", &times).unwrap_err().to_string();
            assert!(e.contains(want) && e.contains("s.pvd"), "{e}");
        }
        let o = PathOptions { start_time: Some(0.5), ..Default::default() };
        let legs = o.legs("s.pvd", &times).unwrap();
        assert_eq!(legs, [Leg { from: 0.5, to: 1.0, bracket: 0 }, Leg { from: 1.0, to: 2.0, bracket: 1 }]);
        assert!(PathOptions { step: Some(0.0), ..Default::default() }.check().is_err());
        // Steps too small to finish (or to move the time at all) are refused up front: a
        // particle has no step limit but the end time.
        for (step, integrator, start) in [
            (Some(1e-12), Integrator::Rk4, None),
            (Some(1e-300), Integrator::Rk4, None),
            (Some(1e-9), Integrator::Rk45, None),
            (Some(1e-6), Integrator::Rk4, Some(1.5)),
        ] {
            let times = [0.0, 1.0, 2e9];
            let o = PathOptions { step, integrator, start_time: start, ..Default::default() };
            let e = o.legs("s.pvd", &times).unwrap_err().to_string();
            assert!(e.contains("too small") && e.contains("use a larger step"), "{step:?}: {e}");
        }
        let o = PathOptions { step: Some(1e-6), ..Default::default() };
        assert!(o.legs("s.pvd", &times).is_ok(), "2e6 steps a particle is a run");
    }
}
