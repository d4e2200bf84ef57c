//! `rowlands`, Rowlands time stepping (paper 001 Sec. 3.3, eqs. 25–37): a processing method
//! Φ = χ⁻¹ ∘ K ∘ χ (eqs. 22–23) for H = ½ pᵀM⁻¹p + U(q) with constant M and no damping.
//!
//! **Kernel** K (eq. 31): Störmer–Verlet, kick–drift–kick (eqs. 26–28), on the effective potential
//! (eq. 30)
//!
//! ```text
//! Û = U − h²/24 · U_qᵀ M⁻¹ U_q,    ∇Û = U_q − h²/12 · U_qq M⁻¹ U_q.
//! ```
//!
//! It runs every step and is second order on its own, symmetric and symplectic (a KDK splitting
//! of H with Û in place of U); ∇Û at the end of a step is kept for the next one (Û depends on h²
//! only, so a step of −h reuses it too).
//!
//! **Processors**, chosen by the method option `processor`:
//! - `none`: the kernel alone; samples report the kernel state (order 2);
//! - `original`: eqs. (32)–(33) before the first step, q̄ = q + c h² M⁻¹U_q(q),
//!   p̄ = p − c h² U_qq(q) M⁻¹p, and at each output their inverse to O(h⁴),
//!   q = q̄ − c h² M⁻¹U_q(q̄), p = p̄ + c h² U_qq(q̄) M⁻¹p̄, with c = 1/12 (see below);
//! - `cheap` (the default): eqs. (34)–(35) before the first step, with
//!   U_q^{±1/2} = U_q(q ± h/2 M⁻¹p), and eqs. (36)–(37) at each output, which need the kernel's
//!   neighbours z̄_{j±1}. They are computed at output time on copies, z̄_{j+1} = K_h(z̄_j) and,
//!   as K is symmetric, z̄_{j−1} = K_{−h}(z̄_j); no history is kept.
//!
//! Post-processing happens only at the samples (and at the end of a run), so its cost scales with
//! the number of samples, not of steps.
//!
//! **Paper correction: (32)–(33) need h²/12, not the printed h²/24.** On the oscillator
//! U = ω²q²/2, M = 1, the kernel is KDK Verlet with ω̂² = ω²(1 − h²ω²/12). It preserves
//! p̄² + ω̂²(1 − h²ω̂²/4) q̄² exactly and turns at the frequency ω̃ with cos hω̃ = 1 − h²ω̂²/2, so
//! ω̃ = ω + O(h⁴): only the shape of its ellipses is off. A processor q̄ = (1 + a)q, p̄ = (1 − b)p
//! carries the exact ellipses p² + ω²q² = E onto the kernel's iff
//! ω²(1 − b)²/(1 + a)² = ω̂²(1 − h²ω̂²/4), i.e. to O(h⁴) 1 − 2a − 2b = 1 − h²ω²/3:
//! **a + b = h²ω²/6**. Eqs. (32)–(33) with coefficient c give a = b = c h²ω², so c = 1/12. The cheap
//! eqs. (34)–(35) agree: they expand to q̄ = q + h²/12 M⁻¹U_q + O(h⁴) and
//! p̄ = p − h²/12 U_qq M⁻¹p + O(h⁴). With the printed c = 1/24, a + b = h²ω²/12 and an O(h²) error
//! in the amplitude remains. Measured (tests/service/rowlands.rs in the service: ℓ² state error at the end and the
//! largest energy drift, t = 4, h = 0.1 … 0.0125): the printed coefficient gives order 2.00 in
//! both on the planar elastic pendulum of the paper's Fig. 4, the oscillator, the pendulum, the
//! elastic 3-D pendulum and N bodies, halving the kernel's error and no more; c = 1/12 gives 4.00,
//! as the cheap processor does.
//! [`Rowlands::with_original_coefficient`] keeps the printed value available for that check.
//!
//! **Force evaluations.** Each gradient U_q counts one. A Hessian counts the gradient evaluations
//! [`MechanicalSystem::hess_potential`] reports: none for an analytic Hessian (the oscillator, the
//! pendulum, the elastic pendulum). Where the system has none (it reports the 2n evaluations of
//! its difference Hessian on the first call), the product U_qq w is instead a central difference
//! of the gradient along w, at two gradient evaluations. So a kernel step costs one gradient (plus
//! two without an analytic Hessian); the cheap processor costs two gradients before the first step
//! and two ∇Û per output (one per neighbour; ∇Û at the sample itself is the kernel's); the
//! original one gradient and one Hessian product before the first step and per output. Outputs
//! are the samples after step 0 and the end of the run (the last sample, when it is there).

use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DefaultAllocator, U1};
use serde::{Deserialize, Serialize};

use super::sources::*;
use super::{Citation, Group, Kind, MethodInfo, MethodOption, Requirement, Steps};
use crate::error::StepError;
use crate::run::Stepper;
use crate::system::{MechanicalSystem, State, Vector};
use crate::tangent::Tangent;

/// The processor of a `rowlands` run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Processor {
    /// The kernel alone (second order).
    None,
    /// Rowlands' transformation, eqs. (32)–(33) with the corrected coefficient h²/12.
    Original,
    /// The cheaper eqs. (34)–(37).
    Cheap,
}

impl Processor {
    /// Every processor, in catalogue order.
    pub const ALL: [Processor; 3] = [Processor::None, Processor::Original, Processor::Cheap];

    /// The processor of a choice that names none.
    pub const DEFAULT: Processor = Processor::Cheap;

    /// The name used in requests.
    pub fn as_str(self) -> &'static str {
        match self {
            Processor::None => "none",
            Processor::Original => "original",
            Processor::Cheap => "cheap",
        }
    }

    /// Parses a request name.
    pub fn parse(s: &str) -> Option<Processor> {
        Processor::ALL.into_iter().find(|p| p.as_str() == s)
    }
}

#[cfg(feature = "openapi")]
impl utoipa::PartialSchema for Processor {
    fn schema() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
        crate::schema::string_enum(
            "The processor of rowlands.",
            Processor::ALL.iter().map(|p| p.as_str()),
        )
    }
}

#[cfg(feature = "openapi")]
impl utoipa::ToSchema for Processor {}

/// The coefficient c of the original processor: h²/12 (the paper prints h²/24; module docs).
pub const ORIGINAL_COEFFICIENT: f64 = 1.0 / 12.0;

/// How the Hessian–vector product U_qq w is formed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum HessianSource {
    /// Not known yet: the first product asks `hess_potential` and looks at its cost.
    Unknown,
    /// `hess_potential` is analytic (it used no gradient evaluations).
    Analytic,
    /// A central difference of the gradient along w.
    Directional,
}

/// Work buffers and the evaluation count, shared by the main trajectory and the copies the
/// post-processor steps.
struct RowlandsScratch<S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// U_q.
    grad: Vector<S::Dim>,
    /// M⁻¹ times something.
    w: Vector<S::Dim>,
    /// U_qq w.
    hw: Vector<S::Dim>,
    /// Scratch for the directional difference.
    shifted: Vector<S::Dim>,
    scratch: Vector<S::Dim>,
    hess: DMatrix<f64>,
    hessian: HessianSource,
    force_evaluations: u64,
}

impl<S: MechanicalSystem> RowlandsScratch<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn new(sys: &S) -> Self {
        let zero = Vector::<S::Dim>::zeros_generic(sys.dim(), U1);
        let n = zero.len();
        Self {
            grad: zero.clone(),
            w: zero.clone(),
            hw: zero.clone(),
            shifted: zero.clone(),
            scratch: zero,
            hess: DMatrix::zeros(n, n),
            hessian: HessianSource::Unknown,
            force_evaluations: 0,
        }
    }

    /// `self.grad = U_q(q)`.
    fn gradient(&mut self, sys: &S, q: &Vector<S::Dim>) {
        sys.grad_potential(q, &mut self.grad);
        self.force_evaluations += 1;
    }

    /// `self.hw = U_qq(q) self.w`.
    fn hessian_times_w(&mut self, sys: &S, q: &Vector<S::Dim>) {
        if self.hessian == HessianSource::Directional {
            let scale = self.w.amax();
            if scale == 0.0 {
                self.hw.fill(0.0);
                return;
            }
            // A step of about 1e-5 relative to q along w: truncation and round-off both stay
            // near 1e-10 relative, and the product is multiplied by h²/12 besides.
            let eps = 1e-5 * (1.0 + q.amax()) / scale;
            self.shifted.copy_from(q);
            self.shifted.axpy(eps, &self.w, 1.0);
            sys.grad_potential(&self.shifted, &mut self.hw);
            self.shifted.copy_from(q);
            self.shifted.axpy(-eps, &self.w, 1.0);
            sys.grad_potential(&self.shifted, &mut self.scratch);
            self.force_evaluations += 2;
            self.hw -= &self.scratch;
            self.hw *= 0.5 / eps;
            return;
        }
        let used = sys.hess_potential(q, &mut self.hess);
        self.force_evaluations += used;
        if self.hessian == HessianSource::Unknown {
            self.hessian = if used == 0 {
                HessianSource::Analytic
            } else {
                HessianSource::Directional
            };
        }
        let n = self.w.len();
        for i in 0..n {
            let mut sum = 0.0;
            for j in 0..n {
                sum += self.hess[(i, j)] * self.w[j];
            }
            self.hw[i] = sum;
        }
    }

    /// `out = ∇Û(q) = U_q − h²/12 U_qq M⁻¹ U_q` (eq. 30's gradient).
    fn modified_gradient(
        &mut self,
        sys: &S,
        q: &Vector<S::Dim>,
        h2: f64,
        out: &mut Vector<S::Dim>,
    ) {
        self.gradient(sys, q);
        sys.velocity(q, &self.grad, &mut self.w);
        self.hessian_times_w(sys, q);
        out.copy_from(&self.grad);
        out.axpy(-h2 / 12.0, &self.hw, 1.0);
    }

    /// One kernel step (eq. 31, kick–drift–kick on Û). `grad` holds ∇Û(z.q) for this h² on entry
    /// and ∇Û at the new position on return.
    fn kernel_step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64, grad: &mut Vector<S::Dim>) {
        z.p.axpy(-0.5 * h, grad, 1.0);
        sys.velocity(&z.q, &z.p, &mut self.w);
        z.q.axpy(h, &self.w, 1.0);
        self.modified_gradient(sys, &z.q, h * h, grad);
        z.p.axpy(-0.5 * h, grad, 1.0);
    }
}

/// The Rowlands stepper: the kernel in `step`, the processors in `pre_process` and
/// `post_process`.
pub struct Rowlands<S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    processor: Processor,
    coefficient: f64,
    work: RowlandsScratch<S>,
    /// ∇Û at the current kernel position, for `cached_h2`.
    grad: Vector<S::Dim>,
    cached_h2: Option<f64>,
    /// The neighbours z̄_{j±1} of the cheap post-processor, and their ∇Û.
    ahead: State<S::Dim>,
    behind: State<S::Dim>,
    side_grad: Vector<S::Dim>,
}

impl<S: MechanicalSystem> Rowlands<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// A stepper for `sys` with `processor`.
    pub fn new(sys: &S, processor: Processor) -> Self {
        let zero = Vector::<S::Dim>::zeros_generic(sys.dim(), U1);
        let state = State {
            q: zero.clone(),
            p: zero.clone(),
        };
        Self {
            processor,
            coefficient: ORIGINAL_COEFFICIENT,
            work: RowlandsScratch::new(sys),
            grad: zero.clone(),
            cached_h2: None,
            ahead: state.clone(),
            behind: state,
            side_grad: zero,
        }
    }

    /// The same stepper with coefficient c in the original processor's c h² (default 1/12). The
    /// paper prints 1/24, which leaves the method second order; this is for checking that.
    pub fn with_original_coefficient(mut self, c: f64) -> Self {
        self.coefficient = c;
        self
    }

    /// The processor.
    pub fn processor(&self) -> Processor {
        self.processor
    }

    /// Makes `self.grad` hold ∇Û(q) for step h.
    fn ensure_gradient(&mut self, sys: &S, q: &Vector<S::Dim>, h: f64) {
        let h2 = h * h;
        if self.cached_h2 != Some(h2) {
            self.work.modified_gradient(sys, q, h2, &mut self.grad);
            self.cached_h2 = Some(h2);
        }
    }

    /// The original processor (`sign` = 1) or its inverse to O(h⁴) (`sign` = −1), in place:
    /// q ← q + sign·c h² M⁻¹U_q(q), p ← p − sign·c h² U_qq(q) M⁻¹p, both at the old q.
    fn original(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64, sign: f64) {
        let k = sign * self.coefficient * h * h;
        let work = &mut self.work;
        sys.velocity(&z.q, &z.p, &mut work.w);
        work.hessian_times_w(sys, &z.q);
        work.gradient(sys, &z.q);
        sys.velocity(&z.q, &work.grad, &mut work.w);
        z.q.axpy(k, &work.w, 1.0);
        z.p.axpy(-k, &work.hw, 1.0);
    }
}

impl<S: MechanicalSystem> Stepper<S> for Rowlands<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    #[inline]
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        self.ensure_gradient(sys, &z.q, h);
        self.work.kernel_step(sys, z, h, &mut self.grad);
        Ok(())
    }

    fn force_evaluations(&self) -> u64 {
        self.work.force_evaluations
    }

    fn restart(&mut self) {
        self.cached_h2 = None;
    }

    fn step_tangent(
        &mut self,
        _sys: &S,
        _z: &mut State<S::Dim>,
        _h: f64,
        _tangent: &mut Tangent<S::Dim>,
    ) -> Result<(), StepError> {
        Err(StepError::TangentUnsupported {
            reason: "rowlands has no tangent map: its kick's Jacobian needs third derivatives of V",
        })
    }

    fn pre_process(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        match self.processor {
            Processor::None => return Ok(()),
            Processor::Original => self.original(sys, z, h, 1.0),
            Processor::Cheap => {
                // Eqs. (34)–(35): U_q^{±1/2} at q ± h/2 M⁻¹p.
                let work = &mut self.work;
                sys.velocity(&z.q, &z.p, &mut work.w);
                work.shifted.copy_from(&z.q);
                work.shifted.axpy(0.5 * h, &work.w, 1.0);
                sys.grad_potential(&work.shifted, &mut work.hw);
                work.shifted.axpy(-h, &work.w, 1.0);
                sys.grad_potential(&work.shifted, &mut work.scratch);
                work.force_evaluations += 2;
                // grad = U⁺ + U⁻, hw = U⁺ − U⁻.
                work.grad.copy_from(&work.hw);
                work.grad += &work.scratch;
                work.hw -= &work.scratch;
                sys.velocity(&z.q, &work.grad, &mut work.w);
                z.q.axpy(h * h / 24.0, &work.w, 1.0);
                z.p.axpy(-h / 12.0, &work.hw, 1.0);
            }
        }
        // The kernel starts from a new position.
        self.cached_h2 = None;
        Ok(())
    }

    fn post_process(
        &mut self,
        sys: &S,
        z: &State<S::Dim>,
        h: f64,
        out: &mut State<S::Dim>,
    ) -> Result<bool, StepError> {
        match self.processor {
            Processor::None => Ok(false),
            Processor::Original => {
                out.clone_from(z);
                self.original(sys, out, h, -1.0);
                Ok(true)
            }
            Processor::Cheap => {
                // Eqs. (36)–(37) with z̄_{j+1} = K_h(z̄_j), z̄_{j−1} = K_{−h}(z̄_j), on copies.
                self.ensure_gradient(sys, &z.q, h);
                self.ahead.clone_from(z);
                self.side_grad.copy_from(&self.grad);
                self.work
                    .kernel_step(sys, &mut self.ahead, h, &mut self.side_grad);
                self.behind.clone_from(z);
                self.side_grad.copy_from(&self.grad);
                self.work
                    .kernel_step(sys, &mut self.behind, -h, &mut self.side_grad);
                // q = q̄ + (q̄₊ − 2q̄ + q̄₋)/12, p = p̄ − (p̄₊ − 2p̄ + p̄₋)/12.
                out.q.copy_from(&self.ahead.q);
                out.q += &self.behind.q;
                out.q.axpy(-2.0, &z.q, 1.0);
                out.q.axpy(1.0, &z.q, 1.0 / 12.0);
                out.p.copy_from(&self.ahead.p);
                out.p += &self.behind.p;
                out.p.axpy(-2.0, &z.p, 1.0);
                out.p.axpy(1.0, &z.p, -1.0 / 12.0);
                Ok(true)
            }
        }
    }
}

/// Catalogue entry of `rowlands`.
pub const ROWLANDS_INFO: MethodInfo = MethodInfo {
    id: "rowlands",
    name: "Rowlands time stepping (processed Störmer–Verlet, effective order 4)",
    order: 4,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: false,
    symmetric: true,
    requirements: &[
        Requirement::SeparableConstantMass,
        Requirement::Conservative,
    ],
    reference: Citation {
        paper: TAKACS,
        equation: "eqs. (30)–(37), (32)–(33) with h²/12",
    },
    group: Group::Geometric,
    options: &[MethodOption::Processor],
    no_step_jacobian: Some("rowlands (whose modified kick would need third derivatives of V) has"),
    steps: Steps::Own,
};
