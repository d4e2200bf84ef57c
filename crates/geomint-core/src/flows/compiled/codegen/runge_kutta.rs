//! An explicit Runge–Kutta method's steps as the stretch writes them: the tableau's walk
//! ([`Tableau::step`], the stepper's own) over values of the function being built, then the
//! count of force evaluations and the check of the state.

use cranelift_codegen::ir::{InstBuilder, Value};

use super::Stretch;
use crate::flows::tableau::Stages;
use crate::flows::Tableau;

impl Stretch<'_, '_> {
    /// Runge–Kutta steps: each one's stages and update, the count, the check of the state.
    pub(super) fn runge_kutta(&mut self, t: &Tableau, h: f64) -> Result<(), String> {
        let n = self.parts.n;
        let step = self.b.create_block();
        self.b.ins().jump(step, &[]);
        self.b.switch_to_block(step);
        let (q, p) = (self.values(&self.q.clone()), self.values(&self.p.clone()));
        let mut stages = CompiledStages {
            stretch: self,
            q,
            p,
            stage_q: Vec::new(),
            stage_p: Vec::new(),
            kq: Vec::new(),
            kp: Vec::new(),
        };
        t.step_rolled(h, &mut stages)?;
        let CompiledStages { q, p, .. } = stages;
        for c in 0..n {
            self.b.def_var(self.q[c], q[c]);
            self.b.def_var(self.p[c], p[c]);
        }
        let evaluations = self.b.use_var(self.evaluations);
        let evaluations = self.b.ins().iadd_imm_s(evaluations, t.stages() as i64);
        self.b.def_var(self.evaluations, evaluations);
        // Stop after this step if it left the state not finite, or after the n-th.
        self.end_of_step(step, true)
    }

    /// a·x + y, as `axpy(a, x, 1)` computes each component.
    fn axpy(&mut self, a: Value, x: Value, y: Value) -> Value {
        let ax = self.b.ins().fmul(a, x);
        self.b.ins().fadd(ax, y)
    }
}

/// A step's stages as values of the function being built: the state (q, p) at the step's start
/// and as it is advanced, the stage's argument, and each stage's slopes.
struct CompiledStages<'s, 'a, 'b> {
    stretch: &'s mut Stretch<'a, 'b>,
    q: Vec<Value>,
    p: Vec<Value>,
    stage_q: Vec<Value>,
    stage_p: Vec<Value>,
    kq: Vec<Vec<Value>>,
    kp: Vec<Vec<Value>>,
}

impl Stages for CompiledStages<'_, '_, '_> {
    type Error = String;

    fn start_stage(&mut self) {
        self.stage_q.clone_from(&self.q);
        self.stage_p.clone_from(&self.p);
    }

    fn add_slope(&mut self, c: f64, j: usize) {
        let c = self.stretch.constant(c);
        for (x, &k) in self.stage_q.iter_mut().zip(&self.kq[j]) {
            *x = self.stretch.axpy(c, k, *x);
        }
        for (x, &k) in self.stage_p.iter_mut().zip(&self.kp[j]) {
            *x = self.stretch.axpy(c, k, *x);
        }
    }

    /// The field (M⁻¹p, −(∇V + r P(q)p)) at the stage's argument, as the system's
    /// `vector_field` computes it.
    fn evaluate(&mut self, i: usize) -> Result<(), String> {
        debug_assert_eq!(i, self.kq.len(), "stages are evaluated in order");
        let s = &mut *self.stretch;
        let parts = s.parts;
        let dq = s.velocity_of(&self.stage_p);
        let gradient = s.program_of(parts.gradient, &self.stage_q, parts.n)?;
        let w = match parts.projector {
            Some(matrix) => s.projected_of(matrix, &self.stage_q, &self.stage_p)?,
            None => self.stage_p.clone(),
        };
        let r = s.constant(parts.rate);
        let dp = (gradient.into_iter().zip(w))
            .map(|(g, w)| {
                let force = s.b.ins().fmul(w, r);
                let sum = s.b.ins().fadd(g, force);
                s.b.ins().fneg(sum)
            })
            .collect();
        self.kq.push(dq);
        self.kp.push(dp);
        Ok(())
    }

    fn advance(&mut self, c: f64, i: usize) {
        let c = self.stretch.constant(c);
        for (x, &k) in self.q.iter_mut().zip(&self.kq[i]) {
            *x = self.stretch.axpy(c, k, *x);
        }
        for (x, &k) in self.p.iter_mut().zip(&self.kp[i]) {
            *x = self.stretch.axpy(c, k, *x);
        }
    }
}
