//! Where one orbit ends up, decided while it runs: an observer of every step that ends the run
//! as soon as the outcome is known, so a cell costs the time to decide rather than `t_end`.
//!
//! The criteria, in the order each step looks at them:
//! 1. **Divergence**: a component (the clock left out) beyond the escape radius, or not finite.
//! 2. **Exits**: the step crossed an exit surface in its direction; the crossing is located by
//!    Hénon's step, as a section's points are, and the earliest exit crossed in the step wins.
//! 3. **The energy argument** (systems nothing drives; see [`super::landscape`]): the energy,
//!    lowered by a margin, is below the lowest saddle, and the segment from the position to a
//!    minimum stays below that level. The margin is twice the largest rise of the energy above its
//!    lowest value so far: the exact flow's energy never rises, so every rise is the method's
//!    own energy error, measured on this orbit as it goes.
//! 4. **Proximity to a given attractor**: the state (a driven system's stroboscopic point) lies
//!    within the attractor's radius of one of its points, in every component.
//! 5. **Recurrence on the stroboscopic map** (driven systems): the points at t = kT repeat with
//!    some period m ≤ `max_period` within `tolerance`, over two whole periods, and the m points
//!    stand apart (else the orbit has a shorter period and is still settling onto it).
//!
//! Coordinates named as angles are compared modulo 2π (a forced pendulum's rotating orbit comes
//! back to itself on the cylinder, its angle 2π further on) and stored in (−π, π].
//!
//! A start at rest on a critical point of V (a saddle's included) is that equilibrium at once.
//! A run that reaches `t_end` undecided stayed (when the map has exits) or is undecided.

use std::collections::VecDeque;
use std::ops::ControlFlow;

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;
use serde::{Deserialize, Serialize};

use super::landscape::Landscape;
use crate::run::Observer;
use crate::sections::henon::{copy, Henon};
use crate::sections::{Direction, Surface};
use crate::system::{MechanicalSystem, State, Vector};
use crate::systems::wrap_angle;

/// How many tolerances apart the points of a periodic orbit must stand to be distinct points.
const SETTLED: f64 = 10.0;

/// An exit of the map, compiled.
#[derive(Debug)]
pub struct Exit {
    /// Its name.
    pub name: String,
    /// S(q, p, t).
    pub surface: Surface,
    /// Which crossings of S = 0 leave.
    pub direction: Direction,
}

/// The stroboscopic map of a driven system.
#[derive(Clone, Copy, Debug)]
pub struct Stroboscope {
    /// Steps per driving period.
    pub steps: u64,
    /// The longest period looked for, in driving periods.
    pub max_period: usize,
    /// How close (largest component difference) points of one period must come back.
    pub tolerance: f64,
}

/// What every cell's run looks for.
#[derive(Debug)]
pub struct Criteria {
    /// The exits.
    pub exits: Vec<Exit>,
    /// The landscape, for the energy argument (systems nothing drives).
    pub landscape: Option<Landscape>,
    /// Whether the system is damped (an orbit trapped in a well settles at its floor).
    pub damped: bool,
    /// The stroboscopic map, for driven systems.
    pub stroboscope: Option<Stroboscope>,
    /// A component beyond this (in absolute value) has escaped to infinity.
    pub escape_radius: f64,
    /// The driven system's clock coordinate, left out of distances.
    pub clock: Option<usize>,
    /// Per component (q then p, without the clock), whether it is an angle.
    pub angles: Vec<bool>,
    /// The attractors the request named.
    pub given: Vec<Given>,
}

/// An attractor the request named, as every cell looks for it.
#[derive(Debug)]
pub struct Given {
    /// Its points, each (q, p) without the clock.
    pub points: Vec<Vec<f64>>,
    /// How close counts, in every component.
    pub radius: f64,
}

impl Criteria {
    /// How far apart `a` and `b` are in component `i`: an angle's difference modulo 2π.
    fn gap(&self, i: usize, a: f64, b: f64) -> f64 {
        if self.angles.get(i).copied().unwrap_or(false) {
            wrap_angle(a - b).abs()
        } else {
            (a - b).abs()
        }
    }

    /// Whether `x` lies within `r` of `y` in every component.
    pub(super) fn near(&self, x: &[f64], y: &[f64], r: f64) -> bool {
        x.iter()
            .zip(y)
            .enumerate()
            .all(|(i, (&a, &b))| self.gap(i, a, b) <= r)
    }

    /// The bound on |qᵢ| that a state keeps within until it escapes: the escape radius (finite,
    /// as the request's check requires), or for an angle `f64::MAX`, since an angle cannot
    /// escape, only leave the finite numbers; `None` for the clock, which never escapes. Not
    /// within its bound (NaN never is) is escaped ([`escapes`]): the one rule of [`Decide`]'s
    /// test and of [`Criteria::quiet_bounds`].
    fn position_bound(&self, i: usize) -> Option<f64> {
        if Some(i) == self.clock {
            None
        } else if self.angles.get(i).copied().unwrap_or(false) {
            Some(f64::MAX)
        } else {
            Some(self.escape_radius)
        }
    }

    /// The bound on |pᵢ|, as [`Criteria::position_bound`]: the escape radius, none for the
    /// clock's momentum.
    fn momentum_bound(&self, i: usize) -> Option<f64> {
        (Some(i) != self.clock).then_some(self.escape_radius)
    }

    /// Bounds on every |qᵢ| and |pᵢ| that a state keeps within exactly when it is finite and
    /// has not escaped ([`Criteria::position_bound`], [`Criteria::momentum_bound`], with
    /// `f64::MAX`, finite, on the clock's components). `None` unless only the stroboscope and the escape radius decide a cell: no
    /// exits, no energy argument, no given attractor looked for at every step. Then a step after
    /// which a cell keeps within the bounds, short of its last step and before its next
    /// stroboscope point ([`Decide::between_looks`]), changes and decides nothing in its
    /// observer, and the lanes need not hand it the state (`lanes.rs`): a driven system's map
    /// looks at its cells once a period so.
    pub(super) fn quiet_bounds<const N: usize>(&self) -> Option<([f64; N], [f64; N])> {
        let quiet = self.exits.is_empty()
            && self.landscape.is_none()
            && (self.given.is_empty() || self.stroboscope.is_some());
        let finite = |bound: Option<f64>| bound.map_or(f64::MAX, |bound| bound.min(f64::MAX));
        quiet.then(|| {
            (
                std::array::from_fn(|i| finite(self.position_bound(i))),
                std::array::from_fn(|i| finite(self.momentum_bound(i))),
            )
        })
    }

    /// The first given attractor one of whose points `x` lies within reach of.
    pub(super) fn given_near(&self, x: &[f64]) -> Option<usize> {
        self.given
            .iter()
            .position(|g| g.points.iter().any(|y| self.near(x, y, g.radius)))
    }
}

/// Whether `x` has escaped its bound (see [`Criteria::position_bound`]): not within it, NaN
/// included; never without a bound.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN is not within any bound: it has escaped.
fn escapes(bound: Option<f64>, x: f64) -> bool {
    bound.is_some_and(|bound| !(x.abs() <= bound))
}

/// Where an orbit ended up.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum OrbitOutcome {
    /// Trapped in the well of critical point `point` (an index into the landscape), where the
    /// damping settles it; or started at rest on that critical point.
    Equilibrium {
        /// The critical point.
        point: usize,
    },
    /// Trapped in the well of critical point `point` of an undamped system.
    Well {
        /// The minimum.
        point: usize,
    },
    /// Left through exit `exit`.
    Exit {
        /// The exit's index.
        exit: usize,
    },
    /// Locked onto a periodic orbit of the stroboscopic map.
    Cycle {
        /// The orbit's points, (q, p) without the clock, starting from the least (in
        /// lexicographic order).
        points: Vec<Vec<f64>>,
    },
    /// Came within reach of a given attractor.
    Given {
        /// The attractor's index among the given ones.
        attractor: usize,
    },
    /// Escaped to infinity (or left the finite numbers) without an exit.
    Diverged,
    /// Reached t_end without leaving through an exit.
    Stayed,
    /// Nothing was decided by t_end.
    Undecided {
        /// Why not, in words.
        reason: String,
    },
    /// The cell's run could not start or failed.
    Failed {
        /// The error.
        error: String,
    },
}

/// One cell's result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellOutcome {
    /// Where it ended up.
    pub outcome: OrbitOutcome,
    /// When that was decided (None for an undecided or failed cell).
    pub decided_at: Option<f64>,
    /// Steps taken.
    pub steps: u64,
    /// The energy margin in use when the energy argument decided the cell.
    pub energy_margin: Option<f64>,
}

/// The observer of one cell's run.
pub struct Decide<'a, S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    sys: &'a S,
    criteria: &'a Criteria,
    henon: Henon<S::Dim>,
    /// The state after the last step, and its time.
    last: State<S::Dim>,
    last_t: f64,
    /// Each exit's S at the last state.
    last_s: Vec<f64>,
    /// The state and time as the exits' compiled functions take them, loaded once per step.
    inputs: Vec<f64>,
    dof: usize,
    point: State<S::Dim>,
    scratch: Vector<S::Dim>,
    lowest_energy: f64,
    largest_rise: f64,
    /// The next stroboscope point's step (`u64::MAX` without a stroboscope):
    /// [`Self::between_looks`] compares with it instead of dividing at every step.
    next_strobe: u64,
    /// Steps to wait before the segment test again, after one failed.
    segment_wait: u64,
    strobe: VecDeque<Vec<f64>>,
    /// The state's components, for the proximity test of a system nothing drives.
    here: Vec<f64>,
    /// What was decided, when, and the energy margin of an energy decision.
    pub decided: Option<(OrbitOutcome, f64, Option<f64>)>,
}

impl<'a, S: MechanicalSystem> Decide<'a, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// The observer of a run from `start` at t = 0, with `dof` degrees of freedom.
    pub fn new(sys: &'a S, criteria: &'a Criteria, start: &State<S::Dim>, dof: usize) -> Self {
        let mut henon = Henon::new(sys.dim(), dof);
        let last_s = criteria
            .exits
            .iter()
            .map(|e| henon.value(&e.surface, start, 0.0))
            .collect();
        let mut decide = Decide {
            sys,
            criteria,
            henon,
            last: start.clone(),
            last_t: 0.0,
            last_s,
            inputs: Surface::buffers(dof).0,
            dof,
            point: start.clone(),
            scratch: start.q.clone(),
            lowest_energy: f64::INFINITY,
            largest_rise: 0.0,
            segment_wait: 0,
            next_strobe: criteria.stroboscope.map_or(u64::MAX, |strobe| strobe.steps),
            strobe: VecDeque::new(),
            here: Vec::new(),
            decided: None,
        };
        // A start at rest on a critical point (a saddle's included) stays there.
        if let Some(point) = decide.resting_on(start) {
            decide.decided = Some((OrbitOutcome::Equilibrium { point }, 0.0, None));
            return decide;
        }
        // The energy argument may decide at once: the start's energy is exact.
        if let ControlFlow::Break(_) = decide.look(0, 0.0, start, false) {
            return decide;
        }
        let here = decide.components(start);
        if let Some(attractor) = decide.criteria.given_near(&here) {
            decide.decided = Some((OrbitOutcome::Given { attractor }, 0.0, None));
            return decide;
        }
        if decide.criteria.stroboscope.is_some() {
            decide.strobe.push_back(here);
        }
        decide
    }

    /// The critical point `z` rests on: p = 0 and q one of the landscape's points to the last
    /// bit or two.
    fn resting_on(&self, z: &State<S::Dim>) -> Option<usize> {
        let landscape = self.criteria.landscape.as_ref()?;
        if z.p.iter().any(|&p| p != 0.0) {
            return None;
        }
        landscape.points.iter().position(|c| {
            c.q.iter()
                .enumerate()
                .all(|(i, &x)| (x - z.q[i]).abs() <= 4.0 * f64::EPSILON * (1.0 + x.abs()))
        })
    }

    /// The state's components without the clock's, angles in (−π, π].
    fn components(&self, z: &State<S::Dim>) -> Vec<f64> {
        let mut out = Vec::new();
        self.load_components(z, &mut out);
        out
    }

    fn load_components(&self, z: &State<S::Dim>, out: &mut Vec<f64>) {
        let skip = self.criteria.clock;
        let angles = &self.criteria.angles;
        out.clear();
        out.extend(
            z.q.iter()
                .enumerate()
                .chain(z.p.iter().enumerate())
                .filter(|(i, _)| Some(*i) != skip)
                .enumerate()
                .map(|(k, (_, &x))| {
                    if angles.get(k).copied().unwrap_or(false) {
                        wrap_angle(x)
                    } else {
                        x
                    }
                }),
        );
    }

    fn decide(&mut self, outcome: OrbitOutcome, t: f64, margin: Option<f64>) -> ControlFlow<f64> {
        self.decided = Some((outcome, t, margin));
        ControlFlow::Break(t)
    }

    /// Divergence and the energy argument at the state `z` after `step` (time `t`).
    fn look(&mut self, step: u64, t: f64, z: &State<S::Dim>, stepped: bool) -> ControlFlow<f64> {
        if self.escaped(z.q.as_slice(), z.p.as_slice()) {
            return self.decide(OrbitOutcome::Diverged, t, None);
        }
        let Some(landscape) = &self.criteria.landscape else {
            return ControlFlow::Continue(());
        };
        let energy = self.sys.energy(&z.q, &z.p);
        self.lowest_energy = self.lowest_energy.min(energy);
        self.largest_rise = self.largest_rise.max(energy - self.lowest_energy);
        let margin = 2.0 * self.largest_rise;
        let level = landscape.barrier.unwrap_or(f64::INFINITY) - margin;
        if !(energy < level) || (stepped && step < self.segment_wait) {
            return ControlFlow::Continue(());
        }
        match landscape.well_of(self.sys, &z.q, level.min(f64::MAX), &mut self.scratch) {
            Some(point) => {
                let outcome = if self.criteria.damped {
                    OrbitOutcome::Equilibrium { point }
                } else {
                    OrbitOutcome::Well { point }
                };
                self.decide(outcome, t, Some(margin))
            }
            None => {
                // The segment test costs about 64 potentials per minimum: not at every step.
                self.segment_wait = step + 16;
                ControlFlow::Continue(())
            }
        }
    }

    /// Whether the state (q, p) has left the escape radius (the clock aside) or, in an angle,
    /// the finite numbers ([`Criteria::position_bound`], [`Criteria::momentum_bound`]).
    fn escaped(&self, q: &[f64], p: &[f64]) -> bool {
        let criteria = &self.criteria;
        let q_beyond = q
            .iter()
            .enumerate()
            .any(|(i, &x)| escapes(criteria.position_bound(i), x));
        q_beyond
            || p.iter()
                .enumerate()
                .any(|(i, &x)| escapes(criteria.momentum_bound(i), x))
    }

    /// Whether `step` falls before the next stroboscope point (any step, without a
    /// stroboscope). See [`Criteria::quiet_bounds`].
    #[inline]
    pub(super) fn between_looks(&self, step: u64) -> bool {
        step < self.next_strobe
    }

    /// The earliest exit the step from the last state to `z` (time `t`) crossed, located.
    fn exit_crossed(&mut self, t: f64, z: &State<S::Dim>) -> Option<(usize, f64)> {
        let mut first: Option<(usize, f64)> = None;
        if self.criteria.exits.is_empty() {
            return None;
        }
        let n = self.dof;
        Surface::load(
            &mut self.inputs,
            &z.q.as_slice()[..n],
            &z.p.as_slice()[..n],
            t,
            n,
        );
        for i in 0..self.criteria.exits.len() {
            let exit = &self.criteria.exits[i];
            let s = exit.surface.value_loaded(&self.inputs, t);
            let before = self.last_s[i];
            self.last_s[i] = s;
            if !exit.direction.crossed(before, s) {
                continue;
            }
            // Hénon's step from the state before, else from the one after; if neither locates
            // it, the linear interpolation of S over the step.
            let from_before = self.henon.locate(
                self.sys,
                &exit.surface,
                (&self.last, self.last_t, before),
                0.0,
                &mut self.point,
            );
            let located = from_before.or_else(|_| {
                self.henon
                    .locate(self.sys, &exit.surface, (z, t, s), 0.0, &mut self.point)
            });
            let at = located
                .ok()
                .filter(|at| (self.last_t..=t).contains(at))
                .unwrap_or(self.last_t + (t - self.last_t) * before / (before - s));
            if first.is_none_or(|(_, earliest)| at < earliest) {
                first = Some((i, at));
            }
        }
        first
    }

    /// A periodic orbit of the stroboscopic map ending at the newest point, if the last points
    /// repeat.
    fn cycle(&self, tolerance: f64, max_period: usize) -> Option<Vec<Vec<f64>>> {
        let n = self.strobe.len();
        let close = |a: &[f64], b: &[f64]| self.criteria.near(a, b, tolerance);
        // Points m apart that agree could still be an orbit of a period d dividing m that has not
        // settled yet: one approached with a multiplier near −1 comes back within the tolerance
        // every second period before it does every period. A cycle counts only if its points
        // stand apart, by more than ten tolerances, at every shift d; otherwise the run goes on
        // until the shorter period is found.
        let distinct = |m: usize| {
            (1..m).filter(|d| m % d == 0).all(|d| {
                (0..m).any(|j| {
                    let (a, b) = (&self.strobe[n - 1 - j], &self.strobe[n - 1 - (j + d) % m]);
                    !self.criteria.near(a, b, SETTLED * tolerance)
                })
            })
        };
        let period = (1..=max_period).take_while(|m| 2 * m < n + 1).find(|&m| {
            (0..m).all(|j| close(&self.strobe[n - 1 - j], &self.strobe[n - 1 - j - m]))
                && distinct(m)
        })?;
        let mut points: Vec<Vec<f64>> = self.strobe.range(n - period..).cloned().collect();
        let least = (0..period)
            .min_by(|&a, &b| {
                points[a]
                    .iter()
                    .zip(&points[b])
                    .fold(std::cmp::Ordering::Equal, |o, (x, y)| {
                        o.then(x.total_cmp(y))
                    })
            })
            .unwrap_or(0);
        points.rotate_left(least);
        Some(points)
    }
}

impl<S: MechanicalSystem> Observer<S::Dim> for Decide<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn on_sample(&mut self, _step: u64, _t: f64, _z: &State<S::Dim>) {}

    fn watches_steps(&self) -> bool {
        true
    }

    fn on_step(&mut self, step: u64, t: f64, z: &State<S::Dim>) -> ControlFlow<f64> {
        if let Some((exit, at)) = self.exit_crossed(t, z) {
            return self.decide(OrbitOutcome::Exit { exit }, at, None);
        }
        if let ControlFlow::Break(at) = self.look(step, t, z, true) {
            return ControlFlow::Break(at);
        }
        let given = !self.criteria.given.is_empty();
        if given && self.criteria.stroboscope.is_none() {
            let mut here = std::mem::take(&mut self.here);
            self.load_components(z, &mut here);
            let near = self.criteria.given_near(&here);
            self.here = here;
            if let Some(attractor) = near {
                return self.decide(OrbitOutcome::Given { attractor }, t, None);
            }
        }
        if let Some(strobe) = self.criteria.stroboscope {
            if step % strobe.steps == 0 {
                self.next_strobe = step + strobe.steps;
                // The oldest point's buffer takes the new one.
                let mut point = if self.strobe.len() == 2 * strobe.max_period + 1 {
                    self.strobe.pop_front().unwrap_or_default()
                } else {
                    Vec::new()
                };
                self.load_components(z, &mut point);
                if let Some(attractor) = self.criteria.given_near(&point) {
                    return self.decide(OrbitOutcome::Given { attractor }, t, None);
                }
                self.strobe.push_back(point);
                if let Some(points) = self.cycle(strobe.tolerance, strobe.max_period) {
                    return self.decide(OrbitOutcome::Cycle { points }, t, None);
                }
            }
        }
        // The state before the step is only for locating an exit's crossing.
        if !self.criteria.exits.is_empty() {
            copy(&mut self.last, z);
            self.last_t = t;
        }
        ControlFlow::Continue(())
    }
}
