//! What a sweep measures in each run of each cell, from the run's samples: the energy error at
//! the end, its largest value and its ℓ² mean (paper 001 eq. 50), each invariant's drift, the
//! time of divergence and the final state; with chaos indicators asked for, each indicator's last
//! value (a chaos map) and the time a threshold stopped the run; with a section, its points
//! (capped by the section's `max_points`).

use serde::{Deserialize, Serialize};

use crate::chaos::Statistic;
use crate::run::RunEnd;
use crate::sections::{Crossing, CrossingKind, SectionSummary};
use crate::simulation::{CrossingColumns, RunReport, Sample, SampleSink};

pub use crate::diagnostics::DIVERGENCE;

pub use crate::simulation::EnergyReference;

/// What one run of one cell measured. A run that diverged reports its time of divergence, its
/// steps and its last finite state, and no error figures; a run that could not start (its
/// initial state is outside the chart) only its `error`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct RunMetrics {
    /// The energy error at the last sample.
    pub energy_error_final: Option<f64>,
    /// The largest |energy error| over the samples.
    pub energy_error_max: Option<f64>,
    /// √(1/(J+1) Σ_j e_j²) over the J + 1 samples (001 eq. 50 when measured against H₀ at every
    /// step).
    pub energy_error_l2: Option<f64>,
    /// max |I(t) − I(0)| over the samples, per invariant of the system (`null`: not finite).
    pub invariant_drift: Vec<Option<f64>>,
    /// When the run diverged: the time of the first non-finite state, else the first sample
    /// whose |H − H₀| exceeded 100·(1 + |H₀|).
    pub diverged_at: Option<f64>,
    /// The last sample's positions, in Cartesian coordinates.
    pub final_q: Vec<f64>,
    /// The last sample's momenta, in Cartesian coordinates.
    pub final_p: Vec<f64>,
    /// Steps taken.
    pub steps: u64,
    /// Force evaluations.
    pub force_evaluations: u64,
    /// Why the run could not start.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// The chaos indicators at the last sample, when asked for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chaos: Option<ChaosMetrics>,
    /// The section's points, when the sweep asks for a section.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub section: Option<CellSection>,
}

/// One run's section in a sweep: its located points, up to the section's `max_points`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct CellSection {
    /// The points: t, q, p and H at each crossing, in the order they were found.
    pub points: CrossingColumns,
    /// Whether crossings after `max_points` went uncollected.
    pub truncated: bool,
    /// Crossings seen whose point could not be located (tangent to the surface within
    /// round-off).
    pub unlocated: u64,
}

/// A run's chaos indicators at its last sample, and when a threshold stopped it: the values a
/// chaos map shows (`null`: not asked for).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ChaosMetrics {
    /// The largest finite-time Lyapunov exponent.
    pub lyapunov_max: Option<f64>,
    /// MEGNO Y.
    pub megno: Option<f64>,
    /// MEGNO's mean ⟨Y⟩.
    pub megno_mean: Option<f64>,
    /// The fast Lyapunov indicator.
    pub fli: Option<f64>,
    /// SALI.
    pub sali: Option<f64>,
    /// GALI_k.
    pub gali: Option<f64>,
    /// The time a threshold (`stop_when`) stopped the run, if one did.
    pub stopped_at: Option<f64>,
}

impl RunMetrics {
    /// A run that could not start, and why.
    pub fn failed(reason: String) -> Self {
        RunMetrics {
            error: Some(reason),
            ..RunMetrics::default()
        }
    }
}

/// Collects a run's metrics from its samples.
pub struct MetricsTally {
    against: EnergyReference,
    start: Option<f64>,
    limit: f64,
    blown_at: Option<f64>,
    sum: f64,
    count: u64,
    max: f64,
    last: Option<f64>,
    invariants0: Vec<f64>,
    drift: Vec<f64>,
    q: Vec<f64>,
    p: Vec<f64>,
    chaos: Option<ChaosMetrics>,
    section: Option<CellSection>,
}

impl MetricsTally {
    /// A collector measuring energy errors against `against`.
    pub fn new(against: EnergyReference) -> Self {
        MetricsTally {
            against,
            start: None,
            limit: f64::INFINITY,
            blown_at: None,
            sum: 0.0,
            count: 0,
            max: 0.0,
            last: None,
            invariants0: Vec::new(),
            drift: Vec::new(),
            q: Vec::new(),
            p: Vec::new(),
            chaos: None,
            section: None,
        }
    }

    /// What the samples of a run integrated elsewhere (in SIMD lanes) leave: the first time H
    /// left its band, Σ e², the number of samples, max |e|, the last e and the last sample's
    /// Cartesian state, for a system without invariants.
    pub(super) fn of_lane(
        blown_at: Option<f64>,
        (sum, count): (f64, u64),
        (max, last): (f64, f64),
        (q, p): (Vec<f64>, Vec<f64>),
    ) -> Self {
        MetricsTally {
            blown_at,
            sum,
            count,
            max,
            last: Some(last),
            q,
            p,
            ..MetricsTally::new(EnergyReference::Initial)
        }
    }

    /// The metrics of a run that ended with `outcome`.
    pub fn finish(mut self, outcome: &RunReport) -> RunMetrics {
        let stopped_at = match outcome.stop {
            RunEnd::Diverged { t, .. } => Some(t),
            _ => None,
        };
        if let (Some(chaos), RunEnd::Indicator(at)) = (self.chaos.as_mut(), outcome.stop) {
            chaos.stopped_at = Some(at.t);
        }
        self.finish_at(
            stopped_at,
            outcome.stats.steps,
            outcome.stats.force_evaluations,
        )
    }

    /// The metrics of a run that took `steps` steps and `force_evaluations` evaluations and, if
    /// its state stopped being finite, stopped at time `stopped_at`.
    pub(super) fn finish_at(
        self,
        stopped_at: Option<f64>,
        steps: u64,
        force_evaluations: u64,
    ) -> RunMetrics {
        let diverged_at = stopped_at.or(self.blown_at);
        let finite = |x: f64| x.is_finite().then_some(x);
        let healthy = diverged_at.is_none();
        let count = self.count.max(1) as f64;
        RunMetrics {
            energy_error_final: self.last.filter(|_| healthy).and_then(finite),
            energy_error_max: healthy.then_some(self.max).and_then(finite),
            energy_error_l2: (healthy && self.last.is_some())
                .then(|| (self.sum / count).sqrt())
                .and_then(finite),
            invariant_drift: self
                .drift
                .iter()
                .map(|&d| healthy.then_some(d).and_then(finite))
                .collect(),
            diverged_at,
            final_q: self.q,
            final_p: self.p,
            steps,
            force_evaluations,
            error: None,
            chaos: self.chaos,
            section: self.section,
        }
    }
}

impl SampleSink for MetricsTally {
    fn on_sample(&mut self, sample: &Sample<'_>) {
        let start = *self.start.get_or_insert_with(|| {
            self.limit = DIVERGENCE * (1.0 + sample.energy.abs());
            self.invariants0 = sample.invariants.to_vec();
            self.drift = vec![0.0; sample.invariants.len()];
            sample.energy
        });
        let from_start = sample.energy - start;
        // NaN compares false: a non-finite energy counts as blown up too.
        if self.blown_at.is_none() && !(from_start.abs() <= self.limit) {
            self.blown_at = Some(sample.t);
        }
        let error = match self.against {
            EnergyReference::Initial => Some(from_start),
            EnergyReference::Exact | EnergyReference::Reference => sample.energy_error,
        };
        if let Some(e) = error {
            self.sum += e * e;
            self.count += 1;
            self.max = self.max.max(e.abs());
        }
        self.last = error;
        for ((d, &now), &then) in self
            .drift
            .iter_mut()
            .zip(sample.invariants)
            .zip(&self.invariants0)
        {
            // A NaN drift stays NaN (and is reported as null).
            let change = (now - then).abs();
            *d = if change > *d || change.is_nan() {
                change
            } else {
                *d
            };
        }
        if let Some(v) = sample.indicators {
            self.chaos = Some(ChaosMetrics {
                lyapunov_max: v.get(Statistic::LyapunovMax),
                megno: v.megno,
                megno_mean: v.megno_mean,
                fli: v.fli,
                sali: v.sali,
                gali: v.gali,
                stopped_at: None,
            });
        }
        let (q, p) = sample.cartesian.unwrap_or((sample.q, sample.p));
        self.q.clear();
        self.q.extend_from_slice(q);
        self.p.clear();
        self.p.extend_from_slice(p);
    }

    fn on_crossing(&mut self, crossing: &Crossing<'_>) {
        if crossing.kind == CrossingKind::Section {
            self.section.get_or_insert_default().points.push(crossing);
        }
    }

    /// A sweep's metrics never read the bodies.
    fn wants_bodies(&self) -> bool {
        false
    }

    fn on_section_end(&mut self, summary: &SectionSummary) {
        let section = self.section.get_or_insert_default();
        section.truncated = summary.truncated;
        section.unlocated = summary.unlocated;
    }
}
