//! The checks of a definition that need numbers or a look ahead: the damping matrix D(q)
//! symmetric and positive semidefinite at deterministic sample points, its form (a projector at
//! one rate, or general), and whether the energy or damping uses the time `t`.

use super::{CustomDefinition, CustomModel, Damping, Energy, Expression};
use crate::error::CoreError;
use crate::expr::{NameScope, NodeId, Var};
use crate::systems::custom::damping::MassFactor;
use crate::systems::custom::system::DampingModel;

/// Deterministic sample points of the configuration space: SplitMix64 in [−1.5, 1.5]ⁿ.
pub(super) fn sample_points(n: usize, count: usize) -> Vec<Vec<f64>> {
    let mut state = 0x5eed_u64;
    let mut next = move || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        let unit = ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64;
        -1.5 + 3.0 * unit
    };
    (0..count)
        .map(|_| (0..n).map(|_| next()).collect())
        .collect()
}

/// The largest |a_ij − b_ij| relative to the larger entries.
fn relative_gap(a: &[f64], b: &[f64]) -> f64 {
    let scale = a
        .iter()
        .chain(b)
        .fold(0.0f64, |m, x| m.max(x.abs()))
        .max(1e-300);
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

/// Whether the symmetric `m` (row-major n×n) is positive semidefinite, to round-off.
pub(super) fn positive_semidefinite(m: &[f64], n: usize) -> bool {
    let scale = m.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    // M + δI positive definite for a δ at round-off of the entries.
    let shifted: Vec<f64> = (0..n * n)
        .map(|k| {
            m[k] + if k / n == k % n {
                1e-10 * scale + 1e-300
            } else {
                0.0
            }
        })
        .collect();
    MassFactor::new(&shifted, n).is_some()
}

impl CustomModel {
    /// Checks that D(q) is symmetric and positive semidefinite at the sample points.
    pub(super) fn check_damping_matrix(
        &self,
        matrix: &[NodeId],
        slots: &[f64],
    ) -> Result<(), CoreError> {
        let n = self.n;
        let field = self.definition.field.key("damping").key("matrix");
        let mut values = slots.to_vec();
        for point in sample_points(n, 16) {
            values[..n].copy_from_slice(&point);
            let d = self.graph.eval(matrix, &values);
            if d.iter().any(|x| !x.is_finite()) {
                continue;
            }
            let scale = d.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(1e-300);
            for i in 0..n {
                for j in 0..i {
                    if matrix[i * n + j] != matrix[j * n + i]
                        && (d[i * n + j] - d[j * n + i]).abs() > 1e-12 * scale
                    {
                        return Err(CoreError::NotSymmetric {
                            field: field.index(i).index(j),
                            other: field.index(j).index(i),
                            at: point.clone(),
                        });
                    }
                }
            }
            if !positive_semidefinite(&d, n) {
                return Err(CoreError::NotDefinite {
                    field,
                    what: "the damping matrix D(q)",
                    property: "positive semidefinite",
                    detail: format!("at q = {point:?} it is {d:?}"),
                });
            }
        }
        Ok(())
    }

    /// The damping's model: a rate times a projector when M = mI and D(q) is idempotent at the
    /// sample points (the closed-form flows of every built-in system apply), else general.
    pub(super) fn damping_model(
        &self,
        epsilon: f64,
        matrix: &[NodeId],
        m: &[f64],
        factor: &MassFactor,
        slots: &[f64],
    ) -> DampingModel {
        let n = self.n;
        let isotropic = (0..n * n).all(|k| {
            let (i, j) = (k / n, k % n);
            if i == j {
                m[k] == m[0]
            } else {
                m[k] == 0.0
            }
        });
        let mut values = slots.to_vec();
        let idempotent = sample_points(n, 16).into_iter().all(|point| {
            values[..n].copy_from_slice(&point);
            let d = self.graph.eval(matrix, &values);
            let d2: Vec<f64> = (0..n * n)
                .map(|k| (0..n).map(|l| d[(k / n) * n + l] * d[l * n + k % n]).sum())
                .collect();
            d.iter().any(|x| !x.is_finite()) || relative_gap(&d, &d2) <= 1e-12
        });
        if isotropic && idempotent {
            DampingModel::Projector {
                rate: epsilon / m[0],
            }
        } else {
            DampingModel::General {
                epsilon,
                factor: factor.clone(),
            }
        }
    }
}

/// Whether the definition's energy or damping matrix uses the variable `t` of `scope` (read
/// before the graph is built, so that the derivatives can be taken in the right variables;
/// expressions that do not parse are left for the parse that reports them).
pub(super) fn uses(definition: &CustomDefinition, scope: &NameScope, t: Var) -> bool {
    let mut texts: Vec<&Expression> = match &definition.energy {
        Energy::Separable { potential, .. } => vec![potential],
        Energy::General { hamiltonian } => vec![hamiltonian],
    };
    if let Some(Damping::Rayleigh { matrix, .. }) = &definition.damping {
        texts.extend(matrix.iter().flatten());
    }
    texts.into_iter().any(|e| {
        crate::expr::parse(&e.text, scope).is_ok_and(|parsed| {
            parsed
                .nodes()
                .iter()
                .any(|node| matches!(node, crate::expr::AstNode::Var(v) if *v == t))
        })
    })
}
