//! A typed-in system's compiled steps, and the built-in Hénon–Heiles system's, give the generic
//! steppers' bits (the splitting composer's
//! fused stretches, Runge–Kutta steps): every sample, the force evaluations and how the run
//! stopped, over systems with each form of mass, undamped, with conformal damping and with a
//! projector damping, driven or not, for the splittings and compositions the stretches take, with
//! stretches of many lengths and runs that blow up inside one (their code built by an earlier run
//! of the same system, as a sweep's cells share it).

use std::sync::Arc;

use geomint_core::error::Field;
use geomint_core::flows::compiled::{StretchPlan, COMPILE_AFTER};
use geomint_core::methods::composition::Scheme;
use geomint_core::methods::lanes::runs::{RunLanes, LANES};
use geomint_core::methods::splitting::{
    SubFlow, CSV1, MODIN_3S, MODIN_RKS, POSITION_VERLET, VELOCITY_VERLET,
};
use geomint_core::methods::{Base, Method, MethodId};
use geomint_core::run::{Budget, RunEnd};
use geomint_core::simulation::{Limits, Sample, SampleSink, Simulation, SimulationSpec};
use geomint_core::system::{Lane, LaneForces, MechanicalSystem};
use geomint_core::systems::custom::{self, CustomDefinition, Damping, Energy, Mass};
use geomint_core::systems::{
    AnySystem, CustomSystem, HenonHeiles, ParamValue, SystemInfo, SystemRef,
};

use crate::chaos_map::expr;

/// Every sample's bits.
#[derive(Default, PartialEq, Debug)]
struct Bits(Vec<u64>);

impl SampleSink for Bits {
    fn on_sample(&mut self, s: &Sample<'_>) {
        self.0.push(s.step);
        self.0.extend(s.q.iter().chain(s.p).map(|x| x.to_bits()));
        self.0.push(s.energy.to_bits());
    }
}

fn system(
    coordinates: &[&str],
    mass: Mass,
    potential: &str,
    gamma: Option<f64>,
) -> Arc<SystemInfo> {
    let damping = gamma.map(|_| Damping::Conformal {
        gamma: expr("damping", "gamma"),
    });
    let parameters = gamma
        .map(|g| ("gamma".to_string(), g))
        .into_iter()
        .collect();
    defined(coordinates, mass, potential, damping, parameters)
}

/// The planar elastic pendulum, typed in, its spring damped along the rod (a projector).
fn elastic_pendulum() -> Arc<SystemInfo> {
    let r2 = "(x^2 + y^2)";
    let entry = |text: String| expr("damping", &text);
    let damping = Damping::Rayleigh {
        epsilon: expr("damping", "epsilon"),
        matrix: vec![
            vec![entry(format!("x^2/{r2}")), entry(format!("x*y/{r2}"))],
            vec![entry(format!("x*y/{r2}")), entry(format!("y^2/{r2}"))],
        ],
    };
    defined(
        &["x", "y"],
        Mass::Scalar(expr("mass", "m")),
        "k/2*(sqrt(x^2 + y^2) - l)^2 - m*g*y",
        Some(damping),
        [
            ("k", 1.0),
            ("l", 1.0),
            ("m", 1.3),
            ("g", 0.2),
            ("epsilon", 0.1),
        ]
        .map(|(name, value)| (name.to_string(), value))
        .to_vec(),
    )
}

fn defined(
    coordinates: &[&str],
    mass: Mass,
    potential: &str,
    damping: Option<Damping>,
    parameters: Vec<(String, f64)>,
) -> Arc<SystemInfo> {
    let definition = CustomDefinition {
        field: Field::new("system"),
        name: None,
        coordinates: coordinates.iter().map(|c| c.to_string()).collect(),
        momenta: None,
        energy: Energy::Separable {
            mass,
            potential: expr("potential", potential),
        },
        damping,
        parameters,
        invariants: Vec::new(),
        positions: None,
        q0: None,
        p0: None,
    };
    custom::define(definition, "test").expect("a valid definition")
}

/// Steps per run: past `COMPILE_AFTER`, so that a run builds its compiled code, and a later run
/// of the same system, method and step (an escaping orbit) finds it from its first stretch.
const STEPS: u64 = COMPILE_AFTER + 5_000;

/// Runs `method` with the compiled stretches and with the generic composer, checks that the
/// samples and the outcome are the same, and returns how the run stopped.
fn both(
    info: &Arc<SystemInfo>,
    method: Method,
    q0: &[f64],
    p0: &[f64],
    h: f64,
    every: u64,
) -> RunEnd {
    let system = SystemRef::Defined(info.clone());
    both_of(system, &[], method, (q0, p0), h, every, None).0
}

/// [`both`] for any system with its parameters, or for `reuse`, a system these prepared before
/// (its compiled code with it); also returns the system the compiled run ran.
fn both_of(
    system: SystemRef,
    params: &[(&str, f64)],
    method: Method,
    (q0, p0): (&[f64], &[f64]),
    h: f64,
    every: u64,
    reuse: Option<AnySystem>,
) -> (RunEnd, AnySystem) {
    let mut spec = SimulationSpec::new(system, &[method.clone()], h, STEPS as f64 * h);
    spec.params = params
        .iter()
        .map(|&(name, value)| (name.to_string(), ParamValue::Number(value)))
        .collect();
    spec.q0 = Some(q0.to_vec());
    spec.p0 = Some(p0.to_vec());
    spec.every = Some(every);
    let mut compiled = Simulation::prepare(&spec, &Limits::default()).expect("a valid run");
    let mut generic = Simulation::prepare(&spec, &Limits::default()).expect("a valid run");
    if let Some(system) = reuse {
        compiled.system = system.clone();
        generic.system = system;
    }
    generic.system = match generic.system {
        AnySystem::Custom1(s) => AnySystem::Custom1(s.without_compiled_stretches()),
        AnySystem::Custom2(s) => AnySystem::Custom2(s.without_compiled_stretches()),
        AnySystem::Custom3(s) => AnySystem::Custom3(s.without_compiled_stretches()),
        AnySystem::HenonHeiles(s) => AnySystem::HenonHeiles(s.without_compiled_steps()),
        other => panic!("not a system with compiled steps: {other:?}"),
    };
    let run = |sim: &Simulation| {
        let mut bits = Bits::default();
        let outcome = sim
            .run_method(0, None, Budget::default(), &mut bits)
            .expect("runs");
        (
            bits,
            outcome.stop,
            outcome.stats.steps,
            outcome.stats.force_evaluations,
        )
    };
    let (a, b) = (run(&compiled), run(&generic));
    assert_eq!(a, b, "{method:?} every {every} from {q0:?}, {p0:?}");
    (a.1, compiled.system)
}

/// Whether `method` runs the driven system `info` (some methods refuse a clock).
fn takes_driven(info: &Arc<SystemInfo>, method: &Method) -> bool {
    let spec = SimulationSpec::new(
        SystemRef::Defined(info.clone()),
        &[method.clone()],
        0.1,
        1.0,
    );
    Simulation::prepare(&spec, &Limits::default()).is_ok()
}

#[test]
fn compiled_stretches_give_the_composers_bits() {
    let gamma = Some(0.05);
    let pendulum = system(&["q"], Mass::Scalar(expr("mass", "1")), "1 - cos(q)", gamma);
    let heavy = system(
        &["q"],
        Mass::Scalar(expr("mass", "1.7")),
        "1 - cos(q)",
        None,
    );
    let henon_heiles = "(x^2 + y^2)/2 + x^2*y - y^3/3";
    let diagonal = system(
        &["x", "y"],
        Mass::Matrix(vec![
            vec![expr("mass", "1.5"), expr("mass", "0")],
            vec![expr("mass", "0"), expr("mass", "0.75")],
        ]),
        henon_heiles,
        gamma,
    );
    let full = system(
        &["x", "y"],
        Mass::Matrix(vec![
            vec![expr("mass", "1.5"), expr("mass", "0.25")],
            vec![expr("mass", "0.25"), expr("mass", "1")],
        ]),
        henon_heiles,
        None,
    );
    let spring = elastic_pendulum();
    // A driven system (the forced damped Duffing oscillator): its clock is one more coordinate
    // to the stretch, moving at velocity 1.
    let duffing = crate::sections::duffing(0.5, 0.1, 1.0);
    let methods = [
        Method::new(MethodId::Modin3s),
        Method::new(MethodId::Csv1),
        Method::composition(Scheme::of(MethodId::KahanLi8).unwrap(), Base::Modin3s),
        Method::triple_jump(Base::Csv1),
    ];
    // Every system the method takes, sampled every 1 to 1000 steps; last an orbit above the
    // escape energy, which leaves and blows up inside a compiled stretch (its code built by the
    // run before it), which the stepper then runs again step by step.
    let on_every_system = |method: &Method, projector: bool| {
        for every in [1, 2, 37, 1000] {
            both(&pendulum, method.clone(), &[2.0], &[0.5], 0.1, every);
            both(&heavy, method.clone(), &[3.0], &[0.0], 0.07, every);
            let (q0, p0) = ([0.1, -0.2], [0.3, 0.1]);
            both(&diagonal, method.clone(), &q0, &p0, 0.05, every);
            if projector {
                let (q0, p0) = ([0.9, -0.6], [0.1, 0.4]);
                both(&spring, method.clone(), &q0, &p0, 0.05, every);
            }
            both(&full, method.clone(), &[0.0, 0.3], &[0.2, 0.1], 0.05, every);
            let (q0, p0) = ([0.0, -1.0], [2.0, 2.0]);
            let stop = both(&full, method.clone(), &q0, &p0, 0.05, every);
            assert!(matches!(stop, RunEnd::Diverged { .. }), "{stop:?}");
            if takes_driven(&duffing, method) {
                both(&duffing, method.clone(), &[0.5], &[0.1], 0.05, every);
                let stop = both(&duffing, method.clone(), &[1e100], &[0.0], 0.05, every);
                assert!(matches!(stop, RunEnd::Diverged { .. }), "{stop:?}");
            }
        }
    };
    for method in &methods {
        on_every_system(method, false);
    }
    // The Verlets, symplectic Euler and compositions: compiled on the undamped systems (whole
    // steps where a step's last flow and the next's first do not fuse: the plain Verlets and
    // symplectic Euler; compositions of velocity Verlet fuse their kicks there), left to the
    // composer on the damped ones.
    for base in [Base::VelocityVerlet, Base::PositionVerlet] {
        on_every_system(
            &Method::composition(Scheme::of(MethodId::KahanLi8).unwrap(), base),
            false,
        );
    }
    for id in [
        MethodId::VelocityVerlet,
        MethodId::PositionVerlet,
        MethodId::SymplecticEuler,
        MethodId::SymplecticEulerAdjoint,
    ] {
        on_every_system(&Method::new(id), false);
    }
    // Runge–Kutta methods, with the projector damping too.
    for id in [
        MethodId::Rk4,
        MethodId::Heun,
        MethodId::Rk3,
        MethodId::ExplicitEuler,
    ] {
        on_every_system(&Method::new(id), true);
    }
    // A projector damping (csv1 and its compositions take conformal damping only).
    for method in [&methods[0], &methods[2]] {
        for every in [1, 37, 1000] {
            both(
                &spring,
                method.clone(),
                &[0.9, -0.6],
                &[0.1, 0.4],
                0.05,
                every,
            );
        }
    }
}

/// The built-in Hénon–Heiles system compiles its steps from its force traced from the code of
/// its `f64` force, and they give its generic steps' bits: undamped and damped, for λ = 1 and
/// couplings whose constants the expression graph rewrites (±1/2, −1), over the splittings,
/// compositions (the processed one of the sections bench among them) and Runge–Kutta methods,
/// on a bounded orbit and on one that escapes and blows up inside a stretch whose code the
/// bounded run built (systems of the same parameters share it). With λ = 0 it keeps the generic
/// steps.
#[test]
fn the_built_in_henon_heiles_compiled_steps_give_its_generic_bits() {
    let henon_heiles = || SystemRef::Id("henon_heiles".into());
    let damped_or_not = [
        Method::new(MethodId::Modin3s),
        Method::new(MethodId::Csv1),
        Method::composition(Scheme::of(MethodId::KahanLi8).unwrap(), Base::Modin3s),
        Method::new(MethodId::Rk4),
        Method::new(MethodId::Heun),
    ];
    let undamped_only = [
        Method::new(MethodId::VelocityVerlet),
        Method::composition(
            Scheme::of(MethodId::BlanesCasasMurua8).unwrap(),
            Base::VelocityVerlet,
        ),
    ];
    let couplings = [
        (1.0, 0.0),
        (1.0, 0.05),
        (-0.7, 0.0),
        (0.5, 0.05),
        (-0.5, 0.0),
        (-1.0, 0.05),
    ];
    for (lambda, gamma) in couplings {
        let undamped = undamped_only.iter().filter(|_| gamma == 0.0);
        let params = [("lambda", lambda), ("gamma", gamma)];
        for method in damped_or_not.iter().chain(undamped) {
            // Runge–Kutta methods compile stretches of two steps or more.
            let runge_kutta = matches!(method.id(), MethodId::Rk4 | MethodId::Heun);
            for every in [1, 37, 1000] {
                let start: (&[f64], &[f64]) = (&[0.0, -0.25], &[0.42, 0.0]);
                let (_, system) =
                    both_of(henon_heiles(), &params, *method, start, 0.05, every, None);
                let AnySystem::HenonHeiles(built_in) = &system else {
                    panic!("the built-in system");
                };
                assert!(
                    built_in.has_compiled_steps() || (runge_kutta && every == 1),
                    "λ = {lambda}, {method:?} every {every}: no compiled steps"
                );
                // The same system, its code built: the escape happens inside a stretch.
                let escaping: (&[f64], &[f64]) = (&[0.0, -1.0], &[2.0, 2.0]);
                let reuse = Some(system);
                let (stop, _) = both_of(
                    henon_heiles(),
                    &params,
                    *method,
                    escaping,
                    0.05,
                    every,
                    reuse,
                );
                assert!(matches!(stop, RunEnd::Diverged { .. }), "{stop:?}");
            }
        }
    }
    let uncoupled = [("lambda", 0.0), ("gamma", 0.0)];
    let start: (&[f64], &[f64]) = (&[0.1, -0.25], &[0.42, 0.0]);
    let modin_3s = damped_or_not[0];
    let (_, system) = both_of(henon_heiles(), &uncoupled, modin_3s, start, 0.05, 1, None);
    let AnySystem::HenonHeiles(system) = system else {
        panic!("the built-in system");
    };
    assert!(!system.has_compiled_steps(), "λ = 0 compiled");
}

/// The stretches take drifts, kicks and damping flows, and the Verlets' θ-kicks when nothing
/// damps (plain kicks then); a θ-kick with damping is left to the composer.
#[test]
fn the_stretches_are_compiled_for_what_they_take() {
    let pendulum = |gamma| {
        let info = system(&["q"], Mass::Scalar(expr("mass", "1")), "1 - cos(q)", gamma);
        let spec = SimulationSpec::new(
            SystemRef::Defined(info),
            &[Method::new(MethodId::Modin3s)],
            0.1,
            1.0,
        );
        let sim = Simulation::prepare(&spec, &Limits::default()).expect("a valid run");
        let AnySystem::Custom1(sys) = sim.system else {
            panic!("a typed-in system of one degree of freedom");
        };
        sys
    };
    fn compiles(
        sys: &CustomSystem<nalgebra::U1>,
        flows: &[(SubFlow, f64)],
        seam: Option<(f64, (f64, f64))>,
    ) -> bool {
        let plan = StretchPlan {
            flows,
            coefficients: &[(0.0, 0.0); 5][..flows.len()],
            h: 0.1,
            seam,
        };
        sys.compiled_forces()
            .and_then(|forces| forces.stretch(&plan, COMPILE_AFTER))
            .is_some()
    }
    let fused = Some((0.1, (0.0, 0.0)));
    let damped = pendulum(Some(0.05));
    assert!(compiles(&damped, MODIN_3S, fused));
    assert!(compiles(&damped, CSV1, fused));
    assert!(compiles(&damped, MODIN_3S, None), "whole steps");
    assert!(!compiles(&damped, POSITION_VERLET, fused));
    assert!(!compiles(&damped, VELOCITY_VERLET, None));
    let undamped = pendulum(None);
    assert!(compiles(&undamped, POSITION_VERLET, fused));
    assert!(compiles(&undamped, VELOCITY_VERLET, None));
    assert!(
        !compiles(&undamped, MODIN_RKS, fused),
        "an inner Runge–Kutta method"
    );
    let generic = damped.clone().without_compiled_stretches();
    assert!(!compiles(&generic, MODIN_3S, fused));
}

/// A typed-in system of two coordinates, as a run of `method` prepares it.
fn two_coordinates(info: &Arc<SystemInfo>, method: MethodId) -> CustomSystem<nalgebra::U2> {
    let spec = SimulationSpec::new(
        SystemRef::Defined(info.clone()),
        &[Method::new(method)],
        0.1,
        1.0,
    );
    let sim = Simulation::prepare(&spec, &Limits::default()).expect("a valid run");
    let AnySystem::Custom2(sys) = sim.system else {
        panic!("a typed-in system of two coordinates");
    };
    sys
}

/// The plain runs' 16 lanes side by side, `steps` steps in stretches of `every`: after each stretch the
/// lanes that ended, and the running lanes' states and the force count, as bits.
fn lanes_run<S: LaneForces<2>>(
    sys: &S,
    flows: &[(SubFlow, f64)],
    rate: f64,
    h: f64,
    starts: &[([f64; 2], [f64; 2]); LANES],
    (steps, every): (u64, u64),
) -> Vec<u64> {
    let mut lanes = RunLanes::<2>::new(flows, &[rate; LANES], h).expect("the lanes take it");
    for (l, (q, p)) in starts.iter().enumerate() {
        lanes.set_state(l, q, p);
    }
    let mut running = [true; LANES];
    let mut bits = Vec::new();
    for _ in 0..steps / every {
        let ended = lanes.advance(sys, every, &running);
        for (l, end) in ended.iter().enumerate() {
            if let (true, Some(end)) = (running[l], end) {
                running[l] = false;
                bits.extend([l as u64, end.steps, end.force_evaluations]);
                bits.push(u64::from(end.diverged));
            }
        }
        for l in (0..LANES).filter(|&l| running[l]) {
            let (q, p) = lanes.state(l);
            bits.extend(q.iter().chain(&p).map(|x| x.to_bits()));
        }
        bits.push(lanes.force_evaluations());
    }
    bits
}

/// The plain runs' lanes through a typed-in system's compiled lanes give the generic lanes'
/// bits: every stretch's states, the force count and the lanes that end (lanes above the escape
/// energy blow up inside a stretch and are run again step by step), for fused stretches
/// (modin_3s and csv1, undamped and with conformal damping; modin_3s with a projector damping
/// and with a force that calls functions; position Verlet; a driven system's csv1 and modin_3s)
/// and whole steps (velocity Verlet), in stretches of 1, 37 and 1000 steps.
#[test]
fn compiled_lanes_give_the_generic_lanes_bits() {
    let henon_heiles = "(x^2 + y^2)/2 + x^2*y - y^3/3";
    let full = Mass::Matrix(vec![
        vec![expr("mass", "1.5"), expr("mass", "0.25")],
        vec![expr("mass", "0.25"), expr("mass", "1")],
    ]);
    let undamped = two_coordinates(
        &system(&["x", "y"], full, henon_heiles, None),
        MethodId::Modin3s,
    );
    let gamma = 0.05;
    let damped = system(
        &["x", "y"],
        Mass::Scalar(expr("mass", "1")),
        henon_heiles,
        Some(gamma),
    );
    let damped = two_coordinates(&damped, MethodId::Modin3s);
    let spring = two_coordinates(&elastic_pendulum(), MethodId::Modin3s);
    // A force that calls functions (cos, sin and pow), which vector lanes call lane by lane;
    // the sine and cosine of x, and of y, from one call each.
    let pendulums = system(
        &["x", "y"],
        Mass::Scalar(expr("mass", "1")),
        "-cos(x) - cos(y) + 0.1*(1 + (x - y)^2)^1.5 + 0.05*sin(x)*cos(y)",
        None,
    );
    let pendulums = two_coordinates(&pendulums, MethodId::Modin3s);
    // Bound orbits near the origin, and in lanes 1, 6 and 11 one above the escape energy: with
    // two lanes to a vector, the upper and lower halves of three different vectors.
    let starts: [([f64; 2], [f64; 2]); LANES] = std::array::from_fn(|l| match l {
        1 | 6 | 11 => ([0.0, -1.0], [2.0, 2.0 + l as f64 / 10.0]),
        _ => {
            let s = l as f64 / LANES as f64 - 0.5;
            ([0.4 * s, -0.3 * s], [0.2 - 0.1 * s, 0.3 * s])
        }
    });
    let springs: [([f64; 2], [f64; 2]); LANES] = std::array::from_fn(|l| {
        let s = l as f64 / LANES as f64;
        (
            [0.9 - 0.5 * s, -0.6 - 0.3 * s],
            [0.1 + 0.2 * s, 0.4 - 0.3 * s],
        )
    });
    // The forced damped Duffing oscillator, (x, t) to the lanes: its clock moves at velocity 1
    // and its momentum takes ∂V/∂t; lanes 1, 6 and 11 start far enough out to blow up.
    let duffing = two_coordinates(&crate::sections::duffing(0.5, 0.1, 1.0), MethodId::Csv1);
    let driven: [([f64; 2], [f64; 2]); LANES] = std::array::from_fn(|l| match l {
        1 | 6 | 11 => ([1e100, 0.0], [0.0, 0.0]),
        _ => {
            let s = l as f64 / LANES as f64 - 0.5;
            ([1.8 * s, 0.0], [0.5 - s, 0.0])
        }
    });
    let cases: [(&CustomSystem<nalgebra::U2>, &[(SubFlow, f64)], f64, _); 10] = [
        (&undamped, MODIN_3S, 0.0, starts),
        (&pendulums, MODIN_3S, 0.0, starts),
        (&undamped, CSV1, 0.0, starts),
        (&undamped, VELOCITY_VERLET, 0.0, starts),
        (&undamped, POSITION_VERLET, 0.0, starts),
        (&damped, MODIN_3S, gamma, starts),
        (&damped, CSV1, gamma, starts),
        (&spring, MODIN_3S, 0.1, springs),
        (&duffing, CSV1, 0.25, driven),
        (&duffing, MODIN_3S, 0.25, driven),
    ];
    for (sys, flows, rate, starts) in cases {
        for every in [1, 37, 1000] {
            let steps = (COMPILE_AFTER + 10_000) / every * every;
            let h = 0.05;
            // The first run builds the code once its steps pass COMPILE_AFTER; the second has
            // it from its first stretch.
            lanes_run(sys, flows, rate, h, &starts, (steps, every));
            let compiled = lanes_run(sys, flows, rate, h, &starts, (steps, every));
            // The code was built and taken, not left to the generic path.
            assert!(
                sys.model().compiled_steps.lanes_built(),
                "{flows:?}: no compiled lanes"
            );
            let generic = sys.clone().without_compiled_stretches();
            let generic = lanes_run(&generic, flows, rate, h, &starts, (steps, every));
            assert!(
                compiled == generic,
                "{flows:?} every {every}: the compiled lanes differ from the generic ones"
            );
        }
    }
}

/// The built-in Hénon–Heiles system's plain runs in lanes take stretches compiled from its traced
/// force too, with the generic lanes' bits: the cases of the typed-in test above (lanes 1, 6 and
/// 11 escape and blow up inside a stretch) for couplings λ = 1, −0.7 and ½, undamped and damped,
/// in stretches of 37 and 1000 steps (its single steps stay on the generic lanes, which inline
/// its force).
#[test]
fn the_built_in_henon_heiles_compiled_lanes_give_the_generic_lanes_bits() {
    let starts: [([f64; 2], [f64; 2]); LANES] = std::array::from_fn(|l| match l {
        1 | 6 | 11 => ([0.0, -1.0], [2.0, 2.0 + l as f64 / 10.0]),
        _ => {
            let s = l as f64 / LANES as f64 - 0.5;
            ([0.4 * s, -0.3 * s], [0.2 - 0.1 * s, 0.3 * s])
        }
    });
    for lambda in [1.0, -0.7, 0.5] {
        for gamma in [0.0, 0.05] {
            let sys = HenonHeiles::new(lambda, gamma);
            let generic = sys.clone().without_compiled_steps();
            let rate = sys.damping_rate();
            let mut methods = vec![MODIN_3S, CSV1];
            if gamma == 0.0 {
                methods.extend([VELOCITY_VERLET, POSITION_VERLET]);
            }
            for flows in methods {
                for every in [37, 1000] {
                    let steps = (COMPILE_AFTER + 10_000) / every * every;
                    let h = 0.05;
                    lanes_run(&sys, flows, rate, h, &starts, (steps, every));
                    let compiled = lanes_run(&sys, flows, rate, h, &starts, (steps, every));
                    let built = sys
                        .compiled_forces()
                        .is_some_and(|forces| forces.code.lanes_built());
                    assert!(
                        built,
                        "λ = {lambda}, γ = {gamma}, {flows:?}: no compiled lanes"
                    );
                    let generic = lanes_run(&generic, flows, rate, h, &starts, (steps, every));
                    assert!(
                        compiled == generic,
                        "λ = {lambda}, γ = {gamma}, {flows:?} every {every}: the compiled lanes \
                         differ from the generic ones"
                    );
                }
            }
        }
    }
}

/// A typed-in system's ∇V and ∇²V compiled over the SIMD lanes give every lane the bits of its
/// one-run functions: arithmetic only (Hénon–Heiles), and with calls made lane by lane (sin,
/// cos, sqrt) and a Hessian whose entries differ from their transposes' programs.
#[test]
fn the_lanes_compiled_forces_give_each_lane_its_one_run_bits() {
    for potential in [
        "(x^2 + y^2)/2 + x^2*y - y^3/3",
        "1 - cos(x) + sin(x*y)^2 + sqrt(1 + y^2) + x^3*y/7",
    ] {
        let info = system(
            &["x", "y"],
            Mass::Scalar(expr("mass", "1")),
            potential,
            None,
        );
        let sys = two_coordinates(&info, MethodId::VelocityVerlet);
        assert!(!sys.model().lane_forces.built());
        let q: [Lane; 2] = std::array::from_fn(|i| {
            std::array::from_fn(|l| (l as f64 - 7.5) * 0.13 + i as f64 * 0.7)
        });
        let mut g = [[0.0; LANES]; 2];
        sys.grad_lanes(&q, &mut g);
        let mut hess = [[[0.0; LANES]; 2]; 2];
        sys.hessian_lanes(&q, &mut hess);
        assert!(
            sys.model().lane_forces.built(),
            "{potential}: the lanes' code was not built"
        );
        for l in 0..LANES {
            let x = nalgebra::Vector2::new(q[0][l], q[1][l]);
            let mut one = nalgebra::Vector2::zeros();
            sys.grad_potential(&x, &mut one);
            let mut one_hess = nalgebra::DMatrix::zeros(2, 2);
            sys.hess_potential(&x, &mut one_hess);
            for i in 0..2 {
                assert_eq!(
                    g[i][l].to_bits(),
                    one[i].to_bits(),
                    "{potential}: ∇V lane {l}"
                );
                for j in 0..2 {
                    assert_eq!(
                        hess[i][j][l].to_bits(),
                        one_hess[(i, j)].to_bits(),
                        "{potential}: ∇²V ({i}, {j}) lane {l}"
                    );
                }
            }
        }
    }
}
