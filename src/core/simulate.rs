//! A simulation as users ask for it: a system with parameters and initial state, one or more
//! methods, a step and a horizon, and the sampling. [`Simulation::prepare`] validates everything
//! (cheap, before any work is queued); [`Simulation::run_method`] integrates one method and feeds
//! its samples, with energies, energy errors and invariants, to a [`SampleSink`].

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;
use serde::Serialize;

use super::error::CoreError;
use super::methods::{self, MethodChoice, MethodInput};
use super::run::{integrate, Budget, Observer, RunStats, Schedule, StopReason};
use super::system::{MechanicalSystem, State};
use super::systems::{self, AnySystem, Params, Resolved};
use crate::{with_stepper, with_system};

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

/// A simulation request in core terms (the HTTP and CLI layers deserialize into this).
#[derive(Clone, Debug, Default)]
pub struct Request {
    /// System id.
    pub system: String,
    /// System parameters.
    pub params: Params,
    /// Coordinate chart (default: the system's first, Cartesian one).
    pub chart: Option<String>,
    /// Whether `q0`/`p0` are given in Cartesian coordinates (transformed into the chart) rather
    /// than in the chart's own.
    pub initial_cartesian: bool,
    /// Methods to run.
    pub methods: Vec<MethodInput>,
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
}

/// A validated simulation, ready to run.
#[derive(Clone, Debug)]
pub struct Simulation {
    /// System id.
    pub system_id: String,
    /// All parameters, defaults filled in.
    pub params: Resolved,
    /// The coordinate chart.
    pub chart: String,
    /// The system (and chart, when not the default) as errors name it.
    pub system_label: String,
    /// The concrete system.
    pub system: AnySystem,
    /// Validated methods, in the order asked.
    pub methods: Vec<MethodChoice>,
    /// Initial positions.
    pub q0: Vec<f64>,
    /// Initial momenta.
    pub p0: Vec<f64>,
    /// Step schedule.
    pub schedule: Schedule,
    /// Whether energy errors come from the reference integrator.
    pub compare_to_reference: bool,
    /// Whether to report the Jacobian determinant defect.
    pub jacobian_defect: bool,
}

/// One sample as sinks receive it.
#[derive(Clone, Debug, Serialize)]
pub struct Sample<'a> {
    /// Step index.
    pub step: u64,
    /// Time.
    pub t: f64,
    /// Positions.
    pub q: &'a [f64],
    /// Momenta.
    pub p: &'a [f64],
    /// The state in Cartesian coordinates (positions, momenta) when the chart is not.
    pub cartesian: Option<(&'a [f64], &'a [f64])>,
    /// Total energy H.
    pub energy: f64,
    /// H − H_exact (exact solution or reference), when known.
    pub energy_error: Option<f64>,
    /// Invariants, in the order of the system's invariant names.
    pub invariants: &'a [f64],
    /// |det ∂Φ/∂z − e^{−r h n}| of the step that ended here, when asked for.
    pub jacobian_defect: Option<f64>,
}

/// Receives samples of one method's run.
pub trait SampleSink {
    /// One sample.
    fn on_sample(&mut self, sample: &Sample<'_>);
}

/// How one method's run ended.
#[derive(Clone, Debug, Serialize)]
pub struct Outcome {
    /// Why it stopped.
    pub stop: StopReason,
    /// Statistics.
    pub stats: RunStats,
}

fn field_vec(
    name: &str,
    given: &Option<Vec<f64>>,
    default: &[f64],
    n: usize,
) -> Result<Vec<f64>, CoreError> {
    let v = given.clone().unwrap_or_else(|| default.to_vec());
    if v.len() != n {
        return Err(CoreError::invalid(
            name,
            format!("needs {n} entries for this system, got {}", v.len()),
        ));
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(CoreError::invalid(format!("{name}[{i}]"), "must be finite"));
    }
    Ok(v)
}

impl Simulation {
    /// Validates a request against the catalogues and the limits.
    pub fn prepare(req: &Request, limits: &Limits) -> Result<Simulation, CoreError> {
        let info = systems::info(&req.system)?;
        let chart = systems::chart_of(&info, req.chart.as_deref())?;
        let params = systems::resolve(&info, &req.params)?;
        if !(req.h.is_finite() && req.h > 0.0) {
            return Err(CoreError::invalid(
                "h",
                format!("must be finite and > 0, got {}", req.h),
            ));
        }
        let system = systems::build(&req.system, chart.id, &params, req.h)?;
        let default_chart = chart.id == info.charts[0].id;
        let system_label = if default_chart {
            req.system.clone()
        } else {
            format!("{} ({} chart)", req.system, chart.id)
        };
        let n = system.dimension();
        // For N bodies the default state belongs to the default masses.
        let default_fits = n == info.q0.len();
        let (dq, dp) = if default_fits {
            (info.q0.clone(), info.p0.clone())
        } else {
            (vec![], vec![])
        };
        if !default_fits && (req.q0.is_none() || req.p0.is_none()) {
            return Err(CoreError::invalid(
                if req.q0.is_none() { "q0" } else { "p0" },
                format!("give q0 and p0 ({n} entries each) for a non-default number of bodies"),
            ));
        }
        let mut q0 = field_vec("q0", &req.q0, &dq, n)?;
        let mut p0 = field_vec("p0", &req.p0, &dp, n)?;
        // The catalogue's defaults are Cartesian; so are given values when asked.
        let given = req.q0.is_some() || req.p0.is_some();
        if !default_chart && (req.initial_cartesian || !given) {
            let field = if given { "q0" } else { "chart" };
            (q0, p0) = with_system!(&system, s => {
                let mut z = State::from_slices(s.dim(), &q0, &p0);
                s.from_cartesian(&q0, &p0, &mut z.q, &mut z.p)
                    .map(|()| (z.q.as_slice().to_vec(), z.p.as_slice().to_vec()))
            })
            .map_err(|why| {
                CoreError::invalid(
                    field,
                    format!(
                        "the initial state is outside the `{}` chart: {why}",
                        chart.id
                    ),
                )
            })?;
        }
        if !(req.t_end.is_finite() && req.t_end > 0.0) {
            return Err(CoreError::invalid(
                "t_end",
                format!("must be finite and > 0, got {}", req.t_end),
            ));
        }
        if req.methods.is_empty() {
            return Err(CoreError::invalid("methods", "give at least one method"));
        }
        if req.methods.len() > 16 {
            return Err(CoreError::invalid(
                "methods",
                "at most 16 methods per request",
            ));
        }
        let steps = super::run::step_count(req.h, req.t_end);
        if steps > limits.max_steps {
            return Err(CoreError::invalid(
                "t_end",
                format!(
                    "t_end/h = {steps} steps exceeds the limit of {} per method",
                    limits.max_steps
                ),
            ));
        }
        let every = match req.every {
            Some(0) => return Err(CoreError::invalid("output.every", "must be ≥ 1")),
            Some(k) => k,
            None => (steps / 1000).max(1),
        };
        let schedule = Schedule {
            h: req.h,
            steps,
            every,
        };
        let total_samples = schedule.samples().saturating_mul(req.methods.len() as u64);
        if total_samples > limits.max_samples {
            return Err(CoreError::invalid(
                "output.every",
                format!(
                    "{total_samples} samples in all exceeds the limit of {}; sample less often",
                    limits.max_samples
                ),
            ));
        }
        let mut methods = Vec::with_capacity(req.methods.len());
        for (i, input) in req.methods.iter().enumerate() {
            let choice = MethodChoice::parse(input, &format!("methods[{i}]"))?;
            // Building checks requirements and step-size limits; the stepper itself is dropped.
            with_system!(&system, s => methods::build(&choice, s, &system_label, req.h).map(|_| ()))?;
            let no_jacobian = match choice.id {
                methods::MethodId::Reference => Some("the adaptive reference has"),
                methods::MethodId::Rowlands => {
                    Some("rowlands (whose modified kick would need third derivatives of V) has")
                }
                _ => None,
            };
            if let Some(which) = no_jacobian.filter(|_| req.jacobian_defect) {
                return Err(CoreError::invalid(
                    format!("methods[{i}]"),
                    format!("{which} no step Jacobian; drop it or jacobian_defect"),
                ));
            }
            methods.push(choice);
        }
        if req.jacobian_defect {
            let st = with_system!(&system, s => s.structure());
            if !(st.conformal_damping && st.separable_constant_mass) {
                return Err(CoreError::invalid(
                    "jacobian_defect",
                    "the determinant defect is defined for conformal damping (D ∝ M) only",
                ));
            }
        }
        Ok(Simulation {
            system_id: req.system.clone(),
            params,
            chart: chart.id.to_string(),
            system_label,
            system,
            methods,
            q0,
            p0,
            schedule,
            compare_to_reference: req.compare_to_reference,
            jacobian_defect: req.jacobian_defect,
        })
    }

    /// Whether energy errors are available (an exact solution, or the reference when asked).
    pub fn has_energy_error(&self) -> bool {
        self.compare_to_reference
            || systems::info(&self.system_id)
                .map(|i| i.exact_solution)
                .unwrap_or(false)
    }

    /// Names of the system's invariants.
    pub fn invariant_names(&self) -> &'static [&'static str] {
        with_system!(&self.system, s => s.invariant_names())
    }

    /// The exact final state (q, p) at the end of the schedule, where the system has a closed
    /// form.
    pub fn exact_final_state(&self) -> Option<(Vec<f64>, Vec<f64>)> {
        let t_end = self.schedule.h * self.schedule.steps as f64;
        with_system!(&self.system, sys => {
            let start = State::from_slices(sys.dim(), &self.q0, &self.p0);
            sys.exact(t_end, &start)
                .map(|z| (z.q.as_slice().to_vec(), z.p.as_slice().to_vec()))
        })
    }

    /// A state of this simulation's chart in Cartesian coordinates (unchanged in a Cartesian
    /// chart).
    pub fn cartesian_state(&self, q: &[f64], p: &[f64]) -> (Vec<f64>, Vec<f64>) {
        with_system!(&self.system, sys => {
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

    /// The reference energies at the sample times (None unless `compare_to_reference`).
    pub fn reference_energies(&self, budget: Budget<'_>) -> Result<Option<Vec<f64>>, CoreError> {
        if !self.compare_to_reference {
            return Ok(None);
        }
        let choice = MethodChoice::new(methods::MethodId::Reference);
        let mut sink = EnergyLog(Vec::with_capacity(self.schedule.samples() as usize));
        let outcome = self.run_choice(&choice, None, budget, &mut sink)?;
        if outcome.stop != StopReason::Finished {
            return Err(CoreError::invalid(
                "compare_to_reference",
                format!("the reference run did not finish ({:?})", outcome.stop),
            ));
        }
        Ok(Some(sink.0))
    }

    /// Runs method `index`, sending samples to `sink`. `reference` holds reference energies per
    /// sample (from [`Simulation::reference_energies`]).
    pub fn run_method(
        &self,
        index: usize,
        reference: Option<&[f64]>,
        budget: Budget<'_>,
        sink: &mut dyn SampleSink,
    ) -> Result<Outcome, CoreError> {
        self.run_choice(&self.methods[index], reference, budget, sink)
    }

    fn run_choice(
        &self,
        choice: &MethodChoice,
        reference: Option<&[f64]>,
        budget: Budget<'_>,
        sink: &mut dyn SampleSink,
    ) -> Result<Outcome, CoreError> {
        with_system!(&self.system, sys => {
            let mut stepper = methods::build(choice, sys, &self.system_label, self.schedule.h)?;
            let start = State::from_slices(sys.dim(), &self.q0, &self.p0);
            let mut z = start.clone();
            let mut observer = Diagnose {
                sys,
                start: &start,
                reference,
                sink,
                invariants: vec![0.0; sys.invariant_names().len()],
                cartesian: (!sys.is_cartesian()).then(|| (vec![0.0; self.q0.len()], vec![0.0; self.q0.len()])),
                expected_det: (-sys.damping_rate() * self.schedule.h * self.q0.len() as f64).exp(),
                last_det: None,
                sample_index: 0,
            };
            let (stop, stats) = with_stepper!(&mut stepper, st => integrate(
                sys,
                st,
                &mut z,
                self.schedule,
                budget,
                // The reference run only supplies energies; it has no tangent map.
                self.jacobian_defect && choice.id != methods::MethodId::Reference,
                &mut observer,
            ))?;
            Ok(Outcome { stop, stats })
        })
    }
}

/// Collects only energies (for the reference run).
struct EnergyLog(Vec<f64>);

impl SampleSink for EnergyLog {
    fn on_sample(&mut self, sample: &Sample<'_>) {
        self.0.push(sample.energy);
    }
}

/// The observer that turns raw states into [`Sample`]s.
struct Diagnose<'a, S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    sys: &'a S,
    start: &'a State<S::Dim>,
    reference: Option<&'a [f64]>,
    sink: &'a mut dyn SampleSink,
    invariants: Vec<f64>,
    /// Buffers for the Cartesian state, when the chart is not Cartesian.
    cartesian: Option<(Vec<f64>, Vec<f64>)>,
    expected_det: f64,
    last_det: Option<f64>,
    sample_index: usize,
}

impl<S: MechanicalSystem> Observer<S::Dim> for Diagnose<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn on_sample(&mut self, step: u64, t: f64, z: &State<S::Dim>) {
        let energy = self.sys.energy(&z.q, &z.p);
        let energy_error = match self.reference {
            Some(r) => r.get(self.sample_index).map(|e| energy - e),
            None => self
                .sys
                .exact(t, self.start)
                .map(|x| energy - self.sys.energy(&x.q, &x.p)),
        };
        self.sys.invariants(t, &z.q, &z.p, &mut self.invariants);
        if let Some((x, px)) = self.cartesian.as_mut() {
            self.sys.to_cartesian(&z.q, &z.p, x, px);
        }
        self.sink.on_sample(&Sample {
            step,
            t,
            q: z.q.as_slice(),
            p: z.p.as_slice(),
            cartesian: self
                .cartesian
                .as_ref()
                .map(|(x, px)| (x.as_slice(), px.as_slice())),
            energy,
            energy_error,
            invariants: &self.invariants,
            jacobian_defect: self.last_det.map(|d| (d - self.expected_det).abs()),
        });
        self.sample_index += 1;
    }

    fn on_step_determinant(&mut self, _step: u64, det: f64) {
        self.last_det = Some(det);
    }
}

/// A whole run in memory: what the JSON response carries per method.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Trajectory {
    /// Sample times.
    pub t: Vec<f64>,
    /// Positions per sample.
    pub q: Vec<Vec<f64>>,
    /// Momenta per sample.
    pub p: Vec<Vec<f64>>,
    /// Cartesian positions per sample, when the chart is not Cartesian.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cartesian_q: Option<Vec<Vec<f64>>>,
    /// Cartesian momenta per sample, when the chart is not Cartesian.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cartesian_p: Option<Vec<Vec<f64>>>,
    /// Energy per sample.
    pub energy: Vec<f64>,
    /// Energy error per sample, when known.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub energy_error: Option<Vec<f64>>,
    /// Invariants per sample, one column per invariant.
    pub invariant_columns: Vec<Vec<f64>>,
    /// Jacobian determinant defect per sample (from the step ending there), when asked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub jacobian_defect: Option<Vec<f64>>,
}

impl SampleSink for Trajectory {
    fn on_sample(&mut self, s: &Sample<'_>) {
        self.t.push(s.t);
        self.q.push(s.q.to_vec());
        self.p.push(s.p.to_vec());
        if let Some((x, px)) = s.cartesian {
            self.cartesian_q
                .get_or_insert_with(Vec::new)
                .push(x.to_vec());
            self.cartesian_p
                .get_or_insert_with(Vec::new)
                .push(px.to_vec());
        }
        self.energy.push(s.energy);
        if let Some(e) = s.energy_error {
            self.energy_error.get_or_insert_with(Vec::new).push(e);
        }
        if self.invariant_columns.len() != s.invariants.len() {
            self.invariant_columns = vec![Vec::new(); s.invariants.len()];
        }
        for (column, &v) in self.invariant_columns.iter_mut().zip(s.invariants) {
            column.push(v);
        }
        if let Some(d) = s.jacobian_defect {
            self.jacobian_defect.get_or_insert_with(Vec::new).push(d);
        }
    }
}

impl Simulation {
    /// The dissipation drift of paper 003 eq. (4.4) for a 1-DOF system with conformal damping,
    /// from a run's samples; `None` for other systems.
    pub fn dissipation_drift(
        &self,
        run: &Trajectory,
    ) -> Option<Vec<super::diagnostics::DriftPoint>> {
        let conformal = with_system!(&self.system, s => s.structure().conformal_damping);
        if self.q0.len() != 1 || !conformal {
            return None;
        }
        let gamma = 0.5 * with_system!(&self.system, s => s.damping_rate());
        let q: Vec<f64> = run.q.iter().map(|q| q[0]).collect();
        Some(super::diagnostics::dissipation_drift(&run.t, &q, gamma))
    }
}

/// Runs method `index` of `sim` into a [`Trajectory`].
pub fn run_to_trajectory(
    sim: &Simulation,
    index: usize,
    reference: Option<&[f64]>,
    budget: Budget<'_>,
) -> Result<(Trajectory, Outcome), CoreError> {
    let mut trajectory = Trajectory::default();
    let outcome = sim.run_method(index, reference, budget, &mut trajectory)?;
    Ok((trajectory, outcome))
}
