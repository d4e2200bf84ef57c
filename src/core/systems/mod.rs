//! The system catalogue: each system's parameters (name, default, valid range), default initial
//! state, invariants, and the construction of a concrete system from user parameters.
//!
//! [`AnySystem`] is the one place where a run dispatches dynamically: [`with_system!`] matches it
//! once, and everything below runs monomorphised for the concrete system type.

mod elastic_pendulum;
mod first_order;
mod nbody;
mod oscillator;
mod pendulum;
mod planar;

use std::collections::BTreeMap;

use serde::Serialize;
use serde_json::Value;

pub use elastic_pendulum::{ElasticPendulum3d, ElasticPendulum3dCylindrical};
pub use first_order::{ExponentialDecay, Gompertz};
pub use nbody::{NBody, PairPotential};
pub use oscillator::{CompensatedOscillator, HarmonicOscillator};
pub use pendulum::Pendulum;
pub use planar::{wrap_angle, PlanarCartesian, PlanarKind, PlanarPolar, PlanarSpring};

use crate::core::error::CoreError;

/// Parameters as given by a user: numbers, and for N bodies also a list and a choice.
pub type Params = serde_json::Map<String, Value>;

/// How a parameter is given and what values it accepts.
#[derive(Clone, Debug, Serialize, PartialEq)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ParamKind {
    /// A number in [min, max] (min excluded when `min_exclusive`).
    Number {
        /// Default value.
        default: f64,
        /// Lower bound.
        min: f64,
        /// Whether the lower bound itself is excluded.
        min_exclusive: bool,
        /// Upper bound.
        max: f64,
    },
    /// One of a fixed set of names.
    Choice {
        /// Default option.
        default: &'static str,
        /// The options.
        options: &'static [&'static str],
    },
    /// A list of positive numbers (N-body masses).
    NumberList {
        /// Default list.
        default: Vec<f64>,
        /// Lower bound (excluded) of every entry.
        min: f64,
        /// Upper bound of every entry.
        max: f64,
        /// Most entries allowed.
        max_len: usize,
    },
}

/// One parameter of a system.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ParamSpec {
    /// Name used in `params`.
    pub name: &'static str,
    /// What it means.
    pub description: &'static str,
    /// Accepted values.
    #[serde(flatten)]
    pub kind: ParamKind,
}

/// A coordinate chart a system is offered in.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ChartInfo {
    /// Identifier used in requests (`chart`).
    pub id: &'static str,
    /// Names of the generalized coordinates, in state order.
    pub coordinates: &'static [&'static str],
    /// Whether H is separable with a constant mass matrix in this chart (the splitting methods
    /// need it).
    pub separable: bool,
    /// The chart's map to Cartesian coordinates and its Hamiltonian.
    pub description: &'static str,
}

const fn chart(
    id: &'static str,
    coordinates: &'static [&'static str],
    separable: bool,
    description: &'static str,
) -> ChartInfo {
    ChartInfo {
        id,
        coordinates,
        separable,
        description,
    }
}

/// A catalogue entry.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct SystemInfo {
    /// Identifier used in requests.
    pub id: &'static str,
    /// Human-readable name.
    pub name: &'static str,
    /// What the system is, with its paper.
    pub description: &'static str,
    /// Degrees of freedom (for N bodies: of the default case).
    pub degrees_of_freedom: usize,
    /// Coordinate charts the system is offered in; the first is the default, and its
    /// coordinates are the Cartesian ones (for a first-order ODE: the original variable) in
    /// which `q0` and `p0` are given.
    pub charts: Vec<ChartInfo>,
    /// Parameters.
    pub params: Vec<ParamSpec>,
    /// Default initial positions.
    pub q0: Vec<f64>,
    /// Default initial momenta.
    pub p0: Vec<f64>,
    /// Names of the invariants reported per sample.
    pub invariants: &'static [&'static str],
    /// Whether a closed-form solution gives the energy error.
    pub exact_solution: bool,
    /// Whether the damping is conformal (so `gamma`/`epsilon` are both accepted).
    pub conformal_damping: bool,
}

const MAX_BODIES: usize = 64;

fn number(
    name: &'static str,
    description: &'static str,
    default: f64,
    min: f64,
    min_exclusive: bool,
    max: f64,
) -> ParamSpec {
    ParamSpec {
        name,
        description,
        kind: ParamKind::Number {
            default,
            min,
            min_exclusive,
            max,
        },
    }
}

fn gamma_param(default: f64) -> ParamSpec {
    number(
        "gamma",
        "Linear damping coefficient γ in p' = −∇V − 2γp; `epsilon` = 2γ may be given instead (paper 000's ε).",
        default,
        0.0,
        false,
        1e6,
    )
}

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

/// The whole catalogue, in a stable order.
pub fn catalog() -> Vec<SystemInfo> {
    let (nb_q, nb_p) = figure_eight();
    vec![
        SystemInfo {
            id: "harmonic_oscillator",
            name: "Damped harmonic oscillator",
            description: "q'' + 2γq' + ω²q = 0 with T = p²/2, V = ω²q²/2 (paper 003 eq. 2.5); exact solution in the under-, critically and over-damped regimes.",
            degrees_of_freedom: 1,
            charts: vec![
                chart("cartesian", &["q"], true, "H = p²/2 + ω²q²/2."),
                chart("compensating", &["Q"], false, "Q = (2/π)(q̂√(1 − q̂²) + arcsin q̂), q̂ = q/(1 + k h²), p̄ = p/Q'(q) (paper 001 eq. 82); H̄ = ½ p̄² Q'(q)² + ½ ω² q² is not separable. Symplectic Euler's first-order energy error vanishes along the unit-amplitude motion (ω = 1, q0 = 1, p0 = 0)."),
            ],
            params: vec![
                number("omega", "Angular frequency ω.", 1.0, 0.0, true, 1e6),
                gamma_param(0.05),
                number("k", "Margin k of the compensating chart, q̂ = q/(1 + k h²) (paper 001 eq. 82; chart `compensating` only).", 2.0, 0.0, true, 1e6),
            ],
            q0: vec![1.0],
            p0: vec![0.0],
            invariants: &[],
            exact_solution: true,
            conformal_damping: true,
        },
        SystemInfo {
            id: "pendulum",
            name: "Damped pendulum",
            description: "T = p²/2, V = 1 − cos q, p' = −sin q − 2γp (paper 000 Sec. 4.3, paper 003 eq. 4.5).",
            degrees_of_freedom: 1,
            charts: vec![chart("cartesian", &["q"], true, "H = p²/2 + 1 − cos q.")],
            params: vec![gamma_param(0.005)],
            q0: vec![0.9 * std::f64::consts::PI],
            p0: vec![0.0],
            invariants: &[],
            exact_solution: false,
            conformal_damping: true,
        },
        SystemInfo {
            id: "elastic_pendulum_3d",
            name: "Elastic 3-D pendulum, damped along the spring",
            description: "A mass on a spring in R³ under gravity (0, 0, −g), V = k/2 (l − |q|)² + m g q_z, Rayleigh damping along the spring only, D = q qᵀ/|q|² (paper 000 Sec. 6.2, eq. 16). J₃ = (q × p)_z is conserved for every ε.",
            degrees_of_freedom: 3,
            charts: vec![
                chart("cartesian", &["x", "y", "z"], true, "H = |p|²/(2m) + k/2 (|q| − l)² + m g z."),
                chart("cylindrical", &["ρ", "φ", "z"], false, "x = ρ cos φ, y = ρ sin φ: H = (p_ρ² + p_φ²/ρ² + p_z²)/(2m) + k/2 (√(ρ² + z²) − l)² + m g z, with J₃ = p_φ cyclic; the damping is the same spring-direction Rayleigh function."),
            ],
            params: vec![
                number("m", "Mass.", 1.0, 0.0, true, 1e6),
                number("k", "Spring stiffness.", 1.0, 0.0, true, 1e6),
                number("l", "Spring rest length.", 1.0, 0.0, true, 1e6),
                number("g", "Gravitational acceleration (along −z).", 1.0, 0.0, false, 1e6),
                number("epsilon", "Damping strength ε of the radial Rayleigh dissipation.", 0.1, 0.0, false, 1e6),
            ],
            q0: vec![0.0, 1.558_845_73, -0.6],
            p0: vec![1.341_640_79, 0.0, 0.0],
            invariants: &["J3"],
            exact_solution: false,
            conformal_damping: false,
        },
        SystemInfo {
            id: "nbody",
            name: "N bodies with linear damping",
            description: "N point masses in R³ with a pairwise radial potential (Newtonian gravity with optional softening, or Lennard-Jones) and p' = −∇V − 2γp. The total angular momentum decays exactly as e^{−2γt}. Default: the figure-eight three-body choreography.",
            degrees_of_freedom: 9,
            charts: vec![chart("cartesian", &["x₁", "y₁", "z₁", "…"], true, "H = Σ|p_i|²/(2m_i) + Σ V(|q_i − q_j|).")],
            params: vec![
                ParamSpec {
                    name: "masses",
                    description: "Body masses; q0 and p0 hold 3 entries per body (x, y, z).",
                    kind: ParamKind::NumberList {
                        default: vec![1.0, 1.0, 1.0],
                        min: 0.0,
                        max: 1e12,
                        max_len: MAX_BODIES,
                    },
                },
                ParamSpec {
                    name: "potential",
                    description: "The pair interaction.",
                    kind: ParamKind::Choice {
                        default: "gravity",
                        options: &["gravity", "lennard_jones"],
                    },
                },
                number("G", "Gravitational constant (gravity).", 1.0, 0.0, false, 1e12),
                number("softening", "Plummer softening length (gravity).", 0.0, 0.0, false, 1e6),
                number("lj_epsilon", "Well depth ε of the Lennard-Jones potential.", 1.0, 0.0, false, 1e6),
                number("lj_sigma", "Length scale σ of the Lennard-Jones potential.", 1.0, 0.0, true, 1e6),
                gamma_param(0.0),
            ],
            q0: nb_q,
            p0: nb_p,
            invariants: &["L_x", "L_y", "L_z", "L_conformal"],
            exact_solution: false,
            conformal_damping: true,
        },
        SystemInfo {
            id: "elastic_pendulum_2d",
            name: "Planar elastic pendulum",
            description: "A mass on a spring in the plane under gravity along +y (y points down), paper 001 Appendix A: H = |p|²/(2m) + k/2 (|q| − l)² − m g y (eq. 73), or in polar coordinates (eq. 72). Undamped.",
            degrees_of_freedom: 2,
            charts: vec![
                chart("cartesian", &["x", "y"], true, "H = (p_x² + p_y²)/(2m) + k/2 (√(x² + y²) − l)² − m g y (001 eq. 73)."),
                chart("polar", &["r", "θ"], false, "x = r sin θ, y = r cos θ (θ from the downward vertical): H = (p_r² + p_θ²/r²)/(2m) + k/2 (r − l)² − m g r cos θ (001 eq. 72); the mass matrix depends on r."),
            ],
            params: vec![
                number("m", "Mass.", 1.0, 0.0, true, 1e6),
                number("k", "Spring stiffness.", 1.0, 0.0, true, 1e6),
                number("l", "Spring rest length.", 1.0, 0.0, true, 1e6),
                number("g", "Gravitational acceleration (along +y, downwards).", 0.2, 0.0, false, 1e6),
            ],
            q0: vec![0.6, 1.2],
            p0: vec![0.0, 0.0],
            invariants: &[],
            exact_solution: false,
            conformal_damping: true,
        },
        SystemInfo {
            id: "free_particle_2d",
            name: "Free particle in the plane",
            description: "H = |p|²/(2m), paper 001 Sec. 5.2: linear momentum (p_x, p_y) and angular momentum L = x p_y − y p_x are conserved. Symplectic Euler keeps p_θ exactly in polar coordinates but not p_x, and keeps L exactly in Cartesian ones.",
            degrees_of_freedom: 2,
            charts: vec![
                chart("cartesian", &["x", "y"], true, "H = (p_x² + p_y²)/(2m) (001 eq. 61)."),
                chart("polar", &["r", "θ"], false, "x = r sin θ, y = r cos θ: H = (p_r² + p_θ²/r²)/(2m) (001 eq. 62), θ cyclic, p_θ = y p_x − x p_y = −L."),
            ],
            params: vec![number("m", "Mass.", 1.0, 0.0, true, 1e6)],
            q0: vec![1.0, 0.5],
            p0: vec![0.2, 1.0],
            invariants: &["L", "p_x", "p_y"],
            exact_solution: true,
            conformal_damping: true,
        },
        SystemInfo {
            id: "exponential_decay",
            name: "Exponential decay (first-order ODE)",
            description: "y' = −αy (paper 001 eq. 14), run as the cotangent lift H = p f(y) (p stays 0 from p0 = 0, H = 0). In the chart `transformed`, ȳ = ln(y)/α (eq. 15) obeys ȳ' = −1 and explicit Euler is exact.",
            degrees_of_freedom: 1,
            charts: vec![
                chart("original", &["y"], false, "y' = −αy; H = −α p y."),
                chart("transformed", &["ȳ"], false, "ȳ = ln(y)/α, p̄ = p α y (001 eq. 15): ȳ' = −1, H̄ = −p̄."),
            ],
            params: vec![number("alpha", "Decay rate α.", 1.0, 0.0, true, 1e6)],
            q0: vec![1.0],
            p0: vec![0.0],
            invariants: &[],
            exact_solution: true,
            conformal_damping: false,
        },
        SystemInfo {
            id: "gompertz",
            name: "Gompertz growth (first-order ODE)",
            description: "y' = y (a − b ln y) (paper 001 eq. 17), run as the cotangent lift H = p f(y). In the chart `transformed`, ȳ = −(1/b) ln(1 − (b/a) ln y) (eq. 18 up to its additive constant) obeys ȳ' = 1 and explicit Euler is exact; it covers 0 < y < e^(a/b).",
            degrees_of_freedom: 1,
            charts: vec![
                chart("original", &["y"], false, "y' = y (a − b ln y); H = p y (a − b ln y)."),
                chart("transformed", &["ȳ"], false, "ȳ = −(1/b) ln(1 − (b/a) ln y), p̄ = p y (a − b ln y) (001 eq. 18): ȳ' = 1, H̄ = p̄."),
            ],
            params: vec![
                number("a", "Growth parameter a.", 2.0, 0.0, true, 1e6),
                number("b", "Growth parameter b (carrying capacity e^(a/b)).", 0.5, 0.0, true, 1e6),
            ],
            q0: vec![3.0],
            p0: vec![0.0],
            invariants: &[],
            exact_solution: true,
            conformal_damping: false,
        },
    ]
}

/// The catalogue entry for `id`.
pub fn info(id: &str) -> Result<SystemInfo, CoreError> {
    catalog()
        .into_iter()
        .find(|s| s.id == id)
        .ok_or_else(|| CoreError::UnknownSystem { id: id.to_string() })
}

/// A concrete system, chosen at run time.
#[derive(Clone, Debug, PartialEq)]
pub enum AnySystem {
    /// See [`HarmonicOscillator`].
    HarmonicOscillator(HarmonicOscillator),
    /// See [`Pendulum`].
    Pendulum(Pendulum),
    /// See [`ElasticPendulum3d`].
    ElasticPendulum3d(ElasticPendulum3d),
    /// See [`NBody`].
    NBody(NBody),
    /// See [`ElasticPendulum3dCylindrical`].
    ElasticPendulum3dCylindrical(ElasticPendulum3dCylindrical),
    /// See [`CompensatedOscillator`].
    CompensatedOscillator(CompensatedOscillator),
    /// See [`PlanarCartesian`].
    PlanarCartesian(PlanarCartesian),
    /// See [`PlanarPolar`].
    PlanarPolar(PlanarPolar),
    /// See [`ExponentialDecay`].
    ExponentialDecay(ExponentialDecay),
    /// See [`Gompertz`].
    Gompertz(Gompertz),
}

/// Runs `$body` with `$s` bound to the concrete system inside an [`AnySystem`].
#[macro_export]
macro_rules! with_system {
    ($any:expr, $s:ident => $body:expr) => {
        match $any {
            $crate::core::systems::AnySystem::HarmonicOscillator($s) => $body,
            $crate::core::systems::AnySystem::Pendulum($s) => $body,
            $crate::core::systems::AnySystem::ElasticPendulum3d($s) => $body,
            $crate::core::systems::AnySystem::NBody($s) => $body,
            $crate::core::systems::AnySystem::ElasticPendulum3dCylindrical($s) => $body,
            $crate::core::systems::AnySystem::CompensatedOscillator($s) => $body,
            $crate::core::systems::AnySystem::PlanarCartesian($s) => $body,
            $crate::core::systems::AnySystem::PlanarPolar($s) => $body,
            $crate::core::systems::AnySystem::ExponentialDecay($s) => $body,
            $crate::core::systems::AnySystem::Gompertz($s) => $body,
        }
    };
}

/// Parameters after validation: every number resolved (defaults filled in), plus N-body extras.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Resolved {
    /// Numeric parameters by name.
    pub numbers: BTreeMap<String, f64>,
    /// N-body masses.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub masses: Option<Vec<f64>>,
    /// N-body pair potential.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub potential: Option<String>,
}

/// Validates `params` against the catalogue entry (unknown names, types, ranges; `gamma` and
/// `epsilon` are exclusive) and fills in defaults.
pub fn resolve(info: &SystemInfo, params: &Params) -> Result<Resolved, CoreError> {
    let mut resolved = Resolved::default();
    let conformal_alias = info.conformal_damping && params.contains_key("epsilon");
    if conformal_alias && params.contains_key("gamma") {
        return Err(CoreError::invalid(
            "params.epsilon",
            "give either gamma or epsilon (= 2γ), not both",
        ));
    }
    for name in params.keys() {
        let known =
            info.params.iter().any(|p| p.name == name) || (conformal_alias && name == "epsilon");
        if !known {
            let names: Vec<&str> = info.params.iter().map(|p| p.name).collect();
            return Err(CoreError::invalid(
                format!("params.{name}"),
                format!(
                    "unknown parameter for `{}`; known: {}",
                    info.id,
                    names.join(", ")
                ),
            ));
        }
    }
    for spec in &info.params {
        let mut field = format!("params.{}", spec.name);
        let mut given = params.get(spec.name);
        // `epsilon` = 2γ on a conformal system: errors name and show what was given.
        let mut scale = 1.0;
        if spec.name == "gamma" && conformal_alias {
            given = params.get("epsilon");
            scale = 2.0;
            field = "params.epsilon".to_string();
        }
        match &spec.kind {
            ParamKind::Number {
                default,
                min,
                min_exclusive,
                max,
            } => {
                let value = match given {
                    None => *default,
                    Some(v) => {
                        v.as_f64()
                            .ok_or_else(|| CoreError::invalid(&field, "must be a number"))?
                            / scale
                    }
                };
                let below = if *min_exclusive {
                    value <= *min
                } else {
                    value < *min
                };
                if !value.is_finite() || below || value > *max {
                    let open = if *min_exclusive { "(" } else { "[" };
                    return Err(CoreError::invalid(
                        &field,
                        format!(
                            "{} is outside the valid range {open}{}, {}]",
                            value * scale,
                            min * scale,
                            max * scale
                        ),
                    ));
                }
                resolved.numbers.insert(spec.name.to_string(), value);
            }
            ParamKind::Choice { default, options } => {
                let value = match given {
                    None => default.to_string(),
                    Some(v) => v
                        .as_str()
                        .ok_or_else(|| CoreError::invalid(&field, "must be a string"))?
                        .to_string(),
                };
                if !options.contains(&value.as_str()) {
                    return Err(CoreError::invalid(
                        &field,
                        format!("`{value}` is not one of {}", options.join(", ")),
                    ));
                }
                resolved.potential = Some(value);
            }
            ParamKind::NumberList {
                default,
                min,
                max,
                max_len,
            } => {
                let list = match given {
                    None => default.clone(),
                    Some(v) => v
                        .as_array()
                        .ok_or_else(|| CoreError::invalid(&field, "must be a list of numbers"))?
                        .iter()
                        .map(|x| {
                            x.as_f64().ok_or_else(|| {
                                CoreError::invalid(&field, "must be a list of numbers")
                            })
                        })
                        .collect::<Result<Vec<f64>, _>>()?,
                };
                if list.is_empty() || list.len() > *max_len {
                    return Err(CoreError::invalid(
                        &field,
                        format!("needs 1 to {max_len} entries, got {}", list.len()),
                    ));
                }
                if let Some(bad) = list
                    .iter()
                    .find(|&&x| !x.is_finite() || x <= *min || x > *max)
                {
                    return Err(CoreError::invalid(
                        &field,
                        format!("{bad} is outside the valid range ({min}, {max}]"),
                    ));
                }
                resolved.masses = Some(list);
            }
        }
    }
    Ok(resolved)
}

/// The chart `requested` of system `info` (default: its first), or an error naming `chart`.
pub fn chart_of<'a>(
    info: &'a SystemInfo,
    requested: Option<&str>,
) -> Result<&'a ChartInfo, CoreError> {
    match requested {
        None => Ok(&info.charts[0]),
        Some(id) => info.charts.iter().find(|c| c.id == id).ok_or_else(|| {
            let known: Vec<&str> = info.charts.iter().map(|c| c.id).collect();
            CoreError::invalid(
                "chart",
                format!(
                    "`{}` has no chart `{id}`; charts: {}",
                    info.id,
                    known.join(", ")
                ),
            )
        }),
    }
}

/// Builds the system `id` in chart `chart` from resolved parameters. `h` is the run's step,
/// which the oscillator's compensating chart (001 eq. 82) depends on.
pub fn build(id: &str, chart: &str, r: &Resolved, h: f64) -> Result<AnySystem, CoreError> {
    let n = |name: &str| r.numbers.get(name).copied().unwrap_or(0.0);
    let planar = |kind| PlanarSpring {
        m: n("m"),
        k: n("k"),
        l: n("l"),
        g: n("g"),
        kind,
    };
    let transformed = chart == "transformed";
    Ok(match (id, chart) {
        ("harmonic_oscillator", _) => {
            let oscillator = HarmonicOscillator {
                omega: n("omega"),
                gamma: n("gamma"),
            };
            if chart == "compensating" {
                AnySystem::CompensatedOscillator(CompensatedOscillator::new(oscillator, n("k"), h))
            } else {
                AnySystem::HarmonicOscillator(oscillator)
            }
        }
        ("pendulum", _) => AnySystem::Pendulum(Pendulum { gamma: n("gamma") }),
        ("elastic_pendulum_3d", _) => {
            let pendulum = ElasticPendulum3d {
                m: n("m"),
                k: n("k"),
                l: n("l"),
                g: n("g"),
                epsilon: n("epsilon"),
            };
            if chart == "cylindrical" {
                AnySystem::ElasticPendulum3dCylindrical(ElasticPendulum3dCylindrical(pendulum))
            } else {
                AnySystem::ElasticPendulum3d(pendulum)
            }
        }
        ("elastic_pendulum_2d" | "free_particle_2d", _) => {
            let spring = if id == "free_particle_2d" {
                PlanarSpring {
                    k: 0.0,
                    l: 0.0,
                    g: 0.0,
                    ..planar(PlanarKind::FreeParticle)
                }
            } else {
                planar(PlanarKind::Pendulum)
            };
            if chart == "polar" {
                AnySystem::PlanarPolar(PlanarPolar(spring))
            } else {
                AnySystem::PlanarCartesian(PlanarCartesian(spring))
            }
        }
        ("exponential_decay", _) => AnySystem::ExponentialDecay(ExponentialDecay {
            alpha: n("alpha"),
            transformed,
        }),
        ("gompertz", _) => AnySystem::Gompertz(Gompertz {
            a: n("a"),
            b: n("b"),
            transformed,
        }),
        ("nbody", _) => AnySystem::NBody(NBody {
            masses: r.masses.clone().unwrap_or_default(),
            potential: match r.potential.as_deref() {
                Some("lennard_jones") => PairPotential::LennardJones {
                    epsilon: n("lj_epsilon"),
                    sigma: n("lj_sigma"),
                },
                _ => PairPotential::Gravity {
                    g: n("G"),
                    softening: n("softening"),
                },
            },
            gamma: n("gamma"),
        }),
        (other, _) => {
            return Err(CoreError::UnknownSystem {
                id: other.to_string(),
            })
        }
    })
}

impl AnySystem {
    /// The configuration-space dimension.
    pub fn dimension(&self) -> usize {
        use crate::core::system::MechanicalSystem;
        with_system!(self, s => nalgebra::Dim::value(&s.dim()))
    }
}
