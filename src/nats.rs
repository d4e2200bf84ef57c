//! Studies on many machines through a NATS JetStream work queue: the executor
//! ([`Executor`]) of `geomint serve --nats URL`.
//!
//! The server puts a study's shards ([`Task`]s: the study's spec and a shard of its cells) on
//! the work-queue stream [`STREAM`] under `geomint.sweep.shards.<study>`; any number of
//! `geomint worker --nats URL` processes pull them one at a time through the durable consumer
//! [`CONSUMER`], run the shard on all their cores (the core's [`parts::run_part`], the same
//! cells as the local executor's) and publish the part to `geomint.sweep.parts.<study>`, then
//! acknowledge the task. The server merges the parts as they arrive ([`parts::merge`]), so the
//! document equals the local one bit for bit. Sweeps and energy maps, stability maps and
//! convergence studies run here; work–precision studies, whose timings compare only on one
//! machine, run on the server.
//!
//! - A job's part ([`crate::jobs`]) goes out the same way, cut into shards of its own cells
//!   ([`Task::cells`]), so that a job's parts run on the workers, not on the server.
//! - A worker that dies mid-shard never acknowledges it: JetStream hands the shard out again
//!   once the consumer's ack wait passes. While a shard runs, its worker reports progress every
//!   third of the ack wait, to JetStream (so a long shard is not handed out twice) and to the
//!   study's server ([`Reply::Progress`]).
//! - A shard that arrives twice (redelivered after a slow worker finished it after all) counts
//!   once.
//! - A study that its client cancels, or that passes its time limit, has the shards it still
//!   waits for taken out of the stream ([`withdraw`]): no worker starts them.
//! - A JetStream cluster: `--nats` may list several of its servers, and `--nats-replicas 3`
//!   keeps three copies of the stream, so that the queue outlives one server. Shards are queued
//!   under message ids that JetStream deduplicates, and tried again while the cluster elects a
//!   new leader ([`ENQUEUE_PATIENCE`]).
//! - A part is a plain NATS message, which a move to another server of the cluster can lose: a
//!   shard acknowledged by its worker (gone from the stream) whose part has not come after an
//!   ack wait of silence, twice in a row, is queued again.
//! - A lost NATS server fails the study after [`DISCONNECTED_GRACE`] with a clear error rather
//!   than waiting for the time limit.
//! - A poison shard (one that panics or kills its worker) is delivered at most `max_deliver`
//!   times, then fails its study ([`poison`]). A shard whose deliveries were spent by workers
//!   that were stopped or starved of CPU, not dead, is waited for as long as one of them still
//!   reports progress on it ([`Queue::exhausted_grace`]).
//! - Connections take NATS credentials and TLS ([`options`]).
//! - The server's jobs are kept in a JetStream object store too ([`jobs_bucket`]), so that a
//!   server that loses its disk takes them back.

pub mod jobs_bucket;
pub mod options;
pub mod poison;
pub mod worker;

pub use worker::work;

use std::collections::{HashMap, HashSet};
use std::ops::Range;
use std::time::{Duration, Instant};

use async_nats::jetstream::{self, consumer::pull, stream, stream::DeleteMessageErrorKind};
use futures_util::StreamExt;
use serde::{Deserialize, Serialize};

use crate::core::error::CoreError;
use crate::core::run::Budget;
use crate::core::studies::engine::{Executor, Local, Order, Study};
use crate::core::studies::parts::{self, Part, Shard};
use crate::core::studies::StudySpec;

/// The work-queue stream of shards.
pub const STREAM: &str = "GEOMINT_SWEEP_SHARDS";
/// The durable pull consumer that every worker shares.
pub const CONSUMER: &str = "geomint-workers";
/// Subject prefix of tasks (`.<study>` follows).
const TASKS: &str = "geomint.sweep.shards";
/// Subject prefix of results (`.<study>` follows).
const PARTS: &str = "geomint.sweep.parts";
/// How long the server tolerates a lost connection before failing a study.
pub const DISCONNECTED_GRACE: Duration = Duration::from_secs(5);
/// The default ack wait: a shard not acknowledged (nor reported in progress) this long after it
/// was handed out goes to another worker.
pub const DEFAULT_ACK_WAIT: Duration = Duration::from_secs(30);
/// Work per shard the server aims at by default (about a second of one core at ~50 ns per
/// step), so that shards balance over workers and a lost one costs little.
pub const DEFAULT_STEPS_PER_SHARD: u64 = 20_000_000;
/// The size a part should stay under (NATS refuses messages over its max_payload, 1 MiB by
/// default).
const PART_BYTES: usize = 512 * 1024;

/// One shard of a study, as a worker receives it.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Task {
    /// The study's id (the subject its parts go to).
    pub study: String,
    /// The study's spec (a stored system inlined: workers keep no store).
    pub spec: StudySpec,
    /// Which shard.
    pub shard: usize,
    /// Of how many.
    pub shards: usize,
    /// The cells the shards cut (a job's part), when not the whole study.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cells: Option<Range<usize>>,
}

/// What a worker publishes for a task; `P` is the part (read as the kind of study the server
/// asked for).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Reply<P> {
    /// The shard's part.
    Part(Box<P>),
    /// The shard cannot be run (the worker says why).
    Failed {
        /// Which shard.
        shard: usize,
        /// Why.
        message: String,
    },
    /// A worker is running the shard and has finished `cells` of its cells: sent every third
    /// of the ack wait, so that the server can tell a slow shard from a lost one.
    Progress {
        /// Which shard.
        shard: usize,
        /// Its cells finished so far.
        cells: usize,
    },
}

/// A connection to the NATS server with the stream and consumer in place.
#[derive(Clone, Debug)]
pub struct Queue {
    client: async_nats::Client,
    jetstream: jetstream::Context,
    stream: stream::Stream,
    url: String,
    /// The runtime the connection lives on: studies block on it from threads of their own (a
    /// request's blocking thread, a job's thread).
    runtime: tokio::runtime::Handle,
    /// The workers' consumer's ack wait, as the NATS server has it.
    ack_wait: Duration,
    /// The workers' consumer's deliveries of a shard before it is given up.
    max_deliver: i64,
    /// Steps per shard the server aims at.
    pub steps_per_shard: u64,
    /// Copies of the streams this process creates.
    replicas: usize,
    /// Where the server keeps its jobs' files besides its disk ([`jobs_bucket`]).
    pub jobs_bucket: Option<std::sync::Arc<jobs_bucket::JobsBucket>>,
}

fn failed(what: &str, url: &str, e: impl std::fmt::Display) -> String {
    format!("{what} (NATS server {url}): {e}")
}

impl Queue {
    /// Connects (failing at once, not retrying, when no server answers) and creates the stream
    /// and the workers' consumer if they do not exist. `url` may list several servers of a
    /// cluster, separated by commas (the client also learns the others from the one it reaches,
    /// and moves to another when that one goes). `ack_wait` applies when this call creates the
    /// consumer.
    pub async fn connect(
        url: &str,
        ack_wait: Duration,
        options: &options::NatsOptions,
    ) -> Result<Queue, String> {
        let servers = url
            .split(',')
            .map(|one| {
                one.trim()
                    .parse::<async_nats::ServerAddr>()
                    .map_err(|e| format!("`{one}` is not a NATS server's URL: {e}"))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let client = options
            .connect_options()
            .await?
            .connect(servers)
            .await
            .map_err(|e| failed("cannot connect", url, e))?;
        let jetstream = jetstream::new(client.clone());
        // Workers and servers starting at the same moment (an array job, a test) may each find
        // no stream and create it: the one whose create comes second is refused ("subjects
        // overlap with an existing stream") and takes the stream the other made.
        let stream = match jetstream
            .get_or_create_stream(stream::Config {
                name: STREAM.into(),
                subjects: vec![format!("{TASKS}.>")],
                retention: stream::RetentionPolicy::WorkQueue,
                storage: stream::StorageType::File,
                num_replicas: options.replicas,
                ..Default::default()
            })
            .await
        {
            Ok(stream) => stream,
            Err(create) => jetstream.get_stream(STREAM).await.map_err(|_| {
                failed(
                    "cannot create the shard stream (is JetStream on?)",
                    url,
                    create,
                )
            })?,
        };
        // The same for the consumer: if another process's create won, its consumer is found
        // below.
        let created = stream
            .get_or_create_consumer(
                CONSUMER,
                pull::Config {
                    durable_name: Some(CONSUMER.into()),
                    ack_policy: jetstream::consumer::AckPolicy::Explicit,
                    ack_wait,
                    max_deliver: options.max_deliver,
                    ..Default::default()
                },
            )
            .await
            .map(|_| ());
        // A consumer made before deliveries were bounded redelivers a poison shard for ever.
        let consumer: jetstream::consumer::PullConsumer = stream
            .get_consumer(CONSUMER)
            .await
            .map_err(|e| match &created {
                Err(create) => failed("cannot create the workers' consumer", url, create),
                Ok(()) => failed("cannot find the workers' consumer", url, e),
            })?;
        let config = consumer.cached_info().config.clone();
        let (ack_wait, mut max_deliver) = (config.ack_wait, config.max_deliver);
        if config.max_deliver <= 0 {
            let bounded = jetstream::consumer::Config {
                max_deliver: options.max_deliver,
                ..config
            };
            // Creating a durable consumer that exists with a compatible configuration updates it.
            stream
                .create_consumer(bounded)
                .await
                .map_err(|e| failed("cannot bound the workers' consumer's deliveries", url, e))?;
            tracing::info!(
                max_deliver = options.max_deliver,
                "bounded the deliveries of the workers' consumer"
            );
            max_deliver = options.max_deliver;
        }
        Ok(Queue {
            client,
            jetstream,
            stream,
            url: url.to_string(),
            runtime: tokio::runtime::Handle::current(),
            ack_wait,
            max_deliver,
            steps_per_shard: DEFAULT_STEPS_PER_SHARD,
            replicas: options.replicas,
            jobs_bucket: None,
        })
    }

    /// The server's URL.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// How long a shard whose deliveries are all spent is waited for after the last word of a
    /// worker running it: as long as JetStream gave its deliveries (`max_deliver` ack waits), so
    /// that a worker stopped or starved of CPU about as long as a delivery lasts, and then
    /// continued, still finishes it; a worker that died says nothing more.
    pub fn exhausted_grace(&self) -> Duration {
        self.ack_wait * self.max_deliver.clamp(1, 100) as u32
    }
}

/// How many shards the server splits `cells` of `study` into: about `steps_per_shard` of work
/// each, parts under [`PART_BYTES`] (`cell_bytes`: about the size of one cell's result), no more
/// shards than cells.
pub fn shard_count<S: Study>(
    study: &S,
    cells: usize,
    steps_per_shard: u64,
    cell_bytes: usize,
) -> usize {
    let cells = cells.max(1);
    let steps_per_cell = (study.steps() / study.cells().max(1) as u64).max(1);
    let by_work = (steps_per_shard / steps_per_cell).max(1) as usize;
    let by_size = (PART_BYTES / cell_bytes.max(1)).max(1);
    cells.div_ceil(by_work.min(by_size).min(cells))
}

impl Executor for Queue {
    /// Hands the cells (the whole study, or a job's part of it) to the workers when the study
    /// may run elsewhere (a spec, cells in any order); a timed study runs here. Called on a
    /// thread outside the runtime's workers (a blocking thread, a job's thread).
    fn run<S: Study>(
        &self,
        study: &S,
        cells: Range<usize>,
        budget: Budget<'_>,
        done: &(dyn Fn(usize, Option<&S::Cell>) + Sync),
    ) -> Result<Vec<Option<S::Cell>>, CoreError> {
        match study.spec() {
            Some(spec)
                if study.order() == Order::Parallel
                    && !cells.is_empty()
                    && cells.end <= study.cells() =>
            {
                self.runtime
                    .block_on(run(self, spec, study, cells, budget, done))
            }
            _ => Local.run(study, cells, budget, done),
        }
    }
}

/// Runs the cells `within` of `study` (whose spec is `spec`) on the workers: publishes their
/// shards, collects the parts, calls `done` for each cell of a part as it arrives, and returns
/// the cells' results in order. Stops (taking what no worker has answered out of the queue) when
/// the budget says so: at the deadline with the cells of the parts received so far (`None` for
/// the others), on cancellation with an error. Fails when the NATS server is gone for
/// [`DISCONNECTED_GRACE`], when a part does not fit its shard, and when a shard was delivered
/// `max_deliver` times and no worker has said a word about it for [`Queue::exhausted_grace`]
/// ([`poison`]).
async fn run<S: Study>(
    queue: &Queue,
    spec: StudySpec,
    study: &S,
    within: Range<usize>,
    budget: Budget<'_>,
    done: &(dyn Fn(usize, Option<&S::Cell>) + Sync),
) -> Result<Vec<Option<S::Cell>>, CoreError> {
    let name = study.name();
    let lost = |what: &str, e: &dyn std::fmt::Display| CoreError::Executor {
        message: format!("the {name} failed: {what} (NATS server {}): {e}", queue.url),
    };
    let id = uuid::Uuid::new_v4().simple().to_string();
    let tasks = format!("{TASKS}.{id}");
    let parts_only = queue
        .client
        .subscribe(format!("{PARTS}.{id}"))
        .await
        .map_err(|e| lost("cannot subscribe to the parts", &e))?;
    // A shard delivered max_deliver times without an answer fails the study.
    let advisories = queue
        .client
        .subscribe(poison::advisory())
        .await
        .map_err(|e| lost("cannot subscribe to the advisories", &e))?;
    let mut parts_in = futures_util::stream::select(parts_only, advisories);
    let mut sequences: HashMap<u64, usize> = HashMap::new();
    // A cell's size in a part, as the spec's size per cell, at least 400 bytes (a sweep's runs
    // carry their final states).
    let spec_bytes = serde_json::to_vec(&spec).map_or(0, |b| b.len());
    let cell_bytes = spec_bytes / study.cells().max(1) + 400;
    let count = shard_count(study, within.len(), queue.steps_per_shard, cell_bytes);
    let whole = within == (0..study.cells());
    tracing::info!(study = %id, kind = name, shards = count, cells = within.len(), first_cell = within.start, "study sent to the workers");
    let task = |shard: usize| {
        let task = Task {
            study: id.clone(),
            spec: spec.clone(),
            shard,
            shards: count,
            cells: (!whole).then(|| within.clone()),
        };
        serde_json::to_vec(&task).map_err(|e| lost("cannot encode a task", &e))
    };
    for index in 0..count {
        let sequence = enqueue(queue, &tasks, task(index)?, &format!("{id}.{index}"))
            .await
            .map_err(|e| lost("the stream did not take a shard", &e))?;
        sequences.insert(sequence, index);
    }

    let mut results: Vec<Option<S::Cell>> = within.clone().map(|_| None).collect();
    let mut answered = vec![false; count];
    // The shards no part has answered yet leave the queue.
    let withdraw_unanswered = |sequences: &HashMap<u64, usize>, answered: &[bool]| {
        let unanswered: Vec<u64> = sequences
            .iter()
            .filter(|&(_, &shard)| !answered[shard])
            .map(|(&sequence, _)| sequence)
            .collect();
        withdraw(queue, &id, unanswered)
    };
    // When the study last heard of its workers, when it last looked for lost parts, and the
    // shards it found gone from the stream with no part.
    let mut heard = Instant::now();
    let mut looked = Instant::now();
    let mut gone: HashSet<usize> = HashSet::new();
    let mut attempts = vec![0u32; count];
    // Shards whose deliveries are spent: the study's error if they stay silent, and when a
    // worker last spoke of them.
    let mut exhausted: HashMap<usize, (CoreError, Instant)> = HashMap::new();
    let mut missing = count;
    let mut disconnected_since: Option<Instant> = None;
    while missing > 0 {
        if budget.cancelled() {
            withdraw_unanswered(&sequences, &answered).await;
            return Err(CoreError::Cancelled {
                what: name,
                shutdown: true,
            });
        }
        if budget.expired() {
            withdraw_unanswered(&sequences, &answered).await;
            return Ok(results);
        }
        let silent = exhausted
            .iter()
            .find(|(_, (_, heard))| heard.elapsed() >= queue.exhausted_grace())
            .map(|(&shard, _)| shard);
        if let Some(shard) = silent {
            withdraw_unanswered(&sequences, &answered).await;
            return Err(exhausted.remove(&shard).expect("found above").0);
        }
        match queue.client.connection_state() {
            async_nats::connection::State::Connected => disconnected_since = None,
            _ => {
                let since = *disconnected_since.get_or_insert_with(Instant::now);
                if since.elapsed() >= DISCONNECTED_GRACE {
                    return Err(CoreError::Executor {
                        message: format!(
                            "the {name} failed: lost the connection to the NATS server {} for {} s \
                             with {missing} of {count} shards still out",
                            queue.url,
                            DISCONNECTED_GRACE.as_secs()
                        ),
                    });
                }
            }
        }
        // Silence for an ack wait: a shard that a worker acknowledged (it is gone from the
        // stream) while its part never came (a part is a plain NATS message: one sent while the
        // server moved to another NATS server of a cluster is lost) is queued again, once it is
        // found gone twice in a row.
        // Only while connected, and for at most an ack wait, so that a lost connection is still
        // noticed in time.
        let connected = disconnected_since.is_none();
        if connected && heard.elapsed() >= queue.ack_wait && looked.elapsed() >= queue.ack_wait {
            looked = Instant::now();
            let look = lost_parts(queue, &sequences, &answered, &mut gone);
            let lost_now = tokio::time::timeout(queue.ack_wait, look)
                .await
                .unwrap_or_default();
            for (shard, sequence) in lost_now {
                sequences.remove(&sequence);
                attempts[shard] += 1;
                let message_id = format!("{id}.{shard}.{}", attempts[shard]);
                let sequence = enqueue(queue, &tasks, task(shard)?, &message_id)
                    .await
                    .map_err(|e| lost("the stream did not take a shard again", &e))?;
                tracing::warn!(study = %id, shard, sequence, "a shard's part was lost; queued again");
                sequences.insert(sequence, shard);
            }
        }
        let message = match tokio::time::timeout(Duration::from_millis(100), parts_in.next()).await
        {
            Err(_) => continue,
            Ok(None) => return Err(lost("the subscription to the parts ended", &"closed")),
            Ok(Some(message)) => message,
        };
        // A shard whose part came after all (from a slow worker) is done, whatever its copies did.
        if let Some((shard, error)) = poison::exhausted(name, &message, &sequences) {
            if !answered[shard] {
                tracing::warn!(study = %id, shard, "a shard's deliveries are spent; waiting for a word from a worker still running it");
                exhausted.entry(shard).or_insert((error, Instant::now()));
            }
        }
        if message.subject.starts_with(poison::ADVISORY) {
            continue;
        }
        heard = Instant::now();
        match serde_json::from_slice::<Reply<Part<S::Cell>>>(&message.payload) {
            Ok(Reply::Part(part)) if part.shard < count && part.shards == count => {
                // A redelivered shard may arrive twice: the first copy counts.
                if answered[part.shard] {
                    continue;
                }
                let slots = Shard {
                    index: part.shard,
                    count,
                }
                .cells_within(&within)
                .map_err(|e| e.to_string())
                .and_then(|range| fitting(study, &spec, &part, range));
                let range = match slots {
                    Ok(range) => range,
                    Err(reason) => {
                        withdraw_unanswered(&sequences, &answered).await;
                        return Err(CoreError::Executor {
                            message: format!(
                                "the {name}'s parts do not fit together: shard {}: {reason}",
                                part.shard
                            ),
                        });
                    }
                };
                let offset = range.start - within.start;
                for (k, cell) in part.cells.into_iter().enumerate() {
                    done(range.start + k, Some(&cell));
                    results[offset + k] = Some(cell);
                }
                answered[part.shard] = true;
                exhausted.remove(&part.shard);
                missing -= 1;
            }
            Ok(Reply::Part(part)) => tracing::warn!(
                shard = part.shard,
                shards = part.shards,
                "a part that is not a shard of this study"
            ),
            Ok(Reply::Progress { shard, cells }) => {
                tracing::debug!(study = %id, shard, cells, "a shard in progress");
                if let Some((_, heard)) = exhausted.get_mut(&shard) {
                    *heard = Instant::now();
                }
            }
            Ok(Reply::Failed { shard, message }) => {
                withdraw_unanswered(&sequences, &answered).await;
                return Err(CoreError::Executor {
                    message: format!(
                        "the {name} failed: a worker cannot run shard {shard}: {message}"
                    ),
                });
            }
            Err(e) => tracing::warn!(error = %e, "an unreadable reply"),
        }
    }
    Ok(results)
}

/// The cells `part` should hold (`range`, of the study's cells) if it is a part of this study:
/// of its format and spec, holding exactly those cells, each one the study can take.
fn fitting<S: Study>(
    study: &S,
    spec: &StudySpec,
    part: &Part<S::Cell>,
    range: Range<usize>,
) -> Result<Range<usize>, String> {
    if part.format != parts::PART_FORMAT || &part.spec != spec {
        return Err("it belongs to another study".into());
    }
    if part.first_cell != range.start || part.cells.len() != range.len() {
        return Err(format!(
            "it holds cells {}..{}, the shard is cells {}..{}",
            part.first_cell,
            part.first_cell + part.cells.len(),
            range.start,
            range.end
        ));
    }
    if !part.cells.iter().all(|cell| study.fits(cell)) {
        return Err("its cells are not the study's (other runs or settings)".into());
    }
    Ok(range)
}

/// How long the server tries to queue a shard before failing its study: about as long as a
/// JetStream cluster takes to elect a stream's new leader once a server is gone.
const ENQUEUE_PATIENCE: Duration = Duration::from_secs(15);

/// Puts a task on the stream under `message_id` and returns its stream sequence. A publish that
/// fails or is not acknowledged (a cluster electing a new leader) is tried again for up to
/// [`ENQUEUE_PATIENCE`]; JetStream keeps one copy of a message id, so a task whose first
/// acknowledgement was lost is still queued once.
async fn enqueue(
    queue: &Queue,
    subject: &str,
    payload: Vec<u8>,
    message_id: &str,
) -> Result<u64, String> {
    let payload = bytes::Bytes::from(payload);
    let until = Instant::now() + ENQUEUE_PATIENCE;
    loop {
        let publish = jetstream::message::PublishMessage::build()
            .payload(payload.clone())
            .message_id(message_id);
        let stored = match queue
            .jetstream
            .send_publish(subject.to_string(), publish)
            .await
        {
            Ok(acknowledged) => acknowledged.await.map_err(|e| e.to_string()),
            Err(e) => Err(e.to_string()),
        };
        match stored {
            Ok(ack) => return Ok(ack.sequence),
            Err(e) if Instant::now() < until => {
                tracing::debug!(error = %e, message_id, "queueing a shard again");
                tokio::time::sleep(Duration::from_millis(250)).await;
            }
            Err(e) => return Err(e),
        }
    }
}

/// The unanswered shards (shard, stream sequence) whose task is gone from the stream, a worker
/// having acknowledged it, and was gone at the last look too (`gone`: shards found gone once).
async fn lost_parts(
    queue: &Queue,
    sequences: &HashMap<u64, usize>,
    answered: &[bool],
    gone: &mut HashSet<usize>,
) -> Vec<(usize, u64)> {
    let mut lost = Vec::new();
    let mut still_gone = HashSet::new();
    for (&sequence, &shard) in sequences {
        if answered[shard] {
            continue;
        }
        match queue.stream.get_raw_message(sequence).await {
            Err(e) if e.kind() == stream::LastRawMessageErrorKind::NoMessageFound => {
                if gone.contains(&shard) {
                    lost.push((shard, sequence));
                } else {
                    still_gone.insert(shard);
                }
            }
            // Still queued or running; or the stream cannot say now: look again later.
            _ => {}
        }
    }
    *gone = still_gone;
    lost
}

/// Takes a study's shards out of the queue by their stream sequences (`id`: the study, for the
/// log). One by one rather than by a purge filtered on the study's subject: on NATS 2.9 such a
/// purge moves the workers' consumer past every earlier message of the stream, so that another
/// study queued before this one would never reach a worker. A shard already gone (answered, or
/// taken by a worker) is no error.
async fn withdraw(queue: &Queue, id: &str, sequences: Vec<u64>) {
    futures_util::stream::iter(sequences)
        .for_each_concurrent(32, |sequence| async move {
            match queue.stream.delete_message(sequence).await {
                Ok(_) => {}
                Err(e) if matches!(e.kind(), DeleteMessageErrorKind::JetStream(_)) => {
                    tracing::debug!(study = %id, sequence, error = %e, "a shard already left the queue");
                }
                Err(e) => {
                    tracing::warn!(study = %id, sequence, error = %e, "cannot take a shard out of the queue");
                }
            }
        })
        .await;
}
