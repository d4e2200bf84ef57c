//! The wire layer: requests as users write them (the HTTP bodies and the command line's spec
//! files), read strictly — unknown fields at any depth, wrong types and missing fields named,
//! floats exact — and turned into the core's specs; and the NDJSON encoding of the lines the
//! core streams. The OpenAPI schemas of the requests are derived from the same types.
//!
//! - [`allowed`]: which points of a section's plane can start an orbit at an energy.
//! - [`basins`]: basin maps (a sweep's grid with exits and recognition settings).
//! - [`chaos`]: chaos indicators, thresholds and energy surfaces.
//! - [`crossings`]: a simulation's section, `stop_when` and energy level.
//! - [`json`]: JSON text into a value, and the field-by-field reader.
//! - [`method`]: a method as an id or an object with options.
//! - [`simulate`]: the simulation request.
//! - [`stability`]: stability maps and single points.
//! - [`studies`]: convergence and work–precision studies, energy-error maps.
//! - [`sweep`]: sweeps over one or two axes, and their presets.
//! - [`system`]: a system as an id or a user's definition.
//!
//! Results are the core's typed documents, serialized as they are.

// The core under the name the service knows it by (`geomint::core`), so that paths read the
// same in both crates.
use geomint_core as core;

pub mod allowed;
pub mod basins;
pub mod chaos;
pub mod crossings;
pub mod json;
pub mod method;
pub mod simulate;
pub mod stability;
pub mod studies;
pub mod sweep;
pub mod system;

use serde::Serialize;

pub use crate::core::error::{ErrorCode, ErrorDetail};
pub use simulate::SimulateRequest;

/// The media type of NDJSON streams.
pub const NDJSON: &str = "application/x-ndjson";

/// One line of an NDJSON stream: compact JSON and a newline. Serializing the service's lines
/// cannot fail (non-finite floats become null); if it ever did, the line says so as an error
/// line rather than vanishing.
pub fn ndjson_line<T: Serialize>(line: &T) -> Vec<u8> {
    let mut out = serde_json::to_vec(line).unwrap_or_else(|e| {
        tracing::error!(error = %e, "a stream line could not be written");
        let error = ErrorDetail::new(
            ErrorCode::Internal,
            "a line of the stream could not be written",
        );
        serde_json::to_vec(&serde_json::json!({"type": "error", "method": null, "error": error}))
            .unwrap_or_default()
    });
    out.push(b'\n');
    out
}
