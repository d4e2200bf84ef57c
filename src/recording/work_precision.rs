//! The recording of a work–precision study: the diagram in a 2-D view, since Rerun's plots have
//! no arbitrary x axis.
//!
//! | entity | archetype | content |
//! |---|---|---|
//! | `/spec` | `TextDocument`: the request as JSON | — |
//! | `/table` | `TextDocument`: every setting with its measurements | — |
//! | `/{m}/settings` | `Points2D` at (log₁₀ max energy error, log₁₀ ms), labelled with the setting | one point per finished setting |
//! | `/{m}/curve` | `LineStrips2D` through them, in order of error | — |
//! | `/{m}/fit` | `LineStrips2D`, the fitted line over the method's error range | — |
//!
//! Everything is static; one colour per method (request order).

use std::io::Write;

use rerun::external::re_sdk_types::blueprint::components::ContainerKind;
use rerun::{LineStrips2D, Points2D, Radius, RecordingStream, TextDocument};

use super::blueprint::{self, BlueprintNode};
use super::Spec;
use super::{color, encode, entity_names, method_color, RecordingError};
use crate::core::studies::work_precision::WorkPrecisionDocument;

/// The per-run labels of a study (`runs[i]`'s method).
fn run_labels(doc: &WorkPrecisionDocument) -> Vec<String> {
    let runs = doc.fits.iter().map(|f| f.run).max().map_or(0, |r| r + 1);
    (0..runs)
        .map(|run| {
            doc.points
                .iter()
                .find(|p| p.run == run)
                .map_or_else(|| format!("run {run}"), |p| p.method.clone())
        })
        .collect()
}

/// Logs the study: spec, table, and per run its points, curve and fitted line.
pub fn log_study(
    rec: &RecordingStream,
    spec: &Spec,
    doc: &WorkPrecisionDocument,
) -> Result<(), RecordingError> {
    let spec_json = spec.json();
    rec.log_static(
        "/spec",
        &TextDocument::from_markdown(format!("```json\n{spec_json}\n```")),
    )?;
    let mut table = format!(
        "**{}**, t_end = {}, {} samples; errors against the {} \n\n\
         | method | setting | ms | force evaluations | max abs energy error | final state error | stop |\n\
         |---|---|---|---|---|---|---|\n",
        doc.system.id, doc.t_end, doc.samples, doc.reference
    );
    let fmt = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{v:.2e}"));
    for p in &doc.points {
        let setting = match (p.h, p.tolerance) {
            (Some(h), _) => format!("h = {h}"),
            (_, Some(t)) => format!("tol = {t:e}"),
            _ => String::new(),
        };
        table.push_str(&format!(
            "| {} | {setting} | {:.3} | {} | {} | {} | {} |\n",
            p.method,
            p.wall_ms,
            p.force_evaluations,
            fmt(p.max_energy_error),
            fmt(p.final_state_error),
            p.stop
        ));
    }
    rec.log_static("/table", &TextDocument::from_markdown(table))?;

    let labels = run_labels(doc);
    for (run, m) in entity_names(&labels).iter().enumerate() {
        let rgb = color(method_color(run));
        let mut points: Vec<([f32; 2], String)> = doc
            .points
            .iter()
            .filter(|p| p.run == run)
            .filter_map(|p| {
                let e = p.max_energy_error.filter(|&e| e > 0.0 && e.is_finite())?;
                let setting = match (p.h, p.tolerance) {
                    (Some(h), _) => format!("h={h}"),
                    (_, Some(t)) => format!("tol={t:e}"),
                    _ => String::new(),
                };
                let label = format!("{} {setting}: {:.3} ms, {e:.1e}", p.method, p.wall_ms);
                Some((
                    [e.log10() as f32, p.wall_ms.max(1e-6).log10() as f32],
                    label,
                ))
            })
            .collect();
        if points.is_empty() {
            continue;
        }
        points.sort_by(|a, b| a.0[0].total_cmp(&b.0[0]));
        rec.log_static(
            format!("/{m}/settings"),
            &Points2D::new(points.iter().map(|p| p.0))
                .with_labels(points.iter().map(|p| p.1.clone()))
                .with_colors([rgb])
                .with_radii([Radius::new_ui_points(4.0)]),
        )?;
        rec.log_static(
            format!("/{m}/curve"),
            &LineStrips2D::new([points.iter().map(|p| p.0)])
                .with_colors([rgb])
                .with_radii([Radius::new_ui_points(1.0)])
                .with_labels([labels[run].clone()]),
        )?;
        if let Some(fit) = doc.fits.iter().find(|f| f.run == run) {
            if let (Some(slope), Some(intercept)) = (fit.slope, fit.intercept) {
                let (x0, x1) = (points[0].0[0], points[points.len() - 1].0[0]);
                let at = |x: f32| [x, (intercept + slope * f64::from(x)) as f32];
                rec.log_static(
                    format!("/{m}/fit"),
                    &LineStrips2D::new([[at(x0), at(x1)]])
                        .with_colors([rgb])
                        .with_radii([Radius::new_ui_points(0.5)])
                        .with_labels([format!("slope {slope:.3}")]),
                )?;
            }
        }
    }
    Ok(())
}

/// The default layout: the diagram beside the table and the spec.
fn blueprint_tree() -> BlueprintNode {
    BlueprintNode::container(
        ContainerKind::Horizontal,
        vec![
            BlueprintNode::view(
                "2D",
                "work–precision: x = log10 max energy error, y = log10 ms",
                vec!["/**".to_string()],
            ),
            BlueprintNode::container(
                ContainerKind::Tabs,
                vec![
                    BlueprintNode::view("TextDocument", "table", vec!["/table".to_string()]),
                    BlueprintNode::view("TextDocument", "spec", vec!["/spec".to_string()]),
                ],
            ),
        ],
    )
}

/// Writes the `.rrd` file of a study to `writer`.
pub fn write_rrd<W: Write + Send + 'static>(
    writer: W,
    spec: &Spec,
    doc: &WorkPrecisionDocument,
) -> Result<W, RecordingError> {
    let name = format!("work–precision: {}", doc.system.id);
    encode::write(writer, name, |rec| {
        log_study(rec, spec, doc)?;
        blueprint::send(rec, &blueprint_tree())
    })
}

/// The `.rrd` file of a study in memory (see [`write_rrd`]).
pub fn rrd_bytes(spec: &Spec, doc: &WorkPrecisionDocument) -> Result<Vec<u8>, RecordingError> {
    write_rrd(Vec::new(), spec, doc)
}
