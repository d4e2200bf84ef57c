//! Service configuration and shared state: the limits, the semaphore that bounds concurrent
//! runs, the shutdown signal that cancels runs, the recording and system stores, and the helper that moves
//! blocking work off the async runtime.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::{watch, OwnedSemaphorePermit, Semaphore};

use super::error::ApiError;
use super::store::RecordingStore;
use super::systems::{SystemStore, DEFAULT_MAX_SYSTEMS, DEFAULT_SYSTEMS_DIR};
use crate::core::simulation::Limits;

/// Settings of the service.
#[derive(Clone, Debug)]
pub struct Config {
    /// Step and sample limits per request.
    pub limits: Limits,
    /// Most simulation threads at once (a request takes one per method while free, at least one).
    pub max_concurrent: usize,
    /// Time limit of a simulation: runs still going then stop with `time_limit`.
    pub request_timeout: Duration,
    /// How long a request waits for a free slot before it is answered 503.
    pub queue_timeout: Duration,
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
}

/// The default directory of stored recordings.
pub const DEFAULT_DATA_DIR: &str = "./data/recordings";
/// The default cap on stored recordings: 1 GiB.
pub const DEFAULT_RECORDINGS_MAX_BYTES: u64 = 1 << 30;

/// The number of cores, the default of [`Config::max_concurrent`].
pub fn default_concurrency() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
}

impl Default for Config {
    fn default() -> Self {
        Self {
            limits: Limits::default(),
            max_concurrent: default_concurrency(),
            request_timeout: Duration::from_secs(60),
            queue_timeout: Duration::from_millis(250),
            cors_origins: Vec::new(),
            static_dir: None,
            body_limit: 1 << 20,
            shutdown_grace: Duration::from_secs(10),
            data_dir: PathBuf::from(DEFAULT_DATA_DIR),
            recordings_max_bytes: DEFAULT_RECORDINGS_MAX_BYTES,
            systems_dir: PathBuf::from(DEFAULT_SYSTEMS_DIR),
            max_systems: DEFAULT_MAX_SYSTEMS,
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
    /// The NATS work queue that runs sweeps, when the server has one (else they run here).
    pub queue: Option<Arc<crate::nats::Queue>>,
    permits: Arc<Semaphore>,
    shutdown: Arc<watch::Sender<bool>>,
}

impl AppState {
    /// State for `config`; reads back the recordings and system definitions stored before.
    pub fn new(config: Config) -> Self {
        let max = config.max_concurrent.max(1);
        let recordings = RecordingStore::open(&config.data_dir, config.recordings_max_bytes);
        let systems = SystemStore::open(&config.systems_dir, config.max_systems);
        Self {
            recordings: Arc::new(recordings),
            systems: Arc::new(systems),
            queue: None,
            config: Arc::new(Config {
                max_concurrent: max,
                ..config
            }),
            permits: Arc::new(Semaphore::new(max)),
            shutdown: Arc::new(watch::channel(false).0),
        }
    }

    /// The same state, running sweeps on the workers of `queue`.
    pub fn with_queue(mut self, queue: Option<crate::nats::Queue>) -> Self {
        self.queue = queue.map(Arc::new);
        self
    }

    /// Simulation threads running now.
    pub fn runs_in_progress(&self) -> usize {
        self.config.max_concurrent - self.permits.available_permits()
    }

    /// Takes slots for a request of `methods` methods: one, waiting up to the queue timeout
    /// (else 503), plus up to `methods − 1` more that are free right now.
    pub async fn acquire(&self, methods: usize) -> Result<Vec<OwnedSemaphorePermit>, ApiError> {
        let first = match self.permits.clone().try_acquire_owned() {
            Ok(p) => p,
            Err(_) => {
                let wait = self.config.queue_timeout;
                match tokio::time::timeout(wait, self.permits.clone().acquire_owned()).await {
                    Ok(Ok(p)) => p,
                    _ => {
                        tracing::info!("no simulation slot free; answering 503");
                        return Err(ApiError::overloaded(1));
                    }
                }
            }
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
