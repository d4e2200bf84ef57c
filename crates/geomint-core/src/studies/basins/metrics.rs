//! Numbers that say how finely a basin map's outcomes are interleaved, computed from its labels
//! alone (so a client can recompute them from the document).
//!
//! - Basin entropy S_b and boundary basin entropy S_bb (Daza, Wagemakers, Georgeot,
//!   Guéry-Odelin & Sanjuán, Sci. Rep. 6 (2016) 31416): the map is cut into boxes of
//!   [`BOX`] × [`BOX`] cells (a one-axis map into runs of [`BOX`] cells; cells past the last whole
//!   box are left out); box i has the Gibbs entropy S_i = Σ_j p_ij ln(1/p_ij) of the fractions
//!   p_ij of its cells with label j. S_b is the mean of S_i over all boxes, S_bb over the boxes
//!   with S_i > 0 (those on a boundary). With natural logarithms, S_bb > ln 2 shows the boundary
//!   is fractal (their "log 2 criterion").
//! - The uncertainty exponent α (Grebogi, McDonald, Ott & Yorke, Phys. Lett. A 99 (1983) 415):
//!   a cell is ε-uncertain when a cell ε away along an axis has another label; the fraction
//!   f(ε) ~ ε^α, fitted by least squares over ε = 1, 2, 4, … cells (the boundary's box-counting
//!   dimension is D − α for a map of D axes). α near 1 is a smooth boundary, near 0 a riddled
//!   one.
//!
//! - The Wada test by merging (after Daza, Wagemakers & Sanjuán, Sci. Rep. 8 (2018) 9954): a
//!   boundary is Wada when every point on it is on the boundary of every basin. For each label
//!   k the other basins are merged into one, and W_k is the share of the map's boundary cells (a
//!   cell with a differently labelled neighbour along an axis) that lie within one cell of the
//!   boundary of k against the merged rest. W_k = 1 for every k is a Wada boundary at the map's
//!   resolution; a basin that touches only some of the others has W_k well below 1. Given for
//!   maps with three or more labels.
//!
//! An undecided cell (label −1) counts as one more outcome in all of these. A cell that starts no orbit
//! (off the energy surface, outside the chart) is left out: so is every box holding one, and
//! every pair of cells ε apart that holds one.

use serde::{Deserialize, Serialize};

use crate::diagnostics::log_log_slope;

/// Cells per side of a box of the basin entropy.
pub const BOX: usize = 5;

/// The fraction of ε-uncertain cells at one ε.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Uncertain {
    /// ε, in cells.
    pub epsilon_cells: usize,
    /// The fraction of the cells with neighbours ε away inside the map that are ε-uncertain.
    pub fraction: f64,
}

/// The metrics of one map.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct BasinMetrics {
    /// S_b (natural logarithm); `None` when the map holds no whole box.
    pub basin_entropy: Option<f64>,
    /// S_bb; `None` when no box lies on a boundary.
    pub boundary_basin_entropy: Option<f64>,
    /// The boxes on a boundary, of all boxes.
    pub boundary_boxes: usize,
    /// Whole boxes whose every cell starts an orbit.
    pub boxes: usize,
    /// α; `None` when fewer than three ε have uncertain cells.
    pub uncertainty_exponent: Option<f64>,
    /// f(ε) at each ε the fit used.
    pub uncertain_fractions: Vec<Uncertain>,
    /// W_k of the Wada test by merging, per label (maps with three labels or more).
    pub wada: Vec<WadaShare>,
}

/// One label's share in the Wada test.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct WadaShare {
    /// The label k.
    pub label: i64,
    /// W_k: the share of the boundary cells within one cell of k's boundary against the rest.
    pub share: f64,
}

/// The metrics of `labels` on a grid of `shape` cells per axis (the first axis fastest), the
/// cells where `started` is false left out.
pub fn basin_metrics(labels: &[i64], started: &[bool], shape: &[usize]) -> BasinMetrics {
    let (nx, ny) = match shape {
        [nx] => (*nx, 1),
        [nx, ny] => (*nx, *ny),
        _ => (labels.len(), 1),
    };
    let label = |x: usize, y: usize| labels[x + nx * y];
    let counts_here = |x: usize, y: usize| started[x + nx * y];
    let (bx, by) = (BOX, if ny == 1 { 1 } else { BOX });
    let mut entropies = Vec::new();
    let mut counts: Vec<(i64, usize)> = Vec::new();
    for y0 in (0..ny / by).map(|k| k * by) {
        for x0 in (0..nx / bx).map(|k| k * bx) {
            counts.clear();
            if !(y0..y0 + by).all(|y| (x0..x0 + bx).all(|x| counts_here(x, y))) {
                continue;
            }
            for y in y0..y0 + by {
                for x in x0..x0 + bx {
                    let l = label(x, y);
                    match counts.iter_mut().find(|(k, _)| *k == l) {
                        Some((_, c)) => *c += 1,
                        None => counts.push((l, 1)),
                    }
                }
            }
            let total = (bx * by) as f64;
            let s: f64 = counts
                .iter()
                .map(|&(_, c)| {
                    let p = c as f64 / total;
                    -p * p.ln()
                })
                .sum();
            entropies.push(s);
        }
    }
    let boundary: Vec<f64> = entropies.iter().copied().filter(|&s| s > 0.0).collect();
    let mean = |v: &[f64]| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);

    let mut uncertain_fractions = Vec::new();
    let mut eps = 1;
    while 2 * eps < nx.max(ny) {
        let (mut cells, mut uncertain) = (0usize, 0usize);
        for y in 0..ny {
            for x in 0..nx {
                if !counts_here(x, y) {
                    continue;
                }
                let mut neighbours = Vec::with_capacity(4);
                if x >= eps && x + eps < nx {
                    neighbours.extend([(x - eps, y), (x + eps, y)]);
                }
                if ny > 1 && y >= eps && y + eps < ny {
                    neighbours.extend([(x, y - eps), (x, y + eps)]);
                }
                neighbours.retain(|&(x, y)| counts_here(x, y));
                if neighbours.is_empty() {
                    continue;
                }
                cells += 1;
                if neighbours.iter().any(|&(u, v)| label(u, v) != label(x, y)) {
                    uncertain += 1;
                }
            }
        }
        if cells > 0 && uncertain > 0 {
            uncertain_fractions.push(Uncertain {
                epsilon_cells: eps,
                fraction: uncertain as f64 / cells as f64,
            });
        }
        eps *= 2;
    }
    let uncertainty_exponent = (uncertain_fractions.len() >= 3).then(|| {
        let (e, f): (Vec<f64>, Vec<f64>) = uncertain_fractions
            .iter()
            .map(|u| (u.epsilon_cells as f64, u.fraction))
            .unzip();
        log_log_slope(&e, &f)
    });
    BasinMetrics {
        basin_entropy: mean(&entropies),
        boundary_basin_entropy: mean(&boundary),
        boundary_boxes: boundary.len(),
        boxes: entropies.len(),
        uncertainty_exponent,
        uncertain_fractions,
        wada: wada(labels, started, nx, ny),
    }
}

/// W_k for every label k ≥ 0, when the started cells carry three labels or more.
fn wada(labels: &[i64], started: &[bool], nx: usize, ny: usize) -> Vec<WadaShare> {
    let mut kinds: Vec<i64> = labels
        .iter()
        .zip(started)
        .filter(|(_, &s)| s)
        .map(|(&l, _)| l)
        .collect();
    kinds.sort_unstable();
    kinds.dedup();
    if kinds.len() < 3 {
        return Vec::new();
    }
    // The cells with a started neighbour along an axis of which `differ` says they differ.
    let boundary = |differ: &dyn Fn(i64, i64) -> bool| -> Vec<bool> {
        (0..nx * ny)
            .map(|c| {
                let (x, y) = (c % nx, c / nx);
                started[c]
                    && [(1, 0), (-1, 0), (0, 1), (0, -1)].iter().any(|&(dx, dy)| {
                        let (u, v) = (x as i64 + dx, y as i64 + dy);
                        (0..nx as i64).contains(&u)
                            && (0..ny as i64).contains(&v)
                            && started[u as usize + nx * v as usize]
                            && differ(labels[c], labels[u as usize + nx * v as usize])
                    })
            })
            .collect()
    };
    let whole = boundary(&|a, b| a != b);
    let on_whole = whole.iter().filter(|&&b| b).count().max(1);
    kinds
        .into_iter()
        .filter(|&k| k >= 0)
        .map(|k| {
            let merged = boundary(&|a, b| (a == k) != (b == k));
            let near = (0..nx * ny)
                .filter(|&c| whole[c])
                .filter(|&c| {
                    let (x, y) = (c % nx, c / nx);
                    (y.saturating_sub(1)..(y + 2).min(ny))
                        .any(|v| (x.saturating_sub(1)..(x + 2).min(nx)).any(|u| merged[u + nx * v]))
                })
                .count();
            WadaShare {
                label: k,
                share: near as f64 / on_whole as f64,
            }
        })
        .collect()
}
