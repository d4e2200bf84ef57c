//! Long horizons with weak damping: the wall time each method needs to reach a max energy error
//! of 1e-6 and 1e-8 over [0, T], the protocol of the peers' long-horizon experiment
//! (`run_long.sh` beside the project): 50 sample times t_k = kT/50, error
//! max_k |H(t_k) − H_ref(t_k)|.
//!
//! Problems: P2' the elastic 3-D pendulum (paper 000 Sec. 6.2; m = k = l = g = 1, radial damping
//! ε ∈ {1e-3, 1e-4}, q0 = (0, 1.55884573, −0.6), p0 = (1.34164079, 0, 0)) and P1' the damped
//! pendulum (ε = 2γ = 1e-4, q0 = 0.9π, p0 = 0), each at T ∈ {1e4, 1e5}.
//!
//! Methods: geomint's compositions of modin_3s (orders 2, 4, 6, 8) and the sixth- and
//! eighth-order ones (Kahan–Li's, and Blanes–Casas–Murua's processed one) of modin_2s too, at
//! fixed steps that divide T/50, its rk4, and its adaptive reference integrator (DOP853, one
//! segment per sample interval) at tolerances 1e-7 … 1e-13. Wall time is the whole sampled run:
//! building the stepper, the steps and the 50 energy evaluations; runs under 50 ms take the
//! median of 5, under 1.5 s the median of 3. The equal-accuracy time is found as the peers find
//! it: settings sorted by time, each error replaced by the worst error of that and every more
//! expensive setting, then log–log interpolation between the last setting that misses the target
//! and the first that meets it (`<x`: the cheapest setting meets it already; `-`: none does).
//!
//! Reference energies: kahan_li_8(modin_3s) at h = 0.025 (error ≈ round-off, bounded in time),
//! checked against the same at h = 0.05 and against the adaptive DOP853 at tolerance 1e-13.
//!
//! With `GEOMINT_PEERS_LONG=DIR` (a results folder of `run_long.sh`, run just before on the
//! same machine) the table also gives the peers' ode_solvers Dop853 and Dopri5 times from
//! `DIR/tables_long.md` and their ratio to geomint's fastest geometric method.
//!
//! A second table times the reference against the `ode_solvers` crate's Dop853 (the same formula,
//! which geomint called before and which reproduces it bit for bit) on P1' and P2': the same
//! segments, each a fresh solver from the previous end state, on fixed-size vectors, and on the
//! dynamic vectors geomint used to hand it. The end states are checked to be the same to the bit.
//!
//! `cargo bench --bench long [-- FILTER]` (FILTER matches the problem name, e.g. `P2' eps=0.0001`,
//! or `DOP853` for the second table alone).

use std::collections::BTreeMap;
use std::hint::black_box;
use std::time::Instant;

use geomint::core::methods::composition::Scheme;
use geomint::core::methods::{self, Base, Method, MethodId};
use geomint::core::run::{integrate, Budget, Observer, RunEnd, Schedule};
use geomint::core::system::{MechanicalSystem, State};
use geomint::core::systems::{ElasticPendulum3d, Pendulum};
use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

#[path = "long/against_crate.rs"]
mod against_crate;
use against_crate::against_crate;

/// Sample times per run.
const SAMPLES: u64 = 50;
/// Energy-error targets.
const TARGETS: [f64; 2] = [1e-6, 1e-8];

/// Energy (and J₃ for 3-D problems) at the sample times.
struct Sampled {
    energy: Vec<f64>,
    j3: Vec<f64>,
}

/// Records H and J₃ = q₀p₁ − q₁p₀ at every sample but the initial one.
struct Recorder<'a, S> {
    sys: &'a S,
    out: Sampled,
}

impl<S: MechanicalSystem> Observer<S::Dim> for Recorder<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn on_sample(&mut self, step: u64, _t: f64, z: &State<S::Dim>) {
        if step == 0 {
            return;
        }
        self.out.energy.push(self.sys.energy(&z.q, &z.p));
        if z.q.len() >= 2 {
            self.out.j3.push(z.q[0] * z.p[1] - z.q[1] * z.p[0]);
        }
    }
}

/// A method at one setting.
#[derive(Clone, Debug)]
struct Setting {
    choice: Method,
    /// The fixed step, or for the adaptive reference its segment length T/50.
    h: f64,
}

impl Setting {
    fn fixed(choice: Method, h: f64) -> Self {
        Setting { choice, h }
    }

    fn describe(&self) -> String {
        match self.choice {
            Method::Reference { tolerance: tol } => format!("tol={tol:e}"),
            _ => format!("h={}", self.h),
        }
    }
}

/// One sampled run of `setting` over [0, t_end].
fn sampled_run<S: MechanicalSystem>(
    sys: &S,
    setting: &Setting,
    start: &State<S::Dim>,
    t_end: f64,
) -> (Sampled, u64)
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let steps = (t_end / setting.h).round() as u64;
    assert_eq!(steps % SAMPLES, 0, "h = {} must divide T/50", setting.h);
    let schedule = Schedule {
        h: setting.h,
        steps,
        every: steps / SAMPLES,
    };
    let mut stepper = methods::build(&setting.choice, sys, "bench", setting.h).expect("builds");
    let mut z = start.clone();
    let mut recorder = Recorder {
        sys,
        out: Sampled {
            energy: Vec::with_capacity(SAMPLES as usize),
            j3: Vec::with_capacity(SAMPLES as usize),
        },
    };
    let (stop, stats) = integrate(
        sys,
        &mut stepper,
        &mut z,
        schedule,
        Budget::default(),
        &mut recorder,
    )
    .expect("the run");
    assert_eq!(stop, RunEnd::Finished, "{}", setting.choice.label());
    (recorder.out, stats.force_evaluations)
}

/// What one setting measured.
#[derive(Clone, Debug)]
struct Measured {
    method: String,
    setting: String,
    ms: f64,
    max_dh: f64,
    max_dj3: Option<f64>,
    force_evaluations: u64,
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs[xs.len() / 2]
}

/// Times `setting` and measures its errors against the reference energies.
fn measure<S: MechanicalSystem>(
    sys: &S,
    setting: &Setting,
    start: &State<S::Dim>,
    t_end: f64,
    reference: &Sampled,
) -> Measured
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let began = Instant::now();
    let (sampled, force_evaluations) = sampled_run(sys, setting, black_box(start), t_end);
    let first = began.elapsed().as_secs_f64() * 1e3;
    let repeats = if first < 50.0 {
        5
    } else if first < 1500.0 {
        3
    } else {
        1
    };
    let mut times = vec![first];
    for _ in 1..repeats {
        let began = Instant::now();
        black_box(sampled_run(sys, setting, black_box(start), t_end));
        times.push(began.elapsed().as_secs_f64() * 1e3);
    }
    let max_dh = sampled
        .energy
        .iter()
        .zip(&reference.energy)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let j3_0 = start
        .q
        .get(0)
        .zip(start.q.get(1))
        .map(|(&x, &y)| x * start.p[1] - y * start.p[0]);
    let max_dj3 = j3_0.filter(|_| !sampled.j3.is_empty()).map(|j0| {
        sampled
            .j3
            .iter()
            .map(|j| (j - j0).abs())
            .fold(0.0, f64::max)
    });
    // Every tolerance of the adaptive reference is one method for the equal-accuracy rule.
    let method = match setting.choice.id() {
        MethodId::Reference => "reference".to_string(),
        _ => setting.choice.label(),
    };
    Measured {
        method,
        setting: setting.describe(),
        ms: median(times),
        max_dh,
        max_dj3,
        force_evaluations,
    }
}

/// The time to reach `target` with the settings of one method (the peers' rule), or `None`.
/// The flag says the cheapest setting meets the target already (printed `<x`).
fn cost_to_target(runs: &[&Measured], target: f64) -> Option<(f64, bool)> {
    let mut runs: Vec<(f64, f64)> = runs.iter().map(|m| (m.ms, m.max_dh)).collect();
    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    // The worst error of this and every more expensive setting.
    for k in (0..runs.len().saturating_sub(1)).rev() {
        runs[k].1 = runs[k].1.max(runs[k + 1].1);
    }
    let first_hit = runs.iter().position(|r| r.1 <= target)?;
    if first_hit == 0 {
        return Some((runs[0].0, true));
    }
    let (t0, e0) = runs[first_hit - 1];
    let (t1, e1) = runs[first_hit];
    if !(e0 > 0.0 && e1 > 0.0 && e0 != e1) {
        return Some((t1, false));
    }
    let s = (target.ln() - e0.ln()) / (e1.ln() - e0.ln());
    Some(((t0.ln() + s * (t1.ln() - t0.ln())).exp(), false))
}

fn format_cost(cost: Option<(f64, bool)>) -> String {
    match cost {
        None => "-".into(),
        Some((ms, true)) => format!("<{ms:.3}"),
        Some((ms, false)) => format!("{ms:.3}"),
    }
}

/// A long-horizon case.
struct Case {
    /// As the peers' tables name it, e.g. `P2' eps=0.0001`.
    name: String,
    t_end: f64,
}

impl Case {
    /// The peers' column name, e.g. `T=1e+05 1e-08`.
    fn column(&self, target: f64) -> String {
        format!("T={} {}", python_e(self.t_end, 0), python_e(target, 0))
    }
}

/// `x` in Python's `{:.Ne}` form (`1e+05`).
fn python_e(x: f64, digits: usize) -> String {
    let s = format!("{x:.digits$e}");
    let (mantissa, exponent) = s.split_once('e').expect("exponent form");
    let exponent: i32 = exponent.parse().expect("an exponent");
    let sign = if exponent < 0 { '-' } else { '+' };
    format!("{mantissa}e{sign}{:02}", exponent.abs())
}

/// The peers' equal-accuracy table: (problem, column) → cell, for each method row.
type PeerTable = BTreeMap<(String, String, String), String>;

/// Reads the "Equal-accuracy wall time" section of the peers' `tables_long.md`.
fn peer_table(markdown: &str) -> PeerTable {
    let mut table = PeerTable::new();
    let mut in_section = false;
    let mut problem = String::new();
    let mut columns: Vec<String> = Vec::new();
    for line in markdown.lines() {
        if line.starts_with("### ") {
            in_section = line.starts_with("### Equal-accuracy wall time");
            continue;
        }
        if !in_section {
            continue;
        }
        if let Some(name) = line.strip_suffix(':') {
            problem = name.trim().to_string();
        } else if line.starts_with("| method |") {
            columns = line.split('|').map(|c| c.trim().to_string()).collect();
        } else if line.starts_with("| ") && !line.starts_with("|---") {
            let cells: Vec<&str> = line.split('|').map(str::trim).collect();
            for (k, cell) in cells.iter().enumerate().skip(2) {
                if let Some(column) = columns.get(k) {
                    table.insert(
                        (problem.clone(), cells[1].to_string(), column.clone()),
                        cell.to_string(),
                    );
                }
            }
        }
    }
    table
}

fn parse_cell(cell: &str) -> Option<f64> {
    cell.trim_start_matches('<').parse().ok()
}

/// Runs every setting of one case and prints its tables.
fn run_case<S: MechanicalSystem>(
    case: &Case,
    sys: &S,
    start: &State<S::Dim>,
    peers: Option<&PeerTable>,
) where
    DefaultAllocator: Allocator<S::Dim>,
{
    let t_end = case.t_end;
    let segment = t_end / SAMPLES as f64;
    let kl8 = Method::composition(Scheme::of(MethodId::KahanLi8).unwrap(), Base::Modin3s);
    let began = Instant::now();
    let (reference, _) = sampled_run(sys, &Setting::fixed(kl8.clone(), 0.025), start, t_end);
    let (coarser, _) = sampled_run(sys, &Setting::fixed(kl8.clone(), 0.05), start, t_end);
    let tight = Method::Reference { tolerance: 1e-13 };
    let (adaptive, _) = sampled_run(sys, &Setting::fixed(tight, segment), start, t_end);
    let diff = |a: &Sampled| {
        a.energy
            .iter()
            .zip(&reference.energy)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    };
    println!(
        "\n## {} T={t_end:e}\n\nreference kahan_li_8(modin_3s) h=0.025: H_ref(T) = {:.12e}; \
         max |dH| against h=0.05: {:.2e}, against DOP853 tol 1e-13: {:.2e} ({:.1} s)\n",
        case.name,
        reference.energy.last().copied().unwrap_or(f64::NAN),
        diff(&coarser),
        diff(&adaptive),
        began.elapsed().as_secs_f64()
    );

    let composition = |id| Method::composition(Scheme::of(id).unwrap(), Base::Modin3s);
    let mut settings: Vec<Setting> = Vec::new();
    for h in [0.05, 0.025, 0.0125] {
        settings.push(Setting::fixed(Method::new(MethodId::Modin3s), h));
    }
    for h in [0.2, 0.1, 0.05, 0.025] {
        settings.push(Setting::fixed(composition(MethodId::TripleJump), h));
    }
    // The sixth- and eighth-order ones of modin_3s and of modin_2s, whose stage is two flows
    // against 3S's four once the seams are fused. The eighth-order ones also at h = 0.5: their
    // errors fall by about 2¹⁰ from 0.8 to 0.4 (not yet 2⁸), so the log–log interpolation across
    // that octave overstates the cost near 1e-8.
    for base in [Base::Modin3s, Base::Modin2s] {
        for h in [0.4, 0.2, 0.1, 0.05] {
            settings.push(Setting::fixed(
                Method::composition(Scheme::of(MethodId::KahanLi6).unwrap(), base),
                h,
            ));
        }
        for scheme in [
            Scheme::of(MethodId::KahanLi8).unwrap(),
            Scheme::of(MethodId::BlanesCasasMurua8).unwrap(),
        ] {
            for h in [1.6, 0.8, 0.5, 0.4, 0.2, 0.1] {
                settings.push(Setting::fixed(Method::composition(scheme, base), h));
            }
        }
    }
    for h in [0.1, 0.05, 0.025, 0.0125] {
        settings.push(Setting::fixed(Method::new(MethodId::Rk4), h));
    }
    for tol in [1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13] {
        settings.push(Setting::fixed(
            Method::Reference { tolerance: tol },
            segment,
        ));
    }

    println!("| method | setting | ms | max abs dH | max abs dJ3 | force evaluations |");
    println!("|---|---|---|---|---|---|");
    let mut measured = Vec::new();
    for setting in &settings {
        let m = measure(sys, setting, start, t_end, &reference);
        println!(
            "| {} | {} | {:.3} | {:.2e} | {} | {} |",
            m.method,
            m.setting,
            m.ms,
            m.max_dh,
            m.max_dj3.map_or("-".into(), |d| format!("{d:.1e}")),
            m.force_evaluations
        );
        measured.push(m);
    }

    let mut methods: Vec<String> = Vec::new();
    for m in &measured {
        if !methods.contains(&m.method) {
            methods.push(m.method.clone());
        }
    }
    let cost = |method: &str, target: f64| {
        let runs: Vec<&Measured> = measured.iter().filter(|m| m.method == method).collect();
        cost_to_target(&runs, target)
    };
    println!("\nEqual-accuracy wall time (ms) to reach max |dH| ≤ target:\n");
    println!(
        "| method | {} |",
        TARGETS.map(|t| format!("{t:e}")).join(" | ")
    );
    println!("|---|{}", "---|".repeat(TARGETS.len()));
    for method in &methods {
        let cells = TARGETS.map(|t| format_cost(cost(method, t)));
        println!("| {method} | {} |", cells.join(" | "));
    }
    let geometric = methods
        .iter()
        .filter(|m| !["rk4", "reference"].contains(&m.as_str()));
    for target in TARGETS {
        let best = geometric
            .clone()
            .filter_map(|m| cost(m, target).map(|c| (c.0, m.as_str())))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let Some((best_ms, best_method)) = best else {
            println!("\n{target:e}: no geometric method reaches the target");
            continue;
        };
        let mut line = format!("\n{target:e}: fastest geometric {best_method} {best_ms:.3} ms");
        for (label, method) in [("rk4", "rk4"), ("reference (DOP853)", "reference")] {
            match cost(method, target) {
                Some((ms, _)) => {
                    line.push_str(&format!("; {label} {ms:.3} ms (ratio {:.2})", ms / best_ms))
                }
                None => line.push_str(&format!("; {label} -")),
            }
        }
        if let Some(peers) = peers {
            for peer in ["ode_solvers Dop853", "ode_solvers Dopri5", "floor 3S-TJ4m"] {
                let key = (case.name.clone(), peer.to_string(), case.column(target));
                match peers.get(&key).and_then(|c| parse_cell(c)) {
                    Some(ms) => line.push_str(&format!(
                        "; peers' {peer} {ms:.3} ms (ratio {:.2})",
                        ms / best_ms
                    )),
                    None => line.push_str(&format!("; peers' {peer} -")),
                }
            }
        }
        println!("{line}");
    }
}

fn main() {
    let filter: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let wanted = |name: &str| filter.is_empty() || filter.iter().any(|f| name.contains(f.as_str()));
    let peers = std::env::var_os("GEOMINT_PEERS_LONG").map(|dir| {
        let path = std::path::Path::new(&dir).join("tables_long.md");
        let text = std::fs::read_to_string(&path)
            .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
        peer_table(&text)
    });
    println!("# Long horizons: time to a max energy error (50 samples on [0, T])");
    let p2_start = State::from_slices(
        nalgebra::U3,
        &[0.0, 1.558_845_73, -0.6],
        &[1.341_640_79, 0.0, 0.0],
    );
    for eps in [1e-3, 1e-4] {
        let sys = ElasticPendulum3d {
            m: 1.0,
            k: 1.0,
            l: 1.0,
            g: 1.0,
            epsilon: eps,
        };
        for t_end in [1e4, 1e5] {
            let case = Case {
                name: format!("P2' eps={eps}"),
                t_end,
            };
            if wanted(&case.name) {
                run_case(&case, &sys, &p2_start, peers.as_ref());
            }
        }
    }
    let p1 = Pendulum { gamma: 0.5e-4 };
    let p1_start = State::from_slices(nalgebra::U1, &[0.9 * std::f64::consts::PI], &[0.0]);
    for t_end in [1e4, 1e5] {
        let case = Case {
            name: "P1' eps=0.0001".to_string(),
            t_end,
        };
        if wanted(&case.name) {
            run_case(&case, &p1, &p1_start, peers.as_ref());
        }
    }
    if wanted("DOP853") {
        println!(
            "\n# Reference against ode_solvers' Dop853 on [0, 1000] (ns per accepted step; \
             ratios of wall times, median of 5)\n"
        );
        println!(
            "| problem | segment | tol | accepted steps | reference | Dop853 SVector | \
             Dop853 DVector | reference / SVector | reference / DVector |"
        );
        println!("|---|---|---|---|---|---|---|---|---|");
        let p2 = ElasticPendulum3d {
            m: 1.0,
            k: 1.0,
            l: 1.0,
            g: 1.0,
            epsilon: 1e-4,
        };
        against_crate::<_, 2>("P1' eps=0.0001", &p1, &p1_start, 1e3);
        against_crate::<_, 6>("P2' eps=0.0001", &p2, &p2_start, 1e3);
    }
}
