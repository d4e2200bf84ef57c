//! The kernel's numbers as values of a function being compiled with Cranelift: a [`Jit`] value's
//! arithmetic writes the instruction that computes it (`fadd`, `fsub`, `fmul`, `fdiv`, `fneg`)
//! into the function, so the kernel's flows, run over `Jit` values, write the code of the flow
//! with exactly the operations, in exactly the order, that they do on an `f64` — and the code
//! gives the same bits. The values may be scalars or vectors of f64 lanes: the instructions
//! are the same.

use std::cell::RefCell;
use std::ops::{Add, Div, Mul, Neg, Sub};

use cranelift_codegen::ir::{InstBuilder, Value};
use cranelift_frontend::FunctionBuilder;

/// What a [`Jit`] value's operations need of the function builder.
pub(crate) trait Instructions {
    /// `a op b`.
    fn binary(&mut self, op: Binary, a: Value, b: Value) -> Value;
    /// `−a`.
    fn negate(&mut self, a: Value) -> Value;
}

/// The four binary operations of [`Real`](super::Real).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Binary {
    Add,
    Sub,
    Mul,
    Div,
}

impl Instructions for FunctionBuilder<'_> {
    fn binary(&mut self, op: Binary, a: Value, b: Value) -> Value {
        match op {
            Binary::Add => self.ins().fadd(a, b),
            Binary::Sub => self.ins().fsub(a, b),
            Binary::Mul => self.ins().fmul(a, b),
            Binary::Div => self.ins().fdiv(a, b),
        }
    }

    fn negate(&mut self, a: Value) -> Value {
        self.ins().fneg(a)
    }
}

/// The builder the values of one kernel call write into.
pub(crate) type Writer<'c> = RefCell<&'c mut dyn Instructions>;

/// A value of the function being built, whose arithmetic writes its instructions.
#[derive(Clone, Copy)]
pub(crate) struct Jit<'c> {
    /// The value in the function.
    pub(crate) value: Value,
    writer: &'c Writer<'c>,
}

impl<'c> Jit<'c> {
    /// `value` of the function `writer` builds.
    pub(crate) fn new(value: Value, writer: &'c Writer<'c>) -> Self {
        Jit { value, writer }
    }

    fn apply(self, op: Binary, other: Jit<'c>) -> Jit<'c> {
        let value = self.writer.borrow_mut().binary(op, self.value, other.value);
        Jit::new(value, self.writer)
    }
}

/// Runs `f` with a writer into `b`: the kernel's flows run on `Jit` values made with it.
pub(crate) fn write<R>(
    b: &mut FunctionBuilder<'_>,
    f: impl for<'c> FnOnce(&'c Writer<'c>) -> R,
) -> R {
    let writer: Writer<'_> = RefCell::new(b);
    f(&writer)
}

/// `values` as the kernel's numbers, written by `writer`.
pub(crate) fn values<'c>(values: &[Value], writer: &'c Writer<'c>) -> Vec<Jit<'c>> {
    values.iter().map(|&v| Jit::new(v, writer)).collect()
}

/// The values of the function behind kernel numbers.
pub(crate) fn of(values: &[Jit<'_>]) -> Vec<Value> {
    values.iter().map(|v| v.value).collect()
}

macro_rules! binary {
    ($($op:ident $method:ident),*) => {$(
        impl<'c> $op for Jit<'c> {
            type Output = Jit<'c>;
            fn $method(self, other: Jit<'c>) -> Jit<'c> {
                self.apply(Binary::$op, other)
            }
        }
    )*};
}

binary!(Add add, Sub sub, Mul mul, Div div);

impl<'c> Neg for Jit<'c> {
    type Output = Jit<'c>;
    fn neg(self) -> Jit<'c> {
        let value = self.writer.borrow_mut().negate(self.value);
        Jit::new(value, self.writer)
    }
}
