//! Checking a sweep ([`SweepSpec::prepare`]): its system, axes, runs and limits, into the job
//! whose cells the engine runs.

use super::axis::MAX_POINTS;
use super::{surface, EnergyReference, Grid, RunLabel, SweepJob, SweepSpec, Target};
use super::{MAX_RUNS, MAX_TOTAL_STEPS};
use crate::error::{CoreError, Field, StepScope};
use crate::simulation::{InitialCoordinates, InputFields, Limits, SimulationSpec, Watching};
use crate::studies::engine::Study;

impl SweepSpec {
    /// Validates the sweep (cheap: builds the system at the corners of the grid, integrates
    /// nothing). Problems that only some cells have — an initial state outside a chart — are
    /// those cells' results, not errors of the request.
    pub fn prepare(&self, limits: &Limits) -> Result<SweepJob, CoreError> {
        self.prepare_up_to(limits, MAX_POINTS)
    }

    /// [`Self::prepare`] with up to `max_points` along each axis (a study whose cells cost less
    /// than a sweep's may allow more).
    pub(crate) fn prepare_up_to(
        &self,
        limits: &Limits,
        max_points: usize,
    ) -> Result<SweepJob, CoreError> {
        let info = self.system.resolve(&Field::new("system"))?;
        if self.axes.is_empty() || self.axes.len() > 2 {
            return Err(CoreError::Count {
                field: Field::new("axes"),
                got: self.axes.len() as u64,
                min: 1,
                max: 2,
                what: "axes",
            });
        }
        for (k, axis) in self.axes.iter().enumerate() {
            axis.check(max_points)?;
            if let Some(earlier) = self.axes[..k].iter().find(|a| a.target == axis.target) {
                return Err(CoreError::Duplicate {
                    field: axis.field.key("name"),
                    value: earlier.target.name(),
                });
            }
        }
        let step_axis = self.axes.iter().find(|a| a.target == Target::Step);
        let h = match (self.h, step_axis) {
            (Some(_), Some(axis)) => {
                return Err(CoreError::Either {
                    field: axis.field.clone(),
                    first: "`h`",
                    second: "an axis over `h`",
                })
            }
            (Some(h), None) => h,
            (None, Some(axis)) => axis.min,
            (None, None) => {
                return Err(CoreError::Missing {
                    field: Field::new("h"),
                    what: "the step size (or an axis over `h`)",
                })
            }
        };
        if self.methods.is_empty() {
            return Err(CoreError::Empty {
                field: Field::new("methods"),
                what: "method",
            });
        }
        let charts: Vec<(Option<String>, Field)> = if self.charts.is_empty() {
            vec![(None, Field::new("chart"))]
        } else {
            self.charts.clone()
        };
        let runs = self.methods.len() * charts.len();
        if runs > MAX_RUNS {
            return Err(CoreError::TooMany {
                field: Field::new("methods"),
                what: "runs (methods × charts) per cell",
                limit: MAX_RUNS,
                got: Some(runs),
            });
        }
        let initial_cartesian = InitialCoordinates::cartesian_in_study(
            self.initial_coordinates,
            charts.len(),
            self.q0.is_some() || self.p0.is_some(),
        )?;
        let mut templates = Vec::with_capacity(runs);
        let mut labels = Vec::with_capacity(runs);
        for method in &self.methods {
            for (chart, chart_field) in &charts {
                let id = info.chart(chart.as_deref(), chart_field)?.id;
                templates.push(SimulationSpec {
                    system: self.system.clone(),
                    params: self.params.clone(),
                    chart: chart.clone(),
                    initial_cartesian,
                    methods: vec![method.clone()],
                    h,
                    t_end: self.t_end,
                    q0: self.q0.clone(),
                    p0: self.p0.clone(),
                    every: Some(self.every.unwrap_or(1)),
                    compare_to_reference: false,
                    jacobian_defect: false,
                    fields: InputFields {
                        chart: chart_field.clone(),
                        every: Field::new("every"),
                        steps: Field::new("t_end"),
                        ..InputFields::default()
                    },
                });
                labels.push(RunLabel {
                    method: method.method.label(),
                    chart: id.to_string(),
                });
            }
        }
        let fills_state = self
            .axes
            .iter()
            .find(|a| matches!(a.target, Target::Q0(_) | Target::P0(_)));
        if let Some(axis) = fills_state {
            let in_chart = !initial_cartesian && charts.iter().any(|(c, _)| c.is_some());
            let missing = match axis.target {
                Target::Q0(_) => self.q0.is_none(),
                _ => self.p0.is_none(),
            };
            if in_chart && missing {
                return Err(CoreError::Missing {
                    field: Field::new(axis.input_field()),
                    what: "the initial state in the chart's coordinates, which the axis varies \
                           (or `initial_coordinates: \"cartesian\"`)",
                });
            }
        }

        let grid = Grid {
            axes: self.axes.clone(),
        };
        if let Some(surface) = &self.energy_surface {
            surface::check_axes(surface, &grid)?;
        }
        let mut job = SweepJob {
            templates,
            runs: labels,
            grid,
            against: EnergyReference::Initial,
            info,
            total_steps: 0,
            digest: self.digest.clone(),
            lanes: None,
            spec: self.clone(),
            chaos: self.chaos.clone(),
            surface: self.energy_surface.clone(),
            watching: self.section.clone().map(|section| Watching {
                section: Some(section),
                stop_when: None,
                energy: None,
            }),
            // A run's samples go into its metrics as they come and are not kept, so the sample
            // limit (which bounds documents) does not apply — except to a reference run, whose
            // energies are kept for the whole run.
            limits: Limits {
                max_samples: u64::MAX,
                ..*limits
            },
        };
        let damped = job.check_corners()?;
        job.check_surface()?;
        if let Some(section) = &self.section {
            // Every point is kept: the points of all cells count against the sample limit.
            let points = section
                .max_points
                .saturating_mul(job.cells() as u64)
                .saturating_mul(job.templates.len() as u64);
            if points > limits.max_samples {
                return Err(CoreError::TooManySamples {
                    field: section.field.key("max_points"),
                    samples: points,
                    limit: limits.max_samples,
                });
            }
        }
        job.against = match self.energy_reference {
            Some(EnergyReference::Exact) if !job.info.exact_solution => {
                return Err(CoreError::Unsupported {
                    field: Field::new("energy_reference"),
                    reason: "the system has no exact solution; use `reference` or `initial`",
                })
            }
            Some(chosen) => chosen,
            None if job.info.exact_solution => EnergyReference::Exact,
            None if damped => EnergyReference::Reference,
            None => EnergyReference::Initial,
        };
        if job.against == EnergyReference::Reference {
            job.limits = *limits;
            job.check_corners()?;
        }
        job.lanes = job.lane_plan();
        job.total_steps = job.count_steps();
        if job.total_steps > MAX_TOTAL_STEPS {
            return Err(CoreError::TooManySteps {
                field: Field::new("axes"),
                steps: job.total_steps,
                limit: MAX_TOTAL_STEPS,
                scope: StepScope::PerStudy,
            });
        }
        Ok(job)
    }
}
