//! Who may do what: bearer tokens with scopes and quotas, the policy for clients without a
//! token, and the caller every request is made by.
//!
//! - [`tokens`]: the tokens file (names, scopes, quotas and digests of the secrets), read at
//!   start-up and again when it changes or on SIGHUP ([`Access::reload`]).
//! - [`reload`]: the file read again on SIGHUP or when it changes.
//! - [`usage`]: what callers use now that no store records: runs in flight and steps in the last
//!   minute.
//!
//! A request's [`Caller`] is a token's (its name owns what it stores, its quotas bound it) or an
//! anonymous client's, keyed by its address (`anonymous@ADDRESS`). What an anonymous client may
//! do is the server's [`Anonymous`] policy: everything on a loopback address without a tokens
//! file (as a single user's machine always did), reading and small runs with `--public`, nothing
//! but the page, the health check and the OpenAPI document otherwise. Scopes are checked per
//! route by the HTTP layer (`http::auth`); ownership by the stores; quotas where work is admitted
//! and where things are stored.

pub mod reload;
pub mod tokens;
pub mod usage;

use std::net::IpAddr;
use std::path::PathBuf;
use std::sync::{Arc, RwLock};

use serde::Serialize;
use utoipa::ToSchema;

use crate::core::error::{ErrorCode, ErrorDetail};
use tokens::{TokenFile, MAX_SECRET_LEN};
pub use usage::{RunGuard, Usage};

/// What a token may do. `admin` includes the others.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Scope {
    /// Read the catalogues, stored systems and recordings.
    Read,
    /// Run simulations and studies.
    Run,
    /// Store recordings and systems, and delete its own.
    Store,
    /// Everything, and delete what others stored.
    Admin,
}

impl Scope {
    /// Every scope, in order.
    pub const ALL: [Scope; 4] = [Scope::Read, Scope::Run, Scope::Store, Scope::Admin];

    /// Its name in the tokens file, the OpenAPI document and error messages.
    pub fn name(self) -> &'static str {
        match self {
            Scope::Read => "read",
            Scope::Run => "run",
            Scope::Store => "store",
            Scope::Admin => "admin",
        }
    }

    fn bit(self) -> u8 {
        1 << self as u8
    }
}

/// A set of scopes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Scopes(u8);

impl Scopes {
    /// No scope.
    pub const NONE: Scopes = Scopes(0);
    /// Every scope.
    pub const ALL: Scopes = Scopes(0b1111);

    /// The scopes of `list`.
    pub fn of(list: &[Scope]) -> Scopes {
        Scopes(list.iter().fold(0, |bits, s| bits | s.bit()))
    }

    /// Reads `read,run,…` (at least one, each known).
    pub fn parse(text: &str) -> Result<Scopes, String> {
        let mut bits = 0;
        for name in text.split(',') {
            let scope = Scope::ALL
                .into_iter()
                .find(|s| s.name() == name)
                .ok_or_else(|| format!("unknown scope `{name}`; known: read, run, store, admin"))?;
            bits |= scope.bit();
        }
        Ok(Scopes(bits))
    }

    /// Whether these scopes grant `scope` (`admin` grants every one).
    pub fn grants(self, scope: Scope) -> bool {
        self.has(scope) || self.has(Scope::Admin)
    }

    /// Whether `scope` is in the set itself.
    pub fn has(self, scope: Scope) -> bool {
        self.0 & scope.bit() != 0
    }

    /// The scopes in the set.
    pub fn list(self) -> Vec<Scope> {
        Scope::ALL.into_iter().filter(|s| self.has(*s)).collect()
    }
}

/// Limits on what one caller uses; `None` is bounded only by the service's own limits.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, ToSchema)]
pub struct Quotas {
    /// Bytes of stored recordings; past it the caller's own oldest recordings are evicted.
    pub recordings_bytes: Option<u64>,
    /// Stored system definitions.
    pub systems: Option<usize>,
    /// Runs and studies in flight at once.
    pub runs: Option<usize>,
    /// Steps (step × phase-space coordinates over a request's runs, as the small-run budget
    /// counts them) of simulations started in any minute.
    pub steps_per_minute: Option<u64>,
}

impl Quotas {
    /// The quotas set, as the tokens file writes them (`key=value`).
    pub fn items(&self) -> Vec<String> {
        [
            ("recordings_bytes", self.recordings_bytes),
            ("systems", self.systems.map(|n| n as u64)),
            ("runs", self.runs.map(|n| n as u64)),
            ("steps_per_minute", self.steps_per_minute),
        ]
        .into_iter()
        .filter_map(|(key, value)| value.map(|v| format!("{key}={v}")))
        .collect()
    }
}

/// What a client without a token may do.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Anonymous {
    /// Everything, deleting anything included: a server only its own machine reaches.
    All,
    /// Read, and run simulations within the small-run budget (`--short-work`).
    Public,
    /// Nothing but the page, the health check and the OpenAPI document.
    None,
}

/// Who makes a request.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct Caller {
    /// The owner of what it stores and the key of its quotas: the token's name, or
    /// `anonymous@ADDRESS`.
    #[schema(example = "alice")]
    pub owner: String,
    /// Whether it sent a valid token.
    pub token: bool,
    /// What it may do.
    #[schema(value_type = Vec<Scope>)]
    #[serde(serialize_with = "scope_list")]
    pub scopes: Scopes,
    /// Its quotas.
    pub quotas: Quotas,
    /// The largest simulation it may run, in steps × phase-space coordinates (the small-run
    /// budget of an anonymous client of a public server); studies are refused with it.
    pub largest_run: Option<u64>,
}

fn scope_list<S: serde::Serializer>(scopes: &Scopes, s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(scopes.list())
}

impl Caller {
    /// An anonymous client at `address` under `policy`.
    fn anonymous(
        address: Option<IpAddr>,
        policy: Anonymous,
        quotas: Quotas,
        short_work: u64,
    ) -> Self {
        let (scopes, largest_run) = match policy {
            Anonymous::All => (Scopes::ALL, None),
            Anonymous::Public => (Scopes::of(&[Scope::Read, Scope::Run]), Some(short_work)),
            Anonymous::None => (Scopes::NONE, None),
        };
        Caller {
            owner: match address {
                Some(ip) => format!("anonymous@{ip}"),
                None => "anonymous".to_string(),
            },
            token: false,
            scopes,
            quotas,
            largest_run,
        }
    }

    /// Whether it may use a route that needs `scope`; the refusal is 401 for a client without
    /// a token (a token would help), 403 for a token without the scope.
    pub fn require(&self, scope: Scope) -> Result<(), Refusal> {
        if self.scopes.grants(scope) {
            return Ok(());
        }
        let name = scope.name();
        Err(if self.token {
            refusal(
                ErrorCode::Forbidden,
                format!(
                    "the token `{}` lacks the `{name}` scope this route needs",
                    self.owner
                ),
            )
        } else {
            refusal(
                ErrorCode::Unauthorized,
                format!("this route needs a token with the `{name}` scope: send `Authorization: Bearer <token>`"),
            )
        })
    }

    /// Whether it may delete what `owners` own: an owner of it, or `admin`. Unowned things
    /// (stored before ownership was recorded) only `admin` deletes.
    pub fn may_delete<'a>(&self, mut owners: impl Iterator<Item = &'a str>) -> bool {
        self.scopes.grants(Scope::Admin) || owners.any(|o| o == self.owner)
    }
}

fn refusal(code: ErrorCode, message: String) -> Refusal {
    Refusal::from(ErrorDetail::at(code, "Authorization", message))
}

/// Why a caller may not go on: the error as the API reports it (its code gives the HTTP
/// status), and for a quota that frees up, when to try again.
#[derive(Debug)]
pub struct Refusal {
    /// The error.
    pub detail: ErrorDetail,
    /// Seconds until a retry may succeed (the `Retry-After` header).
    pub retry_after_secs: Option<u64>,
}

impl Refusal {
    /// The refusal with a time to retry after.
    pub fn with_retry_after(mut self, secs: u64) -> Self {
        self.retry_after_secs = Some(secs);
        self
    }
}

impl From<ErrorDetail> for Refusal {
    fn from(detail: ErrorDetail) -> Self {
        Refusal {
            detail,
            retry_after_secs: None,
        }
    }
}

/// The access settings of a server.
#[derive(Clone, Debug)]
pub struct AccessConfig {
    /// The tokens file; without one an `Authorization` header is ignored.
    pub tokens_file: Option<PathBuf>,
    /// What clients without a token may do.
    pub anonymous: Anonymous,
    /// The quotas of each anonymous client address.
    pub anonymous_quotas: Quotas,
}

impl Default for AccessConfig {
    fn default() -> Self {
        AccessConfig {
            tokens_file: None,
            anonymous: Anonymous::All,
            anonymous_quotas: Quotas::default(),
        }
    }
}

/// The tokens in force, the anonymous policy and what callers use.
#[derive(Debug)]
pub struct Access {
    config: AccessConfig,
    short_work: u64,
    tokens: RwLock<Arc<TokenFile>>,
    /// Runs in flight and recent steps per caller.
    pub usage: Arc<Usage>,
}

/// Reads a tokens file, naming it in the error.
pub fn read_tokens(path: &std::path::Path) -> Result<TokenFile, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read the tokens file {}: {e}", path.display()))?;
    TokenFile::parse(&text).map_err(|e| format!("the tokens file {}: {e}", path.display()))
}

impl Access {
    /// Access under `config`; a tokens file that cannot be read admits no token (the command line
    /// checks it before the server starts).
    pub fn new(config: AccessConfig, short_work: u64) -> Self {
        let tokens = match &config.tokens_file {
            Some(path) => read_tokens(path).unwrap_or_else(|e| {
                tracing::error!(error = %e, "no token is valid until the file is fixed");
                TokenFile::default()
            }),
            None => TokenFile::default(),
        };
        Access {
            config,
            short_work,
            tokens: RwLock::new(Arc::new(tokens)),
            usage: Arc::default(),
        }
    }

    /// The anonymous policy.
    pub fn anonymous(&self) -> Anonymous {
        self.config.anonymous
    }

    /// The tokens file, if any.
    pub fn tokens_file(&self) -> Option<&std::path::Path> {
        self.config.tokens_file.as_deref()
    }

    /// Reads the tokens file again; on an error the tokens in force stay. The number of tokens.
    pub fn reload(&self) -> Result<usize, String> {
        let Some(path) = &self.config.tokens_file else {
            return Ok(0);
        };
        let file = read_tokens(path)?;
        let count = file.entries().len();
        *self.tokens.write().unwrap_or_else(|p| p.into_inner()) = Arc::new(file);
        Ok(count)
    }

    /// The caller of a request with these `Authorization` header values from `address`: a
    /// token's when one verifies, an anonymous client's when none is sent (or the server has no
    /// tokens file, as before tokens existed); 401 for anything else.
    pub fn caller<'a>(
        &self,
        mut authorization: impl Iterator<Item = &'a [u8]>,
        address: Option<IpAddr>,
    ) -> Result<Caller, Refusal> {
        let anonymous = || {
            let quotas = self.config.anonymous_quotas.clone();
            Caller::anonymous(address, self.config.anonymous, quotas, self.short_work)
        };
        // Without a tokens file a header is ignored, as before tokens existed.
        if self.config.tokens_file.is_none() {
            return Ok(anonymous());
        }
        let Some(value) = authorization.next() else {
            return Ok(anonymous());
        };
        if authorization.next().is_some() {
            return Err(refusal(
                ErrorCode::Unauthorized,
                "send one Authorization header, not several".into(),
            ));
        }
        let secret = bearer(value)?;
        let tokens = Arc::clone(&self.tokens.read().unwrap_or_else(|p| p.into_inner()));
        let entry = tokens.verify(secret).ok_or_else(|| {
            refusal(
                ErrorCode::Unauthorized,
                "the bearer token is not valid (unknown, revoked or mistyped)".into(),
            )
        })?;
        Ok(Caller {
            owner: entry.name.clone(),
            token: true,
            scopes: entry.scopes,
            quotas: entry.quotas.clone(),
            largest_run: None,
        })
    }
}

/// The token of an `Authorization: Bearer <token>` value (RFC 6750: the scheme in any case, one
/// or more spaces, a token of visible ASCII).
fn bearer(value: &[u8]) -> Result<&str, Refusal> {
    let wrong = |what: &str| {
        refusal(
            ErrorCode::Unauthorized,
            format!("the Authorization header {what}; send `Authorization: Bearer <token>`"),
        )
    };
    if value.len() > MAX_SECRET_LEN + 16 {
        return Err(wrong("is too long"));
    }
    let text = std::str::from_utf8(value).map_err(|_| wrong("is not ASCII text"))?;
    let (scheme, rest) = text.split_once(' ').ok_or_else(|| wrong("has no token"))?;
    if !scheme.eq_ignore_ascii_case("bearer") {
        return Err(wrong("is not of the Bearer scheme"));
    }
    let token = rest.trim_start_matches(' ');
    if token.is_empty() || !token.bytes().all(|b| b.is_ascii_graphic()) {
        return Err(wrong(
            "has no token, or one with characters a token cannot have",
        ));
    }
    Ok(token)
}
