//! `geomint job submit|status|watch|fetch|cancel|remove|list`: a server's jobs from the command line
//! (see [`crate::jobs`]). The server is `--server` (or `GEOMINT_URL`), the token `--token` (or
//! `GEOMINT_TOKEN`).
//!
//! Exit codes: 0 on success (`watch`: the job is done); 2 for a request the server refused
//! (its message names the field) or a job that failed or was cancelled (`watch`); 1 when the
//! server cannot be reached or the output cannot be written.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::{Args, Subcommand};
use serde_json::{json, Value};

use super::{print_json, read_spec, BAD_INPUT};

/// Settings of `geomint job`.
#[derive(Clone, Debug, Args)]
pub struct JobArgs {
    /// What to do.
    #[command(subcommand)]
    pub action: JobAction,
    /// The server.
    #[arg(
        long,
        global = true,
        env = "GEOMINT_URL",
        default_value = "http://127.0.0.1:8080"
    )]
    pub server: String,
    /// A bearer token (`geomint token` makes one).
    #[arg(long, global = true, env = "GEOMINT_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
}

/// The job commands.
#[derive(Clone, Debug, Subcommand)]
pub enum JobAction {
    /// Submit a study as a job; prints its status (with its id) as JSON.
    Submit {
        /// The kind of study: sweep, basins, energy-map, stability, convergence or
        /// work-precision.
        study: String,
        /// The study's spec (the body of its route); `-` reads standard input.
        spec: PathBuf,
        /// Its priority among your jobs (-1000 to 1000).
        #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
        priority: i32,
    },
    /// Print a job's status as JSON.
    Status {
        /// The job id.
        id: String,
    },
    /// Follow a job's events (on standard error) to its end.
    Watch {
        /// The job id.
        id: String,
    },
    /// Write a done job's document: JSON, or its Rerun recording for a file ending in `.rrd`.
    Fetch {
        /// The job id.
        id: String,
        /// Output file (default: standard output, JSON).
        #[arg(short, long)]
        output: Option<PathBuf>,
    },
    /// Cancel a job (one that has ended is left as it is); prints its status.
    Cancel {
        /// The job id.
        id: String,
    },
    /// Remove a job that has ended, with its result.
    Remove {
        /// The job id.
        id: String,
    },
    /// List your jobs as JSON.
    List,
}

/// Why a call did not give what was asked.
enum CallFailure {
    /// The server answered with an error (its JSON body).
    Refused(u16, Value),
    /// The server could not be reached, or its answer read.
    Unreachable(String),
}

impl CallFailure {
    fn report(self, server: &str) -> ExitCode {
        match self {
            CallFailure::Refused(status, body) => {
                let error = &body["error"];
                let field = error["field"]
                    .as_str()
                    .map(|f| format!(" ({f})"))
                    .unwrap_or_default();
                eprintln!(
                    "error: {status} {}{field}: {}",
                    error["code"].as_str().unwrap_or("?"),
                    error["message"].as_str().unwrap_or("")
                );
                ExitCode::from(BAD_INPUT)
            }
            CallFailure::Unreachable(why) => {
                eprintln!("error: the server at {server} could not be reached: {why}");
                ExitCode::FAILURE
            }
        }
    }
}

struct Server<'a> {
    args: &'a JobArgs,
    http: reqwest::Client,
}

impl Server<'_> {
    fn url(&self, path: &str) -> String {
        format!("{}{path}", self.args.server.trim_end_matches('/'))
    }

    /// `method path` with an optional JSON body: the answer's bytes, or why not.
    async fn call(
        &self,
        method: reqwest::Method,
        path: &str,
        body: Option<&Value>,
    ) -> Result<reqwest::Response, CallFailure> {
        let mut request = self.http.request(method, self.url(path));
        if let Some(token) = &self.args.token {
            request = request.bearer_auth(token);
        }
        if let Some(body) = body {
            request = request.json(body);
        }
        let response = request
            .send()
            .await
            .map_err(|e| CallFailure::Unreachable(e.to_string()))?;
        let status = response.status().as_u16();
        if status >= 400 {
            let body = response.json().await.unwrap_or(Value::Null);
            return Err(CallFailure::Refused(status, body));
        }
        Ok(response)
    }

    async fn json(
        &self,
        method: reqwest::Method,
        path: &str,
        body: Option<&Value>,
    ) -> Result<Value, CallFailure> {
        let response = self.call(method, path, body).await?;
        response
            .json()
            .await
            .map_err(|e| CallFailure::Unreachable(e.to_string()))
    }

    /// Follows the job's events to its last, printing each on standard error; reconnects from
    /// the last event seen when the connection drops (a server restarting), for up to a
    /// minute. The last event.
    async fn watch(&self, id: &str) -> Result<Value, CallFailure> {
        const RETRIES: u32 = 60;
        let mut seen = 0u64;
        let mut retries = 0;
        loop {
            let path = format!("/api/v1/jobs/{id}/events?after={seen}");
            let mut response = match self.call(reqwest::Method::GET, &path, None).await {
                Err(CallFailure::Unreachable(_)) if retries < RETRIES => {
                    retries += 1;
                    tokio::time::sleep(Duration::from_secs(1)).await;
                    continue;
                }
                other => other?,
            };
            retries = 0;
            let mut pending = Vec::new();
            while let Ok(Some(chunk)) = response.chunk().await {
                pending.extend_from_slice(&chunk);
                while let Some(end) = pending.iter().position(|&b| b == b'\n') {
                    let line: Vec<u8> = pending.drain(..=end).collect();
                    let Ok(event) = serde_json::from_slice::<Value>(&line) else {
                        continue;
                    };
                    seen = event["seq"].as_u64().unwrap_or(seen);
                    eprintln!(
                        "{} {}: {}/{} parts, {}/{} cells",
                        event["at"].as_str().unwrap_or(""),
                        event["event"].as_str().unwrap_or(""),
                        event["parts_done"],
                        event["parts"],
                        event["cells_done"],
                        event["cells"]
                    );
                    if matches!(
                        event["event"].as_str(),
                        Some("done" | "failed" | "cancelled")
                    ) {
                        return Ok(event);
                    }
                }
            }
        }
    }
}

/// Carries out `geomint job …`.
pub fn run_job(args: &JobArgs) -> ExitCode {
    let runtime = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(runtime) => runtime,
        Err(e) => {
            eprintln!("error: cannot start: {e}");
            return ExitCode::FAILURE;
        }
    };
    let server = Server {
        args,
        http: reqwest::Client::new(),
    };
    let result = runtime.block_on(act(&server, &args.action));
    result.unwrap_or_else(|failure| failure.report(&args.server))
}

async fn act(server: &Server<'_>, action: &JobAction) -> Result<ExitCode, CallFailure> {
    use reqwest::Method;
    let job = |id: &str| format!("/api/v1/jobs/{id}");
    Ok(match action {
        JobAction::Submit {
            study,
            spec,
            priority,
        } => {
            let text = match read_spec(spec) {
                Ok((_, text)) => text,
                Err(code) => return Ok(code),
            };
            let request: Value = match serde_json::from_slice(&text) {
                Ok(request) => request,
                Err(e) => {
                    eprintln!("error: {}: not JSON: {e}", spec.display());
                    return Ok(ExitCode::from(BAD_INPUT));
                }
            };
            let body = json!({"study": study, "request": request, "priority": priority});
            print_json(
                &server
                    .json(Method::POST, "/api/v1/jobs", Some(&body))
                    .await?,
            )
        }
        JobAction::Status { id } => print_json(&server.json(Method::GET, &job(id), None).await?),
        JobAction::List => print_json(&server.json(Method::GET, "/api/v1/jobs", None).await?),
        JobAction::Cancel { id } => {
            let path = format!("{}/cancel", job(id));
            print_json(&server.json(Method::POST, &path, None).await?)
        }
        JobAction::Remove { id } => {
            server.call(Method::DELETE, &job(id), None).await?;
            eprintln!("job {id} removed");
            ExitCode::SUCCESS
        }
        JobAction::Watch { id } => {
            let last = server.watch(id).await?;
            match last["event"].as_str() {
                Some("done") => ExitCode::SUCCESS,
                _ => {
                    if let Some(message) = last["error"]["message"].as_str() {
                        eprintln!("error: the job failed: {message}");
                    }
                    ExitCode::from(BAD_INPUT)
                }
            }
        }
        JobAction::Fetch { id, output } => {
            let rrd = output
                .as_ref()
                .is_some_and(|p| p.extension().is_some_and(|e| e == "rrd"));
            let path = format!("{}/result{}", job(id), if rrd { "?format=rrd" } else { "" });
            let bytes = server
                .call(Method::GET, &path, None)
                .await?
                .bytes()
                .await
                .map_err(|e| CallFailure::Unreachable(e.to_string()))?;
            let written = match output {
                Some(file) => std::fs::write(file, &bytes),
                None => {
                    use std::io::Write;
                    std::io::stdout().write_all(&bytes)
                }
            };
            super::finish_output(written)
        }
    })
}
