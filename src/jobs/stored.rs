//! The executor a job runs its study on: the study's cells in fixed parts, each taken from the
//! job's directory when it was finished before (by this server or by one that stopped), else
//! run on the service's executor once the part's turn comes ([`super::fair`]) and stored as soon
//! as it is whole. Parts that run on NATS workers go several at a time, so that a job keeps more
//! workers busy than one part's shards would. A cell's result depends only on the study and its index, so a job stopped and
//! taken up again gives its document bit for bit as if it had run through.

use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard, PoisonError};

use crate::core::error::CoreError;
use crate::core::run::Budget;
use crate::core::studies::engine::{Executor, Study};
use crate::executor::StudyExecutor;
use crate::store::jobs::JobDir;

/// What a part that ran tells its job.
pub trait PartSink: Sync {
    /// Waits for the turn of a part predicting `steps`, to run on this machine (`here`) or on
    /// workers elsewhere; `None` when the job is to stop.
    fn turn(&self, steps: u64, here: bool) -> Option<Box<dyn Send + '_>>;
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
    /// Parts run at once when they run on other machines (NATS workers).
    pub in_flight: usize,
    /// Its turns and progress.
    pub sink: &'a dyn PartSink,
}

/// `mutex` locked, whether or not a thread panicked while holding it.
fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(PoisonError::into_inner)
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

impl Stored<'_> {
    /// One part: read back when it was stored before, else run once its turn comes and stored
    /// when whole. Its cells' results, `None` where the part stopped short.
    fn part<S: Study>(
        &self,
        study: &S,
        part: Range<usize>,
        here: bool,
        budget: Budget<'_>,
        done: &(dyn Fn(usize, Option<&S::Cell>) + Sync),
    ) -> Result<Vec<Option<S::Cell>>, CoreError> {
        let stored = self
            .dir
            .read_part::<S::Cell>(&part)
            .filter(|cells| cells.iter().all(|c| study.fits(c)));
        if let Some(stored) = stored {
            for (cell, result) in part.clone().zip(&stored) {
                done(cell, Some(result));
            }
            self.sink.part_done(part, true);
            return Ok(stored.into_iter().map(Some).collect());
        }
        // Past the time limit no part takes a turn: the job ends with what it stored.
        let per_cell = study.steps() / study.cells().max(1) as u64;
        let turn = match budget.cancelled() || budget.expired() {
            true => None,
            false => self
                .sink
                .turn(per_cell.saturating_mul(part.len() as u64), here),
        };
        let Some(_turn) = turn else {
            self.sink.part_unfinished();
            return Ok(part.map(|_| None).collect());
        };
        let computed = self.inner.run(study, part.clone(), budget, done)?;
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
        Ok(computed)
    }
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
        let parts = parts(cells, self.part_cells);
        let done = |cell: usize, result: Option<&S::Cell>| {
            done(cell, result);
            if result.is_some() {
                self.sink.cell_done();
            }
        };
        // A part here takes every core, so parts here go one at a time; parts on other
        // machines go `in_flight` at a time, each on a thread that only waits for it.
        let here = !self.inner.distributes(study);
        let threads = match here {
            true => 1,
            false => self.in_flight.clamp(1, parts.len().max(1)),
        };
        let next = AtomicUsize::new(0);
        let results: Vec<Mutex<Option<Vec<Option<S::Cell>>>>> =
            parts.iter().map(|_| Mutex::new(None)).collect();
        let failure: Mutex<Option<CoreError>> = Mutex::new(None);
        let take_parts = || loop {
            if lock(&failure).is_some() {
                return;
            }
            let index = next.fetch_add(1, Ordering::Relaxed);
            let Some(part) = parts.get(index) else {
                return;
            };
            match self.part(study, part.clone(), here, budget, &done) {
                Ok(cells) => *lock(&results[index]) = Some(cells),
                Err(error) => {
                    lock(&failure).get_or_insert(error);
                    // The job fails with this error: the parts in flight beside it stop as a
                    // cancellation stops them (their shards taken out of the queue).
                    if let Some(stop) = budget.cancel {
                        stop.store(true, Ordering::Relaxed);
                    }
                }
            }
        };
        if threads == 1 {
            take_parts();
        } else {
            std::thread::scope(|scope| {
                for _ in 0..threads {
                    scope.spawn(take_parts);
                }
            });
        }
        if let Some(error) = failure.into_inner().unwrap_or_else(PoisonError::into_inner) {
            return Err(error);
        }
        // Every part was taken and answered (a failure returned above).
        Ok(results
            .into_iter()
            .flat_map(|r| {
                r.into_inner()
                    .unwrap_or_else(PoisonError::into_inner)
                    .unwrap_or_default()
            })
            .collect())
    }
}
