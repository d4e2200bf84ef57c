//! Shards of a sweep: shard i of n is a fixed range of cells, so a shard's result depends only
//! on the spec and (i, n), and any executor — this machine, an array job, NATS workers — gives
//! the same parts. [`merge`] puts parts back together and refuses missing, duplicate and foreign
//! ones.

use std::ops::Range;

use serde::{Deserialize, Serialize};

use super::{RunLabel, RunMetrics, SweepJob};

/// The format tag of a part file.
pub const PART_FORMAT: &str = "geomint-sweep-part/1";

/// Most shards of one sweep.
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
    /// A part of another sweep.
    #[error("{part}: belongs to another sweep (digest {found}, expected {expected})")]
    Foreign {
        /// The part's name (its file).
        part: String,
        /// Its digest.
        found: String,
        /// The digest of the others (or of the spec).
        expected: String,
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
}

/// The result of one shard: what a worker or an array task writes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SweepPart {
    /// [`PART_FORMAT`].
    pub format: String,
    /// The sweep's digest.
    pub digest: String,
    /// The sweep's request (canonical JSON), so that parts merge without the spec file.
    pub request: serde_json::Value,
    /// Which shard.
    pub shard: usize,
    /// Of how many.
    pub shards: usize,
    /// Its first cell.
    pub first_cell: usize,
    /// The runs of every cell, as [`SweepJob::runs`] orders them.
    pub runs: Vec<RunLabel>,
    /// Per cell of the shard, in order, the metrics of each run.
    pub cells: Vec<Vec<RunMetrics>>,
    /// Wall time of the shard in milliseconds.
    pub wall_ms: f64,
}

impl SweepPart {
    /// A part of `job`, asked for by `request`.
    pub fn new(
        job: &SweepJob,
        request: serde_json::Value,
        shard: Shard,
        cells: Vec<Vec<RunMetrics>>,
        wall_ms: f64,
    ) -> Self {
        let first_cell = shard.cells(job.cells()).map(|r| r.start).unwrap_or(0);
        SweepPart {
            format: PART_FORMAT.into(),
            digest: job.digest.clone(),
            request,
            shard: shard.index,
            shards: shard.count,
            first_cell,
            runs: job.runs.clone(),
            cells,
            wall_ms,
        }
    }
}

/// Puts the parts (each with a name for messages, e.g. its file) of `job` back together: every
/// shard of one split exactly once, all of this sweep. Returns every cell's results in order and
/// the summed wall time of the parts.
pub fn merge(
    job: &SweepJob,
    parts: Vec<(String, SweepPart)>,
) -> Result<(Vec<Vec<RunMetrics>>, f64), ShardError> {
    let (first_name, first) = parts.first().ok_or(ShardError::NoParts)?;
    let count = first.shards;
    if count == 0 || count > job.cells().min(MAX_SHARDS) {
        return Err(ShardError::Damaged {
            part: first_name.clone(),
            reason: format!("says it is one of {count} shards of {} cells", job.cells()),
        });
    }
    let mut slots: Vec<Option<(String, SweepPart)>> = Vec::new();
    slots.resize_with(count, || None);
    for (name, part) in parts {
        if part.digest != job.digest || part.format != PART_FORMAT {
            return Err(ShardError::Foreign {
                part: name,
                found: part.digest,
                expected: job.digest.clone(),
            });
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
        let range = shard.cells(job.cells())?;
        let damaged = |reason: String| ShardError::Damaged {
            part: name.clone(),
            reason,
        };
        if part.first_cell != range.start || part.cells.len() != range.len() {
            return Err(damaged(format!(
                "holds cells {}..{}, shard {} of {count} is cells {}..{}",
                part.first_cell,
                part.first_cell + part.cells.len(),
                part.shard,
                range.start,
                range.end
            )));
        }
        if part.runs != job.runs || part.cells.iter().any(|c| c.len() != job.runs.len()) {
            return Err(damaged(
                "its runs are not the sweep's methods and charts".into(),
            ));
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
    let mut cells = Vec::with_capacity(job.cells());
    let mut wall_ms = 0.0;
    for (_, part) in slots.into_iter().flatten() {
        wall_ms += part.wall_ms;
        cells.extend(part.cells);
    }
    Ok((cells, wall_ms))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_cover_the_cells_once_in_order() {
        for (cells, count) in [(1, 1), (10, 3), (10201, 7), (7, 7)] {
            let mut next = 0;
            for index in 0..count {
                let range = Shard { index, count }.cells(cells).unwrap();
                assert_eq!(range.start, next);
                assert!(range.len() >= cells / count && range.len() <= cells / count + 1);
                next = range.end;
            }
            assert_eq!(next, cells);
        }
        assert!(Shard { index: 0, count: 8 }.cells(7).is_err());
    }

    #[test]
    fn shard_designations_are_read_strictly() {
        assert_eq!(Shard::parse("2/5"), Ok(Shard { index: 2, count: 5 }));
        for bad in [
            "5/5",
            "0/0",
            "-1/3",
            "1/",
            "/3",
            "1/3/4",
            "a/3",
            " 1/3",
            "1/1000001",
        ] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
    }
}
