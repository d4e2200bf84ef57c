//! The executor a job runs its study on: the study's cells in fixed parts, each taken from the
//! job's directory when it was finished before (by this server or by one that stopped), else
//! run on the service's executor once the part's turn comes ([`super::fair`]) and stored as soon
//! as it is whole. A cell's result depends only on the study and its index, so a job stopped and
//! taken up again gives its document bit for bit as if it had run through.

use std::ops::Range;

use crate::core::error::CoreError;
use crate::core::run::Budget;
use crate::core::studies::engine::{Executor, Study};
use crate::executor::StudyExecutor;
use crate::store::jobs::JobDir;

/// What a part that ran tells its job.
pub trait PartSink: Sync {
    /// Waits for the turn of a part predicting `steps`; `None` when the job is to stop.
    fn turn(&self, steps: u64) -> Option<Box<dyn Send + '_>>;
    /// A cell was computed or read back.
    fn cell_done(&self);
    /// `cells` were taken from disk (`stored`) or computed and stored.
    fn part_done(&self, cells: Range<usize>, stored: bool);
    /// A part stopped before its end (the budget ran out) and was not stored.
    fn part_unfinished(&self);
    /// A finished part (`cells`) could not be stored: the job fails with this reason.
    fn not_stored(&self, cells: Range<usize>, error: &std::io::Error);
}

/// A job's study executor.
pub struct Stored<'a> {
    /// The job's directory.
    pub dir: &'a JobDir,
    /// Where its parts run.
    pub inner: &'a StudyExecutor,
    /// Cells per part.
    pub part_cells: usize,
    /// Its turns and progress.
    pub sink: &'a dyn PartSink,
}

/// The parts of `cells`, each `size` cells counted from cell 0 (so that a range that starts at
/// a part's boundary, as the engine's whole range does, cuts the same parts every time).
pub fn parts(cells: Range<usize>, size: usize) -> Vec<Range<usize>> {
    let size = size.max(1);
    let mut out = Vec::new();
    let mut start = cells.start;
    while start < cells.end {
        let end = ((start / size + 1) * size).min(cells.end);
        out.push(start..end);
        start = end;
    }
    out
}

impl Executor for Stored<'_> {
    fn run<S: Study>(
        &self,
        study: &S,
        cells: Range<usize>,
        budget: Budget<'_>,
        done: &(dyn Fn(usize, Option<&S::Cell>) + Sync),
    ) -> Result<Vec<Option<S::Cell>>, CoreError> {
        // The job's parts hold whole groups already (see `Jobs::submit`); a study whose group
        // would not divide them still runs, in part-sized ranges.
        let size = self.part_cells;
        let per_cell = study.steps() / study.cells().max(1) as u64;
        let done = |cell: usize, result: Option<&S::Cell>| {
            done(cell, result);
            if result.is_some() {
                self.sink.cell_done();
            }
        };
        let mut results = Vec::with_capacity(cells.len());
        for part in parts(cells, size) {
            let stored = self
                .dir
                .read_part::<S::Cell>(&part)
                .filter(|cells| cells.iter().all(|c| study.fits(c)));
            if let Some(stored) = stored {
                for (cell, result) in part.clone().zip(&stored) {
                    done(cell, Some(result));
                }
                results.extend(stored.into_iter().map(Some));
                self.sink.part_done(part, true);
                continue;
            }
            // Past the time limit no part takes a turn: the job ends with what it stored.
            let turn = match budget.cancelled() || budget.expired() {
                true => None,
                false => self.sink.turn(per_cell.saturating_mul(part.len() as u64)),
            };
            let Some(_turn) = turn else {
                self.sink.part_unfinished();
                results.extend(part.map(|_| None));
                continue;
            };
            let computed = self.inner.run(study, part.clone(), budget, &done)?;
            if let Some(whole) = computed
                .iter()
                .map(Option::as_ref)
                .collect::<Option<Vec<_>>>()
            {
                if let Err(error) = self.dir.write_part(part.start, &whole) {
                    self.sink.not_stored(part.clone(), &error);
                    return Err(CoreError::Executor {
                        message: format!("a finished part could not be stored: {error}"),
                    });
                }
                self.sink.part_done(part, false);
            } else {
                self.sink.part_unfinished();
            }
            results.extend(computed);
        }
        Ok(results)
    }
}
