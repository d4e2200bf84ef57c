//! Energy-error maps (paper 001 Sec. 4.1, Fig. 6): the planar elastic pendulum started at rest
//! from every point (x₀, y₀) of a grid, integrated with one method in Cartesian and in polar
//! coordinates, and per cell the ℓ² energy error of eq. (50) in each chart,
//!
//! ```text
//! ε = √( 1/(J+1) Σ_{j=0..J} (H(q^j, p^j) − H(q^0, p^0))² )
//! ```
//!
//! (the exact flow keeps H, so this is the deviation of the method's distorted Hamiltonian; eq. 50
//! prints 1/J in front of a sum of J + 1 terms — we average over the terms summed), their
//! difference ε(x,y) − ε(r,θ), and the cells whose polar run diverges, beside the region
//! r(0) ≥ 2l + 2mg/k·cos θ(0) where Sec. 4.1 predicts it: there the mass, released at rest, has
//! the energy to reach the pivot, the polar chart's singular point (on the line through the pivot,
//! ½k(r₀ − l)² − mg r₀ cos θ₀ ≥ ½kl² ⇔ r₀ ≥ 2l + 2mg/k·cos θ₀).
//!
//! A run diverges when its state becomes non-finite or its energy leaves H₀ by more than
//! 100·(1 + |H₀|): a polar run that passes next to the pivot takes a kick p_θ²/(m r³) that throws
//! H off by many orders of magnitude (10⁶ to 10¹² on the default grid) while staying finite.
//!
//! Cells are independent and run in parallel (rayon, all cores), reporting to a progress
//! callback as they finish. The run stops between steps when the budget says so. With symplectic
//! Euler or its adjoint (Fig. 6's method), four cells run side by side in SIMD lanes (`lanes`),
//! with the bits of the cell-by-cell path and about a third of its time (README, Speed).

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::U2;
use rayon::prelude::*;
use serde::Serialize;

use crate::error::{CoreError, Field, Range};
use crate::methods::build::{self, Origin};
use crate::methods::{self, Method};
use crate::run::{integrate, step_count, Budget, Observer, Schedule, StopReason};
use crate::simulation::MethodAt;
use crate::system::{MechanicalSystem, State, Vector};
use crate::systems::{
    self, ParamValue, PlanarCartesian, PlanarKind, PlanarPolar, PlanarSpring,
};
use crate::with_stepper;
use lanes::{Order, LANES};

mod document;
pub(crate) mod lanes;

pub use document::{run, EnergyMapDocument, MapLine, MapParams, MapSummary};

/// Most grid points per axis.
pub const MAX_AXIS: usize = 401;
/// Most steps over all cells and both charts of one map.
pub const MAX_TOTAL_STEPS: u64 = 20_000_000_000;

/// One cell: its Cartesian and polar runs and its starting energy.
type CellRuns = (ChartRun, ChartRun, f64);

/// A validated map request.
#[derive(Clone, Debug)]
pub struct EnergyMapJob {
    /// The method, run in both charts.
    pub method: Method,
    /// Mass, stiffness, rest length and gravity.
    pub pendulum: PlanarSpring,
    /// Step size.
    pub h: f64,
    /// Final time.
    pub t_max: f64,
    /// Steps per cell and chart (t_max/h).
    pub steps: u64,
    /// Grid points along x, from `x.0` to `x.1`.
    pub nx: usize,
    /// Grid points along y, from `y.0` to `y.1`.
    pub ny: usize,
    /// Range of x₀.
    pub x: (f64, f64),
    /// Range of y₀ (y points down, along gravity).
    pub y: (f64, f64),
}

/// How a map's cells are run. Both give the same bits for every cell they finish; a time limit
/// stops lanes a group of four at a time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Engine {
    /// Four cells side by side in SIMD lanes where the method is one the lanes run (symplectic
    /// Euler and its adjoint), else cell by cell.
    Lanes,
    /// Each cell through the generic stepper and observer.
    CellByCell,
}

/// One chart's run of one cell.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ChartRun {
    /// The ℓ² energy error of eq. (50); `None` when the run diverged or could not start.
    pub epsilon: Option<f64>,
    /// The time at which the run diverged (non-finite state, or |H − H₀| > 100·(1 + |H₀|)).
    pub diverged_at: Option<f64>,
}

/// The map: per-cell columns in row-major order (row j is y₀ = ys[j], column i is x₀ = xs[i]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EnergyMap {
    /// The method's label.
    pub method: String,
    /// Grid x₀ values.
    pub xs: Vec<f64>,
    /// Grid y₀ values.
    pub ys: Vec<f64>,
    /// H at the start of each cell.
    pub energy: Vec<f64>,
    /// ε in Cartesian coordinates.
    pub cartesian: Vec<ChartRun>,
    /// ε in polar coordinates (`epsilon` and `diverged_at` both `None` at the pivot, r = 0,
    /// where the chart does not exist).
    pub polar: Vec<ChartRun>,
    /// Whether Sec. 4.1's boundary puts the start in the region where the polar run passes
    /// through the pivot: r₀ ≥ 2l + 2mg/k·cos θ₀.
    pub predicted_divergent: Vec<bool>,
    /// Steps taken over all cells and charts.
    pub steps: u64,
    /// The cells the time limit stopped (their runs are `None`, `None`), in order.
    pub unfinished: Vec<usize>,
}

impl EnergyMap {
    /// ε(x,y) − ε(r,θ) per cell, where both exist.
    pub fn difference(&self) -> Vec<Option<f64>> {
        self.cartesian
            .iter()
            .zip(&self.polar)
            .map(|(c, p)| Some(c.epsilon? - p.epsilon?))
            .collect()
    }
}

impl EnergyMapJob {
    /// Grid coordinate k of `n` points over `range`.
    fn at(range: (f64, f64), n: usize, k: usize) -> f64 {
        if n == 1 {
            0.5 * (range.0 + range.1)
        } else {
            range.0 + (range.1 - range.0) * k as f64 / (n - 1) as f64
        }
    }

    /// Checks the grid and the work against the limits, and the method against the polar
    /// chart's Hamiltonian; errors name the request's fields (`nx`, `x`, `t_max`, `method`).
    pub fn check(&self) -> Result<(), CoreError> {
        for (name, n) in [("nx", self.nx), ("ny", self.ny)] {
            if n == 0 || n > MAX_AXIS {
                return Err(CoreError::Count {
                    field: Field::new(name),
                    got: n as u64,
                    min: 1,
                    max: MAX_AXIS as u64,
                    what: "grid points",
                });
            }
        }
        for (name, (lo, hi)) in [("x", self.x), ("y", self.y)] {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(CoreError::BadInterval {
                    field: Field::new(name),
                    min: lo,
                    max: hi,
                });
            }
        }
        let cells = (self.nx * self.ny) as u64;
        // Saturating: t_max/h can be as large as u64 holds, and a wrapped product would pass.
        let total = cells.saturating_mul(2).saturating_mul(self.steps);
        if total > MAX_TOTAL_STEPS {
            return Err(CoreError::MapTooLarge {
                field: Field::new("t_max"),
                cells,
                steps: self.steps,
                total,
                limit: MAX_TOTAL_STEPS,
            });
        }
        let probe = PlanarPolar(self.pendulum.clone());
        let origin = Origin {
            method: &Field::new("method"),
            h: &Field::new("h"),
            system: "elastic_pendulum_2d (polar chart)",
        };
        build::check(&self.method, &probe, self.h, &origin)
    }

    /// The analytic prediction of Sec. 4.1 at (x₀, y₀).
    pub fn predicted_divergent(&self, x0: f64, y0: f64) -> bool {
        let s = &self.pendulum;
        let r = x0.hypot(y0);
        let cos = if r > 0.0 { y0 / r } else { 1.0 };
        r >= 2.0 * s.l + 2.0 * s.m * s.g / s.k * cos
    }

    /// Points (x, y) of the boundary r = 2l + 2mg/k·cos θ, x = r sin θ, y = r cos θ, at `n`
    /// angles around the pivot.
    pub fn boundary(&self, n: usize) -> Vec<[f64; 2]> {
        let s = &self.pendulum;
        (0..=n)
            .map(|k| {
                let th = std::f64::consts::TAU * k as f64 / n as f64;
                let r = 2.0 * s.l + 2.0 * s.m * s.g / s.k * th.cos();
                [r * th.sin(), r * th.cos()]
            })
            .collect()
    }

    /// Runs every cell; `progress(done, total)` is called as cells finish (from worker threads;
    /// in lanes, four at a time). Cells the deadline stopped are listed in `unfinished` (in
    /// lanes, whole groups of four); `Ok(None)` when the cancellation flag stopped the map.
    pub fn run(
        &self,
        budget: Budget<'_>,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Option<EnergyMap>, CoreError> {
        self.run_with(Engine::Lanes, budget, progress)
    }

    /// [`Self::run`] on the engine `engine`.
    pub fn run_with(
        &self,
        engine: Engine,
        budget: Budget<'_>,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Option<EnergyMap>, CoreError> {
        self.check()?;
        let total = self.nx * self.ny;
        let done = AtomicUsize::new(0);
        let report =
            |cells: usize| progress(done.fetch_add(cells, Ordering::Relaxed) + cells, total);
        let cells: Vec<Result<Option<CellRuns>, CoreError>> = match Order::of(&self.method) {
            Some(order) if engine == Engine::Lanes => (0..total.div_ceil(LANES))
                .into_par_iter()
                .map(|group| {
                    let runs = self.lane_group(order, group * LANES, total, budget);
                    report(runs.len());
                    runs
                })
                .collect::<Vec<_>>()
                .into_iter()
                .flatten()
                .collect(),
            _ => (0..total)
                .into_par_iter()
                .map(|cell| {
                    let (x0, y0) = self.start_of(cell);
                    let result = self.cell(x0, y0, budget);
                    report(1);
                    result
                })
                .collect(),
        };
        let mut map = EnergyMap {
            method: self.method.label(),
            xs: (0..self.nx).map(|i| Self::at(self.x, self.nx, i)).collect(),
            ys: (0..self.ny).map(|j| Self::at(self.y, self.ny, j)).collect(),
            energy: Vec::with_capacity(total),
            cartesian: Vec::with_capacity(total),
            polar: Vec::with_capacity(total),
            predicted_divergent: Vec::with_capacity(total),
            steps: 0,
            unfinished: Vec::new(),
        };
        let not_run = ChartRun {
            epsilon: None,
            diverged_at: None,
        };
        for (cell, result) in cells.into_iter().enumerate() {
            let (x0, y0) = (map.xs[cell % self.nx], map.ys[cell / self.nx]);
            let Some((cartesian, polar, energy)) = result? else {
                if budget.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                    return Ok(None);
                }
                map.unfinished.push(cell);
                map.predicted_divergent
                    .push(self.predicted_divergent(x0, y0));
                map.energy.push(
                    self.cartesian()
                        .energy(&[x0, y0].into(), &[0.0, 0.0].into()),
                );
                map.cartesian.push(not_run);
                map.polar.push(not_run);
                continue;
            };
            map.predicted_divergent
                .push(self.predicted_divergent(x0, y0));
            map.energy.push(energy);
            for run in [&cartesian, &polar] {
                map.steps += match (run.epsilon, run.diverged_at) {
                    (_, Some(t)) => (t / self.h).round() as u64,
                    (Some(_), None) => self.steps,
                    (None, None) => 0,
                };
            }
            map.cartesian.push(cartesian);
            map.polar.push(polar);
        }
        Ok(Some(map))
    }

    /// The pendulum in Cartesian coordinates.
    fn cartesian(&self) -> PlanarCartesian {
        PlanarCartesian(PlanarSpring {
            kind: PlanarKind::Pendulum,
            ..self.pendulum.clone()
        })
    }

    /// Whether [`Engine::Lanes`] runs this map side by side (its method is symplectic Euler or
    /// its adjoint) rather than cell by cell.
    pub fn runs_in_lanes(&self) -> bool {
        Order::of(&self.method).is_some()
    }

    /// (x₀, y₀) of cell `cell`.
    fn start_of(&self, cell: usize) -> (f64, f64) {
        (
            Self::at(self.x, self.nx, cell % self.nx),
            Self::at(self.y, self.ny, cell / self.nx),
        )
    }

    /// Cells `first..first + LANES` (those below `total`) in [`lanes`], both charts; the same
    /// numbers as [`Self::cell`] for each.
    fn lane_group(
        &self,
        order: Order,
        first: usize,
        total: usize,
        budget: Budget<'_>,
    ) -> Vec<Result<Option<CellRuns>, CoreError>> {
        let cells = (total - first).min(LANES);
        let cartesian = self.cartesian();
        let polar = PlanarPolar(cartesian.0.clone());
        let mut starts = [lanes::Start {
            q: [[0.0; LANES]; 2],
            p: [[0.0; LANES]; 2],
            energy: [0.0; LANES],
            idle: [true; LANES],
        }; 2];
        let (mut q, mut p) = (Vector::<U2>::zeros(), Vector::<U2>::zeros());
        for i in 0..cells {
            let (x0, y0) = self.start_of(first + i);
            let [in_cartesian, in_polar] = &mut starts;
            in_cartesian.q[0][i] = x0;
            in_cartesian.q[1][i] = y0;
            in_cartesian.energy[i] = cartesian.energy(&[x0, y0].into(), &[0.0, 0.0].into());
            in_cartesian.idle[i] = false;
            // The pivot, where the polar chart does not exist, stays idle.
            if polar
                .from_cartesian(&[x0, y0], &[0.0, 0.0], &mut q, &mut p)
                .is_ok()
            {
                for k in 0..2 {
                    in_polar.q[k][i] = q[k];
                    in_polar.p[k][i] = p[k];
                }
                in_polar.energy[i] = polar.energy(&q, &p);
                in_polar.idle[i] = false;
            }
        }
        let run = |chart, start: &lanes::Start| {
            lanes::run(
                &self.pendulum,
                chart,
                order,
                start,
                self.h,
                self.steps,
                budget,
            )
        };
        // As cell by cell: the polar runs only after the Cartesian ones finished.
        let runs = run(lanes::Chart::Cartesian, &starts[0])
            .and_then(|in_cartesian| Some((in_cartesian, run(lanes::Chart::Polar, &starts[1])?)));
        (0..cells)
            .map(|i| Ok(runs.map(|(c, p)| (c[i], p[i], starts[0].energy[i]))))
            .collect()
    }

    /// Both charts' runs from (x₀, y₀) at rest, and the starting energy; `None` if the budget
    /// stopped a run.
    fn cell(&self, x0: f64, y0: f64, budget: Budget<'_>) -> Result<Option<CellRuns>, CoreError> {
        let cartesian = self.cartesian();
        let start = State::from_slices(U2, &[x0, y0], &[0.0, 0.0]);
        let energy = cartesian.energy(&start.q, &start.p);
        let Some(in_cartesian) = self.chart_run(&cartesian, start.clone(), budget)? else {
            return Ok(None);
        };
        let polar = PlanarPolar(cartesian.0.clone());
        let mut polar_start = start.clone();
        let in_polar = if polar
            .from_cartesian(
                &[x0, y0],
                &[0.0, 0.0],
                &mut polar_start.q,
                &mut polar_start.p,
            )
            .is_ok()
        {
            match self.chart_run(&polar, polar_start, budget)? {
                Some(run) => run,
                None => return Ok(None),
            }
        } else {
            ChartRun {
                epsilon: None,
                diverged_at: None,
            }
        };
        Ok(Some((in_cartesian, in_polar, energy)))
    }

    fn chart_run<S: MechanicalSystem<Dim = U2>>(
        &self,
        sys: &S,
        mut z: State<U2>,
        budget: Budget<'_>,
    ) -> Result<Option<ChartRun>, CoreError> {
        let mut stepper = methods::build(&self.method, sys, "elastic_pendulum_2d", self.h)?;
        let start = sys.energy(&z.q, &z.p);
        let mut observer = EnergyDeviation {
            sys,
            start,
            limit: DIVERGENCE * (1.0 + start.abs()),
            sum: 0.0,
            count: 0,
            blown_at: None,
        };
        let schedule = Schedule {
            h: self.h,
            steps: self.steps,
            every: 1,
        };
        let (stop, _) = with_stepper!(&mut stepper, st => integrate(
            sys, st, &mut z, schedule, budget, false, &mut observer
        ))?;
        Ok(match stop {
            StopReason::Finished if observer.blown_at.is_some() => Some(ChartRun {
                epsilon: None,
                diverged_at: observer.blown_at,
            }),
            StopReason::Finished => Some(ChartRun {
                epsilon: Some((observer.sum / observer.count as f64).sqrt()),
                diverged_at: None,
            }),
            StopReason::Diverged { t, .. } => Some(ChartRun {
                epsilon: None,
                diverged_at: Some(t),
            }),
            StopReason::Cancelled { .. }
            | StopReason::TimeLimit { .. }
            | StopReason::Indicator(_) => None,
        })
    }
}

/// A run whose energy error exceeds this many times 1 + |H₀| has diverged.
const DIVERGENCE: f64 = 100.0;

/// Accumulates Σ (H(z_j) − H(z_0))² over the samples, and notes when |H − H₀| first passes
/// `limit`.
struct EnergyDeviation<'a, S> {
    sys: &'a S,
    start: f64,
    limit: f64,
    sum: f64,
    count: u64,
    blown_at: Option<f64>,
}

impl<S: MechanicalSystem<Dim = U2>> Observer<U2> for EnergyDeviation<'_, S> {
    #[inline]
    fn on_sample(&mut self, _step: u64, t: f64, z: &State<U2>) {
        let d = self.sys.energy(&z.q, &z.p) - self.start;
        // NaN compares false: a non-finite energy counts as blown up too.
        let within = d.abs() <= self.limit;
        if self.blown_at.is_none() && !within {
            self.blown_at = Some(t);
        }
        self.sum += d * d;
        self.count += 1;
    }
}

/// Default parameters of 001 Fig. 6 (l = m = k = 1, g = 0.02).
pub const FIG6_G: f64 = 0.02;

/// An energy-error map as asked for.
#[derive(Clone, Debug, PartialEq)]
pub struct EnergyMapSpec {
    /// The method, run in both charts.
    pub method: MethodAt,
    /// `m`, `k`, `l`, `g` of `elastic_pendulum_2d` (g defaults to Fig. 6's 0.02).
    pub params: BTreeMap<String, ParamValue>,
    /// Step size.
    pub h: f64,
    /// Final time.
    pub t_max: f64,
    /// Grid points along x.
    pub nx: usize,
    /// Grid points along y.
    pub ny: usize,
    /// Range of x₀.
    pub x: [f64; 2],
    /// Range of y₀ (y pointing down).
    pub y: [f64; 2],
}

impl EnergyMapSpec {
    /// Validates the map (cheap: no integration).
    pub fn prepare(&self) -> Result<EnergyMapJob, CoreError> {
        let info = systems::info("elastic_pendulum_2d", &Field::new("system"))?;
        let mut params = self.params.clone();
        params
            .entry("g".to_string())
            .or_insert(ParamValue::Number(FIG6_G));
        let resolved = systems::params::resolve(&info, &params, &Field::new("params"))?;
        let h = Range::POSITIVE.check(self.h, &Field::new("h"))?;
        let t_max = Range::POSITIVE.check(self.t_max, &Field::new("t_max"))?;
        if let Method::Reference { .. } = self.method.method {
            return Err(CoreError::Unsupported {
                field: self.method.field.clone(),
                reason: "the adaptive reference is not a fixed-step method; choose e.g. symplectic_euler",
            });
        }
        let pendulum = systems::planar_pendulum(&resolved);
        let job = EnergyMapJob {
            method: self.method.method,
            pendulum,
            h,
            t_max,
            steps: step_count(h, t_max),
            nx: self.nx,
            ny: self.ny,
            x: (self.x[0], self.x[1]),
            y: (self.y[0], self.y[1]),
        };
        job.check()
            .map_err(|e| match e.field().map(Field::as_str) {
                Some("method") => e.at(self.method.field.clone()),
                _ => e,
            })?;
        Ok(job)
    }
}
