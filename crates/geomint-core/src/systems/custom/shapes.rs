//! The matrices and lists of a definition (mass, damping matrix, positions): their shapes
//! checked against the dimension, their entries parsed into graph nodes.

use super::{Expression, Mass, MAX_NAMES};
use crate::error::CoreError;
use crate::error::Field;
use crate::expr::NodeId;

/// Checks that `rows` is an n×n matrix; errors name `field` (and a row's index).
pub(super) fn check_square(
    rows: &[Vec<Expression>],
    n: usize,
    field: &Field,
) -> Result<(), CoreError> {
    if rows.len() != n {
        return Err(CoreError::WrongLength {
            field: field.clone(),
            expected: n,
            got: rows.len(),
        });
    }
    for (i, row) in rows.iter().enumerate() {
        if row.len() != n {
            return Err(CoreError::WrongLength {
                field: field.index(i),
                expected: n,
                got: row.len(),
            });
        }
    }
    Ok(())
}

/// The mass matrix's nodes, row-major n×n.
pub(super) fn mass_nodes(
    mass: &Mass,
    n: usize,
    field: &Field,
    parse: &mut dyn FnMut(&Expression) -> Result<NodeId, CoreError>,
) -> Result<Vec<NodeId>, CoreError> {
    let diagonal = |entries: Vec<NodeId>, zero: NodeId| -> Vec<NodeId> {
        (0..n * n)
            .map(|k| if k / n == k % n { entries[k / n] } else { zero })
            .collect()
    };
    let zero = |parse: &mut dyn FnMut(&Expression) -> Result<NodeId, CoreError>| {
        parse(&Expression {
            text: "0".into(),
            field: field.clone(),
        })
    };
    Ok(match mass {
        Mass::Scalar(m) => {
            let m = parse(m)?;
            diagonal(vec![m; n], zero(parse)?)
        }
        Mass::Diagonal(entries) => {
            if entries.len() != n {
                return Err(CoreError::WrongLength {
                    field: field.clone(),
                    expected: n,
                    got: entries.len(),
                });
            }
            let nodes = entries
                .iter()
                .map(&mut *parse)
                .collect::<Result<Vec<_>, _>>()?;
            diagonal(nodes, zero(parse)?)
        }
        Mass::Matrix(rows) => {
            check_square(rows, n, field)?;
            let nodes = rows
                .iter()
                .flatten()
                .map(&mut *parse)
                .collect::<Result<Vec<_>, _>>()?;
            for i in 0..n {
                for j in 0..i {
                    if nodes[i * n + j] != nodes[j * n + i] {
                        return Err(CoreError::NotSymmetric {
                            field: field.index(i).index(j),
                            other: field.index(j).index(i),
                            at: Vec::new(),
                        });
                    }
                }
            }
            nodes
        }
    })
}

/// The positions' nodes: every body with the same number (2 or 3) of coordinates.
pub(super) fn position_nodes(
    bodies: &[Vec<Expression>],
    field: &Field,
    parse: &mut dyn FnMut(&Expression) -> Result<NodeId, CoreError>,
) -> Result<(usize, Vec<NodeId>), CoreError> {
    if bodies.is_empty() || bodies.len() > MAX_NAMES {
        return Err(CoreError::Count {
            field: field.clone(),
            got: bodies.len() as u64,
            min: 1,
            max: MAX_NAMES as u64,
            what: "bodies",
        });
    }
    let dims = bodies[0].len();
    let mut nodes = Vec::new();
    for (i, body) in bodies.iter().enumerate() {
        if !(2..=3).contains(&body.len()) || body.len() != dims {
            return Err(CoreError::Count {
                field: field.index(i),
                got: body.len() as u64,
                min: dims.clamp(2, 3) as u64,
                max: if (2..=3).contains(&dims) { dims } else { 3 } as u64,
                what: "coordinates (every body 2-D, or every body 3-D)",
            });
        }
        for e in body {
            nodes.push(parse(e)?);
        }
    }
    Ok((dims, nodes))
}
