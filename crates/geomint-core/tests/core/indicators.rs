//! Chaos indicators on orbits: MEGNO, FLI, SALI and GALI on regular and chaotic orbits of the
//! oscillator, the pendulum and Hénon–Heiles; their independence of sampling and renormalisation;
//! thresholds that stop a run; requests the indicators cannot serve, refused naming the field.

use geomint_core::chaos::{ChaosSpec, Indicator, Statistic, ThresholdCrossing};
use geomint_core::methods::{Base, Method, MethodId};
use geomint_core::run::RunEnd;
use geomint_core::simulation::{Columns, Limits, Simulation, SimulationSpec};

use crate::chaos::{chaos_run, spec};

/// The Hénon–Heiles state on the section x = 0 at energy `e` with (y, p_y), p_x ≥ 0 from H = E.
fn section(e: f64, y: f64, py: f64) -> ([f64; 2], [f64; 2]) {
    let px = (2.0 * e - py * py - y * y + 2.0 * y * y * y / 3.0).sqrt();
    ([0.0, y], [px, py])
}

/// The Hénon–Heiles orbit from (q0, p0) of triple_jump(velocity_verlet) at h = 0.05 to
/// `t_end`, sampled every `every` steps, with the indicators of `chaos`.
fn henon_heiles_orbit(
    (q0, p0): &([f64; 2], [f64; 2]),
    t_end: f64,
    every: u64,
    chaos: &ChaosSpec,
) -> (Columns, geomint_core::simulation::RunReport) {
    chaos_run(
        &spec(
            "henon_heiles",
            serde_json::json!({}),
            Method::triple_jump(Base::VelocityVerlet),
            (q0, p0),
            (0.05, t_end, every),
        ),
        chaos,
    )
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
    // Chaotic orbits at E = 1/6: ⟨Y⟩ grows like λ_max t/2, so 2⟨Y⟩(T)/T tends to the
    // finite-time λ_max(T) over the same [0, T]. The relation is asymptotic, and one orbit is a
    // noisy measure of it: the orbits stick near islands for a while, and the round-off of the
    // method decides when (from y = −0.25, 2⟨Y⟩/(λ_max t) at t = T/2 measured 0.83 to 1.05 under
    // three roundings of the same method). So four orbits, each within 15 % at T, and their
    // mean within 5 %: measured 0.90–1.09 per orbit and means 0.97–1.02 under those roundings.
    // Each orbit must be chaotic for the relation to hold: λ_max(T) measured 0.11–0.14, where a
    // regular orbit's falls like ln T / T (below 1e-3 at T = 10⁴).
    let both = ChaosSpec::new(&[Indicator::Megno, Indicator::Lyapunov]);
    let mut ratios = Vec::new();
    for (y, py) in [(-0.25, 0.0), (0.3, 0.1), (-0.1, 0.2), (0.2, -0.2)] {
        let (q0, p0) = section(1.0 / 6.0, y, py);
        let (c, _) = henon_heiles_orbit(&(q0, p0), 1e4, 200, &both);
        let (t, megno) = (*c.t.last().unwrap(), last(&c));
        let lambda = c.lyapunov.as_ref().unwrap().last().unwrap()[0];
        let ratio = 2.0 * megno / t / lambda;
        eprintln!(
            "chaotic orbit from (y, p_y) = ({y}, {py}): 2⟨Y⟩/T {}, λ_max {lambda}",
            ratio * lambda
        );
        assert!(lambda > 0.05, "({y}, {py}): λ_max {lambda}");
        assert!(
            (ratio - 1.0).abs() < 0.15,
            "({y}, {py}): 2⟨Y⟩/(λ_max T) = {ratio}"
        );
        ratios.push(ratio);
    }
    let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
    assert!((mean - 1.0).abs() < 0.05, "mean 2⟨Y⟩/(λ_max T) = {mean}");
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
            let (c, _) = henon_heiles_orbit(&(q0, p0), t_end, 40000, &all);
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
    let run = |every: u64, chaos: &ChaosSpec| henon_heiles_orbit(&(q0, p0), 1e3, every, chaos).0;
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
    let (c, outcome) = henon_heiles_orbit(&(q0, p0), 1e4, 1000, &chaos);
    let RunEnd::Indicator(ThresholdCrossing {
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
