//! The recording of an energy-error map (paper 001 Fig. 6): the map as an image, the two charts'
//! errors as tensors, the divergences as a segmentation image, and Sec. 4.1's boundary drawn
//! over them.
//!
//! Entity layout (all static; a map has no time):
//!
//! | entity | archetype | content |
//! |---|---|---|
//! | `/` | `AnnotationContext`: the divergence classes, see [`Class`] | — |
//! | `/map/difference` | `Image` (RGB, ny rows × nx columns): log₁₀(ε(x,y)/ε(r,θ)) clamped to ±[`RATIO_RANGE`], blue where Cartesian coordinates are more accurate, red where polar ones are, black where a run diverged | one |
//! | `/map/divergence` | `SegmentationImage` of [`Class`] ids | one |
//! | `/map/boundary` | `LineStrips2D`: r = 2l + 2mg/k·cos θ in the images' pixel coordinates | one |
//! | `/epsilon/cartesian`, `/epsilon/polar` | `Tensor` of f64 log₁₀ ε, dims `y0`, `x0`; NaN where it diverged | one |
//! | `/summary` | `TextDocument`: parameters and counts | one |
//!
//! Row j of every grid is y₀ = ys[j] and column i is x₀ = xs[i], as in the JSON answer; pixel
//! (i, j) covers [i, i + 1] × [j, j + 1], so y (pointing down, along gravity) grows downwards in
//! the viewer as in the physical picture.

use std::io::Write;

use rerun::external::re_sdk_types::blueprint::components::ContainerKind;
use rerun::external::re_sdk_types::datatypes::{ChannelDatatype, TensorBuffer, TensorData};
use rerun::{
    AnnotationContext, Image, ImageFormat, LineStrips2D, RecordingStream, Rgba32,
    SegmentationImage, Tensor, TextDocument,
};

use super::blueprint::{self, BlueprintNode};
use super::{encode, RecordingError};
use crate::core::studies::energy_map::EnergyMapDocument;

/// The colour scale of `/map/difference` spans log₁₀(ε(x,y)/ε(r,θ)) ∈ [−RATIO_RANGE, RATIO_RANGE].
pub const RATIO_RANGE: f64 = 2.0;

/// The class of a cell in `/map/divergence` (0 is background and unused).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Class {
    /// Both runs finished.
    Finite = 1,
    /// The polar run diverged, where Sec. 4.1 predicts it.
    PolarDivergedPredicted = 2,
    /// The polar run diverged outside the predicted region.
    PolarDivergedUnpredicted = 3,
    /// Predicted to diverge, but the polar run finished.
    PredictedFinite = 4,
    /// The Cartesian run diverged, or the polar chart does not exist (the pivot).
    Singular = 5,
}

impl Class {
    /// Every class, in id order.
    pub const ALL: [Class; 5] = [
        Class::Finite,
        Class::PolarDivergedPredicted,
        Class::PolarDivergedUnpredicted,
        Class::PredictedFinite,
        Class::Singular,
    ];

    /// The class of cell k of a map.
    pub fn of(doc: &EnergyMapDocument, k: usize) -> Class {
        let singular = doc.cartesian_diverged_at[k].is_some()
            || (doc.epsilon_polar[k].is_none() && doc.polar_diverged_at[k].is_none());
        match (
            singular,
            doc.polar_diverged_at[k].is_some(),
            doc.predicted_divergent[k],
        ) {
            (true, _, _) => Class::Singular,
            (false, true, true) => Class::PolarDivergedPredicted,
            (false, true, false) => Class::PolarDivergedUnpredicted,
            (false, false, true) => Class::PredictedFinite,
            (false, false, false) => Class::Finite,
        }
    }

    fn label(self) -> &'static str {
        match self {
            Class::Finite => "finite in both charts",
            Class::PolarDivergedPredicted => "polar run diverged (predicted)",
            Class::PolarDivergedUnpredicted => "polar run diverged outside the predicted region",
            Class::PredictedFinite => "predicted to diverge, polar run finite",
            Class::Singular => "pivot / Cartesian run diverged",
        }
    }

    fn color(self) -> Rgba32 {
        match self {
            Class::Finite => Rgba32::from_rgb(220, 220, 220),
            Class::PolarDivergedPredicted => Rgba32::from_rgb(40, 40, 40),
            Class::PolarDivergedUnpredicted => Rgba32::from_rgb(255, 127, 14),
            Class::PredictedFinite => Rgba32::from_rgb(148, 103, 189),
            Class::Singular => Rgba32::from_rgb(214, 39, 40),
        }
    }
}

/// The RGB colour of a difference cell: white at equal errors, saturating to blue (Cartesian
/// better) or red (polar better) at a factor 10^RATIO_RANGE; black where either run diverged.
pub fn difference_color(cartesian: Option<f64>, polar: Option<f64>) -> [u8; 3] {
    let (Some(c), Some(p)) = (cartesian, polar) else {
        return [0, 0, 0];
    };
    let ratio = if c > 0.0 && p > 0.0 {
        ((c / p).log10() / RATIO_RANGE).clamp(-1.0, 1.0)
    } else {
        0.0
    };
    let fade = (255.0 * (1.0 - ratio.abs())).round() as u8;
    if ratio < 0.0 {
        [fade, fade, 255]
    } else {
        [255, fade, fade]
    }
}

/// Logs the map.
pub fn log_map(rec: &RecordingStream, doc: &EnergyMapDocument) -> Result<(), RecordingError> {
    let (nx, ny) = (doc.xs.len(), doc.ys.len());
    rec.log_static(
        "/",
        &AnnotationContext::new(Class::ALL.map(|c| (c as u16, c.label(), c.color()))),
    )?;
    let pixels: Vec<u8> = (0..nx * ny)
        .flat_map(|k| difference_color(doc.epsilon_cartesian[k], doc.epsilon_polar[k]))
        .collect();
    rec.log_static(
        "/map/difference",
        &Image::from_rgb24(pixels, [nx as u32, ny as u32]),
    )?;
    let classes: Vec<u8> = (0..nx * ny).map(|k| Class::of(doc, k) as u8).collect();
    rec.log_static(
        "/map/divergence",
        &SegmentationImage::new(
            classes,
            ImageFormat::segmentation([nx as u32, ny as u32], ChannelDatatype::U8),
        ),
    )?;
    rec.log_static(
        "/map/boundary",
        &LineStrips2D::new([boundary_pixels(doc)])
            .with_colors([Rgba32::from_rgb(255, 255, 255)])
            .with_radii([0.15]),
    )?;
    for (chart, eps) in [
        ("cartesian", &doc.epsilon_cartesian),
        ("polar", &doc.epsilon_polar),
    ] {
        let values: Vec<f64> = eps.iter().map(|e| e.map_or(f64::NAN, f64::log10)).collect();
        let data = TensorData::new(vec![ny as u64, nx as u64], TensorBuffer::F64(values.into()))
            .with_dim_names(["y0", "x0"]);
        rec.log_static(format!("/epsilon/{chart}"), &Tensor::new(data))?;
    }
    rec.log_static("/summary", &TextDocument::from_markdown(summary(doc)))?;
    Ok(())
}

/// The boundary curve in pixel coordinates (cell centres at i + ½, j + ½).
fn boundary_pixels(doc: &EnergyMapDocument) -> Vec<[f32; 2]> {
    let axis = |values: &[f64], v: f64| -> f32 {
        let n = values.len();
        if n < 2 || values[n - 1] == values[0] {
            return 0.5;
        }
        let step = (values[n - 1] - values[0]) / (n - 1) as f64;
        ((v - values[0]) / step + 0.5) as f32
    };
    doc.boundary
        .iter()
        .map(|&[x, y]| [axis(&doc.xs, x), axis(&doc.ys, y)])
        .collect()
}

fn summary(doc: &EnergyMapDocument) -> String {
    let s = &doc.summary;
    format!(
        "**{}** on the planar elastic pendulum, m = {}, k = {}, l = {}, g = {}; h = {}, t_max = {} \
         ({} steps per run), {} × {} cells in x₀ ∈ [{}, {}], y₀ ∈ [{}, {}], p₀ = 0\n\n\
         - Cartesian more accurate (ε(x,y) < ε(r,θ)): {} cells\n\
         - polar more accurate: {} cells\n\
         - polar runs diverged: {} ({} outside the predicted region r₀ ≥ 2l + 2mg/k·cos θ₀, \
         which holds {} cells)\n\
         - Cartesian runs diverged: {}\n\
         - {} steps in {:.0} ms\n",
        doc.method,
        doc.params.m,
        doc.params.k,
        doc.params.l,
        doc.params.g,
        doc.h,
        doc.t_max,
        doc.steps_per_run,
        doc.xs.len(),
        doc.ys.len(),
        doc.xs[0],
        doc.xs[doc.xs.len() - 1],
        doc.ys[0],
        doc.ys[doc.ys.len() - 1],
        s.cartesian_better,
        s.polar_better,
        s.polar_diverged,
        s.diverged_outside_prediction,
        s.predicted_divergent,
        s.cartesian_diverged,
        doc.steps,
        doc.wall_ms,
    )
}

/// The default layout: the difference image and the divergence classes, each with the boundary,
/// above the two error tensors, beside the summary.
fn blueprint_tree() -> BlueprintNode {
    let with_boundary = |entity: &str| vec![entity.to_string(), "/map/boundary".to_string()];
    BlueprintNode::container(
        ContainerKind::Horizontal,
        vec![
            BlueprintNode::container(
                ContainerKind::Vertical,
                vec![
                    BlueprintNode::container(
                        ContainerKind::Horizontal,
                        vec![
                            BlueprintNode::view(
                                "2D",
                                "ε(x,y) vs ε(r,θ): blue Cartesian better, red polar",
                                with_boundary("/map/difference"),
                            ),
                            BlueprintNode::view(
                                "2D",
                                "divergence",
                                with_boundary("/map/divergence"),
                            ),
                        ],
                    ),
                    BlueprintNode::container(
                        ContainerKind::Horizontal,
                        vec![
                            BlueprintNode::view(
                                "Tensor",
                                "log10 ε, Cartesian",
                                vec!["/epsilon/cartesian".to_string()],
                            ),
                            BlueprintNode::view(
                                "Tensor",
                                "log10 ε, polar",
                                vec!["/epsilon/polar".to_string()],
                            ),
                        ],
                    ),
                ],
            ),
            BlueprintNode::view("TextDocument", "summary", vec!["/summary".to_string()]),
        ],
    )
}

/// Writes the `.rrd` file of a map to `writer`; returns the writer once the stream is complete.
pub fn write_rrd<W: Write + Send + 'static>(
    writer: W,
    doc: &EnergyMapDocument,
) -> Result<W, RecordingError> {
    let name = format!("energy map: {}", doc.method);
    encode::write(writer, name, |rec| {
        log_map(rec, doc)?;
        blueprint::send(rec, &blueprint_tree())
    })
}

/// The `.rrd` file of a map in memory (see [`write_rrd`]).
pub fn rrd_bytes(doc: &EnergyMapDocument) -> Result<Vec<u8>, RecordingError> {
    write_rrd(Vec::new(), doc)
}
