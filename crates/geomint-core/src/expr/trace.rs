//! Rust code as a program: a [`Traced`] number's arithmetic adds its operation to a [`Graph`],
//! so a function written once over [`Real`](crate::flows::Real), run on traced inputs, leaves
//! the graph of what it computes, operation for operation and in its order; [`Program::build`]
//! lowers that, and the JIT compiles it. A built-in system's force is written so, and its
//! compiled steps give the bits of its `f64` force.
//!
//! The graph's builders simplify only where IEEE arithmetic gives the same result, with the
//! exceptions listed in `graph`: a product by the constant 0 is 0 and a sum with 0 is the other
//! operand, which can differ in the sign of a zero or where the other factor is not finite, and
//! `(-x) - y` is `-(x + y)`, which can differ in the sign of a zero. A function whose constants
//! may be 0, or which subtracts from a negated value, is not traced with them (Hénon–Heiles's
//! force does neither for λ ≠ 0).

use std::cell::RefCell;
use std::ops::{Add, Div, Mul, Neg, Sub};

use crate::expr::graph::{Graph, NodeId};
use crate::expr::program::Program;
use crate::expr::{ExprError, ExprLimits, Var};

/// A value of the function being traced: a node of its graph.
#[derive(Clone, Copy)]
pub struct Traced<'g> {
    id: NodeId,
    graph: &'g RefCell<Graph>,
}

impl<'g> Traced<'g> {
    fn node(graph: &'g RefCell<Graph>, id: NodeId) -> Self {
        Traced { id, graph }
    }

    /// The constant `value`, in the same graph.
    pub fn constant(self, value: f64) -> Self {
        let id = self.graph.borrow_mut().constant(value);
        Traced::node(self.graph, id)
    }
}

macro_rules! traced {
    ($($op:ident $method:ident),*) => {$(
        impl<'g> $op for Traced<'g> {
            type Output = Traced<'g>;
            fn $method(self, other: Traced<'g>) -> Traced<'g> {
                debug_assert!(std::ptr::eq(self.graph, other.graph), "values of one trace");
                let id = self.graph.borrow_mut().$method(self.id, other.id);
                Traced::node(self.graph, id)
            }
        }
    )*};
}

traced!(Add add, Sub sub, Mul mul, Div div);

impl<'g> Neg for Traced<'g> {
    type Output = Traced<'g>;
    fn neg(self) -> Traced<'g> {
        let id = self.graph.borrow_mut().neg(self.id);
        Traced::node(self.graph, id)
    }
}

/// The program of `f` on `I` inputs (variables 0 … I − 1, read from `inputs[i]`) and its `O`
/// outputs.
pub fn program<const I: usize, const O: usize>(
    f: impl for<'g> FnOnce([Traced<'g>; I]) -> [Traced<'g>; O],
) -> Result<Program, ExprError> {
    let graph = RefCell::new(Graph::new());
    let layout: [Var; I] = std::array::from_fn(|i| Var(i as u32));
    let inputs = layout.map(|var| {
        let id = graph.borrow_mut().var(var);
        Traced::node(&graph, id)
    });
    let outputs = f(inputs).map(|output| output.id);
    let graph = graph.borrow();
    Program::build(
        &graph,
        &outputs,
        &layout,
        ExprLimits::DEFAULT.max_program_len,
    )
}
