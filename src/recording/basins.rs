//! The recording of a basin map: per run (a method in a chart) the labels as a segmentation
//! image whose classes name the attractors, the decision times as a tensor and a heatmap, and a
//! summary with the attractors' table and the metrics.
//!
//! Entity layout (all static; a map has no time):
//!
//! | entity | archetype | content |
//! |---|---|---|
//! | `/{run}` | `AnnotationContext`: class 0 `undecided` (grey), class k + 1 the attractor of label k, named and coloured | one |
//! | `/{run}/labels` | `SegmentationImage` u16, one row per point of the second axis: label + 1 per cell | one |
//! | `/{run}/decided_at` | `Tensor` f64, dims `axes[1]`, `axes[0]` (or `axes[0]` alone); NaN where undecided | one |
//! | `/{run}/decided_at/heatmap` | `Image` (RGB): the decision time from dark blue (earliest) to yellow (latest), black where undecided | one |
//! | `/summary` | `TextDocument`: the system, the axes, and per run its attractors with their shares and the metrics | one |
//!
//! `{run}` is `{method}_{chart}` made an entity path part.

use std::io::Write;

use rerun::external::re_sdk_types::datatypes::{ChannelDatatype, TensorBuffer, TensorData};
use rerun::{
    AnnotationContext, Image, ImageFormat, RecordingStream, Rgba32, SegmentationImage, Tensor,
    TextDocument,
};

use super::blueprint::{self, BlueprintNode};
use super::{encode, entity_names, method_color, RecordingError};
use crate::core::studies::basins::{BasinRun, BasinsDocument};

/// The class of undecided cells.
const UNDECIDED: (u16, &str, [u8; 3]) = (0, "undecided", [128, 128, 128]);

fn run_labels(doc: &BasinsDocument) -> Vec<String> {
    doc.runs
        .iter()
        .map(|r| format!("{}_{}", r.label.method, r.label.chart))
        .collect()
}

/// Logs the map.
pub fn log_basins(rec: &RecordingStream, doc: &BasinsDocument) -> Result<(), RecordingError> {
    let n0 = doc.axes[0].n;
    let n1 = doc.axes.get(1).map_or(1, |a| a.n);
    let (shape, names): (Vec<u64>, Vec<String>) = match doc.axes.get(1) {
        Some(second) => (
            vec![n1 as u64, n0 as u64],
            vec![second.name.clone(), doc.axes[0].name.clone()],
        ),
        None => (vec![n0 as u64], vec![doc.axes[0].name.clone()]),
    };
    let mut text = summary_head(doc);
    for (run, part) in doc.runs.iter().zip(entity_names(&run_labels(doc))) {
        let classes: Vec<(u16, &str, [u8; 3])> = std::iter::once(UNDECIDED)
            .chain(run.attractors.iter().map(|a| {
                let id = u16::try_from(a.label + 1).unwrap_or(u16::MAX);
                (id, a.name.as_str(), method_color(a.label as usize))
            }))
            .collect();
        rec.log_static(
            format!("/{part}"),
            &AnnotationContext::new(
                classes
                    .iter()
                    .map(|&(id, name, [r, g, b])| (id, name, Rgba32::from_rgb(r, g, b))),
            ),
        )?;
        let ids: Vec<u8> = run
            .labels
            .iter()
            .map(|&l| u16::try_from(l + 1).unwrap_or(0))
            .flat_map(u16::to_le_bytes)
            .collect();
        rec.log_static(
            format!("/{part}/labels"),
            &SegmentationImage::new(
                ids,
                ImageFormat::segmentation([n0 as u32, n1 as u32], ChannelDatatype::U16),
            ),
        )?;
        let times: Vec<f64> = run
            .decided_at
            .iter()
            .map(|t| t.unwrap_or(f64::NAN))
            .collect();
        let data = TensorData::new(shape.clone(), TensorBuffer::F64(times.clone().into()))
            .with_dim_names(names.clone());
        rec.log_static(format!("/{part}/decided_at"), &Tensor::new(data))?;
        let (pixels, _) = super::sweep::heatmap(&times, false);
        rec.log_static(
            format!("/{part}/decided_at/heatmap"),
            &Image::from_rgb24(pixels, [n0 as u32, n1 as u32]),
        )?;
        text.push_str(&run_summary(&part, run));
    }
    rec.log_static("/summary", &TextDocument::from_markdown(text))?;
    Ok(())
}

fn summary_head(doc: &BasinsDocument) -> String {
    let axes: Vec<String> = doc
        .axes
        .iter()
        .enumerate()
        .map(|(k, a)| {
            let along = if k == 0 { "columns" } else { "rows" };
            format!(
                "- {along}: `{}` from {} to {} in {} points",
                a.name, a.min, a.max, a.n
            )
        })
        .collect();
    let saddle = doc
        .lowest_saddle_energy
        .map_or(String::new(), |e| format!("Lowest saddle: V = {e}.\n\n"));
    format!(
        "**Basin map of {}**, {} cells in {:.0} ms\n\n{}\n\n{saddle}",
        doc.system,
        doc.cells,
        doc.wall_ms,
        axes.join("\n"),
    )
}

fn run_summary(part: &str, run: &BasinRun) -> String {
    let mut text = format!(
        "### {} ({})\n\n| label | attractor | kind | share |\n|---|---|---|---|\n",
        run.label.method, run.label.chart
    );
    for a in &run.attractors {
        let share = run.fractions.get(a.label as usize).copied().unwrap_or(0.0);
        text.push_str(&format!(
            "| {} | {} | {:?} | {:.4} |\n",
            a.label, a.name, a.kind, share
        ));
    }
    let number = |x: Option<f64>| x.map_or("–".to_string(), |x| format!("{x:.4}"));
    text.push_str(&format!(
        "\nUndecided: {:.4} of the cells that start an orbit; {} start none. Basin entropy \
         S_b = {}, boundary basin entropy S_bb = {}, uncertainty exponent α = {}. Images: \
         `/{part}/labels`, `/{part}/decided_at/heatmap`.\n\n",
        run.undecided_fraction,
        run.not_started,
        number(run.metrics.basin_entropy),
        number(run.metrics.boundary_basin_entropy),
        number(run.metrics.uncertainty_exponent),
    ));
    text
}

/// The default layout: each run's label map, beside the summary.
fn blueprint_tree(doc: &BasinsDocument) -> BlueprintNode {
    let labels = run_labels(doc);
    let views = entity_names(&labels)
        .into_iter()
        .zip(&labels)
        .map(|(part, label)| {
            BlueprintNode::view(
                "2D",
                format!("{label}: basins"),
                vec![format!("/{part}/labels")],
            )
        })
        .collect();
    blueprint::grid_beside_summary(views)
}

/// Writes the `.rrd` file of a basin map to `writer`; returns the writer once the stream is
/// complete.
pub fn write_rrd<W: Write + Send + 'static>(
    writer: W,
    doc: &BasinsDocument,
) -> Result<W, RecordingError> {
    let name = format!("basins: {}", doc.system);
    encode::write(writer, name, |rec| {
        log_basins(rec, doc)?;
        blueprint::send(rec, &blueprint_tree(doc))
    })
}

/// The `.rrd` file of a basin map in memory (see [`write_rrd`]).
pub fn rrd_bytes(doc: &BasinsDocument) -> Result<Vec<u8>, RecordingError> {
    write_rrd(Vec::new(), doc)
}
