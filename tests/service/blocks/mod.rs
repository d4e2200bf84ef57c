//! The service's building blocks one at a time, through the library's public interfaces: access,
//! the OpenAPI document, recordings, the store, the jobs' replica and the jobs' fair gate.

mod access;
mod job_replica;
mod jobs;
mod openapi;
mod recording;
mod store;
