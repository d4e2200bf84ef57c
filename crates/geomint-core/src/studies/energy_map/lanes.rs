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
//!
//! The runs go through the lanes' run loop ([`drive_lanes`]) as every other group of lanes
//! does: the lanes are a [`LaneGroup`] whose stretches tally every step, each run a
//! [`LaneRun`] that ends at its last step or where its state stops being finite.

// The lanes are indexed side by side in several arrays at once: loops over lane numbers are the
// form the compiler vectorises.
#![allow(clippy::needless_range_loop)]

use std::ops::ControlFlow;

use crate::diagnostics::DIVERGENCE;
use crate::flows;
use crate::methods::lanes::Isa;
use crate::methods::{Method, MethodId};
use crate::run::driver::{drive_lanes, LaneEnd, LaneGroup, LaneRun, LaneStretch};
use crate::run::{Budget, RunEnd};
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

/// A run's start in its chart, as the one-cell path prepares it.
#[derive(Clone, Copy, Debug)]
pub struct TallyStart {
    /// q₀.
    pub q: [f64; 2],
    /// p₀.
    pub p: [f64; 2],
    /// H(q₀, p₀) as the one-cell path computes it.
    pub energy: f64,
}

/// What a run's steps leave: the sum of eq. (50), the first steps at which the run left the
/// energy band and the finite numbers (∞: never), the largest and the last |H − H₀|, and the
/// state the one-run path ends with.
#[derive(Clone, Copy, Debug)]
pub struct Tally {
    /// Σ (H − H₀)² over the samples, the first included.
    pub sum: f64,
    /// The first step whose energy left the band.
    pub blown: f64,
    /// The first step whose state is not finite, where the run ended.
    pub non_finite: f64,
    /// The largest |H − H₀| (sweeps only).
    pub max: f64,
    /// The last H − H₀ (sweeps only).
    pub last: f64,
    /// The last finite state, as the one-cell path's last sample (sweeps only).
    pub q: [f64; 2],
    /// Its momenta.
    pub p: [f64; 2],
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

    /// `steps` steps of size `h` from each of `starts`, [`PENDULUM_LANES`] at a time (a lane
    /// whose run ends takes the next), each measured against its H₀ at every step; `None` when
    /// the budget stopped them.
    pub fn tally(
        &self,
        starts: &[TallyStart],
        h: f64,
        steps: u64,
        budget: Budget<'_>,
    ) -> Option<Vec<Tally>> {
        let mut group = TallyGroup::new(self, h);
        let mut tallies = vec![None; starts.len()];
        let runs = starts.iter().map(|&start| TallyRun { start, steps });
        drive_lanes(&mut group, runs, budget, |i, tally| tallies[i] = tally);
        // A run the budget stopped, or never started, has none.
        tallies.into_iter().collect()
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

/// The lanes of a [`LaneKernel`] as a [`LaneGroup`]: the runs' states, and per lane what its
/// run's steps have tallied.
struct TallyGroup {
    cartesian: PlanarCartesian,
    polar: PlanarPolar,
    chart: Chart,
    order: EulerOrder,
    isa: Isa,
    h: f64,
    lanes: TallyLanes,
}

/// The lanes' states and tallies. Steps are counted from the group's start, so that the lanes
/// compare and select them in SIMD registers (as f64, exact to 2⁵³); a run's own count is
/// that less the step at which it entered.
struct TallyLanes {
    z: Cells,
    /// The group's steps so far.
    taken: u64,
    /// Per lane: the group's step at which its run entered, its H₀ and its energy band.
    entered: FourLanes,
    energy0: FourLanes,
    limit: FourLanes,
    sum: FourLanes,
    blown: FourLanes,
    /// ∞ while the lane's state is finite (an empty lane counts as stopped from the start).
    non_finite: FourLanes,
    max: FourLanes,
    last: FourLanes,
    /// Per lane whose state stopped being finite: the state of the step before.
    before: ([FourLanes; 2], [FourLanes; 2]),
}

/// `$body` with `$kernel` bound to the group's chart and order: one kernel type per pair, each
/// a loop the compiler specialises.
macro_rules! with_chart_kernel {
    ($group:expr, $kernel:ident => $body:expr) => {
        match ($group.chart, $group.order) {
            (Chart::Cartesian, EulerOrder::MomentumFirst) => {
                let $kernel = Cartesian::<true>(&$group.cartesian);
                $body
            }
            (Chart::Cartesian, EulerOrder::PositionFirst) => {
                let $kernel = Cartesian::<false>(&$group.cartesian);
                $body
            }
            (Chart::Polar, EulerOrder::MomentumFirst) => {
                let $kernel = Polar::<true>(&$group.polar);
                $body
            }
            (Chart::Polar, EulerOrder::PositionFirst) => {
                let $kernel = Polar::<false>(&$group.polar);
                $body
            }
        }
    };
}

impl TallyGroup {
    fn new(kernel: &LaneKernel, h: f64) -> Self {
        let empty = [0.0; PENDULUM_LANES];
        TallyGroup {
            cartesian: PlanarCartesian(kernel.pendulum.clone()),
            polar: PlanarPolar(kernel.pendulum.clone()),
            chart: kernel.chart,
            order: kernel.order,
            isa: kernel.isa,
            h,
            lanes: TallyLanes {
                z: Cells {
                    q: [empty; 2],
                    p: [empty; 2],
                    shared: [empty; 2],
                },
                taken: 0,
                entered: empty,
                energy0: empty,
                limit: empty,
                sum: empty,
                blown: empty,
                non_finite: empty,
                max: empty,
                last: empty,
                before: ([empty; 2], [empty; 2]),
            },
        }
    }

    /// Loads `start` into lane `l`, with its first sample, H₀ − H₀: zero, or NaN where H₀ is
    /// not finite.
    fn load(&mut self, l: usize, start: &TallyStart) {
        let lanes = &mut self.lanes;
        for k in 0..2 {
            lanes.z.q[k][l] = start.q[k];
            lanes.z.p[k][l] = start.p[k];
        }
        // What the chart shares between steps, for every lane: the others' is what it was,
        // since it is a function of q alone.
        with_chart_kernel!(self, kernel => kernel.prime(&mut lanes.z));
        let at = lanes.taken as f64;
        let limit = DIVERGENCE * (1.0 + start.energy.abs());
        #[allow(clippy::eq_op)]
        let d = start.energy - start.energy;
        lanes.entered[l] = at;
        lanes.energy0[l] = start.energy;
        lanes.limit[l] = limit;
        lanes.sum[l] = 0.0;
        lanes.sum[l] += d * d;
        lanes.blown[l] = if d.abs() <= limit { f64::INFINITY } else { at };
        lanes.non_finite[l] = f64::INFINITY;
        lanes.max[l] = 0.0;
        lanes.last[l] = 0.0;
    }

    /// Lane `l`'s tally, its steps counted from its run's start.
    fn report(&self, l: usize) -> Tally {
        let lanes = &self.lanes;
        let entered = lanes.entered[l];
        let (q, p) = if lanes.non_finite[l] == f64::INFINITY {
            (&lanes.z.q, &lanes.z.p)
        } else {
            (&lanes.before.0, &lanes.before.1)
        };
        Tally {
            sum: lanes.sum[l],
            blown: lanes.blown[l] - entered,
            non_finite: lanes.non_finite[l] - entered,
            max: lanes.max[l],
            last: lanes.last[l],
            q: [q[0][l], q[1][l]],
            p: [p[0][l], p[1][l]],
        }
    }

    /// `n` steps of every lane, in the build for the group's instruction set.
    fn steps(&mut self, n: u64, running: &[bool; PENDULUM_LANES]) {
        #[cfg(target_arch = "x86_64")]
        if self.isa != Isa::Portable {
            // SAFETY: the CPU supports AVX2: `isa` is one it has (detected, or checked by
            // `LaneKernel::with_isa`), and both wider ones imply AVX2.
            return unsafe { steps_avx2(self, n, running) };
        }
        steps_portable(self, n, running)
    }
}

impl LaneGroup<PENDULUM_LANES> for TallyGroup {
    /// The stretch; the runs whose state stopped being finite inside it end there.
    fn advance(&mut self, n: u64, running: &[bool; PENDULUM_LANES]) -> LaneStretch<PENDULUM_LANES> {
        let block = self.lanes.taken;
        self.steps(n, running);
        let stopped_in = |l: usize| {
            let stopped = self.lanes.non_finite[l];
            (running[l] && stopped > block as f64 && stopped != f64::INFINITY)
                .then_some(stopped as u64)
        };
        LaneStretch {
            steps: n,
            ended: std::array::from_fn(|l| {
                stopped_in(l).map(|stopped| LaneEnd {
                    steps: stopped - block,
                    // One force evaluation per step.
                    force_evaluations: stopped,
                    diverged: true,
                })
            }),
        }
    }
}

/// An energy map's run in a lane: it ends at its last step, or where its state stops being
/// finite.
struct TallyRun {
    start: TallyStart,
    steps: u64,
}

impl LaneRun<TallyGroup, PENDULUM_LANES> for TallyRun {
    type Report = Option<Tally>;

    fn enter(&mut self, group: &mut TallyGroup, l: usize) -> ControlFlow<Self::Report> {
        group.load(l, &self.start);
        if self.steps == 0 {
            return ControlFlow::Break(Some(group.report(l)));
        }
        ControlFlow::Continue(())
    }

    fn next_look(&self, _step: u64) -> u64 {
        self.steps
    }

    fn look(
        &mut self,
        group: &mut TallyGroup,
        l: usize,
        step: u64,
        end: Option<LaneEnd>,
    ) -> ControlFlow<Self::Report> {
        if end.is_some() || step == self.steps {
            return ControlFlow::Break(Some(group.report(l)));
        }
        ControlFlow::Continue(())
    }

    fn stopped(&mut self, _: &mut TallyGroup, _: usize, _: u64, _: RunEnd) -> Self::Report {
        None
    }
}

/// [`steps_portable`] compiled with AVX2 (f64×4 registers). Still no fused multiply-add, which
/// would round once where the one-cell path rounds twice: rustc never contracts a·b + c into
/// one (only `mul_add` does), whatever the target features.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn steps_avx2(group: &mut TallyGroup, n: u64, running: &[bool; PENDULUM_LANES]) {
    steps_portable(group, n, running)
}

/// The steps in the group's chart and order.
#[inline(always)]
fn steps_portable(group: &mut TallyGroup, n: u64, running: &[bool; PENDULUM_LANES]) {
    let lanes = &mut group.lanes;
    with_chart_kernel!(group, kernel => tally_steps(group.h, lanes, n, running, kernel))
}

/// The loop: every lane `n` steps, its energy deviation summed and its first blow-up noted; a
/// running lane whose state stopped being finite keeps the state of the step before, as the
/// one-cell path ends with.
#[inline(always)]
fn tally_steps<K: ChartKernel>(
    h: f64,
    lanes: &mut TallyLanes,
    n: u64,
    running: &[bool; PENDULUM_LANES],
    kernel: K,
) {
    let (block, at_block) = (lanes.taken, lanes.z);
    let until = block + n;
    let mut energy = [0.0; PENDULUM_LANES];
    while lanes.taken < until {
        lanes.taken += 1;
        kernel.step(h, &mut lanes.z, &mut energy);
        let at = lanes.taken as f64;
        let z = &lanes.z;
        for i in 0..PENDULUM_LANES {
            // `&`, not `&&`: no branches in the lane loop.
            let finite = (z.q[0][i].abs() < f64::INFINITY)
                & (z.q[1][i].abs() < f64::INFINITY)
                & (z.p[0][i].abs() < f64::INFINITY)
                & (z.p[1][i].abs() < f64::INFINITY);
            let d = energy[i] - lanes.energy0[i];
            // NaN compares false: a non-finite energy has blown up too.
            let within = d.abs() <= lanes.limit[i];
            lanes.sum[i] += d * d;
            // The step numbers grow: the minimum keeps the first.
            let first = |seen: f64, fine: bool| if fine { seen } else { seen.min(at) };
            lanes.non_finite[i] = first(lanes.non_finite[i], finite);
            lanes.blown[i] = first(lanes.blown[i], within);
            // As the sweep's measure: the largest magnitude (`f64::max`, written as the
            // comparison it is here, where the running maximum is never NaN: one `maxpd`) and
            // the last deviation.
            let size = d.abs();
            lanes.max[i] = if size > lanes.max[i] {
                size
            } else {
                lanes.max[i]
            };
            lanes.last[i] = d;
        }
    }
    // A running lane whose state stopped being finite in this stretch ends, as the one-cell
    // path does, with the state of the step before: run again from the stretch's start up to
    // that step (the lanes do not touch each other, so its bits are the ones it had).
    for i in 0..PENDULUM_LANES {
        let stopped = lanes.non_finite[i];
        if running[i] && stopped > block as f64 && stopped <= until as f64 {
            let mut again = at_block;
            let mut scratch = [0.0; PENDULUM_LANES];
            for _ in block + 1..stopped as u64 {
                kernel.step(h, &mut again, &mut scratch);
            }
            for k in 0..2 {
                lanes.before.0[k][i] = again.q[k][i];
                lanes.before.1[k][i] = again.p[k][i];
            }
        }
    }
}

/// One chart's step on all lanes, and its energy. Each operation is a loop over the lanes with
/// nothing but arithmetic in it, which the compiler turns into SIMD instructions.
trait ChartKernel {
    /// `shared` for the state as it starts.
    fn prime(&self, z: &mut Cells);
    /// One step of size `h` of every lane; H at the new states into `energy`.
    fn step(&self, h: f64, z: &mut Cells, energy: &mut FourLanes);
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
