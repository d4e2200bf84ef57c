//! Service configuration and shared state: the limits, the semaphore that bounds concurrent
//! runs, the shutdown signal that cancels runs, the recording and system stores, and the helper that moves
//! blocking work off the async runtime.

use std::collections::HashMap;
use std::net::IpAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::Mutex;
use std::time::Duration;

use tokio::sync::{watch, OwnedSemaphorePermit, Semaphore};

use super::error::ApiError;
use crate::access::{Access, AccessConfig};
use crate::core::simulation::Limits;
use crate::executor::{cores, StudyExecutor};
use crate::jobs::{JobContext, Jobs, JobsConfig};
use crate::store::recordings::RecordingStore;
use crate::store::systems::{SystemStore, DEFAULT_MAX_SYSTEMS, DEFAULT_SYSTEMS_DIR};

/// Settings of the service.
#[derive(Clone, Debug)]
pub struct Config {
    /// Step and sample limits per request.
    pub limits: Limits,
    /// Most simulation threads at once (a request takes one per method while free, at least one).
    pub max_concurrent: usize,
    /// Time limit of a simulation: runs still going then stop with `time_limit`.
    pub request_timeout: Duration,
    /// How long short work waits for a free slot before it is answered 503.
    pub queue_timeout: Duration,
    /// How long long work waits its turn (first come, first served; one waiting request per
    /// client address) before it is answered 503.
    pub long_queue_timeout: Duration,
    /// Slots kept for short work only, beside the `max_concurrent` shared ones: short runs are
    /// served while long ones hold every shared slot.
    pub short_lane: usize,
    /// The largest predicted cost ([`Cost`]) that counts as short work.
    pub short_work: u64,
    /// Most open connections; past it the server stops accepting until one closes.
    pub max_connections: usize,
    /// Time limit on reading a request's head, and on an idle keep-alive connection.
    pub header_timeout: Duration,
    /// Time limit on receiving a request's body.
    pub body_timeout: Duration,
    /// Origins allowed by CORS; empty turns CORS off, `*` allows any origin.
    pub cors_origins: Vec<String>,
    /// Directory served at `/` (when it exists).
    pub static_dir: Option<PathBuf>,
    /// Largest request body in bytes.
    pub body_limit: usize,
    /// After a shutdown signal, how long running simulations may go on before they are
    /// cancelled.
    pub shutdown_grace: Duration,
    /// Directory of the stored recordings.
    pub data_dir: PathBuf,
    /// Most bytes of stored recordings; past it the oldest are deleted.
    pub recordings_max_bytes: u64,
    /// Directory of the stored system definitions.
    pub systems_dir: PathBuf,
    /// Most stored system definitions.
    pub max_systems: usize,
    /// Tokens, and what clients without one may do.
    pub access: AccessConfig,
    /// Jobs: where they are kept and how many an owner may have; none turns jobs off.
    pub jobs: Option<JobsConfig>,
}

/// The default directory of stored recordings.
pub const DEFAULT_DATA_DIR: &str = "./data/recordings";
/// The default cap on stored recordings: 1 GiB.
pub const DEFAULT_RECORDINGS_MAX_BYTES: u64 = 1 << 30;

/// The default largest cost of short work: 2·10⁵ step-coordinates, a few milliseconds.
pub const DEFAULT_SHORT_WORK: u64 = 200_000;

/// What a request predicts it will compute before it starts, for admission: short work may use
/// the short lane, long work waits its turn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cost {
    /// Steps × coordinates of every run (a simulation, a stored recording's run).
    Steps(u64),
    /// A study: many runs, always long work.
    Study,
    /// Reading back stored data: always short.
    Read,
}

impl Cost {
    /// Whether this is short work under `config`.
    fn is_short(self, config: &Config) -> bool {
        match self {
            Cost::Steps(n) => n <= config.short_work,
            Cost::Study => false,
            Cost::Read => true,
        }
    }
}

impl Default for Config {
    fn default() -> Self {
        Self {
            limits: Limits::default(),
            max_concurrent: cores(),
            request_timeout: Duration::from_secs(60),
            queue_timeout: Duration::from_millis(250),
            long_queue_timeout: Duration::from_secs(5),
            short_lane: 1,
            short_work: DEFAULT_SHORT_WORK,
            max_connections: 1024,
            header_timeout: Duration::from_secs(10),
            body_timeout: Duration::from_secs(60),
            cors_origins: Vec::new(),
            static_dir: None,
            body_limit: 1 << 20,
            shutdown_grace: Duration::from_secs(10),
            data_dir: PathBuf::from(DEFAULT_DATA_DIR),
            recordings_max_bytes: DEFAULT_RECORDINGS_MAX_BYTES,
            systems_dir: PathBuf::from(DEFAULT_SYSTEMS_DIR),
            max_systems: DEFAULT_MAX_SYSTEMS,
            access: AccessConfig::default(),
            jobs: None,
        }
    }
}

/// State shared by all handlers.
#[derive(Clone, Debug)]
pub struct AppState {
    /// The settings.
    pub config: Arc<Config>,
    /// The stored recordings.
    pub recordings: Arc<RecordingStore>,
    /// The stored system definitions.
    pub systems: Arc<SystemStore>,
    /// Tokens in force, the anonymous policy, and what callers use.
    pub access: Arc<Access>,
    /// Where studies run: here, or on NATS workers.
    pub executor: StudyExecutor,
    /// The jobs, when they are on.
    pub jobs: Option<Arc<Jobs>>,
    permits: Arc<Semaphore>,
    short_lane: Arc<Semaphore>,
    waiting_long: Arc<Mutex<HashMap<IpAddr, usize>>>,
    shutdown: Arc<watch::Sender<bool>>,
}

impl AppState {
    /// State for `config`; reads back the recordings and system definitions stored before.
    pub fn new(config: Config) -> Self {
        let max = config.max_concurrent.max(1);
        let config_short_lane = config.short_lane;
        let recordings = RecordingStore::open(&config.data_dir, config.recordings_max_bytes);
        let systems = SystemStore::open(&config.systems_dir, config.max_systems);
        let jobs = config.jobs.as_ref().map(|c| Arc::new(Jobs::open(c)));
        Self {
            jobs,
            recordings: Arc::new(recordings),
            systems: Arc::new(systems),
            access: Arc::new(Access::new(config.access.clone(), config.short_work)),
            executor: StudyExecutor::Local,
            config: Arc::new(Config {
                max_concurrent: max,
                ..config
            }),
            permits: Arc::new(Semaphore::new(max)),
            short_lane: Arc::new(Semaphore::new(config_short_lane)),
            waiting_long: Arc::default(),
            shutdown: Arc::new(watch::channel(false).0),
        }
    }

    /// The same state, running studies on the workers of `queue` (here without one).
    pub fn with_queue(mut self, queue: Option<crate::nats::Queue>) -> Self {
        // The jobs keep their files in the queue's bucket too, when it has one.
        let bucket = queue.as_ref().and_then(|q| q.jobs_bucket.clone());
        if let (Some(jobs), Some(bucket)) = (&self.jobs, bucket) {
            jobs.replicate_to(bucket);
        }
        self.executor = queue.map_or(StudyExecutor::Local, |q| StudyExecutor::Nats(Arc::new(q)));
        self
    }

    /// Simulation threads running now (shared slots and the short lane's).
    pub fn runs_in_progress(&self) -> usize {
        self.config.max_concurrent - self.permits.available_permits() + self.config.short_lane
            - self.short_lane.available_permits()
    }

    /// Takes slots for a request of `methods` methods and predicted `cost` from `client`: one,
    /// plus up to `methods − 1` more shared slots that are free right now.
    ///
    /// Short work takes a shared slot or a short-lane slot, whichever frees first within the
    /// queue timeout. Long work takes only shared slots, waiting its turn in order of arrival up
    /// to the long queue timeout; a client has one long request waiting at most, so one client's
    /// burst cannot push everyone else's out. Otherwise 503.
    pub async fn acquire(
        &self,
        methods: usize,
        cost: Cost,
        client: Option<IpAddr>,
    ) -> Result<Vec<OwnedSemaphorePermit>, ApiError> {
        let first = if cost.is_short(&self.config) {
            self.acquire_short().await
        } else {
            self.acquire_long(client).await
        };
        let Some(first) = first else {
            tracing::info!(?cost, "no simulation slot free in time; answering 503");
            return Err(ApiError::overloaded(1));
        };
        let mut permits = vec![first];
        while permits.len() < methods {
            match self.permits.clone().try_acquire_owned() {
                Ok(p) => permits.push(p),
                Err(_) => break,
            }
        }
        Ok(permits)
    }

    async fn acquire_short(&self) -> Option<OwnedSemaphorePermit> {
        if let Ok(p) = self.permits.clone().try_acquire_owned() {
            return Some(p);
        }
        if let Ok(p) = self.short_lane.clone().try_acquire_owned() {
            return Some(p);
        }
        let either = async {
            tokio::select! {
                p = self.permits.clone().acquire_owned() => p,
                p = self.short_lane.clone().acquire_owned() => p,
            }
        };
        match tokio::time::timeout(self.config.queue_timeout, either).await {
            Ok(Ok(p)) => Some(p),
            _ => None,
        }
    }

    async fn acquire_long(&self, client: Option<IpAddr>) -> Option<OwnedSemaphorePermit> {
        if let Ok(p) = self.permits.clone().try_acquire_owned() {
            return Some(p);
        }
        let _waiting = match client {
            Some(ip) => Some(WaitingLong::enter(&self.waiting_long, ip)?),
            None => None,
        };
        let wait = self.permits.clone().acquire_owned();
        match tokio::time::timeout(self.config.long_queue_timeout, wait).await {
            Ok(Ok(p)) => Some(p),
            _ => None,
        }
    }

    /// What the jobs take from the service (a job's part that runs here takes one of its shared
    /// slots while it runs).
    pub fn job_context(&self) -> JobContext {
        JobContext {
            systems: self.systems.clone(),
            limits: self.config.limits.clone(),
            executor: self.executor.clone(),
            usage: self.access.usage.clone(),
            slots: self.permits.clone(),
            recordings: self.recordings.clone(),
        }
    }

    /// Cancels every running simulation (they end with `cancelled`) and makes new ones cancel
    /// at once. Used at shutdown.
    pub fn cancel_runs(&self) {
        self.shutdown.send_replace(true);
    }

    /// A receiver that turns true when runs are to be cancelled.
    pub fn cancellation(&self) -> watch::Receiver<bool> {
        self.shutdown.subscribe()
    }
}

/// A client's place in the queue of long work, given up when dropped.
struct WaitingLong {
    queue: Arc<Mutex<HashMap<IpAddr, usize>>>,
    client: IpAddr,
}

impl WaitingLong {
    /// The place of `client`, unless it already waits with another long request.
    fn enter(queue: &Arc<Mutex<HashMap<IpAddr, usize>>>, client: IpAddr) -> Option<Self> {
        let mut waiting = queue.lock().unwrap_or_else(|p| p.into_inner());
        let count = waiting.entry(client).or_insert(0);
        if *count >= 1 {
            return None;
        }
        *count += 1;
        Some(Self {
            queue: queue.clone(),
            client,
        })
    }
}

impl Drop for WaitingLong {
    fn drop(&mut self) {
        let mut waiting = self.queue.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(count) = waiting.get_mut(&self.client) {
            *count -= 1;
            if *count == 0 {
                waiting.remove(&self.client);
            }
        }
    }
}

/// Runs blocking work on tokio's blocking pool inside the caller's tracing span. A panic
/// becomes a 500 (its message is logged, not sent).
pub async fn run_blocking<F, T>(work: F) -> Result<T, ApiError>
where
    F: FnOnce() -> T + Send + 'static,
    T: Send + 'static,
{
    let span = tracing::Span::current();
    match tokio::task::spawn_blocking(move || span.in_scope(work)).await {
        Ok(value) => Ok(value),
        Err(e) if e.is_panic() => {
            let panic = e.into_panic();
            let message = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic without a message".to_string());
            Err(ApiError::internal(format!(
                "computation panicked: {message}"
            )))
        }
        Err(e) => Err(ApiError::internal(format!("computation task failed: {e}"))),
    }
}
