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
//! The map is a sweep ([`super::sweep`]) of two runs per cell, the method in each chart, over
//! (x₀, y₀) with p₀ = 0, measured against H₀ at every step: its ε is the sweep's `energy_error_l2`
//! and its divergence times the sweep's `diverged_at`, bit for bit. So it runs wherever the study
//! engine runs sweeps — on all cores, four cells side by side in SIMD lanes with symplectic Euler
//! or its adjoint (Fig. 6's method; [`crate::methods::lanes`]), on NATS workers — and this module
//! only validates the map's request and adapts the sweep's document into the map's.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::error::{CoreError, Field, Range};
use crate::methods::build::{self, MethodOrigin};
use crate::methods::Method;
use crate::run::{step_count, Budget};
use crate::simulation::{InitialCoordinates, Limits, MethodAt};
use crate::studies::engine::{self, Executor, Finished, Local, Progress, Study};
use crate::studies::sweep::{
    Axis, EnergyReference, RunMetrics, Scale, SweepJob, SweepSpec, Target,
};
use crate::system::MechanicalSystem;
use crate::systems::{self, ParamValue, PlanarCartesian, PlanarKind, PlanarPolar, PlanarSpring};

mod document;
pub mod lanes;

pub use document::{run, EnergyMapDocument, MapLine, MapParams, MapSummary};

/// Most grid points per axis.
pub const MAX_AXIS: usize = 401;
/// Most steps over all cells and both charts of one map.
pub const MAX_TOTAL_STEPS: u64 = 20_000_000_000;

/// A validated map request, and the sweep that computes it.
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
    /// The sweep: runs 0 and 1 of each cell are the Cartesian and the polar one.
    sweep: SweepJob,
}

/// How a map's cells are run. Both give the same bits for every cell they finish; a time limit
/// stops lanes a group of four at a time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellPath {
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

impl ChartRun {
    /// The run as the sweep measured it (`None`: not run).
    fn of(metrics: Option<&RunMetrics>) -> ChartRun {
        ChartRun {
            epsilon: metrics.and_then(|m| m.energy_error_l2),
            diverged_at: metrics.and_then(|m| m.diverged_at),
        }
    }
}

/// The map: per-cell columns in row-major order (row j is y₀ = ys[j], column i is x₀ = xs[i]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EnergyMapCells {
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

impl EnergyMapCells {
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
    /// The sweep that computes the map (what the engine runs).
    pub fn sweep(&self) -> &SweepJob {
        &self.sweep
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

    /// Whether [`CellPath::Lanes`] runs this map side by side (its method is symplectic Euler or
    /// its adjoint) rather than cell by cell.
    pub fn runs_in_lanes(&self) -> bool {
        self.sweep.runs_in_lanes()
    }

    /// Runs every cell on this machine; `progress(done, total)` is called as cells finish (from
    /// worker threads; in lanes, four at a time). Cells the deadline stopped are listed in
    /// `unfinished` (in lanes, whole groups of four); `Ok(None)` when the cancellation flag
    /// stopped the map.
    pub fn run(
        &self,
        budget: Budget<'_>,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Option<EnergyMapCells>, CoreError> {
        self.run_with(CellPath::Lanes, budget, progress)
    }

    /// [`Self::run`] on the path `path`.
    pub fn run_with(
        &self,
        path: CellPath,
        budget: Budget<'_>,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Option<EnergyMapCells>, CoreError> {
        let sweep = match path {
            CellPath::Lanes => self.sweep.clone(),
            CellPath::CellByCell => self.sweep.clone().cell_by_cell(),
        };
        let counter = Progress::new(sweep.cells(), progress);
        match engine::run(&sweep, &Local, budget, &|_, _| counter.add(1)) {
            Ok(finished) => Ok(Some(self.map_of(&finished))),
            Err(CoreError::Cancelled { .. }) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// The map from what the sweep's cells came to.
    pub fn map_of(&self, finished: &Finished<Vec<RunMetrics>>) -> EnergyMapCells {
        let xs: Vec<f64> = self.sweep.grid.axes[0].values();
        let ys: Vec<f64> = self.sweep.grid.axes[1].values();
        let cartesian = self.cartesian();
        let total = self.nx * self.ny;
        let mut map = EnergyMapCells {
            method: self.method.label(),
            energy: Vec::with_capacity(total),
            cartesian: Vec::with_capacity(total),
            polar: Vec::with_capacity(total),
            predicted_divergent: Vec::with_capacity(total),
            steps: 0,
            unfinished: finished.unfinished(),
            xs,
            ys,
        };
        for (cell, runs) in finished.cells.iter().enumerate() {
            let (x0, y0) = (map.xs[cell % self.nx], map.ys[cell / self.nx]);
            map.energy
                .push(cartesian.energy(&[x0, y0].into(), &[0.0, 0.0].into()));
            map.predicted_divergent
                .push(self.predicted_divergent(x0, y0));
            let [in_cartesian, in_polar] =
                [0, 1].map(|run| ChartRun::of(runs.as_ref().map(|r| &r[run])));
            for run in [&in_cartesian, &in_polar] {
                // As the map always counted: up to the divergence, or every step.
                map.steps += match (run.epsilon, run.diverged_at) {
                    (_, Some(t)) => (t / self.h).round() as u64,
                    (Some(_), None) => self.steps,
                    (None, None) => 0,
                };
            }
            map.cartesian.push(in_cartesian);
            map.polar.push(in_polar);
        }
        map
    }

    /// The pendulum in Cartesian coordinates.
    fn cartesian(&self) -> PlanarCartesian {
        PlanarCartesian(PlanarSpring {
            kind: PlanarKind::Pendulum,
            ..self.pendulum.clone()
        })
    }
}

/// Runs the map's sweep on `executor`, with progress as the map reports it.
pub(super) fn run_on<E: Executor>(
    job: &EnergyMapJob,
    executor: &E,
    budget: Budget<'_>,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Finished<Vec<RunMetrics>>, CoreError> {
    let counter = Progress::new(job.sweep.cells(), progress);
    engine::run(&job.sweep, executor, budget, &|_, _| counter.add(1)).map_err(|e| match e {
        CoreError::Cancelled { .. } => CoreError::Cancelled {
            what: "map",
            shutdown: true,
        },
        e => e,
    })
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
    /// Checks the grid and the work against the limits, and the method against the polar
    /// chart's Hamiltonian; errors name the request's fields (`nx`, `x`, `t_max`, `method`).
    fn check(
        &self,
        method: &Method,
        pendulum: &PlanarSpring,
        h: f64,
        steps: u64,
    ) -> Result<(), CoreError> {
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
        for (name, [lo, hi]) in [("x", self.x), ("y", self.y)] {
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
        let total = cells.saturating_mul(2).saturating_mul(steps);
        if total > MAX_TOTAL_STEPS {
            return Err(CoreError::MapTooLarge {
                field: Field::new("t_max"),
                cells,
                steps,
                total,
                limit: MAX_TOTAL_STEPS,
            });
        }
        let probe = PlanarPolar(pendulum.clone());
        let origin = MethodOrigin {
            method: &Field::new("method"),
            h: &Field::new("h"),
            system: "elastic_pendulum_2d (polar chart)",
        };
        build::check(method, &probe, h, &origin)
    }

    /// Validates the map (cheap: no integration) and prepares its sweep.
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
        let steps = step_count(h, t_max);
        self.check(&self.method.method, &pendulum, h, steps)
            .map_err(|e| match e.field().map(Field::as_str) {
                Some("method") => e.at(self.method.field.clone()),
                _ => e,
            })?;
        // The map's runs are bounded by its total only (as they always were), not by the
        // per-run limit of simulations.
        let unlimited = Limits {
            max_steps: u64::MAX,
            max_samples: u64::MAX,
        };
        Ok(EnergyMapJob {
            method: self.method.method,
            pendulum,
            h,
            t_max,
            steps,
            nx: self.nx,
            ny: self.ny,
            x: (self.x[0], self.x[1]),
            y: (self.y[0], self.y[1]),
            sweep: self.sweep(params).prepare(&unlimited)?,
        })
    }

    /// The sweep of the map: both charts, at rest, from every (x₀, y₀), against H₀ at every
    /// step.
    fn sweep(&self, params: BTreeMap<String, ParamValue>) -> SweepSpec {
        let axis = |i: usize, [min, max]: [f64; 2], n: usize, name: &str| Axis {
            target: Target::Q0(i),
            min,
            max,
            n,
            scale: Scale::Linear,
            field: Field::new(name),
        };
        SweepSpec {
            system: "elastic_pendulum_2d".into(),
            params,
            charts: ["cartesian", "polar"]
                .map(|c| (Some(c.to_string()), Field::new("chart")))
                .into(),
            initial_coordinates: Some(InitialCoordinates::Cartesian),
            q0: None,
            p0: Some(vec![0.0, 0.0]),
            methods: vec![self.method.clone()],
            h: Some(self.h),
            t_end: self.t_max,
            every: None,
            energy_reference: Some(EnergyReference::Initial),
            axes: vec![axis(0, self.x, self.nx, "x"), axis(1, self.y, self.ny, "y")],
            chaos: None,
            energy_surface: None,
            section: None,
            digest: String::new(),
        }
    }
}
