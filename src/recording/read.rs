//! Recordings read back with Rerun's own decoder (`re_log_encoding`, the crate the viewer uses):
//! the check of an uploaded `.rrd` before the store keeps it ([`inspect`]), and the samples of a
//! stored simulation recording as JSON for the page's charts ([`samples`]).
//!
//! An upload is a recording the embedded viewer (Rerun 0.33) reads when it starts with the RRD
//! header of a Rerun from 0.23 (the oldest the decoder accepts) to this server's 0.33, ends with
//! the stream footer (else it was cut short), and every message decodes, with at least one
//! recording store in it. Nothing here trusts the file: every datatype is checked before it is
//! read, so that a crafted upload is refused with a message instead of reaching a panic.
//!
//! The samples come from the recording's own rows (see [`crate::recording::simulation`] for the
//! layout): times from the `t` timeline, energies, energy errors and invariants exactly (they
//! are stored as f64), positions and momenta from the phase points (stored as f32, for the first
//! [`MAX_PHASE_DOFS`] degrees of freedom), Cartesian positions from the bodies in the world
//! view (f32). The system, its resolved parameters and the schedule come from the recorded spec
//! (`/spec`), prepared but never run.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use re_log_encoding::DecoderApp;
use rerun::external::arrow::array::{Array, FixedSizeListArray, Float32Array, Float64Array};
use rerun::external::re_build_info::CrateVersion;
use rerun::external::re_log_types::{LogMsg, StoreKind};
use rerun::log::Chunk;
use rerun::{ComponentIdentifier, Points2D, Points3D, Scalars, TextDocument};
use serde::Serialize;
use serde_json::Value;
use utoipa::ToSchema;

use super::{
    entity_names, entity_part, APPLICATION_ID, MAX_PHASE_DOFS, STEP_TIMELINE, TIME_TIMELINE,
};
use crate::api::system::NoStoredSystems;
use crate::api::SimulateRequest;
use crate::core::diagnostics::DriftPoint;
use crate::core::simulation::{Columns, Limits, ScheduleSummary, Simulation, SystemSummary};

/// The first bytes of every RRD stream this decoder reads.
const RRD_MAGIC: &[u8; 4] = b"RRF2";
/// The first bytes of the RRD streams of Rerun before 0.23, which no longer decode.
const OLD_RRD_MAGICS: [&[u8; 4]; 3] = [b"RRF0", b"RRF1", b"RRIO"];
/// The oldest Rerun minor version (of 0.x) whose recordings the decoder and viewer read.
const OLDEST_READABLE_MINOR: u8 = 23;
/// The stream footer's tag, in the last 12 bytes of a complete stream.
const FOOTER_TAG: &[u8; 8] = b"RRF2FOOT";

/// Why a recording cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// Not a complete Rerun recording of a version the viewer reads.
    #[error("{0}")]
    Invalid(String),
    /// A recording, but not of one of this service's simulations.
    #[error("{0}")]
    NotASimulation(String),
    /// More samples than a JSON answer may carry.
    #[error("the recording holds {samples} samples, more than the {max} a JSON answer carries (the server's sample limit); open it in the Rerun viewer instead")]
    TooManySamples {
        /// Samples in the recording, over all methods.
        samples: u64,
        /// The limit.
        max: u64,
    },
    /// The file could not be read.
    #[error("reading the recording: {0}")]
    Io(#[from] io::Error),
}

fn invalid(message: impl Into<String>) -> ReadError {
    ReadError::Invalid(message.into())
}

/// The RRD header's four bytes as text when they are printable, else as hex.
pub fn show_bytes(bytes: &[u8]) -> String {
    if !bytes.is_empty() && bytes.iter().all(|b| b.is_ascii_graphic() || *b == b' ') {
        format!("`{}`", String::from_utf8_lossy(bytes))
    } else {
        let hex: String = bytes.iter().map(|b| format!("{b:02X}")).collect();
        format!("0x{hex}")
    }
}

/// Checks the stream header and footer of the file at `path`: the Rerun version that wrote it.
fn check_frame(file: &mut File) -> Result<CrateVersion, ReadError> {
    let len = file.metadata()?.len();
    let mut head = [0u8; 12];
    let read = read_up_to(file, &mut head)?;
    if read < 4 || &head[..4] != RRD_MAGIC {
        let shown = show_bytes(&head[..read.min(4)]);
        if read >= 4 && OLD_RRD_MAGICS.iter().any(|m| &head[..4] == *m) {
            return Err(invalid(format!(
                "a recording of a Rerun older than 0.{OLDEST_READABLE_MINOR} (header {shown}); \
                 the viewer reads Rerun 0.{OLDEST_READABLE_MINOR} to {} recordings",
                local_version()
            )));
        }
        return Err(invalid(format!(
            "not a Rerun recording (.rrd): the file starts with {shown}, not the RRD header `RRF2`"
        )));
    }
    if read < head.len() {
        return Err(invalid(format!(
            "cut short: {len} bytes, less than an RRD stream header"
        )));
    }
    let version = CrateVersion::from_bytes([head[4], head[5], head[6], head[7]]);
    let local = CrateVersion::LOCAL;
    let readable = version.major == 0 && version.minor >= OLDEST_READABLE_MINOR;
    let not_newer = (version.major, version.minor) <= (local.major, local.minor);
    if !readable || !not_newer {
        return Err(invalid(format!(
            "written by Rerun {version}; the viewer here reads recordings of Rerun \
             0.{OLDEST_READABLE_MINOR} to {}",
            local_version()
        )));
    }
    let mut tail = [0u8; 12];
    let complete = len >= 24 && {
        file.seek(SeekFrom::End(-12))?;
        file.read_exact(&mut tail)?;
        &tail[..8] == FOOTER_TAG
    };
    if !complete {
        return Err(invalid(format!(
            "cut short: the {len} bytes do not end with the RRD stream footer (an interrupted \
             write or a partial download)"
        )));
    }
    file.seek(SeekFrom::Start(0))?;
    Ok(version)
}

/// `major.minor` of the Rerun this server decodes with (and the page's viewer is).
fn local_version() -> String {
    let local = CrateVersion::LOCAL;
    format!("{}.{}", local.major, local.minor)
}

/// Reads as much of `buf` as the file holds.
fn read_up_to(file: &mut File, buf: &mut [u8]) -> io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match file.read(&mut buf[filled..])? {
            0 => break,
            n => filled += n,
        }
    }
    Ok(filled)
}

/// What a decoded recording holds: its application id and, by entity path, the recording's
/// chunks that `keep` asked for.
struct Decoded {
    application_id: Option<String>,
    chunks: BTreeMap<String, Vec<Chunk>>,
}

/// Decodes every message of the recording at `path` (the frame checked first), keeping the
/// recording store's chunks whose entity path `keep` accepts.
fn decode(path: &Path, keep: impl Fn(&str) -> bool) -> Result<Decoded, ReadError> {
    let mut file = File::open(path)?;
    check_frame(&mut file)?;
    let mut decoded = Decoded {
        application_id: None,
        chunks: BTreeMap::new(),
    };
    let mut recordings = 0usize;
    let messages = DecoderApp::decode_lazy(BufReader::with_capacity(1 << 20, file));
    for (index, message) in messages.enumerate() {
        let message = message.map_err(|e| {
            invalid(format!(
                "message {index} of the stream does not decode: {e}"
            ))
        })?;
        match message {
            LogMsg::SetStoreInfo(info) => {
                let id = &info.info.store_id;
                if id.kind() == StoreKind::Recording {
                    recordings += 1;
                    decoded
                        .application_id
                        .get_or_insert_with(|| id.application_id().to_string());
                }
            }
            LogMsg::ArrowMsg(store, arrow) => {
                let chunk = Chunk::from_arrow_msg(&arrow).map_err(|e| {
                    invalid(format!(
                        "message {index} holds a chunk that does not decode: {e}"
                    ))
                })?;
                let path = chunk.entity_path().to_string();
                if store.kind() == StoreKind::Recording && keep(&path) {
                    decoded.chunks.entry(path).or_default().push(chunk);
                }
            }
            LogMsg::BlueprintActivationCommand(_) => {}
        }
    }
    if recordings == 0 {
        return Err(invalid(
            "the stream holds no recording (no recording store; a blueprint alone, or nothing)",
        ));
    }
    Ok(decoded)
}

/// The spec text of `/spec` (a Markdown code block of JSON), if the recording has one.
fn spec_text(chunks: &BTreeMap<String, Vec<Chunk>>) -> Option<String> {
    let component = TextDocument::descriptor_text().component;
    chunks.get("/spec")?.iter().find_map(|chunk| {
        let texts = chunk
            .component_batch::<rerun::components::Text>(component, 0)?
            .ok()?;
        texts.first().map(|t| t.as_str().to_string())
    })
}

/// The request recorded in `/spec`, parsed and prepared (never run), with its JSON.
fn recorded_simulation(
    decoded: &Decoded,
) -> Result<(Value, SimulateRequest, Simulation), ReadError> {
    let not_ours = |why: &str| {
        ReadError::NotASimulation(format!(
            "not a recording of a geomint simulation: {why}; it can be viewed, not plotted"
        ))
    };
    if decoded.application_id.as_deref() != Some(APPLICATION_ID) {
        return Err(not_ours(&format!(
            "its application id is `{}`",
            decoded.application_id.as_deref().unwrap_or("")
        )));
    }
    let text = spec_text(&decoded.chunks).ok_or_else(|| not_ours("it has no `/spec`"))?;
    let json = text
        .trim()
        .strip_prefix("```json")
        .and_then(|rest| rest.strip_suffix("```"))
        .unwrap_or(&text);
    let value: Value =
        serde_json::from_str(json).map_err(|_| not_ours("its `/spec` is not a request"))?;
    let request = SimulateRequest::from_value(&value)
        .map_err(|e| not_ours(&format!("its `/spec` is not a valid request ({e})")))?;
    // Preparing resolves the system, its parameters and the schedule; nothing is integrated,
    // so the server's step limits do not apply to a recording made elsewhere.
    let unlimited = Limits {
        max_steps: u64::MAX,
        max_samples: u64::MAX,
    };
    let sim = request
        .prepare(&unlimited, &NoStoredSystems)
        .map_err(|e| not_ours(&format!("its `/spec` does not prepare ({e})")))?;
    Ok((value, request, sim))
}

/// What an uploaded recording holds.
#[derive(Debug)]
pub struct Inspected {
    /// The application id written in the recording.
    pub application_id: Option<String>,
    /// The simulation it records, when it records one of this service's simulations (prepared
    /// from its `/spec`, never run).
    pub simulation: Option<Simulation>,
}

/// Checks an uploaded recording at `path` (see the module docs) and says what it holds.
pub fn inspect(path: &Path) -> Result<Inspected, ReadError> {
    let decoded = decode(path, |p| p == "/spec")?;
    let simulation = recorded_simulation(&decoded).ok().map(|(_, _, sim)| sim);
    Ok(Inspected {
        application_id: decoded.application_id,
        simulation,
    })
}

/// A stored simulation recording's samples, read back from the `.rrd` file: the same shape as
/// the runs of a simulation's JSON answer, without what a recording does not hold (why a run
/// stopped, its wall time).
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct RecordedDocument {
    /// The request, as the recording holds it in `/spec`.
    #[schema(value_type = Object)]
    pub request: Value,
    /// The system, parameters resolved from the request.
    pub system: SystemSummary,
    /// The sampling, from the request.
    pub schedule: ScheduleSummary,
    /// Names of the invariants in each run's `invariants`.
    pub invariants: Vec<String>,
    /// One run per method, in the order asked.
    pub runs: Vec<RecordedRun>,
}

/// One method's rows in a recording.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct RecordedRun {
    /// The method's label.
    #[schema(example = "modin_3s")]
    pub method: String,
    /// The samples: `t` from the `t` timeline; `energy`, `energy_error` and `invariants` exact;
    /// `q` and `p` from the phase points (f32, the first six degrees of freedom);
    /// `cartesian_q` from the bodies in the world view (f32; absent for the pendulum, whose
    /// world shows the bob, not its angle).
    #[serde(flatten)]
    pub columns: Columns,
    /// The step of the last row.
    pub last_step: u64,
    /// Force evaluations of the run, as recorded at its end.
    pub force_evaluations: Option<u64>,
    /// The dissipation drift of the recorded positions (1-DOF systems with conformal damping).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dissipation_drift: Option<Vec<DriftPoint>>,
}

/// One row of an entity: its step, its time in seconds and its values.
struct Row<T> {
    step: i64,
    t: f64,
    value: T,
}

/// The temporal rows of `path` in step order, their values read by `read` from each chunk
/// (`None` when a chunk does not hold the expected component and datatype).
fn rows<T>(
    chunks: &BTreeMap<String, Vec<Chunk>>,
    path: &str,
    read: impl Fn(&Chunk) -> Option<Vec<T>>,
) -> Result<Option<Vec<Row<T>>>, ReadError> {
    let Some(chunks) = chunks.get(path) else {
        return Ok(None);
    };
    let mut out = Vec::new();
    for chunk in chunks.iter().filter(|c| !c.is_static()) {
        let timelines = chunk.timelines();
        let (Some(steps), Some(times)) = (
            timelines.get(&STEP_TIMELINE.into()),
            timelines.get(&TIME_TIMELINE.into()),
        ) else {
            return Err(invalid(format!("{path} lacks the `step` or `t` timeline")));
        };
        let values = read(chunk)
            .ok_or_else(|| invalid(format!("{path} does not hold the expected component")))?;
        let (steps, times) = (steps.times_raw(), times.times_raw());
        if values.len() != steps.len() || times.len() != steps.len() {
            return Err(invalid(format!("{path} has rows without one value each")));
        }
        out.extend(
            values
                .into_iter()
                .zip(steps.iter().zip(times))
                .map(|(value, (&step, &t))| Row {
                    step,
                    t: t as f64 * 1e-9,
                    value,
                }),
        );
    }
    out.sort_by_key(|r| r.step);
    Ok(Some(out))
}

/// The list array of `component` in `chunk`, with one batch per row.
fn batches(chunk: &Chunk, component: ComponentIdentifier) -> Option<(&dyn Array, Vec<usize>)> {
    let list = chunk.components().get_array(component)?;
    let offsets = list.value_offsets();
    let lengths = offsets
        .windows(2)
        .map(|w| usize::try_from(w[1] - w[0]).ok())
        .collect::<Option<Vec<_>>>()?;
    let starts = offsets.first().copied().unwrap_or(0);
    (starts == 0).then_some((list.values().as_ref(), lengths))
}

/// One f64 per row (a `Scalars` column).
fn scalar_rows(chunk: &Chunk) -> Option<Vec<f64>> {
    let (values, lengths) = batches(chunk, Scalars::descriptor_scalars().component)?;
    let values = values.as_any().downcast_ref::<Float64Array>()?;
    if lengths.iter().any(|&n| n != 1) || values.len() != lengths.len() {
        return None;
    }
    Some(values.values().to_vec())
}

/// The points of every row (a `Points2D` or `Points3D` positions column) as f64.
fn point_rows<const N: usize>(
    chunk: &Chunk,
    component: ComponentIdentifier,
) -> Option<Vec<Vec<f64>>> {
    let (values, lengths) = batches(chunk, component)?;
    let list = values.as_any().downcast_ref::<FixedSizeListArray>()?;
    let coordinates = list.values().as_any().downcast_ref::<Float32Array>()?;
    if list.value_length() as usize != N || coordinates.len() != N * list.len() {
        return None;
    }
    if lengths.iter().sum::<usize>() != list.len() {
        return None;
    }
    let flat = coordinates.values();
    let mut start = 0;
    Some(
        lengths
            .iter()
            .map(|&n| {
                let row = flat[N * start..N * (start + n)]
                    .iter()
                    .map(|&x| f64::from(x))
                    .collect();
                start += n;
                row
            })
            .collect(),
    )
}

/// Checks that an entity's rows are at the steps of the energy's.
fn aligned<T>(path: &str, rows: &[Row<T>], steps: &[i64]) -> Result<(), ReadError> {
    if rows.len() != steps.len() || rows.iter().zip(steps).any(|(r, s)| r.step != *s) {
        return Err(invalid(format!(
            "{path} has {} rows, not one at each of the energy's {} steps",
            rows.len(),
            steps.len()
        )));
    }
    Ok(())
}

/// The samples of the stored simulation recording at `path`, refused past `max_samples` rows
/// over all methods.
pub fn samples(path: &Path, max_samples: u64) -> Result<RecordedDocument, ReadError> {
    // Paths are drawn from the rows, so their entities are not needed.
    let decoded = decode(path, |p| !p.ends_with("/path"))?;
    let (request, _, sim) = recorded_simulation(&decoded)?;
    // A geomint recording that decodes but lacks the rows this server writes (say, from
    // another version of it) is not a simulation this server can plot.
    columns_of(&decoded.chunks, &sim, max_samples)
        .map(|runs| RecordedDocument {
            request,
            system: SystemSummary::of(&sim),
            schedule: ScheduleSummary::of(&sim),
            invariants: sim
                .invariant_names()
                .iter()
                .map(|n| n.to_string())
                .collect(),
            runs,
        })
        .map_err(|e| match e {
            ReadError::Invalid(why) => ReadError::NotASimulation(format!(
                "not laid out as this server records simulations: {why}; it can be viewed, not \
                 plotted"
            )),
            other => other,
        })
}

/// Every method's runs in `chunks`, laid out as [`crate::recording::simulation`] writes `sim`.
fn columns_of(
    chunks: &BTreeMap<String, Vec<Chunk>>,
    sim: &Simulation,
    max_samples: u64,
) -> Result<Vec<RecordedRun>, ReadError> {
    let labels: Vec<String> = sim.methods.iter().map(|m| m.label()).collect();
    let entities = entity_names(&labels);
    let invariants: Vec<String> = sim
        .invariant_names()
        .iter()
        .map(|n| n.to_string())
        .collect();
    let dof = sim.q0.len();
    let phase_dofs = dof.min(MAX_PHASE_DOFS);

    let mut energies = Vec::with_capacity(entities.len());
    let mut total = 0u64;
    for m in &entities {
        let path = format!("/{m}/energy");
        let energy = rows(chunks, &path, scalar_rows)?
            .ok_or_else(|| invalid(format!("the recording has no {path}")))?;
        total += energy.len() as u64;
        if total > max_samples {
            let all: u64 = entities
                .iter()
                .filter_map(|m| chunks.get(&format!("/{m}/energy")))
                .flatten()
                .filter(|c| !c.is_static())
                .map(|c| c.num_rows() as u64)
                .sum();
            return Err(ReadError::TooManySamples {
                samples: all,
                max: max_samples,
            });
        }
        energies.push(energy);
    }

    let mut runs = Vec::with_capacity(entities.len());
    for ((m, label), energy) in entities.iter().zip(&labels).zip(energies) {
        let steps: Vec<i64> = energy.iter().map(|r| r.step).collect();
        let mut columns = Columns::with_invariants(&invariants);
        columns.t = energy.iter().map(|r| r.t).collect();
        columns.energy = energy.iter().map(|r| r.value).collect();

        let path = format!("/{m}/energy_error");
        if let Some(errors) = rows(chunks, &path, scalar_rows)? {
            aligned(&path, &errors, &steps)?;
            columns.energy_error = Some(errors.into_iter().map(|r| r.value).collect());
        }
        for name in &invariants {
            let path = format!("/{m}/invariants/{}", entity_part(name));
            if let Some(values) = rows(chunks, &path, scalar_rows)? {
                aligned(&path, &values, &steps)?;
                columns
                    .invariants
                    .insert(name.clone(), values.into_iter().map(|r| r.value).collect());
            }
        }

        // Positions and momenta from the phase points, one entity per degree of freedom.
        columns.q = vec![Vec::with_capacity(phase_dofs); steps.len()];
        columns.p = vec![Vec::with_capacity(phase_dofs); steps.len()];
        let positions = Points2D::descriptor_positions().component;
        for d in 0..phase_dofs {
            let path = format!("/{m}/phase/{d}/point");
            let points = rows(chunks, &path, |c| point_rows::<2>(c, positions))?
                .ok_or_else(|| invalid(format!("the recording has no {path}")))?;
            aligned(&path, &points, &steps)?;
            for (k, row) in points.into_iter().enumerate() {
                let [q, p] = row.value.as_slice() else {
                    return Err(invalid(format!("{path} has a row without one point")));
                };
                columns.q[k].push(*q);
                columns.p[k].push(*p);
            }
        }

        let path = format!("/{m}/world/bodies");
        let bodies = Points3D::descriptor_positions().component;
        if let Some(world) = rows(chunks, &path, |c| point_rows::<3>(c, bodies))? {
            aligned(&path, &world, &steps)?;
            columns.cartesian_q = world
                .iter()
                .map(|r| sim.world().configuration(&r.value))
                .collect();
        }

        let path = format!("/{m}/force_evaluations");
        let force_evaluations = rows(chunks, &path, scalar_rows)?
            .and_then(|rows| rows.last().map(|r| r.value))
            .filter(|v| v.is_finite() && *v >= 0.0)
            .map(|v| v as u64);
        let q: Vec<f64> = columns
            .q
            .iter()
            .filter_map(|q| q.first().copied())
            .collect();
        let drift = sim.dissipation_drift(&columns.t, &q);
        runs.push(RecordedRun {
            method: label.clone(),
            last_step: steps.last().map_or(0, |&s| s.max(0) as u64),
            columns,
            force_evaluations,
            dissipation_drift: drift,
        });
    }
    Ok(runs)
}
