//! The page's static files. Small files (the page, its scripts and styles: up to
//! [`MAX_CACHED_BYTES`] each) are read into memory when the router is built and answered from
//! there, with a strong `ETag` (a digest of the content), `Last-Modified` and `Cache-Control:
//! no-cache`, so that a browser revalidates and gets `304 Not Modified` while nothing changed.
//! Reading each request's file from disk on the blocking pool held the page to about 10 000
//! answers per second on two cores; from memory it is several times that (README, Reliability).
//!
//! A file is looked at again (one `stat`) at most once per [`REVALIDATE`], and read again when
//! its size or modification time changed, so that an edited page is served without a restart.
//! Everything else — larger files (the viewer's WebAssembly), directories without a trailing
//! slash, percent-encoded paths, files added after the start, methods other than GET and HEAD —
//! goes to tower-http's `ServeDir`, which also keeps every path inside the directory.

use std::collections::HashMap;
use std::convert::Infallible;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock, RwLock};
use std::time::{Duration, Instant, SystemTime};

use axum::body::Body;
use axum::extract::Request;
use axum::http::{header, HeaderMap, HeaderValue, Method, StatusCode};
use axum::response::{IntoResponse, Response};
use bytes::Bytes;
use sha2::{Digest, Sha256};
use tower::ServiceExt;
use tower_http::services::ServeDir;

/// Largest file kept in memory.
pub const MAX_CACHED_BYTES: u64 = 1 << 20;
/// Most time between two looks at a cached file on disk.
pub const REVALIDATE: Duration = Duration::from_secs(1);

/// One file in memory.
struct Asset {
    body: Bytes,
    content_type: HeaderValue,
    etag: HeaderValue,
    last_modified: HeaderValue,
    /// Size and modification time when read, to notice a change.
    stamp: (u64, SystemTime),
    /// When the file was last looked at on disk, in milliseconds since [`epoch`].
    checked: AtomicU64,
}

/// The origin of [`Asset::checked`].
fn epoch() -> Instant {
    static EPOCH: OnceLock<Instant> = OnceLock::new();
    *EPOCH.get_or_init(Instant::now)
}

/// Milliseconds since [`epoch`].
fn now_ms() -> u64 {
    epoch().elapsed().as_millis() as u64
}

/// The size and modification time of the file at `path`.
fn stamp(path: &Path) -> Option<(u64, SystemTime)> {
    let meta = std::fs::metadata(path).ok()?;
    Some((meta.len(), meta.modified().ok()?))
}

impl Asset {
    fn read(path: &Path) -> Option<Asset> {
        let meta = std::fs::metadata(path).ok()?;
        if !meta.is_file() || meta.len() > MAX_CACHED_BYTES {
            return None;
        }
        let modified = meta.modified().ok()?;
        // Read after the stamp: a write in between makes the stamp stale, so the next look
        // reads the file again rather than keeping a mix.
        let body = Bytes::from(std::fs::read(path).ok()?);
        let digest = Sha256::digest(&body);
        let etag = format!("\"{}\"", hex(&digest[..16]));
        let content_type = mime_guess::from_path(path).first_or_octet_stream();
        Some(Asset {
            stamp: (body.len() as u64, modified),
            body,
            content_type: HeaderValue::from_str(content_type.as_ref()).ok()?,
            etag: HeaderValue::from_str(&etag).ok()?,
            last_modified: HeaderValue::from_str(&httpdate::fmt_http_date(modified)).ok()?,
            checked: AtomicU64::new(now_ms()),
        })
    }

    /// Whether a request's validators say the client has this version.
    fn not_modified(&self, headers: &HeaderMap) -> bool {
        if let Some(tags) = headers.get(header::IF_NONE_MATCH) {
            // If-None-Match wins over If-Modified-Since (RFC 9110, 13.1.3).
            let ours = self.etag.to_str().unwrap_or_default();
            return tags.to_str().is_ok_and(|tags| {
                tags.split(',').map(str::trim).any(|tag| {
                    // Weak comparison, as for GET (RFC 9110, 8.8.3.2).
                    tag == "*" || tag.trim_start_matches("W/") == ours
                })
            });
        }
        let since = headers
            .get(header::IF_MODIFIED_SINCE)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| httpdate::parse_http_date(v).ok());
        // HTTP dates have whole seconds.
        let modified = httpdate::parse_http_date(self.last_modified.to_str().unwrap_or_default());
        matches!((since, modified), (Some(since), Ok(modified)) if modified <= since)
    }

    fn response(&self, method: &Method, headers: &HeaderMap) -> Response {
        let mut response = if self.not_modified(headers) {
            StatusCode::NOT_MODIFIED.into_response()
        } else if method == Method::HEAD {
            let mut response = Response::new(Body::empty());
            response.headers_mut().insert(
                header::CONTENT_LENGTH,
                HeaderValue::from(self.body.len() as u64),
            );
            response
        } else {
            Response::new(Body::from(self.body.clone()))
        };
        let h = response.headers_mut();
        h.insert(header::CONTENT_TYPE, self.content_type.clone());
        h.insert(header::ETAG, self.etag.clone());
        h.insert(header::LAST_MODIFIED, self.last_modified.clone());
        h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
        response
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The static directory: small files from memory, the rest from disk.
#[derive(Clone)]
pub struct Assets {
    dir: PathBuf,
    /// By path relative to `dir`, with `/` separators (`index.html`, `js/main.js`).
    cached: Arc<RwLock<HashMap<String, Arc<Asset>>>>,
    disk: ServeDir,
}

impl Assets {
    /// Reads the small files under `dir` (following no symbolic links out of it).
    pub fn new(dir: &Path) -> Assets {
        let mut cached = HashMap::new();
        let mut pending = vec![dir.to_path_buf()];
        while let Some(folder) = pending.pop() {
            let Ok(entries) = std::fs::read_dir(&folder) else {
                continue;
            };
            for entry in entries.flatten() {
                let path = entry.path();
                let Ok(kind) = entry.file_type() else {
                    continue;
                };
                if kind.is_dir() {
                    pending.push(path);
                } else if kind.is_file() {
                    let key = path.strip_prefix(dir).ok().and_then(|p| {
                        let parts: Option<Vec<&str>> =
                            p.components().map(|c| c.as_os_str().to_str()).collect();
                        parts.map(|parts| parts.join("/"))
                    });
                    if let (Some(key), Some(asset)) = (key, Asset::read(&path)) {
                        cached.insert(key, Arc::new(asset));
                    }
                }
            }
        }
        Assets {
            dir: dir.to_path_buf(),
            cached: Arc::new(RwLock::new(cached)),
            disk: ServeDir::new(dir),
        }
    }

    /// The cached file a request path names (`/` and `/dir/` name their `index.html`), if any.
    fn key(path: &str) -> Option<String> {
        let relative = path.strip_prefix('/')?;
        if relative.contains('%') || relative.split('/').any(|s| s == ".." || s == ".") {
            return None;
        }
        Some(if relative.is_empty() || relative.ends_with('/') {
            format!("{relative}index.html")
        } else {
            relative.to_string()
        })
    }

    /// The cached asset under `key`, looked at again on disk when due.
    fn lookup(&self, key: &str) -> Option<Arc<Asset>> {
        let asset = self.cached.read().ok()?.get(key)?.clone();
        let now = now_ms();
        if now.saturating_sub(asset.checked.load(Ordering::Relaxed)) < REVALIDATE.as_millis() as u64
        {
            return Some(asset);
        }
        let path = self.dir.join(key);
        if stamp(&path) == Some(asset.stamp) {
            asset.checked.store(now, Ordering::Relaxed);
            return Some(asset);
        }
        let mut cached = self.cached.write().ok()?;
        match Asset::read(&path).map(Arc::new) {
            Some(fresh) => {
                cached.insert(key.to_string(), fresh.clone());
                Some(fresh)
            }
            // Gone, or grown past the limit: the disk decides from now on.
            None => {
                cached.remove(key);
                None
            }
        }
    }

    /// Answers a request for a static file.
    pub async fn serve(self, request: Request) -> Result<Response, Infallible> {
        let method = request.method().clone();
        if method == Method::GET || method == Method::HEAD {
            if let Some(asset) = Self::key(request.uri().path()).and_then(|k| self.lookup(&k)) {
                return Ok(asset.response(&method, request.headers()));
            }
        }
        let response = self.disk.oneshot(request).await?;
        Ok(response.map(Body::new))
    }
}
