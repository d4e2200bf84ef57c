//! Time to write a Rerun recording of 10⁶ samples (the pendulum, modin_3s, h = 0.001 over
//! [0, 1000], every step sampled): one warm-up, then the median of 5 writes into memory.

use std::time::Instant;

use geomint::api::SimulateRequest;
use geomint::core::run::Budget;
use geomint::core::simulation::Limits;
use geomint::recording;

fn main() {
    let limits = Limits {
        max_steps: 10_000_000,
        max_samples: 2_000_000,
    };
    let body = serde_json::json!({"system": "pendulum", "method": "modin_3s",
        "h": 0.001, "t_end": 1000, "output": {"every": 1}});
    let spec = SimulateRequest::from_value(&body).expect("a valid spec");
    let sim = spec
        .prepare(&limits, &geomint::api::system::NoStoredSystems)
        .expect("within the limits");
    let doc = sim.simulate(1, Budget::default()).expect("the run");
    let samples = doc.runs[0].columns.energy.len();
    let mut bytes = 0;
    let mut times: Vec<f64> = (0..6)
        .map(|_| {
            let began = Instant::now();
            bytes = recording::rrd_bytes(&recording::Spec::of(&spec), &doc)
                .expect("a recording")
                .len();
            began.elapsed().as_secs_f64() * 1e3
        })
        .skip(1)
        .collect();
    times.sort_by(f64::total_cmp);
    println!(
        "recording of {samples} samples: median {:.0} ms (min {:.0}, max {:.0}), {:.1} MB",
        times[2],
        times[0],
        times[4],
        bytes as f64 / 1e6
    );
}
