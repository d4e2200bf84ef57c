//! Hénon's step against its derivation, on the harmonic oscillator q = cos t, p = −sin t
//! (ω = 1, undamped), whose crossings are known in closed form.

use geomint_core::error::Field;
use geomint_core::sections::henon::Henon;
use geomint_core::sections::names::StateNames;
use geomint_core::sections::Surface;
use geomint_core::system::State;
use geomint_core::systems::HarmonicOscillator;
use nalgebra::U1;

const OSCILLATOR: HarmonicOscillator = HarmonicOscillator {
    omega: 1.0,
    gamma: 0.0,
};

fn exact(t: f64) -> State<U1> {
    State::from_slices(U1, &[t.cos()], &[-t.sin()])
}

fn names() -> StateNames {
    StateNames {
        coordinates: vec!["q".into()],
        momenta: vec!["p_q".into()],
        params: vec![("a".into(), 0.0)],
        time: Some("t".into()),
    }
}

fn surface(text: &str) -> Surface {
    Surface::expression(text, &names(), &Field::new("section.where")).expect("compiles")
}

/// Locates S = 0 from the exact state at `t0`.
fn locate(henon: &mut Henon<U1>, s: &Surface, t0: f64) -> (f64, State<U1>) {
    let z0 = exact(t0);
    let s0 = henon.value(s, &z0, t0);
    let mut out = z0.clone();
    let t = henon
        .locate(&OSCILLATOR, s, (&z0, t0, s0), 0.0, &mut out)
        .expect("located");
    (t, out)
}

#[test]
fn the_step_lands_on_the_exact_crossing_from_any_state_before_it() {
    // q = a is crossed downwards at t* = arccos a: from states up to 0.5 before it, in one
    // step of s (sub-steps where the estimate asks), the located t, q and p are the exact ones.
    let mut henon = Henon::new(U1, 1);
    let mut worst = [0.0f64; 3];
    for a in [0.9, 0.3, -0.5, -0.95] {
        let s = surface(&format!("q - ({a})"));
        let t_star = f64::acos(a);
        // From states after q's turning point at t = 0 (before it, S is no clock).
        for delta in [1e-3, 0.05, 0.2, 0.5].into_iter().filter(|&d| d < t_star) {
            let (t, z) = locate(&mut henon, &s, t_star - delta);
            worst[0] = worst[0].max((t - t_star).abs());
            worst[1] = worst[1].max((z.q[0] - a).abs());
            worst[2] = worst[2].max((z.p[0] + t_star.sin()).abs());
        }
    }
    println!("crossing of q = a: |Δt|, |Δq|, |Δp| at most {worst:?}");
    assert!(worst[0] <= 4e-15, "{worst:?}");
    assert!(worst[1] <= 2e-16, "{worst:?}");
    assert!(worst[2] <= 4e-15, "{worst:?}");
}

#[test]
fn a_surface_in_t_needs_its_time_derivative() {
    // S = q − 0.2 cos t = 0.8 cos t vanishes at t = π/2; σ = ∇S·f + ∂S/∂t = −sin t + 0.2 sin t.
    // Without ∂S/∂t (the printed dz/dS = f/(∇S·f)) the step would miss π/2 by O(δ²).
    let mut henon = Henon::new(U1, 1);
    let s = surface("q - 0.2*cos(t)");
    let half_pi = std::f64::consts::FRAC_PI_2;
    for delta in [0.01, 0.1, 0.4] {
        let (t, z) = locate(&mut henon, &s, half_pi - delta);
        assert!((t - half_pi).abs() <= 4e-15, "δ = {delta}: t = {t}");
        assert!(z.q[0].abs() <= 4e-16, "δ = {delta}: q = {:e}", z.q[0]);
        let rate = henon.rate(&OSCILLATOR, &s, &exact(1.0), 1.0);
        assert!((rate + 0.8 * f64::sin(1.0)).abs() <= 1e-15, "σ = {rate}");
    }
}

#[test]
fn a_clock_surface_is_a_plain_time_step() {
    // S = t: σ = 1, dz/ds = f, and the point at level t* is the exact state at t*.
    let mut henon = Henon::new(U1, 1);
    let s = Surface::Clock {
        period: 1.0,
        phase: 0.0,
    };
    for (t0, t_star) in [(0.0, 0.07), (1.3, 1.4), (2.0, 2.6)] {
        let z0 = exact(t0);
        let mut out = z0.clone();
        let t = henon
            .locate(&OSCILLATOR, &s, (&z0, t0, t0), t_star, &mut out)
            .expect("located");
        assert_eq!(t, t_star);
        let e = exact(t_star);
        let err = (out.q[0] - e.q[0]).abs().max((out.p[0] - e.p[0]).abs());
        assert!(err <= 1e-15, "t* = {t_star}: {err:e}");
    }
}

#[test]
fn the_field_in_s_is_the_difference_quotient_along_the_solution() {
    // dz/ds = f/σ with the engine's exact ∇S, against (z(t+δ) − z(t−δ))/(S(t+δ) − S(t−δ)).
    let mut henon = Henon::new(U1, 1);
    let text = "q^2 + 0.3*p_q - 0.2 + 0.1*sin(t)";
    let s = surface(text);
    let value = |t: f64| {
        let (q, p) = (t.cos(), -t.sin());
        q * q + 0.3 * p - 0.2 + 0.1 * t.sin()
    };
    for t in [0.4, 1.1, 2.5, 4.0] {
        let sigma = henon.rate(&OSCILLATOR, &s, &exact(t), t);
        let d = 1e-5;
        let ds = value(t + d) - value(t - d);
        let dq_ds = ((t + d).cos() - (t - d).cos()) / ds;
        let dp_ds = (-(t + d).sin() + (t - d).sin()) / ds;
        let dt_ds = 2.0 * d / ds;
        let (f_q, f_p) = (-t.sin(), -t.cos());
        for (got, want) in [
            (f_q / sigma, dq_ds),
            (f_p / sigma, dp_ds),
            (1.0 / sigma, dt_ds),
        ] {
            assert!(
                (got - want).abs() <= 1e-8 * (1.0 + want.abs()),
                "t = {t}: {got} against {want}"
            );
        }
    }
}

#[test]
fn a_coordinate_or_momentum_alone_is_read_off_as_the_compiled_functions_give_it() {
    // `q` and `p_q` alone are read off the state and its velocity; `0 + q` and `0 + p_q` go
    // through the compiled value and gradient. Same bits over states and velocities of every
    // sign and scale.
    let (inputs, outputs) = Surface::buffers(1);
    let (mut i1, mut o1, mut i2, mut o2) = (inputs.clone(), outputs.clone(), inputs, outputs);
    let mut compared = 0;
    for (read, compiled) in [("q", "0 + q"), ("p_q", "0 + p_q")] {
        let (read, compiled) = (surface(read), surface(compiled));
        for k in 0..200 {
            let x = |j: i32| (f64::from(k * 37 + j * 11).sin() * 1e3).powi(j % 3 + 1);
            let (q, p, dq, dp, t) = ([x(1)], [x(2)], [x(3)], [x(4)], x(5));
            let a = read.rate((&q, &p, t), (&dq, &dp), &mut i1, &mut o1);
            let b = compiled.rate((&q, &p, t), (&dq, &dp), &mut i2, &mut o2);
            assert_eq!(
                (a.0.to_bits(), a.1.to_bits()),
                (b.0.to_bits(), b.1.to_bits())
            );
            let (va, vb) = (
                read.value(&q, &p, t, &mut i1),
                compiled.value(&q, &p, t, &mut i2),
            );
            assert_eq!(va.to_bits(), vb.to_bits());
            compared += 1;
        }
    }
    assert_eq!(compared, 400);
}
