//! A splitting's flows as the stretch writes them: the loop of steps with its fused seam, each
//! flow over every lane, the force cache, and the lanes' mask of states that left.

use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::immediates::Ieee64;
use cranelift_codegen::ir::{types, Block, InstBuilder, Value};

use super::{kind, Stretch};
use crate::flows;
use crate::flows::compiled::StretchPlan;
use crate::flows::emit::{self, Jit};
use crate::flows::SubFlow;

impl Stretch<'_, '_> {
    /// The splitting's stretch: the first flow, then per step the middle flows and the seam
    /// (the whole last flow at the end), the check of the state, the count of steps. Returns n,
    /// or 0 when a step left the state not finite.
    pub(super) fn splitting(&mut self, plan: &StretchPlan) -> Result<(), String> {
        let m = plan.flows.len();
        let time = |k: usize| plan.flows[k].1 * plan.h;
        let kinds = plan
            .flows
            .iter()
            .map(|&(flow, _)| kind(flow, self.parts).ok_or("a flow the stretch does not take"))
            .collect::<Result<Vec<_>, _>>()?;
        let Some((seam_tau, (seam_c, _))) = plan.seam else {
            // Whole steps, none fused with the next.
            let step = self.b.create_block();
            self.b.ins().jump(step, &[]);
            self.b.switch_to_block(step);
            self.known_valid = None;
            for k in 0..m {
                self.flow(kinds[k], time(k), plan.coefficients[k].0)?;
            }
            return self.end_of_splitting_step(step);
        };
        self.flow(kinds[0], time(0), plan.coefficients[0].0)?;
        let step = self.b.create_block();
        self.b.ins().jump(step, &[]);
        self.b.switch_to_block(step);
        self.known_valid = None;
        for k in 1..m - 1 {
            self.flow(kinds[k], time(k), plan.coefficients[k].0)?;
        }
        // The seam within the stretch, the last flow alone at its end.
        let (last_tau, (last_c, _)) = (time(m - 1), plan.coefficients[m - 1]);
        let n = self.args[4];
        let done = self.b.use_var(self.done);
        let inside = self.b.ins().icmp(IntCC::UnsignedLessThan, done, n);
        let kind = kinds[m - 1];
        let tau = self.choose(inside, seam_tau, last_tau);
        let c = self.choose(inside, seam_c, last_c);
        // A damping flow with c = 0 (no damping) does nothing, as in the composer.
        if !(kind == SubFlow::Damp && seam_c == 0.0 && last_c == 0.0) {
            self.flow_with(kind, tau, c)?;
        }
        self.end_of_splitting_step(step)
    }

    /// The end of a splitting's step: a single run's stretch stops at a state that is not
    /// finite (to be run again step by step); lanes go on, each marking the step in `left`.
    fn end_of_splitting_step(&mut self, step: Block) -> Result<(), String> {
        if self.layout.lanes == 1 {
            return self.end_of_step(step, false);
        }
        let mut left = self.b.use_var(self.left);
        let width = self.layout.width;
        for k in 0..self.lanes.len() {
            self.lane(k);
            let not_finite = self.not_finite();
            let not_finite = if width == 1 {
                self.b.ins().uextend(types::I64, not_finite)
            } else {
                // The vector comparison's lanes are all ones where not finite: their sign bits.
                self.b.ins().vhigh_bits(types::I64, not_finite)
            };
            let flags = self.b.ins().ishl_imm_s(not_finite, (k * width) as i64);
            left = self.b.ins().bor(left, flags);
        }
        self.b.def_var(self.left, left);
        self.next_step(step);
        self.store()?;
        let left = self.b.use_var(self.left);
        self.b.ins().return_(&[left]);
        Ok(())
    }

    /// `a` where `cond` holds, else `b`, in every lane (a constant when they are equal).
    fn choose(&mut self, cond: Value, a: f64, b: f64) -> Value {
        if a.to_bits() == b.to_bits() {
            return self.constant(a);
        }
        let a = self.b.ins().f64const(Ieee64::with_bits(a.to_bits()));
        let b = self.b.ins().f64const(Ieee64::with_bits(b.to_bits()));
        let chosen = self.b.ins().select(cond, a, b);
        self.emitter.broadcast(self.b, chosen)
    }

    /// A flow over the constant time `tau` with damping coefficient `c`.
    fn flow(&mut self, kind: SubFlow, tau: f64, c: f64) -> Result<(), String> {
        if kind == SubFlow::Damp && c == 0.0 {
            return Ok(());
        }
        let (tau, c) = (self.constant(tau), self.constant(c));
        self.flow_with(kind, tau, c)
    }

    /// A flow of every lane, one value after the other.
    fn flow_with(&mut self, kind: SubFlow, tau: Value, c: Value) -> Result<(), String> {
        if kind == SubFlow::Kick {
            self.ensure_gradient()?;
        }
        for l in 0..self.lanes.len() {
            self.lane(l);
            self.lane_flow(kind, tau, c)?;
        }
        if kind == SubFlow::Drift {
            let zero = self.b.ins().iconst(types::I64, 0);
            self.b.def_var(self.valid, zero);
            self.known_valid = Some(false);
        }
        Ok(())
    }

    /// Makes value `k`'s lanes the ones `q`, `p` and `g` name.
    fn lane(&mut self, k: usize) {
        [self.q, self.p, self.g] = self.lanes[k].clone();
    }

    /// The flow's update of the current lane (a kick's force already evaluated): the kernel's
    /// flow (`flows::drift`, `kick`, `decay`) run over the lane's values, which writes its code.
    fn lane_flow(&mut self, kind: SubFlow, tau: Value, c: Value) -> Result<(), String> {
        let (q, p, g) = (
            self.values(&self.q.clone()),
            self.values(&self.p.clone()),
            self.values(&self.g.clone()),
        );
        let (target, updated) = match kind {
            SubFlow::Drift => {
                let v = self.velocity();
                let q = emit::write(self.b, |w| {
                    let mut q = emit::values(&q, w);
                    flows::drift(&mut q, &emit::values(&v, w), Jit::new(tau, w));
                    emit::of(&q)
                });
                (self.q.clone(), q)
            }
            SubFlow::Kick => {
                let p = emit::write(self.b, |w| {
                    let mut p = emit::values(&p, w);
                    flows::kick(&mut p, &emit::values(&g, w), Jit::new(tau, w));
                    emit::of(&p)
                });
                (self.p.clone(), p)
            }
            SubFlow::Damp => {
                let projected = match self.parts.projector {
                    Some(matrix) => self.projected(matrix)?,
                    None => p.clone(),
                };
                let p = emit::write(self.b, |w| {
                    let mut p = emit::values(&p, w);
                    flows::decay(&mut p, &emit::values(&projected, w), Jit::new(c, w));
                    emit::of(&p)
                });
                (self.p.clone(), p)
            }
            _ => return Err("a flow the compiled stretch does not take".into()),
        };
        for (var, value) in target.into_iter().zip(updated) {
            self.b.def_var(var, value);
        }
        Ok(())
    }

    /// ∇V(q) into g unless g holds it: the gradient's program written here, and counted.
    fn ensure_gradient(&mut self) -> Result<(), String> {
        let after = match self.known_valid {
            Some(true) => return Ok(()),
            Some(false) => None,
            None => {
                let (evaluate, after) = (self.b.create_block(), self.b.create_block());
                let valid = self.b.use_var(self.valid);
                self.b.ins().brif(valid, after, &[], evaluate, &[]);
                self.b.switch_to_block(evaluate);
                Some(after)
            }
        };
        for l in 0..self.lanes.len() {
            self.lane(l);
            let q = self.values(&self.q.clone());
            let g = self.program_of(self.parts.gradient, &q, self.parts.n)?;
            for (i, value) in g.into_iter().enumerate() {
                self.b.def_var(self.g[i], value);
            }
        }
        let evaluations = self.b.use_var(self.evaluations);
        let evaluations = self.b.ins().iadd_imm_s(evaluations, 1);
        self.b.def_var(self.evaluations, evaluations);
        let one = self.b.ins().iconst(types::I64, 1);
        self.b.def_var(self.valid, one);
        if let Some(after) = after {
            self.b.ins().jump(after, &[]);
            self.b.switch_to_block(after);
        }
        self.known_valid = Some(true);
        Ok(())
    }
}
