//! The worker's side of the queue (`geomint worker --nats`): pulls shards one at a time, runs
//! each on all cores, reports its progress, publishes its part and then acknowledges it.

use std::sync::atomic::{AtomicUsize, Ordering as AtomicOrdering};
use std::sync::Arc;
use std::time::Duration;

use async_nats::jetstream::{self, AckKind};
use futures_util::StreamExt;
use serde::Deserialize;

use super::{failed, poison, Queue, Reply, Task, CONSUMER, PARTS};
use crate::core::simulation::Limits;
use crate::core::studies::parts::{self, AnyPart, Shard};

/// Pulls shards one at a time and runs them, for as long as the process lives: a lost
/// connection, a failed publish or acknowledgement is logged and retried (the shard, not
/// acknowledged, goes out again after the ack wait). Fails only when the workers' consumer cannot
/// be found at the start. `limits` bound what a task may ask for.
pub async fn work(queue: &Queue, limits: Limits) -> Result<(), String> {
    let consumer: jetstream::consumer::PullConsumer = queue
        .stream
        .get_consumer(CONSUMER)
        .await
        .map_err(|e| failed("cannot find the workers' consumer", &queue.url, e))?;
    let ack_wait = consumer.cached_info().config.ack_wait;
    tracing::info!(url = %queue.url, ack_wait_secs = ack_wait.as_secs_f64(), "worker ready");
    loop {
        if let Err(e) = run_one(queue, &consumer, ack_wait, limits).await {
            tracing::warn!(error = %e, "retrying in a second");
            tokio::time::sleep(Duration::from_secs(1)).await;
        }
    }
}

/// Waits up to 5 s for one shard and runs it: publishes its part, then acknowledges it.
async fn run_one(
    queue: &Queue,
    consumer: &jetstream::consumer::PullConsumer,
    ack_wait: Duration,
    limits: Limits,
) -> Result<(), String> {
    let mut batch = consumer
        .fetch()
        .max_messages(1)
        .expires(Duration::from_secs(5))
        .messages()
        .await
        .map_err(|e| failed("cannot fetch a shard", &queue.url, e))?;
    let Some(message) = batch.next().await else {
        return Ok(());
    };
    let message = Arc::new(message.map_err(|e| failed("cannot fetch a shard", &queue.url, e))?);
    // The study and shard, for the progress reports (a task that cannot be read is answered
    // below).
    let about: Option<(String, usize)> = serde_json::from_slice::<TaskAddress>(&message.payload)
        .ok()
        .map(|t| (t.study, t.shard));
    let cells_done = Arc::new(AtomicUsize::new(0));
    // Tell JetStream the shard is being worked on, so it is not handed out again, and tell the
    // study's server how far it got, so that a shard whose deliveries a stopped or starved
    // worker spent is waited for while a worker still runs it.
    let keepalive = {
        let message = Arc::clone(&message);
        let client = queue.client.clone();
        let cells_done = Arc::clone(&cells_done);
        tokio::spawn(async move {
            let mut tick = tokio::time::interval((ack_wait / 3).max(Duration::from_millis(100)));
            tick.tick().await;
            loop {
                tick.tick().await;
                let _ = message.ack_with(AckKind::Progress).await;
                if let Some((study, shard)) = &about {
                    let report: Reply<AnyPart> = Reply::Progress {
                        shard: *shard,
                        cells: cells_done.load(AtomicOrdering::Relaxed),
                    };
                    if let Ok(bytes) = serde_json::to_vec(&report) {
                        let _ = client
                            .publish(format!("{PARTS}.{study}"), bytes.into())
                            .await;
                    }
                }
            }
        })
    };
    let payload = message.payload.clone();
    let max_payload = queue.client.server_info().max_payload;
    let reply = tokio::task::spawn_blocking(move || {
        let tick = || {
            cells_done.fetch_add(1, AtomicOrdering::Relaxed);
        };
        run_task(&payload, &limits, max_payload, &tick)
    })
    .await;
    keepalive.abort();
    let (study, reply) = match reply {
        Ok(done) => done,
        Err(panic) => {
            return poisoned(queue, &message, consumer, poison::panic_message(panic)).await
        }
    };
    let study = study.filter(|_| !poison::loses_part(&message.payload));
    if let Some(study) = study {
        let bytes = serde_json::to_vec(&reply).map_err(|e| e.to_string())?;
        queue
            .client
            .publish(format!("{PARTS}.{study}"), bytes.into())
            .await
            .map_err(|e| failed("cannot publish a part", &queue.url, e))?;
        queue
            .client
            .flush()
            .await
            .map_err(|e| failed("cannot publish a part", &queue.url, e))?;
    }
    // Acknowledged only once the part is out: a worker that dies before never loses it.
    message
        .double_ack()
        .await
        .map_err(|e| failed("cannot acknowledge a shard", &queue.url, e))
}

/// A shard whose run panicked: given back at once for another attempt, or, on its last
/// delivery, failed (the study's server told why) and terminated.
async fn poisoned(
    queue: &Queue,
    message: &jetstream::Message,
    consumer: &jetstream::consumer::PullConsumer,
    panic: String,
) -> Result<(), String> {
    let delivered = message.info().map(|i| i.delivered).unwrap_or(1);
    let max_deliver = consumer.cached_info().config.max_deliver;
    tracing::error!(delivered, max_deliver, %panic, "a shard panicked");
    let task: Option<Task> = serde_json::from_slice(&message.payload).ok();
    if max_deliver <= 0 || delivered < max_deliver {
        return message
            .ack_with(AckKind::Nak(None))
            .await
            .map_err(|e| failed("cannot give back a shard", &queue.url, e));
    }
    if let Some(task) = task {
        let reply: Reply<AnyPart> = Reply::Failed {
            shard: task.shard,
            message: format!(
                "it panicked on each of its {delivered} deliveries (max_deliver): {panic}"
            ),
        };
        let bytes = serde_json::to_vec(&reply).map_err(|e| e.to_string())?;
        queue
            .client
            .publish(format!("{PARTS}.{}", task.study), bytes.into())
            .await
            .map_err(|e| failed("cannot publish a failure", &queue.url, e))?;
    }
    message
        .ack_with(AckKind::Term)
        .await
        .map_err(|e| failed("cannot terminate a shard", &queue.url, e))
}

/// The fields of a task that say where its reports go, read without its spec.
#[derive(Deserialize)]
struct TaskAddress {
    study: String,
    shard: usize,
}

/// Runs one task (`tick` after each cell): its study (if the task could be read) and the reply.
fn run_task(
    payload: &[u8],
    limits: &Limits,
    max_payload: usize,
    tick: &(dyn Fn() + Sync),
) -> (Option<String>, Reply<AnyPart>) {
    poison::test_fault(payload);
    let task: Task = match serde_json::from_slice(payload) {
        Ok(task) => task,
        Err(e) => {
            tracing::warn!(error = %e, "an unreadable task; dropped");
            return (
                None,
                Reply::Failed {
                    shard: 0,
                    message: e.to_string(),
                },
            );
        }
    };
    let failed = |message: String| Reply::Failed {
        shard: task.shard,
        message,
    };
    if task.shard >= task.shards {
        return (
            Some(task.study),
            failed(format!(
                "shard {} of {} is no shard",
                task.shard, task.shards
            )),
        );
    }
    let shard = Shard {
        index: task.shard,
        count: task.shards,
    };
    tracing::info!(study = %task.study, shard = task.shard, shards = task.shards, "shard started");
    let reply = match parts::run_part(&task.spec, shard, task.cells.clone(), limits, tick) {
        Ok(part) => Reply::Part(Box::new(part)),
        Err(e) => failed(e.to_string()),
    };
    let size = serde_json::to_vec(&reply).map(|b| b.len()).unwrap_or(0);
    if size > max_payload {
        return (
            Some(task.study.clone()),
            failed(format!(
                "its part is {size} bytes, more than the NATS server's max_payload of {max_payload}"
            )),
        );
    }
    (Some(task.study), reply)
}
