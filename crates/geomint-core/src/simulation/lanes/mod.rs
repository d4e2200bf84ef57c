//! Runs of one method from up to [`LANES`] initial states, side by side in SIMD lanes (see
//! [`crate::methods::lanes`]): a chaos map's cells with their indicators, or a sweep's plain runs,
//! which may also differ in their system's parameters (one system per lane) but share the step.
//! Runs the lanes cannot take go one by one.
//!
//! The lanes' run loop ([`crate::run::driver`]) drives them, in a plain or a tracked lane group
//! (`groups`), each with the run that samples it: that run does what
//! [`integrate_tracked`](crate::run::integrate_tracked) does for one run — the samples, the
//! indicators' updates on their grid and their thresholds, divergence, the budget, and for plain
//! runs the stretches between samples with their fused seams — and hands the samples to the same
//! observer, so each run's samples and outcome are bit for bit the one-run path's
//! (`tests/core/chaos_map.rs` and `tests/core/sweep_lanes.rs` compare them cell by cell).

use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim};

use super::run::{RunReport, SampleSink};
use super::spec::Simulation;
use crate::error::CoreError;
use crate::methods::lanes::runs::RunLanes;
use crate::methods::lanes::{LaneForces, TangentLanes};
use crate::methods::{self};
use crate::run::driver::drive_lanes;
use crate::run::Budget;
use crate::system::lanes::{EachLane, PointForces};
use crate::system::{MechanicalSystem, State, LANES};
use crate::tangent::Tangent;

mod groups;

pub(crate) use groups::PlainGroup;
use groups::{SampledLanes, SampledRun, TrackedGroup};

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

    /// The plain lanes of this simulation's first method on `sys` alone, for a study whose runs
    /// look at every step themselves (a basin map's cells, each ending when decided); `None`
    /// where [`runs_in_lanes`](Self::runs_in_lanes) is false or indicators are asked for.
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
            let mut group = TrackedGroup::new(lanes, sys, plan, first.schedule.h);
            sampled(&mut group, systems, sims, plan.qr_every, budget, sinks)?
        }
        (Some(Lanes::Runs(lanes)), _) => {
            let every = first.schedule.every;
            match EachLane::new(systems) {
                Some(each) if systems.iter().any(|s| *s != sys) => {
                    let mut group = PlainGroup::new(lanes, &each, true);
                    sampled(&mut group, systems, sims, every, budget, sinks)?
                }
                _ => {
                    let mut group = PlainGroup::new(lanes, sys, true);
                    sampled(&mut group, systems, sims, every, budget, sinks)?
                }
            }
        }
        _ => return one_by_one(sims, budget, sinks),
    };
    Some(outcomes.into_iter().map(Ok).collect())
}

/// Runs `sims`, run `l` on `systems[l]` in lane `l` of `group`, their indicators updated every
/// `update_every` steps; their reports in their order, `None` when the budget stopped them. At
/// most [`LANES`] runs, so that all enter at the group's start, each in the lane of its system
/// (a tracked group's steps are its runs' steps, and a group of one system per lane has its
/// systems in the runs' order).
fn sampled<S, G>(
    group: &mut G,
    systems: &[&S],
    sims: &[&Simulation],
    update_every: u64,
    budget: Budget<'_>,
    sinks: &mut [&mut dyn SampleSink],
) -> Option<Vec<Option<RunReport>>>
where
    S: MechanicalSystem,
    G: SampledLanes<S::Dim>,
    DefaultAllocator: Allocator<S::Dim>,
{
    assert!(sims.len() <= LANES, "a lane group's runs enter together");
    let starts: Vec<State<S::Dim>> = sims
        .iter()
        .zip(systems)
        .map(|(sim, sys)| State::at_time(*sys, 0.0, &sim.q0, &sim.p0))
        .collect();
    let runs = sims
        .iter()
        .zip(systems)
        .zip(&starts)
        .zip(sinks.iter_mut())
        .map(|(((sim, sys), start), sink)| SampledRun {
            observer: sim.observer(*sys, start, None, &mut **sink, false),
            state: start.clone(),
            schedule: sim.schedule,
            update_every,
        });
    let mut reports = vec![None; sims.len()];
    drive_lanes(group, runs, budget, |i, report| reports[i] = report);
    let by_budget = |r: &Option<RunReport>| r.as_ref().is_some_and(|r| r.stop.by_budget());
    (!reports.iter().any(by_budget)).then_some(reports)
}
