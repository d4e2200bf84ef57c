use super::*;

/// The portable build of the kernels (what a CPU without AVX2 runs) and the one this CPU
/// is dispatched to give the same bits, in every chart and order, through blow-ups; a lane
/// left idle changes nothing in the others.
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
    let c = Constants::new(&pendulum, 0.2);
    // Two ordinary starts, one far outside its energy band (H₀ given as 0.3), one at the
    // origin (the pivot in either chart: 0/0 at the first step).
    let start = Start {
        q: [[0.3, 1.9, 2.6, 0.0], [1.2, -0.4, 0.5, 0.0]],
        p: [[0.0, 0.1, 20.0, 0.0], [0.0, -0.2, 20.0, 0.0]],
        energy: [0.4, 1.1, 0.3, 0.3],
        idle: [false; LANES],
    };
    let limit = start.energy.map(|e| DIVERGENCE * (1.0 + e.abs()));
    let bits = |t: &Tally| {
        let [q0, q1, p0, p1] = [t.q[0], t.q[1], t.p[0], t.p[1]];
        [t.sum, t.blown, t.non_finite, t.max, t.last, q0, q1, p0, p1]
            .map(|lane| lane.map(f64::to_bits))
    };
    for chart in [Chart::Cartesian, Chart::Polar] {
        for order in [Order::MomentumFirst, Order::PositionFirst] {
            let portable = integrate(&c, chart, order, &start, 20_000, &limit, Budget::default());
            let dispatched = dispatch(&c, chart, order, &start, 20_000, &limit, Budget::default());
            let (portable, dispatched) = (portable.unwrap(), dispatched.unwrap());
            assert_eq!(bits(&portable), bits(&dispatched), "{chart:?} {order:?}");
            assert!(
                portable.sum[..2].iter().all(|s| *s > 0.0),
                "{chart:?} {order:?}"
            );
            assert_eq!(portable.blown[2], 1.0, "{chart:?} {order:?}");
            assert_eq!(portable.non_finite[3], 1.0, "{chart:?} {order:?}");
            assert_eq!(portable.non_finite[..3], [f64::INFINITY; 3]);
            let idle = Start {
                idle: [false, true, false, false],
                ..start
            };
            let with_idle =
                dispatch(&c, chart, order, &idle, 20_000, &limit, Budget::default()).unwrap();
            assert_eq!(with_idle.non_finite[1], 0.0);
            for lane in [0, 2, 3] {
                assert_eq!(
                    bits(&with_idle).map(|b| b[lane]),
                    bits(&dispatched).map(|b| b[lane])
                );
            }
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
                let start = Start {
                    q: [[1.5, 2.0, 1e-3, 0.4], [0.3, -1.0, 1.2, 1.1]],
                    p: [[0.0; LANES]; 2],
                    energy: [0.0; LANES],
                    idle: [false; LANES],
                };
                let run = |steps| {
                    let budget = Budget::default();
                    let kernel = LaneKernel {
                        pendulum: pendulum.clone(),
                        chart,
                        order,
                    };
                    kernel.tally(&start, 0.2, steps, budget).unwrap()
                };
                let full = run(steps);
                for i in 0..LANES {
                    let stopped = full.non_finite[i];
                    if stopped == f64::INFINITY {
                        continue;
                    }
                    let before = run(stopped as u64 - 1);
                    assert_eq!(before.non_finite[i], f64::INFINITY);
                    let bits =
                        |t: &Tally| [t.q[0][i], t.q[1][i], t.p[0][i], t.p[1][i]].map(f64::to_bits);
                    assert_eq!(bits(&full), bits(&before), "{chart:?} {order:?} lane {i}");
                    stops.push(stopped as u64);
                }
            }
        }
    }
    println!("stops: {stops:?}");
    assert!(stops.iter().any(|&s| s > 1) && stops.iter().any(|&s| s > CHECK_EVERY));
}
