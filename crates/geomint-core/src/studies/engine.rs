//! The study engine: every study is a fixed list of independent cells — a sweep's grid points,
//! a stability map's rows, a convergence or work–precision study's settings — each reduced to a
//! result that depends only on the study and the cell's index. Where the cells run is an
//! [`Executor`]'s business: [`Local`] runs them on this machine's cores (or one at a time, in
//! order, for a study whose timings must compare), a shard runs a fixed range of them
//! ([`super::parts`]), and the service's NATS executor hands shards to workers. Whichever ran
//! them, the study's document is the same bit for bit.
//!
//! Written once here: the walk over the cells (in groups for studies that run several cells side
//! by side in SIMD lanes), progress, cancellation (an error), and a time limit (the cells that
//! did not finish are `None`, and the study answers with the others, marked
//! [`StudyCompletion::TimeLimit`]). A cell looks at the budget itself — a run inside it stops between
//! steps — and answers `None` when the budget stopped it.

use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use rayon::prelude::*;
use serde::de::DeserializeOwned;
use serde::Serialize;

use super::{StudyCompletion, StudySpec};
use crate::error::{CoreError, ErrorDetail};
use crate::run::Budget;

/// How a study's cells may run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    /// In parallel, in any order.
    Parallel,
    /// One at a time, in order, on one machine: the cells are timed, and their wall times
    /// compare only when nothing else runs beside them (work–precision).
    Timed,
}

/// A study as the engine runs it.
pub trait Study: Sync {
    /// One cell's result: serialisable, so that a worker can send it back and an array task
    /// write it into a part, and read back bit for bit.
    type Cell: Clone + Send + Serialize + DeserializeOwned;

    /// What the study is called in messages (`sweep`, `stability maps`).
    fn name(&self) -> &'static str;

    /// Cells in all.
    fn cells(&self) -> usize;

    /// How the cells may run.
    fn order(&self) -> Order {
        Order::Parallel
    }

    /// Cells that run together: the engine hands [`Study::run_cells`] consecutive cells in
    /// groups of this many, counted from the start of the range (a study whose cells run in SIMD
    /// lanes gives the lane count).
    fn group(&self) -> usize {
        1
    }

    /// Runs consecutive `cells` (at most [`Study::group`] of them); `None` for a cell the
    /// budget stopped. An error fails the whole study.
    fn run_cells(
        &self,
        cells: Range<usize>,
        budget: Budget<'_>,
    ) -> Result<Vec<Option<Self::Cell>>, CoreError>;

    /// Whether `cell` (read from a part) has the shape of this study's cells.
    fn fits(&self, _cell: &Self::Cell) -> bool {
        true
    }

    /// The spec a worker prepares the same study from, when the study may run elsewhere.
    fn spec(&self) -> Option<StudySpec>;

    /// About how many steps the whole study takes (executors size shards by it).
    fn steps(&self) -> u64;
}

/// Where a study's cells run.
pub trait Executor {
    /// Runs `cells` of `study` and returns their results in cell order; `done(cell, result)` is
    /// called as each finishes (from any thread, in any order unless the study is
    /// [`Order::Timed`]).
    fn run<S: Study>(
        &self,
        study: &S,
        cells: Range<usize>,
        budget: Budget<'_>,
        done: &(dyn Fn(usize, Option<&S::Cell>) + Sync),
    ) -> Result<Vec<Option<S::Cell>>, CoreError>;

    /// The wall time, in milliseconds, of the cells it hands back, when it knows it better than
    /// the time [`run`] measures around it: cells computed elsewhere and merged here from their
    /// parts took the sum of the parts' wall times.
    fn wall_ms(&self) -> Option<f64> {
        None
    }
}

/// This machine: every core, through rayon's pool (a timed study's cells one after another).
#[derive(Clone, Copy, Debug, Default)]
pub struct Local;

impl Executor for Local {
    fn run<S: Study>(
        &self,
        study: &S,
        cells: Range<usize>,
        budget: Budget<'_>,
        done: &(dyn Fn(usize, Option<&S::Cell>) + Sync),
    ) -> Result<Vec<Option<S::Cell>>, CoreError> {
        let group = study.group().max(1);
        // Groups from the start of the range, so that a shard runs its cells as the whole study
        // would up to the group boundaries (a cell's numbers do not depend on its neighbours
        // either way).
        let groups: Vec<Range<usize>> = cells
            .clone()
            .step_by(group)
            .map(|first| first..(first + group).min(cells.end))
            .collect();
        let run_group = |range: Range<usize>| -> Result<Vec<Option<S::Cell>>, CoreError> {
            let results = study.run_cells(range.clone(), budget)?;
            for (cell, result) in range.zip(&results) {
                done(cell, result.as_ref());
            }
            Ok(results)
        };
        let results: Vec<Vec<Option<S::Cell>>> = match study.order() {
            Order::Parallel => groups
                .into_par_iter()
                .map(run_group)
                .collect::<Result<_, _>>()?,
            Order::Timed => groups
                .into_iter()
                .map(run_group)
                .collect::<Result<_, _>>()?,
        };
        Ok(results.into_iter().flatten().collect())
    }
}

/// What a study's cells came to.
#[derive(Clone, Debug, PartialEq)]
pub struct Finished<C> {
    /// Every cell's result in order; `None` where the time limit stopped it.
    pub cells: Vec<Option<C>>,
    /// Whether every cell finished.
    pub stop: StudyCompletion,
    /// Wall time in milliseconds.
    pub wall_ms: f64,
}

impl<C> Finished<C> {
    /// The cells the time limit stopped, in order.
    pub fn unfinished(&self) -> Vec<usize> {
        (0..self.cells.len())
            .filter(|&i| self.cells[i].is_none())
            .collect()
    }
}

/// Runs every cell of `study` on `executor`. A study its cancellation flag stopped is an error;
/// one the deadline stopped answers with the cells that finished.
pub fn run<S: Study, E: Executor + ?Sized>(
    study: &S,
    executor: &E,
    budget: Budget<'_>,
    done: &(dyn Fn(usize, Option<&S::Cell>) + Sync),
) -> Result<Finished<S::Cell>, CoreError> {
    let started = Instant::now();
    let cells = executor.run(study, 0..study.cells(), budget, done)?;
    let finished = Finished {
        stop: if cells.iter().all(Option::is_some) {
            StudyCompletion::Finished
        } else {
            StudyCompletion::TimeLimit
        },
        cells,
        wall_ms: executor
            .wall_ms()
            .unwrap_or_else(|| started.elapsed().as_secs_f64() * 1e3),
    };
    if finished.stop == StudyCompletion::TimeLimit && budget.cancelled() {
        return Err(CoreError::Cancelled {
            what: study.name(),
            shutdown: true,
        });
    }
    Ok(finished)
}

/// Counts finished cells and reports the count about every 1 % of `total`, never going
/// backwards although cells finish on several threads (and in lanes, several at a time).
pub struct Progress<'a> {
    total: usize,
    every: usize,
    done: AtomicUsize,
    last_sent: Mutex<usize>,
    report: &'a (dyn Fn(usize, usize) + Sync),
}

impl<'a> Progress<'a> {
    /// Progress over `total` cells, reported as `report(done, total)`.
    pub fn new(total: usize, report: &'a (dyn Fn(usize, usize) + Sync)) -> Self {
        Progress {
            total,
            every: (total / 100).max(1),
            done: AtomicUsize::new(0),
            last_sent: Mutex::new(0),
            report,
        }
    }

    /// `cells` more cells are done.
    pub fn add(&self, cells: usize) {
        let before = self.done.fetch_add(cells, Ordering::Relaxed);
        let done = before + cells;
        if done / self.every != before / self.every || done == self.total {
            let mut last = self.last_sent.lock().unwrap_or_else(|e| e.into_inner());
            if done > *last {
                *last = done;
                (self.report)(done, self.total);
            }
        }
    }
}

/// The lines of the progress stream of a study whose document is made from its cells alone
/// (sweeps, basin maps): progress, the result, an error, the end.
pub trait CellLine: Serialize + Send + 'static {
    /// The study's document.
    type Document: Serialize + Send + 'static;
    /// Cells done so far.
    fn progress(done: usize, total: usize) -> Self;
    /// The document.
    fn result(document: Self::Document) -> Self;
    /// A failure.
    fn error(error: ErrorDetail) -> Self;
    /// The last line of a complete stream.
    fn end() -> Self;
}

/// A study whose document is made from what its cells came to: the route, the command-line
/// verb, its shards and their merge are the same for every such study.
pub trait Documented: Study {
    /// Its progress lines.
    type Line: CellLine;
    /// The document of the study from its cells (the unfinished ones marked so).
    fn document_of(&self, finished: Finished<Self::Cell>) -> <Self::Line as CellLine>::Document;
}

/// The document of `study` from the cells of its merged parts (every cell finished).
pub fn document_of_parts<S: Documented>(
    study: &S,
    cells: Vec<S::Cell>,
    wall_ms: f64,
) -> <S::Line as CellLine>::Document {
    study.document_of(Finished {
        cells: cells.into_iter().map(Some).collect(),
        stop: StudyCompletion::Finished,
        wall_ms,
    })
}

/// Runs every cell of `study` on `executor`, reporting progress (about every 1 %) through
/// `emit`, to its document.
pub fn run_documented<S: Documented, E: Executor + ?Sized>(
    study: &S,
    executor: &E,
    budget: Budget<'_>,
    emit: &(dyn Fn(S::Line) -> bool + Sync),
) -> Result<<S::Line as CellLine>::Document, CoreError> {
    let report = |done, total| {
        emit(S::Line::progress(done, total));
    };
    let progress = Progress::new(study.cells(), &report);
    let finished = run(study, executor, budget, &|_, _| progress.add(1))?;
    Ok(study.document_of(finished))
}
