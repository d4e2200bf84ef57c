//! A sweep's document: its axes, and per method and chart the metrics over the cells as columns
//! in cell order.

use std::collections::BTreeMap;

use serde::Serialize;

use super::axis::Scale;
use super::metrics::{CellSection, ChaosMetrics, EnergyReference, RunMetrics};
use super::RunLabel;
use crate::studies::StudyCompletion;

/// One axis as the document gives it.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct AxisDocument {
    /// `params.<name>`, `h`, `q0[i]` or `p0[i]`.
    pub name: String,
    /// The first value.
    pub min: f64,
    /// The last value.
    pub max: f64,
    /// Points.
    pub n: usize,
    /// Spacing.
    pub scale: Scale,
    /// The points.
    pub values: Vec<f64>,
}

/// One run's metrics over the cells, as columns in cell order (row-major: the first axis runs
/// fastest).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct RunColumns {
    /// The method's label.
    pub method: String,
    /// The chart's id.
    pub chart: String,
    /// Energy error at the last sample (`null`: diverged, or not measured).
    pub energy_error_final: Vec<Option<f64>>,
    /// Largest |energy error| over the samples.
    pub energy_error_max: Vec<Option<f64>>,
    /// ℓ² mean of the energy error over the samples (001 eq. 50).
    pub energy_error_l2: Vec<Option<f64>>,
    /// Per invariant, max |I(t) − I(0)|.
    #[cfg_attr(feature = "openapi", schema(value_type = Object))]
    pub invariant_drift: BTreeMap<String, Vec<Option<f64>>>,
    /// Time of divergence (`null`: none).
    pub diverged_at: Vec<Option<f64>>,
    /// Final positions, Cartesian (empty where the run could not start).
    pub final_q: Vec<Vec<f64>>,
    /// Final momenta, Cartesian.
    pub final_p: Vec<Vec<f64>>,
    /// Steps taken.
    pub steps: Vec<u64>,
    /// Force evaluations.
    pub force_evaluations: Vec<u64>,
    /// Why a run could not start or was not run (`null` where it ran).
    pub errors: Vec<Option<String>>,
    /// The chaos indicators' last values per cell, and the time a threshold stopped a cell's
    /// run (with `indicators` only).
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub chaos: Option<ChaosColumns>,
    /// Per cell, the run's section (null where the run did not start), when the sweep asks for
    /// a section.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sections: Option<Vec<Option<CellSection>>>,
}

/// A chaos map: each indicator's last value per cell (`null` where not asked for or the run did
/// not start), and the time a threshold stopped a cell's run (`null`: it ran to the end).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ChaosColumns {
    /// The largest finite-time Lyapunov exponent.
    pub lyapunov_max: Vec<Option<f64>>,
    /// MEGNO Y.
    pub megno: Vec<Option<f64>>,
    /// MEGNO's mean ⟨Y⟩.
    pub megno_mean: Vec<Option<f64>>,
    /// The fast Lyapunov indicator.
    pub fli: Vec<Option<f64>>,
    /// SALI.
    pub sali: Vec<Option<f64>>,
    /// GALI_k.
    pub gali: Vec<Option<f64>>,
    /// When a threshold (`stop_when`) stopped the run.
    pub stopped_at: Vec<Option<f64>>,
}

impl RunColumns {
    pub(super) fn new(
        label: RunLabel,
        invariants: &[String],
        cells: usize,
        (chaos, section): (bool, bool),
    ) -> Self {
        RunColumns {
            method: label.method,
            chart: label.chart,
            energy_error_final: Vec::with_capacity(cells),
            energy_error_max: Vec::with_capacity(cells),
            energy_error_l2: Vec::with_capacity(cells),
            invariant_drift: invariants
                .iter()
                .map(|n| (n.clone(), Vec::with_capacity(cells)))
                .collect(),
            diverged_at: Vec::with_capacity(cells),
            final_q: Vec::with_capacity(cells),
            final_p: Vec::with_capacity(cells),
            steps: Vec::with_capacity(cells),
            force_evaluations: Vec::with_capacity(cells),
            errors: Vec::with_capacity(cells),
            chaos: chaos.then(ChaosColumns::default),
            sections: section.then(|| Vec::with_capacity(cells)),
        }
    }

    pub(super) fn push(&mut self, m: RunMetrics, invariants: &[String]) {
        self.energy_error_final.push(m.energy_error_final);
        self.energy_error_max.push(m.energy_error_max);
        self.energy_error_l2.push(m.energy_error_l2);
        for (i, name) in invariants.iter().enumerate() {
            if let Some(column) = self.invariant_drift.get_mut(name) {
                column.push(m.invariant_drift.get(i).copied().flatten());
            }
        }
        self.diverged_at.push(m.diverged_at);
        self.final_q.push(m.final_q);
        self.final_p.push(m.final_p);
        self.steps.push(m.steps);
        self.force_evaluations.push(m.force_evaluations);
        self.errors.push(m.error);
        if let Some(columns) = self.chaos.as_mut() {
            columns.push(m.chaos.unwrap_or_default());
        }
        if let Some(sections) = self.sections.as_mut() {
            sections.push(m.section);
        }
    }
}

impl ChaosColumns {
    fn push(&mut self, m: ChaosMetrics) {
        self.lyapunov_max.push(m.lyapunov_max);
        self.megno.push(m.megno);
        self.megno_mean.push(m.megno_mean);
        self.fli.push(m.fli);
        self.sali.push(m.sali);
        self.gali.push(m.gali);
        self.stopped_at.push(m.stopped_at);
    }
}

/// A sweep's result.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct SweepDocument {
    /// The system's id.
    pub system: String,
    /// The axes.
    pub axes: Vec<AxisDocument>,
    /// Cells in all (the product of the axes' points).
    pub cells: usize,
    /// What the energy errors are measured against.
    pub energy_reference: EnergyReference,
    /// The system's invariants.
    pub invariants: Vec<String>,
    /// Per method and chart, the metrics over the cells.
    pub runs: Vec<RunColumns>,
    /// Steps over all cells and runs.
    pub steps: u64,
    /// Force evaluations over all cells and runs.
    pub force_evaluations: u64,
    /// The request's identity (a digest of its canonical JSON).
    pub digest: String,
    /// Wall time in milliseconds.
    pub wall_ms: f64,
    /// `time_limit` when the time limit stopped some cells: their metrics are `null` and their
    /// `errors` say so.
    pub stop: StudyCompletion,
    /// The cells the time limit stopped, in order (empty when `stop` is `finished`).
    pub unfinished_cells: Vec<usize>,
}
