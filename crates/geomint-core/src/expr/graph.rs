//! The expression graph: a hash-consed DAG whose builders simplify as they go.
//!
//! Every node is stored once: building a node equal to an existing one returns the
//! existing id, so a subexpression shared by a potential, its gradient and its Hessian
//! is one node, computed once by the compiled code. Nodes only refer to older nodes, so
//! ids are a topological order; all passes over the graph are loops over ids, never
//! recursion, and cannot overflow the stack however deep the graph.
//!
//! ## Simplification
//! The builders fold constants (computing them with the same [`ops`](crate::expr::ops)
//! functions the compiled code uses, so folding never changes a result) and apply rules
//! that are exact in IEEE arithmetic (`x*1 = x`, `x/1 = x`, `-(-x) = x`, `x + (-y) = x - y`,
//! `(-x)*y = -(x*y)`, `x/2 = 0.5*x` (division by a power of two), `x^1 = x`, `x^0 = 1`,
//! operand order of `+` and `*`, …), plus these
//! deliberate exceptions that are what one wants for derivatives:
//!
//! * `0*x = x*0 = 0` and `0/x = 0`, even though `x` could be infinite or NaN at run
//!   time (where IEEE would give NaN). Without this, derivatives fill up with terms
//!   multiplied by zero.
//! * `x + 0 = 0 + x = x`, `x - 0 = x`, `0 - x = -x` and `(-x) - y = -(x + y)`, which can
//!   differ from IEEE only in the sign of a zero result (`(-0) - (-0)` is +0, `-(0 + (-0))`
//!   is −0).
//!
//! No rule reassociates or distributes, because those change rounding.

use std::collections::HashMap;
use std::hash::{Hash, Hasher};

use crate::expr::ops::{self, BinaryOp, UnaryOp};
use crate::expr::parse::{self, AstNode, NameScope, ParsedExpr};
use crate::expr::{ExprError, ExprLimits, Var};

/// The id of a node in a [`Graph`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId(pub(crate) u32);

impl NodeId {
    /// The node's index; nodes only refer to nodes with smaller indices.
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// A node of the graph.
#[derive(Debug, Clone, Copy)]
pub enum Node {
    /// A constant. Two constants are the same node if their bits are equal.
    Const(f64),
    /// A variable.
    Var(Var),
    /// A one-operand operation.
    Unary(UnaryOp, NodeId),
    /// A two-operand operation. `Pow` here has an exponent that is not a small integer
    /// constant.
    Binary(BinaryOp, NodeId, NodeId),
    /// `x^n` for a constant small integer `n` (see [`ops::powi`]), kept as one node so
    /// that it differentiates to `n*x^(n-1)`.
    PowI(NodeId, i32),
}

impl PartialEq for Node {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Node::Const(a), Node::Const(b)) => a.to_bits() == b.to_bits(),
            (Node::Var(a), Node::Var(b)) => a == b,
            (Node::Unary(o, a), Node::Unary(p, b)) => o == p && a == b,
            (Node::Binary(o, a, b), Node::Binary(p, c, d)) => o == p && a == c && b == d,
            (Node::PowI(a, n), Node::PowI(b, m)) => a == b && n == m,
            _ => false,
        }
    }
}

impl Eq for Node {}

impl Hash for Node {
    fn hash<H: Hasher>(&self, state: &mut H) {
        std::mem::discriminant(self).hash(state);
        match *self {
            Node::Const(value) => value.to_bits().hash(state),
            Node::Var(var) => var.hash(state),
            Node::Unary(op, a) => (op, a).hash(state),
            Node::Binary(op, a, b) => (op, a, b).hash(state),
            Node::PowI(a, n) => (a, n).hash(state),
        }
    }
}

impl Node {
    /// The operands of the node, in order.
    pub fn operands(&self) -> impl Iterator<Item = NodeId> {
        let (first, second) = match *self {
            Node::Const(_) | Node::Var(_) => (None, None),
            Node::Unary(_, a) | Node::PowI(a, _) => (Some(a), None),
            Node::Binary(_, a, b) => (Some(a), Some(b)),
        };
        first.into_iter().chain(second)
    }
}

/// A hash-consed expression DAG with simplifying builders, derivatives
/// ([`Graph::derivative`], [`Graph::gradient`], [`Graph::jacobian`], [`Graph::hessian`])
/// and the limits that bound them.
///
/// A [`NodeId`] is only meaningful in the graph that returned it; passing it to another
/// graph gives a different node or panics on an out-of-range index.
#[derive(Debug, Clone, Default)]
pub struct Graph {
    nodes: Vec<Node>,
    index: HashMap<Node, NodeId>,
    pub(crate) limits: ExprLimits,
    /// Memoised forward derivatives: (node, variable) to derivative.
    pub(crate) derivatives: HashMap<(NodeId, Var), NodeId>,
}

impl Graph {
    /// An empty graph with the default [`ExprLimits`].
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty graph with the given limits.
    pub fn with_limits(limits: ExprLimits) -> Self {
        Graph {
            limits,
            ..Self::default()
        }
    }

    /// The limits in force.
    pub fn limits(&self) -> &ExprLimits {
        &self.limits
    }

    /// The number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Whether the graph has no node.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// A node.
    pub fn node(&self, id: NodeId) -> Node {
        self.nodes[id.index()]
    }

    /// The constant value of a node, if it is a constant.
    pub fn as_const(&self, id: NodeId) -> Option<f64> {
        match self.node(id) {
            Node::Const(value) => Some(value),
            _ => None,
        }
    }

    fn is_const(&self, id: NodeId, value: f64) -> bool {
        self.as_const(id) == Some(value)
    }

    fn negated(&self, id: NodeId) -> Option<NodeId> {
        match self.node(id) {
            Node::Unary(UnaryOp::Neg, inner) => Some(inner),
            _ => None,
        }
    }

    /// Stores a node, or returns the existing equal one.
    fn intern(&mut self, node: Node) -> NodeId {
        if let Some(&id) = self.index.get(&node) {
            return id;
        }
        let id = NodeId(u32::try_from(self.nodes.len()).expect("graph exceeds 2^32 nodes"));
        self.nodes.push(node);
        self.index.insert(node, id);
        id
    }

    /// Drops every node from `len` on (and memoised derivatives that mention them), to
    /// undo an operation that failed part-way.
    pub(crate) fn truncate(&mut self, len: usize) {
        for node in self.nodes.drain(len..) {
            self.index.remove(&node);
        }
        let keep = |id: &NodeId| id.index() < len;
        self.derivatives
            .retain(|(node, _), d| keep(node) && keep(d));
    }

    /// The constant `value`.
    pub fn constant(&mut self, value: f64) -> NodeId {
        self.intern(Node::Const(value))
    }

    /// The variable `var`.
    pub fn var(&mut self, var: Var) -> NodeId {
        self.intern(Node::Var(var))
    }

    /// The id of a variable's node, if the graph has one.
    pub fn find_var(&self, var: Var) -> Option<NodeId> {
        self.index.get(&Node::Var(var)).copied()
    }

    /// `-a`
    pub fn neg(&mut self, a: NodeId) -> NodeId {
        self.unary(UnaryOp::Neg, a)
    }

    /// `a + b`
    pub fn add(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.binary(BinaryOp::Add, a, b)
    }

    /// `a - b`
    pub fn sub(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.binary(BinaryOp::Sub, a, b)
    }

    /// `a * b`
    pub fn mul(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.binary(BinaryOp::Mul, a, b)
    }

    /// `a / b`
    pub fn div(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.binary(BinaryOp::Div, a, b)
    }

    /// `a ^ b`; a small integer constant exponent gives a [`Node::PowI`].
    pub fn pow(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.binary(BinaryOp::Pow, a, b)
    }

    /// `a ^ n` for an integer constant `n`.
    pub fn powi(&mut self, a: NodeId, n: i32) -> NodeId {
        match ops::small_integer_exponent(f64::from(n)) {
            Some(n) => self.small_powi(a, n),
            None => {
                let exponent = self.constant(f64::from(n));
                self.intern(Node::Binary(BinaryOp::Pow, a, exponent))
            }
        }
    }

    fn small_powi(&mut self, a: NodeId, n: i32) -> NodeId {
        match (n, self.as_const(a)) {
            (0, _) => self.constant(1.0),
            (1, _) => a,
            (_, Some(value)) => self.constant(ops::powi(value, n)),
            _ => self.intern(Node::PowI(a, n)),
        }
    }

    /// A one-operand operation, simplified.
    pub fn unary(&mut self, op: UnaryOp, a: NodeId) -> NodeId {
        if let Some(value) = self.as_const(a) {
            return self.constant(op.apply(value));
        }
        match (op, self.node(a)) {
            (UnaryOp::Neg, Node::Unary(UnaryOp::Neg, inner)) => inner,
            (UnaryOp::Abs, Node::Unary(UnaryOp::Neg | UnaryOp::Abs, inner)) => self.abs(inner),
            _ => self.intern(Node::Unary(op, a)),
        }
    }

    fn abs(&mut self, a: NodeId) -> NodeId {
        self.unary(UnaryOp::Abs, a)
    }

    /// A two-operand operation, simplified (see the module docs for the rules).
    pub fn binary(&mut self, op: BinaryOp, a: NodeId, b: NodeId) -> NodeId {
        if let (Some(x), Some(y)) = (self.as_const(a), self.as_const(b)) {
            return self.constant(op.apply(x, y));
        }
        let zero = |g: &Self, id| g.as_const(id) == Some(0.0);
        match op {
            BinaryOp::Add => {
                if zero(self, a) {
                    return b;
                }
                if zero(self, b) {
                    return a;
                }
                if let Some(nb) = self.negated(b) {
                    return self.sub(a, nb);
                }
                if let Some(na) = self.negated(a) {
                    return self.sub(b, na);
                }
            }
            BinaryOp::Sub => {
                if zero(self, b) {
                    return a;
                }
                if zero(self, a) {
                    return self.neg(b);
                }
                if let Some(nb) = self.negated(b) {
                    return self.add(a, nb);
                }
                if let Some(na) = self.negated(a) {
                    let sum = self.add(na, b);
                    return self.neg(sum);
                }
            }
            BinaryOp::Mul => {
                if zero(self, a) {
                    return a;
                }
                if zero(self, b) {
                    return b;
                }
                for (one, other) in [(a, b), (b, a)] {
                    if self.is_const(one, 1.0) {
                        return other;
                    }
                    if self.is_const(one, -1.0) {
                        return self.neg(other);
                    }
                }
                if let Some(na) = self.negated(a) {
                    let product = self.mul(na, b);
                    return self.neg(product);
                }
                if let Some(nb) = self.negated(b) {
                    let product = self.mul(a, nb);
                    return self.neg(product);
                }
            }
            BinaryOp::Div => {
                if zero(self, a) {
                    return a;
                }
                if let Some(reciprocal) = self.as_const(b).and_then(exact_reciprocal) {
                    // Exact: `a / 2^k` and `a * 2^-k` round the same real number.
                    let factor = self.constant(reciprocal);
                    return self.mul(factor, a);
                }
                if let Some(na) = self.negated(a) {
                    let quotient = self.div(na, b);
                    return self.neg(quotient);
                }
                if let Some(nb) = self.negated(b) {
                    let quotient = self.div(a, nb);
                    return self.neg(quotient);
                }
            }
            BinaryOp::Pow => {
                if let Some(n) = self.as_const(b).and_then(ops::small_integer_exponent) {
                    return self.small_powi(a, n);
                }
            }
            BinaryOp::Atan2 => {}
        }
        // IEEE + and * are commutative bit for bit, so put operands in one order (a
        // constant first, as one writes `2*x`, else by id) to share `a*b` and `b*a`.
        let key = |id: NodeId| (self.as_const(id).is_none(), id);
        let (a, b) = if op.is_commutative() && key(b) < key(a) {
            (b, a)
        } else {
            (a, b)
        };
        self.intern(Node::Binary(op, a, b))
    }

    /// Adds a parsed expression and returns its root.
    pub fn add_parsed(&mut self, parsed: &ParsedExpr) -> NodeId {
        let mut ids = Vec::with_capacity(parsed.nodes().len());
        for node in parsed.nodes() {
            let id = match *node {
                AstNode::Number(value) => self.constant(value),
                AstNode::Var(var) => self.var(var),
                AstNode::Unary(op, a) => self.unary(op, ids[a]),
                AstNode::Binary(op, a, b) => self.binary(op, ids[a], ids[b]),
            };
            ids.push(id);
        }
        ids[parsed.root()]
    }

    /// Parses `text` against `scope` with this graph's limits and adds it.
    pub fn parse(&mut self, text: &str, scope: &NameScope) -> Result<NodeId, ExprError> {
        let parsed = parse::parse_with_limits(text, scope, &self.limits)?;
        Ok(self.add_parsed(&parsed))
    }

    /// Marks the nodes reachable from `roots`: `result[i]` for node `i`, for `i` up to
    /// the largest root.
    pub(crate) fn reachable(&self, roots: &[NodeId]) -> Vec<bool> {
        let end = roots.iter().map(|r| r.index() + 1).max().unwrap_or(0);
        let mut marked = vec![false; end];
        for root in roots {
            marked[root.index()] = true;
        }
        for index in (0..end).rev() {
            if marked[index] {
                for operand in self.nodes[index].operands() {
                    marked[operand.index()] = true;
                }
            }
        }
        marked
    }

    /// The number of distinct nodes that `roots` depend on (themselves included): the
    /// size of the DAG that computes them.
    pub fn count_nodes(&self, roots: &[NodeId]) -> usize {
        self.reachable(roots).iter().filter(|m| **m).count()
    }

    /// Evaluates nodes directly (no compilation), with `values[v]` for variable `v`.
    ///
    /// # Panics
    /// If a variable's slot is not in `values`.
    pub fn eval(&self, roots: &[NodeId], values: &[f64]) -> Vec<f64> {
        let marked = self.reachable(roots);
        let mut results = vec![0.0; marked.len()];
        for (index, _) in marked.iter().enumerate().filter(|(_, m)| **m) {
            results[index] = match self.nodes[index] {
                Node::Const(value) => value,
                Node::Var(var) => values[var.index()],
                Node::Unary(op, a) => op.apply(results[a.index()]),
                Node::Binary(op, a, b) => op.apply(results[a.index()], results[b.index()]),
                Node::PowI(a, n) => ops::powi(results[a.index()], n),
            };
        }
        roots.iter().map(|r| results[r.index()]).collect()
    }

    /// Rebuilds the DAG of `roots` in a new graph, replacing the variables for which
    /// `value` gives a number by that constant and simplifying again (which folds the
    /// constants). Returns the new graph and the new roots.
    pub fn substitute(
        &self,
        roots: &[NodeId],
        value: impl Fn(Var) -> Option<f64>,
    ) -> (Graph, Vec<NodeId>) {
        let mut out = Graph::with_limits(self.limits);
        let marked = self.reachable(roots);
        let mut map = vec![NodeId(0); marked.len()];
        for (index, _) in marked.iter().enumerate().filter(|(_, m)| **m) {
            let m = |id: NodeId| map[id.index()];
            map[index] = match self.nodes[index] {
                Node::Const(c) => out.constant(c),
                Node::Var(var) => match value(var) {
                    Some(c) => out.constant(c),
                    None => out.var(var),
                },
                Node::Unary(op, a) => out.unary(op, m(a)),
                Node::Binary(op, a, b) => out.binary(op, m(a), m(b)),
                Node::PowI(a, n) => out.powi(m(a), n),
            };
        }
        let new_roots = roots.iter().map(|r| map[r.index()]).collect();
        (out, new_roots)
    }
}

/// `1/c` if `c` is a power of two whose reciprocal is also a normal number, so that
/// `a / c == a * (1/c)` for every `a`: both are the correctly rounded value of the same
/// real number.
fn exact_reciprocal(c: f64) -> Option<f64> {
    let is_normal_power_of_two = |v: f64| v.is_normal() && v.to_bits() & ((1 << 52) - 1) == 0;
    let reciprocal = 1.0 / c;
    (is_normal_power_of_two(c) && is_normal_power_of_two(reciprocal)).then_some(reciprocal)
}
