//! The parser: expression text to a small syntax tree, against a [`NameScope`] of declared
//! names.
//!
//! A hand-written recursive-descent parser. Only parentheses and function calls recurse;
//! chains of signs, of binary operators and of powers are read in loops, and the nesting
//! of parentheses and calls is checked against [`ExprLimits::max_depth`] *before* recursing,
//! so no input can overflow the stack. Every token is read once, so parsing is linear in
//! the length of the input, which is itself bounded by [`ExprLimits::max_chars`].

use crate::expr::error::{Expected, ExprError};
use crate::expr::lex::{Lexer, Token, TokenKind};
use crate::expr::ops::{self, BinaryOp, Function, UnaryOp};
use crate::expr::{ExprLimits, Var};

/// The names an expression may use, each bound to a variable slot.
///
/// Names are declared in order and get consecutive slots `Var(0)`, `Var(1)`, …
/// A scope can be narrowed with [`NameScope::restricted_to`]: the other names stay known but
/// are refused with [`ExprError::NameNotAllowed`], which gives a clearer message than
/// "unknown name".
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct NameScope {
    names: Vec<String>,
    allowed: Vec<bool>,
}

impl NameScope {
    /// An empty scope.
    pub fn new() -> Self {
        Self::default()
    }

    /// A scope declaring `names` in order.
    pub fn with_names<S: AsRef<str>>(names: &[S]) -> Result<Self, ExprError> {
        let mut scope = NameScope::new();
        for name in names {
            scope.declare(name.as_ref())?;
        }
        Ok(scope)
    }

    /// Declares a name and returns its slot. The name must be an identifier (a letter or
    /// `_`, then letters, digits or `_`), not yet declared, and not a function name or `pi`.
    pub fn declare(&mut self, name: &str) -> Result<Var, ExprError> {
        let refuse = |reason| {
            Err(ExprError::InvalidDeclaration {
                name: name.to_string(),
                reason,
            })
        };
        let mut chars = name.chars();
        let starts_well = chars.next().is_some_and(|c| c.is_alphabetic() || c == '_');
        if !starts_well || !chars.all(|c| c.is_alphanumeric() || c == '_') {
            return refuse("a name is a letter or \"_\" followed by letters, digits or \"_\"");
        }
        if name == "pi" || ops::function(name).is_some() {
            return refuse("it is reserved for a constant or function of the language");
        }
        if self.lookup(name).is_some() {
            return refuse("it is already declared");
        }
        let Ok(index) = u32::try_from(self.names.len()) else {
            return refuse("too many names");
        };
        self.names.push(name.to_string());
        self.allowed.push(true);
        Ok(Var(index))
    }

    /// The slot of a declared name (allowed or not).
    pub fn lookup(&self, name: &str) -> Option<Var> {
        let index = self.names.iter().position(|n| n == name)?;
        Some(Var(index as u32))
    }

    /// The name of a slot.
    pub fn name(&self, var: Var) -> Option<&str> {
        self.names.get(var.index()).map(String::as_str)
    }

    /// The number of declared names.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether no name is declared.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// All declared slots, in order.
    pub fn vars(&self) -> impl Iterator<Item = Var> + '_ {
        (0..self.names.len() as u32).map(Var)
    }

    /// The same names, of which only those in `allowed` may be used.
    pub fn restricted_to(&self, allowed: &[Var]) -> NameScope {
        let mut scope = self.clone();
        for (index, flag) in scope.allowed.iter_mut().enumerate() {
            *flag = allowed.contains(&Var(index as u32));
        }
        scope
    }

    /// Whether a slot may be used.
    pub fn is_allowed(&self, var: Var) -> bool {
        self.allowed.get(var.index()).copied().unwrap_or(false)
    }

    fn allowed_names(&self) -> Vec<String> {
        let pairs = self.names.iter().zip(&self.allowed);
        pairs
            .filter(|(_, ok)| **ok)
            .map(|(n, _)| n.clone())
            .collect()
    }
}

/// The index of a node in a [`ParsedExpr`].
pub type AstId = usize;

/// A node of a parsed expression, exactly as written (no simplification).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AstNode {
    /// A number literal, or `pi`.
    Number(f64),
    /// A declared name.
    Var(Var),
    /// `-a` or a one-argument function.
    Unary(UnaryOp, AstId),
    /// A binary operator or `atan2`.
    Binary(BinaryOp, AstId, AstId),
}

/// A parsed expression: its nodes in post-order (operands before the operation), so the
/// last node is the root.
#[derive(Debug, Clone, PartialEq)]
pub struct ParsedExpr {
    nodes: Vec<AstNode>,
}

impl ParsedExpr {
    /// The nodes, operands before operations.
    pub fn nodes(&self) -> &[AstNode] {
        &self.nodes
    }

    /// The root node.
    pub fn root(&self) -> AstId {
        self.nodes.len() - 1
    }

    /// Evaluates the expression as written, every operation through [`ops`], with
    /// `values[v]` for variable `v`. A reference for testing the compiled forms.
    ///
    /// # Panics
    /// If a variable's slot is not in `values`.
    pub fn eval(&self, values: &[f64]) -> f64 {
        let mut results = Vec::with_capacity(self.nodes.len());
        for node in &self.nodes {
            let value = match *node {
                AstNode::Number(value) => value,
                AstNode::Var(var) => values[var.index()],
                AstNode::Unary(op, a) => op.apply(results[a]),
                AstNode::Binary(op, a, b) => op.apply(results[a], results[b]),
            };
            results.push(value);
        }
        results[self.root()]
    }
}

/// Parses `text` with the default [`ExprLimits`]. See the crate docs for the language.
pub fn parse(text: &str, scope: &NameScope) -> Result<ParsedExpr, ExprError> {
    parse_with_limits(text, scope, &ExprLimits::default())
}

/// Parses `text` with the given limits on length, nesting and size.
pub fn parse_with_limits(
    text: &str,
    scope: &NameScope,
    limits: &ExprLimits,
) -> Result<ParsedExpr, ExprError> {
    // Count only as far as needed, so a huge input is refused without reading it all.
    if text
        .chars()
        .take(limits.max_chars.saturating_add(1))
        .count()
        > limits.max_chars
    {
        return Err(ExprError::TooLong {
            position: limits.max_chars,
            limit: limits.max_chars,
        });
    }
    let mut parser = Parser {
        lexer: Lexer::new(text),
        peeked: None,
        scope,
        limits,
        nodes: Vec::new(),
        depth: 0,
    };
    parser.sum()?;
    let next = parser.next()?;
    if next.kind != TokenKind::End {
        return Err(next.unexpected(Expected::OperatorOrEnd));
    }
    Ok(ParsedExpr {
        nodes: parser.nodes,
    })
}

struct Parser<'a, 's> {
    lexer: Lexer<'a>,
    peeked: Option<Token<'a>>,
    scope: &'s NameScope,
    limits: &'s ExprLimits,
    nodes: Vec<AstNode>,
    depth: usize,
}

impl<'a> Parser<'a, '_> {
    fn peek(&mut self) -> Result<Token<'a>, ExprError> {
        match self.peeked {
            Some(token) => Ok(token),
            None => {
                let token = self.lexer.next_token()?;
                self.peeked = Some(token);
                Ok(token)
            }
        }
    }

    fn next(&mut self) -> Result<Token<'a>, ExprError> {
        let token = self.peek()?;
        self.peeked = None;
        Ok(token)
    }

    /// Adds a node; `position` is where its text starts, for the size error.
    fn push(&mut self, node: AstNode, position: usize) -> Result<AstId, ExprError> {
        if self.nodes.len() >= self.limits.max_parse_nodes {
            return Err(ExprError::TooManyNodes {
                position,
                limit: self.limits.max_parse_nodes,
            });
        }
        self.nodes.push(node);
        Ok(self.nodes.len() - 1)
    }

    /// `term (("+" | "-") term)*`
    fn sum(&mut self) -> Result<AstId, ExprError> {
        let mut lhs = self.product()?;
        loop {
            let token = self.peek()?;
            let op = match token.kind {
                TokenKind::Plus => BinaryOp::Add,
                TokenKind::Minus => BinaryOp::Sub,
                _ => return Ok(lhs),
            };
            self.next()?;
            let rhs = self.product()?;
            lhs = self.push(AstNode::Binary(op, lhs, rhs), token.position)?;
        }
    }

    /// `signed (("*" | "/") signed)*`
    fn product(&mut self) -> Result<AstId, ExprError> {
        let mut lhs = self.signed()?;
        loop {
            let token = self.peek()?;
            let op = match token.kind {
                TokenKind::Star => BinaryOp::Mul,
                TokenKind::Slash => BinaryOp::Div,
                _ => return Ok(lhs),
            };
            self.next()?;
            let rhs = self.signed()?;
            lhs = self.push(AstNode::Binary(op, lhs, rhs), token.position)?;
        }
    }

    /// `("-" | "+")* power`: signs apply to the whole power, so `-x^2` is `-(x^2)`.
    fn signed(&mut self) -> Result<AstId, ExprError> {
        let mut minus_positions = Vec::new();
        loop {
            let token = self.peek()?;
            match token.kind {
                TokenKind::Minus => minus_positions.push(token.position),
                TokenKind::Plus => {}
                _ => break,
            }
            self.next()?;
        }
        let mut operand = self.power()?;
        for &position in minus_positions.iter().rev() {
            operand = self.push(AstNode::Unary(UnaryOp::Neg, operand), position)?;
        }
        Ok(operand)
    }

    /// `primary ("^" ("-" | "+")* primary)*`, grouped from the right: `a^b^c = a^(b^c)`,
    /// and `a^-b^c = a^(-(b^c))`.
    fn power(&mut self) -> Result<AstId, ExprError> {
        let base = self.primary()?;
        if self.peek()?.kind != TokenKind::Caret {
            return Ok(base);
        }
        // Each operand of the chain with the positions of the signs before it, and the
        // position of the `^` before it.
        let mut chain = vec![(base, Vec::new(), 0)];
        while let caret @ Token {
            kind: TokenKind::Caret,
            ..
        } = self.peek()?
        {
            self.next()?;
            let mut minus_positions = Vec::new();
            loop {
                let token = self.peek()?;
                match token.kind {
                    TokenKind::Minus => minus_positions.push(token.position),
                    TokenKind::Plus => {}
                    _ => break,
                }
                self.next()?;
            }
            let operand = self.primary()?;
            chain.push((operand, minus_positions, caret.position));
        }
        let (mut exponent, mut signs, mut caret) = chain.pop().unwrap_or_default();
        while let Some((operand, operand_signs, operand_caret)) = chain.pop() {
            for &position in signs.iter().rev() {
                exponent = self.push(AstNode::Unary(UnaryOp::Neg, exponent), position)?;
            }
            exponent = self.push(AstNode::Binary(BinaryOp::Pow, operand, exponent), caret)?;
            (signs, caret) = (operand_signs, operand_caret);
        }
        Ok(exponent)
    }

    /// Enters a parenthesis or call opened at `position`, refusing to go too deep.
    fn enter(&mut self, position: usize) -> Result<(), ExprError> {
        if self.depth >= self.limits.max_depth {
            return Err(ExprError::TooDeep {
                position,
                limit: self.limits.max_depth,
            });
        }
        self.depth += 1;
        Ok(())
    }

    /// A number, `pi`, a name, a call or a parenthesised expression.
    fn primary(&mut self) -> Result<AstId, ExprError> {
        let token = self.next()?;
        match token.kind {
            TokenKind::Number(value) => self.push(AstNode::Number(value), token.position),
            TokenKind::OpenParen => {
                self.enter(token.position)?;
                let inner = self.sum()?;
                let close = self.next()?;
                if close.kind != TokenKind::CloseParen {
                    return Err(close.unexpected(Expected::OperatorOrCloseParen));
                }
                self.depth -= 1;
                Ok(inner)
            }
            TokenKind::Ident(name) => self.name(name, token.position),
            _ => Err(token.unexpected(Expected::Operand)),
        }
    }

    fn name(&mut self, name: &str, position: usize) -> Result<AstId, ExprError> {
        if let Some((canonical, function)) = ops::function(name) {
            return self.call(canonical, function, position);
        }
        if name == "pi" {
            return self.push(AstNode::Number(std::f64::consts::PI), position);
        }
        match self.scope.lookup(name) {
            Some(var) if self.scope.is_allowed(var) => self.push(AstNode::Var(var), position),
            Some(_) => Err(ExprError::NameNotAllowed {
                name: name.to_string(),
                position,
                allowed: self.scope.allowed_names(),
            }),
            None if self.peek()?.kind == TokenKind::OpenParen => Err(ExprError::UnknownFunction {
                name: crate::expr::error::shorten(name),
                position,
            }),
            None => Err(ExprError::UnknownName {
                name: crate::expr::error::shorten(name),
                position,
                known: self.scope.allowed_names(),
            }),
        }
    }

    /// `name "(" [sum ("," sum)*] ")"`; the argument count is checked after the `)`, so
    /// the error can say how many were given.
    fn call(
        &mut self,
        canonical: &'static str,
        function: Function,
        position: usize,
    ) -> Result<AstId, ExprError> {
        let open = self.next()?;
        if open.kind != TokenKind::OpenParen {
            return Err(open.unexpected(Expected::OpenParen));
        }
        self.enter(open.position)?;
        let arity = function.arity();
        let mut args = [0; 2];
        let mut count = 0;
        if self.peek()?.kind == TokenKind::CloseParen {
            self.next()?;
        } else {
            loop {
                let arg = self.sum()?;
                if count < args.len() {
                    args[count] = arg;
                }
                count += 1;
                let token = self.next()?;
                match token.kind {
                    TokenKind::Comma => continue,
                    TokenKind::CloseParen => break,
                    _ if count < arity => return Err(token.unexpected(Expected::OperatorOrComma)),
                    _ => return Err(token.unexpected(Expected::OperatorOrCloseParen)),
                }
            }
        }
        self.depth -= 1;
        if count != arity {
            return Err(ExprError::WrongArgumentCount {
                function: canonical,
                position,
                expected: arity,
                found: count,
            });
        }
        let node = match function {
            Function::Unary(op) => AstNode::Unary(op, args[0]),
            Function::Binary(op) => AstNode::Binary(op, args[0], args[1]),
        };
        self.push(node, position)
    }
}
