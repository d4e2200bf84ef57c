//! Jobs kept in JetStream: a server with NATS keeps every file of its jobs (their records,
//! finished parts, outcomes and results; not their event logs) in a JetStream object store as
//! well as on its disk ([`crate::store::jobs::Replica`]). A server that lost its disk, or a new
//! one started in its place on the same bucket, takes its jobs back from there and goes on from
//! their finished parts. The bucket has the shard stream's number of copies
//! (`--nats-replicas`), so it outlives a server of a JetStream cluster too.
//!
//! The object store chunks what it keeps, so a part or a result may be larger than a NATS
//! message. Each call is bounded by [`CALL_TIMEOUT`]: a NATS server that does not answer fails
//! the write (and the job, as a part that could not be stored) rather than holding its thread.

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
/// How long one call to the bucket may take.
pub const CALL_TIMEOUT: Duration = Duration::from_secs(30);

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
    /// Runs `call` on the runtime, within [`CALL_TIMEOUT`]; `what` names it in errors.
    fn block<T, E: std::fmt::Display>(
        &self,
        what: &str,
        call: impl Future<Output = Result<T, E>>,
    ) -> io::Result<T> {
        let bucket = &self.name;
        // The timer is made inside the runtime: a job's thread is not one of its threads.
        let bounded = async { tokio::time::timeout(CALL_TIMEOUT, call).await };
        match self.runtime.block_on(bounded) {
            Ok(Ok(value)) => Ok(value),
            Ok(Err(e)) => Err(io::Error::other(format!(
                "JetStream bucket {bucket}: {what}: {e}"
            ))),
            Err(_) => Err(io::Error::new(
                io::ErrorKind::TimedOut,
                format!(
                    "JetStream bucket {bucket}: {what}: no answer in {} s",
                    CALL_TIMEOUT.as_secs()
                ),
            )),
        }
    }
}

impl Replica for JobsBucket {
    fn put(&self, name: &str, bytes: &[u8]) -> io::Result<()> {
        let mut reader = bytes;
        self.block(&format!("cannot keep {name}"), async {
            self.store.put(name, &mut reader).await.map(|_| ())
        })
    }

    fn get(&self, name: &str) -> io::Result<Vec<u8>> {
        self.block(&format!("cannot read {name}"), async {
            let mut object = self.store.get(name).await.map_err(io::Error::other)?;
            let mut bytes = Vec::with_capacity(object.info.size);
            object.read_to_end(&mut bytes).await?;
            Ok::<_, io::Error>(bytes)
        })
    }

    fn names(&self) -> io::Result<Vec<String>> {
        self.block("cannot list its objects", async {
            let mut list = self.store.list().await.map_err(io::Error::other)?;
            let mut names = Vec::new();
            while let Some(info) = list.next().await {
                names.push(info.map_err(io::Error::other)?.name);
            }
            Ok::<_, io::Error>(names)
        })
    }

    fn delete(&self, name: &str) -> io::Result<()> {
        self.block(&format!("cannot delete {name}"), async {
            self.store.delete(name).await
        })
    }
}
