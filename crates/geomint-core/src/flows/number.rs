//! The numbers a kernel computes with: one `f64` (a single run), a [`Pack`] of [`LANES`] `f64`s
//! (runs side by side in SIMD lanes), or a value of compiled code (`emit::Jit`, which writes each
//! operation into the function being built). The flows are written once over [`Real`], so every
//! back end does the same operations in the same order, and IEEE addition, multiplication,
//! division and square root round the same in each, so they give the same bits.

use std::ops::{Add, Div, Index, IndexMut, Mul, Neg, Sub};

/// Runs side by side: four registers of four with AVX2, two of eight with AVX-512. One register
/// of four would leave the CPU waiting on each operation's latency along the step's chain
/// (drift, force, kick); with several independent registers per operation it overlaps them.
/// On the Hénon–Heiles MEGNO map sixteen lanes (AVX-512) with the one-vector sums in lanes took
/// 8.2 ns per cell-step against 16.2 ns for four (chaos-map measurements in the book).
pub const LANES: usize = 16;

/// One value per lane.
pub type Lane = [f64; LANES];

/// What a kernel computes with: the arithmetic of IEEE doubles, one operation at a time. No
/// fused multiply-add: a·b + c is a product rounded, then a sum rounded, in every back end
/// (rustc never contracts one, and neither does Cranelift).
pub trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
}

impl<T> Real for T where
    T: Copy
        + Add<Output = T>
        + Sub<Output = T>
        + Mul<Output = T>
        + Div<Output = T>
        + Neg<Output = T>
{
}

/// [`LANES`] doubles operated on lane by lane: the loops over the lanes are the form the
/// compiler turns into SIMD instructions (of the width the calling function is built for).
#[repr(transparent)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pack(pub Lane);

impl Pack {
    /// `x` in every lane.
    #[inline(always)]
    pub const fn splat(x: f64) -> Self {
        Pack([x; LANES])
    }

    /// The lanes of `x` as packs, in place (a pack is its lane array).
    #[inline(always)]
    pub fn of<const N: usize>(x: &[Lane; N]) -> &[Pack; N] {
        // SAFETY: `Pack` is `repr(transparent)` over `Lane`, so `[Lane; N]` and `[Pack; N]` have
        // one layout, and the borrow is carried over.
        unsafe { &*(x as *const [Lane; N] as *const [Pack; N]) }
    }

    /// [`Pack::of`], mutably.
    #[inline(always)]
    pub fn of_mut<const N: usize>(x: &mut [Lane; N]) -> &mut [Pack; N] {
        // SAFETY: as in `of`.
        unsafe { &mut *(x as *mut [Lane; N] as *mut [Pack; N]) }
    }
}

impl Index<usize> for Pack {
    type Output = f64;
    #[inline(always)]
    fn index(&self, l: usize) -> &f64 {
        &self.0[l]
    }
}

impl IndexMut<usize> for Pack {
    #[inline(always)]
    fn index_mut(&mut self, l: usize) -> &mut f64 {
        &mut self.0[l]
    }
}

macro_rules! lanewise {
    ($($op:ident $method:ident $sym:tt),*) => {$(
        impl $op for Pack {
            type Output = Pack;
            #[inline(always)]
            fn $method(self, other: Pack) -> Pack {
                let mut out = [0.0; LANES];
                for l in 0..LANES {
                    out[l] = self.0[l] $sym other.0[l];
                }
                Pack(out)
            }
        }
    )*};
}

lanewise!(Add add +, Sub sub -, Mul mul *, Div div /);

impl Neg for Pack {
    type Output = Pack;
    #[inline(always)]
    fn neg(self) -> Pack {
        Pack(self.0.map(|x| -x))
    }
}
