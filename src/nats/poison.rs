//! Poison shards: a shard whose run panics, or kills its worker, is delivered at most
//! `max_deliver` times ([`DEFAULT_MAX_DELIVER`]) and then fails its study with a clear error,
//! while the other studies in the queue go on.
//!
//! - A panic is caught by the worker: before the last delivery it gives the shard back at once
//!   (a negative acknowledgement, so the next attempt does not wait for the ack wait); on the
//!   last it publishes a [`Reply::Failed`](super::Reply) naming the panic and terminates the
//!   shard.
//! - A worker that dies never answers: the shard goes out again after each ack wait, and once
//!   JetStream has delivered it `max_deliver` times it publishes the consumer's max-deliveries
//!   advisory ([`ADVISORY`]), which the server that queued the shard watches for its sequence
//!   numbers. The study fails once no worker has reported progress on the shard for a further
//!   `max_deliver` ack waits ([`Queue::exhausted_grace`](super::Queue::exhausted_grace)): a
//!   worker that was only stopped or starved of CPU, and continues, reports again within a third
//!   of an ack wait, and its part still counts.
//!
//! Tests make a shard panic, or kill its worker, through [`test_fault`]: in builds with debug
//! assertions only, a worker whose environment sets `GEOMINT_WORKER_PANIC_ON` panics on a task
//! whose bytes contain that text, and one that sets `GEOMINT_WORKER_ABORT_ON` aborts. One that
//! sets `GEOMINT_WORKER_LOSE_PART_ON` loses the first such part it computes ([`loses_part`]):
//! it acknowledges the task without sending the part, as a part lost in transit would look to
//! the server. Release builds have no such hook, and no request reaches it without the worker's
//! own environment.

use std::collections::HashMap;

use serde::Deserialize;

use crate::core::error::CoreError;

/// Deliveries of a shard before its study fails, when this process creates the consumer.
pub const DEFAULT_MAX_DELIVER: i64 = 3;

/// The subject of the workers' consumer's max-deliveries advisories.
pub fn advisory() -> String {
    format!(
        "$JS.EVENT.ADVISORY.CONSUMER.MAX_DELIVERIES.{}.{}",
        super::STREAM,
        super::CONSUMER
    )
}

/// The subject prefix of advisories, to tell them from parts.
pub const ADVISORY: &str = "$JS.EVENT.ADVISORY.";

#[derive(Deserialize)]
struct MaxDeliveries {
    stream_seq: u64,
    deliveries: u64,
}

/// The shard and the study's error if `message` is a max-deliveries advisory for one of the
/// study's shards (`shards`: stream sequence → shard; `name`: the kind of study).
pub fn exhausted(
    name: &str,
    message: &async_nats::Message,
    shards: &HashMap<u64, usize>,
) -> Option<(usize, CoreError)> {
    if !message.subject.starts_with(ADVISORY) {
        return None;
    }
    let advisory: MaxDeliveries = serde_json::from_slice(&message.payload).ok()?;
    let shard = *shards.get(&advisory.stream_seq)?;
    Some((
        shard,
        CoreError::Executor {
            message: format!(
            "the {name} failed: shard {shard} was handed to workers {} times (max_deliver) and \
             never finished: each worker running it died or panicked",
            advisory.deliveries
        ),
        },
    ))
}

/// The message of a panic caught in a worker.
pub fn panic_message(error: tokio::task::JoinError) -> String {
    if !error.is_panic() {
        return error.to_string();
    }
    let panic = error.into_panic();
    panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".to_string())
}

/// Whether `payload` holds the text a test's environment names.
#[cfg(debug_assertions)]
fn holds(payload: &[u8], marker: &Option<String>) -> bool {
    marker
        .as_deref()
        .is_some_and(|m| payload.windows(m.len()).any(|w| w == m.as_bytes()))
}

/// Whether this worker is to lose the part of the task with these bytes: the first one holding
/// `GEOMINT_WORKER_LOSE_PART_ON`, in builds with debug assertions only.
pub fn loses_part(payload: &[u8]) -> bool {
    #[cfg(debug_assertions)]
    {
        use std::sync::atomic::{AtomicBool, Ordering};
        static MARKER: std::sync::OnceLock<Option<String>> = std::sync::OnceLock::new();
        static LOST: AtomicBool = AtomicBool::new(false);
        let marker = MARKER.get_or_init(|| {
            std::env::var("GEOMINT_WORKER_LOSE_PART_ON")
                .ok()
                .filter(|m| !m.is_empty())
        });
        if holds(payload, marker) && !LOST.swap(true, Ordering::Relaxed) {
            eprintln!("GEOMINT_WORKER_LOSE_PART_ON: a test's part is lost");
            return true;
        }
    }
    #[cfg(not(debug_assertions))]
    let _ = payload;
    false
}

/// Panics, or aborts the worker, when its environment asks it to for a task with these bytes
/// (builds with debug assertions only; see the module's documentation).
pub fn test_fault(payload: &[u8]) {
    #[cfg(debug_assertions)]
    {
        static MARKERS: std::sync::OnceLock<[Option<String>; 2]> = std::sync::OnceLock::new();
        let [panic_on, abort_on] = MARKERS.get_or_init(|| {
            ["GEOMINT_WORKER_PANIC_ON", "GEOMINT_WORKER_ABORT_ON"]
                .map(|name| std::env::var(name).ok().filter(|m| !m.is_empty()))
        });
        if holds(payload, abort_on) {
            eprintln!("GEOMINT_WORKER_ABORT_ON: a test's poison shard kills its worker");
            std::process::abort();
        }
        if holds(payload, panic_on) {
            panic!("GEOMINT_WORKER_PANIC_ON: a test's poison shard");
        }
    }
    #[cfg(not(debug_assertions))]
    let _ = payload;
}
