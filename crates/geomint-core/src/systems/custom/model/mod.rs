//! The model of a user-defined system: its expressions parsed into one graph over the
//! coordinates, momenta and parameters, with the exact derivatives every method needs, checked
//! once ([`CustomModel::new`]); and its compilation for a run's parameter values
//! ([`CustomModel::instantiate`]).

mod checks;
mod compile;

use std::sync::{Arc, Mutex};

use super::damping::MassFactor;
use super::shapes::{check_square, mass_nodes, position_nodes};
use super::system::{Compiled, DampingModel};
use super::{CustomDefinition, Damping, DampingKind, Energy, Expression};
use super::{MAX_COORDINATES, MAX_NAMES};
use crate::error::{CoreError, Field, Range};
use crate::expr::{ExprError, Graph, NameScope, NodeId, Var};
use crate::system::Structure;
use crate::systems::{ParamValues, World};
use checks::uses;

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
    /// For a definition whose energy or damping uses the time `t`: the slots of t and of its
    /// momentum p_t in extended phase space (see [`Clock`]).
    clock: Option<Clock>,
    /// The structure and damping rate at the default parameter values (what the methods
    /// require), and the damping's form.
    at_defaults: (Structure, f64, DampingKind),
    /// The last compilation and the last drawing of the bodies, each with its parameter values'
    /// bits: the cells of a sweep over initial states share them rather than each compiling the
    /// same code again.
    last: LastCompiled<Arc<Compiled>>,
    last_world: LastCompiled<World>,
}

/// The last thing compiled for some parameter values, kept for the next run with the same.
#[derive(Debug)]
struct LastCompiled<T>(Mutex<Option<(Vec<u64>, T)>>);

impl<T: Clone> LastCompiled<T> {
    fn new() -> Self {
        LastCompiled(Mutex::new(None))
    }

    /// The value kept for `values`, or the one `compile` makes, then kept. The same values
    /// compile to the same code, and a value is stored whole, so a poisoned lock holds a valid
    /// one.
    fn get<E>(&self, values: &[f64], compile: impl FnOnce() -> Result<T, E>) -> Result<T, E> {
        let key: Vec<u64> = values.iter().map(|v| v.to_bits()).collect();
        let kept = self
            .lock()
            .as_ref()
            .filter(|(k, _)| *k == key)
            .map(|(_, v)| v.clone());
        if let Some(value) = kept {
            return Ok(value);
        }
        let value = compile()?;
        *self.lock() = Some((key, value.clone()));
        Ok(value)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Option<(Vec<u64>, T)>> {
        self.0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// The time of a driven definition as extended phase space sees it: t a coordinate after the
/// definition's own (its slot `t`, the name `t` in expressions) and p_t a momentum after theirs
/// (`p_t`, used by no expression: H̃ = H + p_t, so ∂H̃/∂p_t = 1 and ∂H̃/∂t = ∂H/∂t).
#[derive(Clone, Copy, Debug)]
struct Clock {
    t: Var,
    p_t: Var,
}

/// A parse or derivative error of the expression at `field`.
fn expression(field: &Field) -> impl Fn(ExprError) -> CoreError + '_ {
    move |error| CoreError::Expression {
        field: field.clone(),
        error,
    }
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
        let mut scope = NameScope::new();
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
        // The time `t`, after every declared name (so the slots above are the same with or
        // without it), unless the definition names something `t` itself.
        let time = scope.declare("t").ok();
        let clock = time
            .filter(|&t| uses(&definition, &scope, t))
            .map(|t| Clock {
                t,
                p_t: Var(t.0 + 1),
            });
        let with_t = |vars: &[&[Var]]| {
            let mut all = vars.concat();
            all.extend(clock.map(|c| c.t));
            all
        };
        let in_q = scope.restricted_to(&with_t(&[&q, &params]));
        let in_qp = scope.restricted_to(&with_t(&[&q, &p, &params]));
        let in_params = scope.restricted_to(&params);
        // The coordinates and momenta methods see: with the clock and its momentum last.
        let q_ext: Vec<Var> = q.iter().copied().chain(clock.map(|c| c.t)).collect();
        let p_ext: Vec<Var> = p.iter().copied().chain(clock.map(|c| c.p_t)).collect();

        let mut graph = Graph::new();
        let coordinate_nodes: Vec<NodeId> = q.iter().map(|&v| graph.var(v)).collect();
        let parse = |e: &Expression, scope: &NameScope, graph: &mut Graph| {
            graph.parse(&e.text, scope).map_err(expression(&e.field))
        };
        let energy = match &definition.energy {
            Energy::Separable { mass, potential } => {
                let v = parse(potential, &in_q, &mut graph)?;
                let gradient = graph
                    .gradient(v, &q_ext)
                    .map_err(expression(&potential.field))?;
                let hessian = graph
                    .hessian(v, &q_ext)
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
                // H̃ = H + p_t in extended phase space; H itself otherwise.
                let extended = match clock {
                    Some(c) => {
                        let p_t = graph.var(c.p_t);
                        graph.add(h, p_t)
                    }
                    None => h,
                };
                let dq = graph.gradient(extended, &q_ext).map_err(&err)?;
                let dp = graph.gradient(extended, &p_ext).map_err(&err)?;
                let hqq = graph.jacobian(&dq, &q_ext).map_err(&err)?.concat();
                let hqp = graph.jacobian(&dq, &p_ext).map_err(&err)?.concat();
                let hpp = graph.jacobian(&dp, &p_ext).map_err(&err)?.concat();
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
        // Positions are drawn from the coordinates alone.
        let in_q_only = scope.restricted_to(&[q.as_slice(), &params].concat());
        let positions = match &definition.positions {
            None => None,
            Some(bodies) => Some(position_nodes(bodies, &at.key("positions"), &mut |e| {
                parse(e, &in_q_only, &mut graph)
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
            clock,
            at_defaults: (
                Structure {
                    separable_constant_mass: false,
                    conformal_damping: false,
                },
                0.0,
                DampingKind::None,
            ),
            last: LastCompiled::new(),
            last_world: LastCompiled::new(),
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
        model.at_defaults = (
            model.structure(&numbers),
            numbers.damping.rate(),
            numbers.damping.kind(),
        );
        Ok(model)
    }

    /// The definition.
    pub fn definition(&self) -> &CustomDefinition {
        &self.definition
    }

    /// Degrees of freedom.
    pub fn dimension(&self) -> usize {
        self.n
    }

    /// The structure and damping rate at the default parameter values: what the methods'
    /// requirements are checked against ([`super::facts`] lists the methods that apply).
    pub fn structure_at_defaults(&self) -> (Structure, f64) {
        (self.at_defaults.0, self.at_defaults.1)
    }

    /// The damping's form at the default parameter values.
    pub fn damping_kind(&self) -> DampingKind {
        self.at_defaults.2
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

    /// Whether the energy or the damping depends on the time `t`.
    pub fn time_dependent(&self) -> bool {
        self.clock.is_some()
    }

    /// The values of every slot for parameters `values`, with q and p (and t, p_t) at zero.
    fn slots(&self, values: &[f64]) -> Vec<f64> {
        let mut slots = vec![0.0; 2 * self.n];
        slots.extend_from_slice(values);
        if self.clock.is_some() {
            slots.extend([0.0, 0.0]);
        }
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

    /// The parameter values of a run, in declaration order.
    fn values(&self, params: &ParamValues) -> Vec<f64> {
        self.definition
            .parameters
            .iter()
            .map(|(name, default)| params.get(name).unwrap_or(*default))
            .collect()
    }
}

/// The numbers a run's parameters fix.
struct Numbers {
    /// The mass matrix (row-major) and its Cholesky factor, for a separable H.
    mass: Option<(Vec<f64>, MassFactor)>,
    damping: DampingModel,
}
