//! Runs of one method from up to [`LANES`] initial states, side by side in SIMD lanes (see
//! [`crate::methods::lanes`]): a chaos map's cells with their indicators, or a sweep's plain runs,
//! which may also differ in their system's parameters (one system per lane) but share the step.
//! For each run the driver does what [`integrate_tracked`](crate::run::integrate_tracked) does —
//! the samples, the indicators' updates on their grid and their thresholds, divergence, the
//! budget, and for plain runs the stretches between samples with their fused seams — and hands
//! the samples to the same observer, so each run's samples and outcome are bit for bit the
//! one-run path's (`tests/core/chaos_map.rs` and `tests/core/sweep_lanes.rs` compare them cell by
//! cell). Runs the lanes cannot take go one by one.

use std::time::Instant;

use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim};

use super::run::{RunReport, SampleSink};
use super::spec::Simulation;
use crate::chaos::{ChaosPlan, OneVectorLanes, ThresholdCrossing, Tracker};
use crate::error::CoreError;
use crate::methods::lanes::runs::RunLanes;
use crate::methods::lanes::tangent::LANES;
use crate::methods::lanes::{LaneForces, TangentLanes, CHECK_EVERY};
use crate::methods::{self};
use crate::run::{Budget, Observer, RunEnd, RunStats};
use crate::system::lanes::{EachLane, PointForces};
use crate::system::{MechanicalSystem, State};
use crate::tangent::Tangent;

/// The lanes a simulation's runs take: with indicators, or plain.
enum Lanes<const N: usize> {
    Tracked(TangentLanes<N>),
    Runs(RunLanes<N>),
}

/// Runs `$body` with `$systems` bound to the systems inside `$sims` (a slice of simulations) if
/// the lanes evaluate them (they implement [`LaneForces`]) and all are of the first one's kind,
/// else `$other`. A system joins the lanes with a variant here.
macro_rules! with_lane_systems {
    ($sims:expr, $systems:ident => $body:expr, _ => $other:expr) => {
        $crate::simulation::with_lane_systems!(@kinds $sims, $systems, $body, $other;
            HenonHeiles, PlanarCartesian, ElasticPendulum3d, HarmonicOscillator,
            Custom1, Custom2, Custom3)
    };
    (@kinds $sims:expr, $systems:ident, $body:expr, $other:expr; $($kind:ident),*) => {
        match &$sims[0].system {
            $($crate::systems::AnySystem::$kind(_) => {
                let of_kind: Option<Vec<_>> = $sims
                    .iter()
                    .map(|sim| match &sim.system {
                        $crate::systems::AnySystem::$kind(sys) => Some(sys),
                        _ => None,
                    })
                    .collect();
                match of_kind {
                    Some($systems) => $body,
                    None => $other,
                }
            })*
            _ => $other,
        }
    };
}
pub(crate) use with_lane_systems;

impl Simulation {
    /// Whether runs of this simulation's first method go side by side in lanes: nothing asked
    /// for but samples and, if any, chaos indicators (no section, event, reference run or
    /// Jacobian defect), a composition of kicks and drifts (and, without indicators, exact
    /// damping flows), on an autonomous system the lanes evaluate (Hénon–Heiles, the planar and
    /// the 3-D elastic pendulum in Cartesian coordinates, the harmonic oscillator, typed-in
    /// separable systems of one to three degrees of freedom), undamped when indicators are
    /// asked for.
    pub fn runs_in_lanes(&self) -> bool {
        with_lane_systems!(
            std::slice::from_ref(self),
            systems => self.lanes(&systems).is_some(),
            _ => false
        )
    }

    /// The plain lanes of this simulation's first method on `sys` alone, for a study that
    /// drives them a step at a time itself (a basin map's cells, each ending when decided);
    /// `None` where [`runs_in_lanes`](Self::runs_in_lanes) is false or indicators are asked for.
    pub(crate) fn plain_lanes<S, const N: usize>(&self, sys: &S) -> Option<RunLanes<N>>
    where
        S: MechanicalSystem + LaneForces<N> + PartialEq,
        DefaultAllocator: Allocator<S::Dim>,
    {
        match self.lanes(&[sys])? {
            Lanes::Runs(lanes) => Some(lanes),
            Lanes::Tracked(_) => None,
        }
    }

    /// Whether `other` can share lanes with this simulation: the same method, schedule, kind of
    /// system and indicators (its parameters and initial state may differ).
    fn shares_lanes_with(&self, other: &Simulation) -> bool {
        let (a, b) = (self.schedule, other.schedule);
        (a.h, a.steps, a.every) == (b.h, b.steps, b.every)
            && self.methods.first() == other.methods.first()
            && std::mem::discriminant(&self.system) == std::mem::discriminant(&other.system)
            && self.chaos.is_some() == other.chaos.is_some()
    }

    /// The lanes for this simulation's first method on `systems` (one per run, this one's
    /// first), if they can run it: with indicators only on one undamped system.
    fn lanes<S, const N: usize>(&self, systems: &[&S]) -> Option<Lanes<N>>
    where
        S: MechanicalSystem + LaneForces<N> + PartialEq,
        DefaultAllocator: Allocator<S::Dim>,
    {
        let sys = *systems.first()?;
        let plain = self.crossings.is_none() && !self.compare_to_reference && !self.jacobian_defect;
        // A driven system's clock is one more coordinate to the plain lanes (velocity 1, its
        // momentum damped or not as the system's own damping flow does it); the tangent lanes'
        // constant M⁻¹ has no place for it.
        let simple = |sys: &S| {
            sys.in_lanes()
                && (sys.clock().is_none() || self.chaos.is_none())
                && sys.structure().separable_constant_mass
                && sys.dim().value() == N
        };
        let one_system = systems.iter().all(|s| *s == sys);
        if !plain || !systems.iter().all(|s| simple(s)) || (self.chaos.is_some() && !one_system) {
            return None;
        }
        let h = self.schedule.h;
        let method = self.methods.first()?;
        let stepper = methods::build(method, sys, &self.system_label, h).ok()?;
        let flows = stepper.splitting_flows()?;
        // Every lane's method must be the same sequence of flows (a method may choose its flows
        // by the system's damping).
        for other in systems.iter().filter(|s| **s != sys) {
            let theirs = methods::build(method, *other, &self.system_label, h).ok()?;
            if theirs.splitting_flows()? != flows {
                return None;
            }
        }
        let Some(plan) = &self.chaos else {
            let rates: Vec<f64> = systems.iter().map(|s| s.damping_rate()).collect();
            return RunLanes::new(flows, &rates, h).map(Lanes::Runs);
        };
        if sys.damping_rate() != 0.0 {
            return None;
        }
        let z = State::from_slices(sys.dim(), &self.q0, &self.p0);
        let tangent = Tangent::new(sys, &z);
        let mut minv = [[0.0; N]; N];
        for (i, row) in minv.iter_mut().enumerate() {
            for (j, m) in row.iter_mut().enumerate() {
                *m = tangent.minv[(i, j)];
            }
        }
        TangentLanes::new(flows, sys.damping_rate(), h, minv, plan.deviations).map(Lanes::Tracked)
    }

    /// Runs the first method of each of `sims`, each run's samples to its sink: runs that
    /// [`share lanes`](Self::shares_lanes_with), [`LANES`] at a time (in the order they come),
    /// in lanes where [`runs_in_lanes`](Self::runs_in_lanes) (one system per lane where their
    /// parameters differ), else one by one; outcomes in the order of `sims`. `None` when the
    /// budget stopped a run. A run given back (`Ok(None)`: a plain run whose state's components
    /// stayed finite while their sum overflowed, after which the one-run path cuts its
    /// stretches where the lanes do not) is to be run again on its own, with a fresh sink.
    pub fn run_side_by_side(
        sims: &[Simulation],
        budget: Budget<'_>,
        sinks: &mut [&mut dyn SampleSink],
    ) -> Option<Vec<Result<Option<RunReport>, CoreError>>> {
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for (i, sim) in sims.iter().enumerate() {
            let open = groups
                .iter_mut()
                .find(|g| g.len() < LANES && sims[g[0]].shares_lanes_with(sim));
            match open {
                Some(group) => group.push(i),
                None => groups.push(vec![i]),
            }
        }
        let mut sinks: Vec<Option<&mut &mut dyn SampleSink>> = sinks.iter_mut().map(Some).collect();
        let mut outcomes: Vec<Option<Result<Option<RunReport>, CoreError>>> =
            (0..sims.len()).map(|_| None).collect();
        for group in groups {
            let members: Vec<&Simulation> = group.iter().map(|&i| &sims[i]).collect();
            let mut group_sinks: Vec<&mut dyn SampleSink> = Vec::with_capacity(group.len());
            for &i in &group {
                group_sinks.push(&mut **sinks[i].take().expect("each run in one group"));
            }
            let ran = match members.len() {
                1 => one_by_one(&members, budget, &mut group_sinks),
                _ => with_lane_systems!(
                    members,
                    systems => side_by_side(&systems, &members, budget, &mut group_sinks),
                    _ => one_by_one(&members, budget, &mut group_sinks)
                ),
            };
            for (i, outcome) in group.into_iter().zip(ran?) {
                outcomes[i] = Some(outcome);
            }
        }
        Some(
            outcomes
                .into_iter()
                .map(|o| o.expect("every run ran"))
                .collect(),
        )
    }
}

/// Each run on its own, through the one-run path.
fn one_by_one(
    sims: &[&Simulation],
    budget: Budget<'_>,
    sinks: &mut [&mut dyn SampleSink],
) -> Option<Vec<Result<Option<RunReport>, CoreError>>> {
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

/// Up to [`LANES`] runs of `sims`, run `l` on `systems[l]`, in lanes (one by one if the lanes
/// cannot take them): the lanes evaluate one system for all when the systems are one, else
/// each its own ([`EachLane`]).
fn side_by_side<S, const N: usize>(
    systems: &[&S],
    sims: &[&Simulation],
    budget: Budget<'_>,
    sinks: &mut [&mut dyn SampleSink],
) -> Option<Vec<Result<Option<RunReport>, CoreError>>>
where
    S: MechanicalSystem + LaneForces<N> + PointForces<N> + PartialEq + Clone,
    DefaultAllocator: Allocator<S::Dim>,
{
    let first = &sims[0];
    let sys = systems[0];
    let outcomes = match (first.lanes(systems), first.chaos.as_ref()) {
        (Some(Lanes::Tracked(lanes)), Some(plan)) => {
            tracked(sys, lanes, plan, sims, budget, sinks)?
                .into_iter()
                .map(Some)
                .collect()
        }
        (Some(Lanes::Runs(lanes)), _) => match EachLane::new(systems) {
            Some(each) if systems.iter().any(|s| *s != sys) => {
                plain(systems, &each, lanes, sims, budget, sinks)?
            }
            _ => plain(systems, sys, lanes, sims, budget, sinks)?,
        },
        _ => return one_by_one(sims, budget, sinks),
    };
    Some(outcomes.into_iter().map(Ok).collect())
}

/// Plain runs in lanes: the one-run driver's stretches (up to the next sample, look at the
/// budget or the end), each taken as the one-run stepper takes it ([`RunLanes::advance`]),
/// the lanes' forces from `forces` (`sys` for all, or one system each).
fn plain<S, F, const N: usize>(
    systems: &[&S],
    forces: &F,
    mut lanes: RunLanes<N>,
    sims: &[&Simulation],
    budget: Budget<'_>,
    sinks: &mut [&mut dyn SampleSink],
) -> Option<Vec<Option<RunReport>>>
where
    S: MechanicalSystem,
    F: LaneForces<N>,
    DefaultAllocator: Allocator<S::Dim>,
{
    let started = Instant::now();
    let count = sims.len();
    let schedule = sims[0].schedule;
    let (h, steps, every) = (schedule.h, schedule.steps, schedule.every.max(1));
    let starts: Vec<State<S::Dim>> = sims
        .iter()
        .zip(systems)
        .map(|(sim, sys)| State::at_time(*sys, 0.0, &sim.q0, &sim.p0))
        .collect();
    let mut states = starts.clone();
    let mut observers: Vec<_> = sims
        .iter()
        .zip(systems)
        .zip(&starts)
        .zip(sinks.iter_mut())
        .map(|(((sim, sys), start), sink)| sim.observer(*sys, start, None, &mut **sink, false))
        .collect();
    let mut running = [false; LANES];
    for l in 0..count {
        lanes.set_state(l, states[l].q.as_slice(), states[l].p.as_slice());
        running[l] = true;
        observers[l].on_sample(0, 0.0, &states[l]);
    }
    // Per run: how it ended early (the stop, its steps and force evaluations), or given back.
    let mut ended: Vec<Option<Option<(RunEnd, u64, u64)>>> = vec![None; count];
    let mut step = 0u64;
    while step < steps && running.contains(&true) {
        if step.is_multiple_of(CHECK_EVERY) && (budget.cancelled() || budget.expired()) {
            return None;
        }
        let next = |m: u64| (step / m + 1) * m;
        let until = next(CHECK_EVERY).min(next(every)).min(steps);
        let stretch = lanes.advance(forces, until - step, &running);
        for (l, end) in stretch.iter().enumerate().take(count) {
            let Some(end) = end.filter(|_| running[l]) else {
                continue;
            };
            running[l] = false;
            let at = step + end.steps;
            ended[l] = Some(end.diverged.then_some((
                RunEnd::Diverged {
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
                let (q, p) = lanes.state(l);
                states[l].q.copy_from_slice(&q);
                states[l].p.copy_from_slice(&p);
                observers[l].on_sample(step, t, &states[l]);
            }
        }
    }
    let wall_time_ms = started.elapsed().as_secs_f64() * 1e3;
    let finished = (RunEnd::Finished, step, lanes.force_evaluations());
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
fn outcome((stop, steps, force_evaluations): (RunEnd, u64, u64), wall_time_ms: f64) -> RunReport {
    RunReport {
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
    sims: &[&Simulation],
    budget: Budget<'_>,
    sinks: &mut [&mut dyn SampleSink],
) -> Option<Vec<RunReport>>
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
    let mut ended: Vec<Option<(RunEnd, u64, u64)>> = vec![None; count];
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
                    let stop = RunEnd::Diverged { step, t };
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
                let stop = RunEnd::Indicator(ThresholdCrossing {
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
    let finished = (RunEnd::Finished, step, lanes.force_evaluations());
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
