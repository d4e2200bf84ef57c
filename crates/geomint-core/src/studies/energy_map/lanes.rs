//! Symplectic Euler and its adjoint on the planar elastic pendulum, in either chart, four runs
//! side by side. The study engine asks [`LaneKernel::of`] for a method on a system; a sweep whose
//! runs all have a kernel runs its cells four at a time (paper 001 Fig. 6's energy map is such a
//! sweep), measured against H₀ at every step.
//!
//! The lanes write no formula of their own: each lane calls the one-run path's formulas, the
//! flows' kick and drift ([`flows::kick`], [`flows::drift`]), the system's force, velocity and
//! energy, and the polar chart's closed-form stages (`PlanarPolar::momentum_stage_at` and
//! `position_stage_at`, in `systems/planar.rs`), inlined into loops over the lanes that the
//! compiler vectorises. IEEE addition, multiplication, division and square root round the same in a SIMD
//! lane as in a scalar register, so runs here are bit for bit the runs of the generic stepper
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
use crate::flows;
use crate::methods::lanes::Isa;
use crate::methods::{Method, MethodId};
use crate::run::driver::CHECK_EVERY;
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
        let (pendulum, chart, order) = (&self.pendulum, self.chart, self.order);
        #[cfg(target_arch = "x86_64")]
        if self.isa != Isa::Portable {
            // SAFETY: the CPU supports AVX2: `isa` is one it has (detected, or checked by
            // `with_isa`), and both wider ones imply AVX2.
            return unsafe {
                integrate_avx2(pendulum, h, chart, order, start, steps, &limit, budget)
            };
        }
        integrate(pendulum, h, chart, order, start, steps, &limit, budget)
    }
}

/// [`integrate`] compiled with AVX2 (f64×4 registers). Still no fused multiply-add, which would
/// round once where the one-cell path rounds twice: rustc never contracts a·b + c into one
/// (only `mul_add` does), whatever the target features.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
fn integrate_avx2(
    pendulum: &PlanarSpring,
    h: f64,
    chart: Chart,
    order: EulerOrder,
    start: &Start,
    steps: u64,
    limit: &FourLanes,
    budget: Budget<'_>,
) -> Option<Tally> {
    integrate(pendulum, h, chart, order, start, steps, limit, budget)
}

/// One kernel per (chart, order), each a loop the compiler specialises.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn integrate(
    pendulum: &PlanarSpring,
    h: f64,
    chart: Chart,
    order: EulerOrder,
    start: &Start,
    steps: u64,
    limit: &FourLanes,
    budget: Budget<'_>,
) -> Option<Tally> {
    let (cartesian, polar) = (
        PlanarCartesian(pendulum.clone()),
        PlanarPolar(pendulum.clone()),
    );
    match (chart, order) {
        (Chart::Cartesian, EulerOrder::MomentumFirst) => lanes(
            h,
            start,
            steps,
            limit,
            budget,
            Cartesian::<true>(&cartesian),
        ),
        (Chart::Cartesian, EulerOrder::PositionFirst) => lanes(
            h,
            start,
            steps,
            limit,
            budget,
            Cartesian::<false>(&cartesian),
        ),
        (Chart::Polar, EulerOrder::MomentumFirst) => {
            lanes(h, start, steps, limit, budget, Polar::<true>(&polar))
        }
        (Chart::Polar, EulerOrder::PositionFirst) => {
            lanes(h, start, steps, limit, budget, Polar::<false>(&polar))
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
trait ChartKernel {
    /// `shared` for the state as it starts.
    fn prime(&self, z: &mut Cells);
    /// One step of size `h` of every lane; H at the new states into `energy`.
    fn step(&self, h: f64, z: &mut Cells, energy: &mut FourLanes);
}

/// The loop: every lane one step, its energy deviation summed, the first blow-up noted; the
/// budget looked at every [`CHECK_EVERY`] steps, and the run left early once every lane is
/// non-finite (where the one-cell path stops).
#[inline(always)]
fn lanes<K: ChartKernel>(
    h: f64,
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
            kernel.step(h, &mut z, &mut energy);
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
                        kernel.step(h, &mut again, &mut scratch);
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

/// The Cartesian chart through the composer's flows, the kick (p ← p − h∇V(q)) and the drift
/// (q ← q + h M⁻¹p) of `flows`, with the system's own ∇V, M⁻¹p and H; `KICK_FIRST` is
/// symplectic Euler, otherwise its adjoint. `shared` holds |q|.
struct Cartesian<'s, const KICK_FIRST: bool>(&'s PlanarCartesian);

impl<const KICK_FIRST: bool> Cartesian<'_, KICK_FIRST> {
    #[inline(always)]
    fn norm(z: &mut Cells) {
        for i in 0..PENDULUM_LANES {
            z.shared[0][i] = (z.q[0][i] * z.q[0][i] + z.q[1][i] * z.q[1][i]).sqrt();
        }
    }

    #[inline(always)]
    fn kick(&self, h: f64, z: &mut Cells) {
        for i in 0..PENDULUM_LANES {
            let g = self.0.grad_with_norm(z.q[0][i], z.q[1][i], z.shared[0][i]);
            let mut p = [z.p[0][i], z.p[1][i]];
            flows::kick(&mut p, &g, h);
            [z.p[0][i], z.p[1][i]] = p;
        }
    }

    #[inline(always)]
    fn drift(&self, h: f64, z: &mut Cells) {
        for i in 0..PENDULUM_LANES {
            let v = self.0.velocity_of(z.p[0][i], z.p[1][i]);
            let mut q = [z.q[0][i], z.q[1][i]];
            flows::drift(&mut q, &v, h);
            [z.q[0][i], z.q[1][i]] = q;
        }
        Self::norm(z);
    }
}

impl<const KICK_FIRST: bool> ChartKernel for Cartesian<'_, KICK_FIRST> {
    #[inline(always)]
    fn prime(&self, z: &mut Cells) {
        Self::norm(z);
    }

    #[inline(always)]
    fn step(&self, h: f64, z: &mut Cells, energy: &mut FourLanes) {
        if KICK_FIRST {
            self.kick(h, z);
            self.drift(h, z);
        } else {
            self.drift(h, z);
            self.kick(h, z);
        }
        for i in 0..PENDULUM_LANES {
            let p = [z.p[0][i], z.p[1][i]];
            energy[i] = self.0.energy_with_norm(z.q[1][i], p, z.shared[0][i]);
        }
    }
}

/// The polar chart through the system's closed-form stages ([`PlanarPolar::momentum_stage_at`],
/// [`PlanarPolar::position_stage_at`]) and the flows of `flows` for the explicit half;
/// `MOMENTUM_FIRST` is symplectic Euler, otherwise its adjoint. `shared` holds (sin θ, cos θ).
struct Polar<'s, const MOMENTUM_FIRST: bool>(&'s PlanarPolar);

impl<const MOMENTUM_FIRST: bool> Polar<'_, MOMENTUM_FIRST> {
    /// sin θ, cos θ: the library's, lane by lane.
    #[inline(always)]
    fn turn(z: &mut Cells) {
        for i in 0..PENDULUM_LANES {
            (z.shared[0][i], z.shared[1][i]) = z.q[1][i].sin_cos();
        }
    }
}

impl<const MOMENTUM_FIRST: bool> ChartKernel for Polar<'_, MOMENTUM_FIRST> {
    #[inline(always)]
    fn prime(&self, z: &mut Cells) {
        Self::turn(z);
    }

    #[inline(always)]
    fn step(&self, h: f64, z: &mut Cells, energy: &mut FourLanes) {
        let sys = self.0;
        if MOMENTUM_FIRST {
            // p₁ from (q, p₁) in closed form, then the drift with ∂H/∂p at (q, p₁).
            for i in 0..PENDULUM_LANES {
                let (r, turn) = (z.q[0][i], (z.shared[0][i], z.shared[1][i]));
                let p1 = sys.momentum_stage_at(h, r, [z.p[0][i], z.p[1][i]], turn);
                let v = sys.velocity_at(r, p1);
                let mut q = [r, z.q[1][i]];
                flows::drift(&mut q, &v, h);
                [z.q[0][i], z.q[1][i]] = q;
                [z.p[0][i], z.p[1][i]] = p1;
            }
            Self::turn(z);
        } else {
            // q₁ from (q₁, p) in closed form, then the kick with ∂H/∂q at (q₁, p).
            for i in 0..PENDULUM_LANES {
                let q1 = sys.position_stage_at(h, [z.q[0][i], z.q[1][i]], [z.p[0][i], z.p[1][i]]);
                [z.q[0][i], z.q[1][i]] = q1;
            }
            Self::turn(z);
            for i in 0..PENDULUM_LANES {
                let turn = (z.shared[0][i], z.shared[1][i]);
                let dh_dq = sys.dh_dq_at(z.q[0][i], z.p[1][i], turn);
                let mut p = [z.p[0][i], z.p[1][i]];
                flows::kick(&mut p, &dh_dq, h);
                [z.p[0][i], z.p[1][i]] = p;
            }
        }
        for i in 0..PENDULUM_LANES {
            let p = [z.p[0][i], z.p[1][i]];
            energy[i] = sys.energy_at(z.q[0][i], p, z.shared[1][i]);
        }
    }
}
