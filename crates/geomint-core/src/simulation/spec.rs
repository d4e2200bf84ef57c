//! A simulation as users ask for it ([`SimulationSpec`]: a system with parameters, chart and
//! initial state, methods, a step and a horizon, the sampling) and its validation into a
//! [`Simulation`] ready to run. Validation is cheap (no integration) and names the field at
//! fault as the caller's input names it ([`InputFields`]).

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::chaos::{self, ChaosPlan, ChaosSpec};
use crate::error::{CoreError, Field, Range, StepError, StepScope};
use crate::methods::build::{self, MethodOrigin};
use crate::methods::{self, Method};
use crate::run::Stepper;
use crate::run::{step_count, Schedule};
use crate::system::{MechanicalSystem, State};
use crate::systems::{
    self, AnySystem, ChartInfo, ParamValue, ParamValues, SystemInfo, SystemRef, World,
};
use crate::tangent::Tangent;
use crate::with_system;

/// Hard limits on the work a request may ask for.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Most steps per method.
    pub max_steps: u64,
    /// Most samples over all methods of a request.
    pub max_samples: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_steps: 10_000_000,
            max_samples: 1_000_000,
        }
    }
}

/// The coordinates an initial state is given in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum InitialCoordinates {
    /// The chart's own generalized coordinates and momenta.
    Chart,
    /// Cartesian coordinates and momenta (for a first-order ODE: the original variable).
    Cartesian,
}

impl InitialCoordinates {
    /// Whether a study's q0 and p0 (`state_given`) are Cartesian, for the choice `chosen` over
    /// `charts` charts: by default they are when there are several (one physical state for every
    /// chart), and in several charts they cannot be a chart's own.
    pub fn cartesian_in_study(
        chosen: Option<InitialCoordinates>,
        charts: usize,
        state_given: bool,
    ) -> Result<bool, CoreError> {
        let several = charts > 1;
        if several && state_given && chosen == Some(InitialCoordinates::Chart) {
            return Err(CoreError::Unsupported {
                field: Field::new("initial_coordinates"),
                reason: "with several charts q0 and p0 are one physical state: give them in \
                         `cartesian` coordinates",
            });
        }
        Ok(match chosen {
            Some(c) => c == InitialCoordinates::Cartesian,
            None => several,
        })
    }
}

/// What the energy error of a sample is measured against.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum EnergyReference {
    /// H at the same time on the exact solution.
    Exact,
    /// H₀, the energy at the start: the exact flow keeps it when nothing is damped (eq. 50).
    Initial,
    /// H at the same time on a reference run (the adaptive DOP853).
    Reference,
}

/// Most methods in one simulation.
pub const MAX_METHODS: usize = 16;

/// A method of a simulation and the field that gave it (`methods[1]`, `method`,
/// `runs[0].method`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MethodAt {
    /// The method.
    pub method: Method,
    /// Where the request gave it.
    pub field: Field,
}

/// Where each input of a simulation came from, as errors name it. The defaults are the names of
/// the simulation request; a study that checks its settings as simulations names its own.
#[derive(Clone, Debug, PartialEq)]
pub struct InputFields {
    /// The system id.
    pub system: Field,
    /// The parameters (`params`; a parameter is `params.<name>`).
    pub params: Field,
    /// The chart.
    pub chart: Field,
    /// The initial positions.
    pub q0: Field,
    /// The initial momenta.
    pub p0: Field,
    /// The step size.
    pub h: Field,
    /// The final time.
    pub t_end: Field,
    /// What is blamed for too many steps.
    pub steps: Field,
    /// The sampling interval.
    pub every: Field,
    /// The list of methods.
    pub methods: Field,
    /// The reference comparison.
    pub compare_to_reference: Field,
    /// The Jacobian determinant defect.
    pub jacobian_defect: Field,
}

impl Default for InputFields {
    fn default() -> Self {
        InputFields {
            system: "system".into(),
            params: "params".into(),
            chart: "chart".into(),
            q0: "q0".into(),
            p0: "p0".into(),
            h: "h".into(),
            t_end: "t_end".into(),
            steps: "t_end".into(),
            every: "output.every".into(),
            methods: "methods".into(),
            compare_to_reference: "compare_to_reference".into(),
            jacobian_defect: "jacobian_defect".into(),
        }
    }
}

/// A simulation request in core terms (the HTTP and CLI layers parse into this).
#[derive(Clone, Debug, PartialEq)]
pub struct SimulationSpec {
    /// The system: a catalogue id or a user's definition.
    pub system: SystemRef,
    /// System parameters by name (omitted ones take their defaults).
    pub params: BTreeMap<String, ParamValue>,
    /// Coordinate chart (default: the system's first, Cartesian one).
    pub chart: Option<String>,
    /// Whether `q0`/`p0` are given in Cartesian coordinates (transformed into the chart) rather
    /// than in the chart's own.
    pub initial_cartesian: bool,
    /// Methods to run, in order.
    pub methods: Vec<MethodAt>,
    /// Step size.
    pub h: f64,
    /// Final time.
    pub t_end: f64,
    /// Initial positions (default from the catalogue).
    pub q0: Option<Vec<f64>>,
    /// Initial momenta (default from the catalogue).
    pub p0: Option<Vec<f64>>,
    /// Sample every this many steps (default: about 1000 samples per method).
    pub every: Option<u64>,
    /// Measure energy errors against the reference integrator.
    pub compare_to_reference: bool,
    /// Report the per-step Jacobian determinant defect.
    pub jacobian_defect: bool,
    /// Where each input came from.
    pub fields: InputFields,
}

impl SimulationSpec {
    /// A spec of `system` with default parameters, state and sampling, running `methods` (named
    /// `methods[i]`) with step `h` to `t_end`.
    pub fn new(system: impl Into<SystemRef>, methods: &[Method], h: f64, t_end: f64) -> Self {
        let fields = InputFields::default();
        SimulationSpec {
            system: system.into(),
            params: BTreeMap::new(),
            chart: None,
            initial_cartesian: false,
            methods: methods
                .iter()
                .enumerate()
                .map(|(i, m)| MethodAt {
                    method: *m,
                    field: fields.methods.index(i),
                })
                .collect(),
            h,
            t_end,
            q0: None,
            p0: None,
            every: None,
            compare_to_reference: false,
            jacobian_defect: false,
            fields,
        }
    }

    /// The number parameter `name` set to `value`.
    pub fn param(mut self, name: &str, value: f64) -> Self {
        self.params
            .insert(name.to_string(), ParamValue::Number(value));
        self
    }
}

/// A validated simulation, ready to run.
#[derive(Clone, Debug)]
pub struct Simulation {
    /// The system's catalogue entry.
    pub info: Arc<SystemInfo>,
    /// All parameters, defaults filled in.
    pub params: ParamValues,
    /// The coordinate chart.
    pub chart: ChartInfo,
    /// How the system appears in space.
    pub world: World,
    /// The system (and chart, when not the default) as messages name it.
    pub system_label: String,
    /// The concrete system.
    pub system: AnySystem,
    /// The methods, in the order asked.
    pub methods: Vec<Method>,
    /// Initial positions, in the chart's coordinates.
    pub q0: Vec<f64>,
    /// Initial momenta, in the chart's coordinates.
    pub p0: Vec<f64>,
    /// Step schedule.
    pub schedule: Schedule,
    /// Whether energy errors come from the reference integrator.
    pub compare_to_reference: bool,
    /// Whether to report the Jacobian determinant defect.
    pub jacobian_defect: bool,
    /// The section and event surfaces each run watches (see [`Simulation::watching`]).
    pub crossings: Option<Arc<crate::sections::Crossings>>,
    /// The chaos indicators each run reports (see [`Simulation::with_chaos`]).
    pub chaos: Option<ChaosPlan>,
    /// Where each method was given (`methods[i]`), as errors name it.
    pub method_fields: Vec<Field>,
}

/// A given list (or the default) with the system's dimension and finite entries.
fn state_vector(
    field: &Field,
    given: &Option<Vec<f64>>,
    default: &[f64],
    n: usize,
) -> Result<Vec<f64>, CoreError> {
    let v = given.clone().unwrap_or_else(|| default.to_vec());
    if v.len() != n {
        return Err(CoreError::WrongLength {
            field: field.clone(),
            expected: n,
            got: v.len(),
        });
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(CoreError::NotFinite {
            field: field.index(i),
        });
    }
    Ok(v)
}

impl Simulation {
    /// The initial state (q0, p0) that [`Simulation::prepare`] would give `spec`, or its error,
    /// where `spec` differs from the spec `self` was prepared from in its initial state only
    /// (the cells of a basin map): only the initial state is checked and converted again, with
    /// `self`'s system, chart and catalogue entry, which the rest of the spec fixes.
    pub(crate) fn start_of(
        &self,
        spec: &SimulationSpec,
    ) -> Result<(Vec<f64>, Vec<f64>), CoreError> {
        initial_state(spec, &self.info, &self.chart, &self.system)
    }

    /// The predicted work, for admission before it starts: steps × phase-space coordinates
    /// summed over the runs (a reference run beside each method counts as one more, and each
    /// deviation vector as one more state).
    pub fn cost(&self) -> u64 {
        let runs = self.methods.len() as u64 * if self.compare_to_reference { 2 } else { 1 };
        // Deviation vectors cost about as much as the state each.
        let vectors = self.chaos.as_ref().map_or(1, |c| 1 + c.deviations as u64);
        let coordinates = 2 * self.q0.len() as u64 * vectors;
        self.schedule
            .steps
            .saturating_mul(coordinates)
            .saturating_mul(runs)
    }

    /// Validates a spec against the catalogues and the limits.
    pub fn prepare(spec: &SimulationSpec, limits: &Limits) -> Result<Simulation, CoreError> {
        let f = &spec.fields;
        let info = spec.system.resolve(&f.system)?;
        let chart = *info.chart(spec.chart.as_deref(), &f.chart)?;
        let params = systems::params::resolve(&info, &spec.params, &f.params)?;
        let h = Range::POSITIVE.check(spec.h, &f.h)?;
        let system = info.build(&params, &chart, h)?;
        let world = info.world(&params)?;
        let default_chart = chart.id == info.charts[0].id;
        let system_label = if default_chart {
            info.id.to_string()
        } else {
            format!("{} ({} chart)", info.id, chart.id)
        };
        let (q0, p0) = initial_state(spec, &info, &chart, &system)?;
        let t_end = Range::POSITIVE.check(spec.t_end, &f.t_end)?;
        if spec.methods.is_empty() {
            return Err(CoreError::Empty {
                field: f.methods.clone(),
                what: "method",
            });
        }
        if spec.methods.len() > MAX_METHODS {
            return Err(CoreError::TooMany {
                field: f.methods.clone(),
                what: "methods per request",
                limit: MAX_METHODS,
                got: None,
            });
        }
        let steps = step_count(h, t_end);
        if steps > limits.max_steps {
            return Err(CoreError::TooManySteps {
                field: f.steps.clone(),
                steps,
                limit: limits.max_steps,
                scope: StepScope::PerMethod,
            });
        }
        let every = match spec.every {
            Some(0) => {
                return Err(CoreError::OutOfRange {
                    field: f.every.clone(),
                    value: 0.0,
                    range: Range::above(1.0, false),
                })
            }
            Some(k) => k,
            None => (steps / 1000).max(1),
        };
        let schedule = Schedule { h, steps, every };
        let samples = schedule.samples().saturating_mul(spec.methods.len() as u64);
        if samples > limits.max_samples {
            return Err(CoreError::TooManySamples {
                field: f.every.clone(),
                samples,
                limit: limits.max_samples,
            });
        }
        for at in &spec.methods {
            let origin = MethodOrigin {
                method: &at.field,
                h: &f.h,
                system: &system_label,
            };
            with_system!(&system, s => build::check(&at.method, s, h, &origin))?;
            if spec.jacobian_defect {
                if let Some(why) = at.method.no_step_jacobian() {
                    return Err(CoreError::NoStepJacobian {
                        field: at.field.clone(),
                        method: at.method.id().as_str(),
                        why,
                    });
                }
            }
        }
        if spec.jacobian_defect {
            let (st, driven) = with_system!(&system, s => (s.structure(), s.clock().is_some()));
            if driven {
                return Err(CoreError::Unsupported {
                    field: f.jacobian_defect.clone(),
                    reason: "the determinant defect is defined for autonomous systems only (this \
                             one depends on the time t)",
                });
            }
            if !(st.conformal_damping && st.separable_constant_mass) {
                return Err(CoreError::Unsupported {
                    field: f.jacobian_defect.clone(),
                    reason: "the determinant defect is defined for conformal damping (D ∝ M) only",
                });
            }
        }
        Ok(Simulation {
            info,
            params,
            chart,
            world,
            system_label,
            system,
            methods: spec.methods.iter().map(|m| m.method).collect(),
            q0,
            p0,
            schedule,
            compare_to_reference: spec.compare_to_reference,
            jacobian_defect: spec.jacobian_defect,
            crossings: None,
            chaos: None,
            method_fields: spec.methods.iter().map(|m| m.field.clone()).collect(),
        })
    }

    /// The same simulation with its runs reporting the chaos indicators of `spec`: checked
    /// against the system's dimension, each method (it needs a step Jacobian) and the system (a
    /// state-dependent damping needs the derivative of its projector).
    pub fn with_chaos(mut self, spec: &ChaosSpec) -> Result<Simulation, CoreError> {
        let plan = spec.plan(self.q0.len())?;
        if self.jacobian_defect {
            return Err(CoreError::Either {
                field: spec.fields.indicators.clone(),
                first: "`jacobian_defect`",
                second: "`indicators`",
            });
        }
        for (method, field) in self.methods.iter().zip(&self.method_fields) {
            if let Some(why) = method.no_step_jacobian() {
                return Err(CoreError::NoTangentMap {
                    field: field.clone(),
                    method: method.label(),
                    system: self.system_label.clone(),
                    why: format!("{why} no step Jacobian"),
                });
            }
        }
        // Each method's tangent map, tried at the start: a system whose damping it cannot
        // differentiate is refused here, by the stepper itself, rather than at the first step.
        for (method, field) in self.methods.iter().zip(&self.method_fields) {
            let refused = with_system!(&self.system, s => {
                // A driven system's state carries its clock (extended phase space).
                let mut z = State::at_time(s, 0.0, &self.q0, &self.p0);
                let mut tangent = Tangent::with_columns(s, &z, chaos::frame::start(z.q.len(), 1));
                methods::build(method, s, &self.system_label, self.schedule.h)
                    .ok()
                    .and_then(|mut st| st.step_tangent(s, &mut z, self.schedule.h, &mut tangent).err())
            });
            if let Some(StepError::TangentUnsupported { reason }) = refused {
                return Err(CoreError::NoTangentMap {
                    field: field.clone(),
                    method: method.label(),
                    system: self.system_label.clone(),
                    why: reason.to_string(),
                });
            }
        }
        self.chaos = Some(plan);
        Ok(self)
    }

    /// The system's id.
    pub fn system_id(&self) -> &str {
        &self.info.id
    }

    /// How the system appears in space.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// What the runs' energy errors are measured against: the reference run when asked for,
    /// else the exact solution where the system has one, else H₀ when nothing damps or drives
    /// the system (its exact flow keeps H); none for a damped or driven system without either.
    pub fn energy_reference(&self) -> Option<EnergyReference> {
        let (rate, driven) =
            with_system!(&self.system, s => (s.damping_rate(), s.clock().is_some()));
        let damped = rate != 0.0;
        if self.compare_to_reference {
            Some(EnergyReference::Reference)
        } else if self.info.exact_solution {
            Some(EnergyReference::Exact)
        } else if !damped && !driven {
            Some(EnergyReference::Initial)
        } else {
            None
        }
    }

    /// Whether energy errors are available.
    pub fn has_energy_error(&self) -> bool {
        self.energy_reference().is_some()
    }

    /// Names of the system's invariants.
    pub fn invariant_names(&self) -> Vec<String> {
        self.info.invariants.iter().map(|n| n.to_string()).collect()
    }

    /// The exact final state (q, p) at the end of the schedule, where the system has a closed
    /// form.
    pub fn exact_final_state(&self) -> Option<(Vec<f64>, Vec<f64>)> {
        let t_end = self.schedule.h * self.schedule.steps as f64;
        with_system!(&self.system, sys => {
            let start = State::at_time(sys, 0.0, &self.q0, &self.p0);
            sys.exact(t_end, &start).map(|z| {
                let (q, p) = z.physical(sys);
                (q.to_vec(), p.to_vec())
            })
        })
    }

    /// A state of this simulation's chart in Cartesian coordinates (unchanged in a Cartesian
    /// chart).
    pub fn cartesian_state(&self, q: &[f64], p: &[f64]) -> (Vec<f64>, Vec<f64>) {
        with_system!(&self.system, sys => {
            if sys.clock().is_some() {
                // Typed-in systems are in their own (Cartesian) coordinates.
                return (q.to_vec(), p.to_vec());
            }
            let z = State::from_slices(sys.dim(), q, p);
            let (mut x, mut px) = (q.to_vec(), p.to_vec());
            sys.to_cartesian(&z.q, &z.p, &mut x, &mut px);
            (x, px)
        })
    }

    /// The exact final state in Cartesian coordinates (see
    /// [`exact_final_state`](Self::exact_final_state)).
    pub fn exact_final_cartesian(&self) -> Option<(Vec<f64>, Vec<f64>)> {
        self.exact_final_state()
            .map(|(q, p)| self.cartesian_state(&q, &p))
    }
}

/// The initial state in the chart's coordinates: the given one (transformed from Cartesian
/// coordinates when asked) or the catalogue's Cartesian default transformed into the chart.
fn initial_state(
    spec: &SimulationSpec,
    info: &SystemInfo,
    chart: &ChartInfo,
    system: &AnySystem,
) -> Result<(Vec<f64>, Vec<f64>), CoreError> {
    let f = &spec.fields;
    let n = system.degrees_of_freedom();
    // For N bodies the default state belongs to the default masses.
    let default_fits = n == info.q0.len();
    let (dq, dp) = if default_fits {
        (info.q0.as_slice(), info.p0.as_slice())
    } else {
        (&[][..], &[][..])
    };
    if !default_fits && (spec.q0.is_none() || spec.p0.is_none()) {
        return Err(CoreError::NeedsInitialState {
            field: if spec.q0.is_none() {
                f.q0.clone()
            } else {
                f.p0.clone()
            },
            dimension: n,
        });
    }
    let q0 = state_vector(&f.q0, &spec.q0, dq, n)?;
    let p0 = state_vector(&f.p0, &spec.p0, dp, n)?;
    // The catalogue's defaults are Cartesian; so are given values when asked.
    let given = spec.q0.is_some() || spec.p0.is_some();
    let default_chart = chart.id == info.charts[0].id;
    if default_chart || !(spec.initial_cartesian || !given) {
        return Ok((q0, p0));
    }
    with_system!(system, s => {
        let mut z = State::from_slices(s.dim(), &q0, &p0);
        s.from_cartesian(&q0, &p0, &mut z.q, &mut z.p)
            .map(|()| (z.q.as_slice().to_vec(), z.p.as_slice().to_vec()))
    })
    .map_err(|reason| CoreError::OutsideChart {
        field: if given { f.q0.clone() } else { f.chart.clone() },
        chart: chart.id.to_string(),
        reason,
    })
}
