//! One streamline as a state machine: the particle says which point it needs the velocity at
//! next ([`Particle::query`]) and is told the answer ([`Particle::answer`]). Both drivers
//! use it: the CPU one answers each query at once from the particle's last tet, the batch one
//! answers the queries of every live particle with one `sample_many` per Runge–Kutta stage.
//! So the arithmetic of a step (f64, VTK's order of operations) has one definition.
//!
//! The loop is vtkStreamTracer's (see the module above), the adaptive step vtkRungeKutta45's
//! `ComputeNextStep`: a step whose error estimate exceeds the maximum error is retried with
//! `0.9 h (err/max)^-1/4`; an accepted step proposes `0.9 h (err/max)^-1/5` for the next one;
//! a proposal beyond the minimum or maximum step is clamped there and that step is taken
//! whatever its error; a step at the minimum is taken whatever its error. (One difference:
//! a step without any error grows to the maximum, where VTK sets the minimum.)

use super::{Integrator, Reason, TraceOptions};
use crate::geom::Vec3;

/// An explicit Runge–Kutta method: stage `i` (from 1) samples at `x + h Σ_j a[i-1][j] k_j`,
/// the step ends at `x + h Σ_j b_j k_j`, and `h Σ_j e_j k_j` estimates its error (no `e`:
/// a fixed step). `fsal`: the last stage samples at the step's end (Dormand–Prince), whose
/// velocity then needs no lookup of its own.
pub(super) struct Tableau {
    pub(super) a: &'static [&'static [f64]],
    pub(super) b: &'static [f64],
    pub(super) e: &'static [f64],
    pub(super) fsal: bool,
}

/// vtkRungeKutta4.
const RK4: Tableau = Tableau {
    a: &[&[0.5], &[0.0, 0.5], &[0.0, 0.0, 1.0]],
    b: &[1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0],
    e: &[],
    fsal: false,
};

/// Dormand–Prince 5(4): the fifth-order solution, the embedded fourth-order one for the error.
const DORMAND_PRINCE: Tableau = Tableau {
    a: &[
        &[1.0 / 5.0],
        &[3.0 / 40.0, 9.0 / 40.0],
        &[44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0],
        &[19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0],
        &[9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0],
        &[35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0],
    ],
    b: &[35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0, 0.0],
    e: &[71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0, 22.0 / 525.0, -1.0 / 40.0],
    fsal: true,
};

/// Cash–Karp 5(4), the tableau of vtkRungeKutta45 (VTK's "RK45").
const CASH_KARP: Tableau = Tableau {
    a: &[
        &[1.0 / 5.0],
        &[3.0 / 40.0, 9.0 / 40.0],
        &[3.0 / 10.0, -9.0 / 10.0, 6.0 / 5.0],
        &[-11.0 / 54.0, 5.0 / 2.0, -70.0 / 27.0, 35.0 / 27.0],
        &[1631.0 / 55296.0, 175.0 / 512.0, 575.0 / 13824.0, 44275.0 / 110592.0, 253.0 / 4096.0],
    ],
    b: &[37.0 / 378.0, 0.0, 250.0 / 621.0, 125.0 / 594.0, 0.0, 512.0 / 1771.0],
    e: &[
        37.0 / 378.0 - 2825.0 / 27648.0,
        0.0,
        250.0 / 621.0 - 18575.0 / 48384.0,
        125.0 / 594.0 - 13525.0 / 55296.0,
        -277.0 / 14336.0,
        512.0 / 1771.0 - 1.0 / 4.0,
    ],
    fsal: false,
};

impl Integrator {
    pub(super) fn tableau(self) -> &'static Tableau {
        match self {
            Integrator::Rk4 => &RK4,
            Integrator::Rk45 => &DORMAND_PRINCE,
            Integrator::CashKarp => &CASH_KARP,
        }
    }
}

pub(super) const MAX_STAGES: usize = 7;

pub(super) fn norm(v: [f64; 3]) -> f64 {
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

/// `x + h Σ_j w_j k_j`.
pub(super) fn combine(x: [f64; 3], h: f64, w: &[f64], k: &[[f64; 3]]) -> [f64; 3] {
    std::array::from_fn(|i| x[i] + h * w.iter().zip(k).map(|(w, k)| w * k[i]).sum::<f64>())
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum State {
    /// The velocity at the seed.
    Seed,
    /// The velocity at stage `i` (from 1) of the step being tried.
    Stage(usize),
    /// The (raw) velocity at the end of the accepted step.
    End,
    Done(Reason),
}

/// One line being traced.
#[derive(Clone, Debug)]
pub struct Particle {
    pub seed: u32,
    pub backward: bool,
    sign: f64,
    x: [f64; 3],
    /// The speed at `x` (the time of a step is its length over it).
    speed: f64,
    t: f64,
    length: f64,
    steps: usize,
    /// The signed step the next step starts from (vtkStreamTracer's `stepSize.Interval`).
    h: f64,
    /// The step being tried, and whether it is taken whatever its error (a fixed-step method,
    /// a step shortened onto the length or time limit, a step clamped to the minimum or
    /// maximum).
    trial: f64,
    take: bool,
    /// The limit this step was shortened onto.
    limit: Option<Reason>,
    /// Stage slopes: the unit field at each stage point (k[0] at `x`).
    k: [[f64; 3]; MAX_STAGES],
    /// The point whose velocity is asked for, and the raw velocity of the last stage (FSAL).
    at: [f64; 3],
    last: [f64; 3],
    points: Vec<[f64; 3]>,
    time: Vec<f64>,
    state: State,
}

impl Particle {
    pub fn new(seed: u32, point: Vec3, backward: bool) -> Particle {
        let x = point.map(f64::from);
        Particle {
            seed,
            backward,
            sign: if backward { -1.0 } else { 1.0 },
            x,
            speed: 0.0,
            t: 0.0,
            length: 0.0,
            steps: 0,
            h: 0.0,
            trial: 0.0,
            take: false,
            limit: None,
            k: [[0.0; 3]; MAX_STAGES],
            at: x,
            last: [0.0; 3],
            points: Vec::new(),
            time: Vec::new(),
            state: State::Seed,
        }
    }

    /// The point whose velocity the particle needs next (as the locators take it: f32), or
    /// `None` when its line is finished.
    #[inline]
    pub fn query(&self) -> Option<Vec3> {
        match self.state {
            State::Done(_) => None,
            _ => Some(self.at.map(|c| c as f32)),
        }
    }

    /// Room for `n` points, taken at once: a line that grew by doubling copied its points
    /// each time, into fresh pages.
    pub fn reserve(&mut self, n: usize) {
        self.points.reserve_exact(n);
        self.time.reserve_exact(n);
    }

    /// Points recorded so far (the seed, then each step's end).
    pub fn n_points(&self) -> usize {
        self.points.len()
    }

    pub fn is_done(&self) -> bool {
        matches!(self.state, State::Done(_))
    }

    /// The velocity at [`Self::query`]'s point (`None`: outside the mesh).
    pub fn answer(&mut self, v: Option<[f32; 3]>, o: &TraceOptions) {
        let v = v.map(|v| v.map(f64::from));
        match (self.state, v) {
            (State::Done(_), _) => {}
            (_, None) => self.state = State::Done(Reason::OutOfDomain),
            (State::Seed, Some(v)) => {
                self.points.push(self.x);
                self.time.push(0.0);
                self.h = self.sign * o.step;
                self.arrive(v, o);
            }
            (State::Stage(i), Some(v)) => {
                self.k[i] = normalized(v);
                self.last = v;
                self.stage(i + 1, o);
            }
            (State::End, Some(v)) => {
                self.points.push(self.x);
                self.time.push(self.t);
                self.arrive(v, o);
            }
        }
    }

    /// The line, when it has more than its seed (VTK makes none otherwise).
    pub fn finish(self) -> Option<super::Line> {
        let State::Done(reason) = self.state else { return None };
        let (mut points, mut time) = (self.points, self.time);
        points.shrink_to_fit();
        time.shrink_to_fit();
        (points.len() > 1).then_some(super::Line {
            seed: self.seed,
            backward: self.backward,
            points,
            time,
            tets: Vec::new(),
            values: Vec::new(),
            reason,
        })
    }

    /// At a new point `x` (already recorded) with raw velocity `v`: the speed, the next step's
    /// bounds, and the next step. After a step (not at the seed) VTK checks the speed first,
    /// and brings the proposed step within the bounds.
    fn arrive(&mut self, v: [f64; 3], o: &TraceOptions) {
        self.speed = norm(v);
        self.k[0] = normalized(v);
        let after_step = self.points.len() > 1;
        if after_step && (self.speed == 0.0 || self.speed <= o.terminal_speed) {
            self.state = State::Done(Reason::Stagnation);
            return;
        }
        if after_step && o.integrator.is_adaptive() {
            let (min, max) = (o.min_step(), o.max_step());
            if self.h.abs() < min {
                self.h = self.sign * min;
            } else if self.h.abs() > max {
                self.h = self.sign * max;
            }
        }
        self.begin_step(o);
    }

    /// The top of vtkStreamTracer's loop: the limits, then the first stage of the next step.
    fn begin_step(&mut self, o: &TraceOptions) {
        let reason = if self.length >= o.max_length {
            Some(Reason::OutOfLength)
        } else if self.t.abs() >= o.max_time {
            Some(Reason::OutOfTime)
        } else if self.steps > o.max_steps {
            Some(Reason::OutOfSteps)
        } else if self.speed == 0.0 || self.speed <= o.terminal_speed {
            Some(Reason::Stagnation)
        } else {
            None
        };
        if let Some(r) = reason {
            self.state = State::Done(r);
            return;
        }
        self.steps += 1;
        self.trial = self.h;
        self.take = !o.integrator.is_adaptive();
        self.limit = None;
        // A step that would pass the length or the time limit is shortened to land on it.
        if self.length + self.trial.abs() > o.max_length {
            self.trial = self.sign * (o.max_length - self.length);
            (self.take, self.limit) = (true, Some(Reason::OutOfLength));
        }
        if self.t.abs() + self.trial.abs() / self.speed > o.max_time {
            self.trial = self.sign * (o.max_time - self.t.abs()) * self.speed;
            (self.take, self.limit) = (true, Some(Reason::OutOfTime));
        }
        self.stage(1, o);
    }

    /// Asks for stage `i` of the step being tried, or ends the trial after the last stage.
    fn stage(&mut self, i: usize, o: &TraceOptions) {
        let tab = o.integrator.tableau();
        if i <= tab.a.len() {
            self.at = combine(self.x, self.trial, tab.a[i - 1], &self.k[..i]);
            self.state = State::Stage(i);
        } else {
            self.end_trial(tab, o);
        }
    }

    /// All stages known: accept the step, or retry it with a smaller one (vtkRungeKutta45).
    fn end_trial(&mut self, tab: &Tableau, o: &TraceOptions) {
        let stages = tab.b.len();
        let next = if tab.fsal { self.at } else { combine(self.x, self.trial, tab.b, &self.k[..stages]) };
        // vtkRungeKutta45: a step that does not move is an unexpected value.
        if o.integrator.is_adaptive() && next == self.x {
            self.state = State::Done(Reason::UnexpectedValue);
            return;
        }
        if self.take {
            return self.accept(next, self.trial, self.h, tab, o);
        }
        let (min, max) = (o.min_step(), o.max_step());
        if self.trial.abs() == min {
            return self.accept(next, self.trial, self.trial, tab, o);
        }
        let slope = combine([0.0; 3], self.trial, tab.e, &self.k[..stages]);
        let ratio = norm(slope) / o.max_error;
        // An exact step (no error at all) grows to the maximum; VTK sets the minimum there
        // ("arbitrarily"), which would crawl through a uniform flow.
        let proposal = if ratio == 0.0 {
            self.sign * f64::INFINITY
        } else if ratio > 1.0 {
            0.9 * self.trial * ratio.powf(-0.25)
        } else {
            0.9 * self.trial * ratio.powf(-0.2)
        };
        if proposal.abs() > max || proposal.abs() < min {
            // Once more with the bound, taken whatever its error.
            self.trial = self.sign * proposal.abs().clamp(min, max);
            self.take = true;
            self.h = self.trial;
            return self.stage(1, o);
        }
        if ratio > 1.0 {
            self.trial = proposal;
            return self.stage(1, o);
        }
        self.accept(next, self.trial, proposal, tab, o)
    }

    /// Takes the step `taken` to `next`; `h` is where the next step starts.
    fn accept(&mut self, next: [f64; 3], taken: f64, h: f64, tab: &Tableau, o: &TraceOptions) {
        let moved = norm(std::array::from_fn(|i| next[i] - self.x[i]));
        if taken == 0.0 || moved / taken.abs() <= o.terminal_speed {
            self.state = State::Done(Reason::Stagnation);
            return;
        }
        self.t += taken / self.speed;
        self.length += taken.abs();
        // Landed on a limit: exactly on it, so the loop ends there.
        match self.limit {
            Some(Reason::OutOfLength) => self.length = o.max_length,
            Some(Reason::OutOfTime) => self.t = self.sign * o.max_time,
            _ => {}
        }
        self.x = next;
        self.h = h;
        if tab.fsal {
            // The last stage sampled here: its velocity is the end point's.
            self.points.push(self.x);
            self.time.push(self.t);
            let v = self.last;
            self.arrive(v, o);
        } else {
            self.at = next;
            self.state = State::End;
        }
    }
}
