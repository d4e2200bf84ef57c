//! The real server on an ephemeral loopback port, shared by the HTTP test files.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use geomint::http::{serve_on, AppState, Config};

/// A running server.
pub struct Server {
    /// `http://127.0.0.1:PORT`.
    pub base: String,
    /// Its address.
    pub addr: std::net::SocketAddr,
    /// Its state (for inspecting slots and settings).
    pub state: AppState,
}

impl Server {
    /// The URL of `path` on this server.
    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }
}

/// Starts the service for `config` on 127.0.0.1:0 in the test's runtime, with the server loop
/// of `geomint serve` (its connection limits and timeouts).
pub async fn start(config: Config) -> Server {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let state = AppState::new(config);
    let serving = state.clone();
    tokio::spawn(async move {
        serve_on(listener, serving, std::future::pending())
            .await
            .unwrap();
    });
    Server {
        base: format!("http://{addr}"),
        addr,
        state,
    }
}

/// The log filter for a `geomint serve` a test starts: warnings, and the line that says where it
/// listens (after [`SERVE_LISTENING`]).
pub const SERVE_LOG: &str = "warn,geomint::http::server=info";
/// What precedes the address in that line.
pub const SERVE_LISTENING: &str = "listening on http://";

/// Starts `command`, a server told to listen on a port the system picks, and returns it with the
/// `host:port` its log (stderr) names after `marker`. A port chosen beforehand could be taken
/// meanwhile by a server another test starts, and the test would then talk to that one. The log
/// is read to its end (and shown with the test's output), so that the server never blocks on a
/// full pipe.
pub fn spawn_listening(mut command: Command, what: &str, marker: &str) -> (Process, String) {
    let mut child = command.stderr(Stdio::piped()).spawn().unwrap();
    let log = child.stderr.take().expect("a piped stderr");
    let process = Process(child);
    let (tell, told) = std::sync::mpsc::channel::<Result<String, String>>();
    let marker = marker.to_owned();
    // The thread inherits the test's output capture: the log shows when the test fails.
    std::thread::spawn(move || {
        let mut tell = Some(tell);
        let mut before = Vec::new();
        let mut log = BufReader::new(log);
        let mut bytes = Vec::new();
        // Byte lines, read to the end whatever they hold: a pipe closed early would make the
        // server's next log line fail.
        while log.read_until(b'\n', &mut bytes).is_ok_and(|n| n > 0) {
            let line = String::from_utf8_lossy(&bytes).trim_end().to_owned();
            bytes.clear();
            eprintln!("{line}");
            let Some(tell_now) = tell.as_ref() else {
                continue;
            };
            match line.find(&marker) {
                Some(at) => {
                    let address: String = line[at + marker.len()..]
                        .chars()
                        .take_while(|c| c.is_ascii_digit() || matches!(c, '.' | ':'))
                        .collect();
                    let _ = tell_now.send(Ok(address));
                    tell = None;
                }
                None => before.push(line),
            }
        }
        if let Some(tell) = tell {
            let _ = tell.send(Err(before.join("\n")));
        }
    });
    match told.recv_timeout(Duration::from_secs(20)) {
        Ok(Ok(address)) => (process, address),
        Ok(Err(log)) => panic!("{what} ended without listening:\n{log}"),
        Err(_) => panic!("{what} did not say where it listens within 20 s"),
    }
}

/// A loopback port bound but not listened on, for as long as the socket lives: connections to
/// it are refused, and no test running beside this one can start a server on it meanwhile.
pub fn closed_port() -> (tokio::net::TcpSocket, u16) {
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    socket.bind(([127, 0, 0, 1], 0).into()).unwrap();
    let port = socket.local_addr().unwrap().port();
    (socket, port)
}

/// A loopback port nobody listens on (at the time of asking), for a process a test starts.
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A child process killed when dropped.
pub struct Process(pub Child);

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Waits until something listens on the loopback `port` (20 s at most).
pub fn wait_for_port(port: u16, what: &str) {
    let until = Instant::now() + Duration::from_secs(20);
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            Instant::now() < until,
            "{what} did not start on port {port}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// A fresh scratch path `label` of this test process, under the build's scratch folder
/// (`target/tmp/scratch/PID/label-N`, N counting the calls; not created). Folders of
/// test processes that are gone are removed first: a test that fails, or whose service is a
/// static that is never dropped, cannot clean up after itself.
pub fn scratch_dir(label: &str) -> std::path::PathBuf {
    let root = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("scratch");
    let gone = |pid: u32| {
        cfg!(target_os = "linux") && !std::path::Path::new(&format!("/proc/{pid}")).exists()
    };
    for entry in std::fs::read_dir(&root).into_iter().flatten().flatten() {
        let pid = entry
            .file_name()
            .to_str()
            .and_then(|name| name.parse().ok());
        if pid.is_some_and(gone) {
            // Best effort: another test process may be removing it at the same time.
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
    // A fresh directory per call: tests of one binary run in parallel and often share a
    // label (every test's `config()`), so a stable name would let one test's set-up remove
    // another's store while it is in use.
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = root
        .join(std::process::id().to_string())
        .join(format!("{label}-{call}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.parent().expect("a parent")).expect("the scratch folder");
    dir
}

/// The temporary files (`.tmp-…`) of a store's directory.
pub fn temporary_files(dir: &std::path::Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .map(|listing| {
            listing
                .flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.starts_with(".tmp-"))
                .collect()
        })
        .unwrap_or_default()
}

/// A client that never goes through a proxy.
pub fn client() -> reqwest::Client {
    reqwest::Client::builder().no_proxy().build().unwrap()
}

/// GETs `path` and reads its answer as JSON.
pub async fn get_json(server: &Server, path: &str) -> serde_json::Value {
    get_json_at(server.url(path)).await
}

/// GETs `url` (of a server this test did not start in its own runtime) and reads its answer as
/// JSON.
pub async fn get_json_at(url: String) -> serde_json::Value {
    client()
        .get(url)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap()
}

/// Posts `body` as JSON to `path`; returns the status and the JSON answer, read with correctly
/// rounded floats so that numbers compare bit for bit.
pub async fn post_json(
    server: &Server,
    path: &str,
    body: &serde_json::Value,
) -> (u16, serde_json::Value) {
    post_json_to(&server.base, path, body).await
}

/// [`post_json`] to the server at `base` (`http://HOST:PORT`), one this test did not start in
/// its own runtime (a `geomint serve` process).
pub async fn post_json_to(
    base: &str,
    path: &str,
    body: &serde_json::Value,
) -> (u16, serde_json::Value) {
    let response = client()
        .post(format!("{base}{path}"))
        .json(body)
        .send()
        .await
        .unwrap();
    let status = response.status().as_u16();
    assert_eq!(response.headers()["content-type"], "application/json");
    let bytes = response.bytes().await.unwrap();
    let answer = geomint::api::json::parse_json(&bytes).expect("a JSON answer");
    (status, answer)
}

/// Posts `body` as JSON to `path` with `accept`, and reads the answer as NDJSON: the status,
/// the content type and every line parsed.
pub async fn post_ndjson(
    server: &Server,
    path: &str,
    accept: &str,
    body: &serde_json::Value,
) -> (u16, String, Vec<serde_json::Value>) {
    let response = client()
        .post(server.url(path))
        .header("accept", accept)
        .json(body)
        .send()
        .await
        .unwrap();
    let status = response.status().as_u16();
    let content_type = response.headers()["content-type"]
        .to_str()
        .unwrap()
        .to_string();
    let text = response.text().await.unwrap();
    let lines = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    (status, content_type, lines)
}
