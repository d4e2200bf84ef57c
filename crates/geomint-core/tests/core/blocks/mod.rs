//! The core's building blocks one at a time, through their public interfaces: the lanes' builds
//! against each other, the chaos indicators' frame, damping flows, drawings, study pieces,
//! streamed documents, expression operations, fits and errors.

mod damping;
mod diagnostics;
mod errors;
mod expr_ops;
mod frame;
mod lanes;
mod stream;
mod studies;
mod world;
