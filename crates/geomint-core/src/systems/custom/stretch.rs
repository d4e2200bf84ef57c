//! A typed-in system's stretches of a splitting, compiled with Cranelift: the composer's fused
//! stretch (see `methods::splitting::compiled`) as one loop in which the state lives in
//! registers and the potential's gradient program is written into every kick that evaluates it,
//! where the generic path calls the compiled gradient through a pointer at each.
//!
//! Taken: autonomous separable systems (constant mass in any of its forms) without damping or
//! with conformal damping, and sequences of drifts, kicks and damping flows (modin_3s, csv1,
//! position Verlet, their compositions, …). Each flow is the composer's arithmetic:
//! - drift: v = M⁻¹p as `InverseMass::apply` computes it, then q ← τv + q;
//! - kick: ∇V(q) evaluated unless the cache holds it, then p ← (−τ)g + p;
//! - damping: p ← (−c)p + p with c = 1 − e^{−rτ} (nothing when c = 0).
//!
//! After each step the state's components are summed as the one-run path sums them (positions,
//! then momenta, from 0) and the stretch reports a sum that is not finite.

use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::immediates::Ieee64;
use cranelift_codegen::ir::{types, AbiParam, InstBuilder, MemFlagsData, Value};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext, Variable};
use cranelift_module::Module;

use super::mass::InverseMass;
use crate::expr::jit::{self, Emitter, OwnedModule};
use crate::expr::program::Program;
use crate::methods::splitting::compiled::{CompiledStretch, StretchFn, StretchPlan};
use crate::methods::splitting::SubFlow;

/// The parts of a system a stretch needs.
pub(super) struct Parts<'a> {
    /// Degrees of freedom.
    pub n: usize,
    /// ∇V as a program of q.
    pub gradient: &'a Program,
    /// M⁻¹.
    pub inverse_mass: &'a InverseMass,
}

/// Compiles `plan` for the system of `parts`, or says why not (a flow it does not take).
pub(super) fn compile(plan: &StretchPlan, parts: &Parts) -> Result<CompiledStretch, String> {
    let taken = plan
        .flows
        .iter()
        .all(|(flow, _)| matches!(flow, SubFlow::Drift | SubFlow::Kick | SubFlow::Damp));
    if !taken || plan.flows.len() < 2 || plan.coefficients.len() != plan.flows.len() {
        return Err("a flow the compiled stretch does not take".into());
    }
    let module = jit::module()?;
    let pointer = module.target_config().pointer_type();
    let mut ctx = module.make_context();
    for _ in 0..4 {
        ctx.func.signature.params.push(AbiParam::new(pointer));
    }
    ctx.func.signature.params.push(AbiParam::new(types::I64));
    ctx.func.signature.returns.push(AbiParam::new(types::I64));
    let mut builder_ctx = FunctionBuilderContext::new();
    let mut b = FunctionBuilder::new(&mut ctx.func, &mut builder_ctx);
    let emitter = Emitter::new(&module, &mut b);
    let mut s = Stretch::new(&mut b, parts, emitter)?;
    s.body(plan)?;
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
            parts.n,
            OwnedModule::new(module),
        ))
    }
}

/// The function being built: its arguments and the variables that hold the state.
struct Stretch<'a, 'b> {
    b: &'a mut FunctionBuilder<'b>,
    parts: &'a Parts<'a>,
    emitter: Emitter,
    args: [Value; 5],
    q: Vec<Variable>,
    p: Vec<Variable>,
    g: Vec<Variable>,
    /// Whether g holds ∇V(q), as 0 or 1.
    valid: Variable,
    evaluations: Variable,
    /// Steps done, counting the one under way.
    done: Variable,
}

/// The arrays are aligned and of the compiled length: the caller checks both.
fn trusted() -> MemFlagsData {
    MemFlagsData::trusted()
}

impl<'a, 'b> Stretch<'a, 'b> {
    /// The entry block: the state, the force cache and the counters loaded into variables.
    fn new(
        b: &'a mut FunctionBuilder<'b>,
        parts: &'a Parts<'a>,
        emitter: Emitter,
    ) -> Result<Self, String> {
        let entry = b.create_block();
        b.append_block_params_for_function_params(entry);
        b.switch_to_block(entry);
        let params = b.block_params(entry);
        let args = [params[0], params[1], params[2], params[3], params[4]];
        let vars = |b: &mut FunctionBuilder, array: Value| -> Result<Vec<Variable>, String> {
            (0..parts.n)
                .map(|i| {
                    let var = b.declare_var(types::F64);
                    let value = b
                        .ins()
                        .load(types::F64, trusted(), array, jit::offset(i as u32)?);
                    b.def_var(var, value);
                    Ok(var)
                })
                .collect()
        };
        let q = vars(b, args[0])?;
        let p = vars(b, args[1])?;
        let g = vars(b, args[2])?;
        let counter = |b: &mut FunctionBuilder, slot: i32| {
            let var = b.declare_var(types::I64);
            let value = b.ins().load(types::I64, trusted(), args[3], slot * 8);
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
            valid,
            evaluations,
            done,
        })
    }

    /// The stretch: the first flow, then per step the middle flows and the seam (the whole last
    /// flow at the end), the check of the state, the count of steps.
    fn body(&mut self, plan: &StretchPlan) -> Result<(), String> {
        let m = plan.flows.len();
        let time = |k: usize| plan.flows[k].1 * plan.h;
        self.flow(plan.flows[0].0, time(0), plan.coefficients[0].0)?;
        let step = self.b.create_block();
        self.b.ins().jump(step, &[]);
        self.b.switch_to_block(step);
        for k in 1..m - 1 {
            self.flow(plan.flows[k].0, time(k), plan.coefficients[k].0)?;
        }
        // The seam within the stretch, the last flow alone at its end.
        let (seam_tau, (seam_c, _)) = plan.seam;
        let (last_tau, (last_c, _)) = (time(m - 1), plan.coefficients[m - 1]);
        let n = self.args[4];
        let done = self.b.use_var(self.done);
        let inside = self.b.ins().icmp(IntCC::UnsignedLessThan, done, n);
        let kind = plan.flows[m - 1].0;
        let tau = self.choose(inside, seam_tau, last_tau);
        let c = self.choose(inside, seam_c, last_c);
        // A damping flow with c = 0 (no damping) does nothing, as in the composer.
        if !(kind == SubFlow::Damp && seam_c == 0.0 && last_c == 0.0) {
            self.flow_with(kind, tau, c)?;
        }
        let finite = self.finite();
        let (more, ended, diverged) = (
            self.b.create_block(),
            self.b.create_block(),
            self.b.create_block(),
        );
        let next = self.b.create_block();
        self.b.ins().brif(finite, more, &[], diverged, &[]);
        self.b.switch_to_block(more);
        let done = self.b.use_var(self.done);
        let last = self.b.ins().icmp(IntCC::Equal, done, n);
        self.b.ins().brif(last, ended, &[], next, &[]);
        self.b.switch_to_block(next);
        let done = self.b.use_var(self.done);
        let done = self.b.ins().iadd_imm_s(done, 1);
        self.b.def_var(self.done, done);
        self.b.ins().jump(step, &[]);
        self.b.switch_to_block(ended);
        self.store()?;
        let yes = self.b.ins().iconst(types::I64, 1);
        self.b.ins().return_(&[yes]);
        self.b.switch_to_block(diverged);
        let no = self.b.ins().iconst(types::I64, 0);
        self.b.ins().return_(&[no]);
        Ok(())
    }

    fn constant(&mut self, x: f64) -> Value {
        self.b.ins().f64const(Ieee64::with_bits(x.to_bits()))
    }

    /// `a` where `cond` holds, else `b` (a constant when they are equal).
    fn choose(&mut self, cond: Value, a: f64, b: f64) -> Value {
        if a.to_bits() == b.to_bits() {
            return self.constant(a);
        }
        let (a, b) = (self.constant(a), self.constant(b));
        self.b.ins().select(cond, a, b)
    }

    /// A flow over the constant time `tau` with damping coefficient `c`.
    fn flow(&mut self, kind: SubFlow, tau: f64, c: f64) -> Result<(), String> {
        if kind == SubFlow::Damp && c == 0.0 {
            return Ok(());
        }
        let (tau, c) = (self.constant(tau), self.constant(c));
        self.flow_with(kind, tau, c)
    }

    fn flow_with(&mut self, kind: SubFlow, tau: Value, c: Value) -> Result<(), String> {
        let n = self.parts.n;
        match kind {
            SubFlow::Drift => {
                let v = self.velocity();
                for i in 0..n {
                    let q = self.b.use_var(self.q[i]);
                    let step = self.b.ins().fmul(tau, v[i]);
                    let q = self.b.ins().fadd(step, q);
                    self.b.def_var(self.q[i], q);
                }
                let zero = self.b.ins().iconst(types::I64, 0);
                self.b.def_var(self.valid, zero);
            }
            SubFlow::Kick => {
                self.ensure_gradient()?;
                let minus_tau = self.b.ins().fneg(tau);
                for i in 0..n {
                    let (p, g) = (self.b.use_var(self.p[i]), self.b.use_var(self.g[i]));
                    let kick = self.b.ins().fmul(minus_tau, g);
                    let p = self.b.ins().fadd(kick, p);
                    self.b.def_var(self.p[i], p);
                }
            }
            SubFlow::Damp => {
                let minus_c = self.b.ins().fneg(c);
                for i in 0..n {
                    let p = self.b.use_var(self.p[i]);
                    let decay = self.b.ins().fmul(minus_c, p);
                    let p = self.b.ins().fadd(decay, p);
                    self.b.def_var(self.p[i], p);
                }
            }
            _ => return Err("a flow the compiled stretch does not take".into()),
        }
        Ok(())
    }

    /// M⁻¹p, as `InverseMass::apply` computes it.
    fn velocity(&mut self) -> Vec<Value> {
        let n = self.parts.n;
        let p: Vec<Value> = (0..n).map(|i| self.b.use_var(self.p[i])).collect();
        match self.parts.inverse_mass {
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
        }
    }

    /// ∇V(q) into g unless g holds it: the gradient's program written here, and counted.
    fn ensure_gradient(&mut self) -> Result<(), String> {
        let (evaluate, after) = (self.b.create_block(), self.b.create_block());
        let valid = self.b.use_var(self.valid);
        self.b.ins().brif(valid, after, &[], evaluate, &[]);
        self.b.switch_to_block(evaluate);
        let (q, g) = (self.q.clone(), self.g.clone());
        self.emitter.emit(
            self.b,
            self.parts.gradient,
            &mut |b, input| {
                let var = q.get(input as usize).ok_or("an input past q")?;
                Ok(b.use_var(*var))
            },
            &mut |b, output, value| {
                let var = g.get(output as usize).ok_or("an output past ∇V")?;
                b.def_var(*var, value);
                Ok(())
            },
        )?;
        let evaluations = self.b.use_var(self.evaluations);
        let evaluations = self.b.ins().iadd_imm_s(evaluations, 1);
        self.b.def_var(self.evaluations, evaluations);
        let one = self.b.ins().iconst(types::I64, 1);
        self.b.def_var(self.valid, one);
        self.b.ins().jump(after, &[]);
        self.b.switch_to_block(after);
        Ok(())
    }

    /// Whether Σq + Σp (each summed from 0, in order) is finite.
    fn finite(&mut self) -> Value {
        let mut total = [self.q.clone(), self.p.clone()].map(|vars| {
            let mut sum = self.constant(0.0);
            for var in vars {
                let x = self.b.use_var(var);
                sum = self.b.ins().fadd(sum, x);
            }
            sum
        });
        let sum = self.b.ins().fadd(total[0], total[1]);
        total[0] = self.b.ins().fabs(sum);
        let max = self.constant(f64::MAX);
        self.b.ins().fcmp(FloatCC::LessThanOrEqual, total[0], max)
    }

    /// The state, the force cache and the counters back into the caller's arrays.
    fn store(&mut self) -> Result<(), String> {
        for (vars, array) in [
            (self.q.clone(), self.args[0]),
            (self.p.clone(), self.args[1]),
            (self.g.clone(), self.args[2]),
        ] {
            for (i, var) in vars.into_iter().enumerate() {
                let value = self.b.use_var(var);
                self.b
                    .ins()
                    .store(trusted(), value, array, jit::offset(i as u32)?);
            }
        }
        for (slot, var) in [(0, self.valid), (1, self.evaluations)] {
            let value = self.b.use_var(var);
            self.b.ins().store(trusted(), value, self.args[3], slot * 8);
        }
        Ok(())
    }
}
