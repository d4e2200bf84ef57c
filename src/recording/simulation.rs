//! The recording of a simulation: the same runs as the JSON document, laid out as
//! entities the Rerun viewer (0.33) shows without configuration, plus a default blueprint.
//!
//! Entity layout (`{m}` is a method's entity name, see [`entity_names`](super::entity_names)):
//!
//! | entity | archetype | rows |
//! |---|---|---|
//! | `/spec` | `TextDocument` (static): the request as JSON | — |
//! | `/{m}/energy`, `/{m}/energy_error` | `Scalars` + static `SeriesLines` (name = method label) | one per sample |
//! | `/{m}/invariants/{name}` | `Scalars` + static `SeriesLines` | one per sample |
//! | `/{m}/force_evaluations` | `Scalars` + static `SeriesPoints` | one, at the last sample |
//! | `/{m}/phase/{dof}/point` | `Points2D` (q, p), the current state | one per sample |
//! | `/{m}/phase/{dof}/path` | `LineStrips2D`, the path since the previous row | see [`path_blocks`](super::layout::path_blocks) |
//! | `/{m}/world/bodies` | `Points3D`, the bodies in physical space (Cartesian coordinates whatever the chart; the planar pendulum at (x, 0, −y)); for the pendulums also `LineStrips3D`, the rod or spring from the origin | one per sample |
//! | `/{m}/world/path` | `LineStrips3D`, each body's path since the previous row | see [`path_blocks`](super::layout::path_blocks) |
//! | `/{m}/section/{dof}` | `Points2D` (q, p) of a Poincaré section's point (runs with a `section`) | one per point, at its time and the step past it |
//! | `/{m}/world/section` | `Points3D`, the bodies at the section's point, in physical space | one per point |
//! | `/{m}/indicators/{name}` | `Scalars` + static `SeriesLines`: `megno_mean`, `megno`, `fli`, `sali`, `gali` (those asked for) | one per sample |
//! | `/{m}/indicators/lyapunov/{i}` | `Scalars` + static `SeriesLines`: the i-th largest finite-time exponent | one per sample |
//!
//! Timelines: `step` (sequence) and `t` (duration, seconds). Every entity of a method carries
//! its colour; all series of one quantity share the series name pattern so that the methods
//! overlay in one plot. Phase portraits exist for the first [`MAX_PHASE_DOFS`](super::layout::MAX_PHASE_DOFS) degrees of freedom.
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
//! Series are sent as columns (`send_columns`), one chunk per entity for each chunk of samples:
//! a [`RunLogger`] logs a run chunk by chunk as the integrator produces them (see
//! [`super::live`]), and a whole document is logged as one chunk per run ([`log_simulation`]),
//! with the same rows.

use std::io::Write;
use std::sync::Mutex;

use rerun::{
    AsComponents as _, LineStrips2D, LineStrips3D, Points2D, Points3D, Radius, RecordingStream,
    Scalars, SeriesLines, SeriesPoints, TextDocument, TimeColumn, ViewCoordinates,
};

use super::layout::{path_block_len, sample_step, send_blueprint, Layout};
use super::Spec;
use super::{color, encode, method_color, RecordingError, STEP_TIMELINE, TIME_TIMELINE};
use crate::core::simulation::{Columns, CrossingColumns, ScheduleSummary, SimulationDocument};
use crate::core::systems::World;

/// Logs every run of `doc` (and the spec) to `rec`: static styles first, then each run's
/// samples as one chunk of columns.
pub fn log_simulation(
    rec: &RecordingStream,
    spec: &Spec,
    doc: &SimulationDocument,
) -> Result<(), RecordingError> {
    let layout = Layout::of(doc);
    // The path blocks of a run follow its actual sample count, also for runs that stopped early.
    let logger = SimulationLogger::start(rec, spec, &layout, &doc.schedule, |i| {
        doc.runs[i].columns.t.len()
    })?;
    for (i, run) in doc.runs.iter().enumerate() {
        logger.samples(i, 0, &run.columns)?;
        if let Some(points) = &run.section {
            logger.section(i, 0, points)?;
        }
        logger.finish(i, run.outcome.stats.force_evaluations)?;
    }
    Ok(())
}

/// Logs a simulation into a recording as its samples come: the spec and every entity's static
/// style when it starts, then each method's chunks of samples in order ([`RunLogger`]), from
/// any thread.
#[derive(Debug)]
pub struct SimulationLogger {
    runs: Vec<Mutex<RunLogger>>,
}

impl SimulationLogger {
    /// Logs the spec and the static styles of every method of `layout`. `expected(i)` is the
    /// number of samples method `i` is expected to have; it sets the length of its path blocks
    /// (see [`path_blocks`](super::layout::path_blocks)).
    pub fn start(
        rec: &RecordingStream,
        spec: &Spec,
        layout: &Layout,
        schedule: &ScheduleSummary,
        expected: impl Fn(usize) -> usize,
    ) -> Result<Self, RecordingError> {
        let spec_json = spec.json();
        rec.log_static(
            "/spec",
            &TextDocument::from_markdown(format!("```json\n{spec_json}\n```")),
        )?;
        rec.log_static("/", &ViewCoordinates::RIGHT_HAND_Z_UP())?;
        let runs = (0..layout.methods.len())
            .map(|i| RunLogger::start(rec, layout, i, schedule, expected(i)).map(Mutex::new))
            .collect::<Result<_, _>>()?;
        Ok(SimulationLogger { runs })
    }

    fn run(&self, method: usize) -> Result<std::sync::MutexGuard<'_, RunLogger>, RecordingError> {
        let run = self.runs.get(method).ok_or_else(|| {
            RecordingError::Unexpected(format!(
                "samples of method {method}, but there are {} methods",
                self.runs.len()
            ))
        })?;
        Ok(run.lock().unwrap_or_else(|p| p.into_inner()))
    }

    /// Logs the samples `offset..offset + n` of method `method`.
    pub fn samples(
        &self,
        method: usize,
        offset: u64,
        columns: &Columns,
    ) -> Result<(), RecordingError> {
        self.run(method)?.samples(offset, columns)
    }

    /// Logs the section points `offset..offset + n` of method `method`.
    pub fn section(
        &self,
        method: usize,
        offset: u64,
        points: &CrossingColumns,
    ) -> Result<(), RecordingError> {
        self.run(method)?.section(offset, points)
    }

    /// Ends the run of method `method` (see [`RunLogger::finish`]).
    pub fn finish(&self, method: usize, force_evaluations: u64) -> Result<(), RecordingError> {
        self.run(method)?.finish(force_evaluations)
    }
}

/// Logs one method's run as its samples come, chunk by chunk, each entity's new rows as columns
/// (`send_columns`): the series, the phase points and the world's bodies at once; the paths
/// whenever a path block (see [`path_blocks`](super::layout::path_blocks)) is complete, keeping the samples since the last
/// block's end until then; the rest of the path and the force evaluations when the run ends.
#[derive(Debug)]
pub struct RunLogger {
    rec: RecordingStream,
    /// The method's entity name.
    entity: String,
    invariants: Vec<(String, String)>,
    phase_dofs: usize,
    world: World,
    /// Bodies drawn per sample.
    per_row: usize,
    every: u64,
    steps: u64,
    /// Samples per path block.
    block: usize,
    /// Samples logged so far.
    logged: u64,
    /// Step and time of the last sample logged.
    last: Option<(i64, f64)>,
    /// The phase path of each degree of freedom since the last path row, that row's last sample
    /// first.
    phase_path: Vec<Vec<[f32; 2]>>,
    /// The bodies' positions since the last path row (`per_row` per sample), likewise.
    world_path: Vec<[f32; 3]>,
    /// The step size (a section point's step is the first after its time).
    h: f64,
    /// Section points logged so far.
    section_logged: u64,
}

/// The series of a run's chaos indicators in `c`: (entity part, values).
fn indicator_series(c: &Columns) -> Vec<(String, Vec<f64>)> {
    let mut series = Vec::new();
    if let Some(spectra) = &c.lyapunov {
        let k = spectra.first().map_or(0, Vec::len);
        for i in 0..k {
            series.push((
                format!("lyapunov/{i}"),
                spectra.iter().map(|s| s[i]).collect(),
            ));
        }
    }
    for (part, column) in [
        ("megno_mean", &c.megno_mean),
        ("megno", &c.megno),
        ("fli", &c.fli),
        ("sali", &c.sali),
        ("gali", &c.gali),
    ] {
        if let Some(values) = column {
            series.push((part.to_string(), values.clone()));
        }
    }
    series
}

impl RunLogger {
    /// Logs the static styles of method `index` of `layout`, whose run is expected to have
    /// `expected` samples.
    pub fn start(
        rec: &RecordingStream,
        layout: &Layout,
        index: usize,
        schedule: &ScheduleSummary,
        expected: usize,
    ) -> Result<Self, RecordingError> {
        let m = &layout.methods[index];
        let label = layout.labels[index].as_str();
        let rgb = method_color(index);
        let series = SeriesLines::new()
            .with_names([label])
            .with_colors([color(rgb)])
            .with_widths([1.5]);
        rec.log_static(format!("/{m}/energy"), &series)?;
        if layout.energy_error {
            rec.log_static(format!("/{m}/energy_error"), &series)?;
        }
        for (_, part) in &layout.invariants {
            rec.log_static(format!("/{m}/invariants/{part}"), &series)?;
        }
        for path in layout.indicator_entities(index) {
            rec.log_static(path, &series)?;
        }
        rec.log_static(
            format!("/{m}/force_evaluations"),
            &SeriesPoints::new()
                .with_names([label])
                .with_colors([color(rgb)])
                .with_marker_sizes([4.0]),
        )?;
        let line_radius = Radius::new_ui_points(0.75);
        for dof in 0..layout.phase_dofs {
            rec.log_static(
                format!("/{m}/phase/{dof}/point"),
                &Points2D::update_fields()
                    .with_colors([color(rgb)])
                    .with_radii([Radius::new_ui_points(3.0)]),
            )?;
            rec.log_static(
                format!("/{m}/phase/{dof}/path"),
                &LineStrips2D::update_fields()
                    .with_colors([color(rgb)])
                    .with_radii([line_radius]),
            )?;
        }
        let mut points = Points3D::update_fields()
            .with_colors([color(rgb)])
            .with_radii([Radius::new_ui_points(5.0)])
            .as_serialized_batches();
        if layout.world.link().is_some() {
            points.extend(
                LineStrips3D::update_fields()
                    .with_colors([color(rgb)])
                    .with_radii([Radius::new_ui_points(1.5)])
                    .as_serialized_batches(),
            );
        }
        rec.log_serialized_batches(format!("/{m}/world/bodies"), true, points)?;
        rec.log_static(
            format!("/{m}/world/path"),
            &LineStrips3D::update_fields()
                .with_colors([color(rgb)])
                .with_radii([line_radius]),
        )?;
        if layout.section {
            let dot = Radius::new_ui_points(1.5);
            for dof in 0..layout.phase_dofs {
                rec.log_static(
                    format!("/{m}/section/{dof}"),
                    &Points2D::update_fields()
                        .with_colors([color(rgb)])
                        .with_radii([dot]),
                )?;
            }
            rec.log_static(
                format!("/{m}/world/section"),
                &Points3D::update_fields()
                    .with_colors([color(rgb)])
                    .with_radii([dot]),
            )?;
        }
        Ok(RunLogger {
            rec: rec.clone(),
            entity: m.clone(),
            invariants: layout.invariants.clone(),
            phase_dofs: layout.phase_dofs,
            world: layout.world.clone(),
            per_row: layout.world.bodies(layout.dof).max(1),
            every: schedule.every,
            steps: schedule.steps,
            block: path_block_len(expected),
            logged: 0,
            last: None,
            phase_path: vec![Vec::new(); layout.phase_dofs],
            world_path: Vec::new(),
            h: schedule.h,
            section_logged: 0,
        })
    }

    /// Logs the next points of the run's section (points `offset..offset + n`; `offset` must be
    /// the number logged before): each at its own time, as (q, p) per degree of freedom and as
    /// the bodies in physical space.
    pub fn section(&mut self, offset: u64, c: &CrossingColumns) -> Result<(), RecordingError> {
        let n = c.t.len();
        if n == 0 {
            return Ok(());
        }
        if offset != self.section_logged {
            return Err(RecordingError::Unexpected(format!(
                "section points of {} from {offset}, but {} were logged before",
                self.entity, self.section_logged
            )));
        }
        let m = &self.entity;
        let steps = c.t.iter().map(|t| (t / self.h).ceil().max(0.0) as i64);
        let times = [
            TimeColumn::new_sequence(STEP_TIMELINE, steps),
            TimeColumn::new_duration_secs(TIME_TIMELINE, c.t.iter().copied()),
        ];
        for dof in 0..self.phase_dofs {
            let points =
                c.q.iter()
                    .zip(&c.p)
                    .map(|(q, p)| [q[dof] as f32, p[dof] as f32]);
            self.rec.send_columns(
                format!("/{m}/section/{dof}"),
                times.iter().cloned(),
                Points2D::new(points).columns_of_unit_batches()?,
            )?;
        }
        let mut exact: Vec<[f64; 3]> = Vec::with_capacity(n * self.per_row);
        for q in c.cartesian_q.as_ref().unwrap_or(&c.q) {
            self.world.positions(q, &mut exact);
        }
        let positions = exact
            .iter()
            .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32]);
        self.rec.send_columns(
            format!("/{m}/world/section"),
            times.iter().cloned(),
            Points3D::new(positions).columns(std::iter::repeat_n(self.per_row, n))?,
        )?;
        self.section_logged += n as u64;
        Ok(())
    }

    /// Logs the next samples of the run: `columns` holds samples `offset..offset + n`, and
    /// `offset` must be the number of samples logged before.
    pub fn samples(&mut self, offset: u64, c: &Columns) -> Result<(), RecordingError> {
        let n = c.t.len();
        if n == 0 {
            return Ok(());
        }
        if offset != self.logged {
            return Err(RecordingError::Unexpected(format!(
                "samples of {} from {offset}, but {} were logged before",
                self.entity, self.logged
            )));
        }
        let m = &self.entity;
        let steps: Vec<i64> = (offset..offset + n as u64)
            .map(|i| sample_step(i, self.every, self.steps))
            .collect();
        let times = [
            TimeColumn::new_sequence(STEP_TIMELINE, steps.iter().copied()),
            TimeColumn::new_duration_secs(TIME_TIMELINE, c.t.iter().copied()),
        ];
        let rec = &self.rec;
        send_scalars(rec, &format!("/{m}/energy"), &times, &c.energy)?;
        if let Some(errors) = &c.energy_error {
            send_scalars(rec, &format!("/{m}/energy_error"), &times, errors)?;
        }
        for (name, part) in &self.invariants {
            if let Some(values) = c.invariants.get(name) {
                send_scalars(rec, &format!("/{m}/invariants/{part}"), &times, values)?;
            }
        }
        for (part, values) in indicator_series(c) {
            send_scalars(rec, &format!("/{m}/indicators/{part}"), &times, &values)?;
        }

        // Phase portraits: the current state.
        let states: Vec<Vec<[f32; 2]>> = (0..self.phase_dofs)
            .map(|dof| {
                c.q.iter()
                    .zip(&c.p)
                    .map(|(q, p)| [q[dof] as f32, p[dof] as f32])
                    .collect()
            })
            .collect();
        for (dof, states) in states.iter().enumerate() {
            rec.send_columns(
                format!("/{m}/phase/{dof}/point"),
                times.iter().cloned(),
                Points2D::new(states.iter().copied()).columns_of_unit_batches()?,
            )?;
        }

        // The world: the bodies, with the rod or spring to the origin; in physical (Cartesian)
        // coordinates whatever the chart.
        let per_row = self.per_row;
        let mut exact: Vec<[f64; 3]> = Vec::with_capacity(n * per_row);
        for q in c.cartesian_q.as_ref().unwrap_or(&c.q) {
            self.world.positions(q, &mut exact);
        }
        let positions: Vec<[f32; 3]> = exact
            .iter()
            .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32])
            .collect();
        let mut columns: Vec<_> = Points3D::new(positions.iter().copied())
            .columns(std::iter::repeat_n(per_row, n))?
            .collect();
        if self.world.link().is_some() {
            let links = positions.iter().map(|&p| [[0.0, 0.0, 0.0], p]);
            columns.extend(LineStrips3D::new(links).columns_of_unit_batches()?);
        }
        rec.send_columns(format!("/{m}/world/bodies"), times.iter().cloned(), columns)?;

        // The paths: a row whenever a block ends (at sample 0, then every `block` samples).
        let mut rows = PathRows::new(self.phase_dofs);
        for k in 0..n {
            for (path, states) in self.phase_path.iter_mut().zip(&states) {
                path.push(states[k]);
            }
            let bodies = &positions[k * per_row..(k + 1) * per_row];
            self.world_path.extend_from_slice(bodies);
            if (offset as usize + k) % self.block == 0 {
                self.cut(&mut rows, steps[k], c.t[k]);
            }
        }
        self.send_paths(rows)?;
        self.logged += n as u64;
        self.last = Some((steps[n - 1], c.t[n - 1]));
        Ok(())
    }

    /// Moves the path since the last row into a new row of `rows` at (`step`, `t`); the path
    /// then starts over from its last sample.
    fn cut(&mut self, rows: &mut PathRows, step: i64, t: f64) {
        rows.steps.push(step);
        rows.t.push(t);
        for (path, strips) in self.phase_path.iter_mut().zip(&mut rows.phase) {
            let last = path.last().copied();
            strips.push(std::mem::replace(path, last.into_iter().collect()));
        }
        let per_row = self.per_row;
        for body in 0..per_row {
            rows.world.push(
                self.world_path[body..]
                    .iter()
                    .step_by(per_row)
                    .copied()
                    .collect(),
            );
        }
        let keep = self.world_path.len() - per_row;
        self.world_path.drain(..keep);
    }

    fn send_paths(&self, rows: PathRows) -> Result<(), RecordingError> {
        if rows.steps.is_empty() {
            return Ok(());
        }
        let m = &self.entity;
        let times = [
            TimeColumn::new_sequence(STEP_TIMELINE, rows.steps.iter().copied()),
            TimeColumn::new_duration_secs(TIME_TIMELINE, rows.t.iter().copied()),
        ];
        for (dof, strips) in rows.phase.iter().enumerate() {
            self.rec.send_columns(
                format!("/{m}/phase/{dof}/path"),
                times.iter().cloned(),
                LineStrips2D::new(strips.iter().map(|s| s.iter().copied()))
                    .columns_of_unit_batches()?,
            )?;
        }
        let count = rows.steps.len();
        self.rec.send_columns(
            format!("/{m}/world/path"),
            times.iter().cloned(),
            LineStrips3D::new(rows.world.iter().map(|s| s.iter().copied()))
                .columns(std::iter::repeat_n(self.per_row, count))?,
        )?;
        Ok(())
    }

    /// Ends the run: logs the rest of the paths (the samples after the last block's end) and
    /// the number of force evaluations, once, at the last sample (step 0 when there is none).
    pub fn finish(&mut self, force_evaluations: u64) -> Result<(), RecordingError> {
        let (step, t) = self.last.unwrap_or((0, 0.0));
        // The path holds the last row's end and the samples since; only these need a row.
        if self.world_path.len() > self.per_row {
            let mut rows = PathRows::new(self.phase_dofs);
            self.cut(&mut rows, step, t);
            self.send_paths(rows)?;
        }
        self.rec.send_columns(
            format!("/{}/force_evaluations", self.entity),
            [
                TimeColumn::new_sequence(STEP_TIMELINE, [step]),
                TimeColumn::new_duration_secs(TIME_TIMELINE, [t]),
            ],
            Scalars::new([force_evaluations as f64]).columns_of_unit_batches()?,
        )?;
        Ok(())
    }
}

/// Path rows being assembled: their times, each degree of freedom's phase strips and the
/// bodies' world strips (`per_row` per row).
struct PathRows {
    steps: Vec<i64>,
    t: Vec<f64>,
    phase: Vec<Vec<Vec<[f32; 2]>>>,
    world: Vec<Vec<[f32; 3]>>,
}

impl PathRows {
    fn new(phase_dofs: usize) -> Self {
        PathRows {
            steps: Vec::new(),
            t: Vec::new(),
            phase: vec![Vec::new(); phase_dofs],
            world: Vec::new(),
        }
    }
}

/// Sends one scalar series: `values[k]` at the k-th time of `times`.
fn send_scalars(
    rec: &RecordingStream,
    path: &str,
    times: &[TimeColumn; 2],
    values: &[f64],
) -> Result<(), RecordingError> {
    rec.send_columns(
        path,
        times.iter().cloned(),
        Scalars::new(values.iter().copied()).columns_of_unit_batches()?,
    )?;
    Ok(())
}

/// The recording name of a simulation: the system and the method labels.
pub fn recording_name<S: AsRef<str>>(system: &str, labels: &[S]) -> String {
    let methods: Vec<&str> = labels.iter().map(|l| l.as_ref()).collect();
    format!("{system}: {}", methods.join(", "))
}

/// The system as a recording names it: a definition's own `name` where the spec's `system` has
/// one (a typed-in system's id, `sys-5b5d…`, says nothing to a reader), else `id`.
pub fn system_label(spec: &Spec, id: &str) -> String {
    serde_json::from_str::<serde_json::Value>(spec.json())
        .ok()
        .and_then(|v| Some(v.get("system")?.get("name")?.as_str()?.trim().to_string()))
        .filter(|name| !name.is_empty())
        .unwrap_or_else(|| id.to_string())
}

/// Writes the `.rrd` file of a simulation to `writer`: the spec, every run of `doc`, and the
/// default blueprint. Returns the writer once the stream is complete (footer included).
pub fn write_rrd<W: Write + Send + 'static>(
    writer: W,
    spec: &Spec,
    doc: &SimulationDocument,
) -> Result<W, RecordingError> {
    let labels: Vec<&str> = doc.runs.iter().map(|r| r.method.as_str()).collect();
    let system = system_label(spec, &doc.system.id);
    encode::write(writer, recording_name(&system, &labels), |rec| {
        log_simulation(rec, spec, doc)?;
        send_blueprint(rec, &Layout::of(doc))
    })
}

/// The `.rrd` file of a simulation in memory (see [`write_rrd`]).
pub fn rrd_bytes(spec: &Spec, doc: &SimulationDocument) -> Result<Vec<u8>, RecordingError> {
    write_rrd(Vec::new(), spec, doc)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_definition_is_named_by_its_name_and_a_built_in_system_by_its_id() {
        let typed = Spec::of(&serde_json::json!({
            "system": {"name": " Hénon–Heiles ", "coordinates": ["x", "y"], "potential": "x^2"},
            "method": "rk4"
        }));
        assert_eq!(system_label(&typed, "sys-5b5d6f70"), "Hénon–Heiles");
        let unnamed =
            Spec::of(&serde_json::json!({"system": {"coordinates": ["x"], "potential": "x^2"}}));
        assert_eq!(system_label(&unnamed, "sys-5b5d6f70"), "sys-5b5d6f70");
        let built_in = Spec::of(&serde_json::json!({"system": "pendulum"}));
        assert_eq!(system_label(&built_in, "pendulum"), "pendulum");
        assert_eq!(
            recording_name(&system_label(&typed, "sys-5b5d6f70"), &["rk4", "heun"]),
            "Hénon–Heiles: rk4, heun"
        );
    }
}
