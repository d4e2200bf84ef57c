//! The step's machinery measured: force evaluations counted and reused across steps, propagated
//! step Jacobians against finite differences of the step, fused stretches of steps against single
//! steps (also when they diverge), and compositions walked stage by stage against the flow-by-flow
//! walk, bit for bit.

use crate::common;

use common::request;
use geomint_core::simulation::{Limits, Simulation};
use geomint_core::system::{MechanicalSystem, State};
use geomint_core::systems::{ElasticPendulum3d, HarmonicOscillator};
use nalgebra::{U1, U3};
use serde_json::json;

#[test]
fn force_evaluations_are_counted_and_reused_across_steps() {
    // 1000 steps. The last force of a csv1 / velocity Verlet step is the first of the next (the
    // damping does not move q), so they cost one evaluation per step plus one to start; 3S and 2S
    // evaluate once per step; RK methods once per stage; cimp once per Newton iteration.
    let methods = [
        "modin_3s",
        "modin_2s",
        "csv1",
        "csv2",
        "velocity_verlet",
        "position_verlet",
        "heun",
        "rk3",
        "rk4",
        "cimp",
    ];
    let sim = Simulation::prepare(
        &request("pendulum", json!({"gamma": 0.1}), &methods, 0.1, 100.0),
        &Limits::default(),
    )
    .unwrap();
    let counts: Vec<u64> = (0..methods.len())
        .map(|i| {
            common::run_to_columns(&sim, i, None, Default::default())
                .unwrap()
                .1
                .stats
                .force_evaluations
        })
        .collect();
    assert_eq!(
        &counts[..9],
        &[1000, 1000, 1001, 1001, 1001, 1000, 2000, 3000, 4000]
    );
    // 003 Table 4.1 reports about 3.5–3.8 CIMP evaluations per step (h = 0.025, with its stopping
    // rule); Newton from an explicit predictor needs a few iterations here too.
    assert!(counts[9] > 2000 && counts[9] < 8000, "cimp: {}", counts[9]);
}

#[test]
fn propagated_step_jacobians_equal_finite_differences_of_the_step() {
    use geomint_core::methods;
    use geomint_core::run::Stepper;
    use geomint_core::tangent::Tangent;
    // rowlands has no tangent map (and needs an undamped system); tests/core_rowlands.rs checks
    // that it says so.
    let choices: Vec<_> = common::every_fixed_step_choice()
        .into_iter()
        .filter(|c| !common::conservative_only(c))
        .collect();
    let pendulum = geomint_core::systems::Pendulum { gamma: 0.3 };
    let z1 = State::from_slices(U1, &[2.0], &[0.4]);
    let bodies = geomint_core::systems::NBody {
        masses: vec![1.0, 2.0, 0.5],
        potential: geomint_core::systems::PairPotential::Gravity {
            g: 1.0,
            softening: 0.3,
        },
        gamma: 0.2,
    };
    let z9 = State::from_slices(
        nalgebra::Dyn(9),
        &[1.0, 0.0, 0.0, -0.5, 0.8, 0.1, -0.5, -0.8, -0.1],
        &[0.0, 0.5, 0.1, -0.4, -0.25, 0.0, 0.4, -0.25, -0.1],
    );
    for choice in &choices {
        let h = 0.1;
        let mut stepper = methods::build(choice, &pendulum, "pendulum", h).unwrap();
        let mut tangent = Tangent::new(&pendulum, &z1);
        let mut z = z1.clone();
        stepper
            .step_tangent(&pendulum, &mut z, h, &mut tangent)
            .unwrap();
        let diff =
            (&tangent.jac - common::step_jacobian_by_differences(&pendulum, choice, &z1, h)).amax();
        assert!(
            diff < 1e-7,
            "{} pendulum: tangent differs from differences by {diff:e}",
            choice.label()
        );
        // N bodies: the Hessian comes from differences of the gradient, so the match is looser.
        let mut stepper = methods::build(choice, &bodies, "nbody", h).unwrap();
        let mut tangent = Tangent::new(&bodies, &z9);
        let mut z = z9.clone();
        stepper
            .step_tangent(&bodies, &mut z, h, &mut tangent)
            .unwrap();
        let diff =
            (&tangent.jac - common::step_jacobian_by_differences(&bodies, choice, &z9, h)).amax();
        assert!(
            diff < 1e-5,
            "{} nbody: tangent differs from differences by {diff:e}",
            choice.label()
        );
    }
}

/// Runs `method` on `sys` for `steps` steps of `h`, sampling every `every` steps: with `every` = 1
/// the driver asks for one step at a time (nothing to fuse), with `every` = `steps` for stretches
/// of up to 1024 steps, which splittings run with their end flows fused.
fn final_state<S: MechanicalSystem>(
    sys: &S,
    method: &geomint_core::methods::Method,
    start: &State<S::Dim>,
    h: f64,
    steps: u64,
    every: u64,
) -> (State<S::Dim>, geomint_core::run::RunEnd, u64)
where
    nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<S::Dim>,
{
    let schedule = geomint_core::run::Schedule { h, steps, every };
    common::run_schedule(sys, method, start, schedule)
}

/// Paper 000 Sec. 6.2's start of the elastic 3-D pendulum: off the vertical, moving sideways.
fn elastic_start() -> State<U3> {
    State::from_slices(U3, &[0.0, 1.558_845_73, -0.6], &[1.341_640_79, 0.0, 0.0])
}

#[test]
fn fused_stretches_agree_with_single_steps_to_round_off() {
    use geomint_core::methods::composition::Scheme;
    use geomint_core::methods::{Base, Method, MethodId};
    use geomint_core::systems::Pendulum;
    let fusing = [
        Method::new(MethodId::Modin3s),
        Method::new(MethodId::Modin2s),
        Method::new(MethodId::ModinRks),
        Method::new(MethodId::Csv1),
        Method::new(MethodId::PositionVerlet),
        Method::composition(Scheme::of(MethodId::KahanLi8).unwrap(), Base::Modin3s),
        Method::composition(Scheme::of(MethodId::TripleJump).unwrap(), Base::Csv1),
    ];
    let steps = 20_000;
    // The largest difference of one component, required to be round-off.
    fn apart<D: nalgebra::Dim>(a: &State<D>, b: &State<D>, system: &str, method: &Method) -> f64
    where
        nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<D>,
    {
        let d =
            a.q.iter()
                .chain(a.p.iter())
                .zip(b.q.iter().chain(b.p.iter()))
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max);
        assert!(
            d < 1e-11,
            "{system} {}: fused differs by {d:e}",
            method.label()
        );
        d
    }
    let mut worst = 0.0f64;
    for method in &fusing {
        let pendulum = Pendulum { gamma: 0.05 };
        let start = State::from_slices(U1, &[2.5], &[0.3]);
        let elastic = ElasticPendulum3d {
            m: 1.0,
            k: 1.0,
            l: 1.0,
            g: 1.0,
            epsilon: 0.1,
        };
        let elastic_start = elastic_start();
        let pairs = [(
            final_state(&pendulum, method, &start, 0.05, steps, 1),
            final_state(&pendulum, method, &start, 0.05, steps, steps),
        )];
        // csv1 needs conformal damping, which the elastic pendulum's radial damping is not.
        let elastic_pairs: Vec<_> = if method.label().contains("csv1") {
            Vec::new()
        } else {
            vec![(
                final_state(&elastic, method, &elastic_start, 0.05, steps, 1),
                final_state(&elastic, method, &elastic_start, 0.05, steps, steps),
            )]
        };
        for ((single, _, single_forces), (fused, stop, fused_forces)) in pairs {
            assert!(matches!(stop, geomint_core::run::RunEnd::Finished));
            assert_eq!(single_forces, fused_forces, "{}", method.label());
            worst = worst.max(apart(&single, &fused, "pendulum", method));
        }
        for ((single, _, single_forces), (fused, stop, fused_forces)) in elastic_pairs {
            assert!(matches!(stop, geomint_core::run::RunEnd::Finished));
            assert_eq!(single_forces, fused_forces, "{}", method.label());
            worst = worst.max(apart(&single, &fused, "elastic pendulum", method));
            // J₃ = q₁p₂ − q₂p₁ is conserved by the radial damping: to round-off in both forms.
            let j3 = |z: &State<U3>| z.q[0] * z.p[1] - z.q[1] * z.p[0];
            let j3_start = j3(&elastic_start);
            assert!(
                (j3(&fused) - j3_start).abs() < 1e-12,
                "{}: J3 drifts",
                method.label()
            );
        }
    }
    eprintln!("fused against single steps: largest difference {worst:e}");
    // The fused form is really taken: it is not bit for bit the step-by-step one.
    let pendulum = Pendulum { gamma: 0.05 };
    let start = State::from_slices(U1, &[2.5], &[0.3]);
    let m = Method::new(MethodId::Modin3s);
    let single = final_state(&pendulum, &m, &start, 0.05, steps, 1).0;
    let fused = final_state(&pendulum, &m, &start, 0.05, steps, steps).0;
    assert_ne!((single.q[0], single.p[0]), (fused.q[0], fused.p[0]));
    assert!(worst > 0.0);
    // A method whose ends do not fuse (velocity Verlet's two half kicks are different θ-kicks)
    // runs the same bits either way.
    let m = Method::new(MethodId::VelocityVerlet);
    let single = final_state(&pendulum, &m, &start, 0.05, steps, 1).0;
    let fused = final_state(&pendulum, &m, &start, 0.05, steps, steps).0;
    assert_eq!((single.q[0], single.p[0]), (fused.q[0], fused.p[0]));
}

#[test]
fn a_fused_stretch_that_diverges_stops_where_single_steps_stop() {
    use geomint_core::methods::{Method, MethodId};
    use geomint_core::run::RunEnd;
    // ωh = 2.5 > 2: modin_3s is unstable on the oscillator and overflows after a few hundred
    // steps, inside the first fused stretch.
    let sys = HarmonicOscillator {
        omega: 50.0,
        gamma: 0.0,
    };
    let start = State::from_slices(U1, &[1.0], &[0.0]);
    for id in [MethodId::Modin3s, MethodId::Modin2s, MethodId::Csv1] {
        let m = Method::new(id);
        let (single, single_stop, single_forces) = final_state(&sys, &m, &start, 0.05, 5000, 1);
        let (fused, fused_stop, fused_forces) = final_state(&sys, &m, &start, 0.05, 5000, 5000);
        let step = match single_stop {
            RunEnd::Diverged { step, .. } => step,
            other => panic!("{id:?}: expected divergence, got {other:?}"),
        };
        assert!(step < 1024, "{id:?}: diverged only at step {step}");
        assert!(
            matches!(fused_stop, RunEnd::Diverged { step: s, .. } if s == step),
            "{id:?}: {fused_stop:?} against step {step}"
        );
        assert_eq!(single.q.as_slice(), fused.q.as_slice(), "{id:?}");
        // The failed fused attempt's force evaluations are not counted.
        assert_eq!(single_forces, fused_forces, "{id:?}: force evaluations");
    }
}

#[test]
fn compositions_walked_stage_by_stage_give_the_bits_of_the_flow_by_flow_walk() {
    use geomint_core::methods::composition::Scheme;
    use geomint_core::methods::splitting::{self, Composition, Flows, Splitting};
    use geomint_core::run::{RunEnd, Schedule};
    use geomint_core::systems::Pendulum;
    // Runs the splitting on `schedule` (samples every step, or one sample: fused stretches).
    fn run<S: MechanicalSystem>(
        sys: &S,
        composition: Composition,
        start: &State<S::Dim>,
        schedule: Schedule,
    ) -> (Vec<u64>, u64)
    where
        nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<S::Dim>,
    {
        let mut stepper = Splitting::new(sys, composition, None);
        let (z, stop, forces) = common::run_stepper(sys, &mut stepper, start, schedule);
        assert_eq!(stop, RunEnd::Finished);
        let bits = z.q.iter().chain(z.p.iter()).map(|x| x.to_bits()).collect();
        (bits, forces)
    }
    let pendulum = Pendulum { gamma: 0.05 };
    let pendulum_start = State::from_slices(U1, &[2.5], &[0.3]);
    let elastic = ElasticPendulum3d {
        m: 1.3,
        k: 0.8,
        l: 1.1,
        g: 1.0,
        epsilon: 0.1,
    };
    let elastic_start = elastic_start();
    let bases = [
        ("modin_3s", splitting::MODIN_3S),
        ("modin_2s", splitting::MODIN_2S),
        ("csv1", splitting::CSV1),
        ("position_verlet", splitting::POSITION_VERLET),
        ("velocity_verlet", splitting::VELOCITY_VERLET),
    ];
    let mut compared = 0;
    for (name, base) in bases {
        for scheme in Scheme::all() {
            let weights = scheme.weights();
            let composition = || Composition::new(base, &weights);
            // The stage-by-stage walk is the one taken, and the general one can be asked for.
            assert!(composition().stages().is_some(), "{name}");
            assert!(composition().without_stages().stages().is_none());
            for every in [1, 500] {
                let schedule = Schedule {
                    h: 0.05,
                    steps: 2000,
                    every,
                };
                let staged = run(&pendulum, composition(), &pendulum_start, schedule);
                let walked = run(
                    &pendulum,
                    composition().without_stages(),
                    &pendulum_start,
                    schedule,
                );
                assert_eq!(
                    staged, walked,
                    "pendulum, {scheme:?}({name}), every {every}"
                );
                let staged = run(&elastic, composition(), &elastic_start, schedule);
                let walked = run(
                    &elastic,
                    composition().without_stages(),
                    &elastic_start,
                    schedule,
                );
                assert_eq!(staged, walked, "elastic, {scheme:?}({name}), every {every}");
                compared += 2;
            }
        }
    }
    assert_eq!(compared, 5 * Scheme::all().count() * 2 * 2);

    // One stage of weight 1 is the base itself, bit for bit, and no stage at all leaves the state
    // as it is.
    let schedule = Schedule {
        h: 0.05,
        steps: 2000,
        every: 500,
    };
    for (name, base) in bases {
        let id = geomint_core::methods::MethodId::parse(name).expect("a method id");
        let method = geomint_core::methods::Method::new(id);
        let (z, _, forces) = common::run_schedule(&pendulum, &method, &pendulum_start, schedule);
        let bits = z.q.iter().chain(z.p.iter()).map(|x| x.to_bits()).collect();
        let one_stage = run(
            &pendulum,
            Composition::new(base, &[1.0]),
            &pendulum_start,
            schedule,
        );
        assert_eq!(one_stage, (bits, forces), "{name}");
        let none = run(
            &pendulum,
            Composition::new(base, &[]),
            &pendulum_start,
            schedule,
        );
        let start_bits: Vec<u64> = pendulum_start
            .q
            .iter()
            .chain(pendulum_start.p.iter())
            .map(|x| x.to_bits())
            .collect();
        assert_eq!(none, (start_bits, 0), "{name}");
    }
}

#[test]
fn compositions_of_velocity_verlet_fuse_their_kicks_on_undamped_systems_only() {
    use geomint_core::methods::composition::Scheme;
    use geomint_core::methods::splitting::{self, Composition, Flows, Splitting};
    use geomint_core::methods::{Base, Method};
    use geomint_core::run::{RunEnd, Schedule};
    use geomint_core::systems::Pendulum;
    let schedule = Schedule {
        h: 0.05,
        steps: 2000,
        every: 2000,
    };
    let start = State::from_slices(U1, &[2.5], &[0.3]);
    let (undamped, damped) = (Pendulum { gamma: 0.0 }, Pendulum { gamma: 0.05 });
    let state = |z: &State<U1>| [z.q[0], z.p[0]];
    // A processed scheme's kernel, processor and output map are built the same way (pinned in
    // `tests/service`'s `undamped_velocity_verlet_compositions`); here the plain compositions.
    for scheme in Scheme::all().filter(|s| s.processor().is_none()) {
        let s = scheme.weights().len();
        let method = Method::Composition {
            scheme,
            base: Base::VelocityVerlet,
        };
        let flows = |sys: &Pendulum| {
            let stepper = geomint_core::methods::build(&method, sys, "test", 0.05).unwrap();
            stepper.splitting_flows().map(<[_]>::len)
        };
        // Undamped, a stage's last kick and the next's first are one: a first kick, then a
        // drift and a kick per stage. Damped, the θ-kicks stay apart: three flows a stage.
        assert_eq!(flows(&undamped), Some(1 + 2 * s), "{scheme:?}");
        assert_eq!(flows(&damped), Some(3 * s), "{scheme:?}");

        // The same composition with its kicks apart: equal to round-off; the stage-by-stage walk
        // of the fused base is the flow-by-flow walk's bits, sampled once (fused stretches), at
        // every seventh step and at every step (no seams).
        let (fused, stop, fused_forces) =
            common::run_schedule(&undamped, &method, &start, schedule);
        assert_eq!(stop, RunEnd::Finished);
        let weights = scheme.weights();
        let run = |composition: Composition, schedule: Schedule| {
            let mut stepper = Splitting::new(&undamped, composition, None);
            common::run_stepper(&undamped, &mut stepper, &start, schedule)
        };
        let (apart, _, apart_forces) = run(
            Composition::new(splitting::VELOCITY_VERLET, &weights),
            schedule,
        );
        assert_eq!(
            fused_forces, apart_forces,
            "{scheme:?}: the force cache spared them before"
        );
        let (a, b) = (state(&fused), state(&apart));
        // Round-off, grown over 2000 steps near the separatrix: at most 2.5e-12 measured.
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() <= 1e-11, "{scheme:?}: {a:?} {b:?}");
        }
        let fused_base = || Composition::new(splitting::UNDAMPED_VELOCITY_VERLET, &weights);
        assert!(fused_base().stages().is_some(), "{scheme:?}");
        let (walked, _, _) = run(fused_base().without_stages(), schedule);
        assert_eq!(state(&walked), a, "{scheme:?}");
        for every in [1, 7] {
            let sampled = Schedule { every, ..schedule };
            let (staged, _, _) = run(fused_base(), sampled);
            let (walked, _, _) = run(fused_base().without_stages(), sampled);
            assert_eq!(state(&staged), state(&walked), "{scheme:?}, every {every}");
        }
    }
}
