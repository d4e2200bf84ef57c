//! The Butcher tableau of an explicit Runge–Kutta method: the data every back end reads (the
//! one-run stepper, the compiled steps); the methods' tableaux themselves are in
//! `methods::runge_kutta`.

/// An explicit Butcher tableau: stage i uses `a[i][j]` for j < i.
#[derive(Debug)]
pub struct Tableau {
    /// Lower-triangular coefficients, row i of length i.
    pub a: &'static [&'static [f64]],
    /// Weights.
    pub b: &'static [f64],
    /// Nodes (c_i = Σ_j a_ij).
    pub c: &'static [f64],
    /// Classical order.
    pub order: u32,
}

impl Tableau {
    /// Number of stages.
    pub fn stages(&self) -> usize {
        self.b.len()
    }

    /// The stability function R(x) = 1 + x bᵀ(I − xA)⁻¹𝟙 and the forcing weight S(x) of one step
    /// of y' = x y − 1 (from y0 = 0): returns (R(x), −y1). Used for tangent maps of linear flows.
    pub fn linear_response(&self, x: f64) -> (f64, f64) {
        let run = |y0: f64, forcing: f64| {
            let mut k = [0.0f64; 8];
            for i in 0..self.stages() {
                let yi = y0 + self.a[i].iter().zip(&k).map(|(a, k)| a * k).sum::<f64>();
                k[i] = x * yi - forcing;
            }
            y0 + self.b.iter().zip(&k).map(|(b, k)| b * k).sum::<f64>()
        };
        (run(1.0, 0.0), -run(0.0, 1.0))
    }
}

impl PartialEq for Tableau {
    fn eq(&self, other: &Self) -> bool {
        std::ptr::eq(self, other)
    }
}
impl Eq for Tableau {}
