//! The model of a user-defined system: its expressions parsed into one graph over the
//! coordinates, momenta and parameters, with the exact derivatives every method needs, checked
//! once ([`CustomModel::new`]); and its compilation for a run's parameter values
//! ([`CustomModel::instantiate`]).

use std::sync::Arc;

use super::damping::MassFactor;
use super::shapes::{check_square, mass_nodes, position_nodes};
use super::system::{Compiled, CustomSystem, DampingModel, EnergyModel};
use super::{applicable, CustomDefinition, Damping, DampingKind, Energy, Expression, Facts};
use super::{MAX_COORDINATES, MAX_NAMES};
use crate::error::{CoreError, Field, Range};
use crate::expr::{CompileOptions, CompiledFunction, ExprError, Graph, NodeId, Scope, Var};
use crate::system::Structure;
use crate::systems::world::Drawing;
use crate::systems::{AnySystem, ParamValues, World};

/// The graph nodes of the energy.
#[derive(Clone, Debug)]
enum EnergyNodes {
    Separable {
        potential: NodeId,
        gradient: Vec<NodeId>,
        /// ∇²V, row-major.
        hessian: Vec<NodeId>,
        /// M, row-major (parameters only).
        mass: Vec<NodeId>,
    },
    General {
        hamiltonian: NodeId,
        dq: Vec<NodeId>,
        dp: Vec<NodeId>,
        /// ∂²H/∂q², ∂²H/∂q∂p, ∂²H/∂p², each row-major, one after the other.
        second: Vec<NodeId>,
    },
}

/// The graph nodes of the damping.
#[derive(Clone, Debug)]
enum DampingNodes {
    None,
    Conformal {
        gamma: NodeId,
    },
    Rayleigh {
        epsilon: NodeId,
        matrix: Vec<NodeId>,
    },
}

/// A checked definition with its derivatives.
#[derive(Debug)]
pub struct CustomModel {
    definition: CustomDefinition,
    n: usize,
    graph: Graph,
    energy: EnergyNodes,
    damping: DampingNodes,
    /// ∂D_ab/∂q_c at index (a n + b) n + c, for Rayleigh damping.
    damping_derivative: Option<Vec<NodeId>>,
    invariants: Vec<NodeId>,
    /// The coordinates' own nodes (drawn when there are no `positions`).
    coordinate_nodes: Vec<NodeId>,
    /// Bodies' positions, `dims` (2 or 3) values each.
    positions: Option<(usize, Vec<NodeId>)>,
    facts: Facts,
}

/// A parse or derivative error of the expression at `field`.
fn expression(field: &Field) -> impl Fn(ExprError) -> CoreError + '_ {
    move |error| CoreError::Expression {
        field: field.clone(),
        error,
    }
}

/// Deterministic sample points of the configuration space: SplitMix64 in [−1.5, 1.5]ⁿ.
fn sample_points(n: usize, count: usize) -> Vec<Vec<f64>> {
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
fn positive_semidefinite(m: &[f64], n: usize) -> bool {
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
    /// Checks `definition` and builds its model.
    pub fn new(definition: CustomDefinition) -> Result<Self, CoreError> {
        let at = &definition.field;
        let n = definition.coordinates.len();
        if !(1..=MAX_COORDINATES).contains(&n) {
            return Err(CoreError::Count {
                field: at.key("coordinates"),
                got: n as u64,
                min: 1,
                max: MAX_COORDINATES as u64,
                what: "coordinates",
            });
        }
        let momenta: Vec<String> = match &definition.momenta {
            Some(names) if names.len() != n => {
                return Err(CoreError::WrongLength {
                    field: at.key("momenta"),
                    expected: n,
                    got: names.len(),
                })
            }
            Some(names) => names.clone(),
            None => definition
                .coordinates
                .iter()
                .map(|c| format!("p_{c}"))
                .collect(),
        };
        for (what, count) in [
            ("parameters", definition.parameters.len()),
            ("invariants", definition.invariants.len()),
        ] {
            if count > MAX_NAMES {
                return Err(CoreError::TooMany {
                    field: at.key(what),
                    what: "names",
                    limit: MAX_NAMES,
                    got: Some(count),
                });
            }
        }
        // Every name once: coordinates, momenta, parameters, in this order of slots.
        let mut scope = Scope::new();
        let mut declared: Vec<(String, Field)> = Vec::new();
        let names = definition
            .coordinates
            .iter()
            .enumerate()
            .map(|(i, c)| (c.clone(), at.key("coordinates").index(i)))
            .chain(momenta.iter().enumerate().map(|(i, c)| {
                let field = if definition.momenta.is_some() {
                    at.key("momenta").index(i)
                } else {
                    at.key("coordinates").index(i)
                };
                (c.clone(), field)
            }))
            .chain(
                definition
                    .parameters
                    .iter()
                    .map(|(name, _)| (name.clone(), at.key("parameters").key(name))),
            );
        for (name, field) in names {
            if let Some((_, first)) = declared.iter().find(|(d, _)| *d == name) {
                return Err(CoreError::DuplicateName {
                    field,
                    name,
                    first: first.clone(),
                });
            }
            scope.declare(&name).map_err(expression(&field))?;
            declared.push((name, field));
        }
        for (name, value) in &definition.parameters {
            if !value.is_finite() {
                return Err(CoreError::NotFinite {
                    field: at.key("parameters").key(name),
                });
            }
        }
        let k = definition.parameters.len();
        let q: Vec<Var> = (0..n as u32).map(Var).collect();
        let p: Vec<Var> = (n as u32..2 * n as u32).map(Var).collect();
        let params: Vec<Var> = (2 * n as u32..(2 * n + k) as u32).map(Var).collect();
        let in_q = scope.restricted_to(&[q.as_slice(), &params].concat());
        let in_qp = scope.restricted_to(&[q.as_slice(), &p, &params].concat());
        let in_params = scope.restricted_to(&params);

        let mut graph = Graph::new();
        let coordinate_nodes: Vec<NodeId> = q.iter().map(|&v| graph.var(v)).collect();
        let parse = |e: &Expression, scope: &Scope, graph: &mut Graph| {
            graph.parse(&e.text, scope).map_err(expression(&e.field))
        };
        let energy = match &definition.energy {
            Energy::Separable { mass, potential } => {
                let v = parse(potential, &in_q, &mut graph)?;
                let gradient = graph
                    .gradient(v, &q)
                    .map_err(expression(&potential.field))?;
                let hessian = graph
                    .hessian(v, &q)
                    .map_err(expression(&potential.field))?
                    .concat();
                let mass = mass_nodes(mass, n, &at.key("mass"), &mut |e| {
                    parse(e, &in_params, &mut graph)
                })?;
                EnergyNodes::Separable {
                    potential: v,
                    gradient,
                    hessian,
                    mass,
                }
            }
            Energy::General { hamiltonian } => {
                let h = parse(hamiltonian, &in_qp, &mut graph)?;
                let err = expression(&hamiltonian.field);
                let dq = graph.gradient(h, &q).map_err(&err)?;
                let dp = graph.gradient(h, &p).map_err(&err)?;
                let hqq = graph.jacobian(&dq, &q).map_err(&err)?.concat();
                let hqp = graph.jacobian(&dq, &p).map_err(&err)?.concat();
                let hpp = graph.jacobian(&dp, &p).map_err(&err)?.concat();
                EnergyNodes::General {
                    hamiltonian: h,
                    dq,
                    dp,
                    second: [hqq, hqp, hpp].concat(),
                }
            }
        };
        let damping = match &definition.damping {
            None => DampingNodes::None,
            Some(Damping::Conformal { gamma }) => DampingNodes::Conformal {
                gamma: parse(gamma, &in_params, &mut graph)?,
            },
            Some(Damping::Rayleigh { epsilon, matrix }) => {
                let field = at.key("damping").key("matrix");
                check_square(matrix, n, &field)?;
                let mut nodes = Vec::with_capacity(n * n);
                for row in matrix {
                    for e in row {
                        nodes.push(parse(e, &in_q, &mut graph)?);
                    }
                }
                DampingNodes::Rayleigh {
                    epsilon: parse(epsilon, &in_params, &mut graph)?,
                    matrix: nodes,
                }
            }
        };
        let mut invariants = Vec::with_capacity(definition.invariants.len());
        for (_, e) in &definition.invariants {
            invariants.push(parse(e, &in_qp, &mut graph)?);
        }
        let positions = match &definition.positions {
            None => None,
            Some(bodies) => Some(position_nodes(bodies, &at.key("positions"), &mut |e| {
                parse(e, &in_q, &mut graph)
            })?),
        };
        // ∂D_ab/∂q_c for the tangent maps of the damping flows, last so that every other
        // function's nodes are as they were; a derivative past the graph's limits leaves the
        // system without tangent dynamics rather than refusing it.
        let damping_derivative = match &damping {
            DampingNodes::Rayleigh { matrix, .. } => {
                graph.jacobian(matrix, &q).ok().map(|rows| rows.concat())
            }
            _ => None,
        };
        let mut model = CustomModel {
            definition,
            n,
            graph,
            energy,
            damping,
            damping_derivative,
            invariants,
            coordinate_nodes,
            positions,
            facts: Facts {
                dimension: n,
                separable: false,
                damping: DampingKind::None,
                methods: Vec::new(),
            },
        };
        model.check_states()?;
        // The numbers the default parameters fix: checked now, so that a definition that can
        // never run is refused when it is made.
        let defaults: Vec<f64> = model
            .definition
            .parameters
            .iter()
            .map(|(_, v)| *v)
            .collect();
        let numbers = model.numbers(&defaults, &model.definition.field.clone())?;
        model.facts = model.facts_of(&numbers);
        Ok(model)
    }

    /// The definition.
    pub fn definition(&self) -> &CustomDefinition {
        &self.definition
    }

    /// What the definition is.
    pub fn facts(&self) -> Facts {
        self.facts.clone()
    }

    /// Checks the default states' lengths and values.
    fn check_states(&self) -> Result<(), CoreError> {
        let at = &self.definition.field;
        for (name, state) in [("q0", &self.definition.q0), ("p0", &self.definition.p0)] {
            if let Some(v) = state {
                if v.len() != self.n {
                    return Err(CoreError::WrongLength {
                        field: at.key(name),
                        expected: self.n,
                        got: v.len(),
                    });
                }
                if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                    return Err(CoreError::NotFinite {
                        field: at.key(name).index(i),
                    });
                }
            }
        }
        Ok(())
    }

    /// The structure of the system (what the methods require).
    fn structure(&self, numbers: &Numbers) -> Structure {
        Structure {
            separable_constant_mass: matches!(self.energy, EnergyNodes::Separable { .. }),
            // No damping is conformal damping with γ = 0 (D = 0 ∝ M), as for the built-in
            // undamped systems: the conformal methods then reduce to their symplectic kernels.
            conformal_damping: matches!(
                numbers.damping,
                DampingModel::None | DampingModel::Conformal { .. }
            ),
        }
    }

    fn facts_of(&self, numbers: &Numbers) -> Facts {
        let structure = self.structure(numbers);
        Facts {
            dimension: self.n,
            separable: structure.separable_constant_mass,
            damping: match numbers.damping {
                DampingModel::None => DampingKind::None,
                DampingModel::Conformal { .. } => DampingKind::Conformal,
                DampingModel::Projector { .. } => DampingKind::RayleighProjector,
                DampingModel::General { .. } => DampingKind::Rayleigh,
            },
            methods: applicable(structure, numbers.damping.rate()),
        }
    }

    /// The values of every slot for parameters `values`, with q and p at zero.
    fn slots(&self, values: &[f64]) -> Vec<f64> {
        let mut slots = vec![0.0; 2 * self.n];
        slots.extend_from_slice(values);
        slots
    }

    /// The numbers parameters fix: the mass matrix, the damping's form and strength, checked;
    /// errors name `field` (the definition, or the run's parameters).
    fn numbers(&self, values: &[f64], field: &Field) -> Result<Numbers, CoreError> {
        let n = self.n;
        let at = &self.definition.field;
        let slots = self.slots(values);
        let mass = match &self.energy {
            EnergyNodes::Separable { mass, .. } => {
                let m = self.graph.eval(mass, &slots);
                let factor = MassFactor::new(&m, n).ok_or_else(|| CoreError::NotDefinite {
                    field: if field == at {
                        at.key("mass")
                    } else {
                        field.clone()
                    },
                    what: "the mass matrix",
                    property: "symmetric positive definite",
                    detail: format!("with these parameters it is {m:?}"),
                })?;
                Some((m, factor))
            }
            EnergyNodes::General { .. } => None,
        };
        let non_negative = |node: NodeId, name: &str| -> Result<f64, CoreError> {
            let x = self.graph.eval(&[node], &slots)[0];
            let place = if field == at {
                at.key("damping").key(name)
            } else {
                field.clone()
            };
            Range::NON_NEGATIVE.check(x, &place)
        };
        let damping = match &self.damping {
            DampingNodes::None => DampingModel::None,
            DampingNodes::Conformal { gamma } => DampingModel::Conformal {
                rate: 2.0 * non_negative(*gamma, "gamma")?,
            },
            DampingNodes::Rayleigh { epsilon, matrix } => {
                let epsilon = non_negative(*epsilon, "epsilon")?;
                let Some((m, factor)) = &mass else {
                    return Err(CoreError::Unsupported {
                        field: at.key("damping"),
                        reason: "Rayleigh damping needs a constant mass matrix: give `mass` and \
                                 `potential` rather than a general `hamiltonian`, or conformal \
                                 damping (`gamma`)",
                    });
                };
                self.check_damping_matrix(matrix, &slots)?;
                self.damping_model(epsilon, matrix, m, factor, &slots)
            }
        };
        Ok(Numbers { mass, damping })
    }

    /// Checks that D(q) is symmetric and positive semidefinite at the sample points.
    fn check_damping_matrix(&self, matrix: &[NodeId], slots: &[f64]) -> Result<(), CoreError> {
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
    fn damping_model(
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

    /// The parameter values of a run, in declaration order.
    fn values(&self, params: &ParamValues) -> Vec<f64> {
        self.definition
            .parameters
            .iter()
            .map(|(name, default)| params.get(name).unwrap_or(*default))
            .collect()
    }

    /// Compiles `outputs` for a run: inputs q (and p with `with_momenta`), parameters folded.
    fn compile(
        &self,
        outputs: &[NodeId],
        with_momenta: bool,
        values: &[f64],
    ) -> Result<CompiledFunction, CoreError> {
        let n = self.n;
        let inputs = if with_momenta { 2 * n } else { n };
        let options = CompileOptions {
            layout: (0..inputs as u32).map(Var).collect(),
            constants: values
                .iter()
                .enumerate()
                .map(|(i, &v)| (Var((2 * n + i) as u32), v))
                .chain((inputs..2 * n).map(|i| (Var(i as u32), 0.0)))
                .collect(),
            ..CompileOptions::default()
        };
        CompiledFunction::new(&self.graph, outputs, &options)
            .map_err(expression(&self.definition.field))
    }

    /// The system for a run with parameters `params`, compiled.
    pub fn instantiate(&self, params: &ParamValues) -> Result<AnySystem, CoreError> {
        let values = self.values(params);
        let numbers = self.numbers(&values, &Field::new("params"))?;
        let structure = self.structure(&numbers);
        let energy = match &self.energy {
            EnergyNodes::Separable {
                potential,
                gradient,
                hessian,
                ..
            } => {
                let Some((m, factor)) = &numbers.mass else {
                    unreachable!("a separable energy always has its mass checked")
                };
                EnergyModel::separable(
                    self.compile(&[*potential], false, &values)?,
                    self.compile(gradient, false, &values)?,
                    self.compile(hessian, false, &values)?,
                    m,
                    factor,
                    self.n,
                )
            }
            EnergyNodes::General {
                hamiltonian,
                dq,
                dp,
                second,
            } => EnergyModel::General {
                hamiltonian: self.compile(&[*hamiltonian], true, &values)?,
                dq: self.compile(dq, true, &values)?,
                dp: self.compile(dp, true, &values)?,
                second: self.compile(second, true, &values)?,
            },
        };
        let damping_matrix = match &self.damping {
            DampingNodes::Rayleigh { matrix, .. } => Some(self.compile(matrix, false, &values)?),
            _ => None,
        };
        let damping_derivative = self
            .damping_derivative
            .as_ref()
            .and_then(|nodes| self.compile(nodes, false, &values).ok());
        let invariants = if self.invariants.is_empty() {
            None
        } else {
            Some(self.compile(&self.invariants, true, &values)?)
        };
        let compiled = Arc::new(Compiled {
            n: self.n,
            structure,
            energy,
            damping: numbers.damping,
            damping_matrix,
            damping_derivative,
            invariants,
        });
        Ok(match self.n {
            1 => AnySystem::Custom1(CustomSystem::new(nalgebra::U1, compiled)),
            2 => AnySystem::Custom2(CustomSystem::new(nalgebra::U2, compiled)),
            3 => AnySystem::Custom3(CustomSystem::new(nalgebra::U3, compiled)),
            n => AnySystem::CustomN(CustomSystem::new(nalgebra::Dyn(n), compiled)),
        })
    }

    /// How the system appears in space for parameters `params`: its `positions`, or without
    /// them its first one to three coordinates.
    pub fn world(&self, params: &ParamValues) -> Result<World, CoreError> {
        let values = self.values(params);
        let (dims, nodes) = match &self.positions {
            Some((dims, nodes)) => (*dims, nodes.clone()),
            None => {
                let shown = &self.coordinate_nodes[..self.n.min(3)];
                (shown.len().max(2), shown.to_vec())
            }
        };
        let function = self.compile(&nodes, false, &values)?;
        Ok(World::Drawn(Arc::new(Drawing::new(function, dims))))
    }
}

/// The numbers a run's parameters fix.
struct Numbers {
    /// The mass matrix (row-major) and its Cholesky factor, for a separable H.
    mass: Option<(Vec<f64>, MassFactor)>,
    damping: DampingModel,
}
