//! The operations of the language and their exact numeric meaning.
//!
//! Every back end (constant folding in the graph, the interpreter, the JIT and the
//! reference evaluator of parsed trees) computes each operation through the functions
//! in this file, so they all produce bit-identical results. In particular `^` has one
//! definition, [`pow`], whether its exponent is known when compiling or only when
//! evaluating.

/// An operation with one operand.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[non_exhaustive]
pub enum UnaryOp {
    /// `-x`
    Neg,
    /// `sqrt(x)`, IEEE square root.
    Sqrt,
    /// `abs(x)`
    Abs,
    /// The sign of `x`: 1 if positive, -1 if negative, `x` itself for ±0 and NaN.
    /// Not in the language; it is the derivative of `abs`.
    Sign,
    /// `sin(x)`
    Sin,
    /// `cos(x)`
    Cos,
    /// `tan(x)`
    Tan,
    /// `asin(x)`
    Asin,
    /// `acos(x)`
    Acos,
    /// `atan(x)`
    Atan,
    /// `sinh(x)`
    Sinh,
    /// `cosh(x)`
    Cosh,
    /// `tanh(x)`
    Tanh,
    /// `exp(x)`
    Exp,
    /// `log(x)`, the natural logarithm.
    Log,
}

/// An operation with two operands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[non_exhaustive]
pub enum BinaryOp {
    /// `a + b`
    Add,
    /// `a - b`
    Sub,
    /// `a * b`
    Mul,
    /// `a / b`
    Div,
    /// `a ^ b`, see [`pow`].
    Pow,
    /// `atan2(a, b)`, the angle of the point (b, a).
    Atan2,
}

/// The functions of the language, with their operation, in the order error messages
/// list them.
pub(crate) const FUNCTIONS: &[(&str, Function)] = &[
    ("sin", Function::Unary(UnaryOp::Sin)),
    ("cos", Function::Unary(UnaryOp::Cos)),
    ("tan", Function::Unary(UnaryOp::Tan)),
    ("asin", Function::Unary(UnaryOp::Asin)),
    ("acos", Function::Unary(UnaryOp::Acos)),
    ("atan", Function::Unary(UnaryOp::Atan)),
    ("sinh", Function::Unary(UnaryOp::Sinh)),
    ("cosh", Function::Unary(UnaryOp::Cosh)),
    ("tanh", Function::Unary(UnaryOp::Tanh)),
    ("exp", Function::Unary(UnaryOp::Exp)),
    ("log", Function::Unary(UnaryOp::Log)),
    ("sqrt", Function::Unary(UnaryOp::Sqrt)),
    ("abs", Function::Unary(UnaryOp::Abs)),
    ("atan2", Function::Binary(BinaryOp::Atan2)),
];

/// A function of the language: the operation a call of it builds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Function {
    Unary(UnaryOp),
    Binary(BinaryOp),
}

impl Function {
    pub(crate) fn arity(self) -> usize {
        match self {
            Function::Unary(_) => 1,
            Function::Binary(_) => 2,
        }
    }
}

/// The function names, comma-separated, for messages.
pub(crate) fn function_names() -> String {
    let names: Vec<&str> = FUNCTIONS.iter().map(|(name, _)| *name).collect();
    names.join(", ")
}

/// Looks a function up by name; returns its canonical name too.
pub(crate) fn function(name: &str) -> Option<(&'static str, Function)> {
    FUNCTIONS.iter().copied().find(|(n, _)| *n == name)
}

/// Exponents with `|n|` up to this are computed by multiplications (see [`powi`]).
pub const MAX_SQUARING_EXPONENT: i32 = 16;

/// `x^n` for a small integer `n`, by repeated squaring, exactly as the compiled code
/// computes it:
///
/// * `n == 0` gives 1 (even for NaN `x`, like `powf`);
/// * `n > 0`: scan the bits of `n` from the lowest; keep `base = x^(2^k)` (each step one
///   multiplication `base * base`) and multiply the accumulator by `base` for every set
///   bit (`acc * base`, the first set bit just takes `base`). So `x^2 = x*x`,
///   `x^3 = x*(x*x)`, `x^4 = (x*x)*(x*x)`;
/// * `n < 0`: `1 / x^(-n)`.
///
/// This is what a hand-written `x*x` computes for `n = 2`; for larger `n` it may differ
/// from `powf` in the last bits.
pub fn powi(x: f64, n: i32) -> f64 {
    if n == 0 {
        return 1.0;
    }
    let positive = powi_positive(x, n.unsigned_abs());
    if n < 0 {
        1.0 / positive
    } else {
        positive
    }
}

fn powi_positive(x: f64, mut n: u32) -> f64 {
    let mut base = x;
    let mut acc: Option<f64> = None;
    loop {
        if n & 1 == 1 {
            acc = Some(match acc {
                None => base,
                Some(a) => a * base,
            });
        }
        n >>= 1;
        if n == 0 {
            // n was at least 1, so some bit was set and `acc` is filled.
            return acc.unwrap_or(base);
        }
        base = base * base;
    }
}

/// Whether an exponent is computed by [`powi`]: an integer with magnitude at most
/// [`MAX_SQUARING_EXPONENT`]. Returns that integer.
pub fn small_integer_exponent(y: f64) -> Option<i32> {
    let limit = MAX_SQUARING_EXPONENT as f64;
    if y.trunc() == y && y.abs() <= limit {
        Some(y as i32)
    } else {
        None
    }
}

/// The language's `x ^ y`: [`powi`] when `y` is a small integer (see
/// [`small_integer_exponent`]), otherwise `f64::powf`. The rule depends only on the value
/// of `y`, so it is the same whether `y` is a constant or computed at run time.
pub fn pow(x: f64, y: f64) -> f64 {
    match small_integer_exponent(y) {
        Some(n) => powi(x, n),
        None => x.powf(y),
    }
}

/// 1 for positive, -1 for negative, and `x` itself for ±0 and NaN. The derivative of `abs`.
pub fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        x
    }
}

impl UnaryOp {
    /// Computes the operation.
    pub fn apply(self, x: f64) -> f64 {
        match self {
            UnaryOp::Neg => -x,
            UnaryOp::Sqrt => x.sqrt(),
            UnaryOp::Abs => x.abs(),
            UnaryOp::Sign => sign(x),
            UnaryOp::Sin => x.sin(),
            UnaryOp::Cos => x.cos(),
            UnaryOp::Tan => x.tan(),
            UnaryOp::Asin => x.asin(),
            UnaryOp::Acos => x.acos(),
            UnaryOp::Atan => x.atan(),
            UnaryOp::Sinh => x.sinh(),
            UnaryOp::Cosh => x.cosh(),
            UnaryOp::Tanh => x.tanh(),
            UnaryOp::Exp => x.exp(),
            UnaryOp::Log => x.ln(),
        }
    }

    /// The name used when printing.
    pub fn name(self) -> &'static str {
        match self {
            UnaryOp::Neg => "-",
            UnaryOp::Sqrt => "sqrt",
            UnaryOp::Abs => "abs",
            UnaryOp::Sign => "sign",
            UnaryOp::Sin => "sin",
            UnaryOp::Cos => "cos",
            UnaryOp::Tan => "tan",
            UnaryOp::Asin => "asin",
            UnaryOp::Acos => "acos",
            UnaryOp::Atan => "atan",
            UnaryOp::Sinh => "sinh",
            UnaryOp::Cosh => "cosh",
            UnaryOp::Tanh => "tanh",
            UnaryOp::Exp => "exp",
            UnaryOp::Log => "log",
        }
    }
}

impl BinaryOp {
    /// Computes the operation.
    pub fn apply(self, a: f64, b: f64) -> f64 {
        match self {
            BinaryOp::Add => a + b,
            BinaryOp::Sub => a - b,
            BinaryOp::Mul => a * b,
            BinaryOp::Div => a / b,
            BinaryOp::Pow => pow(a, b),
            BinaryOp::Atan2 => a.atan2(b),
        }
    }

    /// Whether `a op b == b op a` bit for bit (IEEE addition and multiplication are).
    pub fn is_commutative(self) -> bool {
        matches!(self, BinaryOp::Add | BinaryOp::Mul)
    }

    /// The symbol or name used when printing.
    pub fn name(self) -> &'static str {
        match self {
            BinaryOp::Add => "+",
            BinaryOp::Sub => "-",
            BinaryOp::Mul => "*",
            BinaryOp::Div => "/",
            BinaryOp::Pow => "^",
            BinaryOp::Atan2 => "atan2",
        }
    }
}

/// `extern "C"` entry points for every operation. The JIT calls them for operations
/// that have no machine instruction, and the interpreter calls them for the same ones;
/// each runs [`UnaryOp::apply`] / [`BinaryOp::apply`], so JIT and interpreter agree bit
/// for bit.
pub(crate) mod entry {
    use super::{BinaryOp, UnaryOp};

    macro_rules! unary_entries {
        ($($name:ident => $op:ident),* $(,)?) => {
            $(extern "C" fn $name(x: f64) -> f64 { UnaryOp::$op.apply(x) })*
            /// The entry point of a unary operation.
            pub(crate) fn unary(op: UnaryOp) -> extern "C" fn(f64) -> f64 {
                match op {
                    $(UnaryOp::$op => $name,)*
                }
            }
        };
    }

    macro_rules! binary_entries {
        ($($name:ident => $op:ident),* $(,)?) => {
            $(extern "C" fn $name(a: f64, b: f64) -> f64 { BinaryOp::$op.apply(a, b) })*
            /// The entry point of a binary operation.
            pub(crate) fn binary(op: BinaryOp) -> extern "C" fn(f64, f64) -> f64 {
                match op {
                    $(BinaryOp::$op => $name,)*
                }
            }
        };
    }

    unary_entries! {
        neg => Neg, sqrt => Sqrt, abs => Abs, sign => Sign, sin => Sin, cos => Cos,
        tan => Tan, asin => Asin, acos => Acos, atan => Atan, sinh => Sinh, cosh => Cosh,
        tanh => Tanh, exp => Exp, log => Log,
    }

    /// sin x, with cos x written to `cos`: the JIT's one call where a program takes both. The
    /// compiler makes the pair one call of the C library's `sincos` (it does for glibc
    /// targets), whose results are its `sin`'s and `cos`'s to the bit: glibc computes the
    /// three with the same code (`tests/core/expr/backends.rs` compares the JIT, which calls
    /// this, with the interpreter, which calls `sin` and `cos`).
    pub(crate) extern "C" fn sin_cos(x: f64, cos: *mut f64) -> f64 {
        let (sine, cosine) = (UnaryOp::Sin.apply(x), UnaryOp::Cos.apply(x));
        // SAFETY: the JIT passes the address of a stack slot of one f64.
        unsafe { *cos = cosine };
        sine
    }

    /// [`sin_cos`], its results remembered by the thread: where the argument is a function of
    /// a driven system's clock alone (sin ωt, cos ωt of its forcing), every cell of a map or
    /// sweep steps through the same times, so after the first cell a thread runs, most
    /// arguments were seen before. A pure function's results, taken from memory, are the bits
    /// it would compute again.
    pub(crate) extern "C" fn sin_cos_remembered(x: f64, cos: *mut f64) -> f64 {
        let (sine, cosine) = REMEMBERED.with_borrow_mut(|memory| memory.sin_cos(x));
        // SAFETY: the JIT passes the address of a stack slot of one f64.
        unsafe { *cos = cosine };
        sine
    }

    thread_local! {
        static REMEMBERED: std::cell::RefCell<Remembered> =
            const { std::cell::RefCell::new(Remembered(Vec::new())) };
    }

    /// The last argument seen per slot, with its sine and cosine; an argument's slot is a hash
    /// of its bits.
    struct Remembered(Vec<(u64, f64, f64)>);

    impl Remembered {
        /// 2¹⁴ slots (384 KiB a thread). A map's cells mostly decide within their first
        /// periods, and those times fit with few collisions: on the forced Duffing map (64 steps
        /// a period) glibc's `sincos` fell from 44 % of the time to under 2 %.
        const BITS: u32 = 14;

        fn sin_cos(&mut self, x: f64) -> (f64, f64) {
            if self.0.is_empty() {
                // Every slot starts as the argument +0 with its own results.
                let zero = (
                    0.0f64.to_bits(),
                    UnaryOp::Sin.apply(0.0),
                    UnaryOp::Cos.apply(0.0),
                );
                self.0 = vec![zero; 1 << Self::BITS];
            }
            let bits = x.to_bits();
            // Fibonacci hashing: the top bits of the product mix all of the argument's bits.
            let slot = (bits.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - Self::BITS)) as usize;
            let entry = &mut self.0[slot];
            if entry.0 != bits {
                *entry = (bits, UnaryOp::Sin.apply(x), UnaryOp::Cos.apply(x));
            }
            (entry.1, entry.2)
        }
    }

    binary_entries! {
        add => Add, sub => Sub, mul => Mul, div => Div, pow => Pow, atan2 => Atan2,
    }
}
