//! Watching a run step by step beside its observer: after each step the surfaces' values at the
//! new state are compared with those at the last one, and a crossing is located by Hénon's step
//! ([`super::henon`]) from the last state before it, on a copy: the run goes on from its own
//! state. Located points go to the caller as [`Crossing`]s; an event's last crossing ends the
//! run.
//!
//! A processed method's output state costs a composition of its own per step. Where the output
//! map may be applied late, the watch first judges each step from the kernel states
//! ([`Watch::step_is_clear`]). If no values within a margin of the surface's values at the
//! step's two kernel states can cross in the surface's direction, the step is taken to cross
//! nothing that counts, and no output state is formed for it. The margin is the larger of
//! [`SAFETY`] times the largest difference between a surface's value at a kernel state and at
//! its output state seen so far, and [`STEP_FRACTION`] of the largest change of S over one step;
//! no step is judged before [`CALIBRATION`] steps seen both ways. Every other step is watched on
//! output states as before, so the points located are the same wherever the processor moves S
//! by less than the margin: a heuristic, not a bound (the processor's change of S is not known
//! without forming the output state), which holds for steps well inside the method's accuracy;
//! the tests compare with runs that form every output state. The output state formed after
//! skipped steps is watched from the last one formed, so a crossing the margin missed whose
//! output stays past the surface is still found (located from that earlier state), and the
//! difference seen there widens the margin.

use std::ops::ControlFlow;

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;
use serde::Serialize;

use super::henon::{copy, Henon, Unlocated};
use super::spec::Direction;
use super::surface::{Crossings, Surface};
use crate::system::{MechanicalSystem, State};

/// Steps whose kernel and output states are both seen before any step is judged from the
/// kernel alone.
pub const CALIBRATION: u64 = 64;
/// The margin of a step judged from the kernel alone, in multiples of the largest difference
/// seen between a surface's value at a kernel state and at its output state.
pub const SAFETY: f64 = 16.0;
/// The least margin, as a fraction of the largest change of S over one step seen: the
/// differences seen may all come from where the processor is nearly the identity (a free
/// particle), and it moves S by a fraction of a step's change elsewhere (about hω of it).
pub const STEP_FRACTION: f64 = 0.25;

/// Which kernel state's S a watched output state is compared with.
#[derive(Clone, Copy)]
enum Kernel {
    /// The last judged (the step just taken).
    Last,
    /// The one before it (the last step skipped, formed late).
    BeforeLast,
    /// None: the step was not judged.
    None,
}

/// Which surface a crossing is of.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CrossingKind {
    /// The section's.
    Section,
    /// The event's (`stop_when`).
    Event,
}

/// A located crossing, as sinks receive it.
#[derive(Clone, Copy, Debug)]
pub struct Crossing<'a> {
    /// Whose surface.
    pub kind: CrossingKind,
    /// Its time.
    pub t: f64,
    /// Positions (the degrees of freedom; no clock).
    pub q: &'a [f64],
    /// Momenta.
    pub p: &'a [f64],
    /// H there.
    pub energy: f64,
    /// The positions in Cartesian coordinates, when the chart is not Cartesian.
    pub cartesian_q: Option<&'a [f64]>,
}

/// How a run's section went.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct SectionSummary {
    /// Points located.
    pub points: u64,
    /// Whether crossings after `max_points` went uncollected.
    pub truncated: bool,
    /// Crossings seen whose point could not be located (tangent to the surface within
    /// round-off), or whose point moves across the surface against the section's direction (a
    /// near-tangent crossing of the method's steps that the exact flow from either end of the
    /// step turns back from); none is reported.
    #[serde(skip_serializing_if = "is_zero")]
    pub unlocated: u64,
    /// The least and greatest value of the surface's S over the run's steps (expressions
    /// only). For a processed method, the steps judged clear from the kernel (module docs)
    /// count with S at their kernel state, which differs from the output's by a processor's
    /// small correction.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub surface_range: Option<[f64; 2]>,
    /// Why there are no points, when there are none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// One surface's watch over a run.
struct SurfaceTracker {
    kind: CrossingKind,
    direction: Direction,
    /// Most points (section) or the crossing that ends the run (event).
    limit: u64,
    count: u64,
    unlocated: u64,
    truncated: bool,
    /// S at the last state.
    last: f64,
    range: [f64; 2],
    /// The next stroboscopic level's index.
    next: u64,
    /// S (t for the clock) at the last kernel state judged, and at the one before it.
    kernel: f64,
    kernel_before: f64,
    /// The largest |S(output) − S(kernel)| seen at one state.
    deviation: f64,
    /// The largest change of S over one kernel step seen.
    step_change: f64,
}

/// The watch over one run: the surfaces, the last state, the locator's buffers.
pub struct Watch<'a, S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    crossings: &'a Crossings,
    trackers: Vec<SurfaceTracker>,
    henon: Henon<S::Dim>,
    last: State<S::Dim>,
    last_t: f64,
    point: State<S::Dim>,
    /// The located point in Cartesian coordinates, for a chart that is not.
    cartesian: Option<(Vec<f64>, Vec<f64>)>,
    /// The time of the last kernel state judged, and whether the step being watched was.
    kernel_t: f64,
    kernel_judged: bool,
    /// Steps seen at both their kernel and their output state.
    calibrated: u64,
}

impl<'a, S: MechanicalSystem> Watch<'a, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// A watch of `crossings` over a run of `sys` from `start`.
    pub fn new(sys: &S, crossings: &'a Crossings, start: &State<S::Dim>) -> Self {
        let n = crossings.names.coordinates.len();
        let tracker = |kind, &(_, direction, limit): &(Surface, Direction, u64)| SurfaceTracker {
            kind,
            direction,
            limit,
            count: 0,
            unlocated: 0,
            truncated: false,
            last: f64::NAN,
            range: [f64::INFINITY, f64::NEG_INFINITY],
            next: 0,
            kernel: f64::NAN,
            kernel_before: f64::NAN,
            deviation: 0.0,
            step_change: 0.0,
        };
        let trackers = [
            crossings
                .section
                .as_ref()
                .map(|s| tracker(CrossingKind::Section, s)),
            crossings
                .event
                .as_ref()
                .map(|s| tracker(CrossingKind::Event, s)),
        ]
        .into_iter()
        .flatten()
        .collect();
        let mut watch = Watch {
            crossings,
            trackers,
            henon: Henon::new(sys.dim(), n),
            last: start.clone(),
            last_t: 0.0,
            point: start.clone(),
            cartesian: (!sys.is_cartesian()).then(|| (vec![0.0; n], vec![0.0; n])),
            kernel_t: f64::NAN,
            kernel_judged: false,
            calibrated: 0,
        };
        watch.restart(sys, start, 0.0);
        watch
    }

    fn surface(&self, kind: CrossingKind) -> &'a Surface {
        let crossings = self.crossings;
        match kind {
            CrossingKind::Section => &crossings.section.as_ref().expect("a section").0,
            CrossingKind::Event => &crossings.event.as_ref().expect("an event").0,
        }
    }

    /// Takes `z` at driver time `t` as the last state (the run's first).
    pub fn restart(&mut self, sys: &S, z: &State<S::Dim>, t: f64) {
        copy(&mut self.last, z);
        self.last_t = state_time(sys, z, t);
        for i in 0..self.trackers.len() {
            let surface = self.surface(self.trackers[i].kind);
            let s = self.henon.value(surface, z, self.last_t);
            let tracker = &mut self.trackers[i];
            tracker.last = s;
            if let Surface::Clock { period, phase } = surface {
                // The first level after the start: the start itself is not a crossing.
                tracker.next = ((self.last_t - phase) / period).floor().max(0.0) as u64;
                while phase + tracker.next as f64 * period <= self.last_t {
                    tracker.next += 1;
                }
            } else {
                tracker.range = [s.min(tracker.range[0]), s.max(tracker.range[1])];
            }
        }
    }

    /// Whether the step that ended at the kernel state `z` (driver time `t`) crossed no surface,
    /// judged from the kernel with the margin (module docs): no values within the margin of
    /// each surface's value there and at the last kernel state cross in its direction; each
    /// stroboscopic level is more than the margin and a step ahead. Judges every step, so that
    /// the next one has its values.
    pub fn step_is_clear(&mut self, sys: &S, t: f64, z: &State<S::Dim>) -> bool {
        let t_now = state_time(sys, z, t);
        let step = (t_now - self.kernel_t).abs();
        self.kernel_t = t_now;
        self.kernel_judged = true;
        let mut clear = self.calibrated >= CALIBRATION;
        for i in 0..self.trackers.len() {
            let surface = self.surface(self.trackers[i].kind);
            let s = match surface {
                Surface::Clock { .. } => t_now,
                Surface::Expression { .. } => self.henon.value(surface, z, t_now),
            };
            let tracker = &mut self.trackers[i];
            let before = std::mem::replace(&mut tracker.kernel, s);
            tracker.kernel_before = before;
            let change = (s - before).abs();
            if change.is_finite() && !matches!(surface, Surface::Clock { .. }) {
                tracker.step_change = tracker.step_change.max(change);
            }
            let margin = (SAFETY * tracker.deviation).max(STEP_FRACTION * tracker.step_change);
            // NaN compares false: a value that is not a number is never clear.
            clear &= tracker.truncated
                || match *surface {
                    Surface::Clock { period, phase } => {
                        phase + tracker.next as f64 * period - s > margin + step
                    }
                    Surface::Expression { .. } => tracker.direction.cannot_cross(before, s, margin),
                };
        }
        if clear {
            for tracker in &mut self.trackers {
                let s = tracker.kernel;
                tracker.range = [s.min(tracker.range[0]), s.max(tracker.range[1])];
            }
        }
        clear
    }

    /// The output state `z` at driver time `t` of the last step judged clear, formed because
    /// the step after it is not: watched like any step, from the last output state formed. It
    /// crosses nothing when the margin held; if it did not (the processor moved S by more than
    /// the margin somewhere in the steps skipped), a crossing they hid is still found, located
    /// by Hénon's step from that earlier state, and the difference seen widens the margin.
    pub fn resume(
        &mut self,
        sys: &S,
        t: f64,
        z: &State<S::Dim>,
        emit: &mut dyn FnMut(&Crossing<'_>),
    ) -> ControlFlow<f64> {
        self.watch(sys, t, z, Kernel::BeforeLast, emit)
    }

    /// After a step to `z` at driver time `t`: locates the crossings since the last state,
    /// hands each to `emit`, and ends the run at the event's last one.
    pub fn step(
        &mut self,
        sys: &S,
        t: f64,
        z: &State<S::Dim>,
        emit: &mut dyn FnMut(&Crossing<'_>),
    ) -> ControlFlow<f64> {
        let kernel = if std::mem::take(&mut self.kernel_judged) {
            self.calibrated += 1;
            Kernel::Last
        } else {
            Kernel::None
        };
        self.watch(sys, t, z, kernel, emit)
    }

    /// [`step`](Self::step) and [`resume`](Self::resume): the crossings between the last state
    /// and `z`, and the difference between S at `z` and at its kernel state, when judged.
    fn watch(
        &mut self,
        sys: &S,
        t: f64,
        z: &State<S::Dim>,
        kernel: Kernel,
        emit: &mut dyn FnMut(&Crossing<'_>),
    ) -> ControlFlow<f64> {
        let t_now = state_time(sys, z, t);
        let mut flow = ControlFlow::Continue(());
        // The crossing located at this step and whose surface it was on: a section and an
        // event on the same surface (a run ended at its n-th point) share it.
        let mut located_here: Option<(&Surface, Result<(f64, f64), Unlocated>)> = None;
        for i in 0..self.trackers.len() {
            let kind = self.trackers[i].kind;
            let surface = self.surface(kind);
            let s = self.henon.value(surface, z, t_now);
            let tracker = &mut self.trackers[i];
            let judged = match kernel {
                Kernel::Last => Some(tracker.kernel),
                Kernel::BeforeLast => Some(tracker.kernel_before),
                Kernel::None => None,
            };
            if let Some(k) = judged {
                tracker.deviation = tracker.deviation.max((s - k).abs());
            }
            if let Surface::Clock { period, phase } = *surface {
                loop {
                    let tracker = &self.trackers[i];
                    let level = phase + tracker.next as f64 * period;
                    // A level the step reaches to within round-off of its length counts (as
                    // the run's last step reaches t_end): t_end = kT gives its k-th point.
                    let reach = t_now + 1e-9 * (t_now - self.last_t).abs();
                    if level > reach || tracker.truncated || flow.is_break() {
                        break;
                    }
                    self.trackers[i].next += 1;
                    let located = self.henon.locate(
                        sys,
                        surface,
                        (&self.last, self.last_t, self.last_t),
                        level,
                        &mut self.point,
                    );
                    // A stroboscopic point's time is its level, not the step's sum.
                    flow = self.found(sys, i, located.map(|_| level), emit);
                }
            } else {
                let tracker = &mut self.trackers[i];
                tracker.range = [s.min(tracker.range[0]), s.max(tracker.range[1])];
                let before = tracker.last;
                tracker.last = s;
                if tracker.direction.crossed(before, s) && !tracker.truncated && flow.is_continue()
                {
                    let located = match located_here {
                        Some((other, located)) if other.same_as(surface) => located,
                        _ => self.locate(sys, surface, (before, s), z, t_now),
                    };
                    located_here = Some((surface, located));
                    // The point must move across the surface the way the steps did.
                    let located = located.and_then(|(t, sigma)| {
                        let along = if s > before { sigma > 0.0 } else { sigma < 0.0 };
                        along.then_some(t).ok_or(Unlocated::Reversed)
                    });
                    flow = self.found(sys, i, located, emit);
                }
            }
        }
        copy(&mut self.last, z);
        self.last_t = t_now;
        flow
    }

    /// Locates the crossing of S = 0 between the last state (S = `before`) and `z` (S =
    /// `after`): from the last state when S moves there in the direction it crossed in, else
    /// back from `z`; from the other end when the first attempt fails. Returns the point's time
    /// and the rate σ at which S changes there.
    fn locate(
        &mut self,
        sys: &S,
        surface: &Surface,
        (before, after): (f64, f64),
        z: &State<S::Dim>,
        t_now: f64,
    ) -> Result<(f64, f64), Unlocated> {
        let rising = after > before;
        let sigma = self.henon.rate(sys, surface, &self.last, self.last_t);
        let from_last = (sigma > 0.0) == rising && sigma != 0.0;
        let ends = [(&self.last, self.last_t, before), (z, t_now, after)];
        let order = if from_last { [0, 1] } else { [1, 0] };
        let first = self
            .henon
            .locate(sys, surface, ends[order[0]], 0.0, &mut self.point);
        let t = first.or_else(|_| {
            self.henon
                .locate(sys, surface, ends[order[1]], 0.0, &mut self.point)
        })?;
        Ok((t, self.henon.rate(sys, surface, &self.point, t)))
    }

    /// Reports a located crossing (or counts an unlocated one); the event's last ends the run.
    fn found(
        &mut self,
        sys: &S,
        i: usize,
        located: Result<f64, Unlocated>,
        emit: &mut dyn FnMut(&Crossing<'_>),
    ) -> ControlFlow<f64> {
        let tracker = &mut self.trackers[i];
        let Ok(t) = located else {
            tracker.unlocated += 1;
            return ControlFlow::Continue(());
        };
        tracker.count += 1;
        let n = self.crossings.names.coordinates.len();
        if let Some((x, px)) = self.cartesian.as_mut() {
            sys.to_cartesian(&self.point.q, &self.point.p, x, px);
        }
        emit(&Crossing {
            kind: tracker.kind,
            t,
            q: &self.point.q.as_slice()[..n],
            p: &self.point.p.as_slice()[..n],
            energy: sys.energy(&self.point.q, &self.point.p),
            cartesian_q: self.cartesian.as_ref().map(|(x, _)| x.as_slice()),
        });
        if tracker.count >= tracker.limit {
            match tracker.kind {
                CrossingKind::Section => tracker.truncated = true,
                CrossingKind::Event => return ControlFlow::Break(t),
            }
        }
        ControlFlow::Continue(())
    }

    /// The section's summary, when the run has a section.
    pub fn summary(&self) -> Option<SectionSummary> {
        let tracker = self
            .trackers
            .iter()
            .find(|t| t.kind == CrossingKind::Section)?;
        let expression = matches!(
            self.surface(CrossingKind::Section),
            Surface::Expression { .. }
        );
        let range = (expression && tracker.range[0] <= tracker.range[1]).then_some(tracker.range);
        let note = (tracker.count == 0).then(|| match (range, tracker.unlocated) {
            (_, u) if u > 0 => format!(
                "the surface was crossed {u} times, each time too close to tangent to locate \
                 the point or turned back from short of it"
            ),
            (Some([lo, hi]), _) => format!(
                "the surface was never crossed{}: S stayed in [{lo:e}, {hi:e}]",
                match tracker.direction {
                    Direction::Up => " upwards",
                    Direction::Down => " downwards",
                    Direction::Both => "",
                }
            ),
            (None, _) => "the run ended before the first stroboscopic time".to_string(),
        });
        Some(SectionSummary {
            points: tracker.count,
            truncated: tracker.truncated,
            unlocated: tracker.unlocated,
            surface_range: range,
            note,
        })
    }
}

/// The time of the state `z` at driver time `t`: a driven system's own clock, else `t`.
#[inline]
fn state_time<S: MechanicalSystem>(sys: &S, z: &State<S::Dim>, t: f64) -> f64
where
    DefaultAllocator: Allocator<S::Dim>,
{
    sys.clock().map_or(t, |k| z.q[k])
}
