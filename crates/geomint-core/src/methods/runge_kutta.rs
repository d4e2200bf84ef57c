//! Explicit Runge–Kutta methods as Butcher tableaux, run by one generic stepper on the full damped
//! vector field; and the same tableaux on the momentum equation alone, as the inner method of
//! modin_rks (paper 000 Algorithm 3.3).

use std::convert::Infallible;

use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DefaultAllocator, Dim};

use super::sources::*;
use super::{Citation, Group, Kind, Known, MethodInfo, Steps};
use crate::error::StepError;
use crate::flows;
use crate::flows::compiled::LazyCode;
use crate::flows::tableau::Stages;
pub use crate::flows::Tableau;
use crate::run::{step_by_step, Advanced, Stepper};
use crate::system::{MechanicalSystem, State, Vector};
use crate::tangent::{mul_into, Tangent};

/// Forward Euler.
pub const EXPLICIT_EULER: Tableau = Tableau {
    a: &[&[]],
    b: &[1.0],
    c: &[0.0],
    order: 1,
};

/// Heun's method, the explicit trapezoidal rule (Hairer–Nørsett–Wanner, Solving ODEs I, Table
/// II.1.1; paper 000 footnote 1 calls it Runge's).
pub const HEUN: Tableau = Tableau {
    a: &[&[], &[1.0]],
    b: &[0.5, 0.5],
    c: &[0.0, 1.0],
    order: 2,
};

/// Kutta's third-order method (Hairer–Nørsett–Wanner, Solving ODEs I, Table II.1.1).
pub const RK3: Tableau = Tableau {
    a: &[&[], &[0.5], &[-1.0, 2.0]],
    b: &[1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0],
    c: &[0.0, 0.5, 1.0],
    order: 3,
};

/// The classical fourth-order Runge–Kutta method (Hairer–Nørsett–Wanner, Table II.1.2).
pub const RK4: Tableau = Tableau {
    a: &[&[], &[0.5], &[0.0, 0.5], &[0.0, 0.0, 1.0]],
    b: &[1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0],
    c: &[0.0, 0.5, 0.5, 1.0],
    order: 4,
};

/// Where a Runge–Kutta stepper's tableau comes from: a reference chosen at run time, or a
/// tableau known when the program is compiled ([`Known`]), whose stage loops then unroll with the
/// zero coefficients dropped.
pub trait TableauSource {
    /// The tableau.
    fn tableau(&self) -> &'static Tableau;
}

impl TableauSource for &'static Tableau {
    #[inline(always)]
    fn tableau(&self) -> &'static Tableau {
        self
    }
}

/// A Butcher tableau known when the program is compiled.
pub trait KnownTableau {
    /// The tableau.
    const TABLEAU: &'static Tableau;
}

impl<K: KnownTableau> TableauSource for Known<K> {
    #[inline(always)]
    fn tableau(&self) -> &'static Tableau {
        K::TABLEAU
    }
}

/// Declares a marker type for each built-in tableau.
macro_rules! known_tableaux {
    ($($(#[$doc:meta])* $marker:ident = $tableau:ident;)*) => {
        $(
            $(#[$doc])*
            pub struct $marker;
            impl KnownTableau for $marker {
                const TABLEAU: &'static Tableau = &$tableau;
            }
        )*
    };
}

known_tableaux! {
    /// [`EXPLICIT_EULER`] as a type.
    ExplicitEuler = EXPLICIT_EULER;
    /// [`HEUN`] as a type.
    Heun = HEUN;
    /// [`RK3`] as a type.
    Rk3 = RK3;
    /// [`RK4`] as a type.
    Rk4 = RK4;
}

/// An explicit Runge–Kutta method on the full vector field.
pub struct RungeKutta<D: Dim, T: TableauSource = &'static Tableau>
where
    DefaultAllocator: Allocator<D>,
{
    tableau: T,
    kq: Vec<Vector<D>>,
    kp: Vec<Vector<D>>,
    stage: State<D>,
    scratch: Vector<D>,
    force_evaluations: u64,
    /// The stages of the variational equation (2n × k each), their argument and the field's
    /// Jacobian (2n × 2n), allocated at the first tangent step.
    stage_tangents: Vec<DMatrix<f64>>,
    tangent_arg: DMatrix<f64>,
    field: DMatrix<f64>,
    /// The system's compiled steps for the step size `compiled_h` (see `advance`).
    compiled: LazyCode,
    compiled_h: f64,
}

impl<D: Dim, T: TableauSource> RungeKutta<D, T>
where
    DefaultAllocator: Allocator<D>,
{
    /// A stepper for `tableau` on a system of dimension `dim`.
    pub fn new(tableau: T, dim: D) -> Self {
        let zero = Vector::<D>::zeros_generic(dim, nalgebra::U1);
        let s = tableau.tableau().stages();
        Self {
            tableau,
            kq: vec![zero.clone(); s],
            kp: vec![zero.clone(); s],
            stage: State {
                q: zero.clone(),
                p: zero.clone(),
            },
            scratch: zero,
            force_evaluations: 0,
            stage_tangents: Vec::new(),
            tangent_arg: DMatrix::zeros(0, 0),
            field: DMatrix::zeros(0, 0),
            compiled: LazyCode::default(),
            compiled_h: f64::NAN,
        }
    }
}

impl<S: MechanicalSystem, T: TableauSource> Stepper<S> for RungeKutta<S::Dim, T>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    #[inline(always)]
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        let t = self.tableau.tableau();
        let stages = t.stages();
        // One bounds check here instead of one per use.
        let (kq, kp) = (&mut self.kq[..stages], &mut self.kp[..stages]);
        let mut field = FieldStages {
            sys,
            z,
            stage: &mut self.stage,
            kq,
            kp,
            scratch: &mut self.scratch,
        };
        let Ok(()) = t.step(h, &mut field);
        self.force_evaluations += stages as u64;
        Ok(())
    }

    /// `n` steps, through the system's compiled steps where it has them (the same bits, and
    /// the same stop after a step that leaves the state not finite).
    fn advance(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64, n: u64) -> Advanced {
        if n >= 2 {
            let tableau = self.tableau.tableau();
            if h.to_bits() != self.compiled_h.to_bits() {
                self.compiled.reset();
                self.compiled_h = h;
            }
            let code = self
                .compiled
                .get(n, |steps| sys.compiled_forces()?.steps(tableau, h, steps));
            if let Some(code) = code {
                // The compiled steps keep no force cache: the stage buffer stands in for one.
                let taken = code.run(
                    z.q.as_mut_slice(),
                    z.p.as_mut_slice(),
                    self.scratch.as_mut_slice(),
                    &mut false,
                    &mut self.force_evaluations,
                    n,
                );
                return (taken, Ok(()));
            }
        }
        step_by_step(self, sys, z, h, n)
    }

    fn force_evaluations(&self) -> u64 {
        self.force_evaluations
    }

    /// The variational equation integrated by the same tableau, which is the exact linearisation
    /// of the step: K_i = J(Z_i)(Y + h Σ_j a_ij K_j), Y ← Y + h Σ_i b_i K_i, with J the Jacobian
    /// of the full vector field at each stage ([`Tangent::field_jacobian`]: the second
    /// derivatives of H and, for a projector damping, ∂(P(q)p)/∂q). No allocation after the
    /// first call.
    fn step_tangent(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        tangent: &mut Tangent<S::Dim>,
    ) -> Result<(), StepError> {
        let t = self.tableau.tableau();
        let stages = t.stages();
        let (rows, k) = tangent.jac.shape();
        if self.stage_tangents.len() != stages || self.tangent_arg.shape() != (rows, k) {
            self.stage_tangents = vec![DMatrix::zeros(rows, k); stages];
            self.tangent_arg = DMatrix::zeros(rows, k);
            self.field = DMatrix::zeros(rows, rows);
        }
        let mut walk = TangentStages {
            field: FieldStages {
                sys,
                z,
                stage: &mut self.stage,
                kq: &mut self.kq,
                kp: &mut self.kp,
                scratch: &mut self.scratch,
            },
            tangent,
            argument: &mut self.tangent_arg,
            slopes: &mut self.stage_tangents,
            jacobian: &mut self.field,
            rate: sys.damping_rate(),
            force_evaluations: 0,
        };
        let stepped = t.step_rolled(h, &mut walk);
        self.force_evaluations += walk.force_evaluations;
        stepped?;
        self.force_evaluations += stages as u64;
        Ok(())
    }
}

/// The stages of a step of the full vector field ż = (M⁻¹p, −∇V − r P(q)p) for
/// [`Tableau::step`], in the system's vectors.
struct FieldStages<'a, S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    sys: &'a S,
    z: &'a mut State<S::Dim>,
    stage: &'a mut State<S::Dim>,
    kq: &'a mut [Vector<S::Dim>],
    kp: &'a mut [Vector<S::Dim>],
    scratch: &'a mut Vector<S::Dim>,
}

impl<S: MechanicalSystem> Stages for FieldStages<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    type Error = Infallible;

    #[inline(always)]
    fn start_stage(&mut self) {
        self.stage.q.copy_from(&self.z.q);
        self.stage.p.copy_from(&self.z.p);
    }

    #[inline(always)]
    fn add_slope(&mut self, c: f64, j: usize) {
        self.stage.q.axpy(c, &self.kq[j], 1.0);
        self.stage.p.axpy(c, &self.kp[j], 1.0);
    }

    #[inline(always)]
    fn evaluate(&mut self, i: usize) -> Result<(), Infallible> {
        let (q, p) = (&self.stage.q, &self.stage.p);
        (self.sys).vector_field(q, p, &mut self.kq[i], &mut self.kp[i], self.scratch);
        Ok(())
    }

    #[inline(always)]
    fn advance(&mut self, c: f64, i: usize) {
        self.z.q.axpy(c, &self.kq[i], 1.0);
        self.z.p.axpy(c, &self.kp[i], 1.0);
    }
}

/// The same stages with the variational equation's beside them: the tangent Y (2n × k) is
/// advanced by the same tableau, each stage's slope Kᵢ = J(Zᵢ) (Y + Σⱼ h aᵢⱼ Kⱼ), with J the
/// field's Jacobian at the stage's state ([`Tangent::field_jacobian`]).
struct TangentStages<'a, S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    field: FieldStages<'a, S>,
    tangent: &'a mut Tangent<S::Dim>,
    /// The stage's argument Y + Σⱼ h aᵢⱼ Kⱼ.
    argument: &'a mut DMatrix<f64>,
    slopes: &'a mut [DMatrix<f64>],
    jacobian: &'a mut DMatrix<f64>,
    rate: f64,
    /// The second-derivative evaluations the stages made.
    force_evaluations: u64,
}

impl<S: MechanicalSystem> Stages for TangentStages<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    type Error = StepError;

    fn start_stage(&mut self) {
        self.field.start_stage();
        self.argument.copy_from(&self.tangent.jac);
    }

    fn add_slope(&mut self, c: f64, j: usize) {
        self.field.add_slope(c, j);
        for (x, &y) in self.argument.iter_mut().zip(self.slopes[j].iter()) {
            *x += c * y;
        }
    }

    fn evaluate(&mut self, i: usize) -> Result<(), StepError> {
        let (sys, stage) = (self.field.sys, &*self.field.stage);
        self.force_evaluations += self
            .tangent
            .load_second_derivatives(sys, &stage.q, &stage.p);
        self.tangent.load_damping(sys, &stage.q, &stage.p)?;
        self.tangent.field_jacobian(self.rate, self.jacobian);
        mul_into(self.jacobian, self.argument, &mut self.slopes[i]);
        let Ok(()) = self.field.evaluate(i);
        Ok(())
    }

    fn advance(&mut self, c: f64, i: usize) {
        self.field.advance(c, i);
        for (x, &y) in self.tangent.jac.iter_mut().zip(self.slopes[i].iter()) {
            *x += c * y;
        }
    }
}

/// The Runge–Kutta method used on the momentum equation p' = −∇V(q) − r P(q) p with q frozen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InnerRk {
    /// An explicit tableau.
    Explicit(&'static Tableau),
    /// The implicit midpoint rule, solved in closed form since the equation is linear in p.
    ImplicitMidpoint,
}

/// Work space of the momentum Runge–Kutta sub-flow.
pub struct MomentumRk<D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    method: InnerRk,
    k: Vec<Vector<D>>,
    stage: Vector<D>,
    projected: Vector<D>,
}

impl<D: Dim> MomentumRk<D>
where
    DefaultAllocator: Allocator<D>,
{
    /// Work space for `method` in dimension `dim`.
    pub fn new(method: InnerRk, dim: D) -> Self {
        let zero = Vector::<D>::zeros_generic(dim, nalgebra::U1);
        let stages = match method {
            InnerRk::Explicit(t) => t.stages(),
            InnerRk::ImplicitMidpoint => 0,
        };
        Self {
            method,
            k: vec![zero.clone(); stages],
            stage: zero.clone(),
            projected: zero,
        }
    }

    /// One step of size τ of p' = −g − r P p, with g = ∇V(q) given.
    #[inline]
    pub fn step<S: MechanicalSystem<Dim = D>>(
        &mut self,
        sys: &S,
        z: &mut State<D>,
        tau: f64,
        g: &Vector<D>,
    ) {
        let r = sys.damping_rate();
        match self.method {
            InnerRk::Explicit(t) => {
                let mut momentum = MomentumStages {
                    sys,
                    q: &z.q,
                    p: &mut z.p,
                    g,
                    rate: r,
                    stage: &mut self.stage,
                    k: &mut self.k,
                    projected: &mut self.projected,
                };
                let Ok(()) = t.step_rolled(tau, &mut momentum);
            }
            // On a field linear in p the implicit midpoint rule is the trapezoidal rule.
            InnerRk::ImplicitMidpoint => {
                crate::methods::state_flows::kick_theta(sys, z, tau, 0.5, g, &mut self.projected)
            }
        }
    }

    /// For P = I: one step maps p to A p − B ∇V(q); returns (A, B).
    pub fn tangent_coefficients(&self, r: f64, tau: f64) -> (f64, f64) {
        match self.method {
            InnerRk::Explicit(t) => {
                let (a, b) = t.linear_response(-r * tau);
                (a, tau * b)
            }
            InnerRk::ImplicitMidpoint => flows::kick_theta_tangent(r, tau, 0.5),
        }
    }
}

/// The stages of a step of the momentum equation p' = −g − r P(q) p, q and g = ∇V(q) frozen,
/// for [`Tableau::step`].
struct MomentumStages<'a, S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    sys: &'a S,
    q: &'a Vector<S::Dim>,
    p: &'a mut Vector<S::Dim>,
    g: &'a Vector<S::Dim>,
    rate: f64,
    stage: &'a mut Vector<S::Dim>,
    k: &'a mut [Vector<S::Dim>],
    projected: &'a mut Vector<S::Dim>,
}

impl<S: MechanicalSystem> Stages for MomentumStages<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    type Error = Infallible;

    #[inline(always)]
    fn start_stage(&mut self) {
        self.stage.copy_from(self.p);
    }

    #[inline(always)]
    fn add_slope(&mut self, c: f64, j: usize) {
        self.stage.axpy(c, &self.k[j], 1.0);
    }

    #[inline(always)]
    fn evaluate(&mut self, i: usize) -> Result<(), Infallible> {
        self.sys.project_damped(self.q, self.stage, self.projected);
        let k = &mut self.k[i];
        k.copy_from(self.g);
        k.axpy(self.rate, self.projected, 1.0);
        k.neg_mut();
        Ok(())
    }

    #[inline(always)]
    fn advance(&mut self, c: f64, i: usize) {
        self.p.axpy(c, &self.k[i], 1.0);
    }
}

/// Catalogue entry of `explicit_euler`.
pub const EXPLICIT_EULER_INFO: MethodInfo = MethodInfo {
    id: "explicit_euler",
    name: "Explicit Euler",
    order: 1,
    kind: Kind::Explicit,
    symplectic: false,
    conformal_symplectic: false,
    symmetric: false,
    requirements: &[],
    reference: Citation {
        paper: HNW,
        equation: "Sec. I.7",
    },
    group: Group::Baseline,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::RungeKutta(&EXPLICIT_EULER),
};

/// Catalogue entry of `heun`.
pub const HEUN_INFO: MethodInfo = MethodInfo {
    id: "heun",
    name: "Heun (explicit trapezoid)",
    order: 2,
    kind: Kind::Explicit,
    symplectic: false,
    conformal_symplectic: false,
    symmetric: false,
    requirements: &[],
    reference: Citation {
        paper: MODIN,
        equation: "footnote 1",
    },
    group: Group::Baseline,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::RungeKutta(&HEUN),
};

/// Catalogue entry of `rk3`.
pub const RK3_INFO: MethodInfo = MethodInfo {
    id: "rk3",
    name: "Kutta's third order",
    order: 3,
    kind: Kind::Explicit,
    symplectic: false,
    conformal_symplectic: false,
    symmetric: false,
    requirements: &[],
    reference: Citation {
        paper: HNW,
        equation: "Table II.1.1",
    },
    group: Group::Baseline,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::RungeKutta(&RK3),
};

/// Catalogue entry of `rk4`.
pub const RK4_INFO: MethodInfo = MethodInfo {
    id: "rk4",
    name: "Classical Runge–Kutta 4",
    order: 4,
    kind: Kind::Explicit,
    symplectic: false,
    conformal_symplectic: false,
    symmetric: false,
    requirements: &[],
    reference: Citation {
        paper: HNW,
        equation: "Table II.1.2",
    },
    group: Group::Baseline,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::RungeKutta(&RK4),
};
