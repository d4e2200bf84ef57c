//! The run `scripts/bench-local` times through `geomint.local` in Python, timed here in Rust
//! through the same function the module calls (`geomint_api::simulate::simulate_to_json`:
//! the request read, the run, the document written): the pendulum with modin_3s, h = 0.01 to
//! t_end = 10⁴ (10⁶ steps, two samples). One warm-up, then the median of 9 runs.

use std::time::Instant;

use geomint_api::simulate::simulate_to_json;
use geomint_core::simulation::Limits;

/// The request, as `geomint.local.simulate("pendulum", ["modin_3s"], h=0.01, t_end=10_000,
/// every=1_000_000)` sends it.
pub const REQUEST: &str = r#"{"system": "pendulum", "methods": ["modin_3s"], "h": 0.01, "t_end": 10000, "output": {"every": 1000000}}"#;

fn main() {
    let run = || {
        let began = Instant::now();
        let document =
            simulate_to_json(REQUEST.as_bytes(), &Limits::default(), 1).expect("the request runs");
        (began.elapsed().as_secs_f64() * 1e3, document.len())
    };
    run();
    let mut times: Vec<f64> = (0..9).map(|_| run().0).collect();
    times.sort_by(f64::total_cmp);
    println!(
        "rust: 10^6 pendulum steps (modin_3s) through simulate_to_json: median {:.2} ms \
         (min {:.2}, max {:.2}), {:.2} ns per step",
        times[4],
        times[0],
        times[8],
        times[4] * 1e6 / 1e6
    );
}
