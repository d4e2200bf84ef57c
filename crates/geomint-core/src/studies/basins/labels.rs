//! A basin map's document from what its cells came to: the labels, given in the order outcomes
//! first appear in cell order (the given attractors first), the attractors' table, the shares
//! and the metrics.

use super::document::{
    Attractor, AttractorKind, BasinRun, BasinsDocument, DecidedBy, UndecidedCell,
};
use super::metrics::basin_metrics;
use super::outcome::{CellOutcome, OrbitOutcome};
use super::{BasinsJob, MAX_ATTRACTORS};
use crate::studies::engine::{Finished, Study};

impl BasinsJob {
    /// The document of the map from what its cells came to.
    pub fn document_of(&self, finished: Finished<Vec<CellOutcome>>) -> BasinsDocument {
        let unfinished_cells = finished.unfinished();
        let not_run = CellOutcome {
            outcome: OrbitOutcome::Undecided {
                reason: "not run: the map reached its time limit".into(),
            },
            decided_at: None,
            steps: 0,
            energy_margin: None,
        };
        let runs = (0..self.sweep.runs.len())
            .map(|r| {
                let cells: Vec<&CellOutcome> = finished
                    .cells
                    .iter()
                    .map(|c| c.as_ref().map_or(&not_run, |c| &c[r]))
                    .collect();
                self.run_document(r, &cells)
            })
            .collect();
        BasinsDocument {
            system: self.sweep.info.id.to_string(),
            axes: self.sweep.axis_documents(),
            cells: self.cells(),
            exits: self.exit_names.clone(),
            equilibria: self.criteria.landscape.as_ref().map(|l| l.points.clone()),
            lowest_saddle_energy: self.criteria.landscape.as_ref().and_then(|l| l.barrier),
            runs,
            digest: self.sweep.digest.clone(),
            wall_ms: finished.wall_ms,
            stop: finished.stop,
            unfinished_cells,
        }
    }

    /// One run's labels, attractors and metrics.
    fn run_document(&self, run: usize, cells: &[&CellOutcome]) -> BasinRun {
        // The given attractors take the first labels, whether or not a cell reaches them.
        let mut attractors: Vec<Attractor> = self
            .spec
            .attractors
            .iter()
            .enumerate()
            .map(|(k, given)| Attractor {
                label: k as i64,
                kind: AttractorKind::Given,
                name: given.name.clone(),
                period: None,
                equilibrium: None,
                points: given.points.clone(),
                radius: Some(given.radius),
                cells: 0,
                outcome: OrbitOutcome::Given { attractor: k },
            })
            .collect();
        let mut labels = Vec::with_capacity(cells.len());
        let mut undecided = Vec::new();
        let mut decided_by = DecidedBy::default();
        let mut largest_margin: Option<f64> = None;
        for (i, cell) in cells.iter().enumerate() {
            match &cell.outcome {
                OrbitOutcome::Equilibrium { .. } | OrbitOutcome::Well { .. } => {
                    decided_by.energy += 1
                }
                OrbitOutcome::Exit { .. } => decided_by.exit += 1,
                OrbitOutcome::Cycle { .. } => decided_by.recurrence += 1,
                OrbitOutcome::Given { .. } => decided_by.proximity += 1,
                OrbitOutcome::Diverged => decided_by.divergence += 1,
                OrbitOutcome::Stayed => decided_by.t_end += 1,
                OrbitOutcome::Undecided { .. } | OrbitOutcome::Failed { .. } => {
                    decided_by.undecided += 1
                }
            }
            if let Some(m) = cell.energy_margin {
                largest_margin = Some(largest_margin.map_or(m, |l: f64| l.max(m)));
            }
            let label = match &cell.outcome {
                OrbitOutcome::Undecided { reason } => {
                    undecided.push(UndecidedCell {
                        cell: i,
                        reason: reason.clone(),
                    });
                    -1
                }
                OrbitOutcome::Failed { error } => {
                    undecided.push(UndecidedCell {
                        cell: i,
                        reason: error.clone(),
                    });
                    -1
                }
                outcome => match {
                    let outcome = self.as_given(outcome);
                    let angles = &self.criteria.angles;
                    attractors.iter().position(|a| a.matches(&outcome, angles))
                } {
                    Some(k) => k as i64,
                    None if attractors.len() < MAX_ATTRACTORS => {
                        attractors.push(self.attractor(&attractors, outcome));
                        attractors.len() as i64 - 1
                    }
                    None => {
                        undecided.push(UndecidedCell {
                            cell: i,
                            reason: format!(
                                "more than {MAX_ATTRACTORS} distinct outcomes, given attractors \
                                 included: this one has no label (give fewer attractors, or \
                                 loosen recognition.tolerance)"
                            ),
                        });
                        -1
                    }
                },
            };
            if label >= 0 {
                attractors[label as usize].cells += 1;
            }
            labels.push(label);
        }
        let started: Vec<bool> = cells
            .iter()
            .map(|c| !matches!(c.outcome, OrbitOutcome::Failed { .. }))
            .collect();
        let not_started = started.iter().filter(|&&s| !s).count();
        let total = (cells.len() - not_started).max(1) as f64;
        let fractions = attractors.iter().map(|a| a.cells as f64 / total).collect();
        let shape: Vec<usize> = self.sweep.grid.axes.iter().map(|a| a.n).collect();
        BasinRun {
            label: self.sweep.runs[run].clone(),
            metrics: basin_metrics(&labels, &started, &shape),
            undecided_fraction: (undecided.len() - not_started) as f64 / total,
            not_started,
            decided_at: cells.iter().map(|c| c.decided_at).collect(),
            labels,
            attractors,
            fractions,
            undecided,
            decided_by,
            largest_energy_margin: largest_margin,
            steps: cells.iter().map(|c| c.steps).sum(),
        }
    }

    /// A found equilibrium or periodic orbit that lies within a given attractor's reach (every
    /// point of it), as that attractor's outcome; any other outcome as it is.
    fn as_given<'o>(&self, outcome: &'o OrbitOutcome) -> std::borrow::Cow<'o, OrbitOutcome> {
        use std::borrow::Cow;
        let criteria = &self.criteria;
        let within = |points: &[Vec<f64>]| {
            criteria.given.iter().position(|g| {
                points.iter().all(|x| {
                    g.points
                        .iter()
                        .any(|y| x.len() == y.len() && criteria.near(x, y, g.radius))
                })
            })
        };
        let found = match outcome {
            OrbitOutcome::Cycle { points } if !criteria.given.is_empty() => within(points),
            OrbitOutcome::Equilibrium { point } if !criteria.given.is_empty() => {
                criteria.landscape.as_ref().and_then(|l| {
                    let q = &l.points[*point].q;
                    let state: Vec<f64> = q.iter().copied().chain(q.iter().map(|_| 0.0)).collect();
                    within(&[state])
                })
            }
            _ => None,
        };
        match found {
            Some(attractor) => Cow::Owned(OrbitOutcome::Given { attractor }),
            None => Cow::Borrowed(outcome),
        }
    }

    /// The table entry of a new outcome, after the `known` ones.
    fn attractor(&self, known: &[Attractor], outcome: &OrbitOutcome) -> Attractor {
        let label = known.len();
        let point = |i: usize| {
            self.criteria
                .landscape
                .as_ref()
                .map(|l| l.points[i].clone())
        };
        let (kind, name, equilibrium, points) = match outcome {
            OrbitOutcome::Equilibrium { point: i } => {
                let shape = match point(*i) {
                    Some(p) if !p.is_minimum() => "saddle",
                    _ => "minimum",
                };
                let name = format!("equilibrium {} ({shape})", i + 1);
                (AttractorKind::Equilibrium, name, point(*i), Vec::new())
            }
            OrbitOutcome::Well { point: i } => (
                AttractorKind::Well,
                format!("well {}", i + 1),
                point(*i),
                Vec::new(),
            ),
            OrbitOutcome::Exit { exit } => (
                AttractorKind::Exit,
                self.exit_names[*exit].clone(),
                None,
                Vec::new(),
            ),
            OrbitOutcome::Cycle { points } => {
                let same_period = known
                    .iter()
                    .filter(|a| a.period == Some(points.len()))
                    .count();
                let name = format!("period-{} orbit {}", points.len(), same_period + 1);
                (AttractorKind::Periodic, name, None, points.clone())
            }
            OrbitOutcome::Diverged => {
                (AttractorKind::Diverged, "diverged".into(), None, Vec::new())
            }
            _ => (AttractorKind::Stayed, "stayed".into(), None, Vec::new()),
        };
        Attractor {
            label: label as i64,
            kind,
            name,
            period: (kind == AttractorKind::Periodic).then_some(points.len()),
            equilibrium,
            points,
            radius: None,
            cells: 0,
            outcome: outcome.clone(),
        }
    }
}
