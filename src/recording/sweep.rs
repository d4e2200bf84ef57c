//! The recording of a sweep: per run (a method in a chart) and metric, the values as a tensor
//! whose dimensions are named after the axes, and a heatmap image of them; a summary that labels
//! the axes and every image's colour scale.
//!
//! Entity layout (all static; a sweep has no time):
//!
//! | entity | archetype | content |
//! |---|---|---|
//! | `/{run}/{metric}` | `Tensor` f64, dims `axes[1]`, `axes[0]` (or `axes[0]` alone); NaN where the JSON has null | one |
//! | `/{run}/{metric}/heatmap` | `Image` (RGB, one row per point of the second axis): log₁₀ of the magnitude (linear for `diverged_at`) from dark blue (least) to yellow (most), black where null | one |
//! | `/summary` | `TextDocument`: the system, the axes with their ranges, and per image its colour scale | one |
//!
//! `{run}` is `{method}_{chart}` made an entity path part; the metrics are `energy_error_final`
//! (its magnitude), `energy_error_max`, `energy_error_l2`, `diverged_at` and `drift_{invariant}`.

use std::io::Write;

use rerun::external::re_sdk_types::datatypes::{TensorBuffer, TensorData};
use rerun::{Image, RecordingStream, Tensor, TextDocument};

use super::blueprint::{self, BlueprintNode};
use super::{encode, entity_names, RecordingError};
use crate::core::studies::sweep::{RunColumns, SweepDocument};

/// Anchor colours of the heatmaps' scale, least to most (a viridis-like ramp).
const RAMP: [[f64; 3]; 5] = [
    [68.0, 1.0, 84.0],
    [59.0, 82.0, 139.0],
    [33.0, 145.0, 140.0],
    [94.0, 201.0, 98.0],
    [253.0, 231.0, 37.0],
];

/// The colour of `t` ∈ [0, 1] on [`RAMP`].
pub fn ramp(t: f64) -> [u8; 3] {
    let x = t.clamp(0.0, 1.0) * (RAMP.len() - 1) as f64;
    let i = (x.floor() as usize).min(RAMP.len() - 2);
    let f = x - i as f64;
    let mix = |c: usize| (RAMP[i][c] + (RAMP[i + 1][c] - RAMP[i][c]) * f).round() as u8;
    [mix(0), mix(1), mix(2)]
}

/// One metric of one run: its entity name, its values (NaN for null) and whether its heatmap
/// is logarithmic.
fn metrics(run: &RunColumns) -> Vec<(String, Vec<f64>, bool)> {
    let column = |v: &[Option<f64>], magnitude: bool| -> Vec<f64> {
        v.iter()
            .map(|x| x.map_or(f64::NAN, |x| if magnitude { x.abs() } else { x }))
            .collect()
    };
    let mut out = vec![
        (
            "energy_error_final".to_string(),
            column(&run.energy_error_final, true),
            true,
        ),
        (
            "energy_error_max".to_string(),
            column(&run.energy_error_max, false),
            true,
        ),
        (
            "energy_error_l2".to_string(),
            column(&run.energy_error_l2, false),
            true,
        ),
        (
            "diverged_at".to_string(),
            column(&run.diverged_at, false),
            false,
        ),
    ];
    for (name, drift) in &run.invariant_drift {
        out.push((
            format!("drift_{}", super::entity_part(name)),
            column(drift, false),
            true,
        ));
    }
    if let Some(chaos) = &run.chaos {
        // SALI and GALI fall over many decades in chaos: logarithmic maps.
        for (name, values, log) in [
            ("lyapunov_max", &chaos.lyapunov_max, false),
            ("megno", &chaos.megno, false),
            ("megno_mean", &chaos.megno_mean, false),
            ("fli", &chaos.fli, false),
            ("sali", &chaos.sali, true),
            ("gali", &chaos.gali, true),
            ("stopped_at", &chaos.stopped_at, false),
        ] {
            if values.iter().any(Option::is_some) {
                out.push((name.to_string(), column(values, false), log));
            }
        }
    }
    out
}

/// The heatmap of `values` and its colour scale (the values at either end), or `None` where no
/// value can be drawn.
pub fn heatmap(values: &[f64], log: bool) -> (Vec<u8>, Option<(f64, f64)>) {
    let shown = |v: f64| -> Option<f64> {
        match log {
            true if v > 0.0 && v.is_finite() => Some(v.log10()),
            false if v.is_finite() => Some(v),
            _ => None,
        }
    };
    let finite: Vec<f64> = values.iter().filter_map(|&v| shown(v)).collect();
    let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let pixels = values
        .iter()
        .flat_map(|&v| match shown(v) {
            None => [0, 0, 0],
            Some(x) if hi > lo => ramp((x - lo) / (hi - lo)),
            Some(_) => ramp(0.5),
        })
        .collect();
    (pixels, (!finite.is_empty()).then_some((lo, hi)))
}

/// Logs the sweep.
pub fn log_sweep(
    rec: &RecordingStream,
    doc: &SweepDocument,
) -> Result<Vec<String>, RecordingError> {
    let n0 = doc.axes[0].n;
    let n1 = doc.axes.get(1).map_or(1, |a| a.n);
    let (shape, names): (Vec<u64>, Vec<String>) = match doc.axes.get(1) {
        Some(second) => (
            vec![n1 as u64, n0 as u64],
            vec![second.name.clone(), doc.axes[0].name.clone()],
        ),
        None => (vec![n0 as u64], vec![doc.axes[0].name.clone()]),
    };
    let labels: Vec<String> = doc
        .runs
        .iter()
        .map(|r| format!("{}_{}", r.method, r.chart))
        .collect();
    let mut scales = String::new();
    let mut entities = Vec::new();
    for (run, part) in doc.runs.iter().zip(entity_names(&labels)) {
        for (metric, values, log) in metrics(run) {
            let path = format!("/{part}/{metric}");
            let data = TensorData::new(shape.clone(), TensorBuffer::F64(values.clone().into()))
                .with_dim_names(names.clone());
            rec.log_static(path.clone(), &Tensor::new(data))?;
            let (pixels, scale) = heatmap(&values, log);
            rec.log_static(
                format!("{path}/heatmap"),
                &Image::from_rgb24(pixels, [n0 as u32, n1 as u32]),
            )?;
            let what = if log { "log₁₀ " } else { "" };
            scales.push_str(&match scale {
                Some((lo, hi)) => format!("- `{path}/heatmap`: {what}{metric} from {lo:.3} (dark blue) to {hi:.3} (yellow)\n"),
                None => format!("- `{path}/heatmap`: no finite value\n"),
            });
            entities.push(path);
        }
    }
    rec.log_static(
        "/summary",
        &TextDocument::from_markdown(summary(doc, &scales)),
    )?;
    Ok(entities)
}

fn summary(doc: &SweepDocument, scales: &str) -> String {
    let axes: Vec<String> = doc
        .axes
        .iter()
        .enumerate()
        .map(|(k, a)| {
            let along = if k == 0 { "columns" } else { "rows" };
            format!(
                "- {along}: `{}` from {} to {} in {} points ({:?})",
                a.name, a.min, a.max, a.n, a.scale
            )
        })
        .collect();
    format!(
        "**Sweep of {}**, energy errors against {:?}, {} cells, {} steps in {:.0} ms\n\n{}\n\n\
         Black: no value (the run diverged, or could not start).\n\n{scales}",
        doc.system,
        doc.energy_reference,
        doc.cells,
        doc.steps,
        doc.wall_ms,
        axes.join("\n"),
    )
}

/// The default layout: each run's largest energy error and divergence time as heatmaps, beside
/// the summary.
fn blueprint_tree(doc: &SweepDocument) -> BlueprintNode {
    let labels: Vec<String> = doc
        .runs
        .iter()
        .map(|r| format!("{}_{}", r.method, r.chart))
        .collect();
    let views = entity_names(&labels)
        .into_iter()
        .zip(&labels)
        .flat_map(|(part, label)| {
            ["energy_error_max", "diverged_at"].map(|metric| {
                BlueprintNode::view(
                    "2D",
                    format!("{label}: {metric}"),
                    vec![format!("/{part}/{metric}/heatmap")],
                )
            })
        })
        .collect();
    blueprint::grid_beside_summary(views)
}

/// Writes the `.rrd` file of a sweep to `writer`; returns the writer once the stream is
/// complete.
pub fn write_rrd<W: Write + Send + 'static>(
    writer: W,
    doc: &SweepDocument,
) -> Result<W, RecordingError> {
    let name = format!("sweep: {}", doc.system);
    encode::write(writer, name, |rec| {
        log_sweep(rec, doc)?;
        blueprint::send(rec, &blueprint_tree(doc))
    })
}

/// The `.rrd` file of a sweep in memory (see [`write_rrd`]).
pub fn rrd_bytes(doc: &SweepDocument) -> Result<Vec<u8>, RecordingError> {
    write_rrd(Vec::new(), doc)
}
