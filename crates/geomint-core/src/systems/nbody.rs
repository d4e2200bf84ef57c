//! N point masses in R³ with a pairwise radial potential and linear (conformal) damping
//! p' = −∇V − 2γp: Newtonian gravity with optional Plummer softening, or Lennard-Jones.
//!
//! The total angular momentum L = Σ qᵢ × pᵢ obeys L' = −2γ L (the pair forces are central), so
//! e^{2γt} L is conserved; paper 003 Theorems 2.1.2, 2.2.2 and 2.2.4 show cimp, csv1 and csv2
//! reproduce this decay exactly.

use nalgebra::Dyn;

use std::borrow::Cow;

use super::{AnySystem, Builder, ChartInfo, ParamKind, ParamSpec, ParamValues, SystemInfo, World};
use crate::system::{MechanicalSystem, Structure, Vector};

/// The pair interaction.
#[derive(Clone, Debug, PartialEq)]
pub enum PairPotential {
    /// U(r) = −G mᵢ mⱼ / √(r² + s²).
    Gravity {
        /// Gravitational constant.
        g: f64,
        /// Softening length s.
        softening: f64,
    },
    /// U(r) = 4ε((σ/r)¹² − (σ/r)⁶).
    LennardJones {
        /// Well depth ε.
        epsilon: f64,
        /// Length scale σ.
        sigma: f64,
    },
}

/// N bodies; q and p are stacked as (x₁, y₁, z₁, x₂, …).
#[derive(Clone, Debug, PartialEq)]
pub struct NBody {
    /// Body masses.
    pub masses: Vec<f64>,
    /// The pair interaction.
    pub potential: PairPotential,
    /// Damping coefficient γ.
    pub gamma: f64,
}

impl NBody {
    /// The pair energy U(r²) and the factor f with ∇_{qᵢ} U = f (qᵢ − qⱼ).
    #[inline]
    fn pair(&self, i: usize, j: usize, r2: f64) -> (f64, f64) {
        match self.potential {
            PairPotential::Gravity { g, softening } => {
                let s2 = r2 + softening * softening;
                let inv = 1.0 / s2.sqrt();
                let gm = g * self.masses[i] * self.masses[j];
                (-gm * inv, gm * inv * inv * inv)
            }
            PairPotential::LennardJones { epsilon, sigma } => {
                let sr2 = sigma * sigma / r2;
                let sr6 = sr2 * sr2 * sr2;
                let u = 4.0 * epsilon * (sr6 * sr6 - sr6);
                // dU/dr · 1/r = 4ε(−12 σ¹²/r¹⁴ + 6 σ⁶/r⁸)
                (u, 4.0 * epsilon * (-12.0 * sr6 * sr6 + 6.0 * sr6) / r2)
            }
        }
    }

    fn bodies(&self) -> usize {
        self.masses.len()
    }
}

impl MechanicalSystem for NBody {
    type Dim = Dyn;
    fn dim(&self) -> Dyn {
        Dyn(3 * self.bodies())
    }
    fn structure(&self) -> Structure {
        Structure {
            separable_constant_mass: true,
            conformal_damping: true,
        }
    }
    fn kinetic(&self, _q: &Vector<Dyn>, p: &Vector<Dyn>) -> f64 {
        (0..self.bodies())
            .map(|i| {
                let pi = p.fixed_rows::<3>(3 * i);
                0.5 * pi.norm_squared() / self.masses[i]
            })
            .sum()
    }
    fn potential(&self, q: &Vector<Dyn>) -> f64 {
        let mut v = 0.0;
        for i in 0..self.bodies() {
            for j in i + 1..self.bodies() {
                let d = q.fixed_rows::<3>(3 * i) - q.fixed_rows::<3>(3 * j);
                v += self.pair(i, j, d.norm_squared()).0;
            }
        }
        v
    }
    fn grad_potential(&self, q: &Vector<Dyn>, out: &mut Vector<Dyn>) {
        out.fill(0.0);
        for i in 0..self.bodies() {
            for j in i + 1..self.bodies() {
                let d = q.fixed_rows::<3>(3 * i) - q.fixed_rows::<3>(3 * j);
                let f = self.pair(i, j, d.norm_squared()).1;
                let mut oi = out.fixed_rows_mut::<3>(3 * i);
                oi.axpy(f, &d, 1.0);
                let mut oj = out.fixed_rows_mut::<3>(3 * j);
                oj.axpy(-f, &d, 1.0);
            }
        }
    }
    fn velocity(&self, _q: &Vector<Dyn>, p: &Vector<Dyn>, out: &mut Vector<Dyn>) {
        for (i, m) in self.masses.iter().enumerate() {
            for c in 0..3 {
                out[3 * i + c] = p[3 * i + c] / m;
            }
        }
    }
    fn damping_rate(&self) -> f64 {
        2.0 * self.gamma
    }
    fn invariant_count(&self) -> usize {
        4
    }
    fn invariants(&self, t: f64, q: &Vector<Dyn>, p: &Vector<Dyn>, out: &mut [f64]) {
        let mut l = nalgebra::Vector3::zeros();
        for i in 0..self.bodies() {
            l += q.fixed_rows::<3>(3 * i).cross(&p.fixed_rows::<3>(3 * i));
        }
        out[0] = l.x;
        out[1] = l.y;
        out[2] = l.z;
        // |L| e^{2γt}: constant along the exact flow.
        out[3] = l.norm() * (2.0 * self.gamma * t).exp();
    }
}

/// Most bodies.
const MAX_BODIES: usize = 64;
const MASSES: ParamSpec = ParamSpec {
    name: Cow::Borrowed("masses"),
    description: Cow::Borrowed("Body masses; q0 and p0 hold 3 entries per body (x, y, z)."),
    kind: ParamKind::NumberList {
        default: &[1.0, 1.0, 1.0],
        min: 0.0,
        max: 1e12,
        max_len: MAX_BODIES,
    },
};
const POTENTIAL: ParamSpec = ParamSpec {
    name: Cow::Borrowed("potential"),
    description: Cow::Borrowed("The pair interaction."),
    kind: ParamKind::Choice {
        default: "gravity",
        options: &["gravity", "lennard_jones"],
    },
};
const G: ParamSpec = ParamSpec::number(
    "G",
    "Gravitational constant (gravity).",
    1.0,
    0.0,
    false,
    1e12,
);
const SOFTENING: ParamSpec = ParamSpec::number(
    "softening",
    "Plummer softening length (gravity).",
    0.0,
    0.0,
    false,
    1e6,
);
const LJ_EPSILON: ParamSpec = ParamSpec::number(
    "lj_epsilon",
    "Well depth ε of the Lennard-Jones potential.",
    1.0,
    0.0,
    false,
    1e6,
);
const LJ_SIGMA: ParamSpec = ParamSpec::number(
    "lj_sigma",
    "Length scale σ of the Lennard-Jones potential.",
    1.0,
    0.0,
    true,
    1e6,
);
const GAMMA: ParamSpec = ParamSpec::gamma(0.0);
const CARTESIAN: ChartInfo = ChartInfo::new(
    "cartesian",
    &["x₁", "y₁", "z₁", "…"],
    true,
    "H = Σ|p_i|²/(2m_i) + Σ V(|q_i − q_j|).",
);

/// Figure-eight choreography of three equal masses (Chenciner & Montgomery 2000; initial data
/// from Simó's computation as quoted there), in the z = 0 plane.
fn figure_eight() -> (Vec<f64>, Vec<f64>) {
    let (x1, y1) = (-0.970_004_36, 0.243_087_53);
    let (vx3, vy3) = (-0.932_407_37, -0.864_731_46);
    let q = vec![x1, y1, 0.0, -x1, -y1, 0.0, 0.0, 0.0, 0.0];
    let p = vec![
        -vx3 / 2.0,
        -vy3 / 2.0,
        0.0,
        -vx3 / 2.0,
        -vy3 / 2.0,
        0.0,
        vx3,
        vy3,
        0.0,
    ];
    (q, p)
}

/// The catalogue entry of `nbody`.
pub(super) fn entry() -> SystemInfo {
    let (q0, p0) = figure_eight();
    SystemInfo {
        id: Cow::Borrowed("nbody"),
        name: Cow::Borrowed("N bodies with linear damping"),
        description: Cow::Borrowed("N point masses in R³ with a pairwise radial potential (Newtonian gravity with optional softening, or Lennard-Jones) and p' = −∇V − 2γp. The total angular momentum decays exactly as e^{−2γt}. Default: the figure-eight three-body choreography."),
        degrees_of_freedom: 9,
        charts: vec![CARTESIAN],
        params: vec![MASSES, POTENTIAL, G, SOFTENING, LJ_EPSILON, LJ_SIGMA, GAMMA],
        q0,
        p0,
        invariants: vec![Cow::Borrowed("L_x"), Cow::Borrowed("L_y"), Cow::Borrowed("L_z"), Cow::Borrowed("L_conformal")],
        exact_solution: false,
        conformal_damping: true,
        world: World::Bodies,
        build: Builder::Catalog(|p: &ParamValues, _: &ChartInfo, _: f64| {
            let potential = if p.text(&POTENTIAL) == "lennard_jones" {
                PairPotential::LennardJones {
                    epsilon: p.number(&LJ_EPSILON),
                    sigma: p.number(&LJ_SIGMA),
                }
            } else {
                PairPotential::Gravity {
                    g: p.number(&G),
                    softening: p.number(&SOFTENING),
                }
            };
            AnySystem::NBody(NBody {
                masses: p.numbers(&MASSES),
                potential,
                gamma: p.number(&GAMMA),
            })
        }),
    }
}
