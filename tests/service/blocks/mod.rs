//! The service's building blocks one at a time, through the library's public interfaces: access,
//! the OpenAPI document, recordings and the store.

mod access;
mod openapi;
mod recording;
mod store;
