//! Launching an orbit on an energy surface: the initial momentum named by the request is
//! replaced by the non-negative value that gives H(q₀, p₀) = E, the other coordinates and
//! momenta as given. The root is bracketed between 0 and a value where H ≥ E (doubling), then
//! bisected until the bracket cannot shrink: H's growth in a momentum need not be quadratic
//! (a general H(q, p)), and bisection needs only continuity; the result is the same double on
//! every machine.

use crate::error::{CoreError, Field, Range};

/// Most doublings of the bracket's upper end.
const MAX_DOUBLINGS: u32 = 200;

/// The energy an orbit is launched at, and the momentum that takes it up.
#[derive(Clone, Debug, PartialEq)]
pub struct EnergyLevel {
    /// E.
    pub energy: f64,
    /// The momentum's name (one of the system's momenta).
    pub momentum: String,
    /// Where the request gave it (`energy`).
    pub field: Field,
}

/// The value x ≥ 0 of momentum `index` for which `h(p with p_index = x) = energy`; `h` is H at
/// the run's q₀ as a function of the momenta. Errors name `field`: an energy below H at x = 0
/// (the point lies outside the energy surface), or one no momentum reaches.
pub fn solve(
    h: &dyn Fn(&[f64]) -> f64,
    p0: &[f64],
    index: usize,
    energy: f64,
    field: &Field,
) -> Result<f64, CoreError> {
    let value = field.key("value");
    if !energy.is_finite() {
        return Err(CoreError::NotFinite { field: value });
    }
    let mut p = p0.to_vec();
    let mut at = |x: f64| {
        p[index] = x;
        h(&p) - energy
    };
    let floor = at(0.0);
    if !(floor <= 0.0) {
        // H(q₀, p with this momentum at 0) is the least energy this point can have.
        return Err(CoreError::OutOfRange {
            field: value,
            value: energy,
            range: Range::above(floor + energy, false),
        });
    }
    if floor == 0.0 {
        return Ok(0.0);
    }
    let mut hi = 1.0;
    let mut doublings = 0;
    while !(at(hi) >= 0.0) {
        doublings += 1;
        if doublings > MAX_DOUBLINGS {
            return Err(CoreError::Unsupported {
                field: field.key("momentum"),
                reason: "no value of this momentum reaches the energy",
            });
        }
        hi *= 2.0;
    }
    let mut lo = 0.0f64;
    loop {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if at(mid) >= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    // The end of the final bracket whose energy is closer.
    Ok(if at(hi).abs() <= at(lo).abs() { hi } else { lo })
}
