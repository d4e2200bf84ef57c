//! An explicit Runge–Kutta method's steps as the stretch writes them: each stage's argument and
//! field, the update, the count of force evaluations, the check of the state.

use cranelift_codegen::ir::{InstBuilder, Value};

use super::Stretch;
use crate::flows::Tableau;

impl Stretch<'_, '_> {
    /// Runge–Kutta steps: each one's stages and update, the count, the check of the state.
    pub(super) fn runge_kutta(&mut self, t: &Tableau, h: f64) -> Result<(), String> {
        let n = self.parts.n;
        let step = self.b.create_block();
        self.b.ins().jump(step, &[]);
        self.b.switch_to_block(step);
        let (zq, zp) = (self.values(&self.q.clone()), self.values(&self.p.clone()));
        let (mut kq, mut kp): (Vec<Vec<Value>>, Vec<Vec<Value>>) = (Vec::new(), Vec::new());
        for i in 0..t.stages() {
            let (mut sq, mut sp) = (zq.clone(), zp.clone());
            for (j, &a) in t.a[i].iter().enumerate() {
                if a != 0.0 {
                    let ha = self.constant(h * a);
                    for c in 0..n {
                        sq[c] = self.axpy(ha, kq[j][c], sq[c]);
                    }
                    for c in 0..n {
                        sp[c] = self.axpy(ha, kp[j][c], sp[c]);
                    }
                }
            }
            let dq = self.velocity_of(&sp);
            let gradient = self.program_of(self.parts.gradient, &sq, n)?;
            let w = match self.parts.projector {
                Some(matrix) => self.projected_of(matrix, &sq, &sp)?,
                None => sp,
            };
            let r = self.constant(self.parts.rate);
            let dp = gradient
                .into_iter()
                .zip(w)
                .map(|(g, w)| {
                    let force = self.b.ins().fmul(w, r);
                    let sum = self.b.ins().fadd(g, force);
                    self.b.ins().fneg(sum)
                })
                .collect();
            kq.push(dq);
            kp.push(dp);
        }
        let (mut q, mut p) = (zq, zp);
        for i in 0..t.stages() {
            let hb = self.constant(h * t.b[i]);
            for c in 0..n {
                q[c] = self.axpy(hb, kq[i][c], q[c]);
            }
            for c in 0..n {
                p[c] = self.axpy(hb, kp[i][c], p[c]);
            }
        }
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
