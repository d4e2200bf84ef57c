//! The stroboscopic section of the driven damped Duffing oscillator x″ + δx′ − x + x³ =
//! A cos ωt: a periodic orbit's points repeat; the strange attractor's statistics (mean, spread,
//! histogram) agree with a long run of the adaptive reference. And the events: the n-th
//! crossing's time against the exact one.

use super::henon_heiles::assert_same_points;
use super::{duffing, event, run, sampled_simulation, simulation, stroboscopic};
use geomint_core::methods::composition::Scheme;
use geomint_core::methods::{Base, Method, MethodId};
use geomint_core::run::RunEnd;
use geomint_core::sections::Direction;
use geomint_core::simulation::Watching;
use std::f64::consts::PI;

const OMEGA: f64 = 1.2;

fn strobe(points: u64) -> Watching {
    Watching {
        section: Some(stroboscopic(2.0 * PI / OMEGA, 0.0, points)),
        ..Watching::default()
    }
}

/// Sixth-order composition of modin_3s: conformal damping, driven potential.
fn sixth_order() -> Method {
    Method::composition(Scheme::of(MethodId::KahanLi6).unwrap(), Base::Modin3s)
}

#[test]
fn a_periodic_orbit_repeats_in_the_stroboscopic_section() {
    // Weak forcing: after the transient the orbit is periodic with the drive's period, so its
    // stroboscopic points repeat.
    let period = 2.0 * PI / OMEGA;
    let sim = simulation(
        duffing(0.3, 0.2, OMEGA),
        sixth_order(),
        (period / 64.0, 400.0 * period),
        (&[1.0], &[0.0]),
        strobe(1000),
    );
    let (out, _) = run(&sim);
    let x: Vec<f64> = out.section.q.iter().map(|q| q[0]).collect();
    let p: Vec<f64> = out.section.p.iter().map(|p| p[0]).collect();
    assert_eq!(x.len(), 400);
    // The points' times are the drive's: t = k T exactly as computed from k.
    for (k, t) in out.section.t.iter().enumerate() {
        assert_eq!(*t, (k + 1) as f64 * period);
    }
    let tail = x.len() - 50;
    let repeat = (tail..x.len() - 1)
        .map(|k| (x[k + 1] - x[k]).abs().max((p[k + 1] - p[k]).abs()))
        .fold(0.0, f64::max);
    println!(
        "periodic regime: last 50 points repeat to {repeat:e} (x = {}, p = {})",
        x[x.len() - 1],
        p[p.len() - 1]
    );
    assert!(repeat <= 1e-10, "{repeat:e}");
}

/// Mean, standard deviation and a 24-bin histogram on [−1.8, 1.8] of x.
fn statistics(x: &[f64]) -> (f64, f64, Vec<f64>) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let spread = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    let mut bins = vec![0.0; 24];
    for v in x {
        let i = (((v + 1.8) / 3.6) * 24.0).floor().clamp(0.0, 23.0) as usize;
        bins[i] += 1.0 / n;
    }
    (mean, spread, bins)
}

#[test]
fn the_strange_attractor_has_the_reference_runs_statistics() {
    // δ = 0.3, A = 0.5, ω = 1.2 (the chaotic regime): 10⁴ stroboscopic points of the
    // sixth-order splitting after 100 periods of transient against 10⁵ of the adaptive
    // reference. Chaos makes the orbits differ point by point; the invariant measure they
    // sample does not.
    let period = 2.0 * PI / OMEGA;
    let collect = |method: Method, h: f64, points: u64| {
        let sim = simulation(
            duffing(0.3, 0.5, OMEGA),
            method,
            (h, (points as f64 + 100.5) * period),
            (&[1.0], &[0.0]),
            strobe(points + 100),
        );
        let (out, _) = run(&sim);
        out.section.q[100..]
            .iter()
            .map(|q| q[0])
            .collect::<Vec<_>>()
    };
    let ours = collect(sixth_order(), period / 100.0, 10_000);
    let reference = collect(
        Method::Reference { tolerance: 1e-10 },
        period / 4.0,
        100_000,
    );
    let (m1, s1, b1) = statistics(&ours);
    let (m2, s2, b2) = statistics(&reference);
    let l1: f64 = b1.iter().zip(&b2).map(|(a, b)| (a - b).abs()).sum();
    println!(
        "attractor: mean {m1:.4} / {m2:.4}, spread {s1:.4} / {s2:.4}, histogram L1 distance {l1:.4}"
    );
    assert!((m1 - m2).abs() <= 0.03, "means {m1} and {m2}");
    assert!((s1 - s2).abs() <= 0.03, "spreads {s1} and {s2}");
    assert!(l1 <= 0.08, "histograms {b1:?} and {b2:?}");
    // Not a periodic orbit: the points spread over both wells.
    assert!(s1 > 0.5);
}

#[test]
fn a_processed_method_forms_output_states_only_near_the_stroboscopic_times() {
    // The strange attractor through a processed method, whose clock the processor moves too:
    // sampled at every step, and sparsely (output states formed only near t = kT), the same
    // points bit for bit.
    let period = 2.0 * PI / OMEGA;
    let method = Method::composition(
        Scheme::of(MethodId::BlanesCasasMurua8).unwrap(),
        Base::Modin3s,
    );
    let run_sampled = |every| {
        let sim = sampled_simulation(
            duffing(0.3, 0.5, OMEGA),
            method.clone(),
            (period / 50.0, 500.5 * period, every),
            (&[1.0], &[0.0]),
            strobe(500),
        );
        run(&sim)
    };
    let (lazy, lazy_outcome) = run_sampled(None);
    let (eager, eager_outcome) = run_sampled(Some(1));
    assert_eq!(lazy.section.len(), 500);
    assert_same_points(&lazy, &eager);
    let (few, all) = (
        lazy_outcome.stats.force_evaluations as f64,
        eager_outcome.stats.force_evaluations as f64,
    );
    println!(
        "stroboscopic: {few:.3e} force evaluations against {all:.3e} ({:.2})",
        few / all
    );
    assert!(few <= 0.5 * all, "{few:e} of {all:e}");
}

#[test]
fn the_third_crossing_ends_the_run_at_its_exact_time() {
    // The damped oscillator q″ + 2γq′ + ω²q = 0 from q = 0, p = 1: q = e^{−γt} sin(ω_d t)/ω_d
    // vanishes at t = kπ/ω_d. The run stops at its third crossing of q = 0.
    let (omega, gamma) = (2.0f64, 0.3f64);
    let omega_d = (omega * omega - gamma * gamma).sqrt();
    let exact = 3.0 * PI / omega_d;
    let stop_at = |method: Method| {
        let mut spec = geomint_core::simulation::SimulationSpec::new(
            "harmonic_oscillator",
            &[method],
            0.05,
            100.0,
        )
        .param("omega", omega)
        .param("gamma", gamma);
        spec.q0 = Some(vec![0.0]);
        spec.p0 = Some(vec![1.0]);
        let sim = geomint_core::simulation::Simulation::prepare(&spec, &Default::default())
            .unwrap()
            .watching(&Watching {
                stop_when: Some(event("q", Direction::Both, 3)),
                ..Watching::default()
            })
            .unwrap();
        let (out, outcome) = run(&sim);
        let RunEnd::Event { step, t } = outcome.stop else {
            panic!("stopped by {:?}", outcome.stop)
        };
        assert_eq!(out.events.len(), 3);
        assert_eq!(out.events.t[2], t);
        // The run ends with the step past the crossing, sampled.
        assert_eq!(step, (t / 0.05).ceil() as u64);
        assert_eq!(*out.samples.t.last().unwrap(), step as f64 * 0.05);
        t
    };
    let ours = stop_at(Method::composition(
        Scheme::of(MethodId::KahanLi8).unwrap(),
        Base::Modin3s,
    ));
    let reference = stop_at(Method::new(MethodId::Reference));
    println!(
        "third crossing: exact {exact}, kahan_li_8 {:e} off, reference {:e} off",
        ours - exact,
        reference - exact
    );
    assert!((ours - exact).abs() <= 1e-10);
    assert!((reference - exact).abs() <= 1e-10);
    assert!((ours - reference).abs() <= 1e-10);
}

#[test]
fn a_crossing_the_exact_flow_turns_back_from_is_counted_not_reported_the_wrong_way() {
    // The oscillator q = sin t (ω = 1) and the level q = a just below its amplitude. Velocity
    // Verlet at a coarse step keeps a modified energy whose level curve bulges past the unit
    // circle: some steps cross q = a upwards where the exact flow from either end of the step
    // turns back short of it (from the later end, forwards, it reaches q = a on the way down).
    // Such a crossing is counted unlocated; every point reported moves the way its step
    // crossed: upwards in an upward section, and in a section both ways the downward crossing
    // is not reported twice (once for each step).
    let mut unlocated = [0, 0];
    let mut points = [0, 0];
    for k in 0..42 {
        let a = 1.0 + 0.0008 * f64::from(k);
        for (j, direction) in [Direction::Up, Direction::Both].into_iter().enumerate() {
            let mut spec = geomint_core::simulation::SimulationSpec::new(
                "harmonic_oscillator",
                &[Method::new(MethodId::VelocityVerlet)],
                0.5,
                2000.0,
            )
            .param("omega", 1.0)
            .param("gamma", 0.0);
            spec.q0 = Some(vec![0.0]);
            spec.p0 = Some(vec![1.0]);
            let sim = geomint_core::simulation::Simulation::prepare(&spec, &Default::default())
                .unwrap()
                .watching(&Watching {
                    section: Some(super::section(&format!("q - {a}"), direction, 10_000)),
                    ..Watching::default()
                })
                .unwrap();
            let (out, _) = run(&sim);
            let summary = out.summary.unwrap();
            let p: Vec<f64> = out.section.p.iter().map(|p| p[0]).collect();
            if direction == Direction::Up {
                assert!(p.iter().all(|&p| p > 0.0), "a = {a}: {p:?}");
            } else {
                // No point twice: the times increase.
                let t = &out.section.t;
                assert!(t.windows(2).all(|w| w[0] < w[1]), "a = {a}: {t:?}");
            }
            unlocated[j] += summary.unlocated;
            points[j] += summary.points;
        }
    }
    println!("up, both: {points:?} points located, {unlocated:?} crossings turned back from");
    assert!(unlocated.iter().all(|&u| u > 0) && points.iter().all(|&p| p > 0));
}
