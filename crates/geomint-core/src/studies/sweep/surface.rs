//! What a chaos map adds to a sweep: initial states on an energy surface (the momentum solved
//! per cell, see [`crate::simulation::surface`]), checked against the axes and the grid, and
//! runs that track indicators, which the lanes do not.

use super::axis::{Grid, Target};
use super::SweepJob;
use crate::error::CoreError;
use crate::simulation::EnergySurface;

/// The solved momentum may not also be an axis.
pub(super) fn check_axes(surface: &EnergySurface, grid: &Grid) -> Result<(), CoreError> {
    if !surface.energy.is_finite() {
        return Err(CoreError::NotFinite {
            field: surface.field.key("energy"),
        });
    }
    match grid
        .axes
        .iter()
        .find(|a| a.target == Target::P0(surface.momentum))
    {
        Some(axis) => Err(CoreError::Duplicate {
            field: surface.field.key("solve_for"),
            value: format!("{} (varied by {})", surface.solve_for(), axis.field),
        }),
        None => Ok(()),
    }
}

impl SweepJob {
    /// Whether the runs report chaos indicators.
    pub(super) fn tracks_chaos(&self) -> bool {
        self.chaos.is_some()
    }

    /// With an energy surface, some cell must have a state on it: the grid's middle cell is
    /// tried first (a section is usually centred on the motion), then all in order. Cells
    /// without one are those cells' results; a grid without any is an error of the request,
    /// with the least energy the grid reaches.
    pub(super) fn check_surface(&self) -> Result<(), CoreError> {
        let Some(surface) = &self.surface else {
            return Ok(());
        };
        let cells = self.grid.cells();
        let mut best: Option<(f64, usize)> = None;
        for cell in std::iter::once(cells / 2).chain(0..cells) {
            let mut spec = self.cell_spec(0, &self.grid.point(cell));
            match surface.apply(&mut spec, &self.info) {
                Ok(()) => return Ok(()),
                Err(CoreError::AboveEnergySurface { lowest, .. }) => {
                    if best.is_none_or(|(b, _)| lowest < b) {
                        best = Some((lowest, cell));
                    }
                }
                Err(e) => return Err(e),
            }
        }
        let (lowest, cell) = best.unwrap_or((f64::NAN, 0));
        Err(CoreError::NoEnergySolution {
            field: surface.field.key("energy"),
            energy: surface.energy,
            solve_for: surface.solve_for(),
            lowest,
            cell,
        })
    }
}
