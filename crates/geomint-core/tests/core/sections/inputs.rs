//! What a section, an event or an energy level refuses, with the field and the numbers; a
//! surface never crossed, which is no error.

use super::{duffing, event, henon_heiles, run, section, stroboscopic};
use geomint_core::error::{CoreError, ErrorCode, ErrorDetail, Field};
use geomint_core::methods::{Method, MethodId};
use geomint_core::sections::{Direction, EnergyLevel};
use geomint_core::simulation::{Limits, Simulation, SimulationSpec, Watching};

fn watch(
    system: std::sync::Arc<geomint_core::systems::SystemInfo>,
    w: Watching,
) -> Result<Simulation, CoreError> {
    let mut spec = SimulationSpec::new(system, &[Method::new(MethodId::Rk4)], 0.1, 10.0);
    spec.q0 = Some(vec![0.1, 0.0]);
    spec.p0 = Some(vec![0.0, 0.3]);
    Simulation::prepare(&spec, &Limits::default())?.watching(&w)
}

fn refusal(w: Watching) -> ErrorDetail {
    ErrorDetail::from(watch(henon_heiles(), w).expect_err("refused"))
}

#[test]
fn a_bad_expression_is_refused_at_its_field_and_character() {
    for (text, position) in [("y +", 3), ("y + z", 4), ("sin(y", 5), ("y $ 2", 2)] {
        let e = refusal(Watching {
            section: Some(section(text, Direction::Up, 10)),
            ..Watching::default()
        });
        assert_eq!(e.code, ErrorCode::InvalidExpression, "{text}: {e}");
        assert_eq!(e.field.as_deref(), Some("section.where"), "{text}");
        assert_eq!(e.position, Some(position), "{text}: {e}");
    }
    let e = refusal(Watching {
        stop_when: Some(event("p_y*", Direction::Both, 1)),
        ..Watching::default()
    });
    assert_eq!(e.field.as_deref(), Some("stop_when.where"));
    assert_eq!(e.position, Some(4));
}

#[test]
fn numbers_out_of_bounds_name_their_field() {
    let cases = [
        (
            Some(section("y", Direction::Up, 0)),
            None,
            "section.max_points",
        ),
        (
            Some(section("y", Direction::Up, 2_000_000)),
            None,
            "section.max_points",
        ),
        (Some(stroboscopic(0.0, 0.0, 10)), None, "section.period"),
        (Some(stroboscopic(-1.0, 0.0, 10)), None, "section.period"),
        (Some(stroboscopic(1.0, f64::NAN, 10)), None, "section.phase"),
        (
            Some(stroboscopic(1.0, f64::INFINITY, 10)),
            None,
            "section.phase",
        ),
        (None, Some(event("y", Direction::Up, 0)), "stop_when.count"),
    ];
    for (section, stop_when, field) in cases {
        let e = refusal(Watching {
            section,
            stop_when,
            ..Watching::default()
        });
        assert_eq!(e.code, ErrorCode::InvalidValue, "{e}");
        assert_eq!(e.field.as_deref(), Some(field), "{e}");
    }
}

#[test]
fn an_energy_below_the_point_or_an_unknown_momentum_is_refused() {
    let level = |energy: f64, momentum: &str| Watching {
        energy: Some(EnergyLevel {
            energy,
            momentum: momentum.into(),
            field: Field::new("energy"),
        }),
        ..Watching::default()
    };
    // V(0.1, 0) = 0.005 with p_x = 0: E = 0.001 is below the point.
    let e = refusal(level(0.001, "p_y"));
    assert_eq!(e.field.as_deref(), Some("energy.value"), "{e}");
    assert!(e.message.contains("0.005"), "{e}");
    let e = refusal(level(0.1, "y"));
    assert_eq!(e.field.as_deref(), Some("energy.momentum"), "{e}");
    assert!(e.message.contains("p_x, p_y"), "{e}");
    // Solved: H at the new state is the level, p_y ≥ 0.
    let sim = watch(henon_heiles(), level(0.125, "p_y")).unwrap();
    assert!(sim.p0[1] > 0.0);
    let h = 0.5 * (sim.p0[0].powi(2) + sim.p0[1].powi(2)) + 0.005;
    assert!((h - 0.125).abs() <= 1e-16, "{h}");
}

#[test]
fn a_surface_never_crossed_gives_no_points_and_says_so() {
    let sim = watch(
        henon_heiles(),
        Watching {
            section: Some(section("y - 5", Direction::Up, 10)),
            ..Watching::default()
        },
    )
    .unwrap();
    let (out, _) = run(&sim);
    let summary = out.summary.expect("a summary");
    assert_eq!(summary.points, 0);
    assert!(out.section.is_empty());
    let note = summary.note.expect("a note");
    assert!(note.contains("never crossed upwards"), "{note}");
    let [lo, hi] = summary.surface_range.unwrap();
    assert!(lo >= -5.5 && hi <= -4.5, "{lo} {hi}");
}

#[test]
fn methods_that_cannot_take_time_are_refused_naming_the_method() {
    // csv2 and cimp scale the positions (and so t) by the conformal factor; rowlands is
    // derived for autonomous systems. csv1 and the splittings take t through the drift.
    for (id, refused) in [
        (MethodId::Csv2, true),
        (MethodId::Cimp, true),
        (MethodId::Rowlands, true),
        (MethodId::Csv1, false),
        (MethodId::Modin3s, false),
        (MethodId::Rk4, false),
    ] {
        let mut spec = SimulationSpec::new(duffing(0.3, 0.5, 1.2), &[Method::new(id)], 0.1, 1.0);
        spec.q0 = Some(vec![1.0]);
        spec.p0 = Some(vec![0.0]);
        let result = Simulation::prepare(&spec, &Limits::default());
        if id == MethodId::Rowlands {
            // rowlands needs no damping before it needs no time: either refusal names it.
            assert!(result.is_err());
            continue;
        }
        match result {
            Err(e @ CoreError::TimeDependent { .. }) => {
                assert!(refused, "{id}: {e}");
                let detail = ErrorDetail::from(&e);
                assert_eq!(detail.field.as_deref(), Some("methods[0]"));
                assert_eq!(detail.code, ErrorCode::UnmetRequirement);
                // The reason reads as one sentence (no run of spaces from a wrapped string).
                let message = e.to_string();
                assert!(!message.contains("  "), "{id}: {message}");
                if id == MethodId::Csv2 {
                    assert!(
                        message.contains("would scale the time t with them"),
                        "{message}"
                    );
                }
            }
            Err(e) => panic!("{id}: {e}"),
            Ok(_) => assert!(!refused, "{id} ran"),
        }
    }
    // Undamped, rowlands is refused for the time alone.
    let mut spec = SimulationSpec::new(
        duffing(0.0, 0.5, 1.2),
        &[Method::new(MethodId::Rowlands)],
        0.1,
        1.0,
    );
    spec.q0 = Some(vec![1.0]);
    spec.p0 = Some(vec![0.0]);
    let e = Simulation::prepare(&spec, &Limits::default()).unwrap_err();
    assert!(matches!(e, CoreError::TimeDependent { .. }), "{e}");
    // The definition says so: the methods it lists take time.
    let facts =
        geomint_core::systems::custom::facts(duffing(0.3, 0.5, 1.2).custom_model().unwrap());
    assert!(facts.time_dependent);
    assert!(!facts.methods.contains(&"csv2") && facts.methods.contains(&"csv1"));
}
