//! Where the service runs its studies, chosen once at start-up: this machine's cores, or the
//! workers of a NATS JetStream queue (`geomint serve --nats URL`). Both are executors of the
//! core's study engine, so every study's document is the same bit for bit wherever its cells
//! ran.

use std::ops::Range;
use std::sync::Arc;

use crate::core::error::CoreError;
use crate::core::run::Budget;
use crate::core::studies::engine::{Executor, Local, Order, Study};
use crate::nats::Queue;

/// The number of cores: how many runs at once by default, on the server and the command line.
pub fn cores() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
}

/// The service's executor.
#[derive(Clone, Debug, Default)]
pub enum StudyExecutor {
    /// Every core of this machine.
    #[default]
    Local,
    /// The workers of a NATS queue (timed studies stay here).
    Nats(Arc<Queue>),
}

impl StudyExecutor {
    /// Whether `study`'s cells leave this machine, so that it holds one slot here while it
    /// waits, rather than every free one.
    pub fn distributes<S: Study>(&self, study: &S) -> bool {
        matches!(self, StudyExecutor::Nats(_))
            && study.order() == Order::Parallel
            && study.spec().is_some()
    }

    /// The NATS queue, if studies go to workers.
    pub fn queue(&self) -> Option<&Queue> {
        match self {
            StudyExecutor::Local => None,
            StudyExecutor::Nats(queue) => Some(queue),
        }
    }
}

impl Executor for StudyExecutor {
    fn run<S: Study>(
        &self,
        study: &S,
        cells: Range<usize>,
        budget: Budget<'_>,
        done: &(dyn Fn(usize, Option<&S::Cell>) + Sync),
    ) -> Result<Vec<Option<S::Cell>>, CoreError> {
        match self {
            StudyExecutor::Local => Local.run(study, cells, budget, done),
            StudyExecutor::Nats(queue) => queue.run(study, cells, budget, done),
        }
    }
}
