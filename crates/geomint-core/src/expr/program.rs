//! The linear register program both back ends run, and the interpreter.
//!
//! [`Program::build`] lowers the DAG of a set of outputs into straight-line code:
//! only nodes the outputs need are emitted (dead code never appears), each distinct
//! computation once (value numbering catches what hash-consing could not see, such as
//! the `x*x` inside both `x^2` and `x^3`), `x^n` expanded into the multiplications of
//! [`ops::powi`](crate::expr::ops::powi), and registers reused once a value is dead, so the
//! interpreter's register file stays small. Outputs are stored as soon as they are
//! computed.
//!
//! The interpreter executes that program with the [`ops`](crate::expr::ops) functions; the JIT
//! translates the very same instructions, which is why the two agree bit for bit.

use std::cell::RefCell;
use std::collections::HashMap;

use crate::expr::graph::{Graph, Node, NodeId};
use crate::expr::ops::{entry, BinaryOp, UnaryOp};
use crate::expr::{ExprError, Var};

/// A register index.
pub type Reg = u32;

/// One instruction. `dst` is always written after all operands are read, so it may be
/// one of them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Instr {
    /// `dst = inputs[input]`
    Load {
        /// Destination register.
        dst: Reg,
        /// Index into the input slice.
        input: u32,
    },
    /// `dst = value`
    Const {
        /// Destination register.
        dst: Reg,
        /// The constant.
        value: f64,
    },
    /// `dst = op(a)`
    Unary {
        /// The operation.
        op: UnaryOp,
        /// Destination register.
        dst: Reg,
        /// Operand register.
        a: Reg,
    },
    /// `dst = op(a, b)`
    Binary {
        /// The operation.
        op: BinaryOp,
        /// Destination register.
        dst: Reg,
        /// First operand register.
        a: Reg,
        /// Second operand register.
        b: Reg,
    },
    /// `outputs[output] = src`
    Store {
        /// Source register.
        src: Reg,
        /// Index into the output slice.
        output: u32,
    },
}

/// A straight-line program from a slice of inputs to a slice of outputs.
#[derive(Debug, Clone)]
pub struct Program {
    instrs: Vec<Instr>,
    /// The same instructions in the interpreter's form.
    steps: Vec<Step>,
    inputs: usize,
    outputs: usize,
    registers: usize,
}

/// An instruction as the interpreter runs it: one flat `match` per instruction, and the
/// called operations as the same `extern "C"` entry points the JIT calls.
#[derive(Debug, Clone, Copy)]
enum Step {
    Load(u32, u32),
    Const(u32, f64),
    Add(u32, u32, u32),
    Sub(u32, u32, u32),
    Mul(u32, u32, u32),
    Div(u32, u32, u32),
    Neg(u32, u32),
    Sqrt(u32, u32),
    Abs(u32, u32),
    Call1(u32, u32, extern "C" fn(f64) -> f64),
    Call2(u32, u32, u32, extern "C" fn(f64, f64) -> f64),
    Store(u32, u32),
}

impl Step {
    fn new(instr: Instr) -> Step {
        match instr {
            Instr::Load { dst, input } => Step::Load(dst, input),
            Instr::Const { dst, value } => Step::Const(dst, value),
            Instr::Unary { op, dst, a } => match op {
                UnaryOp::Neg => Step::Neg(dst, a),
                UnaryOp::Sqrt => Step::Sqrt(dst, a),
                UnaryOp::Abs => Step::Abs(dst, a),
                _ => Step::Call1(dst, a, entry::unary(op)),
            },
            Instr::Binary { op, dst, a, b } => match op {
                BinaryOp::Add => Step::Add(dst, a, b),
                BinaryOp::Sub => Step::Sub(dst, a, b),
                BinaryOp::Mul => Step::Mul(dst, a, b),
                BinaryOp::Div => Step::Div(dst, a, b),
                _ => Step::Call2(dst, a, b, entry::binary(op)),
            },
            Instr::Store { src, output } => Step::Store(src, output),
        }
    }
}

/// A value in SSA form while building: the operation and the values it reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Op {
    Load(u32),
    Const(u64),
    Unary(UnaryOp, usize),
    Binary(BinaryOp, usize, usize),
}

impl Op {
    fn operands(self) -> impl Iterator<Item = usize> {
        let (first, second) = match self {
            Op::Load(_) | Op::Const(_) => (None, None),
            Op::Unary(_, a) => (Some(a), None),
            Op::Binary(_, a, b) => (Some(a), Some(b)),
        };
        first.into_iter().chain(second)
    }
}

/// Value numbering: each distinct operation gets one SSA value.
struct ValueNumbering {
    ops: Vec<Op>,
    numbering: HashMap<Op, usize>,
    limit: usize,
}

impl ValueNumbering {
    fn value(&mut self, op: Op) -> Result<usize, ExprError> {
        let op = match op {
            Op::Binary(o, a, b) if o.is_commutative() && b < a => Op::Binary(o, b, a),
            other => other,
        };
        if let Some(&value) = self.numbering.get(&op) {
            return Ok(value);
        }
        if self.ops.len() >= self.limit {
            return Err(ExprError::ProgramTooLarge { limit: self.limit });
        }
        self.ops.push(op);
        self.numbering.insert(op, self.ops.len() - 1);
        Ok(self.ops.len() - 1)
    }

    fn binary(&mut self, op: BinaryOp, a: usize, b: usize) -> Result<usize, ExprError> {
        self.value(Op::Binary(op, a, b))
    }

    /// `x^n` with exactly the multiplications of [`ops::powi`].
    fn powi(&mut self, x: usize, n: i32) -> Result<usize, ExprError> {
        if n == 0 {
            return self.value(Op::Const(1.0f64.to_bits()));
        }
        let mut remaining = n.unsigned_abs();
        let mut base = x;
        let mut acc: Option<usize> = None;
        let positive = loop {
            if remaining & 1 == 1 {
                acc = Some(match acc {
                    None => base,
                    Some(a) => self.binary(BinaryOp::Mul, a, base)?,
                });
            }
            remaining >>= 1;
            if remaining == 0 {
                break acc.unwrap_or(base);
            }
            base = self.binary(BinaryOp::Mul, base, base)?;
        };
        if n < 0 {
            let one = self.value(Op::Const(1.0f64.to_bits()))?;
            self.binary(BinaryOp::Div, one, positive)
        } else {
            Ok(positive)
        }
    }
}

impl Program {
    /// Lowers `outputs` of `graph` to a program reading `inputs[i]` for variable
    /// `layout[i]`. Fails if an output needs a variable not in `layout`, or if the program
    /// would exceed `max_len` values.
    pub fn build(
        graph: &Graph,
        outputs: &[NodeId],
        layout: &[Var],
        max_len: usize,
    ) -> Result<Program, ExprError> {
        let slot: HashMap<Var, u32> = (0..layout.len() as u32)
            .map(|i| (layout[i as usize], i))
            .collect();
        let mut builder = ValueNumbering {
            ops: Vec::new(),
            numbering: HashMap::new(),
            limit: max_len,
        };
        let marked = graph.reachable(outputs);
        let mut value_of = vec![usize::MAX; marked.len()];
        for (index, _) in marked.iter().enumerate().filter(|(_, m)| **m) {
            let v = |id: NodeId| value_of[id.index()];
            value_of[index] = match graph.node(NodeId(index as u32)) {
                Node::Const(c) => builder.value(Op::Const(c.to_bits()))?,
                Node::Var(var) => match slot.get(&var) {
                    Some(&input) => builder.value(Op::Load(input))?,
                    None => return Err(ExprError::UnboundVariable { var: var.0 }),
                },
                Node::Unary(op, a) => builder.value(Op::Unary(op, v(a)))?,
                Node::Binary(op, a, b) => builder.binary(op, v(a), v(b))?,
                Node::PowI(a, n) => builder.powi(v(a), n)?,
            };
        }
        let output_values: Vec<usize> = outputs.iter().map(|o| value_of[o.index()]).collect();
        Ok(allocate(&builder.ops, &output_values, layout.len()))
    }

    /// The instructions.
    pub fn instrs(&self) -> &[Instr] {
        &self.instrs
    }

    /// The number of inputs the program reads.
    pub fn inputs(&self) -> usize {
        self.inputs
    }

    /// The number of outputs the program writes.
    pub fn outputs(&self) -> usize {
        self.outputs
    }

    /// The number of registers the interpreter needs.
    pub fn registers(&self) -> usize {
        self.registers
    }

    /// Whether the program calls an operation (`sin`, `exp`, `pow`, …) instead of computing
    /// with arithmetic instructions only; native code keeps no value in a register across a
    /// call.
    pub fn makes_calls(&self) -> bool {
        self.steps
            .iter()
            .any(|s| matches!(s, Step::Call1(..) | Step::Call2(..)))
    }

    /// The number of instructions that compute something (loads, constants and
    /// operations; not stores).
    pub fn operation_count(&self) -> usize {
        let stores = self
            .instrs
            .iter()
            .filter(|i| matches!(i, Instr::Store { .. }));
        self.instrs.len() - stores.count()
    }

    /// Runs the program in the interpreter.
    ///
    /// # Panics
    /// If `inputs` or `outputs` do not have the lengths the program was built for.
    pub fn run(&self, inputs: &[f64], outputs: &mut [f64]) {
        assert_eq!(inputs.len(), self.inputs, "wrong number of inputs");
        assert_eq!(outputs.len(), self.outputs, "wrong number of outputs");
        // A register file on the stack for the usual small programs, so evaluation does
        // not allocate; a per-thread buffer, grown once, for large ones.
        match self.registers {
            0..=16 => self.execute(inputs, outputs, &mut [0.0; 16]),
            17..=64 => self.execute(inputs, outputs, &mut [0.0; 64]),
            65..=256 => self.execute(inputs, outputs, &mut [0.0; 256]),
            n => SCRATCH.with(|scratch| match scratch.try_borrow_mut() {
                Ok(mut registers) => {
                    if registers.len() < n {
                        registers.resize(n, 0.0);
                    }
                    self.execute(inputs, outputs, &mut registers)
                }
                Err(_) => self.execute(inputs, outputs, &mut vec![0.0; n]),
            }),
        }
    }

    fn execute(&self, inputs: &[f64], outputs: &mut [f64], r: &mut [f64]) {
        let u = |index: u32| index as usize;
        for step in &self.steps {
            match *step {
                Step::Load(dst, input) => r[u(dst)] = inputs[u(input)],
                Step::Const(dst, value) => r[u(dst)] = value,
                Step::Add(dst, a, b) => r[u(dst)] = r[u(a)] + r[u(b)],
                Step::Sub(dst, a, b) => r[u(dst)] = r[u(a)] - r[u(b)],
                Step::Mul(dst, a, b) => r[u(dst)] = r[u(a)] * r[u(b)],
                Step::Div(dst, a, b) => r[u(dst)] = r[u(a)] / r[u(b)],
                Step::Neg(dst, a) => r[u(dst)] = -r[u(a)],
                Step::Sqrt(dst, a) => r[u(dst)] = r[u(a)].sqrt(),
                Step::Abs(dst, a) => r[u(dst)] = r[u(a)].abs(),
                Step::Call1(dst, a, f) => r[u(dst)] = f(r[u(a)]),
                Step::Call2(dst, a, b, f) => r[u(dst)] = f(r[u(a)], r[u(b)]),
                Step::Store(src, output) => outputs[u(output)] = r[u(src)],
            }
        }
    }
}

thread_local! {
    static SCRATCH: RefCell<Vec<f64>> = const { RefCell::new(Vec::new()) };
}

/// Assigns registers to SSA values, reusing a register once its value is dead, and
/// places each output's store right after its value is computed.
fn allocate(ops: &[Op], outputs: &[usize], inputs: usize) -> Program {
    let mut last_use = vec![None; ops.len()];
    for (index, op) in ops.iter().enumerate() {
        for operand in op.operands() {
            last_use[operand] = Some(index);
        }
    }
    let mut stores: Vec<Vec<u32>> = vec![Vec::new(); ops.len()];
    for (output, &value) in outputs.iter().enumerate() {
        stores[value].push(output as u32);
    }
    let mut register = vec![0 as Reg; ops.len()];
    let mut free: Vec<Reg> = Vec::new();
    let mut registers = 0;
    let mut instrs = Vec::with_capacity(ops.len() + outputs.len());
    for (index, op) in ops.iter().enumerate() {
        // Operands whose last reader is this op free their registers before the
        // destination is chosen, so `dst` may reuse one of them.
        let mut operands = op.operands().collect::<Vec<_>>();
        operands.dedup();
        for &operand in &operands {
            if last_use[operand] == Some(index) {
                free.push(register[operand]);
            }
        }
        let dst = free.pop().unwrap_or_else(|| {
            registers += 1;
            registers - 1
        });
        register[index] = dst;
        let reg = |value: usize| register[value];
        instrs.push(match *op {
            Op::Load(input) => Instr::Load { dst, input },
            Op::Const(bits) => Instr::Const {
                dst,
                value: f64::from_bits(bits),
            },
            Op::Unary(op, a) => Instr::Unary { op, dst, a: reg(a) },
            Op::Binary(op, a, b) => Instr::Binary {
                op,
                dst,
                a: reg(a),
                b: reg(b),
            },
        });
        for &output in &stores[index] {
            instrs.push(Instr::Store { src: dst, output });
        }
        if last_use[index].is_none() {
            free.push(dst);
        }
    }
    Program {
        steps: instrs.iter().copied().map(Step::new).collect(),
        instrs,
        inputs,
        outputs: outputs.len(),
        registers: registers as usize,
    }
}
