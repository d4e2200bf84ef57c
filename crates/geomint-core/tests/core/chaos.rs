//! Tangent dynamics and chaos indicators: every method's tangent map against finite differences
//! of its step on every built-in system and chart; Lyapunov spectra against the stability
//! matrices' eigenvalues; the pairing of exponents under (conformal) symplectic maps. The
//! indicators on orbits are `indicators.rs`'s.

use geomint_core::chaos::{ChaosSpec, Indicator};
use geomint_core::methods::Base;
use geomint_core::methods::{self, Method, MethodId};
use geomint_core::run::{Budget, Stepper};
use geomint_core::simulation::{Columns, Limits, RunReport, Simulation, SimulationSpec};
use geomint_core::stability::{propagation_matrix, Spectrum};
use geomint_core::system::{MechanicalSystem, State};
use geomint_core::tangent::Tangent;
use geomint_core::with_system;

use crate::common;

/// Runs `spec` (one method) with the indicators of `chaos`.
pub fn chaos_run(spec: &SimulationSpec, chaos: &ChaosSpec) -> (Columns, RunReport) {
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
        Method::composition(
            methods::composition::Scheme::of(MethodId::KahanLi8).unwrap(),
            Base::Cimp,
        ),
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
