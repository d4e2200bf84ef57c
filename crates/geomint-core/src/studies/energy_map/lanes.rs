//! Symplectic Euler and its adjoint on the planar elastic pendulum, in either chart, four runs
//! side by side. The study engine asks [`LaneKernel::of`] for a method on a system; a sweep whose
//! runs all have a kernel runs its cells four at a time (paper 001 Fig. 6's energy map is such a
//! sweep), measured against H₀ at every step.
//!
//! Every lane does exactly the arithmetic of the one-run path, operation for operation and in
//! the same order (the composer's kick and drift, the chart's closed-form stages, its energy),
//! and IEEE addition, multiplication, division and square root round the same in a SIMD lane as
//! in a scalar register, so runs here are bit for bit the runs of the generic stepper
//! (`tests/core/energy_map.rs` compares every cell of both).
//!
//! Sine and cosine stay the C library's, one call per lane. The compiler turns the sine and
//! cosine of one angle into one `sincos` call, and the energy reuses its cosine where the
//! one-run path calls `cos`: with glibc, whose `sincos` and `cos` share their code, the bits are
//! the same (the test would catch a library where they differ). Besides the packing, the lanes
//! save work twice: the energy that eq. (50) asks for after every step shares |q| (Cartesian) or
//! sin θ, cos θ (polar) with the next step's force, and the per-step calls through the generic
//! composer and observer are gone.

// The lanes are indexed side by side in several arrays at once: loops over lane numbers are the
// form the compiler vectorises.
#![allow(clippy::needless_range_loop)]

use std::sync::atomic::Ordering;
use std::time::Instant;

use crate::diagnostics::DIVERGENCE;
use crate::methods::lanes::{Isa, CHECK_EVERY};
use crate::methods::{Method, MethodId};
use crate::run::Budget;
use crate::systems::{AnySystem, PlanarCartesian, PlanarKind, PlanarPolar, PlanarSpring};

/// Cells integrated side by side.
pub const PENDULUM_LANES: usize = 4;
/// One value per lane.
pub type FourLanes = [f64; PENDULUM_LANES];

/// The chart a lane kernel works in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Chart {
    /// (x, y, p_x, p_y).
    Cartesian,
    /// (r, θ, p_r, p_θ).
    Polar,
}

/// Which symplectic Euler: 001 eqs. (42)–(43) (momentum first) or its adjoint (position first).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EulerOrder {
    /// p₁ from (q, p₁), then q₁ from (q, p₁).
    MomentumFirst,
    /// q₁ from (q₁, p), then p₁ from (q₁, p).
    PositionFirst,
}

impl EulerOrder {
    /// The order of `method`, if the lanes run it.
    pub fn of(method: &Method) -> Option<EulerOrder> {
        match method {
            Method::Plain(MethodId::SymplecticEuler) => Some(EulerOrder::MomentumFirst),
            Method::Plain(MethodId::SymplecticEulerAdjoint) => Some(EulerOrder::PositionFirst),
            _ => None,
        }
    }
}

/// The starting states of [`PENDULUM_LANES`] cells in one chart, and which lanes hold a cell.
#[derive(Clone, Copy, Debug)]
pub struct Start {
    /// q₀, component by component.
    pub q: [FourLanes; 2],
    /// p₀, component by component.
    pub p: [FourLanes; 2],
    /// H(q₀, p₀) as the one-cell path computes it.
    pub energy: FourLanes,
    /// Lanes without a cell (the padding of the last group, the pivot in polar coordinates).
    pub idle: [bool; PENDULUM_LANES],
}

/// The pendulum's constants, combined as the one-cell path combines them.
#[derive(Clone, Copy, Debug)]
struct Constants {
    h: f64,
    m: f64,
    k: f64,
    l: f64,
    /// 1/m (the Cartesian drift multiplies by it).
    inv_m: f64,
    /// m·g.
    mg: f64,
    /// 0.5·k.
    half_k: f64,
    /// (h·m)·g (the polar momentum stage's θ-kick).
    hmg: f64,
}

impl Constants {
    fn new(pendulum: &PlanarSpring, h: f64) -> Self {
        Constants {
            h,
            m: pendulum.m,
            k: pendulum.k,
            l: pendulum.l,
            inv_m: 1.0 / pendulum.m,
            mg: pendulum.m * pendulum.g,
            half_k: 0.5 * pendulum.k,
            hmg: h * pendulum.m * pendulum.g,
        }
    }
}

/// Per lane: the sum of eq. (50) and the first steps at which the lane left the energy band or
/// the finite numbers (as f64, exact to 2⁵³, so that the lanes compare and select in SIMD
/// registers; ∞: never), the largest and the last |H − H₀|, and the state the one-run path
/// ends with.
#[derive(Clone, Copy, Debug)]
pub struct Tally {
    /// Σ (H − H₀)² over the samples, the first included.
    pub sum: FourLanes,
    /// The first step whose energy left the band.
    pub blown: FourLanes,
    /// The first step whose state is not finite (0 for an idle lane).
    pub non_finite: FourLanes,
    /// The largest |H − H₀| (sweeps only).
    pub max: FourLanes,
    /// The last H − H₀ (sweeps only).
    pub last: FourLanes,
    /// The last finite state before the lane stopped, as the one-cell path's last sample
    /// (sweeps only).
    pub q: [FourLanes; 2],
    /// Its momenta.
    pub p: [FourLanes; 2],
}

/// A method on a system that the lanes run.
#[derive(Clone, Debug, PartialEq)]
pub struct LaneKernel {
    pendulum: PlanarSpring,
    chart: Chart,
    order: EulerOrder,
    isa: Isa,
}

impl LaneKernel {
    /// The kernel of `method` on `system`, if the lanes run it: symplectic Euler or its adjoint
    /// on the planar elastic pendulum (not the free particle, whose runs report invariants and
    /// errors against its exact solution), in either chart.
    pub fn of(method: &Method, system: &AnySystem) -> Option<LaneKernel> {
        let order = EulerOrder::of(method)?;
        let (pendulum, chart) = match system {
            AnySystem::PlanarCartesian(PlanarCartesian(s)) => (s, Chart::Cartesian),
            AnySystem::PlanarPolar(PlanarPolar(s)) => (s, Chart::Polar),
            _ => return None,
        };
        (pendulum.kind == PlanarKind::Pendulum).then(|| LaneKernel {
            pendulum: pendulum.clone(),
            chart,
            order,
            isa: Isa::detect(),
        })
    }

    /// The same kernel built for `isa`, if this CPU has it (the numbers are the same bits; the
    /// kernel has a portable build and an AVX2 one, which AVX-512 runs too).
    pub fn with_isa(self, isa: Isa) -> Option<Self> {
        isa.available().then_some(LaneKernel { isa, ..self })
    }

    /// `steps` steps of size `h` from the [`PENDULUM_LANES`] starts, measured against H₀ at every step;
    /// `None` when the budget stopped the run.
    pub fn tally(&self, start: &Start, h: f64, steps: u64, budget: Budget<'_>) -> Option<Tally> {
        let limit = start.energy.map(|e| DIVERGENCE * (1.0 + e.abs()));
        let c = Constants::new(&self.pendulum, h);
        let (chart, order) = (self.chart, self.order);
        #[cfg(target_arch = "x86_64")]
        if self.isa != Isa::Portable {
            // SAFETY: the CPU supports AVX2: `isa` is one it has (detected, or checked by
            // `with_isa`), and both wider ones imply AVX2.
            return unsafe { integrate_avx2(&c, chart, order, start, steps, &limit, budget) };
        }
        integrate(&c, chart, order, start, steps, &limit, budget)
    }
}

/// [`integrate`] compiled with AVX2 (f64×4 registers). Still no fused multiply-add, which would
/// round once where the one-cell path rounds twice: rustc never contracts a·b + c into one
/// (only `mul_add` does), whatever the target features.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn integrate_avx2(
    c: &Constants,
    chart: Chart,
    order: EulerOrder,
    start: &Start,
    steps: u64,
    limit: &FourLanes,
    budget: Budget<'_>,
) -> Option<Tally> {
    integrate(c, chart, order, start, steps, limit, budget)
}

/// One kernel per (chart, order), each a loop the compiler specialises.
#[inline(always)]
fn integrate(
    c: &Constants,
    chart: Chart,
    order: EulerOrder,
    start: &Start,
    steps: u64,
    limit: &FourLanes,
    budget: Budget<'_>,
) -> Option<Tally> {
    match (chart, order) {
        (Chart::Cartesian, EulerOrder::MomentumFirst) => {
            lanes(c, start, steps, limit, budget, Cartesian::<true>)
        }
        (Chart::Cartesian, EulerOrder::PositionFirst) => {
            lanes(c, start, steps, limit, budget, Cartesian::<false>)
        }
        (Chart::Polar, EulerOrder::MomentumFirst) => {
            lanes(c, start, steps, limit, budget, Polar::<true>)
        }
        (Chart::Polar, EulerOrder::PositionFirst) => {
            lanes(c, start, steps, limit, budget, Polar::<false>)
        }
    }
}

/// The state of the lanes and what the last energy left for the next step.
#[derive(Clone, Copy)]
struct Cells {
    q: [FourLanes; 2],
    p: [FourLanes; 2],
    /// |q| (Cartesian) or (sin θ, cos θ) (polar) at the current q.
    shared: [FourLanes; 2],
}

/// One chart's step on all lanes, and its energy. Each operation is a loop over the lanes with
/// nothing but arithmetic in it, which the compiler turns into SIMD instructions.
trait Kernel {
    /// `shared` for the state as it starts.
    fn prime(&self, z: &mut Cells);
    /// One step of every lane; H at the new states into `energy`.
    fn step(&self, c: &Constants, z: &mut Cells, energy: &mut FourLanes);
}

/// The loop: every lane one step, its energy deviation summed, the first blow-up noted; the
/// budget looked at every [`CHECK_EVERY`] steps, and the run left early once every lane is
/// non-finite (where the one-cell path stops).
#[inline(always)]
fn lanes<K: Kernel>(
    c: &Constants,
    start: &Start,
    steps: u64,
    limit: &FourLanes,
    budget: Budget<'_>,
    kernel: K,
) -> Option<Tally> {
    let mut z = Cells {
        q: start.q,
        p: start.p,
        shared: [[0.0; PENDULUM_LANES]; 2],
    };
    kernel.prime(&mut z);
    let mut tally = Tally {
        sum: [0.0; PENDULUM_LANES],
        blown: [f64::INFINITY; PENDULUM_LANES],
        non_finite: [f64::INFINITY; PENDULUM_LANES],
        max: [0.0; PENDULUM_LANES],
        last: [0.0; PENDULUM_LANES],
        q: start.q,
        p: start.p,
    };
    for i in 0..PENDULUM_LANES {
        // The first sample, H₀ − H₀: zero, or NaN where H₀ is not finite.
        #[allow(clippy::eq_op)]
        let d = start.energy[i] - start.energy[i];
        tally.sum[i] += d * d;
        let within = d.abs() <= limit[i];
        if !within {
            tally.blown[i] = 0.0;
        }
        // An idle lane counts as stopped from the start.
        if start.idle[i] {
            tally.non_finite[i] = 0.0;
        }
    }
    let mut energy = [0.0; PENDULUM_LANES];
    let mut step = 0u64;
    while step < steps {
        // Before the budget: lanes that are all done (diverged or idle) have their outcome.
        if tally.non_finite.iter().all(|&s| s != f64::INFINITY) {
            break;
        }
        if budget
            .cancel
            .is_some_and(|flag| flag.load(Ordering::Relaxed))
            || budget.deadline.is_some_and(|d| Instant::now() >= d)
        {
            return None;
        }
        let until = (step + CHECK_EVERY).min(steps);
        let (block, at_block) = (step, z);
        while step < until {
            step += 1;
            kernel.step(c, &mut z, &mut energy);
            let at = step as f64;
            for i in 0..PENDULUM_LANES {
                // `&`, not `&&`: no branches in the lane loop.
                let finite = (z.q[0][i].abs() < f64::INFINITY)
                    & (z.q[1][i].abs() < f64::INFINITY)
                    & (z.p[0][i].abs() < f64::INFINITY)
                    & (z.p[1][i].abs() < f64::INFINITY);
                let d = energy[i] - start.energy[i];
                // NaN compares false: a non-finite energy has blown up too.
                let within = d.abs() <= limit[i];
                tally.sum[i] += d * d;
                // The step numbers grow: the minimum keeps the first.
                let first = |seen: f64, fine: bool| if fine { seen } else { seen.min(at) };
                tally.non_finite[i] = first(tally.non_finite[i], finite);
                tally.blown[i] = first(tally.blown[i], within);
                {
                    // As the sweep's measure: the largest magnitude (`f64::max`, written as the
                    // comparison it is here, where the running maximum is never NaN: one
                    // `maxpd`) and the last deviation.
                    let size = d.abs();
                    tally.max[i] = if size > tally.max[i] {
                        size
                    } else {
                        tally.max[i]
                    };
                    tally.last[i] = d;
                }
            }
        }
        {
            // A lane whose state stopped being finite in this block ends, as the one-cell path
            // does, with the state of the step before: run again from the block's start up to
            // that step (the lanes do not touch each other, so its bits are the ones it had).
            for i in 0..PENDULUM_LANES {
                let stopped = tally.non_finite[i];
                if stopped > block as f64 && stopped <= until as f64 {
                    let mut again = at_block;
                    let mut scratch = [0.0; PENDULUM_LANES];
                    for _ in block + 1..stopped as u64 {
                        kernel.step(c, &mut again, &mut scratch);
                    }
                    for k in 0..2 {
                        tally.q[k][i] = again.q[k][i];
                        tally.p[k][i] = again.p[k][i];
                    }
                }
            }
        }
    }
    {
        // The others end where the run ends.
        for i in 0..PENDULUM_LANES {
            if tally.non_finite[i] == f64::INFINITY {
                for k in 0..2 {
                    tally.q[k][i] = z.q[k][i];
                    tally.p[k][i] = z.p[k][i];
                }
            }
        }
    }
    Some(tally)
}

/// The Cartesian chart, H = |p|²/2m + ½k(|q| − l)² − m g y, through the composer's kick
/// (p ← p − h∇V(q)) and drift (q ← q + h·(p·(1/m))); `KICK_FIRST` is symplectic Euler,
/// otherwise its adjoint. `shared` holds |q|.
struct Cartesian<const KICK_FIRST: bool>;

impl<const KICK_FIRST: bool> Cartesian<KICK_FIRST> {
    #[inline(always)]
    fn norm(z: &mut Cells) {
        for i in 0..PENDULUM_LANES {
            z.shared[0][i] = (z.q[0][i] * z.q[0][i] + z.q[1][i] * z.q[1][i]).sqrt();
        }
    }

    #[inline(always)]
    fn kick(c: &Constants, z: &mut Cells) {
        for i in 0..PENDULUM_LANES {
            let factor = if c.k == 0.0 {
                0.0
            } else {
                c.k * (1.0 - c.l / z.shared[0][i])
            };
            z.p[0][i] += -c.h * (factor * z.q[0][i]);
            z.p[1][i] += -c.h * (factor * z.q[1][i] - c.mg);
        }
    }

    #[inline(always)]
    fn drift(c: &Constants, z: &mut Cells) {
        for i in 0..PENDULUM_LANES {
            z.q[0][i] += c.h * (z.p[0][i] * c.inv_m);
            z.q[1][i] += c.h * (z.p[1][i] * c.inv_m);
        }
        Self::norm(z);
    }
}

impl<const KICK_FIRST: bool> Kernel for Cartesian<KICK_FIRST> {
    #[inline(always)]
    fn prime(&self, z: &mut Cells) {
        Self::norm(z);
    }

    #[inline(always)]
    fn step(&self, c: &Constants, z: &mut Cells, energy: &mut FourLanes) {
        if KICK_FIRST {
            Self::kick(c, z);
            Self::drift(c, z);
        } else {
            Self::drift(c, z);
            Self::kick(c, z);
        }
        for i in 0..PENDULUM_LANES {
            let (px, py) = (z.p[0][i], z.p[1][i]);
            let kinetic = 0.5 * (px * px + py * py) / c.m;
            let stretch = z.shared[0][i] - c.l;
            energy[i] = kinetic + (c.half_k * stretch * stretch - c.mg * z.q[1][i]);
        }
    }
}

/// The polar chart, H = (p_r² + p_θ²/r²)/2m + ½k(r − l)² − m g r cos θ, through its closed-form
/// stages; `MOMENTUM_FIRST` is symplectic Euler, otherwise its adjoint. `shared` holds
/// (sin θ, cos θ).
struct Polar<const MOMENTUM_FIRST: bool>;

impl<const MOMENTUM_FIRST: bool> Polar<MOMENTUM_FIRST> {
    /// sin θ, cos θ: the library's, lane by lane.
    #[inline(always)]
    fn turn(z: &mut Cells) {
        for i in 0..PENDULUM_LANES {
            (z.shared[0][i], z.shared[1][i]) = z.q[1][i].sin_cos();
        }
    }
}

impl<const MOMENTUM_FIRST: bool> Kernel for Polar<MOMENTUM_FIRST> {
    #[inline(always)]
    fn prime(&self, z: &mut Cells) {
        Self::turn(z);
    }

    #[inline(always)]
    fn step(&self, c: &Constants, z: &mut Cells, energy: &mut FourLanes) {
        if MOMENTUM_FIRST {
            // p_θ first (∂H/∂θ holds no p), p_r with the new p_θ, then q with the new p and the
            // old r.
            for i in 0..PENDULUM_LANES {
                let (r, pr, pt) = (z.q[0][i], z.p[0][i], z.p[1][i]);
                let (sin, cos) = (z.shared[0][i], z.shared[1][i]);
                let pt1 = pt - c.hmg * r * sin;
                let dh_dr = -pt1 * pt1 / (c.m * r * r * r) + c.k * (r - c.l) - c.mg * cos;
                let pr1 = pr - c.h * dh_dr;
                z.p[0][i] = pr1;
                z.p[1][i] = pt1;
                z.q[0][i] += c.h * (pr1 / c.m);
                z.q[1][i] += c.h * (pt1 / (c.m * r * r));
            }
            Self::turn(z);
        } else {
            // r first (ṙ holds no q), θ with the new r, then p from ∂H/∂q at the new q.
            for i in 0..PENDULUM_LANES {
                let r1 = z.q[0][i] + c.h * z.p[0][i] / c.m;
                z.q[0][i] = r1;
                z.q[1][i] += c.h * z.p[1][i] / (c.m * r1 * r1);
            }
            Self::turn(z);
            for i in 0..PENDULUM_LANES {
                let (r1, pt) = (z.q[0][i], z.p[1][i]);
                let (sin, cos) = (z.shared[0][i], z.shared[1][i]);
                let mut dh_dr = c.k * (r1 - c.l) - c.mg * cos;
                dh_dr -= pt * pt / (c.m * r1 * r1 * r1);
                let dh_dth = c.mg * r1 * sin;
                z.p[0][i] += -c.h * dh_dr;
                z.p[1][i] += -c.h * dh_dth;
            }
        }
        for i in 0..PENDULUM_LANES {
            let (r, pr, pt, cos) = (z.q[0][i], z.p[0][i], z.p[1][i], z.shared[1][i]);
            let kinetic = 0.5 * (pr * pr + pt * pt / (r * r)) / c.m;
            let stretch = r - c.l;
            energy[i] = kinetic + (c.half_k * stretch * stretch - c.mg * r * cos);
        }
    }
}
