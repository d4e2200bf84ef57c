//! The Butcher tableau of an explicit Runge–Kutta method and its step, written once
//! ([`Tableau::step`]) for every back end: the one-run stepper and its tangent map, the
//! momentum sub-flow of modin_rks, and the compiled steps, each giving the walk its own numbers
//! and vector field through [`Stages`]. The methods' tableaux themselves are in
//! `methods::runge_kutta`.

/// The step of [`Tableau::step`], its loops over the stages written by `$each` (`unroll` or
/// `rolled`).
macro_rules! walk {
    ($tableau:ident, $h:ident, $s:ident, $each:ident) => {{
        $each!($tableau.stages(), i => {
            $s.start_stage();
            for (j, &a) in $tableau.a[i].iter().enumerate() {
                if a != 0.0 {
                    $s.add_slope($h * a, j);
                }
            }
            $s.evaluate(i)?;
        });
        $each!($tableau.stages(), i => {
            $s.advance($h * $tableau.b[i], i);
        });
        Ok(())
    }};
}

/// `for $k in 0..$n`: the loop that `unroll!` writes out, kept as a loop.
macro_rules! rolled {
    ($n:expr, $k:ident => $body:block) => {
        for $k in 0..$n $body
    };
}

/// What one back end gives [`Tableau::step`]: its state y, the slopes kᵢ of the stages and the
/// argument Y of the stage being evaluated, held in its own numbers, and the four updates the
/// step is made of. Each sum is accumulated one term at a time as a·x + y (a product rounded,
/// then a sum), in the order the walk calls them, so every back end rounds alike.
pub trait Stages {
    /// Why a stage's slope could not be had.
    type Error;
    /// The stage's argument starts as the state: Y ← y.
    fn start_stage(&mut self);
    /// Y ← c·kⱼ + Y, with c = h·aᵢⱼ (the product computed in f64 by the walk).
    fn add_slope(&mut self, c: f64, j: usize);
    /// kᵢ ← f(Y).
    fn evaluate(&mut self, i: usize) -> Result<(), Self::Error>;
    /// y ← c·kᵢ + y, with c = h·bᵢ.
    fn advance(&mut self, c: f64, i: usize);
}

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
    #[inline(always)]
    pub fn stages(&self) -> usize {
        self.b.len()
    }

    /// One step of size h: Yᵢ = y + Σ_{j<i} (h aᵢⱼ) kⱼ in order of j, the zero coefficients
    /// skipped, and kᵢ = f(Yᵢ), for each stage in order; then y ← y + Σᵢ (h bᵢ) kᵢ in order of i.
    /// Unrolled over up to six stages: for a tableau known when the program is compiled, every
    /// coefficient then folds.
    #[inline(always)]
    pub fn step<S: Stages>(&self, h: f64, s: &mut S) -> Result<(), S::Error> {
        walk!(self, h, s, unroll)
    }

    /// [`Self::step`] with its loops over the stages kept as loops: where unrolled copies (one
    /// per stage count, for a tableau chosen at run time) would only make the caller's code
    /// larger — modin_rks's momentum sub-flow, the tangent map, the code a compiled stretch
    /// writes. (In the dev profile, unrolling modin_rks's inner heun made P2's step 45 % slower.)
    #[inline(always)]
    pub fn step_rolled<S: Stages>(&self, h: f64, s: &mut S) -> Result<(), S::Error> {
        walk!(self, h, s, rolled)
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
