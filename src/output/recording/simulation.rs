//! The recording of a simulation: the same runs as the JSON document, laid out as
//! entities the Rerun viewer (0.33) shows without configuration, plus a default blueprint.
//!
//! Entity layout (`{m}` is a method's entity name, see [`entity_names`]):
//!
//! | entity | archetype | rows |
//! |---|---|---|
//! | `/spec` | `TextDocument` (static): the request as JSON | — |
//! | `/{m}/energy`, `/{m}/energy_error` | `Scalars` + static `SeriesLines` (name = method label) | one per sample |
//! | `/{m}/invariants/{name}` | `Scalars` + static `SeriesLines` | one per sample |
//! | `/{m}/force_evaluations` | `Scalars` + static `SeriesPoints` | one, at the last sample |
//! | `/{m}/phase/{dof}/point` | `Points2D` (q, p), the current state | one per sample |
//! | `/{m}/phase/{dof}/path` | `LineStrips2D`, the path since the previous row | see [`path_blocks`] |
//! | `/{m}/world/bodies` | `Points3D`, the bodies in physical space; for the pendulums also `LineStrips3D`, the rod or spring from the origin | one per sample |
//! | `/{m}/world/path` | `LineStrips3D`, each body's path since the previous row | see [`path_blocks`] |
//!
//! Timelines: `step` (sequence) and `t` (duration, seconds). Every entity of a method carries
//! its colour; all series of one quantity share the series name pattern so that the methods
//! overlay in one plot. Phase portraits exist for the first [`MAX_PHASE_DOFS`] degrees of freedom.
//!
//! Paths grow with time: each row holds only the newest piece (one segment per sample for runs of
//! up to about 1000 samples, longer pieces for longer runs), and the blueprint's views show the
//! `path` entities over the whole timeline up to the time cursor (a per-entity visible time
//! range), so a recording stays linear in the number of samples. Without the blueprint the
//! viewer shows the newest piece only; points, rods and springs are always the current state.
//!
//! The blueprint ([`send_blueprint`]) is built from Rerun's blueprint archetypes: an energy plot
//! over all methods, tabs with the energy error, invariant and force-evaluation plots, the 3-D
//! view of every method's world, the spec and one 2-D phase view per degree of freedom.
//!
//! Series are sent as columns (`send_columns`): one chunk per entity and method.

use std::io::Write;
use std::time::Duration;

use rerun::external::re_sdk_types::blueprint::components::ContainerKind;
use rerun::{
    AsComponents as _, LineStrips2D, LineStrips3D, Points2D, Points3D, Radius, RecordingStream,
    RecordingStreamBuilder, Scalars, SeriesLines, SeriesPoints, TextDocument, TimeColumn,
    ViewCoordinates,
};

use super::blueprint::{self, Node};
use super::{
    color, encode, entity_names, entity_part, method_color, RecordingError, APPLICATION_ID,
    STEP_TIMELINE, TIME_TIMELINE,
};
use crate::output::document::{RunDocument, SimulationDocument};
use crate::output::request::SimulateRequest;

/// Degrees of freedom with a phase portrait (the first ones; an N-body run has 3N).
pub const MAX_PHASE_DOFS: usize = 6;

/// What the world view draws for a system.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum World {
    /// The oscillator on the x axis, (q, 0, 0).
    Line,
    /// A unit pendulum bob (sin q, 0, −cos q) on a rod from the origin.
    Pendulum,
    /// The elastic pendulum's mass at q on a spring from the origin.
    Spring,
    /// N bodies at q[3i..3i+3].
    Bodies,
}

impl World {
    fn of(system: &str) -> Self {
        match system {
            "pendulum" => World::Pendulum,
            "elastic_pendulum_3d" => World::Spring,
            "nbody" => World::Bodies,
            _ => World::Line,
        }
    }

    /// Bodies drawn per sample for `dof` degrees of freedom.
    fn bodies(self, dof: usize) -> usize {
        match self {
            World::Bodies => dof / 3,
            _ => 1,
        }
    }

    /// The positions of the bodies for configuration `q`, appended to `out`.
    fn positions(self, q: &[f64], out: &mut Vec<[f32; 3]>) {
        match self {
            World::Line => out.push([q.first().copied().unwrap_or(0.0) as f32, 0.0, 0.0]),
            World::Pendulum => {
                let a = q.first().copied().unwrap_or(0.0);
                out.push([a.sin() as f32, 0.0, -a.cos() as f32]);
            }
            World::Spring | World::Bodies => out.extend(
                q.chunks_exact(3)
                    .map(|c| [c[0] as f32, c[1] as f32, c[2] as f32]),
            ),
        }
    }

    /// What links the body to the origin, if anything.
    fn link(self) -> Option<&'static str> {
        match self {
            World::Pendulum => Some("rod"),
            World::Spring => Some("spring"),
            _ => None,
        }
    }
}

/// Where everything of a simulation goes: entity names and colours per method, the invariant
/// parts and what the world view shows.
#[derive(Clone, Debug)]
pub struct Layout {
    /// Method labels, in request order.
    pub labels: Vec<String>,
    /// Entity names of the methods (the first path part).
    pub methods: Vec<String>,
    /// The system's invariants as (name, entity part).
    pub invariants: Vec<(String, String)>,
    /// Degrees of freedom with a phase portrait.
    pub phase_dofs: usize,
    /// Whether the runs carry energy errors.
    pub energy_error: bool,
    world: World,
}

impl Layout {
    /// The layout of a simulation's document.
    pub fn of(doc: &SimulationDocument) -> Self {
        let labels: Vec<String> = doc.runs.iter().map(|r| r.method.clone()).collect();
        let methods = entity_names(&labels);
        let dof = doc.system.q0.len();
        Layout {
            labels,
            methods,
            invariants: doc
                .invariants
                .iter()
                .map(|n| (n.clone(), entity_part(n)))
                .collect(),
            phase_dofs: dof.min(MAX_PHASE_DOFS),
            energy_error: doc.runs.iter().any(|r| r.columns.energy_error.is_some()),
            world: World::of(&doc.system.id),
        }
    }

    /// Every entity path of method `index` that holds data, in a fixed order.
    pub fn method_entities(&self, index: usize) -> Vec<String> {
        let m = &self.methods[index];
        let mut paths = vec![format!("/{m}/energy")];
        if self.energy_error {
            paths.push(format!("/{m}/energy_error"));
        }
        for (_, part) in &self.invariants {
            paths.push(format!("/{m}/invariants/{part}"));
        }
        paths.push(format!("/{m}/force_evaluations"));
        for dof in 0..self.phase_dofs {
            paths.push(format!("/{m}/phase/{dof}/point"));
            paths.push(format!("/{m}/phase/{dof}/path"));
        }
        paths.push(format!("/{m}/world/bodies"));
        paths.push(format!("/{m}/world/path"));
        paths
    }
}

/// The step index of every sample of a run: samples are taken at step 0, every `every` steps
/// and at the last step (`steps`), so sample i is at min(i·every, steps).
pub fn sample_steps(count: usize, every: u64, steps: u64) -> Vec<i64> {
    (0..count as u64)
        .map(|i| i.saturating_mul(every).min(steps) as i64)
        .collect()
}

/// Logs every run of `doc` (and the spec) to `rec`: static styles first, then the series as
/// columns.
pub fn log_simulation(
    rec: &RecordingStream,
    spec: &SimulateRequest,
    doc: &SimulationDocument,
) -> Result<(), RecordingError> {
    let layout = Layout::of(doc);
    let spec_json = serde_json::to_string_pretty(spec).unwrap_or_default();
    rec.log_static(
        "/spec",
        &TextDocument::from_markdown(format!("```json\n{spec_json}\n```")),
    )?;
    rec.log_static("/", &ViewCoordinates::RIGHT_HAND_Z_UP())?;
    for (i, run) in doc.runs.iter().enumerate() {
        log_run(rec, doc, &layout, i, run)?;
    }
    Ok(())
}

/// Sends one scalar series with its style: `values[k]` at sample `k`.
fn send_series(
    rec: &RecordingStream,
    path: &str,
    times: &[TimeColumn; 2],
    values: &[f64],
    label: &str,
    rgb: [u8; 3],
) -> Result<(), RecordingError> {
    rec.log_static(
        path,
        &SeriesLines::new()
            .with_names([label])
            .with_colors([color(rgb)])
            .with_widths([1.5]),
    )?;
    rec.send_columns(
        path,
        times.iter().cloned(),
        Scalars::new(values.iter().copied()).columns_of_unit_batches()?,
    )?;
    Ok(())
}

fn log_run(
    rec: &RecordingStream,
    doc: &SimulationDocument,
    layout: &Layout,
    index: usize,
    run: &RunDocument,
) -> Result<(), RecordingError> {
    let m = &layout.methods[index];
    let label = &layout.labels[index];
    let rgb = method_color(index);
    let c = &run.columns;
    let n = c.t.len();
    let steps = sample_steps(n, doc.schedule.every, doc.schedule.steps);
    let times = [
        TimeColumn::new_sequence(STEP_TIMELINE, steps.iter().copied()),
        TimeColumn::new_duration_secs(TIME_TIMELINE, c.t.iter().copied()),
    ];

    send_series(rec, &format!("/{m}/energy"), &times, &c.energy, label, rgb)?;
    if let Some(errors) = &c.energy_error {
        send_series(
            rec,
            &format!("/{m}/energy_error"),
            &times,
            errors,
            label,
            rgb,
        )?;
    }
    for (name, part) in &layout.invariants {
        if let Some(values) = c.invariants.get(name) {
            let path = format!("/{m}/invariants/{part}");
            send_series(rec, &path, &times, values, label, rgb)?;
        }
    }

    // The number of force evaluations, once, where the run ended.
    let path = format!("/{m}/force_evaluations");
    rec.log_static(
        path.as_str(),
        &SeriesPoints::new()
            .with_names([label.as_str()])
            .with_colors([color(rgb)])
            .with_marker_sizes([4.0]),
    )?;
    let last_step = steps.last().copied().unwrap_or(0);
    let last_t = c.t.last().copied().unwrap_or(0.0);
    rec.send_columns(
        path.as_str(),
        [
            TimeColumn::new_sequence(STEP_TIMELINE, [last_step]),
            TimeColumn::new_duration_secs(TIME_TIMELINE, [last_t]),
        ],
        Scalars::new([run.stats.force_evaluations as f64]).columns_of_unit_batches()?,
    )?;

    // Phase portraits: the current state, and the path in blocks of `block` samples.
    let blocks = path_blocks(n);
    let block_times = [
        TimeColumn::new_sequence(STEP_TIMELINE, blocks.iter().map(|b| steps[b.end])),
        TimeColumn::new_duration_secs(TIME_TIMELINE, blocks.iter().map(|b| c.t[b.end])),
    ];
    let line_radius = Radius::new_ui_points(0.75);
    for dof in 0..layout.phase_dofs {
        let states: Vec<[f32; 2]> =
            c.q.iter()
                .zip(&c.p)
                .map(|(q, p)| [q[dof] as f32, p[dof] as f32])
                .collect();
        let point = format!("/{m}/phase/{dof}/point");
        rec.log_static(
            point.as_str(),
            &Points2D::update_fields()
                .with_colors([color(rgb)])
                .with_radii([Radius::new_ui_points(3.0)]),
        )?;
        rec.send_columns(
            point.as_str(),
            times.iter().cloned(),
            Points2D::new(states.iter().copied()).columns_of_unit_batches()?,
        )?;
        let path = format!("/{m}/phase/{dof}/path");
        rec.log_static(
            path.as_str(),
            &LineStrips2D::update_fields()
                .with_colors([color(rgb)])
                .with_radii([line_radius]),
        )?;
        let strips = blocks.iter().map(|b| &states[b.start..=b.end]);
        rec.send_columns(
            path.as_str(),
            block_times.iter().cloned(),
            LineStrips2D::new(strips.map(|s| s.iter().copied())).columns_of_unit_batches()?,
        )?;
    }

    // The world: the bodies (with the rod or spring to the origin) and their paths.
    let dof = doc.system.q0.len();
    let per_row = layout.world.bodies(dof).max(1);
    let mut positions: Vec<[f32; 3]> = Vec::with_capacity(n * per_row);
    for q in &c.q {
        layout.world.positions(q, &mut positions);
    }
    let path = format!("/{m}/world/bodies");
    let mut points = Points3D::update_fields()
        .with_colors([color(rgb)])
        .with_radii([Radius::new_ui_points(5.0)])
        .as_serialized_batches();
    let has_link = layout.world.link().is_some();
    if has_link {
        points.extend(
            LineStrips3D::update_fields()
                .with_colors([color(rgb)])
                .with_radii([Radius::new_ui_points(1.5)])
                .as_serialized_batches(),
        );
    }
    rec.log_serialized_batches(path.as_str(), true, points)?;
    let mut columns: Vec<_> = Points3D::new(positions.iter().copied())
        .columns(std::iter::repeat_n(per_row, n))?
        .collect();
    if has_link {
        let links = positions.iter().map(|&p| [[0.0, 0.0, 0.0], p]);
        columns.extend(LineStrips3D::new(links).columns_of_unit_batches()?);
    }
    rec.send_columns(path.as_str(), times.iter().cloned(), columns)?;

    let path = format!("/{m}/world/path");
    rec.log_static(
        path.as_str(),
        &LineStrips3D::update_fields()
            .with_colors([color(rgb)])
            .with_radii([line_radius]),
    )?;
    let positions = &positions;
    let strips = blocks.iter().flat_map(|b| {
        (0..per_row).map(move |body| (b.start..=b.end).map(move |k| positions[k * per_row + body]))
    });
    rec.send_columns(
        path.as_str(),
        block_times.iter().cloned(),
        LineStrips3D::new(strips).columns(std::iter::repeat_n(per_row, blocks.len()))?,
    )?;
    Ok(())
}

/// Most rows of a path entity: longer runs draw their paths in blocks of several samples.
pub const MAX_PATH_ROWS: usize = 1000;

/// A block of consecutive samples drawn as one path row, logged at the time of its last sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PathBlock {
    /// First sample of the block (the last sample of the previous block).
    pub start: usize,
    /// Last sample of the block.
    pub end: usize,
}

/// How the path of a run of `n` samples is cut into rows: the first row holds sample 0 alone,
/// then each row continues the path by up to ⌈(n − 1)/[`MAX_PATH_ROWS`]⌉ samples (one sample
/// per row for runs of up to about 1000 samples), so at most about [`MAX_PATH_ROWS`] + 1 rows.
pub fn path_blocks(n: usize) -> Vec<PathBlock> {
    if n == 0 {
        return Vec::new();
    }
    let block = (n - 1).div_ceil(MAX_PATH_ROWS).max(1);
    let mut blocks = vec![PathBlock { start: 0, end: 0 }];
    let mut start = 0;
    while start + 1 < n {
        let end = (start + block).min(n - 1);
        blocks.push(PathBlock { start, end });
        start = end;
    }
    blocks
}

/// The default layout: energy of all methods on top of the other plots (energy error,
/// invariants, force evaluations as tabs), beside the 3-D world with the spec and a grid of
/// phase portraits.
fn blueprint_tree(layout: &Layout) -> Node {
    let each = |f: &dyn Fn(&str) -> String| -> Vec<String> {
        layout.methods.iter().map(|m| f(m)).collect()
    };
    let mut plots = Vec::new();
    if layout.energy_error {
        plots.push(Node::view(
            "TimeSeries",
            "energy error",
            each(&|m| format!("/{m}/energy_error")),
        ));
    }
    for (name, part) in &layout.invariants {
        plots.push(Node::view(
            "TimeSeries",
            name.clone(),
            each(&|m| format!("/{m}/invariants/{part}")),
        ));
    }
    plots.push(Node::view(
        "TimeSeries",
        "force evaluations",
        each(&|m| format!("/{m}/force_evaluations")),
    ));
    let left = Node::container(
        ContainerKind::Vertical,
        vec![
            Node::view("TimeSeries", "energy", each(&|m| format!("/{m}/energy"))),
            Node::container(ContainerKind::Tabs, plots),
        ],
    );

    let world = Node::view("3D", "world", each(&|m| format!("/{m}/world/**")))
        .with_trails(each(&|m| format!("/{m}/world/path")));
    let spec = Node::view("TextDocument", "spec", vec!["/spec".to_string()]);
    let phases: Vec<Node> = (0..layout.phase_dofs)
        .map(|dof| {
            Node::view(
                "2D",
                format!("phase (q{dof}, p{dof})"),
                each(&|m| format!("/{m}/phase/{dof}/**")),
            )
            .with_trails(each(&|m| format!("/{m}/phase/{dof}/path")))
        })
        .collect();
    let right = Node::container(
        ContainerKind::Vertical,
        vec![
            Node::container(ContainerKind::Tabs, vec![world, spec]),
            Node::container(ContainerKind::Grid, phases),
        ],
    );
    Node::container(ContainerKind::Horizontal, vec![left, right])
}

/// Sends the default blueprint for `doc` through `rec` (as Rerun's own SDKs do: a blueprint
/// store logged in full, then an activation command making it the active and default one).
pub fn send_blueprint(
    rec: &RecordingStream,
    doc: &SimulationDocument,
) -> Result<(), RecordingError> {
    blueprint::send(rec, &blueprint_tree(&Layout::of(doc)))
}

/// Writes the `.rrd` file of a simulation to `writer`: the spec, every run of `doc`, and the
/// default blueprint. Returns the writer once the stream is complete (footer included).
pub fn write_rrd<W: Write + Send + 'static>(
    writer: W,
    spec: &SimulateRequest,
    doc: &SimulationDocument,
) -> Result<W, RecordingError> {
    let methods: Vec<&str> = doc.runs.iter().map(|r| r.method.as_str()).collect();
    let name = format!("{}: {}", doc.system.id, methods.join(", "));
    encode::write(writer, name, |rec| {
        log_simulation(rec, spec, doc)?;
        send_blueprint(rec, doc)
    })
}

/// The `.rrd` file of a simulation in memory (see [`write_rrd`]).
pub fn rrd_bytes(
    spec: &SimulateRequest,
    doc: &SimulationDocument,
) -> Result<Vec<u8>, RecordingError> {
    write_rrd(Vec::new(), spec, doc)
}

/// Streams a simulation to a running Rerun viewer at `url` (for example
/// `rerun+http://127.0.0.1:9876/proxy`): the spec, the runs and the blueprint, then waits until
/// everything is sent.
pub fn stream_to_viewer(
    url: &str,
    spec: &SimulateRequest,
    doc: &SimulationDocument,
) -> Result<(), RecordingError> {
    let rec = RecordingStreamBuilder::new(APPLICATION_ID)
        .enabled(true)
        .connect_grpc_opts(url.to_string())?;
    send_blueprint(&rec, doc)?;
    log_simulation(&rec, spec, doc)?;
    rec.flush_with_timeout(Duration::from_secs(30))
        .map_err(|e| RecordingError::Sink(e.to_string()))?;
    Ok(())
}

/// The viewer URL for `host:port`: Rerun 0.33's gRPC proxy address form.
pub fn viewer_url(addr: &str) -> String {
    format!("rerun+http://{addr}/proxy")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entity_parts_are_plain_and_unique() {
        assert_eq!(entity_part("modin_rks(rk4)"), "modin_rks_rk4");
        assert_eq!(entity_part("reference(1e-10)"), "reference_1e-10");
        assert_eq!(entity_part("L_z"), "L_z");
        assert_eq!(entity_part("spec"), "m_spec");
        assert_eq!(
            entity_names(&["heun", "heun", "triple_jump(csv1)", "heun"]),
            ["heun", "heun_2", "triple_jump_csv1", "heun_3"]
        );
    }

    #[test]
    fn path_blocks_cover_every_sample_once() {
        assert_eq!(path_blocks(0), []);
        assert_eq!(path_blocks(1), [PathBlock { start: 0, end: 0 }]);
        let short = path_blocks(3);
        assert_eq!(
            short,
            [
                PathBlock { start: 0, end: 0 },
                PathBlock { start: 0, end: 1 },
                PathBlock { start: 1, end: 2 }
            ]
        );
        let long = path_blocks(1_000_001);
        assert_eq!(long.len(), MAX_PATH_ROWS + 1);
        assert!(long.windows(2).all(|w| w[0].end == w[1].start));
        assert_eq!(long.last().unwrap().end, 1_000_000);
    }

    #[test]
    fn sample_steps_end_at_the_last_step() {
        assert_eq!(sample_steps(4, 10, 25), [0, 10, 20, 25]);
        assert_eq!(sample_steps(3, 10, 20), [0, 10, 20]);
        assert_eq!(sample_steps(2, 10, 25), [0, 10]);
    }
}
