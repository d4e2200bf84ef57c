//! The Cranelift back end: a [`Program`] to native straight-line code.
//!
//! The generated function is `extern "C" fn(inputs: *const f64, outputs: *mut f64)`.
//! Each instruction becomes one Cranelift instruction: loads from `inputs`, `fadd`,
//! `fsub`, `fmul`, `fdiv`, `fneg`, `fabs` and `sqrt` in registers, stores to `outputs`.
//! Everything else (`sin`, `exp`, `pow`, `atan2`, …) is a call to the `extern "C"`
//! entry points in [`ops`](crate::expr::ops), which run the same Rust code as the
//! interpreter. An [`Emitter`] also writes programs over vectors of f64 lanes (the compiled
//! lanes of `flows::compiled`): the same arithmetic lane by lane, a call per lane for
//! the rest. Where a program takes both the sine and the cosine of one value, one call gives
//! both ([`entry::sin_cos`], the same bits: a driven system's forcing and its clock's force are
//! such a pair). Where that value is a function of a driven system's clock alone, the call
//! remembers its results per thread ([`entry::sin_cos_remembered`]): a map's cells step through
//! the same times. Cranelift never contracts a multiply and an add into a fused multiply-add, and
//! its rewrites of floating-point code are exact, so the native code computes exactly what the
//! interpreter does.

use std::collections::{HashMap, HashSet};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Mutex;

use cranelift_codegen::ir::immediates::Ieee64;
use cranelift_codegen::ir::{
    types, AbiParam, InstBuilder, MemFlagsData, SigRef, Signature, StackSlotData, StackSlotKind,
    Value,
};
use cranelift_codegen::settings::{self, Configurable};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext};
use cranelift_jit::JITBuilder;
pub(crate) use cranelift_jit::JITModule;
use cranelift_module::{default_libcall_names, Module};

use crate::expr::ops::{entry, BinaryOp, UnaryOp};
use crate::expr::program::{Instr, Program};

pub(crate) type CompiledFn = unsafe extern "C" fn(*const f64, *mut f64);

/// Native code for one program, and the module that owns its memory.
pub(crate) struct JitFunction {
    code: CompiledFn,
    /// Only touched on drop.
    #[allow(dead_code)]
    module: OwnedModule,
}

impl std::fmt::Debug for JitFunction {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JitFunction").finish_non_exhaustive()
    }
}

impl JitFunction {
    /// The native code: `code(inputs, outputs)` reads the program's inputs and writes its
    /// outputs without checking bounds. It is valid as long as `self` lives.
    pub(crate) fn code(&self) -> CompiledFn {
        self.code
    }
}

/// Compiles a program to native code, or says why it cannot.
pub(crate) fn compile(program: &Program) -> Result<JitFunction, String> {
    // A failure inside the code generator must not take the caller down: the
    // interpreter can always run the program instead.
    catch_unwind(AssertUnwindSafe(|| build(program, 1, 1)))
        .unwrap_or_else(|_| Err("the code generator panicked".to_string()))
}

/// A JIT module for this CPU. A single program arrives value-numbered, folded and free of dead
/// code, so the optimiser's e-graph pass finds nothing to do in it: skipping it (`optimise`
/// false) halves compile time for large programs and measured no slower to run. Loops of whole
/// steps (`optimise`) leave it constants to hoist and values to share across flows. Its rewrites
/// of floating-point code are exact either way.
pub(crate) fn module(optimise: bool) -> Result<JITModule, String> {
    let mut flags = settings::builder();
    for (name, value) in [
        ("opt_level", if optimise { "speed" } else { "none" }),
        // Required by cranelift-jit: absolute addresses, no colocated libcalls.
        ("use_colocated_libcalls", "false"),
        ("is_pic", "false"),
    ] {
        flags.set(name, value).map_err(|e| e.to_string())?;
    }
    let isa = cranelift_native::builder()
        .map_err(|e| e.to_string())?
        .finish(settings::Flags::new(flags))
        .map_err(|e| e.to_string())?;
    Ok(JITModule::new(JITBuilder::with_isa(
        isa,
        default_libcall_names(),
    )))
}

/// Emits programs' instructions into a function being built: arithmetic in registers, the
/// other operations as calls to the `extern "C"` entry points in [`ops`](crate::expr::ops).
pub(crate) struct Emitter {
    pointer: types::Type,
    unary: SigRef,
    binary: SigRef,
    /// `(f64, *mut f64) -> f64`: [`entry::sin_cos`].
    sin_cos: SigRef,
    /// The input whose values recur from cell to cell of a map (a driven system's clock):
    /// sines and cosines of it alone are remembered ([`entry::sin_cos_remembered`]).
    recurring: Option<u32>,
    /// The values' type: `F64`, or a vector of f64 lanes, each computed as the scalar code
    /// computes it (the vector arithmetic is lane by lane IEEE, the calls are made per lane).
    ty: types::Type,
}

impl Emitter {
    /// The target's pointer type.
    pub(crate) fn pointer(&self) -> types::Type {
        self.pointer
    }

    /// An emitter whose values are of `ty`, `F64` or a vector of f64 lanes.
    pub(crate) fn of_type(module: &JITModule, b: &mut FunctionBuilder, ty: types::Type) -> Self {
        let call_conv = module.isa().default_call_conv();
        let float_signature = |params: usize| {
            let mut sig = Signature::new(call_conv);
            sig.params
                .extend((0..params).map(|_| AbiParam::new(types::F64)));
            sig.returns.push(AbiParam::new(types::F64));
            sig
        };
        let pointer = module.target_config().pointer_type();
        let mut sin_cos = float_signature(1);
        sin_cos.params.push(AbiParam::new(pointer));
        Emitter {
            pointer,
            unary: b.import_signature(float_signature(1)),
            binary: b.import_signature(float_signature(2)),
            sin_cos: b.import_signature(sin_cos),
            recurring: None,
            ty,
        }
    }

    /// The same, with `input`'s values recurring from cell to cell (see [`Self::recurring`]).
    pub(crate) fn with_recurring_input(self, input: Option<u32>) -> Self {
        Emitter {
            recurring: input,
            ..self
        }
    }

    /// The scalar `x` in every lane of the values' type.
    pub(crate) fn broadcast(&self, b: &mut FunctionBuilder, x: Value) -> Value {
        if self.ty.is_vector() {
            b.ins().splat(self.ty, x)
        } else {
            x
        }
    }

    /// The entry point `callee` of signature `signature` applied to `args`, lane by lane.
    fn call(
        &self,
        b: &mut FunctionBuilder,
        signature: SigRef,
        callee: usize,
        args: &[Value],
    ) -> Value {
        let address = b.ins().iconst(self.pointer, callee as i64);
        let apply = |b: &mut FunctionBuilder, args: &[Value]| {
            let call = b.ins().call_indirect(signature, address, args);
            b.inst_results(call)[0]
        };
        if !self.ty.is_vector() {
            return apply(b, args);
        }
        let mut result = None;
        for lane in 0..self.ty.lane_count() as u8 {
            let lane_args: Vec<Value> =
                args.iter().map(|&a| b.ins().extractlane(a, lane)).collect();
            let value = apply(b, &lane_args);
            result = Some(self.gather(b, result, value, lane));
        }
        result.expect("a vector has lanes")
    }

    /// `vector` (none yet for lane 0) with `value` in lane `lane`.
    fn gather(
        &self,
        b: &mut FunctionBuilder,
        vector: Option<Value>,
        value: Value,
        lane: u8,
    ) -> Value {
        match vector {
            None => b.ins().splat(self.ty, value),
            Some(vector) => b.ins().insertlane(vector, value, lane),
        }
    }

    /// sin x and cos x from one call of [`entry::sin_cos`], or of
    /// [`entry::sin_cos_remembered`] where x `recurs` (per lane), the cosine passed back through
    /// a stack slot.
    fn sin_cos(&self, b: &mut FunctionBuilder, x: Value, recurs: bool) -> (Value, Value) {
        let slot = b.create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 8, 3));
        let function = match recurs {
            true => entry::sin_cos_remembered,
            false => entry::sin_cos,
        };
        let address = b
            .ins()
            .iconst(self.pointer, function as *const () as usize as i64);
        let apply = |b: &mut FunctionBuilder, x: Value| {
            let cos_at = b.ins().stack_addr(self.pointer, slot, 0);
            let call = b.ins().call_indirect(self.sin_cos, address, &[x, cos_at]);
            let sine = b.inst_results(call)[0];
            (sine, b.ins().stack_load(self.pointer, types::F64, slot, 0))
        };
        if !self.ty.is_vector() {
            return apply(b, x);
        }
        let (mut sine, mut cosine) = (None, None);
        for lane in 0..self.ty.lane_count() as u8 {
            let x = b.ins().extractlane(x, lane);
            let (s, c) = apply(b, x);
            sine = Some(self.gather(b, sine, s, lane));
            cosine = Some(self.gather(b, cosine, c, lane));
        }
        (
            sine.expect("a vector has lanes"),
            cosine.expect("a vector has lanes"),
        )
    }

    /// Emits `program`: its input `i` is `load(b, i)`, and each output `o` it computes goes to
    /// `store(b, o, value)`, in the program's order.
    pub(crate) fn emit(
        &self,
        b: &mut FunctionBuilder,
        program: &Program,
        load: &mut dyn FnMut(&mut FunctionBuilder, u32) -> Result<Value, String>,
        store: &mut dyn FnMut(&mut FunctionBuilder, u32, Value) -> Result<(), String>,
    ) -> Result<(), String> {
        let mut regs: Vec<Option<Value>> = vec![None; program.registers()];
        let get = |regs: &[Option<Value>], r: u32| regs[r as usize].ok_or("read before write");
        let paired = sine_and_cosine_pairs(program);
        // The sine and cosine of each paired value, once the first of the two is reached.
        let mut pairs: HashMap<Value, (Value, Value)> = HashMap::new();
        // Per register: whether its value is a function of the recurring input alone.
        let mut recurs = vec![false; program.registers()];
        for (index, instr) in program.instrs().iter().enumerate() {
            recurs_after(instr, &mut recurs, self.recurring);
            let (dst, value) = match *instr {
                Instr::Load { dst, input } => (dst, load(b, input)?),
                Instr::Const { dst, value } => {
                    let scalar = b.ins().f64const(Ieee64::with_bits(value.to_bits()));
                    (dst, self.broadcast(b, scalar))
                }
                Instr::Unary { op, dst, a } => {
                    let x = get(&regs, a)?;
                    let value = match op {
                        UnaryOp::Neg => b.ins().fneg(x),
                        UnaryOp::Abs => b.ins().fabs(x),
                        UnaryOp::Sqrt => b.ins().sqrt(x),
                        UnaryOp::Sin | UnaryOp::Cos if paired.contains(&index) => {
                            let (sine, cosine) = *pairs
                                .entry(x)
                                .or_insert_with(|| self.sin_cos(b, x, recurs[dst as usize]));
                            if op == UnaryOp::Sin {
                                sine
                            } else {
                                cosine
                            }
                        }
                        other => self.call(b, self.unary, entry::unary(other) as usize, &[x]),
                    };
                    (dst, value)
                }
                Instr::Binary { op, dst, a, b: rhs } => {
                    let (x, y) = (get(&regs, a)?, get(&regs, rhs)?);
                    let value = match op {
                        BinaryOp::Add => b.ins().fadd(x, y),
                        BinaryOp::Sub => b.ins().fsub(x, y),
                        BinaryOp::Mul => b.ins().fmul(x, y),
                        BinaryOp::Div => b.ins().fdiv(x, y),
                        other => self.call(b, self.binary, entry::binary(other) as usize, &[x, y]),
                    };
                    (dst, value)
                }
                Instr::Store { src, output } => {
                    store(b, output, get(&regs, src)?)?;
                    continue;
                }
            };
            regs[dst as usize] = Some(value);
        }
        Ok(())
    }
}

/// The `sin` and `cos` instructions (their indices) whose argument `program` takes both the
/// sine and the cosine of. A register holds several values in turn (a dead value's register is
/// written again), so a value is told apart by the instruction that wrote its register.
fn sine_and_cosine_pairs(program: &Program) -> HashSet<usize> {
    // Per register: the index of the instruction that last wrote it, plus one (0: an input).
    let mut written = vec![0usize; program.registers()];
    let (mut sines, mut cosines) = (HashMap::new(), HashMap::new());
    for (index, instr) in program.instrs().iter().enumerate() {
        let dst = match *instr {
            Instr::Unary { op, dst, a } => {
                let value = (a, written[a as usize]);
                match op {
                    UnaryOp::Sin => sines.insert(value, index),
                    UnaryOp::Cos => cosines.insert(value, index),
                    _ => None,
                };
                dst
            }
            Instr::Load { dst, .. } | Instr::Const { dst, .. } | Instr::Binary { dst, .. } => dst,
            Instr::Store { .. } => continue,
        };
        written[dst as usize] = index + 1;
    }
    sines
        .iter()
        .filter_map(|(value, &sine)| Some([sine, *cosines.get(value)?]))
        .flatten()
        .collect()
}

/// Updates `recurs` (per register: whether its value is a function of the `recurring` input and
/// constants alone) for `instr`'s write.
fn recurs_after(instr: &Instr, recurs: &mut [bool], recurring: Option<u32>) {
    let (dst, value) = match *instr {
        Instr::Load { dst, input } => (dst, Some(input) == recurring),
        Instr::Const { dst, .. } => (dst, true),
        Instr::Unary { dst, a, .. } => (dst, recurs[a as usize]),
        Instr::Binary { dst, a, b, .. } => (dst, recurs[a as usize] && recurs[b as usize]),
        Instr::Store { .. } => return,
    };
    recurs[dst as usize] = value;
}

/// The byte offset of slot `index` of an f64 array.
pub(crate) fn offset(index: u32) -> Result<i32, String> {
    i32::try_from(u64::from(index) * 8).map_err(|_| "slot offset too large".to_string())
}

/// Defines the function built in `ctx` in `module` and returns its address and the module,
/// which owns its memory.
pub(crate) fn finish(
    mut module: JITModule,
    mut ctx: cranelift_codegen::Context,
) -> Result<(*const u8, JITModule), String> {
    let signature = ctx.func.signature.clone();
    let id = module
        .declare_anonymous_function(&signature)
        .map_err(|e| e.to_string())?;
    module
        .define_function(id, &mut ctx)
        .map_err(|e| e.to_string())?;
    module.clear_context(&mut ctx);
    module.finalize_definitions().map_err(|e| e.to_string())?;
    Ok((module.get_finalized_function(id), module))
}

/// Frees a JIT module's code once nothing can call it.
pub(crate) struct OwnedModule(Mutex<Option<JITModule>>);

impl OwnedModule {
    pub(crate) fn new(module: JITModule) -> Self {
        OwnedModule(Mutex::new(Some(module)))
    }
}

impl Drop for OwnedModule {
    fn drop(&mut self) {
        let module = match self.0.get_mut() {
            Ok(slot) => slot.take(),
            Err(poisoned) => poisoned.into_inner().take(),
        };
        if let Some(module) = module {
            // SAFETY: the module's functions are reachable only through their owner, which is
            // being dropped: nothing can be running them or call them again.
            unsafe { module.free_memory() };
        }
    }
}

impl std::fmt::Debug for OwnedModule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OwnedModule").finish_non_exhaustive()
    }
}

/// The f64s in the widest vector Cranelift lowers arithmetic on here: f64×2 on x86-64 (SSE2, or
/// AVX's encodings) and AArch64 (Neon), whose vectors are no wider than 128 bits; elsewhere 1
/// (scalars).
pub(crate) const VECTOR_WIDTH: usize = if cfg!(any(target_arch = "x86_64", target_arch = "aarch64"))
{
    2
} else {
    1
};

/// Compiles `program` over `lanes` runs side by side, as one function of the same signature:
/// input i of run l is `inputs[i·lanes + l]` and output o of run l is `outputs[o·lanes + l]` (an
/// array `[[f64; lanes]; n]`, the SIMD lanes' layout), `width` adjacent runs to a value (a vector
/// of `width` f64s; 1: scalars). Each run's outputs are the bits the scalar code gives it: the
/// arithmetic is lane by lane IEEE, the calls are per lane. The program is written once per
/// group of `width` runs, independent chains the processor overlaps.
pub(crate) fn compile_lanes(
    program: &Program,
    lanes: usize,
    width: usize,
) -> Result<JitFunction, String> {
    if width == 0 || !lanes.is_multiple_of(width) {
        return Err(format!(
            "{lanes} lanes do not split into vectors of {width}"
        ));
    }
    catch_unwind(AssertUnwindSafe(|| build(program, lanes, width)))
        .unwrap_or_else(|_| Err("the code generator panicked".to_string()))
}

/// The function of [`compile_lanes`]; one run in scalars is `lanes` = `width` = 1.
fn build(program: &Program, lanes: usize, width: usize) -> Result<JitFunction, String> {
    let module = module(false)?;
    let pointer = module.target_config().pointer_type();
    let mut signature = module.make_signature();
    signature.params.push(AbiParam::new(pointer));
    signature.params.push(AbiParam::new(pointer));
    let mut ctx = module.make_context();
    ctx.func.signature = signature;

    let mut builder_ctx = FunctionBuilderContext::new();
    let mut b = FunctionBuilder::new(&mut ctx.func, &mut builder_ctx);
    let block = b.create_block();
    b.append_block_params_for_function_params(block);
    b.switch_to_block(block);
    b.seal_block(block);
    let (inputs, outputs) = (b.block_params(block)[0], b.block_params(block)[1]);
    let ty = match width {
        1 => types::F64,
        width => types::F64
            .by(u32::try_from(width).map_err(|e| e.to_string())?)
            .ok_or("no vector of that many f64s")?,
    };
    // The arrays are aligned for f64 and their lengths checked before the call; a vector's
    // access is not necessarily aligned for the vector.
    let flags = match width {
        1 => MemFlagsData::trusted(),
        _ => MemFlagsData::new().with_notrap(),
    };
    let emitter = Emitter::of_type(&module, &mut b, ty);
    let slot = |index: u32, first: usize| -> Result<i32, String> {
        let index = u64::from(index) * lanes as u64 + first as u64;
        offset(u32::try_from(index).map_err(|e| e.to_string())?)
    };
    for first in (0..lanes).step_by(width) {
        emitter.emit(
            &mut b,
            program,
            &mut |b, input| Ok(b.ins().load(ty, flags, inputs, slot(input, first)?)),
            &mut |b, output, value| {
                b.ins().store(flags, value, outputs, slot(output, first)?);
                Ok(())
            },
        )?;
    }
    b.ins().return_(&[]);
    b.finalize(module.target_config());
    let (address, module) = finish(module, ctx)?;
    // SAFETY: the function was just defined with the signature (pointer, pointer) -> ()
    // in the platform's default calling convention, which is the C one.
    let code = unsafe { std::mem::transmute::<*const u8, CompiledFn>(address) };
    Ok(JitFunction {
        code,
        module: OwnedModule::new(module),
    })
}
