//! Basins: where each orbit of a grid of initial states ends up — the well a damped orbit
//! settles in, the periodic response a driven one locks onto, the exit an open system's orbit
//! leaves through — and how finely those outcomes are interleaved ([`metrics`]).
//!
//! A basin map is a sweep over initial-state axes ([`super::sweep`]: the same body, grid, energy
//! surface and cell order) whose cells end their runs as soon as their outcome is decided
//! ([`outcome`]); the criteria are exact where the physics allows (the energy argument of
//! [`landscape`] for systems nothing drives, located crossings of the exits) and a recurrence
//! test on the stroboscopic map for driven systems. Labels are given after all cells are done,
//! in the order outcomes first appear in cell order, so the document is the same bit for bit
//! on any executor, in shards or on NATS workers.

pub mod document;
mod labels;
pub mod landscape;
mod lanes;
pub mod metrics;
pub mod outcome;

use std::ops::Range;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::error::{CoreError, ErrorDetail, Field};
use crate::methods;
use crate::run::{integrate, Budget, RunEnd, Schedule};
use crate::sections::names::StateNames;
use crate::sections::{Direction, Surface};
use crate::simulation::{Limits, Simulation};
use crate::studies::engine::{self, CellLine, Documented, Executor, Finished, Study};
use crate::studies::parts::{Part, ShardAt, Travelling};
use crate::studies::sweep::{EnergyReference, RunLabel, SweepJob, SweepSpec, Target};
use crate::studies::StudySpec;
use crate::system::{MechanicalSystem, State};
use crate::with_system;
pub use document::{
    Attractor, AttractorKind, BasinRun, BasinsDocument, BasinsLine, DecidedBy, UndecidedCell,
};
use landscape::Landscape;
use outcome::{CellOutcome, Criteria, Decide, Exit, Given, OrbitOutcome, Stroboscope};

/// Most points along one axis of a basin map: more than a sweep's, for maps of 10⁶ cells, as
/// most of its cells are decided long before `t_end` (the total steps `t_end` would take stay
/// bounded as a sweep's are).
pub const MAX_MAP_POINTS: usize = 1024;
/// Most exits.
pub const MAX_EXITS: usize = 16;
/// Most distinct outcomes one run of a map may have (labels past it would not fit a legend,
/// and mean the recognition's tolerance is too tight for the attractor).
pub const MAX_ATTRACTORS: usize = 64;
/// The longest period looked for on a stroboscopic map, at most.
pub const MAX_PERIOD: usize = 64;
/// Most points of one given attractor (each cell compares its state with every one).
pub const MAX_GIVEN_POINTS: usize = 256;

/// An exit surface as asked for.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExitSpec {
    /// Its name (unique).
    pub name: String,
    /// S(q, p, t), in the section language.
    pub text: String,
    /// Which crossings of S = 0 leave.
    pub direction: Direction,
    /// Where the request gave it (`exits[i]`).
    pub field: Field,
}

/// How attractors are recognised.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Recognition {
    /// The driving period T of a driven system (its stroboscopic map samples t = kT); required
    /// for one, refused for a system nothing drives.
    pub period: Option<f64>,
    /// The longest period looked for on the stroboscopic map, in driving periods (default 8).
    pub max_period: usize,
    /// How close points one period apart must be, in every component (default 1e-6).
    pub tolerance: f64,
    /// A component beyond this has escaped to infinity (default 1e6).
    pub escape_radius: f64,
    /// The coordinates that are angles, by name: compared modulo 2π on the stroboscopic map and
    /// against given attractors, stored in (−π, π], never taken to have escaped.
    #[serde(default)]
    pub angles: Vec<String>,
    /// Where the request gave it (`recognition`).
    pub field: Field,
}

impl Default for Recognition {
    fn default() -> Self {
        Recognition {
            period: None,
            max_period: 8,
            tolerance: 1e-6,
            escape_radius: 1e6,
            angles: Vec::new(),
            field: Field::new("recognition"),
        }
    }
}

/// An attractor the request names, recognised by proximity: an orbit (a driven system's
/// stroboscopic point) that comes within `radius` of one of its points has ended up there; an
/// equilibrium or periodic orbit found on the fly that lies within `radius` of its points takes
/// its label too.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GivenAttractor {
    /// Its name (unique), which the legend shows.
    pub name: String,
    /// Its points, each (q, p) without a driven system's clock.
    pub points: Vec<Vec<f64>>,
    /// How close counts, in every component (angles modulo 2π).
    pub radius: f64,
    /// Where the request gave it (`attractors[i]`).
    pub field: Field,
}

/// A basin map as asked for.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BasinsSpec {
    /// The grid, system and methods, as a sweep's (no indicators, section or energy reference).
    pub sweep: SweepSpec,
    /// The exits, if any.
    pub exits: Vec<ExitSpec>,
    /// How attractors are recognised.
    pub recognition: Recognition,
    /// The attractors the request names, if any: they take the first labels, in their order.
    #[serde(default)]
    pub attractors: Vec<GivenAttractor>,
}

/// A validated basin map.
pub struct BasinsJob {
    sweep: SweepJob,
    criteria: Arc<Criteria>,
    exit_names: Vec<String>,
    spec: BasinsSpec,
    /// Per run: whether its cells go side by side in lanes ([`lanes`]).
    in_lanes: Vec<bool>,
}

impl BasinsSpec {
    /// Validates the map and prepares what every cell looks for: the landscape of a system
    /// nothing drives, the exits compiled, the stroboscope of a driven one. Errors name the
    /// field.
    pub fn prepare(&self, limits: &Limits) -> Result<BasinsJob, CoreError> {
        if self.sweep.charts.len() > 1 {
            return Err(CoreError::Unsupported {
                field: Field::new("charts"),
                reason: "a basin map runs in one chart: its exits and equilibria are in that \
                         chart's coordinates",
            });
        }
        if self.exits.len() > MAX_EXITS {
            return Err(CoreError::Count {
                field: Field::new("exits"),
                got: self.exits.len() as u64,
                min: 0,
                max: MAX_EXITS as u64,
                what: "exits",
            });
        }
        for (i, exit) in self.exits.iter().enumerate() {
            if self.exits[..i].iter().any(|e| e.name == exit.name) {
                return Err(CoreError::Duplicate {
                    field: exit.field.key("name"),
                    value: exit.name.clone(),
                });
            }
        }
        // A basin map compares no energies: its cells' runs need no reference run beside them.
        let sweep = SweepSpec {
            energy_reference: Some(EnergyReference::Initial),
            ..self.sweep.clone()
        }
        .prepare_up_to(limits, MAX_MAP_POINTS)?;
        for axis in &sweep.grid.axes {
            if !matches!(axis.target, Target::Q0(_) | Target::P0(_)) {
                return Err(CoreError::Unsupported {
                    field: axis.field.key("name"),
                    reason: "a basin map's axes are components of the initial state (`q0[i]`, \
                             `p0[i]`): its landscape and attractors belong to one system at one \
                             step size",
                });
            }
        }
        let recognition = &self.recognition;
        let r = &recognition.field;
        crate::error::Range::POSITIVE.check(recognition.tolerance, &r.key("tolerance"))?;
        crate::error::Range::POSITIVE.check(recognition.escape_radius, &r.key("escape_radius"))?;
        crate::error::Range::closed(1.0, false, MAX_PERIOD as f64)
            .check(recognition.max_period as f64, &r.key("max_period"))?;
        // The system as every cell has it (the axes move only the initial state).
        let sim = some_simulation(&sweep)?;
        let names = StateNames::of(&sim.info, &sim.chart, &sim.params, sim.q0.len());
        let exits = self
            .exits
            .iter()
            .map(|e| {
                Ok(Exit {
                    name: e.name.clone(),
                    surface: Surface::expression(&e.text, &names, &e.field.key("where"))?,
                    direction: e.direction,
                })
            })
            .collect::<Result<Vec<_>, CoreError>>()?;
        let dof = sim.q0.len();
        let angles = angle_components(&recognition.angles, &names, &r.key("angles"))?;
        let given = given_attractors(&self.attractors, dof)?;
        let (clock, damped) = with_system!(&sim.system, s => (s.clock(), s.damping_rate() != 0.0));
        let stroboscope = match (clock, recognition.period) {
            (Some(_), None) => {
                return Err(CoreError::Unsupported {
                    field: r.key("period"),
                    reason: "a driven system's attractors are recognised on its stroboscopic \
                             map: give the driving period T",
                })
            }
            (None, Some(_)) => {
                return Err(CoreError::Unsupported {
                    field: r.key("period"),
                    reason: "nothing drives this system: its attractors are found from its \
                             energy, and there is no driving period",
                })
            }
            (None, None) => None,
            (Some(_), Some(period)) => {
                let at = r.key("period");
                crate::error::Range::POSITIVE.check(period, &at)?;
                let h = sim.schedule.h;
                let steps = (period / h).round();
                if steps < 1.0 || ((steps * h - period) / period).abs() > 1e-9 {
                    return Err(CoreError::NotADivisor {
                        field: Field::new("h"),
                        h,
                        span: period,
                        span_name: "recognition.period",
                        purpose: "so that the stroboscopic map's points are step endpoints",
                        show_ratio: true,
                    });
                }
                Some(Stroboscope {
                    steps: steps as u64,
                    max_period: recognition.max_period,
                    tolerance: recognition.tolerance,
                })
            }
        };
        if clock.is_none() && !damped && exits.is_empty() {
            return Err(CoreError::Unsupported {
                field: Field::new("exits"),
                reason: "an undamped system that nothing drives settles nowhere: give exits to \
                         map where its orbits leave, or damping",
            });
        }
        let landscape = match clock {
            Some(_) => None,
            None => Some(
                search_box(&sweep, &sim)
                    .map(|(lo, hi)| with_system!(&sim.system, s => Landscape::find(s, &lo, &hi)))?,
            ),
        };
        let criteria = Criteria {
            exits,
            landscape,
            damped,
            stroboscope,
            escape_radius: recognition.escape_radius,
            clock,
            angles,
            given,
        };
        // Every cell of a run shares its system and method, so one cell that starts an orbit
        // answers for all of them.
        let cell = sweep.grid.point(some_cell(&sweep));
        let in_lanes = (0..sweep.runs.len())
            .map(|run| {
                sweep
                    .cell_simulation(run, &cell)
                    .is_ok_and(|sim| sim.runs_in_lanes())
            })
            .collect();
        Ok(BasinsJob {
            exit_names: self.exits.iter().map(|e| e.name.clone()).collect(),
            sweep,
            criteria: Arc::new(criteria),
            spec: self.clone(),
            in_lanes,
        })
    }
}

/// Per component of a state (q then p, `names`' order), whether it is one of the `angles`
/// named at `field`: coordinates only.
fn angle_components(
    angles: &[String],
    names: &StateNames,
    field: &Field,
) -> Result<Vec<bool>, CoreError> {
    let dof = names.coordinates.len();
    let mut mask = vec![false; 2 * dof];
    for (k, name) in angles.iter().enumerate() {
        let at = field.index(k);
        match names.find(name) {
            Some((false, i)) if mask[i] => {
                return Err(CoreError::Duplicate {
                    field: at,
                    value: name.clone(),
                })
            }
            Some((false, i)) => mask[i] = true,
            Some((true, _)) => {
                return Err(CoreError::Unsupported {
                    field: at,
                    reason: "a momentum is not an angle: name coordinates whose values are taken \
                             modulo 2π",
                })
            }
            None => {
                return Err(CoreError::UnknownName {
                    field: at,
                    what: "coordinate".into(),
                    value: name.clone(),
                    known: names.coordinates.clone(),
                })
            }
        }
    }
    Ok(mask)
}

/// The given attractors checked (count, names, points of 2·`dof` finite components, radius) and
/// compiled.
fn given_attractors(given: &[GivenAttractor], dof: usize) -> Result<Vec<Given>, CoreError> {
    if given.len() > MAX_ATTRACTORS {
        return Err(CoreError::Count {
            field: Field::new("attractors"),
            got: given.len() as u64,
            min: 0,
            max: MAX_ATTRACTORS as u64,
            what: "attractors (the labels a map can hold)",
        });
    }
    given
        .iter()
        .enumerate()
        .map(|(k, a)| {
            if given[..k].iter().any(|b| b.name == a.name) {
                return Err(CoreError::Duplicate {
                    field: a.field.key("name"),
                    value: a.name.clone(),
                });
            }
            let at = a.field.key("points");
            if a.points.is_empty() || a.points.len() > MAX_GIVEN_POINTS {
                return Err(CoreError::Count {
                    field: at,
                    got: a.points.len() as u64,
                    min: 1,
                    max: MAX_GIVEN_POINTS as u64,
                    what: "points",
                });
            }
            for (j, point) in a.points.iter().enumerate() {
                let at = at.index(j);
                if point.len() != 2 * dof {
                    return Err(CoreError::WrongLength {
                        field: at,
                        expected: 2 * dof,
                        got: point.len(),
                    });
                }
                if let Some(i) = point.iter().position(|x| !x.is_finite()) {
                    return Err(CoreError::NotFinite { field: at.index(i) });
                }
            }
            crate::error::Range::POSITIVE.check(a.radius, &a.field.key("radius"))?;
            Ok(Given {
                points: a.points.clone(),
                radius: a.radius,
            })
        })
        .collect()
}

/// A cell's simulation, the centre's if it starts an orbit (it may lie off the energy surface),
/// else the first cell's that does; the centre's error when none does.
fn some_simulation(sweep: &SweepJob) -> Result<Simulation, CoreError> {
    let centre = sweep.cell_simulation(0, &sweep.grid.point(sweep.grid.cells() / 2));
    centre.or_else(|e| {
        sweep
            .cell_simulation(0, &sweep.grid.point(some_cell(sweep)))
            .map_err(|_| e)
    })
}

/// The centre cell if it starts an orbit, else the first cell that does (else the centre).
fn some_cell(sweep: &SweepJob) -> usize {
    let cells = sweep.grid.cells();
    let starts = |cell: &usize| sweep.cell_simulation(0, &sweep.grid.point(*cell)).is_ok();
    std::iter::once(cells / 2)
        .chain(0..cells)
        .find(starts)
        .unwrap_or(cells / 2)
}

/// The box of positions the map starts from: the chart's positions at the grid's corners and
/// centre.
fn search_box(sweep: &SweepJob, centre: &Simulation) -> Result<(Vec<f64>, Vec<f64>), CoreError> {
    let mut lo = centre.q0.clone();
    let mut hi = centre.q0.clone();
    let axes = &sweep.grid.axes;
    for corner in 0..(1usize << axes.len()) {
        let point: Vec<f64> = axes
            .iter()
            .enumerate()
            .map(|(k, a)| if corner >> k & 1 == 0 { a.min } else { a.max })
            .collect();
        // A corner off the energy surface or outside the chart starts no orbit.
        let Ok(sim) = sweep.cell_simulation(0, &point) else {
            continue;
        };
        for (i, &x) in sim.q0.iter().enumerate() {
            lo[i] = lo[i].min(x);
            hi[i] = hi[i].max(x);
        }
    }
    Ok((lo, hi))
}

impl BasinsJob {
    /// The runs (method × chart), as a sweep's.
    pub fn runs(&self) -> &[RunLabel] {
        &self.sweep.runs
    }

    /// The landscape the energy argument uses, for a system nothing drives.
    pub fn landscape(&self) -> Option<&Landscape> {
        self.criteria.landscape.as_ref()
    }

    /// The same map with every cell run on its own, none in lanes: the reference the lanes are
    /// checked against, bit for bit.
    pub fn one_cell_at_a_time(mut self) -> Self {
        self.in_lanes.fill(false);
        self
    }

    /// Run `run` of the cell at `point`, to its outcome; `None` when the budget stopped it.
    fn run_cell(&self, run: usize, point: &[f64], budget: Budget<'_>) -> Option<CellOutcome> {
        let sim = match self.sweep.cell_simulation(run, point) {
            Ok(sim) => sim,
            Err(e) => return Some(CellOutcome::failed(e)),
        };
        let result = with_system!(&sim.system, sys => {
            self.decide(sys, &sim, budget)
        });
        result.unwrap_or_else(|e| Some(CellOutcome::failed(e)))
    }

    fn decide<S: MechanicalSystem>(
        &self,
        sys: &S,
        sim: &Simulation,
        budget: Budget<'_>,
    ) -> Result<Option<CellOutcome>, CoreError>
    where
        nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<S::Dim>,
    {
        let start = State::at_time(sys, 0.0, &sim.q0, &sim.p0);
        let mut decide = Decide::new(sys, &self.criteria, &start, sim.q0.len());
        let mut steps = 0;
        let mut stop = RunEnd::Finished;
        let t_end = sim.schedule.steps as f64 * sim.schedule.h;
        if decide.decided.is_none() {
            let mut stepper =
                methods::build(&sim.methods[0], sys, &sim.system_label, sim.schedule.h)?;
            let mut z = start.clone();
            // One sample, at the end: the observer watches every step itself.
            let schedule = Schedule {
                every: sim.schedule.steps.max(1),
                ..sim.schedule
            };
            // The stepper as the enum of every method: one driver per system, not one per
            // system and method (the cell's observer looks at every step, which costs more than
            // the dispatch; the runs that need speed go in lanes).
            let (why, stats) = integrate(sys, &mut stepper, &mut z, schedule, budget, &mut decide)?;
            steps = stats.steps;
            stop = why;
        }
        Ok(self.conclude(decide.decided.take(), stop, steps, t_end))
    }

    /// A cell's outcome from what its observer decided (outcome, time, energy margin) and how
    /// its run stopped after `steps`; `None` when the budget stopped it undecided.
    fn conclude(
        &self,
        decided: Option<(OrbitOutcome, f64, Option<f64>)>,
        stop: RunEnd,
        steps: u64,
        t_end: f64,
    ) -> Option<CellOutcome> {
        let (outcome, decided_at, energy_margin) = match (decided, stop) {
            (Some((outcome, t, margin)), _) => (outcome, Some(t), margin),
            (None, RunEnd::Cancelled { .. } | RunEnd::TimeLimit { .. }) => return None,
            (None, RunEnd::Diverged { t, .. }) => (OrbitOutcome::Diverged, Some(t), None),
            (None, _) if !self.criteria.exits.is_empty() => {
                (OrbitOutcome::Stayed, Some(t_end), None)
            }
            (None, _) => (
                OrbitOutcome::Undecided {
                    reason: self.undecided_reason().into(),
                },
                None,
                None,
            ),
        };
        Some(CellOutcome {
            outcome,
            decided_at,
            steps,
            energy_margin,
        })
    }

    fn undecided_reason(&self) -> &'static str {
        match (&self.criteria.landscape, self.criteria.stroboscope) {
            (Some(l), _) if l.barrier.is_some() => {
                "the energy stayed above the lowest saddle (less the margin) until t_end"
            }
            (Some(_), _) => "the orbit did not come near a minimum the search found by t_end",
            (None, Some(_)) => {
                "no periodic orbit of the stroboscopic map within the tolerance and the longest \
                 period by t_end: a quasi-periodic or chaotic attractor, or a long transient"
            }
            (None, None) => "nothing decided it by t_end",
        }
    }
}

impl Study for BasinsJob {
    type Cell = Vec<CellOutcome>;

    fn name(&self) -> &'static str {
        "basin map"
    }

    fn cells(&self) -> usize {
        self.sweep.grid.cells()
    }

    fn group(&self) -> usize {
        if self.in_lanes.contains(&true) {
            lanes::GROUP
        } else {
            1
        }
    }

    fn run_cells(
        &self,
        cells: Range<usize>,
        budget: Budget<'_>,
    ) -> Result<Vec<Option<Vec<CellOutcome>>>, CoreError> {
        // Run by run (each in lanes where it can go), then cell by cell.
        let mut runs: Vec<std::vec::IntoIter<Option<CellOutcome>>> = (0..self.sweep.runs.len())
            .map(|run| {
                let in_lanes = self.in_lanes[run]
                    .then(|| self.decide_in_lanes(run, cells.clone(), budget))
                    .flatten();
                in_lanes
                    .unwrap_or_else(|| {
                        cells
                            .clone()
                            .map(|cell| self.run_cell(run, &self.sweep.grid.point(cell), budget))
                            .collect()
                    })
                    .into_iter()
            })
            .collect();
        Ok(cells
            .map(|_| {
                runs.iter_mut()
                    .map(|run| run.next().flatten())
                    .collect::<Option<Vec<_>>>()
            })
            .collect())
    }

    fn fits(&self, cell: &Vec<CellOutcome>) -> bool {
        cell.len() == self.sweep.runs.len()
    }

    fn spec(&self) -> Option<StudySpec> {
        Some(StudySpec::Basins(self.spec.clone()))
    }

    fn steps(&self) -> u64 {
        self.sweep.total_steps
    }
}

/// Runs the map on `executor`, reporting progress through `emit`.
pub fn run<E: Executor + ?Sized>(
    job: &BasinsJob,
    executor: &E,
    budget: Budget<'_>,
    emit: &(dyn Fn(BasinsLine) -> bool + Sync),
) -> Result<BasinsDocument, CoreError> {
    engine::run_documented(job, executor, budget, emit)
}

impl Documented for BasinsJob {
    type Line = BasinsLine;

    fn document_of(&self, finished: Finished<Vec<CellOutcome>>) -> BasinsDocument {
        BasinsJob::document_of(self, finished)
    }
}

impl CellLine for BasinsLine {
    type Document = BasinsDocument;

    fn progress(done: usize, total: usize) -> Self {
        BasinsLine::Progress { done, total }
    }

    fn result(document: BasinsDocument) -> Self {
        BasinsLine::Result(Box::new(document))
    }

    fn error(error: ErrorDetail) -> Self {
        BasinsLine::Error { error }
    }

    fn end() -> Self {
        BasinsLine::End
    }
}

/// A shard of it, as a worker or an array task runs it.
impl Travelling for BasinsSpec {
    type Cell = Vec<CellOutcome>;

    fn run_shard(
        &self,
        at: &ShardAt<'_>,
        limits: &crate::simulation::Limits,
    ) -> Result<Part<Self::Cell>, CoreError> {
        at.run(&self.prepare(limits)?)
    }
}
