//! From a [`Method`] to a stepper for a concrete system: the one place that knows which family
//! runs which method. [`AnyStepper`] holds the stepper chosen at run time; matching on it once
//! per run ([`with_stepper!`](crate::with_stepper)) runs the driver monomorphised for it.

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

use super::composition::{inverse, Composed, Processed};
use super::conformal::Csv2;
use super::implicit::{ImplicitMidpoint, MidpointField};
use super::reference::Reference;
use super::rowlands::Rowlands;
use super::runge_kutta::{self, InnerRk, KnownTableau, MomentumRk, RungeKutta, Tableau};
use super::splitting::{self, KnownSequence, Splitting, SubFlow};
use super::symplectic_euler::{GeneralSymplecticEuler, Variant};
use super::{Base, Known, Method, MethodId, Steps};
use crate::error::{CoreError, Field, StepError};
use crate::run::{Advanced, Stepper};
use crate::system::{MechanicalSystem, State};
use crate::tangent::Tangent;

/// The Butcher tableau of an explicit Runge–Kutta method (`None` for the other methods), from
/// its catalogue entry.
pub fn tableau(id: MethodId) -> Option<&'static Tableau> {
    match id.info().steps {
        Steps::RungeKutta(tableau) => Some(tableau),
        _ => None,
    }
}

/// The sub-flow sequence of a splitting method (`None` for the other methods), from its
/// catalogue entry.
pub fn sequence(id: MethodId) -> Option<splitting::Sequence> {
    match id.info().steps {
        Steps::Splitting(sequence) => Some(sequence),
        _ => None,
    }
}

/// A stepper for a concrete system, chosen at run time.
pub enum AnyStepper<S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// A composition of splittings: its sequence is built at run time.
    Splitting(Splitting<S>),
    /// modin_3s.
    Modin3s(Splitting<S, Known<splitting::Modin3s>>),
    /// modin_2s.
    Modin2s(Splitting<S, Known<splitting::Modin2s>>),
    /// modin_rks.
    ModinRks(Splitting<S, Known<splitting::ModinRks>>),
    /// csv1.
    Csv1(Splitting<S, Known<splitting::Csv1>>),
    /// Symplectic Euler on a separable Hamiltonian.
    SymplecticEuler(Splitting<S, Known<splitting::SymplecticEuler>>),
    /// The adjoint symplectic Euler on a separable Hamiltonian.
    SymplecticEulerAdjoint(Splitting<S, Known<splitting::SymplecticEulerAdjoint>>),
    /// position_verlet.
    PositionVerlet(Splitting<S, Known<splitting::PositionVerlet>>),
    /// velocity_verlet.
    VelocityVerlet(Splitting<S, Known<splitting::VelocityVerlet>>),
    /// explicit_euler.
    ExplicitEuler(RungeKutta<S::Dim, Known<runge_kutta::ExplicitEuler>>),
    /// heun.
    Heun(RungeKutta<S::Dim, Known<runge_kutta::Heun>>),
    /// rk3.
    Rk3(RungeKutta<S::Dim, Known<runge_kutta::Rk3>>),
    /// rk4.
    Rk4(RungeKutta<S::Dim, Known<runge_kutta::Rk4>>),
    /// Any other explicit Runge–Kutta method: its tableau read at run time.
    RungeKutta(RungeKutta<S::Dim>),
    /// implicit_midpoint or cimp.
    Midpoint(ImplicitMidpoint<S>),
    /// csv2.
    Csv2(Csv2<S>),
    /// A composition of implicit_midpoint or cimp.
    ComposedMidpoint(Composed<ImplicitMidpoint<S>>),
    /// A composition of csv2.
    ComposedCsv2(Composed<Csv2<S>>),
    /// Symplectic Euler or its adjoint on a non-separable Hamiltonian.
    GeneralSymplecticEuler(GeneralSymplecticEuler<S>),
    /// The adaptive reference.
    Reference(Reference<S::Dim>),
    /// rowlands.
    Rowlands(Rowlands<S>),
    /// A processed composition: kernel, processor and output map, each a composition stepper.
    Processed(Box<Processed<AnyStepper<S>>>),
}

impl<S: MechanicalSystem> AnyStepper<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// The sub-flows of one step, for a splitting or a composition of splittings (none for the
    /// other families, whose steps are not sequences of exact flows).
    pub fn splitting_flows(&self) -> Option<&[(SubFlow, f64)]> {
        Some(match self {
            AnyStepper::Splitting(s) => s.flows(),
            AnyStepper::Modin3s(s) => s.flows(),
            AnyStepper::Modin2s(s) => s.flows(),
            AnyStepper::ModinRks(s) => s.flows(),
            AnyStepper::Csv1(s) => s.flows(),
            AnyStepper::SymplecticEuler(s) => s.flows(),
            AnyStepper::SymplecticEulerAdjoint(s) => s.flows(),
            AnyStepper::PositionVerlet(s) => s.flows(),
            AnyStepper::VelocityVerlet(s) => s.flows(),
            _ => return None,
        })
    }
}

/// Runs `$body` with `$st` bound to the concrete stepper inside an [`AnyStepper`].
#[macro_export]
macro_rules! with_stepper {
    ($any:expr, $st:ident => $body:expr) => {
        match $any {
            $crate::methods::AnyStepper::Splitting($st) => $body,
            $crate::methods::AnyStepper::Modin3s($st) => $body,
            $crate::methods::AnyStepper::Modin2s($st) => $body,
            $crate::methods::AnyStepper::ModinRks($st) => $body,
            $crate::methods::AnyStepper::Csv1($st) => $body,
            $crate::methods::AnyStepper::SymplecticEuler($st) => $body,
            $crate::methods::AnyStepper::SymplecticEulerAdjoint($st) => $body,
            $crate::methods::AnyStepper::PositionVerlet($st) => $body,
            $crate::methods::AnyStepper::VelocityVerlet($st) => $body,
            $crate::methods::AnyStepper::ExplicitEuler($st) => $body,
            $crate::methods::AnyStepper::Heun($st) => $body,
            $crate::methods::AnyStepper::Rk3($st) => $body,
            $crate::methods::AnyStepper::Rk4($st) => $body,
            $crate::methods::AnyStepper::RungeKutta($st) => $body,
            $crate::methods::AnyStepper::Midpoint($st) => $body,
            $crate::methods::AnyStepper::Csv2($st) => $body,
            $crate::methods::AnyStepper::ComposedMidpoint($st) => $body,
            $crate::methods::AnyStepper::ComposedCsv2($st) => $body,
            $crate::methods::AnyStepper::GeneralSymplecticEuler($st) => $body,
            $crate::methods::AnyStepper::Reference($st) => $body,
            $crate::methods::AnyStepper::Rowlands($st) => $body,
            $crate::methods::AnyStepper::Processed($st) => $body,
        }
    };
}

impl<S: MechanicalSystem> Stepper<S> for AnyStepper<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        with_stepper!(self, st => st.step(sys, z, h))
    }
    fn advance(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64, n: u64) -> Advanced {
        with_stepper!(self, st => advance_out_of_line(st, sys, z, h, n))
    }
    fn force_evaluations(&self) -> u64 {
        with_stepper!(self, st => Stepper::<S>::force_evaluations(st))
    }
    fn check_interval(&self) -> u64 {
        with_stepper!(self, st => Stepper::<S>::check_interval(st))
    }
    fn set_deadline(&mut self, deadline: Option<std::time::Instant>) {
        with_stepper!(self, st => Stepper::<S>::set_deadline(st, deadline))
    }
    fn restart(&mut self) {
        with_stepper!(self, st => Stepper::<S>::restart(st))
    }
    fn pre_process(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        with_stepper!(self, st => st.pre_process(sys, z, h))
    }
    fn post_process(
        &mut self,
        sys: &S,
        z: &State<S::Dim>,
        h: f64,
        out: &mut State<S::Dim>,
    ) -> Result<bool, StepError> {
        with_stepper!(self, st => st.post_process(sys, z, h, out))
    }
    fn processes_any_state(&self) -> bool {
        with_stepper!(self, st => Stepper::<S>::processes_any_state(st))
    }
    fn step_tangent(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        t: &mut Tangent<S::Dim>,
    ) -> Result<(), StepError> {
        with_stepper!(self, st => st.step_tangent(sys, z, h, t))
    }
}

/// One concrete stepper's [`Stepper::advance`] as a function of its own: the compiler then
/// inlines that stepper's step into its loop, which it stops doing inside one function that
/// holds the loops of every kind of stepper.
#[inline(never)]
fn advance_out_of_line<S: MechanicalSystem, M: Stepper<S>>(
    stepper: &mut M,
    sys: &S,
    z: &mut State<S::Dim>,
    h: f64,
    n: u64,
) -> Advanced
where
    DefaultAllocator: Allocator<S::Dim>,
{
    stepper.advance(sys, z, h, n)
}

/// Where a method and its step size come from, as errors name them, and the system as they
/// call it.
#[derive(Clone, Debug)]
pub struct MethodOrigin<'a> {
    /// The method's field, e.g. `methods[1]`.
    pub method: &'a Field,
    /// The step size's field, e.g. `h`.
    pub h: &'a Field,
    /// The system (and its chart), e.g. `elastic_pendulum_2d (polar chart)`.
    pub system: &'a str,
}

/// Checks that `method` can run on `sys` at step `h`: the system meets its requirements and
/// no linear solve of the method is singular at this step size.
pub fn check<S: MechanicalSystem>(
    method: &Method,
    sys: &S,
    h: f64,
    origin: &MethodOrigin<'_>,
) -> Result<(), CoreError>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    method.check(
        origin.method,
        origin.system,
        sys.structure(),
        sys.damping_rate(),
    )?;
    if sys.clock().is_some() {
        if let Some(why) = no_time(method, sys.damping_rate()) {
            return Err(CoreError::TimeDependent {
                field: origin.method.clone(),
                method: method.label(),
                system: origin.system.to_string(),
                why,
            });
        }
    }
    check_divisors(method, sys.damping_rate(), h, origin.h)
}

/// Why `method` cannot integrate a system that depends on the time t, if it cannot (a
/// composition as its base). Every other method treats the clock of extended phase space (see
/// [`MechanicalSystem::clock`]) as one more coordinate and so integrates t exactly:
/// - splittings and their compositions: the drift flow q ← q + τ ∂H̃/∂p moves t by τ, the kick
///   and damping flows hold q, and with it t, fixed, so each sub-flow stays exact and the
///   sequence keeps its order (the potential is evaluated at the time the drifts have reached);
/// - Runge–Kutta methods and the adaptive reference: stage i sees t + cᵢh, since t' = 1 and
///   cᵢ = Σⱼ aᵢⱼ;
/// - implicit midpoint and symplectic Euler in Newton form: t is solved for with the rest, and
///   comes out as t + h (resp. t + h at the stage that moves it).
///
/// csv2 and cimp with damping scale the positions by the conformal factor e^{−γh} (csv2's
/// (1 + γh/2)e^{−γh}/(1 − γh/2), cimp's decays of the whole state z), which would scale t too;
/// rowlands' modified potential and processors are derived for an autonomous Hamiltonian.
pub fn no_time(method: &Method, damping_rate: f64) -> Option<&'static str> {
    let (base, _) = stages(method);
    match base {
        MethodId::Csv2 | MethodId::Cimp if damping_rate != 0.0 => Some(
            "it scales the positions by the conformal factor, and would scale the time t with \
             them; use csv1 or modin_3s (or their compositions) for a driven damped system",
        ),
        MethodId::Rowlands => {
            Some("its modified potential and processors are derived for an autonomous Hamiltonian")
        }
        _ => None,
    }
}

/// Builds the stepper for `method` on `sys` with step `h`, after [`check`]ing it (errors name
/// the method `method` and the step `h`; callers with other names check first).
pub fn build<S: MechanicalSystem>(
    method: &Method,
    sys: &S,
    system: &str,
    h: f64,
) -> Result<AnyStepper<S>, CoreError>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let origin = MethodOrigin {
        method: &Field::new("method"),
        h: &Field::new("h"),
        system,
    };
    check(method, sys, h, &origin)?;
    Ok(stepper(method, sys))
}

/// The stepper of the composition of `base` with `weights` (a processed method's kernel,
/// processor or output map, or a plain composition).
fn composed<S: MechanicalSystem>(sys: &S, base: Base, weights: &[f64]) -> AnyStepper<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let weights = weights.to_vec();
    let sequence = match base {
        // Its kicks are exact kicks there, and fuse from stage to stage.
        Base::VelocityVerlet if sys.damping_rate() == 0.0 => {
            Some(splitting::UNDAMPED_VELOCITY_VERLET)
        }
        _ => sequence(base.id()),
    };
    match (sequence, base) {
        (Some(seq), _) => AnyStepper::Splitting(Splitting::new(
            sys,
            splitting::Composition::new(seq, &weights),
            None,
        )),
        (None, Base::Csv2) => AnyStepper::ComposedCsv2(Composed::new(Csv2::new(sys), weights)),
        (None, Base::Cimp) => AnyStepper::ComposedMidpoint(Composed::new(
            ImplicitMidpoint::new(sys, MidpointField::Conformal),
            weights,
        )),
        (None, _) => AnyStepper::ComposedMidpoint(Composed::new(
            ImplicitMidpoint::new(sys, MidpointField::Full),
            weights,
        )),
    }
}

/// The stepper of a checked method. The built-in splittings and tableaux get steppers with their
/// coefficients known at compile time; compositions build their sequence at run time.
fn stepper<S: MechanicalSystem>(method: &Method, sys: &S) -> AnyStepper<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn known<S: MechanicalSystem, K: KnownSequence>(sys: &S) -> Splitting<S, Known<K>>
    where
        DefaultAllocator: Allocator<S::Dim>,
    {
        Splitting::new(sys, Known::new(), None)
    }
    fn explicit<D: nalgebra::Dim, K: KnownTableau>(dim: D) -> RungeKutta<D, Known<K>>
    where
        DefaultAllocator: Allocator<D>,
    {
        RungeKutta::new(Known::new(), dim)
    }
    let separable = sys.structure().separable_constant_mass;
    match *method {
        Method::Composition { scheme, base } => match scheme.processor() {
            Some(processor) => AnyStepper::Processed(Box::new(Processed::new(
                composed(sys, base, &scheme.weights()),
                composed(sys, base, &processor),
                composed(sys, base, &inverse(&processor)),
            ))),
            None => composed(sys, base, &scheme.weights()),
        },
        Method::ModinRks { inner } => {
            let inner = MomentumRk::new(
                tableau(inner.id()).map_or(InnerRk::ImplicitMidpoint, InnerRk::Explicit),
                sys.dim(),
            );
            AnyStepper::ModinRks(Splitting::new(sys, Known::new(), Some(inner)))
        }
        Method::Reference { tolerance } => {
            AnyStepper::Reference(Reference::new(tolerance, sys.dim()))
        }
        Method::Rowlands { processor } => AnyStepper::Rowlands(Rowlands::new(sys, processor)),
        Method::Plain(id) => match id {
            MethodId::SymplecticEuler if !separable => AnyStepper::GeneralSymplecticEuler(
                GeneralSymplecticEuler::new(sys, Variant::Original),
            ),
            MethodId::SymplecticEulerAdjoint if !separable => AnyStepper::GeneralSymplecticEuler(
                GeneralSymplecticEuler::new(sys, Variant::Adjoint),
            ),
            MethodId::ImplicitMidpoint => {
                AnyStepper::Midpoint(ImplicitMidpoint::new(sys, MidpointField::Full))
            }
            MethodId::Cimp => {
                AnyStepper::Midpoint(ImplicitMidpoint::new(sys, MidpointField::Conformal))
            }
            MethodId::Csv2 => AnyStepper::Csv2(Csv2::new(sys)),
            MethodId::Modin3s => AnyStepper::Modin3s(known(sys)),
            MethodId::Modin2s => AnyStepper::Modin2s(known(sys)),
            MethodId::Csv1 => AnyStepper::Csv1(known(sys)),
            MethodId::SymplecticEuler => AnyStepper::SymplecticEuler(known(sys)),
            MethodId::SymplecticEulerAdjoint => AnyStepper::SymplecticEulerAdjoint(known(sys)),
            MethodId::PositionVerlet => AnyStepper::PositionVerlet(known(sys)),
            MethodId::VelocityVerlet => AnyStepper::VelocityVerlet(known(sys)),
            MethodId::ExplicitEuler => AnyStepper::ExplicitEuler(explicit(sys.dim())),
            MethodId::Heun => AnyStepper::Heun(explicit(sys.dim())),
            MethodId::Rk3 => AnyStepper::Rk3(explicit(sys.dim())),
            MethodId::Rk4 => AnyStepper::Rk4(explicit(sys.dim())),
            // Any other sequence or tableau runs as read at run time; a method with options
            // written as `Plain` takes its defaults.
            id => match id.info().steps {
                Steps::Splitting(seq) => AnyStepper::Splitting(Splitting::new(
                    sys,
                    splitting::Composition::new(seq, &[1.0]),
                    None,
                )),
                Steps::RungeKutta(tableau) => {
                    AnyStepper::RungeKutta(RungeKutta::new(tableau, sys.dim()))
                }
                Steps::Composition(_) | Steps::Own => stepper(&Method::new(id), sys),
            },
        },
    }
}

/// The base method of `method` and the weights of its sub-steps (one, of weight 1, for a method
/// that is not a composition; a processed method's processor's too, which run with the same h).
fn stages(method: &Method) -> (MethodId, Vec<f64>) {
    match method {
        Method::Composition { scheme, base } => {
            let mut weights = scheme.weights();
            weights.extend(scheme.processor().unwrap_or_default());
            (base.id(), weights)
        }
        other => (other.id(), vec![1.0]),
    }
}

/// Refuses a step whose sub-steps w·h make one of the method's linear solves singular: csv2
/// divides by 1 ∓ γτ/2, a damped θ-kick by 1 + θrτ. With a composition's negative weights
/// these vanish at values of γh other than the plain method's.
fn check_divisors(method: &Method, r: f64, h: f64, field: &Field) -> Result<(), CoreError> {
    let singular = |d: f64| d.abs() < 1e-9;
    let (base, weights) = stages(method);
    for &w in &weights {
        let bad = match (base, sequence(base)) {
            (MethodId::Csv2, _) => {
                let a = 0.25 * r * w * h;
                singular(1.0 - a) || singular(1.0 + a)
            }
            (_, Some(seq)) => seq.iter().any(|&(flow, frac)| match flow {
                SubFlow::DampedKick(theta) => singular(1.0 + theta.value() * r * w * frac * h),
                _ => false,
            }),
            _ => false,
        };
        if bad {
            return Err(CoreError::SingularStep {
                field: field.clone(),
                method: base.as_str(),
                gamma_h: 0.5 * r * h,
            });
        }
    }
    Ok(())
}
