//! Where a splitting's flows come from and how the composer walks them: written out for a
//! built-in, stage by stage for a composition of one, flow by flow otherwise.

use super::*;
use crate::methods::Known;

/// Where a splitting's sub-flows come from: a sequence built at run time (a [`Composition`]), or
/// one fixed in the program ([`Known`]), for which the compiler unrolls the step and resolves
/// each flow's kind, so a built-in method runs as the straight-line code one would write by hand.
/// Sealed: the composer trusts what [`Flows::stages`] says about the layout of the flows.
pub trait Flows: sealed::Sealed {
    /// Whether the sequence is known at compile time: the composer then writes its step out
    /// flow by flow; a sequence built at run time is looped over.
    const KNOWN: bool;
    /// The sub-flows with their fractions of h, in the order they act.
    fn flows(&self) -> &[(SubFlow, f64)];
    /// The built-in sequence this one composes, if it is a [`Composition`] of one.
    #[inline(always)]
    fn stages(&self) -> Option<ComposedBase> {
        None
    }
}

/// A splitting sequence known when the program is compiled.
pub trait KnownSequence {
    /// The sequence.
    const FLOWS: Sequence;
}

impl<K: KnownSequence> Flows for Known<K> {
    const KNOWN: bool = true;
    #[inline(always)]
    fn flows(&self) -> &[(SubFlow, f64)] {
        K::FLOWS
    }
}

mod sealed {
    /// Implemented by the two sources of flows only.
    pub trait Sealed {}
    impl<K: super::KnownSequence> Sealed for super::Known<K> {}
    impl Sealed for super::Composition {}
}

/// The built-in splittings a composition accepts as its base (the symmetric second-order ones).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ComposedBase {
    /// [`MODIN_3S`].
    Modin3s,
    /// [`MODIN_2S`].
    Modin2s,
    /// [`CSV1`].
    Csv1,
    /// [`POSITION_VERLET`].
    PositionVerlet,
    /// [`VELOCITY_VERLET`].
    VelocityVerlet,
    /// [`UNDAMPED_VELOCITY_VERLET`].
    UndampedVelocityVerlet,
}

impl ComposedBase {
    /// The built-in whose sequence is `sequence`, if one is.
    fn of(sequence: &[(SubFlow, f64)]) -> Option<ComposedBase> {
        [
            (ComposedBase::Modin3s, MODIN_3S),
            (ComposedBase::Modin2s, MODIN_2S),
            (ComposedBase::Csv1, CSV1),
            (ComposedBase::PositionVerlet, POSITION_VERLET),
            (ComposedBase::VelocityVerlet, VELOCITY_VERLET),
            (
                ComposedBase::UndampedVelocityVerlet,
                UNDAMPED_VELOCITY_VERLET,
            ),
        ]
        .into_iter()
        .find(|(_, known)| *known == sequence)
        .map(|(base, _)| base)
    }
}

/// A composition of a splitting as one sequence ([`compose`]). When the base is a built-in, the
/// composer walks it stage by stage with the base's flow kinds known at compile time, which
/// spares a dispatch on the kind at every flow: kahan_li_8(modin_3s) on the elastic pendulum went
/// from 3110 to 2070 instructions per step (callgrind).
pub struct Composition {
    flows: Vec<(SubFlow, f64)>,
    base: Option<ComposedBase>,
}

impl Composition {
    /// Φ_{w_k h} ∘ … ∘ Φ_{w_1 h} for the splitting `base`.
    pub fn new(base: Sequence, weights: &[f64]) -> Self {
        let flows = compose(base, weights);
        // The stages are laid out as the walk expects (a shared first flow when the base's ends
        // fuse, then `weights.len()` stages of the rest), which holds for every built-in base
        // and checks that no flows fused inside a stage; else walk flow by flow.
        let shared = usize::from(base.len() > 1 && base[base.len() - 1].0.fuses_with(base[0].0));
        let laid_out =
            !weights.is_empty() && flows.len() == shared + weights.len() * (base.len() - shared);
        Self {
            base: ComposedBase::of(base).filter(|_| laid_out),
            flows,
        }
    }

    /// The same composition walked flow by flow, as a sequence of unknown origin is: the general
    /// path, which the stage-by-stage walk must reproduce bit for bit.
    pub fn without_stages(self) -> Self {
        Self { base: None, ..self }
    }
}

impl Flows for Composition {
    const KNOWN: bool = false;
    #[inline(always)]
    fn flows(&self) -> &[(SubFlow, f64)] {
        &self.flows
    }
    #[inline(always)]
    fn stages(&self) -> Option<ComposedBase> {
        self.base
    }
}

/// How the composer names the kinds of a sequence's flows: read from the sequence at run time,
/// or known at compile time. A sequence is walked as a first flow (`START` = 1: shared by the
/// stages of a composition whose stages fuse end to start) and then stages of `period` flows.
pub(super) trait Walk {
    /// 1 when the first flow stands apart from the stages, else 0.
    const START: usize;
    /// Flows per stage.
    fn period(flows: &[(SubFlow, f64)]) -> usize;
    /// The kind of flow `i` of the sequence; `j` is its index in the base's sequence, for a walk
    /// that knows the base.
    fn kind(flows: &[(SubFlow, f64)], i: usize, j: usize) -> SubFlow;
}

/// A sequence of unknown origin: flow by flow, with a dispatch on each flow's kind.
pub(super) struct Loop;

/// A built-in sequence ([`Known`]): one stage, written out.
pub(super) struct Unrolled;

/// A composition of the built-in sequence `K`: stage after stage, each written out with `K`'s
/// kinds. [`compose`] lays the stages out as `K`'s flows, with each stage's first flow merged
/// into the previous stage's last when the two fuse: after that shared first flow, every stage
/// is `PERIOD` flows ([`Composition::new`] checks the layout).
pub(super) struct KnownStages<K>(std::marker::PhantomData<K>);

impl<K: KnownSequence> KnownStages<K> {
    /// Whether `K`'s last flow and its first fuse, so that stages share one flow.
    const FUSED: bool = K::FLOWS[K::FLOWS.len() - 1].0.fuses_with(K::FLOWS[0].0);
    /// Flows per stage after the shared one.
    const PERIOD: usize = {
        assert!(K::FLOWS.len() >= 2, "a composed base has two flows or more");
        K::FLOWS.len() - Self::FUSED as usize
    };
}

impl Walk for Loop {
    const START: usize = 0;
    #[inline(always)]
    fn period(_: &[(SubFlow, f64)]) -> usize {
        1
    }
    #[inline(always)]
    fn kind(flows: &[(SubFlow, f64)], i: usize, _: usize) -> SubFlow {
        flows[i].0
    }
}

impl Walk for Unrolled {
    const START: usize = 0;
    #[inline(always)]
    fn period(flows: &[(SubFlow, f64)]) -> usize {
        flows.len()
    }
    #[inline(always)]
    fn kind(flows: &[(SubFlow, f64)], i: usize, _: usize) -> SubFlow {
        flows[i].0
    }
}

impl<K: KnownSequence> Walk for KnownStages<K> {
    const START: usize = Self::FUSED as usize;
    #[inline(always)]
    fn period(_: &[(SubFlow, f64)]) -> usize {
        Self::PERIOD
    }
    #[inline(always)]
    fn kind(_: &[(SubFlow, f64)], _: usize, j: usize) -> SubFlow {
        K::FLOWS[j].0
    }
}

/// Runs `$call` with `$walk` the [`Walk`] that suits the sequence of the splitting `$split`:
/// unrolled for a built-in, stage by stage for a composition of one, else a loop. Used inside
/// `impl<…, Q: Flows> … for Splitting<S, Q>`, whose `Q` it reads.
macro_rules! with_walk {
    ($split:expr, $walk:ident => $call:expr) => {
        if Q::KNOWN {
            type $walk = Unrolled;
            $call
        } else {
            match $split.sequence.stages() {
                Some(ComposedBase::Modin3s) => {
                    type $walk = KnownStages<Modin3s>;
                    $call
                }
                Some(ComposedBase::Modin2s) => {
                    type $walk = KnownStages<Modin2s>;
                    $call
                }
                Some(ComposedBase::Csv1) => {
                    type $walk = KnownStages<Csv1>;
                    $call
                }
                Some(ComposedBase::PositionVerlet) => {
                    type $walk = KnownStages<PositionVerlet>;
                    $call
                }
                Some(ComposedBase::VelocityVerlet) => {
                    type $walk = KnownStages<VelocityVerlet>;
                    $call
                }
                Some(ComposedBase::UndampedVelocityVerlet) => {
                    type $walk = KnownStages<UndampedVelocityVerlet>;
                    $call
                }
                None => {
                    type $walk = Loop;
                    $call
                }
            }
        }
    };
}
pub(super) use with_walk;
