//! The batched steppers (`methods::lanes`): every build of a kernel gives the same bits, and a
//! lane stops where a run of its own would.

use geomint_core::methods::lanes::tangent::LANES;
use geomint_core::methods::lanes::{Isa, TangentLanes};
use geomint_core::methods::splitting::VELOCITY_VERLET;
use geomint_core::methods::{Method, MethodId};
use geomint_core::run::driver::CHECK_EVERY;
use geomint_core::run::Budget;
use geomint_core::studies::energy_map::lanes::{
    Chart, EulerOrder as Order, LaneKernel, Tally, TallyStart,
};
use geomint_core::systems::{
    AnySystem, HenonHeiles, PlanarCartesian, PlanarKind, PlanarPolar, PlanarSpring,
};

/// The kernel of symplectic Euler (momentum first) or its adjoint on `pendulum` in `chart`.
fn kernel(pendulum: &PlanarSpring, chart: Chart, order: Order) -> LaneKernel {
    let method = Method::Plain(match order {
        Order::MomentumFirst => MethodId::SymplecticEuler,
        Order::PositionFirst => MethodId::SymplecticEulerAdjoint,
    });
    let system = match chart {
        Chart::Cartesian => AnySystem::PlanarCartesian(PlanarCartesian(pendulum.clone())),
        Chart::Polar => AnySystem::PlanarPolar(PlanarPolar(pendulum.clone())),
    };
    LaneKernel::of(&method, &system).expect("the lanes run symplectic Euler on the pendulum")
}

/// The portable build of the kernels (what a CPU without AVX2 runs) and the one this CPU
/// is dispatched to give the same bits, in every chart and order, through blow-ups; a run's
/// bits do not depend on the runs beside it, nor on when it took its lane.
#[test]
fn the_portable_kernels_give_the_bits_of_the_dispatched_ones() {
    #[cfg(target_arch = "x86_64")]
    if !std::arch::is_x86_feature_detected!("avx2") {
        eprintln!("no AVX2 here: the portable build is compared with itself");
    }
    let pendulum = PlanarSpring {
        m: 1.3,
        k: 0.7,
        l: 1.0,
        g: 0.4,
        kind: PlanarKind::Pendulum,
    };
    // Two ordinary starts, one far outside its energy band (H₀ given as 0.3), one at the
    // origin (the pivot in either chart: 0/0 at the first step).
    let start = |q: [f64; 2], p: [f64; 2], energy: f64| TallyStart { q, p, energy };
    let starts = [
        start([0.3, 1.2], [0.0, 0.0], 0.4),
        start([1.9, -0.4], [0.1, -0.2], 1.1),
        start([2.6, 0.5], [20.0, 20.0], 0.3),
        start([0.0, 0.0], [0.0, 0.0], 0.3),
    ];
    let bits = |t: &Tally| {
        let [q0, q1] = t.q;
        let [p0, p1] = t.p;
        [t.sum, t.blown, t.non_finite, t.max, t.last, q0, q1, p0, p1].map(f64::to_bits)
    };
    let all_bits = |tallies: &[Tally]| tallies.iter().map(bits).collect::<Vec<_>>();
    for chart in [Chart::Cartesian, Chart::Polar] {
        for order in [Order::MomentumFirst, Order::PositionFirst] {
            let kernel = kernel(&pendulum, chart, order);
            let portable = kernel.clone().with_isa(Isa::Portable).unwrap();
            let [portable, dispatched] = [&portable, &kernel]
                .map(|k| k.tally(&starts, 0.2, 20_000, Budget::default()).unwrap());
            assert_eq!(
                all_bits(&portable),
                all_bits(&dispatched),
                "{chart:?} {order:?}"
            );
            assert!(
                portable[..2].iter().all(|t| t.sum > 0.0),
                "{chart:?} {order:?}"
            );
            assert_eq!(portable[2].blown, 1.0, "{chart:?} {order:?}");
            assert_eq!(portable[3].non_finite, 1.0, "{chart:?} {order:?}");
            assert!(portable[..3].iter().all(|t| t.non_finite == f64::INFINITY));
            // Without the second run beside them.
            let fewer = [starts[0], starts[2], starts[3]];
            let alone = kernel
                .tally(&fewer, 0.2, 20_000, Budget::default())
                .unwrap();
            assert_eq!(
                all_bits(&alone),
                [0, 2, 3].map(|i| bits(&dispatched[i])),
                "{chart:?} {order:?}"
            );
            // Three times as many runs as lanes: the pivot's run ends at its first step and
            // the next one waiting takes its lane there, one step behind the others.
            let many: Vec<TallyStart> = (0..3).flat_map(|_| starts).collect();
            let refilled = kernel.tally(&many, 0.2, 20_000, Budget::default()).unwrap();
            assert_eq!(
                all_bits(&refilled),
                [&dispatched[..]; 3]
                    .concat()
                    .iter()
                    .map(bits)
                    .collect::<Vec<_>>(),
                "{chart:?} {order:?}"
            );
        }
    }
}

/// A lane whose state stops being finite at step s ends with the state of step s − 1, which
/// the measured run finds by running its block again: the same bits as a run of s − 1
/// steps, which ends where it stops and reruns nothing. A spring too stiff for the step
/// (hω ≈ 2.1 and 2.4: the amplitude grows about twofold per step) overflows after a few
/// hundred to a thousand steps, across the first block boundary.
#[test]
fn a_stopped_lane_ends_with_the_state_of_the_step_before() {
    let steps = 3000;
    let mut stops = Vec::new();
    for k in [110.0, 150.0] {
        let pendulum = PlanarSpring {
            m: 1.0,
            k,
            l: 1.0,
            g: 0.02,
            kind: PlanarKind::Pendulum,
        };
        for chart in [Chart::Cartesian, Chart::Polar] {
            for order in [Order::MomentumFirst, Order::PositionFirst] {
                let starts =
                    [[1.5, 0.3], [2.0, -1.0], [1e-3, 1.2], [0.4, 1.1]].map(|q| TallyStart {
                        q,
                        p: [0.0; 2],
                        energy: 0.0,
                    });
                let run = |steps| {
                    let budget = Budget::default();
                    kernel(&pendulum, chart, order)
                        .tally(&starts, 0.2, steps, budget)
                        .unwrap()
                };
                let full = run(steps);
                for (i, ended) in full.iter().enumerate() {
                    let stopped = ended.non_finite;
                    if stopped == f64::INFINITY {
                        continue;
                    }
                    let before = run(stopped as u64 - 1);
                    assert_eq!(before[i].non_finite, f64::INFINITY);
                    let bits = |t: &Tally| [t.q[0], t.q[1], t.p[0], t.p[1]].map(f64::to_bits);
                    assert_eq!(bits(ended), bits(&before[i]), "{chart:?} {order:?} run {i}");
                    stops.push(stopped as u64);
                }
            }
        }
    }
    println!("stops: {stops:?}");
    assert!(stops.iter().any(|&s| s > 1) && stops.iter().any(|&s| s > CHECK_EVERY));
}

/// The portable build of the step (what a CPU without AVX2 runs) and each wider one this
/// CPU has give the same bits, escaping orbits and the range guard's flags included.
#[test]
fn every_build_of_the_step_agrees_bit_for_bit() {
    let sys = HenonHeiles::new(1.0, 0.0);
    let identity = [[1.0, 0.0], [0.0, 1.0]];
    let mut start =
        TangentLanes::<2>::new(VELOCITY_VERLET, 0.0, 0.05, identity, 2).expect("kicks and drifts");
    // Per group of four lanes: two bound orbits, one near the escape energy, one far above
    // it; each group a little further out than the one before.
    let orbits = [
        [0.0, -0.25, 0.42, 0.0],
        [0.1, 0.2, 0.3, -0.2],
        [0.0, 0.0, 0.57, 0.05],
        [0.3, 0.9, 1.5, 0.8],
    ];
    for l in 0..LANES {
        let [x, y, px, py] = orbits[l % 4];
        let out = 1.0 + 0.01 * (l / 4) as f64;
        start.q[0][l] = x * out;
        start.q[1][l] = y * out;
        start.p[0][l] = px * out;
        start.p[1][l] = py;
    }
    for (c, column) in start.columns.iter_mut().enumerate() {
        column.q[c] = [1.0; LANES];
        column.p[1 - c] = [0.5; LANES];
    }
    let bits = |l: &TangentLanes<2>| {
        let mut v: Vec<u64> =
            l.q.iter()
                .chain(&l.p)
                .flatten()
                .map(|x| x.to_bits())
                .collect();
        for c in &l.columns {
            v.extend(c.q.iter().chain(&c.p).flatten().map(|x| x.to_bits()));
        }
        v
    };
    let wider = [Isa::Avx2, Isa::Avx512].into_iter();
    for (isa, mut lanes) in wider.filter_map(|isa| Some((isa, start.clone().with_isa(isa)?))) {
        let mut portable = start.clone().with_isa(Isa::Portable).unwrap();
        let all = [true; LANES];
        let mut flagged = 0;
        for _ in 0..400 {
            let a = lanes.advance(&sys, 5, &[false; LANES]);
            let b = portable.advance(&sys, 5, &[false; LANES]);
            assert_eq!(bits(&lanes), bits(&portable), "{isa:?}");
            assert_eq!(
                (a.not_finite, a.out_of_range),
                (b.not_finite, b.out_of_range)
            );
            flagged += usize::from(a.not_finite.iter().any(|&f| f));
            let (a, b) = (
                lanes.advance(&sys, 1, &all),
                portable.advance(&sys, 1, &all),
            );
            assert_eq!(a.steps, b.steps);
        }
        assert!(flagged > 0, "the fast orbits escape");
        assert!(lanes.finite(0) && !lanes.finite(3));
        assert_eq!(lanes.force_evaluations(), portable.force_evaluations());
    }
}
