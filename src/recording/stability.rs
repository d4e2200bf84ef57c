//! The recording of a stability study: each method's map over the (γ, h) grid as a tensor of
//! spectral radii and as an image of verdicts, the analytic relation's disagreements marked.
//!
//! Entity layout (`{m}` is a method's entity name, see [`entity_names`]); everything is static,
//! since a study has no time:
//!
//! | entity | archetype | content |
//! |---|---|---|
//! | `/` | `AnnotationContext`: the verdict classes, see [`Verdict`] | — |
//! | `/spec` | `TextDocument`: the request as JSON | — |
//! | `/{m}/spectral_radius` | `Tensor` of f64, shape [h.n, gamma.n], dimensions named `h` and `gamma`; NaN where the radius is not finite (JSON's `null`) | one |
//! | `/{m}/verdict` | `SegmentationImage`, h.n rows × gamma.n columns of [`Verdict`] class ids | one |
//! | `/{m}/summary` | `TextDocument`: axes, stable cells and disagreement counts | one |
//!
//! Row k of both grids is the k-th h value and column j the j-th γ value, as in the JSON answer,
//! so the viewer draws h growing downwards. The blueprint puts the tensors (colour-mapped, value
//! range [0, 2] so that 1 is mid-scale) beside the verdict images, one pair per method.

use std::io::Write;

use rerun::external::re_sdk_types::blueprint::components::ContainerKind;
use rerun::external::re_sdk_types::datatypes::{ChannelDatatype, TensorBuffer, TensorData};
use rerun::{
    AnnotationContext, ImageFormat, RecordingStream, Rgba32, SegmentationImage, Tensor,
    TextDocument,
};

use super::blueprint::{self, BlueprintNode};
use super::Spec;
use super::{encode, entity_names, RecordingError};
use crate::core::studies::stability::{MapDocument, StabilityDocument};

/// The class of a cell in a `verdict` image. Class 0 is left unused: segmentation images draw
/// it as background.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Verdict {
    /// Spectral radius ≤ 1 (+1e-12), and the analytic relation (if any) agrees.
    Stable = 1,
    /// Spectral radius > 1 or not finite, and the analytic relation (if any) agrees.
    Unstable = 2,
    /// Stable, but the corrected analytic relation says unstable.
    StableAnalyticUnstable = 3,
    /// Unstable, but the corrected analytic relation says stable.
    UnstableAnalyticStable = 4,
}

impl Verdict {
    /// Every class, in id order.
    pub const ALL: [Verdict; 4] = [
        Verdict::Stable,
        Verdict::Unstable,
        Verdict::StableAnalyticUnstable,
        Verdict::UnstableAnalyticStable,
    ];

    /// The verdict of a cell: the numerical one, and the analytic relation's where there is one.
    pub fn of(stable: bool, analytic: Option<bool>) -> Verdict {
        match (stable, analytic) {
            (true, None | Some(true)) => Verdict::Stable,
            (false, None | Some(false)) => Verdict::Unstable,
            (true, Some(false)) => Verdict::StableAnalyticUnstable,
            (false, Some(true)) => Verdict::UnstableAnalyticStable,
        }
    }

    /// The label shown in the viewer.
    pub fn label(self) -> &'static str {
        match self {
            Verdict::Stable => "stable",
            Verdict::Unstable => "unstable",
            Verdict::StableAnalyticUnstable => "stable; analytic relation: unstable",
            Verdict::UnstableAnalyticStable => "unstable; analytic relation: stable",
        }
    }

    fn color(self) -> Rgba32 {
        match self {
            Verdict::Stable => Rgba32::from_rgb(44, 160, 44),
            Verdict::Unstable => Rgba32::from_rgb(214, 39, 40),
            Verdict::StableAnalyticUnstable => Rgba32::from_rgb(255, 220, 0),
            Verdict::UnstableAnalyticStable => Rgba32::from_rgb(148, 0, 211),
        }
    }
}

/// The verdict classes of a map, row-major (one row per h value).
pub fn verdicts(map: &MapDocument) -> Vec<u8> {
    let analytic = map.analytic.as_ref();
    map.stable
        .iter()
        .enumerate()
        .flat_map(|(k, row)| {
            row.iter()
                .enumerate()
                .map(move |(j, &stable)| Verdict::of(stable, analytic.map(|a| a[k][j])) as u8)
        })
        .collect()
}

/// Logs a study: the classes, the spec, and per method the tensor, the verdict image and the
/// summary.
pub fn log_study(
    rec: &RecordingStream,
    spec: &Spec,
    doc: &StabilityDocument,
) -> Result<(), RecordingError> {
    rec.log_static(
        "/",
        &AnnotationContext::new(Verdict::ALL.map(|v| (v as u16, v.label(), v.color()))),
    )?;
    let spec_json = spec.json();
    rec.log_static(
        "/spec",
        &TextDocument::from_markdown(format!("```json\n{spec_json}\n```")),
    )?;
    let labels: Vec<&str> = doc.maps.iter().map(|m| m.method.as_str()).collect();
    let (rows, cols) = (doc.h.n, doc.gamma.n);
    for (map, m) in doc.maps.iter().zip(entity_names(&labels)) {
        let radii: Vec<f64> = map
            .spectral_radius
            .iter()
            .flatten()
            .map(|r| r.unwrap_or(f64::NAN))
            .collect();
        let data = TensorData::new(
            vec![rows as u64, cols as u64],
            TensorBuffer::F64(radii.into()),
        )
        .with_dim_names(["h", "gamma"]);
        rec.log_static(
            format!("/{m}/spectral_radius"),
            &Tensor::new(data).with_value_range([0.0, 2.0]),
        )?;
        rec.log_static(
            format!("/{m}/verdict"),
            &SegmentationImage::new(
                verdicts(map),
                ImageFormat::segmentation([cols as u32, rows as u32], ChannelDatatype::U8),
            ),
        )?;
        rec.log_static(
            format!("/{m}/summary"),
            &TextDocument::from_markdown(summary(doc, map)),
        )?;
    }
    Ok(())
}

/// A method's map in words: the grid, the stable cells and the disagreements.
fn summary(doc: &StabilityDocument, map: &MapDocument) -> String {
    let cells = doc.gamma.n * doc.h.n;
    let stable = map.stable.iter().flatten().filter(|&&s| s).count();
    let mut text = format!(
        "**{}** at ω = {}\n\n- γ: {} values in [{}, {}] (columns)\n- h: {} values in [{}, {}] (rows)\n\
         - stable cells: {stable} of {cells}\n",
        map.method,
        doc.omega,
        doc.gamma.n,
        doc.gamma.min,
        doc.gamma.max,
        doc.h.n,
        doc.h.min,
        doc.h.max
    );
    if let Some(n) = map.disagreements {
        text.push_str(&format!(
            "- cells where the corrected analytic relation disagrees, off the boundary: {n}\n"
        ));
    }
    if let Some(n) = map.printed_disagreements {
        text.push_str(&format!(
            "- cells where the relation as printed disagrees, off the boundary: {n}\n"
        ));
    }
    text
}

/// The default layout: one row per method with its spectral-radius tensor and its verdict
/// image, beside the spec.
fn blueprint_tree(doc: &StabilityDocument) -> BlueprintNode {
    let labels: Vec<&str> = doc.maps.iter().map(|m| m.method.as_str()).collect();
    let rows = doc
        .maps
        .iter()
        .zip(entity_names(&labels))
        .map(|(map, m)| {
            BlueprintNode::container(
                ContainerKind::Horizontal,
                vec![
                    BlueprintNode::view(
                        "Tensor",
                        format!("{}: spectral radius", map.method),
                        vec![format!("/{m}/spectral_radius")],
                    ),
                    BlueprintNode::view(
                        "2D",
                        format!("{}: verdict", map.method),
                        vec![format!("/{m}/verdict")],
                    ),
                    BlueprintNode::view(
                        "TextDocument",
                        format!("{}: summary", map.method),
                        vec![format!("/{m}/summary")],
                    ),
                ],
            )
        })
        .collect();
    BlueprintNode::container(
        ContainerKind::Horizontal,
        vec![
            BlueprintNode::container(ContainerKind::Vertical, rows),
            BlueprintNode::view("TextDocument", "spec", vec!["/spec".to_string()]),
        ],
    )
}

/// Writes the `.rrd` file of a stability study to `writer`: the maps of `doc` (computed from
/// `spec`) and the default blueprint. Returns the writer once the stream is complete.
pub fn write_rrd<W: Write + Send + 'static>(
    writer: W,
    spec: &Spec,
    doc: &StabilityDocument,
) -> Result<W, RecordingError> {
    let labels: Vec<&str> = doc.maps.iter().map(|m| m.method.as_str()).collect();
    let name = format!("stability at ω = {}: {}", doc.omega, labels.join(", "));
    encode::write(writer, name, |rec| {
        log_study(rec, spec, doc)?;
        blueprint::send(rec, &blueprint_tree(doc))
    })
}

/// The `.rrd` file of a stability study in memory (see [`write_rrd`]).
pub fn rrd_bytes(spec: &Spec, doc: &StabilityDocument) -> Result<Vec<u8>, RecordingError> {
    write_rrd(Vec::new(), spec, doc)
}
