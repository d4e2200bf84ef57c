//! Runs of one simulation's method from up to [`LANES`] initial states, side by side in SIMD
//! lanes (see [`crate::methods::lanes`]): a chaos map's cells with their indicators, or a sweep's
//! plain runs. For each run the driver does what [`integrate_tracked`](crate::run::integrate_tracked)
//! does — the samples, the indicators' updates on their grid and their thresholds, divergence, the
//! budget, and for plain runs the stretches between samples with their fused seams — and hands
//! the samples to the same observer, so each run's samples and outcome are bit for bit the
//! one-run path's (`tests/core/chaos_map.rs` and `tests/core/sweep_lanes.rs` compare them cell by
//! cell). Runs the lanes cannot take go one by one.

use std::time::Instant;

use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim};

use super::run::{Outcome, SampleSink};
use super::spec::Simulation;
use crate::chaos::{ChaosPlan, OneVectorLanes, ThresholdStop, Tracker};
use crate::error::CoreError;
use crate::methods::lanes::tangent::LANES;
use crate::methods::lanes::{LaneForces, TangentLanes, CHECK_EVERY};
use crate::methods::{self};
use crate::run::{Budget, Observer, RunStats, StopReason};
use crate::system::{MechanicalSystem, State};
use crate::systems::AnySystem;
use crate::tangent::Tangent;

/// Runs `$body` with `$sys` bound to the system inside `$any` if the lanes evaluate it (it
/// implements [`LaneForces`]), else `$other`. A system joins the lanes with an arm here.
macro_rules! with_lane_system {
    ($any:expr, $sys:ident => $body:expr, _ => $other:expr) => {
        match $any {
            AnySystem::HenonHeiles($sys) => $body,
            AnySystem::PlanarCartesian($sys) => $body,
            AnySystem::ElasticPendulum3d($sys) => $body,
            AnySystem::Custom1($sys) => $body,
            AnySystem::Custom2($sys) => $body,
            AnySystem::Custom3($sys) => $body,
            _ => $other,
        }
    };
}

impl Simulation {
    /// Whether runs of this simulation's first method go side by side in lanes: nothing asked
    /// for but samples and, if any, chaos indicators (no section, event, reference run or
    /// Jacobian defect), a composition of kicks and drifts, on an undamped autonomous system the
    /// lanes evaluate (Hénon–Heiles, the planar and the 3-D elastic pendulum in Cartesian
    /// coordinates, typed-in separable systems of one to three degrees of freedom).
    pub fn runs_in_lanes(&self) -> bool {
        with_lane_system!(&self.system, sys => self.lanes(sys).is_some(), _ => false)
    }

    /// The lanes for this simulation's first method on `sys`, if they can run it.
    fn lanes<S, const N: usize>(&self, sys: &S) -> Option<TangentLanes<N>>
    where
        S: MechanicalSystem + LaneForces<N>,
        DefaultAllocator: Allocator<S::Dim>,
    {
        let deviations = self.chaos.as_ref().map_or(0, |plan| plan.deviations);
        let plain = self.crossings.is_none() && !self.compare_to_reference && !self.jacobian_defect;
        let simple = sys.in_lanes()
            && sys.damping_rate() == 0.0
            && sys.clock().is_none()
            && sys.structure().separable_constant_mass
            && sys.dim().value() == N;
        if !plain || !simple {
            return None;
        }
        let h = self.schedule.h;
        let stepper = methods::build(self.methods.first()?, sys, &self.system_label, h).ok()?;
        let z = State::from_slices(sys.dim(), &self.q0, &self.p0);
        let tangent = Tangent::new(sys, &z);
        let mut minv = [[0.0; N]; N];
        for (i, row) in minv.iter_mut().enumerate() {
            for (j, m) in row.iter_mut().enumerate() {
                *m = tangent.minv[(i, j)];
            }
        }
        let flows = stepper.splitting_flows()?;
        TangentLanes::new(flows, sys.damping_rate(), h, minv, deviations)
    }

    /// Runs the first method of each of `sims` (simulations that differ only in their initial
    /// states), each run's samples to its sink: [`LANES`] at a time in lanes where
    /// [`runs_in_lanes`](Self::runs_in_lanes), else one by one. `None` when the budget stopped
    /// a run. A run given back (`Ok(None)`: a plain run whose state's components stayed finite
    /// while their sum overflowed, after which the one-run path cuts its stretches where the
    /// lanes do not) is to be run again on its own, with a fresh sink.
    pub fn run_side_by_side(
        sims: &[Simulation],
        budget: Budget<'_>,
        sinks: &mut [&mut dyn SampleSink],
    ) -> Option<Vec<Result<Option<Outcome>, CoreError>>> {
        let mut outcomes = Vec::with_capacity(sims.len());
        for (group, sinks) in sims.chunks(LANES).zip(sinks.chunks_mut(LANES)) {
            let ran = with_lane_system!(
                &group[0].system,
                sys => side_by_side(sys, group, budget, sinks),
                _ => one_by_one(group, budget, sinks)
            );
            outcomes.extend(ran?);
        }
        Some(outcomes)
    }
}

/// Each run on its own, through the one-run path.
fn one_by_one(
    sims: &[Simulation],
    budget: Budget<'_>,
    sinks: &mut [&mut dyn SampleSink],
) -> Option<Vec<Result<Option<Outcome>, CoreError>>> {
    let mut outcomes = Vec::with_capacity(sims.len());
    for (sim, sink) in sims.iter().zip(sinks) {
        let outcome = sim.run_method(0, None, budget, &mut **sink);
        if outcome.as_ref().is_ok_and(|o| o.stop.by_budget()) {
            return None;
        }
        outcomes.push(outcome.map(Some));
    }
    Some(outcomes)
}

/// Up to [`LANES`] runs of `sims` on `sys` in lanes (one by one if the lanes cannot take them).
fn side_by_side<S, const N: usize>(
    sys: &S,
    sims: &[Simulation],
    budget: Budget<'_>,
    sinks: &mut [&mut dyn SampleSink],
) -> Option<Vec<Result<Option<Outcome>, CoreError>>>
where
    S: MechanicalSystem + LaneForces<N>,
    DefaultAllocator: Allocator<S::Dim>,
{
    let first = &sims[0];
    let Some(lanes) = first.lanes(sys) else {
        return one_by_one(sims, budget, sinks);
    };
    let outcomes = match first.chaos.as_ref() {
        Some(plan) => tracked(sys, lanes, plan, sims, budget, sinks)?
            .into_iter()
            .map(Some)
            .collect(),
        None => plain(sys, lanes, sims, budget, sinks)?,
    };
    Some(outcomes.into_iter().map(Ok).collect())
}

/// Plain runs in lanes: the one-run driver's stretches (up to the next sample, look at the
/// budget or the end), each taken as the one-run stepper takes it ([`TangentLanes::advance_runs`]).
fn plain<S, const N: usize>(
    sys: &S,
    mut lanes: TangentLanes<N>,
    sims: &[Simulation],
    budget: Budget<'_>,
    sinks: &mut [&mut dyn SampleSink],
) -> Option<Vec<Option<Outcome>>>
where
    S: MechanicalSystem + LaneForces<N>,
    DefaultAllocator: Allocator<S::Dim>,
{
    let started = Instant::now();
    let count = sims.len();
    let schedule = sims[0].schedule;
    let (h, steps, every) = (schedule.h, schedule.steps, schedule.every.max(1));
    let starts: Vec<State<S::Dim>> = sims
        .iter()
        .map(|sim| State::at_time(sys, 0.0, &sim.q0, &sim.p0))
        .collect();
    let mut states = starts.clone();
    let mut observers: Vec<_> = sims
        .iter()
        .zip(&starts)
        .zip(sinks.iter_mut())
        .map(|((sim, start), sink)| sim.observer(sys, start, None, &mut **sink, false))
        .collect();
    let mut running = [false; LANES];
    for l in 0..count {
        for i in 0..N {
            lanes.q[i][l] = states[l].q[i];
            lanes.p[i][l] = states[l].p[i];
        }
        running[l] = true;
        observers[l].on_sample(0, 0.0, &states[l]);
    }
    // Per run: how it ended early (the stop, its steps and force evaluations), or given back.
    let mut ended: Vec<Option<Option<(StopReason, u64, u64)>>> = vec![None; count];
    let mut step = 0u64;
    while step < steps && running.contains(&true) {
        if step.is_multiple_of(CHECK_EVERY) && (budget.cancelled() || budget.expired()) {
            return None;
        }
        let next = |m: u64| (step / m + 1) * m;
        let until = next(CHECK_EVERY).min(next(every)).min(steps);
        let stretch = lanes.advance_runs(sys, until - step, &running);
        for (l, end) in stretch.iter().enumerate().take(count) {
            let Some(end) = end.filter(|_| running[l]) else {
                continue;
            };
            running[l] = false;
            let at = step + end.steps;
            ended[l] = Some(end.diverged.then_some((
                StopReason::Diverged {
                    step: at,
                    t: at as f64 * h,
                },
                at,
                end.force_evaluations,
            )));
        }
        step = until;
        if step.is_multiple_of(every) || step == steps {
            let t = step as f64 * h;
            for l in (0..count).filter(|&l| running[l]) {
                for i in 0..N {
                    states[l].q[i] = lanes.q[i][l];
                    states[l].p[i] = lanes.p[i][l];
                }
                observers[l].on_sample(step, t, &states[l]);
            }
        }
    }
    let wall_time_ms = started.elapsed().as_secs_f64() * 1e3;
    let finished = (StopReason::Finished, step, lanes.force_evaluations());
    Some(
        ended
            .into_iter()
            .map(|end| match end {
                None => Some(outcome(finished, wall_time_ms)),
                Some(None) => None,
                Some(Some(end)) => Some(outcome(end, wall_time_ms)),
            })
            .collect(),
    )
}

/// A run's outcome from how it ended: its stop, steps and force evaluations.
fn outcome((stop, steps, force_evaluations): (StopReason, u64, u64), wall_time_ms: f64) -> Outcome {
    Outcome {
        stop,
        stats: RunStats {
            steps,
            force_evaluations,
            wall_time_ms,
        },
    }
}

/// Runs with their chaos indicators in lanes.
fn tracked<S, const N: usize>(
    sys: &S,
    mut lanes: TangentLanes<N>,
    plan: &ChaosPlan,
    sims: &[Simulation],
    budget: Budget<'_>,
    sinks: &mut [&mut dyn SampleSink],
) -> Option<Vec<Outcome>>
where
    S: MechanicalSystem + LaneForces<N>,
    DefaultAllocator: Allocator<S::Dim>,
{
    let first = &sims[0];
    let started = Instant::now();
    let count = sims.len();
    let schedule = first.schedule;
    let (h, steps, every) = (schedule.h, schedule.steps, schedule.every.max(1));
    let qr_every = plan.qr_every.max(1);
    let starts: Vec<State<S::Dim>> = sims
        .iter()
        .map(|sim| State::at_time(sys, 0.0, &sim.q0, &sim.p0))
        .collect();
    let mut states = starts.clone();
    let mut trackers: Vec<Tracker<S::Dim>> = starts
        .iter()
        .map(|z| Tracker::new(sys, z, plan, h))
        .collect();
    let mut observers: Vec<_> = sims
        .iter()
        .zip(&starts)
        .zip(sinks.iter_mut())
        .map(|((sim, start), sink)| sim.observer(sys, start, None, &mut **sink, false))
        .collect();
    // Powers of two the lanes took out of each run's vectors since its tracker last saw them.
    let mut exponents = vec![vec![0; plan.deviations]; count];
    let mut running = [false; LANES];
    for l in 0..count {
        for i in 0..N {
            lanes.q[i][l] = states[l].q[i];
            lanes.p[i][l] = states[l].p[i];
        }
        lanes.load(l, &trackers[l].tangent.jac);
        running[l] = true;
        observers[l].on_indicators(&trackers[l].peek(0));
        observers[l].on_sample(0, 0.0, &states[l]);
    }
    let mut ended: Vec<Option<(StopReason, u64, u64)>> = vec![None; count];
    // With one vector and nothing to look at between samples, the lanes keep the sums and
    // update them together; each run's tracker takes them over at its samples.
    let mut sums = OneVectorLanes::<LANES>::new(plan, h);
    let mut step = 0u64;
    while step < steps && running.iter().any(|&r| r) {
        if step.is_multiple_of(CHECK_EVERY) && (budget.cancelled() || budget.expired()) {
            return None;
        }
        // Up to the next look at the budget, update of the indicators or sample, or the end.
        let next = |m: u64| (step / m + 1) * m;
        let until = next(CHECK_EVERY)
            .min(next(qr_every))
            .min(next(every))
            .min(steps);
        let advanced = lanes.advance(sys, until - step, &running);
        step += advanced.steps;
        let t = step as f64 * h;
        // Lanes whose indicators this step updates: the one-run path leaves them alone after a
        // step whose state's components are finite but overflow when summed.
        let mut update = [false; LANES];
        for l in 0..count {
            if !running[l] {
                continue;
            }
            if advanced.not_finite[l] {
                if !lanes.finite(l) {
                    running[l] = false;
                    let stop = StopReason::Diverged { step, t };
                    ended[l] = Some((stop, step, lanes.force_evaluations()));
                }
                continue;
            }
            if advanced.out_of_range[l] {
                lanes.guard(l, &mut exponents[l]);
            }
            update[l] = step.is_multiple_of(qr_every);
        }
        let mut passed = [None; LANES];
        if let Some(sums) = sums.as_mut() {
            if update.iter().any(|&u| u) {
                let (r, kept) = lanes.normalise_first(&update);
                let e = std::array::from_fn(|l| exponents.get(l).map_or(0, |e| e[0]));
                sums.update(step, &r, &e, &kept);
                for l in 0..count {
                    if kept[l] {
                        exponents[l][0] = 0;
                    } else if update[l] {
                        // A vector with no length: the tracker replaces it.
                        sums.hand_to(l, &mut trackers[l]);
                        hand_over(&lanes, l, &mut trackers[l], &mut exponents[l]);
                        trackers[l].after_step(step);
                        lanes.load(l, &trackers[l].tangent.jac);
                        sums.take_from(l, &trackers[l]);
                    }
                }
            }
        } else {
            for l in (0..count).filter(|&l| update[l]) {
                let tracker = &mut trackers[l];
                hand_over(&lanes, l, tracker, &mut exponents[l]);
                // The tracker's own guard finds the vectors in range: it only updates.
                passed[l] = tracker.after_step(step);
                lanes.load(l, &tracker.tangent.jac);
            }
        }
        for l in 0..count {
            if !running[l] {
                continue;
            }
            let due = step.is_multiple_of(every) || step == steps || passed[l].is_some();
            if due {
                let tracker = &mut trackers[l];
                match &sums {
                    // The lanes' next update still needs the exponents since the last: the
                    // tracker, which only reads the run here, is given a copy.
                    Some(sums) => {
                        sums.hand_to(l, tracker);
                        lanes.store(l, &mut tracker.tangent.jac);
                        tracker.add_exponents(&exponents[l]);
                    }
                    None => hand_over(&lanes, l, tracker, &mut exponents[l]),
                }
                for i in 0..N {
                    states[l].q[i] = lanes.q[i][l];
                    states[l].p[i] = lanes.p[i][l];
                }
                observers[l].on_indicators(&tracker.peek(step));
                observers[l].on_sample(step, t, &states[l]);
            }
            if let Some((indicator, value, threshold)) = passed[l] {
                running[l] = false;
                let stop = StopReason::Indicator(ThresholdStop {
                    step,
                    t,
                    indicator,
                    value,
                    threshold,
                });
                ended[l] = Some((stop, step, lanes.force_evaluations()));
            }
        }
    }
    let wall_time_ms = started.elapsed().as_secs_f64() * 1e3;
    let finished = (StopReason::Finished, step, lanes.force_evaluations());
    Some(
        ended
            .into_iter()
            .map(|end| outcome(end.unwrap_or(finished), wall_time_ms))
            .collect(),
    )
}

/// Gives run `l`'s deviation vectors and the exponents the lanes took out of them to its
/// tracker.
fn hand_over<D: Dim, const N: usize>(
    lanes: &TangentLanes<N>,
    l: usize,
    tracker: &mut Tracker<D>,
    exponents: &mut [i32],
) where
    DefaultAllocator: Allocator<D>,
{
    lanes.store(l, &mut tracker.tangent.jac);
    tracker.add_exponents(exponents);
    exponents.fill(0);
}
