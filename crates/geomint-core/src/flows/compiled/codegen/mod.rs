//! The compiled steps' code generator: a system's stretches of a splitting, compiled with
//! Cranelift from its programs ([`ForcePrograms`]: a typed-in system's, or a built-in one's
//! traced from its code): the composer's fused stretch (see `flows::compiled`), or its whole
//! steps when the method's last and first flows do not fuse, as one loop in which the state
//! lives in registers and the potential's gradient program is written into every kick that
//! evaluates it (where a typed-in system's generic path calls its compiled gradient through a
//! pointer at each).
//!
//! Taken: separable systems (constant mass in any of its forms) without damping, with conformal
//! damping or with a projector damping r D(q) p, and sequences of drifts, kicks and damping flows
//! (modin_3s, csv1, their compositions, …); without damping also the Verlets' θ-kicks, which are
//! then plain kicks. A driven system's splittings are taken too (without a projector damping; its
//! Runge–Kutta steps are left to the stepper): its clock t is the last coordinate, whose velocity
//! is 1 and whose momentum the kick gives −τ ∂V/∂t. Each flow is the composer's arithmetic:
//! - drift: v = M⁻¹p as `InverseMass::apply` computes it (and 1 for a clock), then q ← τv + q;
//! - kick: ∇V(q) evaluated unless the cache holds it, then p ← (−τ)g + p;
//! - damping: w = D(q)p (w = p when conformal), then p ← (−c)w + p with c = 1 − e^{−rτ}
//!   (nothing when c = 0).
//!
//! After each step the state's components are summed in the one-run path's order (positions,
//! then momenta), less its leading 0 +, which cannot change whether the sum is finite, and the
//! stretch reports a sum that is not finite.
//!
//! This file holds the entry points, how the runs sit in the arrays ([`LaneLayout`]) and the
//! state every stretch shares; `splitting.rs` writes a splitting's flows and `runge_kutta.rs` a
//! Runge–Kutta method's steps.

use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::immediates::Ieee64;
use cranelift_codegen::ir::{
    types, AbiParam, Block, InstBuilder, MemFlagsData, StackSlot, StackSlotData, StackSlotKind,
    Type, Value,
};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext, Variable};
use cranelift_module::Module;

use super::{CompiledStretch, StretchFn, StretchPlan};
use crate::expr::jit::{self, Emitter, OwnedModule};
use crate::expr::program::Program;
use crate::flows::{InverseMass, SubFlow, Tableau, LANES};

mod runge_kutta;
mod splitting;

/// What compiled steps take from a system: its forces as programs of q, its mass and its
/// damping. A typed-in system gives its own programs, a built-in one its force traced from its
/// code (`expr::trace`).
pub struct ForcePrograms<'a> {
    /// Coordinates, a driven system's clock among them.
    pub n: usize,
    /// A driven system's clock, the last coordinate: its velocity ∂H̃/∂p_t is 1, and M⁻¹ acts
    /// on the coordinates before it (as on the one-run path and in the generic lanes).
    pub clock: Option<usize>,
    /// ∇V as a program of q.
    pub gradient: &'a Program,
    /// M⁻¹.
    pub inverse_mass: &'a InverseMass,
    /// D(q) as a program of q (n² outputs, row-major) for a damping r D(q) p with D(q) a
    /// projector; `None` for conformal damping (D = I) or none.
    pub projector: Option<&'a Program>,
    /// The damping rate r (0 undamped).
    pub rate: f64,
}

/// Compiles `plan` for the system of `parts`, or says why not (a flow it does not take).
pub(super) fn compile(
    plan: &StretchPlan,
    parts: &ForcePrograms,
) -> Result<CompiledStretch, String> {
    check(plan, parts)?;
    build(parts, LaneLayout::ONE_RUN, |s| s.splitting(plan))
}

/// Compiles `plan` for [`LANES`] runs of the system of `parts` side by side (the plain runs'
/// lanes, `methods::lanes::runs`): each lane's flows are [`compile`]'s, two lanes to a vector
/// where the target has f64×2 vectors ([`LaneLayout::LANES`]), independent chains that the
/// processor overlaps. The arrays hold component i of lane l at i·LANES + l. One call runs
/// [`LaneLayout::LANES`]'s lanes from the arrays' starts (all of them); every lane takes all n
/// steps, and the code returns the mask of the lanes whose state did not sum to a finite number
/// after some step (bit l for lane l), which the lanes' engine runs again step by step.
pub(super) fn compile_lanes(
    plan: &StretchPlan,
    parts: &ForcePrograms,
) -> Result<CompiledStretch, String> {
    check(plan, parts)?;
    build(parts, LaneLayout::LANES, |s| s.splitting(plan))
}

/// How a function's runs sit in its arrays and in its values.
#[derive(Clone, Copy, Debug)]
struct LaneLayout {
    /// Runs one call takes, from the arrays' starts.
    lanes: usize,
    /// Runs one value holds: 1 (an f64), or that many adjacent lanes in a vector.
    width: usize,
    /// Lanes in the arrays: component i of lane l is at i·stride + l.
    stride: usize,
}

impl LaneLayout {
    /// One run in scalars.
    const ONE_RUN: LaneLayout = LaneLayout {
        lanes: 1,
        width: 1,
        stride: 1,
    };

    /// The plain runs' lanes, [`jit::VECTOR_WIDTH`] to a vector (f64×2 where Cranelift lowers
    /// it, scalars elsewhere). All the lanes in one call, eight independent chains of vectors: in one build
    /// of `cargo bench --bench chaos`, the typed-in Hénon–Heiles sweep took 7.2–7.8 ns per
    /// cell-step with them, against 7.6–8.4 with eight lanes to a call and 10.7 with four (the
    /// state spills out of the 16 registers Cranelift allocates either way).
    const LANES: LaneLayout = LaneLayout {
        lanes: LANES,
        width: jit::VECTOR_WIDTH,
        stride: LANES,
    };

    /// The type of a value: f64, or a vector of `width` of them.
    fn value_type(self) -> Type {
        match self.width {
            1 => types::F64,
            width => types::F64.by(width as u32).expect("a vector of f64"),
        }
    }

    /// The memory flags of the state's loads and stores: the arrays are in bounds (the caller
    /// checks their length) and aligned for f64, not necessarily for a vector.
    fn flags(self) -> MemFlagsData {
        match self.width {
            1 => MemFlagsData::trusted(),
            _ => MemFlagsData::new().with_notrap(),
        }
    }
}

/// Whether the stretches take `plan` on the system of `parts`.
fn check(plan: &StretchPlan, parts: &ForcePrograms) -> Result<(), String> {
    let taken = plan
        .flows
        .iter()
        .all(|&(flow, _)| kind(flow, parts).is_some());
    if !taken || plan.flows.len() < 2 || plan.coefficients.len() != plan.flows.len() {
        return Err("a flow the compiled stretch does not take".into());
    }
    Ok(())
}

/// The flow a stretch writes for `flow`, if it takes it: a θ-kick of an undamped system is the
/// plain kick (`flows::kick_theta` with r = 0 is `flows::kick`, operation for operation), so
/// the Verlets, symplectic Euler and their compositions compile when nothing damps.
fn kind(flow: SubFlow, parts: &ForcePrograms) -> Option<SubFlow> {
    match flow {
        SubFlow::Drift | SubFlow::Kick | SubFlow::Damp => Some(flow),
        SubFlow::DampedKick(_) if parts.rate == 0.0 => Some(SubFlow::Kick),
        _ => None,
    }
}

/// Compiles steps of the explicit Runge–Kutta method `tableau` at step `h` for the system of
/// `parts`: the stepper's arithmetic (each stage's argument z + Σⱼ (h aᵢⱼ) kⱼ over the nonzero
/// aᵢⱼ, the field (M⁻¹p, −(∇V + r P(q)p)), then z + Σᵢ (h bᵢ) kᵢ), and the count of one force
/// evaluation per stage. The code stops after the first step whose state does not sum to a
/// finite number, as the one-run path's steps do, and returns the steps taken.
pub(super) fn compile_runge_kutta(
    tableau: &Tableau,
    h: f64,
    parts: &ForcePrograms,
) -> Result<CompiledStretch, String> {
    if parts.clock.is_some() {
        return Err("a driven system's Runge–Kutta steps are the stepper's".into());
    }
    build(parts, LaneLayout::ONE_RUN, |s| s.runge_kutta(tableau, h))
}

/// A function of [`StretchFn`]'s signature over the runs of `layout` whose loop `body` writes.
fn build(
    parts: &ForcePrograms,
    layout: LaneLayout,
    body: impl FnOnce(&mut Stretch) -> Result<(), String>,
) -> Result<CompiledStretch, String> {
    let module = jit::module(true)?;
    let pointer = module.target_config().pointer_type();
    let mut ctx = module.make_context();
    for _ in 0..4 {
        ctx.func.signature.params.push(AbiParam::new(pointer));
    }
    ctx.func.signature.params.push(AbiParam::new(types::I64));
    ctx.func.signature.returns.push(AbiParam::new(types::I64));
    let mut builder_ctx = FunctionBuilderContext::new();
    let mut b = FunctionBuilder::new(&mut ctx.func, &mut builder_ctx);
    // In lanes (the cells of a map or sweep) the clock's values recur from cell to cell: every
    // cell starts at the same time and steps alike, so the sines and cosines of a driven
    // system's forcing are remembered. A single run never sees a time twice.
    let clock = parts.clock.filter(|_| layout.lanes > 1).map(|k| k as u32);
    let emitter =
        Emitter::of_type(&module, &mut b, layout.value_type()).with_recurring_input(clock);
    let mut s = Stretch::new(&mut b, parts, layout, emitter)?;
    body(&mut s)?;
    b.seal_all_blocks();
    b.finalize(module.target_config());
    let (address, module) = jit::finish(module, ctx)?;
    // SAFETY: the function was just defined with StretchFn's signature in the platform's C
    // calling convention; it reads and writes n components of q, p and grad and two counters,
    // and `module` owns it.
    unsafe {
        let code = std::mem::transmute::<*const u8, StretchFn>(address);
        Ok(CompiledStretch::new(
            code,
            parts.n * layout.stride,
            layout.lanes,
            OwnedModule::new(module),
        ))
    }
}

/// The function being built: its arguments and the variables that hold the state.
struct Stretch<'a, 'b> {
    b: &'a mut FunctionBuilder<'b>,
    parts: &'a ForcePrograms<'a>,
    emitter: Emitter,
    args: [Value; 5],
    /// The value being written (a lane, or `layout.width` of them): its positions, momenta and
    /// force (see [`Self::lane`]).
    q: Vec<Variable>,
    p: Vec<Variable>,
    g: Vec<Variable>,
    /// Every value's q, p and force (one for a single run), value k holding lanes
    /// k·width to (k + 1)·width − 1.
    lanes: Vec<[Vec<Variable>; 3]>,
    layout: LaneLayout,
    /// Lanes whose state was not finite after some step, as a mask (lanes only).
    left: Variable,
    /// Whether g holds ∇V(q), as 0 or 1 (the same for every lane: they take the same flows).
    valid: Variable,
    /// What the code being written knows of `valid` here: after a drift it is 0, after an
    /// evaluation 1, and a kick then writes no test; at a loop's head it is unknown.
    known_valid: Option<bool>,
    evaluations: Variable,
    /// Steps done, counting the one under way.
    done: Variable,
}

/// The index of component `i` of lane `lane` in arrays of `stride` lanes (i·stride + lane).
fn slot(i: usize, lane: usize, stride: usize) -> Result<u32, String> {
    u32::try_from(i * stride + lane).map_err(|_| "too many components".to_string())
}

impl<'a, 'b> Stretch<'a, 'b> {
    /// The entry block: the state, the force cache and the counters loaded into variables.
    fn new(
        b: &'a mut FunctionBuilder<'b>,
        parts: &'a ForcePrograms<'a>,
        layout: LaneLayout,
        emitter: Emitter,
    ) -> Result<Self, String> {
        let entry = b.create_block();
        b.append_block_params_for_function_params(entry);
        b.switch_to_block(entry);
        let params = b.block_params(entry);
        let args = [params[0], params[1], params[2], params[3], params[4]];
        let ty = layout.value_type();
        let vars =
            |b: &mut FunctionBuilder, array: Value, lane: usize| -> Result<Vec<Variable>, String> {
                (0..parts.n)
                    .map(|i| {
                        let var = b.declare_var(ty);
                        let at = jit::offset(slot(i, lane, layout.stride)?)?;
                        let value = b.ins().load(ty, layout.flags(), array, at);
                        b.def_var(var, value);
                        Ok(var)
                    })
                    .collect()
            };
        let all = (0..layout.lanes)
            .step_by(layout.width)
            .map(|l| {
                Ok([
                    vars(b, args[0], l)?,
                    vars(b, args[1], l)?,
                    vars(b, args[2], l)?,
                ])
            })
            .collect::<Result<Vec<_>, String>>()?;
        let [q, p, g] = all[0].clone();
        let left = b.declare_var(types::I64);
        let none = b.ins().iconst(types::I64, 0);
        b.def_var(left, none);
        let counter = |b: &mut FunctionBuilder, slot: i32| {
            let var = b.declare_var(types::I64);
            let value = b
                .ins()
                .load(types::I64, MemFlagsData::trusted(), args[3], slot * 8);
            b.def_var(var, value);
            var
        };
        let valid = counter(b, 0);
        let evaluations = counter(b, 1);
        let done = b.declare_var(types::I64);
        let one = b.ins().iconst(types::I64, 1);
        b.def_var(done, one);
        Ok(Stretch {
            b,
            parts,
            emitter,
            args,
            q,
            p,
            g,
            lanes: all,
            layout,
            left,
            valid,
            known_valid: None,
            evaluations,
            done,
        })
    }

    /// Counts the step and goes on to the next at `step`, or after the n-th into a new block,
    /// where the caller ends the stretch.
    fn next_step(&mut self, step: Block) {
        let (next, ended) = (self.b.create_block(), self.b.create_block());
        let done = self.b.use_var(self.done);
        let last = self.b.ins().icmp(IntCC::Equal, done, self.args[4]);
        self.b.ins().brif(last, ended, &[], next, &[]);
        self.b.switch_to_block(next);
        let done = self.b.ins().iadd_imm_s(done, 1);
        self.b.def_var(self.done, done);
        self.b.ins().jump(step, &[]);
        self.b.switch_to_block(ended);
    }

    /// The end of a step of the loop that starts at `step`: the next step, or after the n-th
    /// the state stored and n returned. A step that leaves the state not finite returns 0 when
    /// `keep_at_stop` is false (the caller runs the stretch again), else stores the state and
    /// returns the steps taken.
    fn end_of_step(&mut self, step: Block, keep_at_stop: bool) -> Result<(), String> {
        let not_finite = self.not_finite();
        let (more, stopped) = (self.b.create_block(), self.b.create_block());
        self.b.ins().brif(not_finite, stopped, &[], more, &[]);
        self.b.switch_to_block(more);
        self.next_step(step);
        self.store()?;
        let done = self.b.use_var(self.done);
        self.b.ins().return_(&[done]);
        self.b.switch_to_block(stopped);
        if keep_at_stop {
            self.store()?;
            let done = self.b.use_var(self.done);
            self.b.ins().return_(&[done]);
        } else {
            let none = self.b.ins().iconst(types::I64, 0);
            self.b.ins().return_(&[none]);
        }
        Ok(())
    }

    /// `x` in every lane of a value.
    fn constant(&mut self, x: f64) -> Value {
        let scalar = self.b.ins().f64const(Ieee64::with_bits(x.to_bits()));
        self.emitter.broadcast(self.b, scalar)
    }

    /// D(q) p as the system's `damping_times` computes it: the matrix's program written here,
    /// each row's products summed from the first.
    fn projected(&mut self, matrix: &Program) -> Result<Vec<Value>, String> {
        let (q, p) = (self.values(&self.q.clone()), self.values(&self.p.clone()));
        self.projected_of(matrix, &q, &p)
    }

    /// D(q) p at the given positions and momenta.
    fn projected_of(
        &mut self,
        matrix: &Program,
        q: &[Value],
        p: &[Value],
    ) -> Result<Vec<Value>, String> {
        let n = self.parts.n;
        let d = self.program_of(matrix, q, n * n)?;
        let rows = d.chunks(n).map(|row| {
            let mut sum: Option<Value> = None;
            for (&a, &x) in row.iter().zip(p) {
                let term = self.b.ins().fmul(a, x);
                sum = Some(match sum {
                    None => term,
                    Some(s) => self.b.ins().fadd(s, term),
                });
            }
            sum.ok_or_else(|| "an empty row".to_string())
        });
        rows.collect()
    }

    /// The velocity at the current momenta (see [`Self::velocity_of`]).
    fn velocity(&mut self) -> Vec<Value> {
        let p = self.values(&self.p.clone());
        self.velocity_of(&p)
    }

    /// The variables' current values.
    fn values(&mut self, vars: &[Variable]) -> Vec<Value> {
        vars.iter().map(|&var| self.b.use_var(var)).collect()
    }

    /// M⁻¹p, as `InverseMass::apply` computes it, and a driven system's clock's velocity 1.
    fn velocity_of(&mut self, p: &[Value]) -> Vec<Value> {
        let n = self.parts.clock.unwrap_or(self.parts.n);
        let p = p[..n].to_vec();
        let mut v = match self.parts.inverse_mass {
            InverseMass::Unit => p,
            InverseMass::Scalar(m) => {
                let m = self.constant(*m);
                p.iter().map(|&x| self.b.ins().fdiv(x, m)).collect()
            }
            InverseMass::Diagonal(d) => {
                let d = d.clone();
                p.iter()
                    .zip(d)
                    .map(|(&x, m)| {
                        let m = self.constant(m);
                        self.b.ins().fdiv(x, m)
                    })
                    .collect()
            }
            InverseMass::Full(inverse) => {
                let inverse = inverse.clone();
                (0..n)
                    .map(|i| {
                        // Σⱼ aᵢⱼ xⱼ from the first term: an f64 sum's start, −0, adds nothing.
                        let mut sum = None;
                        for (j, &x) in p.iter().enumerate() {
                            let a = self.constant(inverse[i * n + j]);
                            let term = self.b.ins().fmul(a, x);
                            sum = Some(match sum {
                                None => term,
                                Some(s) => self.b.ins().fadd(s, term),
                            });
                        }
                        sum.expect("at least one degree of freedom")
                    })
                    .collect()
            }
        };
        if self.parts.clock.is_some() {
            v.push(self.constant(1.0));
        }
        v
    }

    /// The `outputs` values of a program of q, written here with q = `q`.
    ///
    /// A value live across a call is kept in memory by the register allocator, and for the
    /// state's variables, which the loop carries from step to step, it kept them there for the
    /// whole loop: a step's last update of p was stored and loaded again before the next step's
    /// drift, on the chain of every step. Around a program that calls, the state is therefore
    /// stored before it and its variables loaded again after it, so that the loop carries them
    /// in registers (P1 typed in, modin_3s: 19.0 → 17.1 ns per step, the built-in system's
    /// 17.2). Lanes are bound by throughput, not by one chain, and keep the allocator's choice.
    fn program_of(
        &mut self,
        program: &Program,
        q: &[Value],
        outputs: usize,
    ) -> Result<Vec<Value>, String> {
        let one_run = self.lanes.len() == 1;
        let kept = (one_run && program.makes_calls()).then(|| self.keep_state());
        let out = self.emit_program(program, q, outputs)?;
        if let Some(kept) = kept {
            self.reload_state(kept);
        }
        Ok(out)
    }

    /// The state's q and p stored in a stack slot of their own.
    fn keep_state(&mut self) -> (StackSlot, Vec<(Variable, i32)>) {
        let (pointer, ty) = (self.emitter.pointer(), self.layout.value_type());
        let vars: Vec<Variable> = self.q.iter().chain(&self.p).copied().collect();
        let bytes = ty.bytes();
        let slot = self.b.create_sized_stack_slot(StackSlotData::new(
            StackSlotKind::ExplicitSlot,
            bytes * vars.len() as u32,
            bytes.trailing_zeros() as u8,
        ));
        let places = (vars.into_iter().enumerate())
            .map(|(k, var)| {
                let offset = (k as u32 * bytes) as i32;
                let value = self.b.use_var(var);
                self.b.ins().stack_store(pointer, value, slot, offset);
                (var, offset)
            })
            .collect();
        (slot, places)
    }

    /// The variables [`Self::keep_state`] stored, loaded again.
    fn reload_state(&mut self, (slot, places): (StackSlot, Vec<(Variable, i32)>)) {
        let (pointer, ty) = (self.emitter.pointer(), self.layout.value_type());
        for (var, offset) in places {
            let value = self.b.ins().stack_load(pointer, ty, slot, offset);
            self.b.def_var(var, value);
        }
    }

    /// [`Self::program_of`]'s program, written as it is.
    fn emit_program(
        &mut self,
        program: &Program,
        q: &[Value],
        outputs: usize,
    ) -> Result<Vec<Value>, String> {
        let mut out: Vec<Option<Value>> = vec![None; outputs];
        self.emitter.emit(
            self.b,
            program,
            &mut |_, input| {
                q.get(input as usize)
                    .copied()
                    .ok_or_else(|| "an input past q".into())
            },
            &mut |_, output, value| {
                let slot = out
                    .get_mut(output as usize)
                    .ok_or("an output past the program's")?;
                *slot = Some(value);
                Ok(())
            },
        )?;
        out.into_iter()
            .map(|v| v.ok_or_else(|| "an output never computed".to_string()))
            .collect()
    }

    /// Whether Σq + Σp, summed in order, is not finite: a bool, or per lane all ones or zeros in
    /// a vector. The one-run path sums each from 0; 0 + x differs from x only in a zero's sign,
    /// which no later sum can make infinite, so the verdict is the same without the first
    /// addition. s − s is 0 for a finite s and NaN for an infinite or NaN one.
    fn not_finite(&mut self) -> Value {
        let [q, p] = [self.q.clone(), self.p.clone()].map(|vars| {
            let values: Vec<Value> = vars.into_iter().map(|var| self.b.use_var(var)).collect();
            let (first, rest) = values
                .split_first()
                .expect("at least one degree of freedom");
            rest.iter()
                .fold(*first, |sum, &x| self.b.ins().fadd(sum, x))
        });
        let sum = self.b.ins().fadd(q, p);
        let zero_if_finite = self.b.ins().fsub(sum, sum);
        self.b
            .ins()
            .fcmp(FloatCC::Unordered, zero_if_finite, zero_if_finite)
    }

    /// The state, the force cache and the counters back into the caller's arrays.
    fn store(&mut self) -> Result<(), String> {
        let layout = self.layout;
        for (k, vars) in self.lanes.clone().into_iter().enumerate() {
            for (vars, &array) in vars.into_iter().zip(&self.args[..3]) {
                for (i, var) in vars.into_iter().enumerate() {
                    let value = self.b.use_var(var);
                    let at = jit::offset(slot(i, k * layout.width, layout.stride)?)?;
                    self.b.ins().store(layout.flags(), value, array, at);
                }
            }
        }
        for (slot, var) in [(0, self.valid), (1, self.evaluations)] {
            let value = self.b.use_var(var);
            self.b
                .ins()
                .store(MemFlagsData::trusted(), value, self.args[3], slot * 8);
        }
        Ok(())
    }
}
