//! A surface S(q, p, t) compiled for a run: the expression parsed against the run's names (its
//! errors carry the field and the character, as a definition's do), its exact gradient taken by
//! the expression engine, the parameters folded in; or the clock t of a stroboscopic section.
//! [`Crossings`] holds a simulation's section and event surfaces.

use super::names::StateNames;
use super::spec::{Direction, EventSpec, SectionSpec, SurfaceSpec};
use crate::error::{CoreError, Field};
use crate::expr::{CompileOptions, CompiledFunction, Graph, NameScope, Var};

/// A surface, compiled.
#[derive(Debug)]
pub enum Surface {
    /// S(q, p, t) = 0.
    Expression {
        /// The text, as given.
        text: String,
        /// S alone, of (q, p, t).
        value: CompiledFunction,
        /// S, ∂S/∂q, ∂S/∂p and ∂S/∂t, of (q, p, t), in one pass.
        gradient: CompiledFunction,
        /// Degrees of freedom.
        n: usize,
        /// For S a coordinate or a momentum alone, its index in (q, p): S and σ are then read
        /// off the state and its velocity, the numbers the compiled functions give (σ sums
        /// zeros and one product by 1).
        component: Option<usize>,
    },
    /// S = t, crossed at its levels φ + kT.
    Clock {
        /// T.
        period: f64,
        /// φ.
        phase: f64,
    },
}

impl Surface {
    /// Compiles the expression `text` (at `field`) against `names`.
    pub fn expression(text: &str, names: &StateNames, field: &Field) -> Result<Surface, CoreError> {
        let n = names.coordinates.len();
        let error = |error| CoreError::Expression {
            field: field.clone(),
            error,
        };
        let mut scope = NameScope::new();
        for name in names
            .coordinates
            .iter()
            .chain(&names.momenta)
            .chain(names.params.iter().map(|(name, _)| name))
        {
            scope.declare(name).map_err(error)?;
        }
        let time = match &names.time {
            Some(t) => scope.declare(t).map_err(error)?,
            // No name for it: a slot no expression can reach.
            None => Var(scope.len() as u32),
        };
        let mut graph = Graph::new();
        let s = graph.parse(text, &scope).map_err(error)?;
        let state: Vec<Var> = (0..2 * n as u32).map(Var).chain([time]).collect();
        let gradient = graph.gradient(s, &state).map_err(error)?;
        let options = CompileOptions {
            layout: state,
            constants: names
                .params
                .iter()
                .enumerate()
                .map(|(i, (_, v))| (Var((2 * n + i) as u32), *v))
                .collect(),
            ..CompileOptions::default()
        };
        let compile =
            |outputs: &[_]| CompiledFunction::new(&graph, outputs, &options).map_err(error);
        let component = names
            .find(text.trim())
            .map(|(momentum, i)| if momentum { n + i } else { i });
        Ok(Surface::Expression {
            text: text.to_string(),
            value: compile(&[s])?,
            gradient: compile(&[[s].as_slice(), &gradient].concat())?,
            n,
            component,
        })
    }

    /// Whether `other` is the same expression (so of the same values everywhere): a clock is
    /// never taken for another.
    pub fn same_as(&self, other: &Surface) -> bool {
        match (self, other) {
            (Surface::Expression { text: a, .. }, Surface::Expression { text: b, .. }) => a == b,
            _ => false,
        }
    }

    /// S at (q, p, t), with `inputs` a buffer of 2n + 1 numbers.
    #[inline]
    pub fn value(&self, q: &[f64], p: &[f64], t: f64, inputs: &mut [f64]) -> f64 {
        match self {
            Surface::Expression {
                component: Some(i),
                n,
                ..
            } => component(q, p, *i, *n),
            Surface::Expression { value, n, .. } => evaluate(value, q, p, t, inputs, *n),
            Surface::Clock { .. } => t,
        }
    }

    /// S at the (q, p, t) already in `inputs` ([`Surface::load`] put them there): several
    /// surfaces looked at in one state load it once. The same number as [`Surface::value`].
    #[inline]
    pub fn value_loaded(&self, inputs: &[f64], t: f64) -> f64 {
        match self {
            Surface::Expression {
                component: Some(i), ..
            } => inputs[*i],
            Surface::Expression { value, .. } => {
                let mut s = [0.0];
                value.eval(inputs, &mut s);
                s[0]
            }
            Surface::Clock { .. } => t,
        }
    }

    /// (q, p, t) of `n` degrees of freedom into the inputs of [`Surface::value_loaded`] (2n + 1
    /// numbers).
    #[inline]
    pub fn load(inputs: &mut [f64], q: &[f64], p: &[f64], t: f64, n: usize) {
        load(inputs, q, p, t, n);
    }

    /// S and σ = ∇_q S·q' + ∇_p S·p' + ∂S/∂t at (q, p, t) for the velocity (q', p'); `inputs`
    /// holds 2n + 1 numbers and `outputs` 2n + 2.
    #[inline]
    pub fn rate(
        &self,
        (q, p, t): (&[f64], &[f64], f64),
        (dq, dp): (&[f64], &[f64]),
        inputs: &mut [f64],
        outputs: &mut [f64],
    ) -> (f64, f64) {
        match self {
            Surface::Expression {
                component: Some(i),
                n,
                ..
            } => (component(q, p, *i, *n), component(dq, dp, *i, *n)),
            Surface::Expression { gradient, n, .. } => {
                let n = *n;
                load(inputs, q, p, t, n);
                gradient.eval(inputs, outputs);
                let mut sigma = outputs[2 * n + 1];
                for i in 0..n {
                    sigma += outputs[1 + i] * dq[i] + outputs[1 + n + i] * dp[i];
                }
                (outputs[0], sigma)
            }
            Surface::Clock { .. } => (t, 1.0),
        }
    }

    /// The buffers [`value`](Self::value) and [`rate`](Self::rate) need: inputs, outputs.
    pub fn buffers(n: usize) -> (Vec<f64>, Vec<f64>) {
        (vec![0.0; 2 * n + 1], vec![0.0; 2 * n + 2])
    }
}

/// S through its compiled function: out of line, so that [`Surface::value`]'s other cases,
/// asked at every step of a watched run, inline into the watch.
#[inline(never)]
fn evaluate(
    value: &CompiledFunction,
    q: &[f64],
    p: &[f64],
    t: f64,
    inputs: &mut [f64],
    n: usize,
) -> f64 {
    load(inputs, q, p, t, n);
    let mut s = [0.0];
    value.eval(inputs, &mut s);
    s[0]
}

/// The `i`-th number of (q, p), with `n` degrees of freedom.
#[inline]
fn component(q: &[f64], p: &[f64], i: usize, n: usize) -> f64 {
    if i < n {
        q[i]
    } else {
        p[i - n]
    }
}

/// (q, p, t) into the compiled functions' input layout.
#[inline]
fn load(inputs: &mut [f64], q: &[f64], p: &[f64], t: f64, n: usize) {
    inputs[..n].copy_from_slice(&q[..n]);
    inputs[n..2 * n].copy_from_slice(&p[..n]);
    inputs[2 * n] = t;
}

/// A simulation's surfaces: its section (with its direction and most points) and its event.
#[derive(Debug)]
pub struct Crossings {
    /// The section's surface, direction (none for a stroboscopic one) and most points.
    pub section: Option<(Surface, Direction, u64)>,
    /// The event's surface, direction and the crossing that ends the run.
    pub event: Option<(Surface, Direction, u64)>,
    /// The names expressions use (and section points are reported in).
    pub names: StateNames,
}

impl Crossings {
    /// Checks and compiles `section` and `event` against `names`.
    pub fn new(
        section: Option<&SectionSpec>,
        event: Option<&EventSpec>,
        names: StateNames,
    ) -> Result<Crossings, CoreError> {
        let section = match section {
            None => None,
            Some(spec) => {
                spec.check()?;
                Some(match &spec.surface {
                    SurfaceSpec::Where { text, direction } => (
                        Surface::expression(text, &names, &spec.field.key("where"))?,
                        *direction,
                        spec.max_points,
                    ),
                    SurfaceSpec::Stroboscopic { period, phase } => (
                        // The times t ≡ φ (mod T): φ taken into [0, T).
                        Surface::Clock {
                            period: *period,
                            phase: phase.rem_euclid(*period),
                        },
                        Direction::Up,
                        spec.max_points,
                    ),
                })
            }
        };
        let event = match event {
            None => None,
            Some(spec) => {
                spec.check()?;
                Some((
                    Surface::expression(&spec.text, &names, &spec.field.key("where"))?,
                    spec.direction,
                    spec.count,
                ))
            }
        };
        Ok(Crossings {
            section,
            event,
            names,
        })
    }
}
