//! Printing: graph nodes as infix text in the language, programs as listings.

use std::fmt;

use crate::expr::graph::{Graph, Node, NodeId};
use crate::expr::ops::{BinaryOp, UnaryOp};
use crate::expr::parse::NameScope;
use crate::expr::program::{Instr, Program};

/// Binding strength when printing; higher binds tighter.
const SUM: u8 = 1;
const PRODUCT: u8 = 2;
const SIGNED: u8 = 3;
const POWER: u8 = 4;
const ATOM: u8 = 5;

impl Graph {
    /// The expression of node `id` as text in the language (with `sign(x)` for the
    /// derivative of `abs`), parenthesised so that it parses back to the same tree.
    /// Returns `None` if the expression, written out as a tree, would have more than
    /// `max_nodes` nodes: a DAG with much sharing can be exponentially larger as text.
    pub fn to_infix(&self, id: NodeId, scope: &NameScope, max_nodes: usize) -> Option<String> {
        // Tree size of every node in the cone, saturating, to refuse before printing.
        let marked = self.reachable(&[id]);
        let mut size = vec![0usize; marked.len()];
        for index in (0..marked.len()).filter(|&i| marked[i]) {
            let node = self.node(NodeId(index as u32));
            let operands = node.operands().map(|op| size[op.index()]);
            size[index] = operands.fold(1usize, usize::saturating_add);
        }
        if size[id.index()] > max_nodes {
            return None;
        }
        // The tree has at most `max_nodes` nodes, which bounds the recursion below.
        let mut out = String::new();
        self.write_infix(id, scope, &mut out);
        Some(out)
    }

    fn strength(&self, id: NodeId) -> u8 {
        match self.node(id) {
            Node::Const(c) if c.is_sign_negative() => SIGNED,
            Node::Const(_) | Node::Var(_) => ATOM,
            Node::Unary(UnaryOp::Neg, _) => SIGNED,
            Node::Unary(..) | Node::Binary(BinaryOp::Atan2, ..) => ATOM,
            Node::Binary(BinaryOp::Add | BinaryOp::Sub, ..) => SUM,
            Node::Binary(BinaryOp::Mul | BinaryOp::Div, ..) => PRODUCT,
            Node::Binary(BinaryOp::Pow, ..) | Node::PowI(..) => POWER,
        }
    }

    fn write_operand(&self, id: NodeId, min: u8, scope: &NameScope, out: &mut String) {
        if self.strength(id) < min {
            out.push('(');
            self.write_infix(id, scope, out);
            out.push(')');
        } else {
            self.write_infix(id, scope, out);
        }
    }

    fn write_infix(&self, id: NodeId, scope: &NameScope, out: &mut String) {
        match self.node(id) {
            Node::Const(c) => out.push_str(&format_number(c)),
            Node::Var(var) => match scope.name(var) {
                Some(name) => out.push_str(name),
                None => out.push_str(&format!("v{}", var.0)),
            },
            Node::Unary(UnaryOp::Neg, a) => {
                out.push('-');
                self.write_operand(a, POWER, scope, out);
            }
            Node::Unary(op, a) => {
                out.push_str(op.name());
                out.push('(');
                self.write_infix(a, scope, out);
                out.push(')');
            }
            Node::Binary(BinaryOp::Atan2, a, b) => {
                out.push_str("atan2(");
                self.write_infix(a, scope, out);
                out.push_str(", ");
                self.write_infix(b, scope, out);
                out.push(')');
            }
            Node::Binary(op, a, b) => {
                let (left, right) = match op {
                    BinaryOp::Add | BinaryOp::Sub => (SUM, PRODUCT),
                    BinaryOp::Mul | BinaryOp::Div => (PRODUCT, SIGNED),
                    // Right-associative: the base must bind tighter than `^`.
                    _ => (ATOM, SIGNED),
                };
                self.write_operand(a, left, scope, out);
                if op == BinaryOp::Pow {
                    out.push('^');
                } else {
                    out.push_str(&format!(" {} ", op.name()));
                }
                self.write_operand(b, right, scope, out);
            }
            Node::PowI(a, n) => {
                self.write_operand(a, ATOM, scope, out);
                out.push_str(&format!("^{n}"));
            }
        }
    }
}

/// The shortest text that reads back as the same `f64`, without a needless `.0`.
fn format_number(value: f64) -> String {
    let text = format!("{value:?}");
    match text.strip_suffix(".0") {
        Some(integer) => integer.to_string(),
        None => text,
    }
}

impl fmt::Display for Program {
    /// One instruction per line: `r2 = r0 * r1`, `out[0] = r2`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for instr in self.instrs() {
            match *instr {
                Instr::Load { dst, input } => writeln!(f, "r{dst} = in[{input}]")?,
                Instr::Const { dst, value } => writeln!(f, "r{dst} = {}", format_number(value))?,
                Instr::Unary { op, dst, a } => writeln!(f, "r{dst} = {}(r{a})", op.name())?,
                Instr::Binary {
                    op: BinaryOp::Atan2,
                    dst,
                    a,
                    b,
                } => writeln!(f, "r{dst} = atan2(r{a}, r{b})")?,
                Instr::Binary { op, dst, a, b } => writeln!(f, "r{dst} = r{a} {} r{b}", op.name())?,
                Instr::Store { src, output } => writeln!(f, "out[{output}] = r{src}")?,
            }
        }
        Ok(())
    }
}
