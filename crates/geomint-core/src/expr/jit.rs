//! The Cranelift back end: a [`Program`] to native straight-line code.
//!
//! The generated function is `extern "C" fn(inputs: *const f64, outputs: *mut f64)`.
//! Each instruction becomes one Cranelift instruction: loads from `inputs`, `fadd`,
//! `fsub`, `fmul`, `fdiv`, `fneg`, `fabs` and `sqrt` in registers, stores to `outputs`.
//! Everything else (`sin`, `exp`, `pow`, `atan2`, …) is a call to the `extern "C"`
//! entry points in [`ops`](crate::expr::ops), which run the same Rust code as the
//! interpreter. Cranelift never contracts a multiply and an add into a fused
//! multiply-add, and its rewrites of floating-point code are exact, so the native code
//! computes exactly what the interpreter does.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Mutex;

use cranelift_codegen::ir::immediates::Ieee64;
use cranelift_codegen::ir::{types, AbiParam, InstBuilder, MemFlagsData, Signature, Value};
use cranelift_codegen::settings::{self, Configurable};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext};
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{default_libcall_names, Module};

use crate::expr::ops::{entry, BinaryOp, UnaryOp};
use crate::expr::program::{Instr, Program};

pub(crate) type CompiledFn = unsafe extern "C" fn(*const f64, *mut f64);

/// Native code for one program, and the module that owns its memory.
pub(crate) struct JitFunction {
    code: CompiledFn,
    /// Only touched on drop; the mutex makes the (`Send` but not `Sync`) module
    /// shareable without any unsafe assertion.
    module: Mutex<Option<JITModule>>,
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

impl Drop for JitFunction {
    fn drop(&mut self) {
        let module = match self.module.get_mut() {
            Ok(slot) => slot.take(),
            Err(poisoned) => poisoned.into_inner().take(),
        };
        if let Some(module) = module {
            // SAFETY: `code` points into this module and is only reachable through
            // `&self`; being dropped, nothing can be running it or call it again.
            unsafe { module.free_memory() };
        }
    }
}

/// Compiles a program to native code, or says why it cannot.
pub(crate) fn compile(program: &Program) -> Result<JitFunction, String> {
    // A failure inside the code generator must not take the caller down: the
    // interpreter can always run the program instead.
    catch_unwind(AssertUnwindSafe(|| compile_inner(program)))
        .unwrap_or_else(|_| Err("the code generator panicked".to_string()))
}

fn compile_inner(program: &Program) -> Result<JitFunction, String> {
    let mut flags = settings::builder();
    for (name, value) in [
        // The program arrives value-numbered, folded and free of dead code, so the
        // optimiser's e-graph pass finds nothing to do; skipping it halves compile time
        // for large programs and measured no slower to run.
        ("opt_level", "none"),
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
    let mut module = JITModule::new(JITBuilder::with_isa(isa, default_libcall_names()));
    let pointer = module.target_config().pointer_type();
    let call_conv = module.isa().default_call_conv();

    let mut signature = module.make_signature();
    signature.params.push(AbiParam::new(pointer));
    signature.params.push(AbiParam::new(pointer));
    let mut ctx = module.make_context();
    ctx.func.signature = signature.clone();

    let mut builder_ctx = FunctionBuilderContext::new();
    let mut b = FunctionBuilder::new(&mut ctx.func, &mut builder_ctx);
    let block = b.create_block();
    b.append_block_params_for_function_params(block);
    b.switch_to_block(block);
    b.seal_block(block);
    let (inputs, outputs) = (b.block_params(block)[0], b.block_params(block)[1]);
    // The slices are aligned and their lengths checked before the call.
    let trusted = MemFlagsData::trusted();

    let float_signature = |params: usize| {
        let mut sig = Signature::new(call_conv);
        sig.params
            .extend((0..params).map(|_| AbiParam::new(types::F64)));
        sig.returns.push(AbiParam::new(types::F64));
        sig
    };
    let unary_sig = b.import_signature(float_signature(1));
    let binary_sig = b.import_signature(float_signature(2));

    let offset = |index: u32| {
        i32::try_from(u64::from(index) * 8).map_err(|_| "slot offset too large".to_string())
    };
    let mut regs: Vec<Option<Value>> = vec![None; program.registers()];
    let get = |regs: &[Option<Value>], r: u32| regs[r as usize].ok_or("read before write");
    for instr in program.instrs() {
        let (dst, value) = match *instr {
            Instr::Load { dst, input } => {
                let at = offset(input)?;
                (dst, b.ins().load(types::F64, trusted, inputs, at))
            }
            Instr::Const { dst, value } => {
                (dst, b.ins().f64const(Ieee64::with_bits(value.to_bits())))
            }
            Instr::Unary { op, dst, a } => {
                let x = get(&regs, a)?;
                let value = match op {
                    UnaryOp::Neg => b.ins().fneg(x),
                    UnaryOp::Abs => b.ins().fabs(x),
                    UnaryOp::Sqrt => b.ins().sqrt(x),
                    other => {
                        let callee = entry::unary(other);
                        let address = b.ins().iconst(pointer, callee as usize as i64);
                        let call = b.ins().call_indirect(unary_sig, address, &[x]);
                        b.inst_results(call)[0]
                    }
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
                    other => {
                        let callee = entry::binary(other);
                        let address = b.ins().iconst(pointer, callee as usize as i64);
                        let call = b.ins().call_indirect(binary_sig, address, &[x, y]);
                        b.inst_results(call)[0]
                    }
                };
                (dst, value)
            }
            Instr::Store { src, output } => {
                let value = get(&regs, src)?;
                let at = offset(output)?;
                b.ins().store(trusted, value, outputs, at);
                continue;
            }
        };
        regs[dst as usize] = Some(value);
    }
    b.ins().return_(&[]);
    b.finalize(module.target_config());

    let id = module
        .declare_anonymous_function(&signature)
        .map_err(|e| e.to_string())?;
    module
        .define_function(id, &mut ctx)
        .map_err(|e| e.to_string())?;
    module.clear_context(&mut ctx);
    module.finalize_definitions().map_err(|e| e.to_string())?;
    let address = module.get_finalized_function(id);
    // SAFETY: the function was just defined with the signature (pointer, pointer) -> ()
    // in the platform's default calling convention, which is the C one.
    let code = unsafe { std::mem::transmute::<*const u8, CompiledFn>(address) };
    Ok(JitFunction {
        code,
        module: Mutex::new(Some(module)),
    })
}
