//! The tokens file (`geomint serve --tokens FILE`): who may use the service, with which scopes
//! and quotas. It holds digests of the secrets, never the secrets.
//!
//! One token a line, fields separated by spaces; `#` starts a comment:
//!
//! ```text
//! # name   scopes          digest of the secret                                                        quotas (optional)
//! alice    read,run,store  sha256:2c26b46b68ffc68ff99b453c1d30413413422d706483bfa0f98a5e886266e7ae  recordings_bytes=268435456 systems=50 runs=2 steps_per_minute=1e9
//! ops      admin           sha256:fcde2b2edba56bf408601fb721fe9b5c338d10ee429ea04fae5511b68fbf8fb9
//! ```
//!
//! - `name`: 1 to 64 of `A–Z a–z 0–9 - _ .`, unique in the file; it owns what the token stores
//!   and names it in the access log.
//! - `scopes`: comma-separated `read`, `run`, `store`, `admin` ([`Scope`]).
//! - the digest: `sha256:` and the 64 lowercase hex digits of the SHA-256 of the secret.
//!   `geomint token NAME --scopes …` makes a secret and prints its line ([`generate`]).
//! - quotas ([`Quotas`]), each `key=value` with a whole number (`1e9` style accepted):
//!   `recordings_bytes`, `systems`, `runs` (in flight), `steps_per_minute`. An absent quota is
//!   bounded only by the service's own limits.
//!
//! Why SHA-256 and not a password hash (argon2, bcrypt): a secret is 32 random bytes (256 bits),
//! not a password a person chose, so no dictionary or brute-force search can invert its digest
//! and a deliberately slow hash would only cost CPU time on every request. A presented token is
//! digested once and compared with every digest of the file in constant time (`subtle`), so the
//! time taken says nothing about how much of a digest matched.

use std::collections::BTreeSet;
use std::fmt;

use base64::Engine;
use sha2::{Digest, Sha256};
use subtle::ConstantTimeEq;

use super::{Quotas, Scope, Scopes};

/// The prefix of every secret `geomint token` makes (it lets secret scanners find leaked ones).
pub const SECRET_PREFIX: &str = "gmt_";
/// The longest bearer token read; longer ones are refused before they are digested.
pub const MAX_SECRET_LEN: usize = 256;
/// The longest token name.
pub const MAX_NAME_LEN: usize = 64;

/// One token of the file.
#[derive(Clone, Debug, PartialEq)]
pub struct TokenEntry {
    /// Its name: the owner of what it stores.
    pub name: String,
    /// What it may do.
    pub scopes: Scopes,
    /// The SHA-256 of its secret.
    pub digest: [u8; 32],
    /// Its quotas.
    pub quotas: Quotas,
}

/// A line of the tokens file that cannot be read.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("line {line}: {message}")]
pub struct TokenFileError {
    /// The line (from 1).
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

/// The tokens of a file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TokenFile {
    entries: Vec<TokenEntry>,
}

/// Whether `name` may name a token.
pub fn is_valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= MAX_NAME_LEN
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.'))
}

/// The SHA-256 digest of a secret.
pub fn digest(secret: &str) -> [u8; 32] {
    Sha256::digest(secret.as_bytes()).into()
}

/// The digest as the file writes it: `sha256:` and 64 hex digits.
pub fn digest_text(digest: &[u8; 32]) -> String {
    let hex: String = digest.iter().map(|b| format!("{b:02x}")).collect();
    format!("sha256:{hex}")
}

fn parse_digest(text: &str) -> Result<[u8; 32], String> {
    let hex = text
        .strip_prefix("sha256:")
        .ok_or_else(|| format!("`{text}` is not a digest: `sha256:` and 64 hex digits"))?;
    if hex.len() != 64 || !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err("a digest is `sha256:` and 64 hex digits (never the secret itself)".into());
    }
    let mut out = [0u8; 32];
    for (i, byte) in out.iter_mut().enumerate() {
        *byte = u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).map_err(|e| e.to_string())?;
    }
    Ok(out)
}

/// Parses a whole number ≥ 0 as the tokens file's quotas and the command line's counts write it:
/// digits with optional `_` separators, or `1e7` style.
pub(crate) fn parse_count(s: &str) -> Result<u64, String> {
    let s = s.trim().replace('_', "");
    if let Ok(n) = s.parse::<u64>() {
        return Ok(n);
    }
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 0.0 && x.fract() == 0.0 && x < u64::MAX as f64 => {
            Ok(x as u64)
        }
        _ => Err(format!("`{s}` is not a whole number ≥ 0")),
    }
}

fn parse_quota(quotas: &mut Quotas, item: &str) -> Result<(), String> {
    let (key, value) = item
        .split_once('=')
        .ok_or_else(|| format!("`{item}` is not a quota (key=value)"))?;
    let n = parse_count(value).map_err(|e| format!("{key}: {e}"))?;
    match key {
        "recordings_bytes" => quotas.recordings_bytes = Some(n),
        "systems" => quotas.systems = Some(usize::try_from(n).unwrap_or(usize::MAX)),
        "runs" => quotas.runs = Some(usize::try_from(n).unwrap_or(usize::MAX)),
        "steps_per_minute" => quotas.steps_per_minute = Some(n),
        other => {
            return Err(format!(
                "unknown quota `{other}`; known: recordings_bytes, systems, runs, steps_per_minute"
            ))
        }
    }
    Ok(())
}

fn parse_line(line: &str) -> Result<Option<TokenEntry>, String> {
    let line = line.split('#').next().unwrap_or("").trim();
    if line.is_empty() {
        return Ok(None);
    }
    let mut fields = line.split_whitespace();
    let (Some(name), Some(scopes), Some(digest)) = (fields.next(), fields.next(), fields.next())
    else {
        return Err("a token is `name scopes sha256:<digest> [quota=value …]`".into());
    };
    if !is_valid_name(name) {
        return Err(format!(
            "`{name}` is not a token name: 1 to {MAX_NAME_LEN} of A-Z a-z 0-9 - _ ."
        ));
    }
    let mut quotas = Quotas::default();
    for item in fields {
        parse_quota(&mut quotas, item)?;
    }
    Ok(Some(TokenEntry {
        name: name.to_string(),
        scopes: Scopes::parse(scopes)?,
        digest: parse_digest(digest)?,
        quotas,
    }))
}

impl TokenFile {
    /// Reads the text of a tokens file; the first wrong line is an error naming it.
    pub fn parse(text: &str) -> Result<TokenFile, TokenFileError> {
        let mut entries: Vec<TokenEntry> = Vec::new();
        let mut names = BTreeSet::new();
        for (i, line) in text.lines().enumerate() {
            let wrong = |message: String| TokenFileError {
                line: i + 1,
                message,
            };
            let Some(entry) = parse_line(line).map_err(wrong)? else {
                continue;
            };
            if !names.insert(entry.name.clone()) {
                return Err(wrong(format!("the name `{}` is used twice", entry.name)));
            }
            if entries.iter().any(|e| e.digest == entry.digest) {
                return Err(wrong(format!(
                    "`{}` has the digest of another token: make a new secret",
                    entry.name
                )));
            }
            entries.push(entry);
        }
        Ok(TokenFile { entries })
    }

    /// The tokens.
    pub fn entries(&self) -> &[TokenEntry] {
        &self.entries
    }

    /// The token whose secret is `secret`, if any. The secret is digested once and compared
    /// with every digest in constant time, whichever matches.
    pub fn verify(&self, secret: &str) -> Option<&TokenEntry> {
        if secret.len() > MAX_SECRET_LEN {
            return None;
        }
        let presented = digest(secret);
        let mut found = None;
        for entry in &self.entries {
            if bool::from(entry.digest.ct_eq(&presented)) {
                found = Some(entry);
            }
        }
        found
    }
}

/// A new secret and the line of the tokens file that admits it.
pub struct Generated {
    /// The secret to give the client (`Authorization: Bearer <secret>`); shown once.
    pub secret: String,
    /// The line for the tokens file: name, scopes, digest, quotas.
    pub line: String,
}

/// Makes a secret of 32 random bytes from the operating system for token `name`.
pub fn generate(name: &str, scopes: Scopes, quotas: &Quotas) -> Result<Generated, String> {
    if !is_valid_name(name) {
        return Err(format!(
            "`{name}` is not a token name: 1 to {MAX_NAME_LEN} of A-Z a-z 0-9 - _ ."
        ));
    }
    let mut bytes = [0u8; 32];
    getrandom::fill(&mut bytes).map_err(|e| format!("no randomness from the system: {e}"))?;
    let secret = format!(
        "{SECRET_PREFIX}{}",
        base64::engine::general_purpose::URL_SAFE_NO_PAD.encode(bytes)
    );
    let mut line = format!("{name} {scopes} {}", digest_text(&digest(&secret)));
    for quota in quotas.items() {
        line.push(' ');
        line.push_str(&quota);
    }
    Ok(Generated { secret, line })
}

impl fmt::Display for Scopes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let names: Vec<&str> = Scope::ALL
            .iter()
            .filter(|s| self.has(**s))
            .map(|s| s.name())
            .collect();
        f.write_str(&names.join(","))
    }
}
