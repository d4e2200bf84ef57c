//! Symbolic derivatives on the [`Graph`]: exact, simplified, and sharing nodes.
//!
//! Each operation knows its local partial derivatives (the table in [`Graph::partial`]).
//! From that table:
//!
//! * [`Graph::derivative`] is forward mode: `d(node)/dv` for every node the target
//!   depends on, in id order, memoised per (node, variable) in the graph, so repeated
//!   calls (e.g. the columns of a Hessian) reuse earlier work.
//! * [`Graph::gradient`] is reverse mode: one sweep from the output down accumulates the
//!   adjoint of every node, so the outer part of the chain rule is built once and shared
//!   by all components. For `V = k/2*(r - l)^2` with `r = sqrt(x^2+y^2+z^2)`, the three
//!   components share `k/2*(2*(r-l))/(2*r)` and each adds one multiplication, which is
//!   what one would write by hand.
//! * [`Graph::hessian`] differentiates the gradient in forward mode (forward over
//!   reverse), filling the lower triangle and mirroring it.
//!
//! Every call is bounded: if it adds more than [`ExprLimits::max_derivative_nodes`] nodes it
//! stops, removes what it added and returns [`ExprError::DerivativeTooLarge`].
//!
//! [`ExprLimits::max_derivative_nodes`]: crate::expr::ExprLimits::max_derivative_nodes

use crate::expr::graph::{Graph, Node, NodeId};
use crate::expr::ops::{BinaryOp, UnaryOp};
use crate::expr::{ExprError, Var};

/// A local partial derivative, as what to do to an incoming derivative: multiply by a
/// node, divide by it (`d sqrt(a) = da / (2*sqrt(a))` is cheaper and more accurate than
/// `da * (1 / (2*sqrt(a)))`), or scale by a constant then multiply by a node. The last
/// is for `x^n`: `(n*adjoint) * x^(n-1)` lets the components of a gradient share
/// `n*adjoint` (in `x^2 + y^2 + z^2` the three components share `2*adjoint`, leaving
/// one multiplication each, as by hand).
#[derive(Debug, Clone, Copy)]
enum Partial {
    Times(NodeId),
    Over(NodeId),
    ScaledTimes(NodeId, NodeId),
}

impl Graph {
    /// `d f / d v`, simplified. Memoised: asking again is free.
    pub fn derivative(&mut self, f: NodeId, v: Var) -> Result<NodeId, ExprError> {
        let start = self.len();
        self.rollback_on_error(start, |g| g.forward(f, v, start))
    }

    /// The gradient of `f` with respect to `vars`, in reverse mode (see the module docs).
    pub fn gradient(&mut self, f: NodeId, vars: &[Var]) -> Result<Vec<NodeId>, ExprError> {
        let start = self.len();
        self.rollback_on_error(start, |g| g.reverse(f, vars, start))
    }

    /// The gradients of several outputs with respect to `vars`: `result[i][j]` is
    /// `d outputs[i] / d vars[j]`.
    pub fn jacobian(
        &mut self,
        outputs: &[NodeId],
        vars: &[Var],
    ) -> Result<Vec<Vec<NodeId>>, ExprError> {
        let start = self.len();
        self.rollback_on_error(start, |g| {
            outputs.iter().map(|&f| g.reverse(f, vars, start)).collect()
        })
    }

    /// The Hessian of `f` with respect to `vars`: `result[i][j]` is
    /// `d^2 f / d vars[i] d vars[j]`, symmetric (the same node for `[i][j]` and `[j][i]`).
    pub fn hessian(&mut self, f: NodeId, vars: &[Var]) -> Result<Vec<Vec<NodeId>>, ExprError> {
        let start = self.len();
        self.rollback_on_error(start, |g| {
            let gradient = g.reverse(f, vars, start)?;
            // The lower triangle, row i holding d gradient[i] / d vars[..=i].
            let mut lower: Vec<Vec<NodeId>> = Vec::with_capacity(vars.len());
            for (i, &component) in gradient.iter().enumerate() {
                let row = vars[..=i].iter().map(|&v| g.forward(component, v, start));
                lower.push(row.collect::<Result<_, _>>()?);
            }
            let entry = |i: usize, j: usize| if j <= i { lower[i][j] } else { lower[j][i] };
            let n = vars.len();
            Ok((0..n)
                .map(|i| (0..n).map(|j| entry(i, j)).collect())
                .collect())
        })
    }

    fn rollback_on_error<T>(
        &mut self,
        start: usize,
        work: impl FnOnce(&mut Self) -> Result<T, ExprError>,
    ) -> Result<T, ExprError> {
        let result = work(self);
        if result.is_err() {
            self.truncate(start);
        }
        result
    }

    fn check_growth(&self, start: usize) -> Result<(), ExprError> {
        let limit = self.limits.max_derivative_nodes;
        if self.len() - start > limit {
            return Err(ExprError::DerivativeTooLarge { limit });
        }
        Ok(())
    }

    /// Forward mode, without recursion: mark what needs a derivative, then build the
    /// derivatives in id order (operands first).
    fn forward(&mut self, f: NodeId, v: Var, start: usize) -> Result<NodeId, ExprError> {
        if let Some(&d) = self.derivatives.get(&(f, v)) {
            return Ok(d);
        }
        let end = f.index() + 1;
        let mut needed = vec![false; end];
        needed[f.index()] = true;
        for index in (0..end).rev() {
            if !needed[index] {
                continue;
            }
            let id = NodeId(index as u32);
            if self.derivatives.contains_key(&(id, v)) {
                needed[index] = false;
                continue;
            }
            for operand in self.node(id).operands() {
                needed[operand.index()] = true;
            }
        }
        let zero = self.constant(0.0);
        for index in (0..end).filter(|&i| needed[i]) {
            let id = NodeId(index as u32);
            let node = self.node(id);
            let d = match node {
                Node::Const(_) => zero,
                Node::Var(w) if w == v => self.constant(1.0),
                Node::Var(_) => zero,
                _ => {
                    let mut sum = zero;
                    for (k, operand) in node.operands().enumerate() {
                        let d_operand = self.derivatives[&(operand, v)];
                        if d_operand != zero {
                            let partial = self.partial(id, k);
                            let term = self.chain(d_operand, partial);
                            sum = self.add(sum, term);
                        }
                    }
                    sum
                }
            };
            self.derivatives.insert((id, v), d);
            self.check_growth(start)?;
        }
        Ok(self.derivatives[&(f, v)])
    }

    /// Reverse mode: accumulate adjoints from `f` down to the variables, visiting only
    /// nodes that lie between them.
    fn reverse(&mut self, f: NodeId, vars: &[Var], start: usize) -> Result<Vec<NodeId>, ExprError> {
        let end = f.index() + 1;
        let reachable = self.reachable(&[f]);
        // depends[i]: node i is reachable from f and depends on one of `vars`.
        let mut depends = vec![false; end];
        for index in 0..end {
            let node = self.node(NodeId(index as u32));
            depends[index] = reachable[index]
                && match node {
                    Node::Var(w) => vars.contains(&w),
                    _ => node.operands().any(|op| depends[op.index()]),
                };
        }
        let zero = self.constant(0.0);
        let mut adjoint: Vec<Option<NodeId>> = vec![None; end];
        if depends[f.index()] {
            adjoint[f.index()] = Some(self.constant(1.0));
        }
        for index in (0..end).rev() {
            let Some(adj) = adjoint[index].filter(|_| depends[index]) else {
                continue;
            };
            let id = NodeId(index as u32);
            let node = self.node(id);
            for (k, operand) in node.operands().enumerate() {
                if !depends[operand.index()] {
                    continue;
                }
                let partial = self.partial(id, k);
                let term = self.chain(adj, partial);
                let slot = &mut adjoint[operand.index()];
                *slot = Some(match *slot {
                    None => term,
                    Some(previous) => self.add(previous, term),
                });
            }
            self.check_growth(start)?;
        }
        let gradient = vars.iter().map(|&v| {
            let var_node = self.find_var(v).filter(|id| id.index() < end);
            var_node.and_then(|id| adjoint[id.index()]).unwrap_or(zero)
        });
        Ok(gradient.collect())
    }

    fn chain(&mut self, incoming: NodeId, partial: Partial) -> NodeId {
        match partial {
            Partial::Times(factor) => self.mul(incoming, factor),
            Partial::Over(divisor) => self.div(incoming, divisor),
            Partial::ScaledTimes(scale, factor) => {
                let scaled = self.mul(scale, incoming);
                self.mul(scaled, factor)
            }
        }
    }

    /// The partial derivative of node `id` with respect to its operand number `k`.
    fn partial(&mut self, id: NodeId, k: usize) -> Partial {
        use Partial::{Over, Times};
        let node = self.node(id);
        let one = self.constant(1.0);
        match node {
            Node::Const(_) | Node::Var(_) => unreachable!("leaves have no operands"),
            Node::Unary(op, a) => match op {
                UnaryOp::Neg => Times(self.constant(-1.0)),
                UnaryOp::Sqrt => {
                    let two = self.constant(2.0);
                    Over(self.mul(two, id))
                }
                UnaryOp::Abs => Times(self.unary(UnaryOp::Sign, a)),
                UnaryOp::Sign => Times(self.constant(0.0)),
                UnaryOp::Sin => Times(self.unary(UnaryOp::Cos, a)),
                UnaryOp::Cos => {
                    let sin = self.unary(UnaryOp::Sin, a);
                    Times(self.neg(sin))
                }
                UnaryOp::Tan => {
                    let square = self.powi(id, 2);
                    Times(self.add(one, square))
                }
                UnaryOp::Asin | UnaryOp::Acos => {
                    let square = self.powi(a, 2);
                    let difference = self.sub(one, square);
                    let root = self.unary(UnaryOp::Sqrt, difference);
                    if op == UnaryOp::Asin {
                        Over(root)
                    } else {
                        Over(self.neg(root))
                    }
                }
                UnaryOp::Atan => {
                    let square = self.powi(a, 2);
                    Over(self.add(one, square))
                }
                UnaryOp::Sinh => Times(self.unary(UnaryOp::Cosh, a)),
                UnaryOp::Cosh => Times(self.unary(UnaryOp::Sinh, a)),
                UnaryOp::Tanh => {
                    let square = self.powi(id, 2);
                    Times(self.sub(one, square))
                }
                UnaryOp::Exp => Times(id),
                UnaryOp::Log => Over(a),
            },
            Node::Binary(op, a, b) => match (op, k) {
                (BinaryOp::Add, _) | (BinaryOp::Sub, 0) => Times(one),
                (BinaryOp::Sub, _) => Times(self.constant(-1.0)),
                (BinaryOp::Mul, 0) => Times(b),
                (BinaryOp::Mul, _) => Times(a),
                (BinaryOp::Div, 0) => Over(b),
                (BinaryOp::Div, _) => {
                    let quotient = self.div(id, b);
                    Times(self.neg(quotient))
                }
                // d(a^b)/da = b * a^(b-1), which stays finite at a = 0 for b >= 1.
                (BinaryOp::Pow, 0) => {
                    let exponent = self.sub(b, one);
                    let power = self.pow(a, exponent);
                    Times(self.mul(b, power))
                }
                // d(a^b)/db = a^b * log(a).
                (BinaryOp::Pow, _) => {
                    let log = self.unary(UnaryOp::Log, a);
                    Times(self.mul(id, log))
                }
                // atan2(y, x): d/dy = x / (x^2 + y^2), d/dx = -y / (x^2 + y^2).
                (BinaryOp::Atan2, _) => {
                    let (y, x) = (a, b);
                    let y2 = self.powi(y, 2);
                    let x2 = self.powi(x, 2);
                    let radius2 = self.add(x2, y2);
                    if k == 0 {
                        Times(self.div(x, radius2))
                    } else {
                        let quotient = self.div(y, radius2);
                        Times(self.neg(quotient))
                    }
                }
            },
            Node::PowI(a, n) => {
                let power = self.powi(a, n - 1);
                let scale = self.constant(f64::from(n));
                Partial::ScaledTimes(scale, power)
            }
        }
    }
}
