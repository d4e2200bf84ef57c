//! Rerun recordings (`.rrd`, Rerun 0.33): what geomint computes, laid out as entities the
//! Rerun viewer shows without configuration, each with a default blueprint.
//!
//! - [`simulation`]: the runs of a simulation (energies, invariants, phase portraits, the bodies
//!   in 3-D, drawn by the system's world embedding), as JSON answers them, logged chunk by chunk;
//!   [`layout`] says where each entity goes and sends the default blueprint.
//! - [`live`]: a simulation streamed live to a running Rerun viewer, each chunk of samples logged
//!   as the integrator produces it.
//! - [`stability`]: a stability study, each method's map as a tensor and a verdict image.
//! - [`work_precision`]: a work–precision study as a log–log diagram in a 2-D view.
//! - [`energy_map`]: an energy-error map as images, a segmentation of its divergences and
//!   tensors.
//! - [`sweep`]: a sweep's metrics as tensors and heatmaps.
//! - [`basins`]: a basin map's labels as a segmentation image whose classes name the
//!   attractors, and its decision times.
//! - [`read`]: recordings read back with Rerun's decoder: uploads checked, a simulation's
//!   samples recovered for the page's charts.
//!
//! All are encoded by one writer ([`encode`]): the recording's messages are encoded on their
//! own thread while the next columns are built. The blueprint ([`blueprint`]) is written as
//! Rerun's blueprint records, since the 0.33 Rust blueprint API cannot set visible time ranges.

pub mod basins;
mod blueprint;
mod encode;
pub mod energy_map;
pub mod layout;
pub mod live;
pub mod read;
pub mod simulation;
pub mod stability;
pub mod sweep;
pub mod work_precision;

use std::collections::HashSet;

use rerun::Color;

pub use layout::{
    path_block_len, path_blocks, sample_step, sample_steps, send_blueprint, Layout, PathBlock,
    MAX_PATH_ROWS, MAX_PHASE_DOFS,
};
pub use live::{connect_viewer, viewer_url, LiveRecording, StreamRecorder};
pub use simulation::{
    log_simulation, recording_name, rrd_bytes, system_label, write_rrd, RunLogger, SimulationLogger,
};

/// The request a recording keeps in `/spec`, as pretty JSON: whatever request the recording was
/// made from (recordings need nothing else of the wire layer's types).
#[derive(Clone, Debug, PartialEq)]
pub struct Spec(String);

impl Spec {
    /// The spec of `request`.
    pub fn of(request: &impl serde::Serialize) -> Spec {
        Spec(serde_json::to_string_pretty(request).unwrap_or_default())
    }

    /// The JSON text.
    pub fn json(&self) -> &str {
        &self.0
    }
}

/// The application id of every recording.
pub const APPLICATION_ID: &str = "geomint";
/// The sequence timeline: the step index of each sample.
pub const STEP_TIMELINE: &str = "step";
/// The duration timeline: the time of each sample, in seconds.
pub const TIME_TIMELINE: &str = "t";
/// The media type of `.rrd` files.
pub const RRD_MEDIA_TYPE: &str = "application/octet-stream";

/// One colour per method, in request order (16 methods at most per request).
const PALETTE: [[u8; 3]; 16] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [127, 127, 127],
    [188, 189, 34],
    [23, 190, 207],
    [57, 59, 121],
    [173, 73, 74],
    [99, 121, 57],
    [206, 109, 189],
    [231, 186, 82],
    [82, 84, 163],
];

/// Why a recording could not be written.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The recording stream refused the data.
    #[error("recording stream: {0}")]
    Stream(#[from] rerun::RecordingStreamError),
    /// A component could not be serialised.
    #[error("serialisation: {0}")]
    Serialization(#[from] rerun::SerializationError),
    /// The `.rrd` encoder failed.
    #[error("encoding: {0}")]
    Encode(#[from] rerun::external::re_log_encoding::EncodeError),
    /// The viewer connection failed.
    #[error("{0}")]
    Sink(String),
    /// Data that does not fit the recording (samples out of order, an unknown method).
    #[error("{0}")]
    Unexpected(String),
}

/// The colour of method `index` (request order) as RGB.
pub fn method_color(index: usize) -> [u8; 3] {
    PALETTE[index % PALETTE.len()]
}

/// Makes `label` a valid, plain entity path part: ASCII letters, digits, `_` and `-` are kept,
/// anything else becomes `_` (so `modin_rks(rk4)` becomes `modin_rks_rk4`).
pub fn entity_part(label: &str) -> String {
    let mut part: String = label
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    while part.ends_with('_') && part.len() > 1 {
        part.pop();
    }
    if part.is_empty() || part.starts_with("__") || part == "spec" {
        part.insert_str(0, "m_");
    }
    part
}

/// The entity names of a request's methods, from their labels, in order: [`entity_part`] of each
/// label, with `_2`, `_3`, … appended to repeats so that every method has its own subtree.
pub fn entity_names<S: AsRef<str>>(labels: &[S]) -> Vec<String> {
    let mut taken = HashSet::new();
    labels
        .iter()
        .map(|label| {
            let base = entity_part(label.as_ref());
            let mut name = base.clone();
            let mut n = 2;
            while !taken.insert(name.clone()) {
                name = format!("{base}_{n}");
                n += 1;
            }
            name
        })
        .collect()
}

pub(crate) fn color(rgb: [u8; 3]) -> Color {
    Color::from_rgb(rgb[0], rgb[1], rgb[2])
}
