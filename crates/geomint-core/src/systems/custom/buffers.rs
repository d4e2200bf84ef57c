//! Work space for evaluating a typed-in system's compiled functions: small buffers on the stack,
//! longer ones kept per thread, and the phase point (q, p) laid out as the functions read it.

use std::cell::Cell;

use crate::expr::CompiledFunction;

thread_local! {
    /// A buffer for intermediate values too long for the stack buffer (kept per thread, taken
    /// while used, so a nested use gets its own).
    static SPARE: Cell<Vec<f64>> = const { Cell::new(Vec::new()) };
}

/// Runs `f` on a zeroed buffer of `len` numbers: on the stack for up to 16, else a per-thread
/// buffer that is allocated once.
#[inline]
pub(super) fn with_buffer<R>(len: usize, f: impl FnOnce(&mut [f64]) -> R) -> R {
    // Up to a 4 × 4 matrix (a 3-D system's damping matrix is 9) on the stack.
    if len <= 16 {
        let mut buffer = [0.0; 16];
        f(&mut buffer[..len])
    } else {
        let mut buffer = SPARE.with(Cell::take);
        buffer.clear();
        buffer.resize(len, 0.0);
        let result = f(&mut buffer);
        SPARE.with(|spare| spare.set(buffer));
        result
    }
}

/// Runs `f` on (q, p) laid out as the compiled functions of both read them.
#[inline]
pub(super) fn with_phase<R>(q: &[f64], p: &[f64], f: impl FnOnce(&[f64]) -> R) -> R {
    let n = q.len();
    with_buffer(2 * n, |x| {
        x[..n].copy_from_slice(q);
        x[n..].copy_from_slice(p);
        f(x)
    })
}

/// `f` at the phase point (q, p); out of line, so that the separable paths that call it only
/// for a general H stay small enough to inline.
#[inline(never)]
pub(super) fn eval_on_phase(f: &CompiledFunction, q: &[f64], p: &[f64], out: &mut [f64]) {
    with_phase(q, p, |x| f.eval(x, out))
}
