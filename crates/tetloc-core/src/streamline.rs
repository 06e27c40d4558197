//! What a streamline is and the options that make one: the vocabulary that `ops::trace` and
//! a backend's own tracer ([`crate::locate::LineTracer`]) share. It sits below both, so that
//! the locators' tracer capability names it without reaching up into the operations.

use crate::error::{Error, Result};
use std::ops::Range;

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
    /// The integration time reached `max_time` (VTK has no such limit; 7 is the first code
    /// it leaves to custom termination criteria).
    OutOfTime = 7,
}

crate::named! {
    /// How a step is computed.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub enum Integrator: "integrator" {
        /// Classical Runge–Kutta with a fixed step (vtkRungeKutta4).
        Rk4 => "rk4",
        /// Dormand–Prince 5(4) with vtkRungeKutta45's step control.
        Rk45 => "rk45",
        /// Cash–Karp 5(4), VTK's vtkRungeKutta45 itself.
        CashKarp => "cash-karp",
    }
}

impl Integrator {
    pub fn is_adaptive(self) -> bool {
        self != Integrator::Rk4
    }
}

crate::named! {
    /// Which way lines go from their seeds. `Both` gives two lines per seed: all the forward
    /// lines, then all the backward ones (VTK's order).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub enum Direction: "direction" {
        Forward => "forward",
        Backward => "backward",
        Both => "both",
    }
}

#[derive(Clone, Debug)]
pub struct TraceOptions {
    /// Arc length of one step (mesh units), > 0; the first step of an adaptive integrator.
    pub step: f64,
    /// Steps per line (VTK takes one more before it stops with OUT_OF_STEPS).
    pub max_steps: usize,
    /// Longest line (VTK's MaximumPropagation).
    pub max_length: f64,
    /// Longest integration time (|time| of backward lines).
    pub max_time: f64,
    /// Speeds at or below this stop a line (STAGNATION).
    pub terminal_speed: f64,
    pub direction: Direction,
    pub integrator: Integrator,
    /// Adaptive integrators: the largest error estimate of a step (mesh units) and the step
    /// bounds; by default `step` / 50 and 2 `step` (VTK's 0.01 and 1 around its 0.5).
    pub max_error: f64,
    pub min_step: Option<f64>,
    pub max_step: Option<f64>,
}

impl Default for TraceOptions {
    fn default() -> Self {
        TraceOptions {
            step: 0.01,
            max_steps: 2000,
            max_length: f64::INFINITY,
            max_time: f64::INFINITY,
            terminal_speed: 1e-12,
            direction: Direction::Forward,
            integrator: Integrator::Rk4,
            max_error: 1e-6,
            min_step: None,
            max_step: None,
        }
    }
}

impl TraceOptions {
    pub fn min_step(&self) -> f64 {
        self.min_step.unwrap_or(self.step / 50.0)
    }

    pub fn max_step(&self) -> f64 {
        self.max_step.unwrap_or(2.0 * self.step)
    }

    pub fn check(&self) -> Result<()> {
        let positive = |x: f64| x.is_finite() && x > 0.0;
        if !positive(self.step) {
            return Err(Error::Invalid(format!("the step must be a positive length, got {}", self.step)));
        }
        if self.max_length.is_nan() || self.max_length <= 0.0 {
            return Err(Error::Invalid(format!("the maximum length must be positive, got {}", self.max_length)));
        }
        if self.max_time.is_nan() || self.max_time <= 0.0 {
            return Err(Error::Invalid(format!("the maximum time must be positive, got {}", self.max_time)));
        }
        if self.terminal_speed.is_nan() || self.terminal_speed < 0.0 {
            return Err(Error::Invalid(format!("the terminal speed must be 0 or more, got {}", self.terminal_speed)));
        }
        if self.integrator.is_adaptive() {
            let (min, max) = (self.min_step(), self.max_step());
            if !(positive(min) && positive(max) && min <= max) {
                return Err(Error::Invalid(format!(
                    "the step bounds must be positive lengths with min <= max, got min {min}, max {max}"
                )));
            }
            if !positive(self.max_error) {
                return Err(Error::Invalid(format!("the maximum error must be positive, got {}", self.max_error)));
            }
        }
        Ok(())
    }

    /// An error when the step (or, adaptive, the smallest step) is too short to move a
    /// particle at coordinates up to `largest_coordinate` in magnitude: f64 cannot tell such
    /// a step from none, and every line would stop where it starts.
    pub fn check_scale(&self, largest_coordinate: f64) -> Result<()> {
        let resolution = 4.0 * f64::EPSILON * largest_coordinate.abs();
        let smallest = if self.integrator.is_adaptive() { self.min_step().min(self.step) } else { self.step };
        if smallest < resolution {
            return Err(Error::Invalid(format!(
                "the step {smallest:e} is too small: at coordinates up to {largest_coordinate:e}, f64 cannot \
                 move a point by less than about {resolution:.1e}; use a larger step"
            )));
        }
        Ok(())
    }

    /// The lines to trace, in VTK's order: (seed, backward) — with `Both`, every forward line
    /// and then every backward one.
    pub fn jobs(&self, n_seeds: usize) -> Vec<(u32, bool)> {
        let dirs: &[bool] = match self.direction {
            Direction::Forward => &[false],
            Direction::Backward => &[true],
            Direction::Both => &[false, true],
        };
        dirs.iter().flat_map(|&b| (0..n_seeds as u32).map(move |s| (s, b))).collect()
    }
}

/// Points a batch of [`TraceOptions::batches`] may hold by default: about 1.8 GB of lines
/// (at `tetloc trace`'s 106 bytes a point), whatever the number of seeds; the CLI holds two
/// batches at once (one written while the next is traced).
pub const BATCH_POINTS: usize = 1 << 24;

impl TraceOptions {
    /// The most steps a line takes: `max_steps`, or fewer where `max_length` stops it first
    /// (each step but the last is at least the step, or the smallest adaptive step, long).
    pub fn steps_bound(&self) -> usize {
        let shortest = if self.integrator.is_adaptive() { self.min_step() } else { self.step };
        let by_length = (self.max_length / shortest).ceil() + 2.0;
        if by_length.is_finite() && by_length < self.max_steps as f64 {
            by_length as usize
        } else {
            self.max_steps
        }
    }

    /// The lines of [`Self::jobs`] in batches whose lines hold at most about `points` points
    /// together (a line has at most `max_steps + 2`; a batch at least one line, so a batch's
    /// memory is bounded by `points` or by one line): each batch is these options for one
    /// direction and a range of seeds, in VTK's line order.
    pub fn batches(&self, n_seeds: usize, points: usize) -> Vec<(TraceOptions, Range<usize>)> {
        let per = (points / self.steps_bound().saturating_add(2)).max(1);
        let dirs = match self.direction {
            Direction::Both => vec![Direction::Forward, Direction::Backward],
            d => vec![d],
        };
        dirs.into_iter()
            .flat_map(|direction| {
                (0..n_seeds)
                    .step_by(per)
                    .map(move |s| (TraceOptions { direction, ..self.clone() }, s..(s + per).min(n_seeds)))
            })
            .collect()
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
    /// The tet of each point, where the tracer keeps them (the GPU's stream kernel: the tet
    /// its velocity came from); empty otherwise.
    pub tets: Vec<i32>,
    /// The line fields at each point, as the tracer sampled them there (the GPU's stream
    /// kernel: the fields asked of [`crate::locate::LineTracer::trace_lines`], their values
    /// a point in that order, as the backend's own sampling computes them); empty otherwise.
    pub values: Vec<f32>,
    pub reason: Reason,
}
