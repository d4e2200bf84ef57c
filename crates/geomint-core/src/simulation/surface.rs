//! Starting on an energy surface: one momentum of the initial state solved from H = E, the rest of
//! the state given — how a chaos map samples a Poincaré section (the Hénon–Heiles (y, p_y) plane
//! at x = 0, E = 1/8, with p_x from the energy).
//!
//! The state must be given in coordinates where H = ½ pᵀM⁻¹p + V(q) with a constant M (a
//! system's Cartesian chart, or a separable definition). H is then a quadratic in the solved
//! momentum p_i: a p_i² + b p_i + c with a = ½(M⁻¹)_ii, b = Σ_{j≠i}(M⁻¹)_ij p_j and
//! c = ½ Σ_{j,l≠i} p_j (M⁻¹)_jl p_l + V(q) − E. The larger root p_i = (−b + √(b² − 4ac))/(2a) is
//! taken — for a diagonal mass the non-negative one, p_i = √(2 m_i (E − V − T_rest)), as on the
//! usual section (p_x ≥ 0). Where b² < 4ac no state has H = E (the rest of the state alone has
//! more energy) and the cell is marked as such.

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

use super::spec::SimulationSpec;
use crate::error::{CoreError, Field};
use crate::system::{MechanicalSystem, State};
use crate::systems::{self, SystemInfo};
use crate::with_system;

/// The initial momentum `momentum` solved from H = `energy`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EnergySurface {
    /// E.
    pub energy: f64,
    /// The index i of the momentum p_i that is solved for.
    pub momentum: usize,
    /// Where the request gave it (`energy_surface`).
    pub field: Field,
}

/// Why a state has no momentum on the surface: the least H over the solved momentum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AboveSurface {
    /// min over p_i of H, which exceeds E.
    pub lowest: f64,
}

impl EnergySurface {
    /// The name of the solved momentum, `p0[i]`.
    pub fn solve_for(&self) -> String {
        format!("p0[{}]", self.momentum)
    }

    /// Solves the momentum in `p` for the state (q, p) of `sys`.
    pub fn solve<S: MechanicalSystem>(
        &self,
        sys: &S,
        z: &mut State<S::Dim>,
    ) -> Result<(), AboveSurface>
    where
        DefaultAllocator: Allocator<S::Dim>,
    {
        let i = self.momentum;
        let n = z.q.len();
        // Column i of M⁻¹, and the rest of the kinetic energy with p_i = 0.
        let mut unit = z.p.clone();
        unit.fill(0.0);
        unit[i] = 1.0;
        let mut column = z.p.clone();
        sys.velocity(&z.q, &unit, &mut column);
        z.p[i] = 0.0;
        let rest = sys.kinetic(&z.q, &z.p);
        let a = 0.5 * column[i];
        let b: f64 = (0..n).filter(|&j| j != i).map(|j| column[j] * z.p[j]).sum();
        let c = rest + sys.potential(&z.q) - self.energy;
        let discriminant = b * b - 4.0 * a * c;
        if !(discriminant >= 0.0) || !(a > 0.0) {
            return Err(AboveSurface {
                lowest: self.energy + c - b * b / (4.0 * a),
            });
        }
        z.p[i] = (-b + discriminant.sqrt()) / (2.0 * a);
        Ok(())
    }

    /// Fills in the solved momentum of `spec`'s initial state (its other components given, or the
    /// system's defaults). The state's coordinates are the Cartesian ones when the spec gives it
    /// so (or uses the default chart), else the chart's, which must be separable. A state with
    /// no momentum on the surface is an error that says by how much it misses.
    pub fn apply(&self, spec: &mut SimulationSpec, info: &SystemInfo) -> Result<(), CoreError> {
        let f = &spec.fields;
        let default_chart =
            spec.chart.is_none() || spec.chart.as_deref() == Some(info.charts[0].id);
        let chart = if default_chart || spec.initial_cartesian {
            info.charts[0]
        } else {
            *info.chart(spec.chart.as_deref(), &f.chart)?
        };
        if !chart.separable {
            return Err(CoreError::Unsupported {
                field: self.field.clone(),
                reason: "the energy surface is solved where H = ½pᵀM⁻¹p + V(q): give the \
                         initial state in Cartesian coordinates (`initial_coordinates`)",
            });
        }
        let params = systems::params::resolve(info, &spec.params, &f.params)?;
        let system = info.build(&params, &chart, spec.h)?;
        let q = spec.q0.clone().unwrap_or_else(|| info.q0.clone());
        let mut p = spec.p0.clone().unwrap_or_else(|| info.p0.clone());
        let n = system.dimension();
        if q.len() != n || p.len() != n || self.momentum >= n {
            // The simulation's own checks name the vector at fault.
            if self.momentum >= n {
                return Err(CoreError::WrongLength {
                    field: self.field.key("solve_for"),
                    expected: n,
                    got: self.momentum + 1,
                });
            }
            return Ok(());
        }
        let solved = with_system!(&system, s => {
            let mut z = State::from_slices(s.dim(), &q, &p);
            self.solve(s, &mut z).map(|()| z.p[self.momentum])
        });
        match solved {
            Ok(value) => {
                p[self.momentum] = value;
                spec.p0 = Some(p);
                Ok(())
            }
            Err(AboveSurface { lowest }) => Err(CoreError::AboveEnergySurface {
                field: self.field.key("energy"),
                energy: self.energy,
                solve_for: self.solve_for(),
                lowest,
            }),
        }
    }
}
