//! Plain runs (no deviation vectors) of a composition of kicks, drifts and exact damping flows
//! (modin_3s, csv1, velocity Verlet and their compositions, …) on a separable system with
//! constant mass, [`LANES`] runs side by side: a sweep's cells, which may differ in their
//! initial states, their damping rates and, through one system per lane
//! ([`EachLane`](super::each::EachLane)), any parameter.
//!
//! A stretch between samples goes as the one-run composer takes it (`Stepper::advance`): the
//! last flow of each step and the first of the next applied as one where they fuse (the seam),
//! the whole last step at the stretch's end, and a lane whose state stops being finite inside
//! the stretch taken again step by step from the stretch's start, so that it ends at the step
//! where single steps end it, while the others keep the fused stretch. Each flow does the
//! composer's arithmetic in its order, and the force is evaluated again only after a drift (the
//! composer's force cache), so the evaluations count the same.
//!
//! A system with compiled steps ([`LaneForces::compiled_forces_in_lanes`]: a typed-in system,
//! or the built-in Hénon–Heiles system, for the plans their one-run stretches take) runs the
//! lanes' stretches through code compiled for them once it has it, with the same bits: the force
//! is then written into the step instead of called lane by lane (through a pointer, for a
//! typed-in system).

// Lanes and components are indexed side by side: loops over lane numbers are the form the
// compiler vectorises.
#![allow(clippy::needless_range_loop)]

use crate::flows::compiled::{LazyCode, StretchPlan};
use crate::flows::SubFlow;
use crate::flows::{self, Pack};
use crate::methods::splitting;
use crate::run::driver::{LaneEnd, LaneEnds};

use super::Isa;

pub use crate::system::{Lane, LaneForces, LANES};

/// A flow of the sequence with its time τ = fraction · h.
#[derive(Clone, Copy, Debug)]
enum RunFlow {
    Drift(f64),
    Kick(f64),
    /// The exact damping flow, with the lanes' coefficients c = 1 − e^{−rτ} at this index of
    /// [`RunLanes::decay`].
    Damp(f64, usize),
}

/// The lanes' state: q, p, the force at q and whether it is valid, and the force evaluations
/// so far. A stretch runs on a local copy, which the compiler may keep in registers across the
/// flows (the fields of the lanes would go through memory at every flow).
#[derive(Clone, Copy, Debug)]
struct Phase<const N: usize> {
    q: [Lane; N],
    p: [Lane; N],
    grad: [Lane; N],
    grad_valid: bool,
    force_evaluations: u64,
}

/// The plain runs of [`LANES`] cells.
#[derive(Clone, Debug)]
pub struct RunLanes<const N: usize> {
    flows: Vec<RunFlow>,
    /// The last flow and the first of the next step applied as one over their summed time.
    seam: Option<RunFlow>,
    /// Per damping flow (and fused seam of two), each lane's c = 1 − e^{−rτ}, computed as the
    /// one-run composer computes it for that lane's rate.
    decay: Vec<Lane>,
    phase: Phase<N>,
    isa: Isa,
    /// The one-run composer's plan of the same flows, for a system with compiled steps
    /// ([`LaneForces::compiled_forces_in_lanes`]); `None` when the lanes' rates differ (their
    /// systems differ then).
    plan: Option<Plan>,
    compiled: LazyCode,
}

/// A [`StretchPlan`]'s parts, as the composer prepares them for h.
#[derive(Clone, Debug)]
struct Plan {
    flows: Vec<(SubFlow, f64)>,
    coefficients: Vec<(f64, f64)>,
    seam: Option<(f64, (f64, f64))>,
    h: f64,
}

impl Plan {
    /// The composer's coefficients and seam for `flows` at step `h` and damping rate `r`.
    fn new(flows: &[(SubFlow, f64)], r: f64, h: f64) -> Self {
        Plan {
            flows: flows.to_vec(),
            coefficients: flows
                .iter()
                .map(|&(flow, fraction)| flow.coefficients(r, fraction * h))
                .collect(),
            seam: splitting::seam(flows, r, h),
            h,
        }
    }
}

impl<const N: usize> RunLanes<N> {
    /// The lanes of the splitting `flows` at step `h` on systems of damping rates `rates` (one
    /// per lane; lanes past the last take the first's), all at the origin. `None` unless every
    /// flow is a kick, a drift or the exact damping flow: without damping (r = 0) a θ-kick is a
    /// kick too, to the bit (its state update is the kick's).
    pub fn new(flows: &[(SubFlow, f64)], rates: &[f64], h: f64) -> Option<Self> {
        let first_rate = *rates.first()?;
        if rates.len() > LANES {
            return None;
        }
        let rate = |l: usize| rates.get(l).copied().unwrap_or(first_rate);
        let undamped = rates.iter().all(|&r| r == 0.0);
        let mut decay = Vec::new();
        let mut lane_flow = |flow: SubFlow, tau: f64| match flow {
            SubFlow::Drift => Some(RunFlow::Drift(tau)),
            SubFlow::Kick => Some(RunFlow::Kick(tau)),
            SubFlow::DampedKick(_) if undamped => Some(RunFlow::Kick(tau)),
            SubFlow::Damp => {
                // The composer's coefficient for each lane's rate.
                let mut c = [0.0; LANES];
                for (l, c) in c.iter_mut().enumerate() {
                    *c = flows::damp_coefficient(rate(l), tau);
                }
                decay.push(c);
                Some(RunFlow::Damp(tau, decay.len() - 1))
            }
            _ => None,
        };
        let sequence = flows
            .iter()
            .map(|&(flow, fraction)| lane_flow(flow, fraction * h))
            .collect::<Option<Vec<_>>>()?;
        // The composer's seam: the same kinds, and the same time (b + a)·h.
        let seam = match (flows.first(), flows.last()) {
            (Some(&(first, a)), Some(&(last, b))) if flows.len() > 2 && last.fuses_with(first) => {
                Some(lane_flow(first, (b + a) * h)?)
            }
            _ => None,
        };
        let zero = [[0.0; LANES]; N];
        let one_rate = rates.iter().all(|&r| r.to_bits() == first_rate.to_bits());
        Some(RunLanes {
            flows: sequence,
            seam,
            decay,
            plan: one_rate.then(|| Plan::new(flows, first_rate, h)),
            compiled: LazyCode::default(),
            phase: Phase {
                q: zero,
                p: zero,
                grad: zero,
                grad_valid: false,
                force_evaluations: 0,
            },
            isa: Isa::detect(),
        })
    }

    /// Lane `l`'s state (q, p).
    pub fn state(&self, l: usize) -> ([f64; N], [f64; N]) {
        let mut state = ([0.0; N], [0.0; N]);
        for i in 0..N {
            state.0[i] = self.phase.q[i][l];
            state.1[i] = self.phase.p[i][l];
        }
        state
    }

    /// Per lane: whether every |qᵢ| ≤ `q_bounds[i]` and |pᵢ| ≤ `p_bounds[i]` (not where a
    /// component is NaN), all lanes at once.
    pub fn within(&self, q_bounds: &[f64; N], p_bounds: &[f64; N]) -> [bool; LANES] {
        let mut inside = [true; LANES];
        for i in 0..N {
            for l in 0..LANES {
                // `&`, not `&&`: no branches in the lane loop.
                inside[l] &= (self.phase.q[i][l].abs() <= q_bounds[i])
                    & (self.phase.p[i][l].abs() <= p_bounds[i]);
            }
        }
        inside
    }

    /// Sets lane `l`'s state.
    pub fn set_state(&mut self, l: usize, q: &[f64], p: &[f64]) {
        for i in 0..N {
            self.phase.q[i][l] = q[i];
            self.phase.p[i][l] = p[i];
        }
        self.phase.grad_valid = false;
    }

    /// Force evaluations so far (every lane has taken the same).
    pub fn force_evaluations(&self) -> u64 {
        self.phase.force_evaluations
    }

    /// Up to `n` steps of every lane, as the one-run path's `Stepper::advance` takes a stretch
    /// between samples (see the module docs). Lanes not `watched` are never looked at.
    pub fn advance<S: LaneForces<N>>(
        &mut self,
        sys: &S,
        n: u64,
        watched: &[bool; LANES],
    ) -> LaneEnds {
        if let Some(ended) = self.advance_compiled(sys, n, watched) {
            return ended;
        }
        match self.isa {
            // SAFETY: the CPU supports AVX-512F, detected when the lanes were made.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => unsafe { self.advance_avx512(sys, n, watched) },
            // SAFETY: the CPU supports AVX2, detected when the lanes were made.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe { self.advance_avx2(sys, n, watched) },
            _ => self.advance_portable(sys, n, watched),
        }
    }

    /// The stretch through the system's compiled lanes, if it has them by now: the same bits as
    /// [`Self::advance_portable`], lane by lane (every lane takes the stretch; those that left
    /// go again step by step). `None` when the generic lanes are to take it. Where a lane is
    /// watched, the stretch runs on a copy of the lanes, kept unless a lane left; where none is
    /// (a basin map's lanes, whose observers look at the states themselves), nothing can go
    /// again and it runs on the lanes in place. Single steps (a sweep sampled every step) come
    /// here too, although the copy in and out was then a cost the generic lanes, which work in
    /// place, did not have: with the lanes in f64×2 vectors the typed-in Hénon–Heiles sweep
    /// sampled every step took 24.6–25.3 ns per cell-step so, against 28.3–28.4 on the generic
    /// lanes (with scalar compiled lanes it was 33.9 against 31.2). A system whose generic lanes
    /// inline its force keeps its single steps there ([`LaneForces::single_steps_compiled`]).
    fn advance_compiled<S: LaneForces<N>>(
        &mut self,
        sys: &S,
        n: u64,
        watched: &[bool; LANES],
    ) -> Option<LaneEnds> {
        if n == 0 || (n == 1 && !sys.single_steps_compiled()) {
            return None;
        }
        let plan = self.plan.as_ref()?;
        let stretch = StretchPlan {
            flows: &plan.flows,
            coefficients: &plan.coefficients,
            h: plan.h,
            seam: plan.seam,
        };
        let code = self.compiled.get(n, |steps| {
            sys.compiled_forces_in_lanes()?
                .lanes_stretch(&stretch, steps)
        })?;
        let run = |phase: &mut Phase<N>| {
            code.run_lanes(
                phase.q.as_flattened_mut(),
                phase.p.as_flattened_mut(),
                phase.grad.as_flattened_mut(),
                &mut phase.grad_valid,
                &mut phase.force_evaluations,
                n,
            )
        };
        if !watched.contains(&true) {
            // No lane goes again step by step: the stretch runs on the lanes in place.
            run(&mut self.phase);
            return Some([None; LANES]);
        }
        let mut phase = self.phase;
        let not_finite = run(&mut phase);
        let left = std::array::from_fn(|l| watched[l] & not_finite[l]);
        Some(self.keep(sys, n, phase, &left))
    }

    /// [`Self::advance_portable`] compiled with AVX-512 (f64×8 registers).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn advance_avx512<S: LaneForces<N>>(
        &mut self,
        sys: &S,
        n: u64,
        watched: &[bool; LANES],
    ) -> LaneEnds {
        self.advance_portable(sys, n, watched)
    }

    /// [`Self::advance_portable`] compiled with AVX2 (f64×4 registers).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn advance_avx2<S: LaneForces<N>>(
        &mut self,
        sys: &S,
        n: u64,
        watched: &[bool; LANES],
    ) -> LaneEnds {
        self.advance_portable(sys, n, watched)
    }

    #[inline(always)]
    fn advance_portable<S: LaneForces<N>>(
        &mut self,
        sys: &S,
        n: u64,
        watched: &[bool; LANES],
    ) -> LaneEnds {
        let seam = match self.seam {
            Some(seam) if n >= 2 => seam,
            _ => return self.steps_ended(sys, n, watched, false),
        };
        let mut phase = self.phase;
        let (flows, decay) = (&self.flows[..], &self.decay[..]);
        let m = flows.len();
        let mut left = [false; LANES];
        phase.apply(sys, flows[0], decay);
        for done in 1..=n {
            for &flow in &flows[1..m - 1] {
                phase.apply(sys, flow, decay);
            }
            phase.apply(sys, if done < n { seam } else { flows[m - 1] }, decay);
            let not_finite = phase.not_finite();
            for l in 0..LANES {
                left[l] |= watched[l] & not_finite[l];
            }
        }
        self.keep(sys, n, phase, &left)
    }

    /// Keeps `phase`, the lanes after a stretch of `n` steps from `self.phase`, except for the
    /// lanes that `left` (their state stopped being finite), which go again step by step.
    #[inline(always)]
    fn keep<S: LaneForces<N>>(
        &mut self,
        sys: &S,
        n: u64,
        phase: Phase<N>,
        left: &[bool; LANES],
    ) -> LaneEnds {
        if !left.contains(&true) {
            self.phase = phase;
            return [None; LANES];
        }
        // The lanes that left: step by step from the stretch's start. The others keep the
        // stretch, with its force cache and count (those of single steps too, when they run to
        // the end).
        let ended = self.steps_ended(sys, n, left, true);
        for l in (0..LANES).filter(|&l| !left[l]) {
            for i in 0..N {
                self.phase.q[i][l] = phase.q[i][l];
                self.phase.p[i][l] = phase.p[i][l];
                self.phase.grad[i][l] = phase.grad[i][l];
            }
        }
        self.phase.grad_valid = phase.grad_valid;
        self.phase.force_evaluations = phase.force_evaluations;
        ended
    }

    /// Up to `n` single steps; each `watched` lane ends at its first step whose state does not
    /// sum to a finite number. With `until_all_ended`, stops once every watched lane has ended.
    #[inline(always)]
    fn steps_ended<S: LaneForces<N>>(
        &mut self,
        sys: &S,
        n: u64,
        watched: &[bool; LANES],
        until_all_ended: bool,
    ) -> LaneEnds {
        let mut ended = [None; LANES];
        let mut open = *watched;
        let (flows, decay) = (&self.flows[..], &self.decay[..]);
        let phase = &mut self.phase;
        for done in 0..n {
            for &flow in flows {
                phase.apply(sys, flow, decay);
            }
            let not_finite = phase.not_finite();
            for l in 0..LANES {
                if open[l] && not_finite[l] {
                    open[l] = false;
                    ended[l] = Some(LaneEnd {
                        steps: done + 1,
                        force_evaluations: phase.force_evaluations,
                        diverged: !(0..N)
                            .all(|i| phase.q[i][l].is_finite() && phase.p[i][l].is_finite()),
                    });
                }
            }
            if until_all_ended && !open.contains(&true) {
                break;
            }
        }
        ended
    }
}

impl<const N: usize> Phase<N> {
    /// One flow of every lane.
    #[inline(always)]
    fn apply<S: LaneForces<N>>(&mut self, sys: &S, flow: RunFlow, decay: &[Lane]) {
        match flow {
            RunFlow::Drift(tau) => {
                let mut v = [[0.0; LANES]; N];
                sys.velocity_lanes(&self.p, &mut v);
                flows::drift(Pack::of_mut(&mut self.q), Pack::of(&v), Pack::splat(tau));
                self.grad_valid = false;
            }
            RunFlow::Kick(tau) => {
                if !self.grad_valid {
                    sys.grad_lanes(&self.q, &mut self.grad);
                    self.force_evaluations += 1;
                    self.grad_valid = true;
                }
                flows::kick(
                    Pack::of_mut(&mut self.p),
                    Pack::of(&self.grad),
                    Pack::splat(tau),
                );
            }
            // q, and with it the force, stays.
            RunFlow::Damp(tau, k) => sys.damp_lanes(&self.q, &mut self.p, tau, &decay[k]),
        }
    }

    /// Per lane: whether the state's components fail to sum to a finite number (summed as the
    /// one-run path sums them, positions then momenta).
    #[inline(always)]
    fn not_finite(&self) -> [bool; LANES] {
        let mut not_finite = [false; LANES];
        for l in 0..LANES {
            let (mut sq, mut sp) = (0.0, 0.0);
            for i in 0..N {
                sq += self.q[i][l];
                sp += self.p[i][l];
            }
            not_finite[l] = !(sq + sp).is_finite();
        }
        not_finite
    }
}
