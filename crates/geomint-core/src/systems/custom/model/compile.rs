//! A model's compilation for a run's parameter values: its functions as machine code, the
//! last compilation kept for the next run with the same values (the cells of a sweep over
//! initial states), and the drawing of its bodies.

use std::sync::Arc;

use super::{expression, CustomModel, DampingNodes, EnergyNodes, Numbers};
use crate::error::{CoreError, Field};
use crate::expr::{CompileOptions, CompiledFunction, NodeId, Var};
use crate::systems::custom::system::{Compiled, CustomSystem, EnergyModel};
use crate::systems::world::Drawing;
use crate::systems::{AnySystem, ParamValues, World};

impl CustomModel {
    /// Compiles `outputs` for a run: inputs q (and p with `with_momenta`), parameters folded.
    /// For a driven definition the inputs are those of extended phase space, (q, t) and
    /// (q, t, p, p_t), unless `positions` asks for the coordinates alone.
    fn compile(
        &self,
        outputs: &[NodeId],
        with_momenta: bool,
        values: &[f64],
    ) -> Result<CompiledFunction, CoreError> {
        self.compile_with(outputs, with_momenta, self.clock.is_some(), values)
    }

    fn compile_with(
        &self,
        outputs: &[NodeId],
        with_momenta: bool,
        with_clock: bool,
        values: &[f64],
    ) -> Result<CompiledFunction, CoreError> {
        let n = self.n;
        let inputs = if with_momenta { 2 * n } else { n };
        let mut layout: Vec<Var> = (0..n as u32).map(Var).collect();
        let mut constants: Vec<(Var, f64)> = values
            .iter()
            .enumerate()
            .map(|(i, &v)| (Var((2 * n + i) as u32), v))
            .chain((inputs..2 * n).map(|i| (Var(i as u32), 0.0)))
            .collect();
        match self.clock {
            Some(c) if with_clock => {
                layout.push(c.t);
                if with_momenta {
                    layout.extend((n as u32..2 * n as u32).map(Var));
                    layout.push(c.p_t);
                } else {
                    constants.push((c.p_t, 0.0));
                }
            }
            _ => {
                if with_momenta {
                    layout.extend((n as u32..2 * n as u32).map(Var));
                }
                if let Some(c) = self.clock {
                    constants.extend([(c.t, 0.0), (c.p_t, 0.0)]);
                }
            }
        }
        let options = CompileOptions {
            layout,
            constants,
            ..CompileOptions::default()
        };
        CompiledFunction::new(&self.graph, outputs, &options)
            .map_err(expression(&self.definition.field))
    }

    /// The system for a run with parameters `params`, compiled.
    pub fn instantiate(&self, params: &ParamValues) -> Result<AnySystem, CoreError> {
        let values = self.values(params);
        let numbers = self.numbers(&values, &Field::new("params"))?;
        let compiled = self
            .last
            .get(&values, || self.compile_system(&values, numbers))?;
        Ok(match compiled.n {
            1 => AnySystem::Custom1(CustomSystem::new(nalgebra::U1, compiled)),
            2 => AnySystem::Custom2(CustomSystem::new(nalgebra::U2, compiled)),
            3 => AnySystem::Custom3(CustomSystem::new(nalgebra::U3, compiled)),
            n => AnySystem::CustomN(CustomSystem::new(nalgebra::Dyn(n), compiled)),
        })
    }

    /// The system's functions compiled for parameter values `values`, which fix `numbers`.
    fn compile_system(&self, values: &[f64], numbers: Numbers) -> Result<Arc<Compiled>, CoreError> {
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
                    self.compile(&[*potential], false, values)?,
                    self.compile(gradient, false, values)?,
                    self.compile(hessian, false, values)?,
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
                hamiltonian: self.compile(&[*hamiltonian], true, values)?,
                dq: self.compile(dq, true, values)?,
                dp: self.compile(dp, true, values)?,
                second: self.compile(second, true, values)?,
            },
        };
        let damping_matrix = match &self.damping {
            DampingNodes::Rayleigh { matrix, .. } => Some(self.compile(matrix, false, values)?),
            _ => None,
        };
        let damping_derivative = self
            .damping_derivative
            .as_ref()
            .and_then(|nodes| self.compile(nodes, false, values).ok());
        let invariants = if self.invariants.is_empty() {
            None
        } else {
            Some(self.compile(&self.invariants, true, values)?)
        };
        Ok(Arc::new(Compiled {
            n: self.n + usize::from(self.clock.is_some()),
            clock: self.clock.map(|_| self.n),
            structure,
            energy,
            damping: numbers.damping,
            damping_matrix,
            damping_derivative,
            invariants,
            lane_forces: Default::default(),
            compiled_steps: Default::default(),
        }))
    }

    /// How the system appears in space for parameters `params`: its `positions`, or without
    /// them its first one to three coordinates.
    pub fn world(&self, params: &ParamValues) -> Result<World, CoreError> {
        let values = self.values(params);
        self.last_world.get(&values, || {
            let (dims, nodes) = match &self.positions {
                Some((dims, nodes)) => (*dims, nodes.clone()),
                None => {
                    let shown = &self.coordinate_nodes[..self.n.min(3)];
                    (shown.len().max(2), shown.to_vec())
                }
            };
            let function = self.compile_with(&nodes, false, false, &values)?;
            Ok(World::Drawn(Arc::new(Drawing::new(function, dims))))
        })
    }
}
