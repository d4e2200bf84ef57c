//! Parts merged back into their study: an [`Executor`] whose cells come from the part files of
//! a study cut into shards (`geomint study KIND --shard i/n`), so that `geomint study merge`
//! makes every kind's document through the kind's own run, as the whole study makes it.

use std::ops::Range;
use std::sync::Mutex;

use crate::core::error::CoreError;
use crate::core::run::Budget;
use crate::core::studies::engine::{Executor, Study};
use crate::core::studies::parts::{self, Part, ShardError};
use crate::core::studies::StudySpec;

/// A part as read so far: its name for messages (its file), the spec of its study, its JSON.
pub struct PartText {
    /// Its name for messages.
    pub name: String,
    /// The spec of the study it is a part of.
    pub spec: StudySpec,
    /// Its JSON text.
    pub text: Vec<u8>,
}

/// The parts of one study.
pub struct Merged {
    parts: Vec<PartText>,
    wall_ms: f64,
    refused: Mutex<Option<ShardError>>,
}

impl Merged {
    /// The parts `parts`, whose wall times add up to `wall_ms` (milliseconds).
    pub fn new(parts: Vec<PartText>, wall_ms: f64) -> Merged {
        Merged {
            parts,
            wall_ms,
            refused: Mutex::new(None),
        }
    }

    /// Why the parts were refused, if they were: missing, duplicate, foreign or damaged parts
    /// (the run fails with the same words).
    pub fn refused(&self) -> Option<ShardError> {
        self.refused
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take()
    }

    /// Fails the run with `error`, kept for [`Merged::refused`].
    fn refuse(&self, error: ShardError) -> CoreError {
        let message = error.to_string();
        *self.refused.lock().unwrap_or_else(|e| e.into_inner()) = Some(error);
        CoreError::Executor { message }
    }
}

impl Executor for Merged {
    fn run<S: Study>(
        &self,
        study: &S,
        cells: Range<usize>,
        _budget: Budget<'_>,
        done: &(dyn Fn(usize, Option<&S::Cell>) + Sync),
    ) -> Result<Vec<Option<S::Cell>>, CoreError> {
        let executor = |message: String| CoreError::Executor { message };
        if cells != (0..study.cells()) {
            return Err(executor(format!(
                "parts merge into the whole {}, not into its cells {}..{}",
                study.name(),
                cells.start,
                cells.end
            )));
        }
        let spec = study
            .spec()
            .ok_or_else(|| executor(format!("the {} is not cut into parts", study.name())))?;
        let mut read = Vec::with_capacity(self.parts.len());
        for PartText {
            name,
            spec: of,
            text,
        } in &self.parts
        {
            // A part of another study is refused as such, before its cells are read as this
            // study's.
            if *of != spec {
                return Err(self.refuse(ShardError::Foreign { part: name.clone() }));
            }
            match serde_json::from_slice::<Part<S::Cell>>(text) {
                Ok(part) => read.push((name.clone(), part)),
                Err(e) => {
                    return Err(self.refuse(ShardError::Unreadable {
                        part: name.clone(),
                        reason: e.to_string(),
                    }))
                }
            }
        }
        let (merged, _) = parts::merge(study, &spec, read).map_err(|e| self.refuse(e))?;
        for (cell, result) in merged.iter().enumerate() {
            done(cell, Some(result));
        }
        Ok(merged.into_iter().map(Some).collect())
    }

    fn wall_ms(&self) -> Option<f64> {
        Some(self.wall_ms)
    }
}
