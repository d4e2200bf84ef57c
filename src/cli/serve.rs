//! `geomint serve`: the HTTP service with its settings (flags or `GEOMINT_*` variables), sweeps
//! run on NATS workers with `--nats`; and `geomint worker --nats URL`, such a worker.

use std::io::{self, IsTerminal};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::Args;

use super::parse_count;
use crate::access::{read_tokens, AccessConfig, Anonymous, Quotas};
use crate::core::simulation::Limits;
use crate::http::{self, Config};
use crate::nats::options::NatsOptions;
use crate::nats::{self, Queue};

/// Settings of `geomint serve`.
#[derive(Clone, Debug, Args)]
pub struct ServeArgs {
    /// Address to listen on.
    #[arg(long, env = "GEOMINT_ADDR", default_value = "127.0.0.1:8080")]
    pub addr: SocketAddr,
    /// Most steps per method (1e7 style accepted).
    #[arg(long, env = "GEOMINT_MAX_STEPS", default_value = "10000000", value_parser = parse_count)]
    pub max_steps: u64,
    /// Most samples per request over all methods.
    #[arg(long, env = "GEOMINT_MAX_SAMPLES", default_value = "1000000", value_parser = parse_count)]
    pub max_samples: u64,
    /// Most simulation threads at once (default: the number of cores).
    #[arg(long, env = "GEOMINT_MAX_CONCURRENT", value_parser = clap::value_parser!(u64).range(1..=4096))]
    pub max_concurrent: Option<u64>,
    /// Time limit of a simulation in seconds; runs then stop with `time_limit`.
    #[arg(long, env = "GEOMINT_REQUEST_TIMEOUT_SECS", default_value_t = 60, value_parser = clap::value_parser!(u64).range(1..))]
    pub request_timeout_secs: u64,
    /// How long a request waits for a free simulation slot before it gets 503, in milliseconds.
    #[arg(long, env = "GEOMINT_QUEUE_TIMEOUT_MS", default_value_t = 250)]
    pub queue_timeout_ms: u64,
    /// How long long work (more than --short-work step-coordinates, and every study) waits its
    /// turn for a slot before it gets 503, in seconds; a client has one such request waiting.
    #[arg(long, env = "GEOMINT_LONG_QUEUE_TIMEOUT_SECS", default_value_t = 5)]
    pub long_queue_timeout_secs: u64,
    /// Simulation slots kept for short work beside --max-concurrent: small runs are served while
    /// long ones hold every other slot.
    #[arg(long, env = "GEOMINT_SHORT_LANE", default_value_t = 1, value_parser = clap::value_parser!(u64).range(0..=4096))]
    pub short_lane: u64,
    /// The largest run that counts as short work, in steps × phase-space coordinates over its
    /// methods (1e5 style accepted).
    #[arg(long, env = "GEOMINT_SHORT_WORK", default_value = "200000", value_parser = parse_count)]
    pub short_work: u64,
    /// Most open connections; past it new ones wait in the listen backlog.
    #[arg(long, env = "GEOMINT_MAX_CONNECTIONS", default_value_t = 1024, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    pub max_connections: u64,
    /// Seconds a client has to send a request's head; an idle keep-alive connection is closed
    /// after as long.
    #[arg(long, env = "GEOMINT_HEADER_TIMEOUT_SECS", default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..))]
    pub header_timeout_secs: u64,
    /// Seconds a client has to send a request's body (408 after).
    #[arg(long, env = "GEOMINT_BODY_TIMEOUT_SECS", default_value_t = 60, value_parser = clap::value_parser!(u64).range(1..))]
    pub body_timeout_secs: u64,
    /// Origins allowed by CORS, comma-separated, or `*` (default: CORS off).
    #[arg(long, env = "GEOMINT_CORS_ORIGINS", value_delimiter = ',')]
    pub cors_origins: Vec<String>,
    /// Directory served at `/`, if it exists.
    #[arg(long, env = "GEOMINT_STATIC_DIR", default_value = "static")]
    pub static_dir: PathBuf,
    /// Largest request body in bytes.
    #[arg(long, env = "GEOMINT_BODY_LIMIT", default_value = "1048576", value_parser = parse_count)]
    pub body_limit: u64,
    /// Seconds running simulations may go on after a shutdown signal before they are cancelled.
    #[arg(long, env = "GEOMINT_SHUTDOWN_GRACE_SECS", default_value_t = 10)]
    pub shutdown_grace_secs: u64,
    /// Directory of the stored Rerun recordings (created when the first one is stored).
    #[arg(long, env = "GEOMINT_DATA_DIR", default_value = http::state::DEFAULT_DATA_DIR)]
    pub data_dir: PathBuf,
    /// Most bytes of stored recordings; past it the oldest are deleted (1e9 style accepted).
    #[arg(long, env = "GEOMINT_RECORDINGS_MAX_BYTES", default_value = "1073741824", value_parser = parse_count)]
    pub recordings_max_bytes: u64,
    /// Directory of the stored system definitions (created when the first one is stored).
    #[arg(long, env = "GEOMINT_SYSTEMS_DIR", default_value = crate::store::systems::DEFAULT_SYSTEMS_DIR)]
    pub systems_dir: PathBuf,
    /// Most stored system definitions.
    #[arg(long, env = "GEOMINT_MAX_SYSTEMS", default_value_t = crate::store::systems::DEFAULT_MAX_SYSTEMS)]
    pub max_systems: usize,
    /// Directory of the jobs, their finished parts and results (default: `jobs` beside the data
    /// directory, e.g. `./data/jobs`).
    #[arg(long, env = "GEOMINT_JOBS_DIR")]
    pub jobs_dir: Option<PathBuf>,
    /// Most unfinished jobs per owner.
    #[arg(long, env = "GEOMINT_MAX_JOBS_PER_OWNER", default_value_t = crate::jobs::DEFAULT_MAX_JOBS_PER_OWNER as u64, value_parser = clap::value_parser!(u64).range(1..))]
    pub max_jobs_per_owner: u64,
    /// About how many steps each stored part of a job takes: the work a restart can lose, and
    /// the grain at which owners' jobs take turns (1e8 style accepted).
    #[arg(long, env = "GEOMINT_JOB_PART_STEPS", default_value = "100000000", value_parser = parse_count)]
    pub job_part_steps: u64,
    /// Parts of jobs in flight at once on the NATS workers (with --nats; without, a part takes
    /// every core and parts run one at a time).
    #[arg(long, env = "GEOMINT_JOB_PARTS_IN_FLIGHT", default_value_t = crate::jobs::DEFAULT_PARTS_IN_FLIGHT as u64, value_parser = clap::value_parser!(u64).range(1..=64))]
    pub job_parts_in_flight: u64,
    /// Seconds a job may run under one server before it fails (its finished parts are kept).
    #[arg(long, env = "GEOMINT_JOB_TIME_LIMIT_SECS", default_value_t = 86_400, value_parser = clap::value_parser!(u64).range(1..))]
    pub job_time_limit_secs: u64,
    /// Log filter (tracing's EnvFilter syntax).
    #[arg(long, env = "GEOMINT_LOG", default_value = "info")]
    pub log: String,
    /// Log lines as text or as one JSON object each (the access log included).
    #[arg(long, env = "GEOMINT_LOG_FORMAT", value_enum, default_value_t = LogFormat::Text)]
    pub log_format: LogFormat,
    /// The tokens file: names, scopes, quotas and SHA-256 digests of the secrets (`geomint token`
    /// makes the lines). Reloaded when it changes and on SIGHUP. Requests then authenticate with
    /// `Authorization: Bearer <secret>`.
    #[arg(long, env = "GEOMINT_TOKENS")]
    pub tokens: Option<PathBuf>,
    /// What clients without a token may do: `all` (everything), `public` (read, and run
    /// simulations within --short-work), `none`. Default: `all` on a loopback address without
    /// --tokens, `none` with --tokens; another address needs --tokens, --public or this.
    #[arg(long, env = "GEOMINT_ANONYMOUS", value_enum)]
    pub anonymous: Option<Anonymous>,
    /// The same as --anonymous public.
    #[arg(long, env = "GEOMINT_PUBLIC", conflicts_with = "anonymous")]
    pub public: bool,
    /// Runs in flight per address of clients without a token (default 2 with --public, else
    /// unbounded).
    #[arg(long, env = "GEOMINT_ANONYMOUS_RUNS")]
    pub anonymous_runs: Option<usize>,
    /// Steps × coordinates per minute per address of clients without a token (default 60 ×
    /// --short-work with --public, else unbounded; 1e9 style accepted).
    #[arg(long, env = "GEOMINT_ANONYMOUS_STEPS_PER_MINUTE", value_parser = parse_count)]
    pub anonymous_steps_per_minute: Option<u64>,
    /// Run sweeps on the workers of this NATS server (JetStream on), e.g. nats://host:4222,
    /// instead of on this machine's cores. The server must answer at start-up.
    #[arg(long, env = "GEOMINT_NATS_URL")]
    pub nats: Option<String>,
    /// Seconds a worker may hold a shard without reporting progress before it goes to another
    /// (applies when this process creates the workers' consumer).
    #[arg(long, env = "GEOMINT_NATS_ACK_WAIT_SECS", default_value_t = 30, value_parser = clap::value_parser!(u64).range(1..=3600))]
    pub nats_ack_wait_secs: u64,
    /// Steps of work per shard a sweep on NATS workers is split into (smaller: finer balance
    /// and less lost with a worker, more messages).
    #[arg(long, env = "GEOMINT_NATS_SHARD_STEPS", default_value = "20000000", value_parser = parse_count)]
    pub nats_shard_steps: u64,
    /// The JetStream object store that keeps the jobs' files besides the jobs directory (made if
    /// missing), from which a server that lost its disk takes them back; `off` keeps them on
    /// disk only. Servers that share one share their jobs: give each server its own, unless it
    /// replaces another.
    #[arg(long, env = "GEOMINT_NATS_JOBS_BUCKET", default_value = crate::nats::jobs_bucket::DEFAULT_BUCKET)]
    pub nats_jobs_bucket: String,
    /// NATS credentials, TLS and deliveries.
    #[command(flatten)]
    pub nats_options: NatsArgs,
}

/// How `serve` and `worker` connect to NATS.
#[derive(Clone, Debug, Args)]
pub struct NatsArgs {
    /// A NATS credentials file (`.creds`: a user's JWT and NKey seed).
    #[arg(long, env = "GEOMINT_NATS_CREDS")]
    pub nats_creds: Option<PathBuf>,
    /// The certificate authority (PEM) that signs the NATS server's certificate; the connection
    /// then requires TLS.
    #[arg(long, env = "GEOMINT_NATS_TLS_CA")]
    pub nats_tls_ca: Option<PathBuf>,
    /// Deliveries of a study's shard before the study fails (a shard that panics or kills its
    /// worker); applies when this process creates the workers' consumer, or bounds one that has
    /// no bound.
    #[arg(long, env = "GEOMINT_NATS_MAX_DELIVER", default_value_t = crate::nats::poison::DEFAULT_MAX_DELIVER, value_parser = clap::value_parser!(i64).range(1..=1000))]
    pub nats_max_deliver: i64,
    /// Copies of the shard stream in a JetStream cluster (1, 3 or 5), so that the queue outlives
    /// a NATS server; applies when this process creates the stream.
    #[arg(long, env = "GEOMINT_NATS_REPLICAS", default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=5))]
    pub nats_replicas: u8,
}

impl NatsArgs {
    fn options(&self) -> NatsOptions {
        NatsOptions {
            creds: self.nats_creds.clone(),
            tls_ca: self.nats_tls_ca.clone(),
            max_deliver: self.nats_max_deliver,
            replicas: self.nats_replicas.into(),
        }
    }
}

/// Settings of `geomint worker`.
#[derive(Clone, Debug, Args)]
pub struct WorkerArgs {
    /// The NATS server (JetStream on) whose sweep shards this worker runs.
    #[arg(long, env = "GEOMINT_NATS_URL")]
    pub nats: String,
    /// Seconds a worker may hold a shard without reporting progress before it goes to another
    /// (applies when this process creates the workers' consumer).
    #[arg(long, env = "GEOMINT_NATS_ACK_WAIT_SECS", default_value_t = 30, value_parser = clap::value_parser!(u64).range(1..=3600))]
    pub ack_wait_secs: u64,
    /// Most steps per run a shard may ask for.
    #[arg(long, env = "GEOMINT_MAX_STEPS", default_value = "10000000", value_parser = parse_count)]
    pub max_steps: u64,
    /// NATS credentials, TLS and deliveries.
    #[command(flatten)]
    pub nats_options: NatsArgs,
    /// Log filter (tracing's EnvFilter syntax).
    #[arg(long, env = "GEOMINT_LOG", default_value = "info")]
    pub log: String,
    /// Log lines as text or as one JSON object each.
    #[arg(long, env = "GEOMINT_LOG_FORMAT", value_enum, default_value_t = LogFormat::Text)]
    pub log_format: LogFormat,
}

/// How log lines are written.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LogFormat {
    /// Human-readable text.
    Text,
    /// One JSON object a line.
    Json,
}

impl ServeArgs {
    /// The service configuration these settings describe.
    pub fn config(&self) -> Config {
        Config {
            limits: Limits {
                max_steps: self.max_steps,
                max_samples: self.max_samples,
            },
            max_concurrent: self
                .max_concurrent
                .map_or_else(crate::executor::cores, |n| n as usize),
            request_timeout: Duration::from_secs(self.request_timeout_secs),
            queue_timeout: Duration::from_millis(self.queue_timeout_ms),
            long_queue_timeout: Duration::from_secs(self.long_queue_timeout_secs),
            short_lane: self.short_lane as usize,
            short_work: self.short_work,
            max_connections: self.max_connections as usize,
            header_timeout: Duration::from_secs(self.header_timeout_secs),
            body_timeout: Duration::from_secs(self.body_timeout_secs),
            cors_origins: self.cors_origins.clone(),
            static_dir: Some(self.static_dir.clone()),
            body_limit: usize::try_from(self.body_limit).unwrap_or(usize::MAX),
            shutdown_grace: Duration::from_secs(self.shutdown_grace_secs),
            data_dir: self.data_dir.clone(),
            recordings_max_bytes: self.recordings_max_bytes,
            systems_dir: self.systems_dir.clone(),
            max_systems: self.max_systems,
            access: AccessConfig::default(),
            jobs: Some(crate::jobs::JobsConfig {
                dir: self.jobs_dir.clone().unwrap_or_else(|| {
                    let parent = self.data_dir.parent().unwrap_or(std::path::Path::new(""));
                    parent.join("jobs")
                }),
                max_per_owner: usize::try_from(self.max_jobs_per_owner).unwrap_or(usize::MAX),
                part_steps: self.job_part_steps.max(1),
                time_limit: Duration::from_secs(self.job_time_limit_secs),
                parts_in_flight: match self.nats {
                    Some(_) => usize::try_from(self.job_parts_in_flight).unwrap_or(1),
                    None => 1,
                },
            }),
        }
    }

    /// Who may do what under these settings: the tokens file (checked now) and the policy for
    /// clients without a token. An address other machines reach needs the policy said.
    pub fn access(&self) -> Result<AccessConfig, String> {
        if let Some(path) = &self.tokens {
            read_tokens(path)?;
        }
        let anonymous = match (self.anonymous, self.public) {
            (Some(policy), _) => policy,
            (None, true) => Anonymous::Public,
            (None, false) if self.tokens.is_some() => Anonymous::None,
            (None, false) if self.addr.ip().is_loopback() => Anonymous::All,
            (None, false) => {
                return Err(format!(
                    "{} is reachable from other machines, and without a tokens file anyone who \
                     reaches it could delete every recording: pass --tokens FILE (`geomint \
                     token` makes its lines), --public (clients may read and run small runs), or \
                     --anonymous all (anyone may do everything, as on a single user's machine)",
                    self.addr
                ))
            }
        };
        let public = anonymous == Anonymous::Public;
        Ok(AccessConfig {
            tokens_file: self.tokens.clone(),
            anonymous,
            anonymous_quotas: Quotas {
                runs: self.anonymous_runs.or(public.then_some(2)),
                steps_per_minute: self
                    .anonymous_steps_per_minute
                    .or(public.then(|| self.short_work.saturating_mul(60))),
                ..Quotas::default()
            },
        })
    }
}

/// Logs to standard error with `filter`, as text or JSON lines.
fn init_logging(filter: &str, format: LogFormat) {
    let parsed = tracing_subscriber::EnvFilter::try_new(filter).unwrap_or_else(|e| {
        eprintln!("warning: invalid log filter `{filter}` ({e}); using `info`");
        tracing_subscriber::EnvFilter::new("info")
    });
    let builder = tracing_subscriber::fmt()
        .with_env_filter(parsed)
        .with_writer(io::stderr);
    match format {
        LogFormat::Text => builder.with_ansi(io::stderr().is_terminal()).init(),
        LogFormat::Json => builder.json().flatten_event(true).init(),
    }
}

/// Settles glibc's malloc for a process that runs for days, before its threads start: at most
/// four arenas (glibc's default, eight per core, lets most threads that ever allocated keep one
/// of their own), and a fixed threshold of 128 KiB above which blocks are mapped and given back
/// on free (the default threshold climbs after each large free, so that large transient buffers,
/// request bodies and recordings, end up in the arenas and stay there). Measured with
/// `scripts/soak` over ten minutes: the defaults grew the resident memory by a third, the
/// threshold alone as much, two arenas by 9 % but at a cost in throughput under contention, four
/// arenas with the threshold by 6 % (the README's figures). `MALLOC_ARENA_MAX` or
/// `MALLOC_MMAP_THRESHOLD_` in the environment take precedence.
fn tune_allocator() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        const ARENAS: libc::c_int = 4;
        const MMAP_THRESHOLD: libc::c_int = 128 * 1024;
        for (variable, parameter, value) in [
            ("MALLOC_ARENA_MAX", libc::M_ARENA_MAX, ARENAS),
            (
                "MALLOC_MMAP_THRESHOLD_",
                libc::M_MMAP_THRESHOLD,
                MMAP_THRESHOLD,
            ),
        ] {
            if std::env::var_os(variable).is_none() {
                // SAFETY: mallopt only sets allocator parameters; it is called before the
                // process starts its other threads.
                if unsafe { libc::mallopt(parameter, value) } != 1 {
                    tracing::warn!(parameter = variable, "mallopt refused the setting");
                }
            }
        }
    }
}

/// The async runtime of the server and the worker (with the allocator settled first).
fn runtime() -> Result<tokio::runtime::Runtime, ExitCode> {
    tune_allocator();
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(|e| {
            eprintln!("error: cannot start the async runtime: {e}");
            ExitCode::FAILURE
        })
}

/// Connects to the NATS server, or says why not.
fn connect(
    runtime: &tokio::runtime::Runtime,
    url: &str,
    ack_wait_secs: u64,
    options: &NatsArgs,
) -> Result<Queue, ExitCode> {
    let options = options.options();
    runtime
        .block_on(Queue::connect(
            url,
            Duration::from_secs(ack_wait_secs),
            &options,
        ))
        .map_err(|e| {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        })
}

pub(crate) fn serve(args: &ServeArgs) -> ExitCode {
    init_logging(&args.log, args.log_format);
    let mut config = args.config();
    config.access = match args.access() {
        Ok(access) => access,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let runtime = match runtime() {
        Ok(rt) => rt,
        Err(code) => return code,
    };
    let queue = match &args.nats {
        None => None,
        Some(url) => match connect(&runtime, url, args.nats_ack_wait_secs, &args.nats_options) {
            Ok(mut queue) => {
                queue.steps_per_shard = args.nats_shard_steps.max(1);
                let bucket = args.nats_jobs_bucket.as_str();
                if config.jobs.is_some() && bucket != crate::nats::jobs_bucket::NO_BUCKET {
                    match runtime.block_on(queue.jobs_bucket(bucket)) {
                        Ok(bucket) => queue.jobs_bucket = Some(std::sync::Arc::new(bucket)),
                        Err(e) => {
                            eprintln!("error: {e}");
                            return ExitCode::FAILURE;
                        }
                    }
                }
                Some(queue)
            }
            Err(code) => return code,
        },
    };
    match runtime.block_on(http::serve(args.addr, config, queue)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: cannot serve on {}: {e}", args.addr);
            ExitCode::FAILURE
        }
    }
}

/// `geomint worker`: runs sweep shards from the NATS server for as long as it lives (a lost
/// connection is retried); fails when no server answers at the start.
pub(crate) fn work(args: &WorkerArgs) -> ExitCode {
    init_logging(&args.log, args.log_format);
    let runtime = match runtime() {
        Ok(rt) => rt,
        Err(code) => return code,
    };
    let queue = match connect(&runtime, &args.nats, args.ack_wait_secs, &args.nats_options) {
        Ok(queue) => queue,
        Err(code) => return code,
    };
    let limits = Limits {
        max_steps: args.max_steps,
        ..Limits::default()
    };
    match runtime.block_on(nats::work(&queue, limits)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
