//! Compiling outputs of a graph into a [`CompiledFunction`] that evaluates them all in one
//! pass, natively through the JIT or in the interpreter.

use std::collections::HashSet;

use crate::expr::graph::{Graph, NodeId};
use crate::expr::jit::{self, CompiledFn, JitFunction};
use crate::expr::program::Program;
use crate::expr::{ExprError, Var};

/// Which back end runs the compiled code.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Backend {
    /// The JIT where the platform supports it, else the interpreter.
    #[default]
    Auto,
    /// The JIT; compiling fails with [`ExprError::JitUnavailable`] if it cannot be used.
    Jit,
    /// The interpreter.
    Interpreter,
}

/// How to compile: what the input slice holds, which variables are baked in, and the
/// back end.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CompileOptions {
    /// `inputs[i]` at evaluation holds the value of variable `layout[i]`; for example
    /// the coordinates, then the momenta, then the parameters.
    pub layout: Vec<Var>,
    /// Variables replaced by a constant before compiling; the graph is simplified again,
    /// so the constants fold. A variable may not be both here and in `layout`.
    pub constants: Vec<(Var, f64)>,
    /// The back end.
    pub backend: Backend,
}

impl CompileOptions {
    /// Options reading all of `layout` from the input slice, with the default back end.
    pub fn with_layout(layout: impl IntoIterator<Item = Var>) -> Self {
        CompileOptions {
            layout: layout.into_iter().collect(),
            ..Self::default()
        }
    }
}

/// A compiled set of outputs: `eval(inputs, outputs)` computes them all in one pass,
/// common subexpressions once, without allocating.
///
/// It is `Send + Sync`: any number of threads may evaluate it at the same time.
#[derive(Debug)]
pub struct CompiledFunction {
    /// Copied out of `jit` so that a call reads one field.
    code: Option<CompiledFn>,
    inputs: usize,
    outputs: usize,
    program: Program,
    /// Owns the memory `code` points into; declared after `code` and never replaced.
    jit: Option<JitFunction>,
}

impl CompiledFunction {
    /// Compiles `outputs` of `graph`. Output `j` of [`CompiledFunction::eval`] is the value of
    /// `outputs[j]`.
    pub fn new(
        graph: &Graph,
        outputs: &[NodeId],
        options: &CompileOptions,
    ) -> Result<Self, ExprError> {
        let mut bound = HashSet::new();
        let bindings = options
            .layout
            .iter()
            .chain(options.constants.iter().map(|(v, _)| v));
        for var in bindings {
            if !bound.insert(*var) {
                return Err(ExprError::DuplicateBinding { var: var.0 });
            }
        }
        let constant = |var: Var| {
            let pair = options.constants.iter().find(|(v, _)| *v == var);
            pair.map(|(_, value)| *value)
        };
        let (program, roots) = if options.constants.is_empty() {
            (None, outputs.to_vec())
        } else {
            let (substituted, roots) = graph.substitute(outputs, constant);
            (Some(substituted), roots)
        };
        let source = program.as_ref().unwrap_or(graph);
        let max_len = graph.limits().max_program_len;
        let program = Program::build(source, &roots, &options.layout, max_len)?;
        let jit = match options.backend {
            Backend::Interpreter => None,
            Backend::Auto => jit::compile(&program).ok(),
            Backend::Jit => Some(
                jit::compile(&program).map_err(|reason| ExprError::JitUnavailable { reason })?,
            ),
        };
        Ok(CompiledFunction {
            code: jit.as_ref().map(JitFunction::code),
            inputs: program.inputs(),
            outputs: program.outputs(),
            program,
            jit,
        })
    }

    /// Evaluates all outputs: `inputs` in the layout given when compiling, one slot per
    /// output in `outputs`.
    ///
    /// # Panics
    /// If the slices do not have the compiled lengths (see [`CompiledFunction::try_eval`]).
    #[inline]
    pub fn eval(&self, inputs: &[f64], outputs: &mut [f64]) {
        if inputs.len() != self.inputs || outputs.len() != self.outputs {
            self.length_mismatch(inputs.len(), outputs.len());
        }
        self.run(inputs, outputs);
    }

    /// Like [`CompiledFunction::eval`], but returns an error for slices of the wrong length.
    #[inline]
    pub fn try_eval(&self, inputs: &[f64], outputs: &mut [f64]) -> Result<(), ExprError> {
        self.check_lengths(inputs.len(), outputs.len())?;
        self.run(inputs, outputs);
        Ok(())
    }

    /// Runs the code on slices whose lengths were checked.
    #[inline]
    fn run(&self, inputs: &[f64], outputs: &mut [f64]) {
        match self.code {
            // SAFETY: the callers checked that `inputs` and `outputs` have the lengths the
            // code was generated for, and `self.jit` keeps the code alive.
            Some(code) => unsafe { code(inputs.as_ptr(), outputs.as_mut_ptr()) },
            None => self.program.run(inputs, outputs),
        }
    }

    /// Evaluates with the interpreter even if native code exists (the reference the JIT
    /// is tested against).
    ///
    /// # Panics
    /// If the slices do not have the compiled lengths.
    pub fn eval_interpreted(&self, inputs: &[f64], outputs: &mut [f64]) {
        if inputs.len() != self.inputs || outputs.len() != self.outputs {
            self.length_mismatch(inputs.len(), outputs.len());
        }
        self.program.run(inputs, outputs);
    }

    #[cold]
    #[inline(never)]
    fn length_mismatch(&self, inputs: usize, outputs: usize) -> ! {
        match self.check_lengths(inputs, outputs) {
            Err(error) => panic!("{error}"),
            Ok(()) => unreachable!("called only on a mismatch"),
        }
    }

    fn check_lengths(&self, inputs: usize, outputs: usize) -> Result<(), ExprError> {
        for (which, expected, found) in [
            ("inputs", self.inputs, inputs),
            ("outputs", self.outputs, outputs),
        ] {
            if expected != found {
                return Err(ExprError::WrongSliceLength {
                    which,
                    expected,
                    found,
                });
            }
        }
        Ok(())
    }

    /// Whether native code runs `eval` (else the interpreter does).
    pub fn is_jit(&self) -> bool {
        self.jit.is_some()
    }

    /// The number of inputs `eval` expects.
    pub fn input_count(&self) -> usize {
        self.inputs
    }

    /// The number of outputs `eval` writes.
    pub fn output_count(&self) -> usize {
        self.outputs
    }

    /// The linear program behind both back ends.
    pub fn program(&self) -> &Program {
        &self.program
    }
}
