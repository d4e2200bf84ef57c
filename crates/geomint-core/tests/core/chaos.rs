//! Tangent dynamics and chaos indicators: every method's tangent map against finite differences
//! of its step on every built-in system and chart; Lyapunov spectra against the stability
//! matrices' eigenvalues; the pairing of exponents under (conformal) symplectic maps; MEGNO,
//! FLI, SALI and GALI on regular and chaotic orbits.

use geomint_core::chaos::{ChaosSpec, Indicator, Statistic, ThresholdStop};
use geomint_core::methods::Base;
use geomint_core::methods::{self, Method, MethodId};
use geomint_core::run::{Budget, Stepper, StopReason};
use geomint_core::simulation::{Columns, Limits, Outcome, Simulation, SimulationSpec};
use geomint_core::stability::{propagation_matrix, Spectrum};
use geomint_core::system::{MechanicalSystem, State};
use geomint_core::tangent::Tangent;
use geomint_core::with_system;

use crate::common;

/// Runs `spec` (one method) with the indicators of `chaos`.
pub fn chaos_run(spec: &SimulationSpec, chaos: &ChaosSpec) -> (Columns, Outcome) {
    let sim = Simulation::prepare(spec, &Limits::default())
        .and_then(|s| s.with_chaos(chaos))
        .expect("a valid request");
    common::run_to_columns(&sim, 0, None, Budget::default()).expect("the run succeeds")
}

/// A spec of `system` with `params` (JSON), the method `method`, initial state and schedule.
pub fn spec(
    system: &str,
    params: serde_json::Value,
    method: Method,
    (q0, p0): (&[f64], &[f64]),
    (h, t_end, every): (f64, f64, u64),
) -> SimulationSpec {
    SimulationSpec {
        params: common::params(params),
        q0: Some(q0.to_vec()),
        p0: Some(p0.to_vec()),
        every: Some(every),
        ..SimulationSpec::new(system, &[method], h, t_end)
    }
}

#[test]
fn tangent_maps_equal_differences_of_the_step_for_every_method_on_every_system() {
    // Damping switched on wherever a system has it, so that the damping flows' tangent maps
    // (conformal, and the spring's projector) are exercised.
    let damped = |id: &str| match id {
        "elastic_pendulum_3d" => serde_json::json!({"epsilon": 0.3}),
        "harmonic_oscillator" | "pendulum" | "nbody" | "henon_heiles" => {
            serde_json::json!({"gamma": 0.2})
        }
        _ => serde_json::json!({}),
    };
    let mut checked = 0;
    let mut worst = 0.0f64;
    let mut failures = Vec::new();
    for info in geomint_core::systems::catalog() {
        for chart in &info.charts {
            let mut spec = SimulationSpec {
                params: common::params(damped(&info.id)),
                chart: Some(chart.id.to_string()),
                ..SimulationSpec::new(
                    info.id.to_string(),
                    &[Method::Plain(MethodId::Rk4)],
                    0.05,
                    1.0,
                )
            };
            if info.id == "harmonic_oscillator" {
                // Inside the compensating chart's range (|q̂| < 1; the default start is its edge).
                spec.q0 = Some(vec![0.5]);
                spec.p0 = Some(vec![0.3]);
                spec.initial_cartesian = true;
            }
            if info.id == "exponential_decay" || info.id == "gompertz" {
                // A momentum away from 0, so that the lift's p-equation moves too.
                spec.p0 = Some(vec![0.3]);
                spec.initial_cartesian = true;
            }
            let sim = Simulation::prepare(&spec, &Limits::default()).expect("a valid system");
            for choice in common::every_fixed_step_choice() {
                if choice.no_step_jacobian().is_some() {
                    continue;
                }
                let h = 0.05;
                with_system!(&sim.system, sys => {
                    let Ok(mut stepper) = methods::build(&choice, sys, "test", h) else {
                        continue;
                    };
                    let z0 = State::from_slices(sys.dim(), &sim.q0, &sim.p0);
                    let mut tangent = Tangent::new(sys, &z0);
                    let mut z = z0.clone();
                    stepper.step_tangent(sys, &mut z, h, &mut tangent).expect("a tangent step");
                    let reference = common::step_jacobian_by_differences(sys, &choice, &z0, h);
                    let diff = (&tangent.jac - &reference).amax() / reference.amax().max(1.0);
                    // N bodies have no analytic Hessian: their ∇²V is a central difference.
                    let tolerance = if info.id == "nbody" { 1e-5 } else { 1e-7 };
                    if !(diff < tolerance) {
                        failures.push(format!(
                            "{} on {} ({}): the tangent map differs from differences by {diff:e}",
                            choice.label(), info.id, chart.id
                        ));
                    }
                    worst = worst.max(if info.id == "nbody" { 0.0 } else { diff });
                    checked += 1;
                });
            }
        }
    }
    eprintln!("tangent maps checked: {checked}, worst relative difference {worst:e}");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // 289 pairs of method and system (chart) in all.
    assert!(checked > 250, "{checked}");
}

/// Every fixed-step method with a tangent map that runs on a damped system.
fn damped_choices() -> Vec<Method> {
    common::every_fixed_step_choice()
        .into_iter()
        .filter(|c| c.no_step_jacobian().is_none() && !common::conservative_only(c))
        .collect()
}

/// The finite-time exponents over the window [t₁, t₂] from the spectra at its ends:
/// (t₂ λ(t₂) − t₁ λ(t₁))/(t₂ − t₁).
fn window(columns: &Columns, i1: usize, i2: usize) -> Vec<f64> {
    let (t1, t2) = (columns.t[i1], columns.t[i2]);
    let lyapunov = columns.lyapunov.as_ref().expect("the spectrum");
    lyapunov[i1]
        .iter()
        .zip(&lyapunov[i2])
        .map(|(a, b)| (t2 * b - t1 * a) / (t2 - t1))
        .collect()
}

#[test]
fn on_the_damped_oscillator_the_exponents_are_the_logarithms_of_the_stability_matrix_eigenvalues() {
    // Overdamped (ω = 1, γ = 2): every method's one-step matrix has two real eigenvalues of
    // different size, and the QR estimates over a window after the transient (whose decay is
    // geometric, (μ₂/μ₁)ⁿ) are (1/h) ln|μᵢ|. Underdamped (ω = 3.51, γ = 0.4): a complex pair of
    // modulus √det M, so the two estimates sum to (1/h) ln det M at every time and each
    // approaches (1/2h) ln det M as O(1/t).
    let h = 0.05;
    let chaos = ChaosSpec::new(&[Indicator::Lyapunov]);
    let (mut worst_real, mut worst_sum, mut worst_drift) = (0.0f64, 0.0f64, 0.0f64);
    for choice in damped_choices() {
        for (omega, gamma) in [(1.0, 2.0), (3.51, 0.4)] {
            let m = propagation_matrix(&choice, omega, gamma, h).expect("a matrix");
            let spectrum = Spectrum::of(&m);
            let moduli: Vec<f64> = spectrum
                .eigenvalues
                .iter()
                .map(|e| e.re.hypot(e.im))
                .collect();
            let mut expected: Vec<f64> = moduli.iter().map(|m| m.ln() / h).collect();
            expected.sort_by(|a, b| b.total_cmp(a));
            let params = serde_json::json!({"omega": omega, "gamma": gamma});
            let (c, _) = chaos_run(
                &spec(
                    "harmonic_oscillator",
                    params,
                    choice,
                    (&[1.0], &[0.0]),
                    (h, 50.0, 100),
                ),
                &chaos,
            );
            let last = c.t.len() - 1;
            let lyapunov = c.lyapunov.as_ref().unwrap();
            let sum = lyapunov[last][0] + lyapunov[last][1];
            let det = spectrum.det.ln() / h;
            worst_sum = worst_sum.max((sum - det).abs());
            assert!(
                (sum - det).abs() < 1e-10,
                "{}: λ₁ + λ₂ = {sum}, (1/h) ln det M = {det}",
                choice.label()
            );
            if spectrum.eigenvalues[0].im == 0.0 {
                let measured = window(&c, 4, last);
                for (got, want) in measured.iter().zip(&expected) {
                    worst_real = worst_real.max((got - want).abs());
                    assert!(
                        (got - want).abs() < 1e-10,
                        "{} (ω {omega}, γ {gamma}): {measured:?} against {expected:?}",
                        choice.label()
                    );
                }
            } else {
                let t = c.t[last];
                for got in &lyapunov[last] {
                    worst_drift = worst_drift.max((got - expected[0]).abs() * t);
                }
            }
        }
    }
    eprintln!("real eigenvalues: worst {worst_real:e}; sums: worst {worst_sum:e}; complex pairs: |λ − ln|μ|/h|·t ≤ {worst_drift:.3}");
    // Measured 1.26: bounded by the eigenvectors' condition, not growing.
    assert!(worst_drift < 2.0, "{worst_drift}");
}

/// The largest |λ_i + λ_{2n+1−i} − c| over the samples of `columns`.
fn pairing_defect(columns: &Columns, c: f64) -> f64 {
    let mut worst = 0.0f64;
    for spectrum in columns
        .lyapunov
        .as_ref()
        .expect("the spectrum")
        .iter()
        .skip(1)
    {
        let m = spectrum.len();
        for i in 0..m / 2 {
            worst = worst.max((spectrum[i] + spectrum[m - 1 - i] - c).abs());
        }
    }
    worst
}

#[test]
fn conformal_symplectic_methods_pair_the_exponents_to_minus_two_gamma() {
    // The damping is p' = … − 2γp, so the conformal factor per unit time is e^{−2γ}: each pair
    // of the full spectrum sums to −2γ (and all 2n sum to −2nγ), at every sample.
    let chaos = ChaosSpec::new(&[Indicator::Lyapunov]);
    let gamma = 0.1;
    let conformal = [
        Method::Plain(MethodId::Csv1),
        Method::Plain(MethodId::Csv2),
        Method::Plain(MethodId::Cimp),
        Method::Plain(MethodId::Modin3s),
        Method::Plain(MethodId::Modin2s),
        Method::triple_jump(Base::Csv1),
        Method::triple_jump(Base::Csv2),
        Method::composition(methods::composition::Scheme::KahanLi8, Base::Cimp),
    ];
    let mut worst = 0.0f64;
    for choice in conformal {
        let (c, _) = chaos_run(
            &spec(
                "henon_heiles",
                serde_json::json!({"gamma": gamma}),
                choice,
                (&[0.0, -0.25], &[0.42, 0.0]),
                (0.05, 200.0, 200),
            ),
            &chaos,
        );
        let defect = pairing_defect(&c, -2.0 * gamma);
        worst = worst.max(defect);
        assert!(
            defect < 1e-10,
            "{} on Hénon–Heiles: pairs miss −2γ by {defect:e}",
            choice.label()
        );
    }
    // Three bodies (n = 9, 18 exponents), γ = 0.05.
    for choice in [
        Method::Plain(MethodId::Csv1),
        Method::Plain(MethodId::Csv2),
        Method::Plain(MethodId::Cimp),
    ] {
        let (c, _) = chaos_run(
            &SimulationSpec {
                params: common::params(serde_json::json!({"gamma": 0.05})),
                every: Some(100),
                ..SimulationSpec::new("nbody", &[choice], 0.01, 5.0)
            },
            &chaos,
        );
        assert_eq!(c.lyapunov.as_ref().unwrap()[0].len(), 18);
        let defect = pairing_defect(&c, -0.1);
        worst = worst.max(defect);
        assert!(
            defect < 1e-10,
            "{} on three bodies: pairs miss −2γ by {defect:e}",
            choice.label()
        );
    }
    // rk4 is not conformal symplectic: its pairs miss by the method's error.
    let (c, _) = chaos_run(
        &spec(
            "henon_heiles",
            serde_json::json!({"gamma": gamma}),
            Method::Plain(MethodId::Rk4),
            (&[0.0, -0.25], &[0.42, 0.0]),
            (0.05, 200.0, 200),
        ),
        &chaos,
    );
    let rk4 = pairing_defect(&c, -2.0 * gamma);
    eprintln!("pairing defects: conformal methods ≤ {worst:e}, rk4 {rk4:e}");
    // Measured 6.0e-8 at h = 0.05: over a million times the conformal methods' defect.
    assert!(rk4 > 1e-8, "rk4's pairs miss by {rk4:e} only");
}

#[test]
fn symplectic_methods_pair_the_exponents_to_zero() {
    let chaos = ChaosSpec::new(&[Indicator::Lyapunov]);
    let symplectic = [
        Method::Plain(MethodId::VelocityVerlet),
        Method::Plain(MethodId::PositionVerlet),
        Method::Plain(MethodId::SymplecticEuler),
        Method::Plain(MethodId::SymplecticEulerAdjoint),
        Method::Plain(MethodId::ImplicitMidpoint),
        Method::ModinRks {
            inner: methods::Inner::Rk4,
        },
        Method::triple_jump(Base::VelocityVerlet),
        Method::new(MethodId::BlanesCasasMurua8),
    ];
    let mut worst = 0.0f64;
    for choice in symplectic {
        let (c, _) = chaos_run(
            &spec(
                "henon_heiles",
                serde_json::json!({}),
                choice,
                (&[0.0, -0.25], &[0.42, 0.0]),
                (0.05, 200.0, 200),
            ),
            &chaos,
        );
        let defect = pairing_defect(&c, 0.0);
        worst = worst.max(defect);
        assert!(
            defect < 1e-12,
            "{}: pairs miss 0 by {defect:e}",
            choice.label()
        );
    }
    // Symplectic Euler on a non-separable H: the planar pendulum in polar coordinates.
    for choice in [
        Method::Plain(MethodId::SymplecticEuler),
        Method::Plain(MethodId::SymplecticEulerAdjoint),
    ] {
        let (c, _) = chaos_run(
            &SimulationSpec {
                chart: Some("polar".into()),
                every: Some(100),
                ..SimulationSpec::new("elastic_pendulum_2d", &[choice], 0.01, 20.0)
            },
            &chaos,
        );
        let defect = pairing_defect(&c, 0.0);
        worst = worst.max(defect);
        assert!(
            defect < 1e-12,
            "{} (polar): pairs miss 0 by {defect:e}",
            choice.label()
        );
    }
    eprintln!("symplectic pairing defects ≤ {worst:e}");
}

/// The Hénon–Heiles state on the section x = 0 at energy `e` with (y, p_y), p_x ≥ 0 from H = E.
fn section(e: f64, y: f64, py: f64) -> ([f64; 2], [f64; 2]) {
    let px = (2.0 * e - py * py - y * y + 2.0 * y * y * y / 3.0).sqrt();
    ([0.0, y], [px, py])
}

#[test]
fn megno_tends_to_zero_for_the_oscillator_to_two_for_a_libration_and_grows_like_half_lambda_for_chaos(
) {
    let megno = ChaosSpec::new(&[Indicator::Megno]);
    let last = |c: &Columns| *c.megno_mean.as_ref().unwrap().last().unwrap();
    // An isochronous motion: the deviation stays bounded, ⟨Y⟩ → 0.
    let (c, _) = chaos_run(
        &spec(
            "harmonic_oscillator",
            serde_json::json!({"gamma": 0.0}),
            Method::Plain(MethodId::VelocityVerlet),
            (&[1.0], &[0.0]),
            (0.05, 1e4, 10000),
        ),
        &megno,
    );
    let oscillator = last(&c);
    // A libration of the pendulum (amplitude 2.5 rad): the deviation grows linearly, ⟨Y⟩ → 2.
    let (c, _) = chaos_run(
        &spec(
            "pendulum",
            serde_json::json!({"gamma": 0.0}),
            Method::Plain(MethodId::VelocityVerlet),
            (&[2.5], &[0.0]),
            (0.05, 1e4, 10000),
        ),
        &megno,
    );
    let libration = last(&c);
    eprintln!("⟨Y⟩ at T = 10⁴: oscillator {oscillator:e}, pendulum libration {libration}");
    assert!(oscillator.abs() < 1e-6, "{oscillator}");
    assert!((libration - 2.0).abs() < 0.01, "{libration}");
    // A chaotic orbit at E = 1/6: ⟨Y⟩ grows like λ_max t/2; the slope of a least-squares line
    // through the second half against λ_max(T)/2.
    let both = ChaosSpec::new(&[Indicator::Megno, Indicator::Lyapunov]);
    let (q0, p0) = section(1.0 / 6.0, -0.25, 0.0);
    let (c, _) = chaos_run(
        &spec(
            "henon_heiles",
            serde_json::json!({}),
            Method::triple_jump(Base::VelocityVerlet),
            (&q0, &p0),
            (0.05, 1e4, 200),
        ),
        &both,
    );
    let n = c.t.len();
    let (t, y) = (&c.t[n / 2..], &c.megno_mean.as_ref().unwrap()[n / 2..]);
    let (slope, _) = geomint_core::diagnostics::fit_line(t, y).unwrap();
    let lambda = c.lyapunov.as_ref().unwrap()[n - 1][0];
    eprintln!(
        "chaotic orbit: ⟨Y⟩ slope {slope}, λ_max/2 = {}",
        lambda / 2.0
    );
    assert!(
        (slope / (lambda / 2.0) - 1.0).abs() < 0.1,
        "slope {slope}, λ/2 {}",
        lambda / 2.0
    );
}

#[test]
fn fli_sali_and_megno_classify_orbits_alike() {
    // Orbits on the section x = 0 at E = 1/8 and 1/6, T = 2000: chaos is FLI > 2 ln T,
    // SALI < 1e-8, ⟨Y⟩ > 4; regular motion keeps FLI near ln T, SALI away from 0, ⟨Y⟩ near 2.
    let all = ChaosSpec::new(&[Indicator::Megno, Indicator::Fli, Indicator::Sali]);
    let t_end: f64 = 2000.0;
    let mut verdicts = Vec::new();
    for e in [0.125, 1.0 / 6.0] {
        for (y, py) in [
            (-0.25, 0.0),
            (0.0, 0.0),
            (0.1, 0.0),
            (0.3, 0.1),
            (-0.1, 0.2),
            (0.2, -0.2),
            (0.45, 0.0),
        ] {
            let (q0, p0) = section(e, y, py);
            if !p0[0].is_finite() {
                continue;
            }
            let (c, _) = chaos_run(
                &spec(
                    "henon_heiles",
                    serde_json::json!({}),
                    Method::triple_jump(Base::VelocityVerlet),
                    (&q0, &p0),
                    (0.05, t_end, 40000),
                ),
                &all,
            );
            let fli = *c.fli.as_ref().unwrap().last().unwrap();
            let sali = *c.sali.as_ref().unwrap().last().unwrap();
            let megno = *c.megno_mean.as_ref().unwrap().last().unwrap();
            let by_fli = fli > 2.0 * t_end.ln();
            let by_sali = sali < 1e-8;
            let by_megno = megno > 4.0;
            eprintln!(
                "E {e:.4} (y, p_y) = ({y}, {py}): FLI {fli:.2}, SALI {sali:.3e}, ⟨Y⟩ {megno:.3}"
            );
            assert_eq!(
                (by_fli, by_sali),
                (by_megno, by_megno),
                "E {e}, ({y}, {py})"
            );
            verdicts.push(by_megno);
        }
    }
    // Both kinds are among them.
    assert!(
        verdicts.iter().any(|&c| c) && verdicts.iter().any(|&c| !c),
        "{verdicts:?}"
    );
}

#[test]
fn indicators_do_not_depend_on_sampling_and_stay_finite_however_rarely_renormalised() {
    let all = ChaosSpec {
        deviations: Some(4),
        ..ChaosSpec::new(&[
            Indicator::Lyapunov,
            Indicator::Megno,
            Indicator::Fli,
            Indicator::Sali,
            Indicator::Gali,
        ])
    };
    let (q0, p0) = section(1.0 / 6.0, -0.25, 0.0);
    let run = |every: u64, chaos: &ChaosSpec| {
        chaos_run(
            &spec(
                "henon_heiles",
                serde_json::json!({}),
                Method::triple_jump(Base::VelocityVerlet),
                (&q0, &p0),
                (0.05, 1e3, every),
            ),
            chaos,
        )
        .0
    };
    let (dense, sparse) = (run(1, &all), run(7, &all));
    for (k, t) in sparse.t.iter().enumerate() {
        let j = (t / 0.05).round() as usize;
        assert_eq!(dense.t[j], *t);
        assert_eq!(
            dense.megno_mean.as_ref().unwrap()[j],
            sparse.megno_mean.as_ref().unwrap()[k]
        );
        assert_eq!(
            dense.lyapunov.as_ref().unwrap()[j],
            sparse.lyapunov.as_ref().unwrap()[k]
        );
        assert_eq!(
            dense.gali.as_ref().unwrap()[j],
            sparse.gali.as_ref().unwrap()[k]
        );
    }
    // Renormalised once in 10⁹ steps, i.e. never: the vectors would grow by e^{100} and more; the
    // range guard keeps them finite, and λ_max (from ‖A v₁‖ alone) is the same to round-off.
    let rare = run(
        1000,
        &ChaosSpec {
            qr_every: Some(1_000_000_000),
            ..all.clone()
        },
    );
    let often = run(1000, &all);
    let finite = |c: &Columns| {
        c.lyapunov
            .as_ref()
            .unwrap()
            .iter()
            .flatten()
            .all(|x| x.is_finite())
            && [&c.megno, &c.megno_mean, &c.fli, &c.sali, &c.gali]
                .iter()
                .all(|col| col.as_ref().unwrap().iter().all(|x| x.is_finite()))
    };
    assert!(finite(&rare) && finite(&often));
    let (a, b) = (
        rare.lyapunov.as_ref().unwrap().last().unwrap()[0],
        often.lyapunov.as_ref().unwrap().last().unwrap()[0],
    );
    eprintln!("λ_max renormalised every 10 steps {b}, never {a}");
    assert!((a - b).abs() < 1e-9 * b.abs(), "{a} vs {b}");
}

#[test]
fn a_threshold_stops_the_run_with_its_indicator_and_last_sample() {
    let chaos = ChaosSpec {
        stop_when: vec![(Statistic::MegnoMean, 8.0)],
        ..ChaosSpec::new(&[Indicator::Megno])
    };
    let (q0, p0) = section(1.0 / 6.0, -0.25, 0.0);
    let (c, outcome) = chaos_run(
        &spec(
            "henon_heiles",
            serde_json::json!({}),
            Method::triple_jump(Base::VelocityVerlet),
            (&q0, &p0),
            (0.05, 1e4, 1000),
        ),
        &chaos,
    );
    let StopReason::Indicator(ThresholdStop {
        step,
        t,
        indicator,
        value,
        threshold,
    }) = outcome.stop
    else {
        panic!("stopped by {:?}", outcome.stop)
    };
    assert_eq!((indicator, threshold), (Statistic::MegnoMean, 8.0));
    assert!(
        value >= 8.0 && step % 10 == 0 && step < 200_000,
        "{value} at {step}"
    );
    assert_eq!(*c.t.last().unwrap(), t);
    assert_eq!(*c.megno_mean.as_ref().unwrap().last().unwrap(), value);
    // The mean before it was still below the threshold (grid steps are 10 steps apart).
    let before = c.megno_mean.as_ref().unwrap();
    assert!(before[before.len() - 2] < 8.0);
    eprintln!("stopped at t = {t} with ⟨Y⟩ = {value}");
}

#[test]
fn requests_the_indicators_cannot_serve_are_refused_naming_the_field() {
    let field = |spec: &SimulationSpec, chaos: &ChaosSpec| {
        Simulation::prepare(spec, &Limits::default())
            .and_then(|s| s.with_chaos(chaos))
            .err()
            .and_then(|e| e.field().map(|f| f.to_string()))
    };
    let hh = SimulationSpec::new(
        "henon_heiles",
        &[Method::Plain(MethodId::VelocityVerlet)],
        0.05,
        1.0,
    );
    let megno = ChaosSpec::new(&[Indicator::Megno]);
    assert_eq!(
        field(
            &hh,
            &ChaosSpec {
                deviations: Some(5),
                ..megno.clone()
            }
        )
        .as_deref(),
        Some("deviations")
    );
    assert_eq!(
        field(
            &hh,
            &ChaosSpec {
                deviations: Some(0),
                ..megno.clone()
            }
        )
        .as_deref(),
        Some("deviations")
    );
    assert_eq!(
        field(
            &hh,
            &ChaosSpec {
                deviations: Some(1),
                ..ChaosSpec::new(&[Indicator::Sali])
            }
        )
        .as_deref(),
        Some("deviations")
    );
    assert_eq!(
        field(
            &hh,
            &ChaosSpec {
                stop_when: vec![(Statistic::Fli, 10.0)],
                ..megno.clone()
            }
        )
        .as_deref(),
        Some("stop_when.fli")
    );
    assert_eq!(
        field(
            &hh,
            &ChaosSpec {
                qr_every: Some(0),
                ..megno.clone()
            }
        )
        .as_deref(),
        Some("qr_every")
    );
    let rowlands = SimulationSpec::new(
        "henon_heiles",
        &[
            Method::Plain(MethodId::VelocityVerlet),
            Method::new(MethodId::Rowlands),
        ],
        0.05,
        1.0,
    );
    assert_eq!(field(&rowlands, &megno).as_deref(), Some("methods[1]"));
    let reference = SimulationSpec::new(
        "henon_heiles",
        &[Method::new(MethodId::Reference)],
        0.05,
        1.0,
    );
    assert_eq!(field(&reference, &megno).as_deref(), Some("methods[0]"));
    let defect = SimulationSpec {
        jacobian_defect: true,
        ..hh.clone()
    };
    assert_eq!(field(&defect, &megno).as_deref(), Some("indicators"));
}
