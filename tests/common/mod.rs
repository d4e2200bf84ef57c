//! Helpers shared by the core integration tests.
#![allow(dead_code)]

use geomint::core::methods::MethodInput;
use geomint::core::methods::{self, MethodChoice};
use geomint::core::run::{integrate, Budget, Observer, Schedule, StopReason};
use geomint::core::simulate::{run_to_trajectory, Limits, Request, Simulation, Trajectory};
use geomint::core::system::{MechanicalSystem, State};
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
    choice: &MethodChoice,
    start: &State<S::Dim>,
    h: f64,
    t_end: f64,
) -> State<S::Dim>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let mut stepper = methods::build(choice, sys, "test", h).expect("method builds");
    let mut z = start.clone();
    let (stop, _) = integrate(
        sys,
        &mut stepper,
        &mut z,
        Schedule::new(h, t_end, u64::MAX),
        Budget::default(),
        false,
        &mut Discard,
    )
    .expect("run succeeds");
    assert_eq!(stop, StopReason::Finished);
    z
}

/// A request sampling every step.
pub fn request(
    system: &str,
    params: serde_json::Value,
    methods: &[&str],
    h: f64,
    t_end: f64,
) -> Request {
    Request {
        system: system.into(),
        params: params.as_object().expect("params object").clone(),
        methods: methods
            .iter()
            .map(|m| MethodInput::Id(m.to_string()))
            .collect(),
        h,
        t_end,
        every: Some(1),
        ..Default::default()
    }
}

/// Runs every method of `req`, returning the trajectories in order.
pub fn run_all(req: &Request) -> (Simulation, Vec<Trajectory>) {
    let sim = Simulation::prepare(req, &Limits::default()).expect("valid request");
    let reference = sim
        .reference_energies(Budget::default())
        .expect("reference runs");
    let runs = (0..sim.methods.len())
        .map(|i| {
            run_to_trajectory(&sim, i, reference.as_deref(), Budget::default())
                .expect("run succeeds")
                .0
        })
        .collect();
    (sim, runs)
}

/// Every fixed-step method choice: each id but the reference with default options, every
/// triple-jump base, every inner method of modin_rks and every processor of rowlands (which
/// needs an undamped system: see [`conservative_only`]).
pub fn every_fixed_step_choice() -> Vec<MethodChoice> {
    use geomint::core::methods::rowlands::Processor;
    use geomint::core::methods::{MethodId, COMPOSITION_BASES, RKS_INNER};
    let mut choices: Vec<MethodChoice> = MethodId::ALL
        .iter()
        .filter(|&&m| m != MethodId::Reference && m != MethodId::Rowlands)
        .map(|&m| MethodChoice::new(m))
        .collect();
    choices.extend(Processor::ALL.map(MethodChoice::rowlands));
    choices.extend(
        COMPOSITION_BASES
            .iter()
            .map(|&b| MethodChoice::triple_jump(b)),
    );
    choices.extend(RKS_INNER.iter().map(|&i| MethodChoice::rks(i)));
    choices
}

/// Whether `choice` runs on undamped systems only (rowlands).
pub fn conservative_only(choice: &MethodChoice) -> bool {
    choice
        .requirements()
        .contains(&geomint::core::methods::Requirement::Conservative)
}
