//! Jobs kept in JetStream: a server with NATS keeps every file of its jobs (their records,
//! finished parts, outcomes and results; not their event logs) in a JetStream object store as
//! well as on its disk ([`crate::store::jobs::Replica`]). A server that lost its disk, or a new
//! one started in its place on the same bucket, takes its jobs back from there and goes on from
//! their finished parts. The bucket has the shard stream's number of copies
//! (`--nats-replicas`), so it outlives a server of a JetStream cluster too.
//!
//! The object store chunks what it keeps, so a part or a result may be larger than a NATS
//! message. Every call is idempotent (a part written twice is the same bytes) and is tried again
//! for up to [`CALL_PATIENCE`], as a JetStream cluster electing a new leader for the bucket's
//! stream refuses calls for a few seconds; then it fails (a write fails the job, as a part that
//! could not be stored, rather than holding its thread).

use std::future::Future;
use std::io;
use std::time::Duration;

use async_nats::jetstream::{object_store, stream::StorageType};
use futures_util::StreamExt;
use tokio::io::AsyncReadExt;

use super::Queue;
use crate::store::jobs::Replica;

/// The default name of the jobs' bucket (`--nats-jobs-bucket`).
pub const DEFAULT_BUCKET: &str = "geomint-jobs";
/// The `--nats-jobs-bucket` that keeps jobs on the server's disk only.
pub const NO_BUCKET: &str = "off";
/// How long a call to the bucket is tried before it fails.
pub const CALL_PATIENCE: Duration = Duration::from_secs(30);

/// The jobs' object store, with the runtime its calls block on.
pub struct JobsBucket {
    store: object_store::ObjectStore,
    name: String,
    runtime: tokio::runtime::Handle,
}

/// Whether `name` can name a bucket: letters, digits, `-` and `_`.
pub fn is_bucket_name(name: &str) -> bool {
    !name.is_empty()
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
}

impl Queue {
    /// The jobs' bucket `name`, made (with the queue's number of copies) if it does not exist.
    pub async fn jobs_bucket(&self, name: &str) -> Result<JobsBucket, String> {
        if !is_bucket_name(name) {
            return Err(format!(
                "--nats-jobs-bucket `{name}` is not a bucket name: use letters, digits, - and _"
            ));
        }
        let store = match self.jetstream.get_object_store(name).await {
            Ok(store) => store,
            Err(_) => self
                .jetstream
                .create_object_store(object_store::Config {
                    bucket: name.to_string(),
                    description: Some("geomint's jobs: records, finished parts, results".into()),
                    storage: StorageType::File,
                    num_replicas: self.replicas,
                    ..Default::default()
                })
                .await
                .map_err(|e| super::failed("cannot create the jobs' bucket", &self.url, e))?,
        };
        Ok(JobsBucket {
            store,
            name: name.to_string(),
            runtime: self.runtime.clone(),
        })
    }
}

impl std::fmt::Debug for JobsBucket {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JobsBucket")
            .field("name", &self.name)
            .finish()
    }
}

impl JobsBucket {
    /// Runs the call that `call` makes on the runtime, again until it succeeds or
    /// [`CALL_PATIENCE`] has passed; `what` names it in errors.
    fn block<T, E: std::fmt::Display, F: Future<Output = Result<T, E>>>(
        &self,
        what: &str,
        call: impl Fn() -> F,
    ) -> io::Result<T> {
        let bucket = &self.name;
        // The timers are made inside the runtime: a job's thread is not one of its threads.
        let patient = async {
            let until = tokio::time::Instant::now() + CALL_PATIENCE;
            loop {
                let last = match tokio::time::timeout_at(until, call()).await {
                    Ok(Ok(value)) => return Ok(value),
                    Ok(Err(e)) => e.to_string(),
                    Err(_) => format!("no answer in {} s", CALL_PATIENCE.as_secs()),
                };
                if tokio::time::Instant::now() + RETRY_PAUSE >= until {
                    return Err(last);
                }
                tracing::debug!(
                    bucket,
                    what,
                    error = last,
                    "a call to the jobs' bucket failed; trying again"
                );
                tokio::time::sleep(RETRY_PAUSE).await;
            }
        };
        self.runtime
            .block_on(patient)
            .map_err(|e| io::Error::other(format!("JetStream bucket {bucket}: {what}: {e}")))
    }
}

/// The pause between two tries of a call.
const RETRY_PAUSE: Duration = Duration::from_millis(250);

impl Replica for JobsBucket {
    fn put(&self, name: &str, bytes: &[u8]) -> io::Result<()> {
        self.block(&format!("cannot keep {name}"), || async {
            let mut reader = bytes;
            self.store.put(name, &mut reader).await.map(|_| ())
        })
    }

    fn get(&self, name: &str) -> io::Result<Vec<u8>> {
        self.block(&format!("cannot read {name}"), || async {
            let mut object = self.store.get(name).await.map_err(io::Error::other)?;
            let mut bytes = Vec::new();
            object.read_to_end(&mut bytes).await?;
            Ok::<_, io::Error>(bytes)
        })
    }

    fn names(&self) -> io::Result<Vec<String>> {
        self.block("cannot list its objects", || async {
            let mut list = self.store.list().await.map_err(io::Error::other)?;
            let mut names = Vec::new();
            while let Some(info) = list.next().await {
                names.push(info.map_err(io::Error::other)?.name);
            }
            Ok::<_, io::Error>(names)
        })
    }

    fn delete(&self, name: &str) -> io::Result<()> {
        // A name already gone (an earlier try that was answered too late) is deleted.
        self.block(&format!("cannot delete {name}"), || async {
            match self.store.delete(name).await {
                Err(e) if e.kind() == object_store::DeleteErrorKind::NotFound => Ok(()),
                other => other,
            }
        })
    }
}
