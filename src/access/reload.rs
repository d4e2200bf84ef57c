//! Reloading the tokens file while the server runs: on SIGHUP, and whenever the file changes (its
//! modification time, size or inode, looked at every [`POLL`]), so that a token is revoked or
//! added without a restart. A file that no longer reads leaves the tokens in force, with an error
//! in the log.

use std::sync::Arc;
use std::time::{Duration, SystemTime};

use super::Access;

/// How often the file is looked at.
pub const POLL: Duration = Duration::from_secs(2);

/// What identifies a version of the file.
fn stamp(path: &std::path::Path) -> Option<(SystemTime, u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    let meta = std::fs::metadata(path).ok()?;
    Some((meta.modified().ok()?, meta.len(), meta.ino()))
}

/// Reloads `access`'s tokens file on SIGHUP or a change, for as long as the server runs.
pub async fn watch(access: Arc<Access>) {
    let Some(path) = access.tokens_file().map(std::path::Path::to_path_buf) else {
        return;
    };
    let mut hangup = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::hangup()).ok();
    let mut seen = stamp(&path);
    let mut tick = tokio::time::interval(POLL);
    loop {
        let signalled = async {
            match hangup.as_mut() {
                Some(signal) => signal.recv().await,
                None => std::future::pending().await,
            }
        };
        let why = tokio::select! {
            _ = tick.tick() => {
                let now = stamp(&path);
                if now == seen {
                    continue;
                }
                seen = now;
                "the file changed"
            }
            _ = signalled => "SIGHUP",
        };
        match access.reload() {
            Ok(tokens) => tracing::info!(file = %path.display(), tokens, why, "tokens reloaded"),
            Err(error) => {
                tracing::error!(%error, why, "the tokens file does not read; the tokens in force stay")
            }
        }
    }
}
