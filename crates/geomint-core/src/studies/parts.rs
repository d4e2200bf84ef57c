//! Shards of a study: shard i of n is a fixed range of cells, so a shard's result depends only
//! on the study's spec and (i, n), and any executor — this machine, an array job, NATS workers —
//! gives the same parts. A part carries the study's spec, so parts merge without the spec file;
//! [`merge`] puts them back together and refuses missing, duplicate and foreign ones.

use std::ops::Range;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::engine::{Executor, Local, Study};
use super::StudySpec;
use crate::error::CoreError;
use crate::run::Budget;
use crate::simulation::Limits;

/// The format tag of a part file.
pub const PART_FORMAT: &str = "geomint-study-part/2";

/// Most shards of one study.
pub const MAX_SHARDS: usize = 100_000;

/// Shard `index` of `count` (0 ≤ index < count).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// Which shard.
    pub index: usize,
    /// Of how many.
    pub count: usize,
}

/// Why a shard designation or a set of parts is refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ShardError {
    /// Not `i/n` with 0 ≤ i < n ≤ MAX_SHARDS.
    #[error("`{given}` is not a shard: give i/n with 0 ≤ i < n ≤ {MAX_SHARDS}, or `auto`")]
    NotAShard {
        /// What was given.
        given: String,
    },
    /// More shards than cells.
    #[error("{count} shards for {cells} cells: give at most one shard per cell")]
    MoreShardsThanCells {
        /// Shards asked for.
        count: usize,
        /// Cells of the sweep.
        cells: usize,
    },
    /// No parts at all.
    #[error("no parts to merge")]
    NoParts,
    /// A part of another study.
    #[error("{part}: belongs to another study (or is not a part of format {PART_FORMAT})")]
    Foreign {
        /// The part's name (its file).
        part: String,
    },
    /// A part that cannot be read.
    #[error("{part}: not a part: {reason}")]
    Unreadable {
        /// The part's name (its file).
        part: String,
        /// Why.
        reason: String,
    },
    /// A part split another way.
    #[error("{part}: shard {index} of {count}, but the other parts are shards of {expected}")]
    OtherSplit {
        /// The part's name.
        part: String,
        /// Its index.
        index: usize,
        /// Its count.
        count: usize,
        /// The others' count.
        expected: usize,
    },
    /// The same shard twice.
    #[error("{part}: shard {index} is also in {first}")]
    Duplicate {
        /// The part's name.
        part: String,
        /// The shard.
        index: usize,
        /// The part that had it first.
        first: String,
    },
    /// Shards missing.
    #[error("missing shards {missing:?} of {count}")]
    Missing {
        /// The missing indices.
        missing: Vec<usize>,
        /// Shards in all.
        count: usize,
    },
    /// A part whose contents do not fit its shard.
    #[error("{part}: {reason}")]
    Damaged {
        /// The part's name.
        part: String,
        /// What does not fit.
        reason: String,
    },
}

impl Shard {
    /// Reads `i/n`.
    pub fn parse(text: &str) -> Result<Shard, ShardError> {
        let bad = || ShardError::NotAShard {
            given: text.to_string(),
        };
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
        if !digits(i) || !digits(n) {
            return Err(bad());
        }
        let (index, count) = (i.parse().map_err(|_| bad())?, n.parse().map_err(|_| bad())?);
        if count == 0 || count > MAX_SHARDS || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    /// The shard's cells among `cells`.
    pub fn cells(&self, cells: usize) -> Result<Range<usize>, ShardError> {
        if self.count > cells {
            return Err(ShardError::MoreShardsThanCells {
                count: self.count,
                cells,
            });
        }
        let at = |i: usize| (i as u128 * cells as u128 / self.count as u128) as usize;
        Ok(at(self.index)..at(self.index + 1))
    }

    /// The shard's cells when the shards cut `within` (a range of the study's cells) rather than
    /// the whole study: the same slicing, counted from `within.start`.
    pub fn cells_within(&self, within: &Range<usize>) -> Result<Range<usize>, ShardError> {
        let slice = self.cells(within.len())?;
        Ok(within.start + slice.start..within.start + slice.end)
    }
}

/// The result of one shard: what a worker or an array task writes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Part<C> {
    /// [`PART_FORMAT`].
    pub format: String,
    /// The study's spec, so that parts merge without the spec file.
    pub spec: StudySpec,
    /// Which shard.
    pub shard: usize,
    /// Of how many.
    pub shards: usize,
    /// Its first cell.
    pub first_cell: usize,
    /// Every cell of the shard, in order.
    pub cells: Vec<C>,
    /// Wall time of the shard in milliseconds.
    pub wall_ms: f64,
}

/// Runs shard `shard` of `study` (whose spec is `spec`) on this machine's cores to the end.
pub fn run_shard<S: Study>(
    study: &S,
    spec: StudySpec,
    shard: Shard,
    done: &(dyn Fn(usize, Option<&S::Cell>) + Sync),
) -> Result<Part<S::Cell>, CoreError> {
    run_shard_within(study, spec, shard, 0..study.cells(), done)
}

/// Runs shard `shard` of the cells `within` of `study` (a job's part cut again into shards for
/// workers) on this machine's cores to the end. The part's `first_cell` counts from the study's
/// first cell.
pub fn run_shard_within<S: Study>(
    study: &S,
    spec: StudySpec,
    shard: Shard,
    within: Range<usize>,
    done: &(dyn Fn(usize, Option<&S::Cell>) + Sync),
) -> Result<Part<S::Cell>, CoreError> {
    let executor = |message: String| CoreError::Executor { message };
    if within.is_empty() || within.end > study.cells() {
        return Err(executor(format!(
            "cells {}..{} are not a range of the study's {} cells",
            within.start,
            within.end,
            study.cells()
        )));
    }
    let cells = shard
        .cells_within(&within)
        .map_err(|e| executor(e.to_string()))?;
    let started = Instant::now();
    let first_cell = cells.start;
    let results = Local.run(study, cells, Budget::default(), done)?;
    let cells = results
        .into_iter()
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| CoreError::Executor {
            message: "a shard without a time limit stopped before its end".into(),
        })?;
    Ok(Part {
        format: PART_FORMAT.into(),
        spec,
        shard: shard.index,
        shards: shard.count,
        first_cell,
        cells,
        wall_ms: started.elapsed().as_secs_f64() * 1e3,
    })
}

pub use super::AnyPart;

/// A study's spec as it travels: how a worker or an array task prepares the study and runs a
/// shard of it. Implemented beside each study; its line in `travelling_studies!` (in
/// [`super`]) makes it a [`StudySpec`] and an [`AnyPart`].
pub trait Travelling {
    /// One cell's result.
    type Cell: Clone + Send + Serialize + serde::de::DeserializeOwned;

    /// Prepares the study within `limits` and runs the shard `at` here, to the end (a settings
    /// study computes its truth first: the same bits as wherever else it is computed).
    fn run_shard(&self, at: &ShardAt<'_>, limits: &Limits) -> Result<Part<Self::Cell>, CoreError>;
}

/// Which shard of a study to run, and where to report its cells.
pub struct ShardAt<'a> {
    /// The study's spec as it travels (the part carries it).
    pub spec: &'a StudySpec,
    /// Which shard.
    pub shard: Shard,
    /// The cells the shards cut (a job's part), or all of the study's.
    pub within: Option<Range<usize>>,
    /// Called as each cell is done.
    pub done: &'a (dyn Fn() + Sync),
}

impl ShardAt<'_> {
    /// The shard of the prepared `study` run here: what every [`Travelling::run_shard`] ends
    /// with.
    pub fn run<S: Study>(&self, study: &S) -> Result<Part<S::Cell>, CoreError> {
        let cells = self.within.clone().unwrap_or(0..study.cells());
        let done = self.done;
        run_shard_within(study, self.spec.clone(), self.shard, cells, &|_, _| done())
    }
}

/// Prepares the study `spec` within `limits` and runs its shard `shard` here, to the end: what a
/// worker or an array task does. The shards cut the cells `within` (a job's part), or the whole
/// study when that is `None`.
pub fn run_part(
    spec: &StudySpec,
    shard: Shard,
    within: Option<Range<usize>>,
    limits: &Limits,
    done: &(dyn Fn() + Sync),
) -> Result<AnyPart, CoreError> {
    spec.run_part(shard, within, limits, done)
}

/// Puts the parts (each with a name for messages, e.g. its file) of `study`, whose spec is
/// `spec`, back together: every shard of one split exactly once, all of this study, each cell a
/// result the study can take. Returns every cell's result in order and the summed wall time of
/// the parts.
pub fn merge<S: Study>(
    study: &S,
    spec: &StudySpec,
    parts: Vec<(String, Part<S::Cell>)>,
) -> Result<(Vec<S::Cell>, f64), ShardError> {
    let cells = study.cells();
    let (first_name, first) = parts.first().ok_or(ShardError::NoParts)?;
    let count = first.shards;
    if count == 0 || count > cells.min(MAX_SHARDS) {
        return Err(ShardError::Damaged {
            part: first_name.clone(),
            reason: format!("says it is one of {count} shards of {cells} cells"),
        });
    }
    let mut slots: Vec<Option<(String, Part<S::Cell>)>> = Vec::new();
    slots.resize_with(count, || None);
    for (name, part) in parts {
        if part.format != PART_FORMAT || &part.spec != spec {
            return Err(ShardError::Foreign { part: name });
        }
        if part.shards != count || part.shard >= count {
            return Err(ShardError::OtherSplit {
                part: name,
                index: part.shard,
                count: part.shards,
                expected: count,
            });
        }
        let shard = Shard {
            index: part.shard,
            count,
        };
        let range = shard.cells(cells)?;
        if part.first_cell != range.start || part.cells.len() != range.len() {
            return Err(ShardError::Damaged {
                reason: format!(
                    "holds cells {}..{}, shard {} of {count} is cells {}..{}",
                    part.first_cell,
                    part.first_cell + part.cells.len(),
                    part.shard,
                    range.start,
                    range.end
                ),
                part: name,
            });
        }
        if !part.cells.iter().all(|cell| study.fits(cell)) {
            return Err(ShardError::Damaged {
                part: name,
                reason: "its cells are not the study's (other runs or settings)".into(),
            });
        }
        if let Some((first, _)) = &slots[part.shard] {
            return Err(ShardError::Duplicate {
                part: name,
                index: part.shard,
                first: first.clone(),
            });
        }
        let index = part.shard;
        slots[index] = Some((name, part));
    }
    let missing: Vec<usize> = slots
        .iter()
        .enumerate()
        .filter_map(|(i, s)| s.is_none().then_some(i))
        .collect();
    if !missing.is_empty() {
        return Err(ShardError::Missing { missing, count });
    }
    let mut all = Vec::with_capacity(cells);
    let mut wall_ms = 0.0;
    for (_, part) in slots.into_iter().flatten() {
        wall_ms += part.wall_ms;
        all.extend(part.cells);
    }
    Ok((all, wall_ms))
}
