//! Running one method of a [`Simulation`]: the driver integrates, an observer turns each sampled
//! state into a [`Sample`] (energy, energy error, invariants, the Cartesian state, the Jacobian
//! determinant defect), and a [`SampleSink`] takes it — a document's columns, a stream's chunks,
//! a study's measurements. Also the reference run whose energies give the errors when the system
//! has no exact solution, and the parallel execution of a simulation's methods.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

use super::spec::{EnergyReference, Simulation};
use crate::chaos::{ChaosPlan, IndicatorValues, Tracker};
use crate::error::{CoreError, Field};
use crate::methods::{self, Method, MethodId};
use crate::run::{integrate, integrate_tracked, Budget, Observer, RunEnd, RunStats, Tracking};
use crate::sections::{Crossing, SectionSummary, Watch};
use crate::system::{MechanicalSystem, State};
use crate::systems::world::Drawing;
use crate::systems::World;
use crate::{with_stepper, with_system};

/// One sample as sinks receive it.
#[derive(Clone, Debug)]
pub struct Sample<'a> {
    /// Step index.
    pub step: u64,
    /// Time.
    pub t: f64,
    /// Positions.
    pub q: &'a [f64],
    /// Momenta.
    pub p: &'a [f64],
    /// The state in Cartesian coordinates (positions, momenta) when the chart is not.
    pub cartesian: Option<(&'a [f64], &'a [f64])>,
    /// Total energy H.
    pub energy: f64,
    /// H − H_exact (exact solution or reference), when known.
    pub energy_error: Option<f64>,
    /// Invariants, in the order of the system's invariant names.
    pub invariants: &'a [f64],
    /// |det ∂Φ/∂z − e^{−r h n}| of the step that ended here, when asked for.
    pub jacobian_defect: Option<f64>,
    /// The bodies' coordinates, for a system drawn by its definition's `positions`.
    pub bodies: Option<&'a [f64]>,
    /// The chaos indicators, when asked for.
    pub indicators: Option<&'a IndicatorValues>,
}

/// Receives samples of one method's run.
pub trait SampleSink {
    /// One sample.
    fn on_sample(&mut self, sample: &Sample<'_>);

    /// A located crossing of the run's section or event surface (runs that watch one only).
    fn on_crossing(&mut self, _crossing: &Crossing<'_>) {}

    /// How the run's section went, once the run has ended (runs with a section only).
    fn on_section_end(&mut self, _summary: &SectionSummary) {}

    /// Whether the samples should carry the bodies' coordinates of a system that draws them
    /// (a sink that never reads them spares their evaluation at every sample).
    fn wants_bodies(&self) -> bool {
        true
    }
}

/// How one method's run ended, as the driver reports it: why it stopped and its statistics
/// (the document's [`RunOutcome`](super::RunOutcome) adds what its observers measured).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunReport {
    /// Why it stopped.
    pub stop: RunEnd,
    /// Statistics.
    pub stats: RunStats,
}

impl Simulation {
    /// Runs method `index`, sending samples to `sink`. `reference` holds reference energies per
    /// sample (from [`Simulation::reference_energies`]).
    pub fn run_method(
        &self,
        index: usize,
        reference: Option<&[f64]>,
        budget: Budget<'_>,
        sink: &mut dyn SampleSink,
    ) -> Result<RunReport, CoreError> {
        self.run(&self.methods[index], reference, budget, sink)
    }

    /// Runs `method` from this simulation's initial state over its schedule, with the chaos
    /// indicators the simulation asks for.
    pub fn run(
        &self,
        method: &Method,
        reference: Option<&[f64]>,
        budget: Budget<'_>,
        sink: &mut dyn SampleSink,
    ) -> Result<RunReport, CoreError> {
        self.run_with(method, reference, budget, sink, true, self.chaos.as_ref())
    }

    /// [`run`](Self::run), watching the simulation's section and event when `watch` is set and
    /// tracking the indicators `chaos` (the reference run does neither: its energies are all
    /// it gives).
    fn run_with(
        &self,
        method: &Method,
        reference: Option<&[f64]>,
        budget: Budget<'_>,
        sink: &mut dyn SampleSink,
        watch: bool,
        chaos: Option<&ChaosPlan>,
    ) -> Result<RunReport, CoreError> {
        with_system!(&self.system, sys => {
            let mut stepper = methods::build(method, sys, &self.system_label, self.schedule.h)?;
            let start = State::at_time(sys, 0.0, &self.q0, &self.p0);
            let mut z = start.clone();
            let mut observer = self.observer(sys, &start, reference, sink, watch);
            let mut tracker = chaos.map(|plan| Tracker::new(sys, &z, plan, self.schedule.h));
            let tracking = match tracker.as_mut() {
                Some(tracker) => Tracking::Chaos(tracker),
                None if self.jacobian_defect && method.no_step_jacobian().is_none() => {
                    Tracking::Determinant
                }
                None => Tracking::Off,
            };
            // Runs with tangents take the stepper as the enum of every method (their tangent
            // steps cost far more than its dispatch, and the core compiles one such driver per
            // system); plain and watched runs, one copy per method, stretches inlined.
            let (stop, stats) = match tracking {
                Tracking::Off => with_stepper!(&mut stepper, st => integrate(
                    sys, st, &mut z, self.schedule, budget, &mut observer,
                )),
                tracking => integrate_tracked(
                    sys, &mut stepper, &mut z, self.schedule, budget, tracking, &mut observer,
                ),
            }?;
            if let Some(summary) = observer.watch.as_ref().and_then(Watch::summary) {
                observer.sink.on_section_end(&summary);
            }
            Ok(RunReport { stop, stats })
        })
    }

    /// The observer of a run of this simulation from `start` on `sys`: it turns the driver's
    /// states into samples for `sink` and, when `watch` is set, watches the simulation's
    /// section and event.
    pub(super) fn observer<'a, S: MechanicalSystem>(
        &'a self,
        sys: &'a S,
        start: &'a State<S::Dim>,
        reference: Option<&'a [f64]>,
        sink: &'a mut dyn SampleSink,
        watch: bool,
    ) -> Diagnose<'a, S>
    where
        DefaultAllocator: Allocator<S::Dim>,
    {
        let n = self.q0.len();
        let crossings = self.crossings.as_deref().filter(|_| watch);
        let bodies = sink.wants_bodies();
        Diagnose {
            watch: crossings.map(|c| Watch::new(sys, c, start)),
            sys,
            start,
            reference,
            sink,
            invariants: vec![0.0; sys.invariant_count()],
            cartesian: (!sys.is_cartesian()).then(|| (vec![0.0; n], vec![0.0; n])),
            drawing: match &self.world {
                World::Drawn(drawing) if bodies => Some((&**drawing, Vec::new())),
                _ => None,
            },
            expected_det: (-sys.damping_rate() * self.schedule.h * n as f64).exp(),
            last_det: None,
            indicators: None,
            sample_index: 0,
            initial_energy: (self.energy_reference() == Some(EnergyReference::Initial))
                .then(|| sys.energy(&start.q, &start.p)),
        }
    }

    /// The reference energies at the sample times (None unless `compare_to_reference`).
    pub fn reference_energies(&self, budget: Budget<'_>) -> Result<Option<Vec<f64>>, CoreError> {
        if !self.compare_to_reference {
            return Ok(None);
        }
        let mut log = EnergyLog(Vec::with_capacity(self.schedule.samples() as usize));
        let field = Field::new("compare_to_reference");
        // The reference runs to the end, whatever the runs' events.
        let outcome = self
            .run_with(
                &Method::new(MethodId::Reference),
                None,
                budget,
                &mut log,
                false,
                None,
            )
            .map_err(|e| match e {
                CoreError::Step {
                    step, t, source, ..
                } => CoreError::Step {
                    field: Some(field.clone()),
                    run: Some("reference run".into()),
                    step,
                    t,
                    source,
                },
                other => other,
            })?;
        match outcome.stop {
            RunEnd::Finished => Ok(Some(log.0)),
            RunEnd::TimeLimit { .. } => Err(CoreError::TimeLimit {
                field: Some(field),
                message: "the reference run did not finish within the time limit; ask for fewer \
                          steps"
                    .into(),
            }),
            stop => Err(CoreError::ReferenceUnfinished {
                field,
                stop: format!("{stop:?}"),
            }),
        }
    }
}

/// Collects only energies (for the reference run).
struct EnergyLog(Vec<f64>);

impl SampleSink for EnergyLog {
    fn on_sample(&mut self, sample: &Sample<'_>) {
        self.0.push(sample.energy);
    }

    fn wants_bodies(&self) -> bool {
        false
    }
}

/// The observer that turns raw states into [`Sample`]s, and watches every step for the
/// crossings of a section or an event.
pub(super) struct Diagnose<'a, S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    watch: Option<Watch<'a, S>>,
    sys: &'a S,
    start: &'a State<S::Dim>,
    reference: Option<&'a [f64]>,
    sink: &'a mut dyn SampleSink,
    invariants: Vec<f64>,
    /// Buffers for the Cartesian state, when the chart is not Cartesian.
    cartesian: Option<(Vec<f64>, Vec<f64>)>,
    /// The drawing of a user-defined system and a buffer for its bodies' coordinates.
    drawing: Option<(&'a Drawing, Vec<f64>)>,
    expected_det: f64,
    last_det: Option<f64>,
    indicators: Option<IndicatorValues>,
    sample_index: usize,
    /// H at the start, when energy errors are measured against it.
    initial_energy: Option<f64>,
}

impl<S: MechanicalSystem> Observer<S::Dim> for Diagnose<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn on_sample(&mut self, step: u64, t: f64, z: &State<S::Dim>) {
        let energy = self.sys.energy(&z.q, &z.p);
        let energy_error = match (self.reference, self.initial_energy) {
            (Some(r), _) => r.get(self.sample_index).map(|e| energy - e),
            (None, Some(e0)) => Some(energy - e0),
            (None, None) => self
                .sys
                .exact(t, self.start)
                .map(|x| energy - self.sys.energy(&x.q, &x.p)),
        };
        self.sys.invariants(t, &z.q, &z.p, &mut self.invariants);
        if let Some((x, px)) = self.cartesian.as_mut() {
            self.sys.to_cartesian(&z.q, &z.p, x, px);
        }
        let (q, p) = z.physical(self.sys);
        if let Some((drawing, bodies)) = self.drawing.as_mut() {
            drawing.coordinates(q, bodies);
        }
        self.sink.on_sample(&Sample {
            step,
            t,
            q,
            p,
            cartesian: self
                .cartesian
                .as_ref()
                .map(|(x, px)| (x.as_slice(), px.as_slice())),
            energy,
            energy_error,
            invariants: &self.invariants,
            jacobian_defect: self.last_det.map(|d| (d - self.expected_det).abs()),
            bodies: self.drawing.as_ref().map(|(_, bodies)| bodies.as_slice()),
            indicators: self.indicators.as_ref(),
        });
        self.sample_index += 1;
    }

    fn on_step_determinant(&mut self, _step: u64, det: f64) {
        self.last_det = Some(det);
    }

    fn watches_steps(&self) -> bool {
        self.watch.is_some()
    }

    fn on_step(&mut self, _step: u64, t: f64, z: &State<S::Dim>) -> ControlFlow<f64> {
        let sink = &mut self.sink;
        match self.watch.as_mut() {
            Some(watch) => watch.step(self.sys, t, z, &mut |c| sink.on_crossing(c)),
            None => ControlFlow::Continue(()),
        }
    }

    fn step_is_clear(&mut self, t: f64, z: &State<S::Dim>) -> bool {
        let sys = self.sys;
        self.watch
            .as_mut()
            .is_some_and(|watch| watch.step_is_clear(sys, t, z))
    }

    fn on_clear_step(&mut self, t: f64, z: &State<S::Dim>) -> ControlFlow<f64> {
        let sink = &mut self.sink;
        match self.watch.as_mut() {
            Some(watch) => watch.resume(self.sys, t, z, &mut |c| sink.on_crossing(c)),
            None => ControlFlow::Continue(()),
        }
    }

    fn on_indicators(&mut self, values: &IndicatorValues) {
        self.indicators = Some(values.clone());
    }
}

/// Runs `job(i)` for `i` in `0..count` on up to `workers` threads (the caller's thread alone when
/// `workers` ≤ 1) and returns the results in index order. A panic in a job resumes in the
/// caller.
pub fn for_each_method<T: Send>(
    count: usize,
    workers: usize,
    job: impl Fn(usize) -> T + Sync,
) -> Vec<T> {
    let workers = workers.clamp(1, count.max(1));
    if workers == 1 {
        return (0..count).map(job).collect();
    }
    let next = AtomicUsize::new(0);
    let span = tracing::Span::current();
    let mut results: Vec<(usize, T)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                scope.spawn(|| {
                    let _entered = span.enter();
                    let mut done = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        if i >= count {
                            break done;
                        }
                        done.push((i, job(i)));
                    }
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| {
                h.join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
            })
            .collect()
    });
    results.sort_by_key(|(i, _)| *i);
    results.into_iter().map(|(_, r)| r).collect()
}
