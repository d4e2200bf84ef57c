//! Helpers shared by the core integration tests.

use geomint_core::methods::{self, Method, MethodId};
use geomint_core::run::{integrate, Budget, Observer, RunEnd, Schedule, Stepper};
use geomint_core::simulation::{
    ColumnSink, Columns, Limits, RunReport, Simulation, SimulationSpec,
};
use geomint_core::system::{MechanicalSystem, State};
use geomint_core::systems::ParamValue;
use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

/// An observer that ignores samples.
pub struct Discard;
impl<D: nalgebra::Dim> Observer<D> for Discard
where
    DefaultAllocator: Allocator<D>,
{
    fn on_sample(&mut self, _: u64, _: f64, _: &State<D>) {}
}

/// Integrates `choice` on `sys` from `start` to `t_end` with step `h`; returns the end state.
pub fn final_state<S: MechanicalSystem>(
    sys: &S,
    choice: &Method,
    start: &State<S::Dim>,
    h: f64,
    t_end: f64,
) -> State<S::Dim>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let (z, stop, _) = run_schedule(sys, choice, start, Schedule::new(h, t_end, u64::MAX));
    assert_eq!(stop, RunEnd::Finished);
    z
}

/// Integrates `choice` on `sys` from `start` on `schedule`, samples discarded; returns the end
/// state, the stop reason and the force evaluations. The sampling interval decides how many steps
/// the driver hands the stepper at once.
pub fn run_schedule<S: MechanicalSystem>(
    sys: &S,
    choice: &Method,
    start: &State<S::Dim>,
    schedule: Schedule,
) -> (State<S::Dim>, RunEnd, u64)
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let mut stepper = methods::build(choice, sys, "test", schedule.h).expect("method builds");
    run_stepper(sys, &mut stepper, start, schedule)
}

/// [`run_schedule`] with a stepper made by the caller.
pub fn run_stepper<S: MechanicalSystem, M: Stepper<S>>(
    sys: &S,
    stepper: &mut M,
    start: &State<S::Dim>,
    schedule: Schedule,
) -> (State<S::Dim>, RunEnd, u64)
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let mut z = start.clone();
    let (stop, stats) = integrate(
        sys,
        stepper,
        &mut z,
        schedule,
        Budget::default(),
        &mut Discard,
    )
    .expect("run succeeds");
    (z, stop, stats.force_evaluations)
}

/// The numbers of a JSON object as system parameters.
pub fn params(params: serde_json::Value) -> std::collections::BTreeMap<String, ParamValue> {
    params
        .as_object()
        .expect("params object")
        .iter()
        .map(|(k, v)| {
            let value = match v {
                serde_json::Value::Number(n) => ParamValue::Number(n.as_f64().unwrap()),
                serde_json::Value::String(s) => ParamValue::Text(s.clone()),
                serde_json::Value::Array(a) => {
                    ParamValue::Numbers(a.iter().map(|x| x.as_f64().unwrap()).collect())
                }
                _ => ParamValue::Other,
            };
            (k.clone(), value)
        })
        .collect()
}

/// The method of a request id.
pub fn method(id: &str) -> Method {
    Method::new(MethodId::parse(id).expect("a method id"))
}

/// A simulation spec sampling every step.
pub fn request(
    system: &str,
    params_json: serde_json::Value,
    methods: &[&str],
    h: f64,
    t_end: f64,
) -> SimulationSpec {
    let methods: Vec<Method> = methods.iter().map(|m| method(m)).collect();
    SimulationSpec {
        params: params(params_json),
        every: Some(1),
        ..SimulationSpec::new(system, &methods, h, t_end)
    }
}

/// Runs method `index` of `sim` into columns.
pub fn run_to_columns(
    sim: &Simulation,
    index: usize,
    reference: Option<&[f64]>,
    budget: Budget<'_>,
) -> Result<(Columns, RunReport), geomint_core::error::CoreError> {
    let mut sink = ColumnSink::new(sim.invariant_names());
    let outcome = sim.run_method(index, reference, budget, &mut sink)?;
    Ok((sink.take(), outcome))
}

/// Runs every method of `req`, returning their samples in order.
pub fn run_all(req: &SimulationSpec) -> (Simulation, Vec<Columns>) {
    let sim = Simulation::prepare(req, &Limits::default()).expect("valid request");
    let reference = sim
        .reference_energies(Budget::default())
        .expect("reference runs");
    let runs = (0..sim.methods.len())
        .map(|i| {
            run_to_columns(&sim, i, reference.as_deref(), Budget::default())
                .expect("run succeeds")
                .0
        })
        .collect();
    (sim, runs)
}

/// Every fixed-step method: each id but the reference with default options, every composition
/// base, every inner method of modin_rks and every processor of rowlands (which needs an
/// undamped system: see [`conservative_only`]).
pub fn every_fixed_step_choice() -> Vec<Method> {
    use geomint_core::methods::rowlands::Processor;
    use geomint_core::methods::{Base, Inner};
    let mut choices: Vec<Method> = MethodId::ALL
        .iter()
        .filter(|&&m| m != MethodId::Reference && m != MethodId::Rowlands)
        .map(|&m| Method::new(m))
        .collect();
    choices.extend(Processor::ALL.map(|processor| Method::Rowlands { processor }));
    choices.extend(Base::ALL.iter().map(|&b| Method::triple_jump(b)));
    choices.extend(Inner::ALL.iter().map(|&inner| Method::ModinRks { inner }));
    choices
}

/// Whether `choice` runs on undamped systems only (rowlands).
pub fn conservative_only(choice: &Method) -> bool {
    choice
        .requirements()
        .contains(&geomint_core::methods::Requirement::Conservative)
}

/// The system of catalogue entry `info` in `chart` with default parameters, for step `h`.
pub fn default_system(
    info: &geomint_core::systems::SystemInfo,
    chart: &geomint_core::systems::ChartInfo,
    h: f64,
) -> geomint_core::systems::AnySystem {
    let params = geomint_core::systems::params::resolve(
        info,
        &Default::default(),
        &geomint_core::error::Field::new("params"),
    )
    .expect("default parameters are valid");
    info.build(&params, chart, h)
        .expect("a catalogue system builds")
}

/// The catalogue entry of `id`.
pub fn info(id: &str) -> std::sync::Arc<geomint_core::systems::SystemInfo> {
    geomint_core::systems::info(id, &geomint_core::error::Field::new("system"))
        .expect("a catalogue system")
}

/// The Jacobian of one step of `choice` at `z` by central differences, each evaluation from a
/// fresh stepper.
pub fn step_jacobian_by_differences<S: MechanicalSystem>(
    sys: &S,
    choice: &Method,
    z: &State<S::Dim>,
    h: f64,
) -> nalgebra::DMatrix<f64>
where
    nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<S::Dim>,
{
    let n = z.q.len();
    let mut jac = nalgebra::DMatrix::zeros(2 * n, 2 * n);
    let step = |z: &State<S::Dim>| {
        let mut stepper = methods::build(choice, sys, "test", h).expect("builds");
        let mut z = z.clone();
        stepper.step(sys, &mut z, h).expect("a step");
        z
    };
    // Central differences at d and d/2, extrapolated: an error of O(d⁴), and Newton's stopping
    // tolerance (1e-12 of the state) enters as 1e-12/d only.
    let central = |j: usize, d: f64| {
        let (mut a, mut b) = (z.clone(), z.clone());
        if j < n {
            a.q[j] += d;
            b.q[j] -= d;
        } else {
            a.p[j - n] += d;
            b.p[j - n] -= d;
        }
        let (fa, fb) = (step(&a), step(&b));
        let mut column = vec![0.0; 2 * n];
        for i in 0..n {
            column[i] = (fa.q[i] - fb.q[i]) / (2.0 * d);
            column[n + i] = (fa.p[i] - fb.p[i]) / (2.0 * d);
        }
        column
    };
    for j in 0..2 * n {
        let d = 1e-3
            * (1.0
                + if j < n {
                    z.q[j].abs()
                } else {
                    z.p[j - n].abs()
                });
        let (coarse, fine) = (central(j, d), central(j, 0.5 * d));
        for i in 0..2 * n {
            jac[(i, j)] = (4.0 * fine[i] - coarse[i]) / 3.0;
        }
    }
    jac
}
