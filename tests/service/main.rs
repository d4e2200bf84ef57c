//! The service's integration tests, in one binary: the HTTP routes against the real server on an
//! ephemeral port, the command line and the NATS executor as real processes, recordings decoded
//! by Rerun's own readers (Rust and Python), the pinned answers, the fuzz targets, and the core
//! behaviours that requests reach through the wire layer (definitions, method options, sweeps),
//! and the library's building blocks one at a time (its unit tests are these: the library builds
//! no test target of its own, which would compile the whole service a second time).

#[path = "../../crates/geomint-core/tests/core/common.rs"]
#[allow(dead_code)]
mod common;
#[allow(dead_code)]
mod decoded;
#[allow(dead_code)]
mod server;

mod blocks;
mod chaos;
mod cli_shards;
mod definitions;
mod definitions_compiled;
mod fuzz_auth;
mod fuzz_definitions;
mod fuzz_routes;
mod http;
mod http_access;
mod http_access_log;
mod http_allowed;
mod http_basins;
mod http_charts;
mod http_cli;
mod http_convergence;
mod http_faults;
mod http_jobs;
mod http_ownership;
mod http_ownership_restarts;
mod http_paths;
mod http_recordings;
mod http_recordings_upload;
mod http_refusals;
mod http_reliability;
mod http_sections;
mod http_server;
mod http_stability;
mod http_stability_refusals;
mod http_studies;
mod http_sweep;
mod http_systems;
mod http_time_limit;
mod method_inputs;
mod nats;
mod nats_jobs;
mod nats_poison;
mod pinned;
mod rowlands;
mod rowlands_requests;
mod rrd;
#[cfg(unix)]
mod rrd_live;
mod rrd_python;
mod sweeps;
