//! ns per step of the core's hot loop, measured like the hand-written floor loops beside the
//! project (`../shared/peers/floor`, subcommand `bench`); the timing loop is in `common`.
//! Each method twice: step by step (the form of the floor's plain loops 3S-DKD, 3S-KDK, Heun,
//! RK4) and as runs take it, in stretches between samples where a splitting fuses the last flow
//! of a step with the first of the next (the form of the floor's 3S-DKDm).
//!
//! P1: damped pendulum, ε = 0.01, q0 = 0.9π, p0 = 0. P2: elastic 3-D pendulum, ε = 0.1,
//! q0 = (0, 1.55884573, −0.6), p0 = (1.34164079, 0, 0) (paper 000 Secs. 4.3 and 6.2).

use std::time::Instant;

use geomint::core::methods::{Method, MethodId};
use geomint::core::system::State;
use geomint::core::systems::{ElasticPendulum3d, Pendulum};

mod common;
use common::{measure, measure_step_by_step};

/// Wall time of 400×400 stability maps (ω = 3.51, γ ∈ [0, 3.5], h ∈ [0, 1]) for every
/// fixed-step method, computed in parallel over the cores.
fn stability_maps() {
    use geomint::core::stability::{check_map, map, StabilityAxis};
    let gamma = StabilityAxis {
        min: 0.0,
        max: 3.5,
        n: 400,
    };
    let h = StabilityAxis {
        min: 0.0,
        max: 1.0,
        n: 400,
    };
    // The methods a damped map takes (rowlands and blanes_moan_srkn11 need an undamped
    // system, so they have no map over γ > 0), as the map itself decides.
    let choices: Vec<Method> = MethodId::ALL
        .iter()
        .filter(|&&m| m != MethodId::Reference)
        .map(|&m| Method::new(m))
        .filter(|m| check_map(m, 3.51, gamma, h).is_ok())
        .collect();
    let began = Instant::now();
    let mut unstable = 0;
    for c in &choices {
        unstable += map(c, 3.51, gamma, h)
            .expect("map")
            .stable
            .iter()
            .filter(|s| !**s)
            .count();
    }
    println!(
        "\n400×400 stability maps of {} methods: {:.0} ms in all ({} unstable cells)",
        choices.len(),
        began.elapsed().as_secs_f64() * 1e3,
        unstable
    );
}

fn main() {
    let filter: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let wanted = |name: &str| filter.is_empty() || filter.iter().any(|f| name.contains(f.as_str()));
    let choices = [
        Method::new(MethodId::Modin3s),
        Method::new(MethodId::Csv1),
        Method::new(MethodId::Rk4),
        Method::new(MethodId::Heun),
    ];
    println!(
        "| problem | method | ns/step, step by step | ns/step, fused stretches | checksum (fused) |"
    );
    println!("|---|---|---|---|---|");
    let p1 = Pendulum { gamma: 0.005 };
    let p1_start = State::from_slices(nalgebra::U1, &[0.9 * std::f64::consts::PI], &[0.0]);
    for c in &choices {
        let name = format!("P1 {}", c.label());
        if wanted(&name) {
            let (single, _) = measure_step_by_step(&p1, c, &p1_start);
            let (ns, sum) = measure(&p1, c, &p1_start);
            println!(
                "| P1 pendulum | {} | {single:.1} | {ns:.1} | {sum:.6e} |",
                c.label()
            );
        }
    }
    let p2 = ElasticPendulum3d {
        m: 1.0,
        k: 1.0,
        l: 1.0,
        g: 1.0,
        epsilon: 0.1,
    };
    let p2_start = State::from_slices(
        nalgebra::U3,
        &[0.0, 1.558_845_73, -0.6],
        &[1.341_640_79, 0.0, 0.0],
    );
    for c in choices.iter().filter(|c| c.id() != MethodId::Csv1) {
        let name = format!("P2 {}", c.label());
        if wanted(&name) {
            let (single, _) = measure_step_by_step(&p2, c, &p2_start);
            let (ns, sum) = measure(&p2, c, &p2_start);
            println!(
                "| P2 elastic pendulum | {} | {single:.1} | {ns:.1} | {sum:.6e} |",
                c.label()
            );
        }
    }
    if wanted("stability") {
        stability_maps();
    }
}
