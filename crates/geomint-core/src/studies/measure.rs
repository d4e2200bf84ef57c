//! One setting's run measured: its errors over the samples against the truth ([`Measure`]), its
//! wall time (timed again on request, and always when short, with the median as the time), and
//! how it stopped, in the studies' words.

use std::time::Instant;

use crate::error::CoreError;
use crate::run::{Budget, RunEnd};
use crate::simulation::{RunReport, Sample, SampleSink, Simulation};

/// Runs shorter than this many milliseconds are timed [`SHORT_RUN_REPEATS`] times.
const SHORT_RUN_MS: f64 = 20.0;
/// Timings of a short run; its wall time is their median.
const SHORT_RUN_REPEATS: usize = 5;

/// Collects what a study measures from one run's samples.
pub struct Measure<'a> {
    /// The system's invariant names.
    pub names: Vec<String>,
    reference_energies: Option<&'a [f64]>,
    /// max_k |H(t_k) − H_exact(t_k)|.
    pub max_energy_error: f64,
    /// H − H_exact at the last sample.
    pub last_energy_error: Option<f64>,
    invariants_at_start: Vec<f64>,
    /// max_k |I(t_k) − I(0)| per invariant.
    pub drift: Vec<f64>,
    /// H at every sample (the truth's energies, when this is the reference run).
    pub(super) energies: Vec<f64>,
    /// The last state, in Cartesian coordinates.
    pub last: Option<(Vec<f64>, Vec<f64>)>,
}

impl<'a> Measure<'a> {
    /// Nothing measured yet, against `reference_energies` (none: the exact solution).
    pub(super) fn new(names: Vec<String>, reference_energies: Option<&'a [f64]>) -> Self {
        Measure {
            names,
            reference_energies,
            max_energy_error: 0.0,
            last_energy_error: None,
            invariants_at_start: Vec::new(),
            drift: Vec::new(),
            energies: Vec::new(),
            last: None,
        }
    }
}

impl SampleSink for Measure<'_> {
    fn on_sample(&mut self, s: &Sample<'_>) {
        if let Some(e) = s.energy_error {
            self.max_energy_error = self.max_energy_error.max(e.abs());
        }
        self.last_energy_error = s.energy_error;
        if self.invariants_at_start.is_empty() {
            self.invariants_at_start = s.invariants.to_vec();
            self.drift = vec![0.0; s.invariants.len()];
        }
        for (k, (&v, &v0)) in s
            .invariants
            .iter()
            .zip(&self.invariants_at_start)
            .enumerate()
        {
            self.drift[k] = self.drift[k].max((v - v0).abs());
        }
        if self.reference_energies.is_none() {
            self.energies.push(s.energy);
        }
        let (q, p) = s.cartesian.unwrap_or((s.q, s.p));
        self.last = Some((q.to_vec(), p.to_vec()));
    }

    fn wants_bodies(&self) -> bool {
        false
    }
}

/// Runs the setting `sim` once against the reference `energies` and measures it; also returns
/// the wall time in milliseconds.
pub fn measure_once<'a>(
    sim: &Simulation,
    energies: Option<&'a [f64]>,
    budget: Budget<'_>,
) -> Result<(RunReport, Measure<'a>, f64), CoreError> {
    let mut sink = Measure::new(sim.invariant_names(), energies);
    let began = Instant::now();
    let outcome = sim
        .run_method(0, energies, budget, &mut sink)
        .map_err(|e| match e {
            CoreError::Step {
                step, t, source, ..
            } => CoreError::Step {
                field: None,
                run: Some(sim.methods[0].label()),
                step,
                t,
                source,
            },
            other => other,
        })?;
    Ok((outcome, sink, began.elapsed().as_secs_f64() * 1e3))
}

/// Most timings of one setting a study may ask for.
pub const MAX_REPEATS: u64 = 20;

/// [`measure_once`] timed `repeats` times (their numbers are the same, bit for bit), and a short
/// run at least [`SHORT_RUN_REPEATS`] times: every timing, fastest first. Their median is the
/// setting's wall time, so that one scheduling hiccup does not move a point of a diagram. A run
/// that did not finish is timed once.
pub fn measure_timed<'a>(
    sim: &Simulation,
    energies: Option<&'a [f64]>,
    budget: Budget<'_>,
    repeats: usize,
) -> Result<(RunReport, Measure<'a>, Vec<f64>), CoreError> {
    let (outcome, sink, first) = measure_once(sim, energies, budget)?;
    let mut times = vec![first];
    let wanted = if first < SHORT_RUN_MS {
        repeats.max(SHORT_RUN_REPEATS)
    } else {
        repeats
    };
    while outcome.stop == RunEnd::Finished && times.len() < wanted {
        times.push(measure_once(sim, energies, budget)?.2);
    }
    times.sort_by(f64::total_cmp);
    Ok((outcome, sink, times))
}

/// The median of timings sorted fastest first (the upper one of an even count, as a setting's
/// wall time has always been taken).
pub fn median(sorted: &[f64]) -> f64 {
    sorted[sorted.len() / 2]
}

/// How a run stopped, as studies report it.
pub fn stop_name(stop: &RunEnd) -> &'static str {
    match stop {
        RunEnd::Finished => "finished",
        RunEnd::Diverged { .. } => "diverged",
        RunEnd::Cancelled { .. } => "cancelled",
        RunEnd::TimeLimit { .. } => "time_limit",
        RunEnd::Event { .. } => "event",
        RunEnd::Indicator(_) => "indicator",
    }
}
