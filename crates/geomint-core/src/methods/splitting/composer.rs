//! The composer: one splitting run, its force cache and work vectors, and the fused stretches
//! between samples.

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

use super::compiled::{LazyCode, StretchPlan};
use super::walk::{with_walk, KnownStages, Loop, Unrolled, Walk};
use super::*;
use crate::error::StepError;
use crate::flows;
use crate::methods::runge_kutta::MomentumRk;
use crate::methods::state_flows;
use crate::methods::unroll;
use crate::run::{finite, step_by_step, Advanced, Stepper};
use crate::system::{MechanicalSystem, State, Vector};
use crate::tangent::{no_projector_derivative, Tangent};

/// Runs a splitting sequence; one instance per run, so its buffers are allocated once.
pub struct Splitting<S: MechanicalSystem, Q: Flows = Composition>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    sequence: Q,
    /// Per-flow coefficients that depend on h only (the damping exponentials), for `coeff_h`.
    coefficients: Vec<(f64, f64)>,
    /// The flow that ends one step and begins the next, fused (see [`Splitting::advance`]): its
    /// time τ and coefficients for `coeff_h`, if the sequence ends and begins with one kind of
    /// flow that fuses.
    seam: Option<(f64, (f64, f64))>,
    coeff_h: f64,
    /// The system's compiled stretches for `coeff_h`.
    compiled: LazyCode,
    work: FlowScratch<S>,
}

/// What the sub-flows change besides the state: the force cache and the work vectors.
struct FlowScratch<S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    inner: Option<MomentumRk<S::Dim>>,
    grad: Vector<S::Dim>,
    grad_valid: bool,
    w1: Vector<S::Dim>,
    w2: Vector<S::Dim>,
    force_evaluations: u64,
    /// The state at the start of a fused stretch, to run it again step by step if it diverges.
    start: State<S::Dim>,
    /// The force cache at the start of a fused stretch, restored with `start` so that a rerun
    /// counts exactly the evaluations of the step-by-step run.
    start_grad: Vector<S::Dim>,
}

impl<S: MechanicalSystem, Q: Flows> Splitting<S, Q>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// A composer for `sequence`; `inner` is the Runge–Kutta method for `MomentumRk` flows.
    pub fn new(sys: &S, sequence: Q, inner: Option<MomentumRk<S::Dim>>) -> Self {
        let zero = Vector::<S::Dim>::zeros_generic(sys.dim(), nalgebra::U1);
        Self {
            coefficients: vec![(0.0, 0.0); sequence.flows().len()],
            seam: None,
            coeff_h: f64::NAN,
            compiled: LazyCode::default(),
            sequence,
            work: FlowScratch {
                inner,
                grad: zero.clone(),
                grad_valid: false,
                w1: zero.clone(),
                w2: zero.clone(),
                force_evaluations: 0,
                start: State {
                    q: zero.clone(),
                    p: zero.clone(),
                },
                start_grad: zero,
            },
        }
    }

    /// The sub-flows of one step with their fractions of h, in the order they act.
    pub fn flows(&self) -> &[(SubFlow, f64)] {
        self.sequence.flows()
    }

    /// Recomputes the h-dependent coefficients when the step size changes (once per fixed-step
    /// run; compositions of splittings are flattened into one sequence, so they too). The test
    /// is inlined into every step, the recomputation kept out of it.
    #[inline(always)]
    fn prepare(&mut self, sys: &S, h: f64) {
        if h != self.coeff_h {
            self.recompute(sys, h);
        }
    }

    #[cold]
    #[inline(never)]
    fn recompute(&mut self, sys: &S, h: f64) {
        let r = sys.damping_rate();
        let sequence = self.sequence.flows();
        for (k, &(flow, frac)) in sequence.iter().enumerate() {
            self.coefficients[k] = flow.coefficients(r, frac * h);
        }
        self.seam = seam(sequence, r, h);
        self.coeff_h = h;
        self.compiled.reset();
    }

    /// `n ≥ 1` steps through the system's compiled stretch of this splitting at the prepared h,
    /// if it has one by now ([`LazyCode`]): the bits of [`Self::advance_fused`] (of whole steps
    /// when the sequence has no seam, or for one step), and the same rerun step by step of a
    /// stretch that diverges. `None` when the generic path is to take the steps. Inlined into
    /// its one caller: returned through memory, its result stalled a watched run's every step.
    #[inline(always)]
    fn advance_compiled(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        n: u64,
    ) -> Option<Advanced> {
        let flows = self.sequence.flows();
        let plan = StretchPlan {
            flows,
            coefficients: &self.coefficients[..flows.len()],
            h: self.coeff_h,
            seam: self.seam,
        };
        let code = self
            .compiled
            .get(n, |steps| sys.compiled_forces()?.stretch(&plan, steps))?;
        let work = &mut self.work;
        let start = work.keep_start(z);
        let taken = code.run(
            z.q.as_mut_slice(),
            z.p.as_mut_slice(),
            work.grad.as_mut_slice(),
            &mut work.grad_valid,
            &mut work.force_evaluations,
            n,
        );
        if taken == n {
            return Some((n, Ok(())));
        }
        work.back_to_start(z, start);
        Some(step_by_step(self, sys, z, h, n))
    }

    /// `n ≥ 2` steps with the last flow of each step and the first of the next applied as one
    /// flow over their summed time (exact in exact arithmetic: with q frozen, or p for a drift,
    /// two flows of one autonomous field compose to the flow over the sum). The state between
    /// them is never observed, and the stretch ends with the whole last step, so the result
    /// differs from `n` separate steps only by round-off; modin_3s saves one of its two damping
    /// flows per step this way, modin_2s and position_verlet one drift. A stretch that diverges
    /// is run again step by step, so a run stops at the same step as it would unfused.
    #[inline(always)]
    fn advance_fused<W: Walk>(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        n: u64,
        (seam_tau, seam_coefficients): (f64, (f64, f64)),
    ) -> Advanced {
        let sequence = self.sequence.flows();
        let m = sequence.len();
        let coefficients = &self.coefficients[..m];
        let work = &mut self.work;
        let start = work.keep_start(z);
        let first = sequence[0];
        let last = W::kind(sequence, m - 1, W::START + W::period(sequence) - 1);
        let last_frac = sequence[m - 1].1;
        work.apply(sys, z, first.0, first.1 * h, coefficients[0]);
        for done in 1..=n {
            // The flows between the first and the last.
            walk::<W, S>(work, sys, z, h, sequence, coefficients, 1, m - 1);
            // The seam, or at the end of the stretch the last flow alone.
            let (tau, cd) = if done < n {
                (seam_tau, seam_coefficients)
            } else {
                (last_frac * h, coefficients[m - 1])
            };
            work.apply(sys, z, last, tau, cd);
            if !finite(z) {
                break;
            }
            if done == n {
                return (n, Ok(()));
            }
        }
        work.back_to_start(z, start);
        step_by_step(self, sys, z, h, n)
    }

    /// One step, walking the sequence with `W`.
    #[inline(always)]
    fn step_with<W: Walk>(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) {
        let flows = self.sequence.flows();
        // One bounds check here instead of one per flow.
        let coefficients = &self.coefficients[..flows.len()];
        walk::<W, S>(
            &mut self.work,
            sys,
            z,
            h,
            flows,
            coefficients,
            0,
            flows.len(),
        );
    }
}

impl<S: MechanicalSystem> FlowScratch<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// Keeps the state and the force cache at the start of a stretch; returns the cache's
    /// validity and the count, for [`Self::back_to_start`].
    #[inline(always)]
    fn keep_start(&mut self, z: &State<S::Dim>) -> (bool, u64) {
        self.start.q.copy_from(&z.q);
        self.start.p.copy_from(&z.p);
        self.start_grad.copy_from(&self.grad);
        (self.grad_valid, self.force_evaluations)
    }

    /// A stretch that diverged goes back to where it started, with the force cache and the
    /// count as they were, to be run again step by step: the stop step, the state and the count
    /// are then those of single steps.
    fn back_to_start(&mut self, z: &mut State<S::Dim>, (grad_valid, count): (bool, u64)) {
        z.q.copy_from(&self.start.q);
        z.p.copy_from(&self.start.p);
        self.grad.copy_from(&self.start_grad);
        self.grad_valid = grad_valid;
        self.force_evaluations = count;
    }

    /// Applies `flow` for time τ, with its h-dependent coefficients (c, d).
    #[inline(always)]
    fn apply(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        flow: SubFlow,
        tau: f64,
        (c, d): (f64, f64),
    ) {
        match flow {
            Drift => {
                state_flows::drift(sys, z, tau, &mut self.w1);
                self.grad_valid = false;
            }
            Kick => {
                self.ensure_grad(sys, &z.q);
                state_flows::kick(z, tau, &self.grad);
            }
            DampedKick(theta) => {
                self.ensure_grad(sys, &z.q);
                state_flows::kick_theta(sys, z, tau, theta.value(), &self.grad, &mut self.w1);
            }
            Damp => state_flows::damp_with(sys, z, tau, c, &mut self.w1),
            KickDamp if self.grad_valid => self.kick_damp(sys, z, tau, (c, d)),
            KickDamp => {
                // A fresh force and the kick after it are one straight line of code, in which
                // the compiler shares what both compute from q (the elastic pendulum's radial
                // coefficient; a P2' long run took 68 ms with one arm after the cache test, 51
                // ms with two).
                self.ensure_grad(sys, &z.q);
                self.kick_damp(sys, z, tau, (c, d));
            }
            MomentumRk => {
                self.ensure_grad(sys, &z.q);
                if let Some(inner) = self.inner.as_mut() {
                    inner.step(sys, z, tau, &self.grad);
                }
            }
        }
    }

    /// The kick-and-damp with the cached force.
    #[inline(always)]
    fn kick_damp(&mut self, sys: &S, z: &mut State<S::Dim>, tau: f64, (c, d): (f64, f64)) {
        state_flows::kick_damp_with(sys, z, tau, c, d, &self.grad, &mut self.w1, &mut self.w2);
    }

    #[inline]
    fn ensure_grad(&mut self, sys: &S, q: &Vector<S::Dim>) {
        if !self.grad_valid {
            sys.grad_potential(q, &mut self.grad);
            self.force_evaluations += 1;
            self.grad_valid = true;
        }
    }
}

impl<S: MechanicalSystem, Q: Flows> Stepper<S> for Splitting<S, Q>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    #[inline(always)]
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        self.prepare(sys, h);
        with_walk!(self, W => self.step_with::<W>(sys, z, h));
        Ok(())
    }

    #[inline]
    fn advance(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64, n: u64) -> Advanced {
        self.prepare(sys, h);
        if let Some(advanced) = self.advance_compiled(sys, z, h, n) {
            return advanced;
        }
        match self.seam {
            Some(seam) if n >= 2 => {
                with_walk!(self, W => self.advance_fused::<W>(sys, z, h, n, seam))
            }
            _ => step_by_step(self, sys, z, h, n),
        }
    }

    fn force_evaluations(&self) -> u64 {
        self.work.force_evaluations
    }

    fn restart(&mut self) {
        self.work.grad_valid = false;
    }

    fn step_tangent(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        tangent: &mut Tangent<S::Dim>,
    ) -> Result<(), StepError> {
        let r = sys.damping_rate();
        self.prepare(sys, h);
        let flows = self.sequence.flows();
        let projector = tangent.projector_damping();
        for (&(flow, frac), &cd) in flows.iter().zip(&self.coefficients) {
            let tau = frac * h;
            if projector && !matches!(flow, Drift | Kick) {
                self.work
                    .projector_flow_tangent(sys, z, (flow, tau, cd), tangent)?;
                continue;
            }
            // Each flow's Jacobian is taken at the state it acts on, before it moves it.
            match flow {
                Drift => tangent.drift(tau),
                Damp => tangent.kick_scaled((-r * tau).exp(), 0.0),
                Kick | DampedKick(_) | KickDamp | MomentumRk => {
                    self.work.force_evaluations += tangent.load_hessian(sys, &z.q);
                    let (a, b) = match flow {
                        Kick => (1.0, tau),
                        DampedKick(theta) => flows::kick_theta_tangent(r, tau, theta.value()),
                        KickDamp => ((-r * tau).exp(), one_minus_exp_neg_over(r, tau)),
                        _ => match self.work.inner.as_ref() {
                            Some(inner) => inner.tangent_coefficients(r, tau),
                            None => (1.0, tau),
                        },
                    };
                    tangent.kick_scaled(a, b);
                }
            }
            self.work.apply(sys, z, flow, tau, cd);
        }
        Ok(())
    }
}

impl<S: MechanicalSystem> FlowScratch<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// A damping sub-flow and its tangent map when the damping is r P(q) with P a projector
    /// that depends on q (the tangent maps of `tangent`'s module docs), the state moved too.
    fn projector_flow_tangent(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        (flow, tau, cd): (SubFlow, f64, (f64, f64)),
        tangent: &mut Tangent<S::Dim>,
    ) -> Result<(), StepError> {
        let r = sys.damping_rate();
        let unsupported = no_projector_derivative;
        if !sys.damping_is_projector() {
            return Err(StepError::TangentUnsupported {
                reason: "the exact damping flow e^{−τεD(q)M⁻¹} of a damping matrix that is not a \
                         projector has no tangent map here (rk4 and implicit_midpoint linearise \
                         the whole field)",
            });
        }
        match flow {
            Damp => {
                tangent.load_damping(sys, &z.q, &z.p)?;
                tangent.decay_projector(cd.0);
            }
            KickDamp => {
                self.ensure_grad(sys, &z.q);
                self.force_evaluations += tangent.load_hessian(sys, &z.q);
                let (c, d) = cd;
                self.w2.copy_from(&z.p);
                self.w2 *= -c;
                self.w2.axpy(d, &self.grad, 1.0);
                if !tangent.load_projector(sys, &z.q, &self.w2) {
                    return Err(unsupported());
                }
                tangent.kick_damp_projector(tau, c, d);
            }
            DampedKick(theta) => {
                let theta = theta.value();
                self.force_evaluations += tangent.load_hessian(sys, &z.q);
                tangent.load_damping(sys, &z.q, &z.p)?;
                tangent.theta_kick_projector_before(tau, (1.0 - theta) * r * tau);
                self.apply(sys, z, flow, tau, cd);
                if !tangent.load_projector_derivative(sys, &z.q, &z.p) {
                    return Err(unsupported());
                }
                tangent.theta_kick_projector_after(theta * r * tau);
                return Ok(());
            }
            MomentumRk => {
                self.ensure_grad(sys, &z.q);
                self.force_evaluations += tangent.load_hessian(sys, &z.q);
                let (a, b) = match self.inner.as_ref() {
                    Some(inner) => inner.tangent_coefficients(r, tau),
                    None => (1.0, tau),
                };
                self.w2.copy_from(&z.p);
                self.w2 *= a - 1.0;
                self.w2.axpy(-(b - tau), &self.grad, 1.0);
                if !tangent.load_projector(sys, &z.q, &self.w2) {
                    return Err(unsupported());
                }
                tangent.momentum_rk_projector(tau, (a, b));
            }
            Drift | Kick => unreachable!("drifts and kicks do not involve the damping"),
        }
        self.apply(sys, z, flow, tau, cd);
        Ok(())
    }
}

/// Applies `flows[lo..hi]` to `z` with their h-dependent coefficients, walking with `W`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn walk<W: Walk, S: MechanicalSystem>(
    work: &mut FlowScratch<S>,
    sys: &S,
    z: &mut State<S::Dim>,
    h: f64,
    flows: &[(SubFlow, f64)],
    coefficients: &[(f64, f64)],
    lo: usize,
    hi: usize,
) where
    DefaultAllocator: Allocator<S::Dim>,
{
    let (start, period) = (W::START, W::period(flows));
    debug_assert_eq!((flows.len() - start) % period, 0, "whole stages");
    if lo < start && start <= hi {
        let kind = W::kind(flows, 0, 0);
        work.apply(sys, z, kind, flows[0].1 * h, coefficients[0]);
    }
    let stages = flows[start..].chunks_exact(period);
    let stage_coefficients = coefficients[start..].chunks_exact(period);
    let mut at = start;
    for (stage, cds) in stages.zip(stage_coefficients) {
        if at >= lo && at + period <= hi {
            unroll!(period, k => {
                let kind = W::kind(flows, at + k, start + k);
                work.apply(sys, z, kind, stage[k].1 * h, cds[k]);
            });
        } else {
            // A stage the range starts or ends inside.
            unroll!(period, k => {
                if at + k >= lo && at + k < hi {
                    let kind = W::kind(flows, at + k, start + k);
                    work.apply(sys, z, kind, stage[k].1 * h, cds[k]);
                }
            });
        }
        at += period;
    }
}

/// (1 − e^{−rτ})/r, which tends to τ as r → 0.
fn one_minus_exp_neg_over(r: f64, tau: f64) -> f64 {
    if r == 0.0 {
        tau
    } else {
        flows::one_minus_exp_neg(r * tau) / r
    }
}
