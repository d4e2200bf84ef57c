//! The potential's landscape of a system nothing drives: its critical points (the equilibria,
//! ∇V(q) = 0 with p = 0), found by Newton's method with the system's Hessian from a lattice of
//! starts over the region the basin map covers, and classified by the Hessian's eigenvalues.
//!
//! What makes it worth finding is the energy argument. Under Rayleigh or conformal damping the
//! energy never rises, so an orbit whose energy is below the lowest critical value that is not a
//! minimum (the lowest saddle, or a maximum in one dimension) can never leave the connected part
//! of {V < E} it is in. By the mountain-pass theorem such a part holds one minimum at most
//! (two would have a saddle between them, lower than the lowest). Where the straight segment
//! from the orbit's position to a minimum stays below that saddle level, the orbit is in that
//! minimum's well for good: with damping it settles there, without it it stays.
//!
//! The argument is only as good as the search: a saddle the lattice missed would make the
//! barrier too high. The search covers the map's region widened by half its size each way; the
//! tests compare every cell it decides with a tight adaptive integration.

use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DVector, DefaultAllocator};
use serde::{Deserialize, Serialize};

use crate::system::{MechanicalSystem, Vector};

/// Starts of the Newton search per coordinate on a lattice.
const STARTS_PER_AXIS: usize = 9;
/// Most Newton starts in all: fewer in many dimensions, where a Newton step costs O(n³).
fn most_starts(n: usize) -> usize {
    ((1usize << 20) / n.max(1).pow(3)).clamp(8, 4096)
}
/// Newton iterations per start.
const NEWTON_ITERATIONS: usize = 60;
/// Points at which V is looked at along a segment from a position to a minimum.
const SEGMENT_POINTS: usize = 64;

/// A critical point of V.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct CriticalPoint {
    /// Its position (p = 0 there).
    pub q: Vec<f64>,
    /// V at it: the energy of the equilibrium.
    pub energy: f64,
    /// The Hessian's eigenvalues, ascending.
    pub hessian_eigenvalues: Vec<f64>,
}

impl CriticalPoint {
    /// Its Morse index: how many directions V falls in (0 for a minimum, 1 for a saddle between
    /// two wells).
    pub fn index(&self) -> usize {
        self.hessian_eigenvalues
            .iter()
            .filter(|&&e| e < 0.0)
            .count()
    }

    /// Whether V has a strict minimum here.
    pub fn is_minimum(&self) -> bool {
        self.hessian_eigenvalues.iter().all(|&e| e > 0.0)
    }
}

/// The critical points found, and the level below which the energy argument holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Landscape {
    /// Every critical point found, minima first, each group by energy.
    pub points: Vec<CriticalPoint>,
    /// The lowest V over the critical points that are not minima; `None` when there are none
    /// (one well, nothing to cross).
    pub barrier: Option<f64>,
}

impl Landscape {
    /// Searches the box `lo..hi` (the positions the map starts from) widened by half its size
    /// each way, and a unit each way where it is flat.
    pub fn find<S: MechanicalSystem>(sys: &S, lo: &[f64], hi: &[f64]) -> Landscape
    where
        DefaultAllocator: Allocator<S::Dim>,
    {
        let n = lo.len();
        let (lo, hi): (Vec<f64>, Vec<f64>) = lo
            .iter()
            .zip(hi)
            .map(|(&a, &b)| {
                let widen = (0.5 * (b - a)).max(1.0);
                (a - widen, b + widen)
            })
            .unzip();
        let mut points: Vec<CriticalPoint> = Vec::new();
        let mut start = Vector::<S::Dim>::zeros_generic(sys.dim(), nalgebra::U1);
        let starts = Starts::new(n);
        for k in 0..starts.count {
            for (i, f) in starts.point(k).enumerate() {
                start[i] = lo[i] + f * (hi[i] - lo[i]);
            }
            let Some(point) = newton(sys, &start) else {
                continue;
            };
            let same = |other: &CriticalPoint| {
                let scale = 1.0 + norm(&other.q);
                distance(&other.q, &point.q) <= 1e-7 * scale
            };
            if !points.iter().any(same) {
                points.push(point);
            }
        }
        // Minima first, then by energy, ties by position: an order that does not depend on
        // which start found a point first.
        points.sort_by(|a, b| {
            (!a.is_minimum())
                .cmp(&!b.is_minimum())
                .then(a.energy.total_cmp(&b.energy))
                .then_with(|| {
                    a.q.iter()
                        .zip(&b.q)
                        .fold(std::cmp::Ordering::Equal, |o, (x, y)| {
                            o.then(x.total_cmp(y))
                        })
                })
        });
        let barrier = points
            .iter()
            .filter(|p| !p.is_minimum())
            .map(|p| p.energy)
            .min_by(f64::total_cmp);
        Landscape { points, barrier }
    }

    /// The minima, as indices into [`points`](Self::points).
    pub fn minima(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.points.len()).filter(|&i| self.points[i].is_minimum())
    }

    /// The minimum whose well holds position `q` below the level `level`: the first minimum,
    /// nearest first, that the straight segment from `q` reaches with V below `level` all the
    /// way. `None` when no segment does (the position may still be in a well whose floor the
    /// segment cannot see straight, and is then decided later, nearer its floor).
    pub fn well_of<S: MechanicalSystem>(
        &self,
        sys: &S,
        q: &Vector<S::Dim>,
        level: f64,
        scratch: &mut Vector<S::Dim>,
    ) -> Option<usize>
    where
        DefaultAllocator: Allocator<S::Dim>,
    {
        let mut minima: Vec<usize> = self.minima().collect();
        let from = |i: usize| -> f64 {
            self.points[i]
                .q
                .iter()
                .enumerate()
                .map(|(k, x)| (x - q[k]).powi(2))
                .sum()
        };
        minima.sort_by(|&a, &b| from(a).total_cmp(&from(b)).then(a.cmp(&b)));
        minima.into_iter().find(|&m| {
            let target = &self.points[m].q;
            (0..=SEGMENT_POINTS).all(|j| {
                let f = j as f64 / SEGMENT_POINTS as f64;
                for (k, &x) in target.iter().enumerate() {
                    scratch[k] = q[k] + f * (x - q[k]);
                }
                sys.potential(scratch) < level
            })
        })
    }
}

/// Where the Newton search starts, as fractions of the box: the midpoints of a lattice of
/// [`STARTS_PER_AXIS`] cells per coordinate where it holds at most [`most_starts`] points, else
/// that many points of the R_d low-discrepancy sequence (Roberts 2018: x_k = frac(½ + k·α) with
/// α_i = g^−(i+1), g the positive root of g^(n+1) = g + 1), which covers the box evenly in any
/// dimension.
struct Starts {
    count: usize,
    /// Points per coordinate of the lattice, or None for the sequence.
    lattice: Option<usize>,
    alpha: Vec<f64>,
}

impl Starts {
    fn new(n: usize) -> Starts {
        let most = most_starts(n);
        let lattice = STARTS_PER_AXIS
            .checked_pow(n as u32)
            .filter(|&c| c <= most)
            .map(|_| STARTS_PER_AXIS);
        let mut g = 2.0f64;
        for _ in 0..64 {
            g = (1.0 + g).powf(1.0 / (n as f64 + 1.0));
        }
        Starts {
            count: lattice.map_or(most, |m| m.pow(n as u32)),
            lattice,
            alpha: (1..=n).map(|i| g.powi(-(i as i32))).collect(),
        }
    }

    /// Start `k`, as a fraction of the box per coordinate.
    fn point(&self, k: usize) -> impl Iterator<Item = f64> + '_ {
        let mut rest = k;
        self.alpha.iter().map(move |a| match self.lattice {
            Some(m) => {
                let j = rest % m;
                rest /= m;
                (j as f64 + 0.5) / m as f64
            }
            None => (0.5 + k as f64 * a).fract(),
        })
    }
}

/// Newton's method for ∇V = 0 from `start`, each step halved until |∇V| falls; the point with
/// its Hessian's eigenvalues, or `None` when it does not converge to a finite point.
fn newton<S: MechanicalSystem>(sys: &S, start: &Vector<S::Dim>) -> Option<CriticalPoint>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let n = start.len();
    let mut q = start.clone();
    let mut trial = start.clone();
    let mut g = start.clone();
    let mut g_trial = start.clone();
    let mut hessian: DMatrix<f64> = DMatrix::zeros(n, n);
    sys.grad_potential(&q, &mut g);
    let scale = |q: &Vector<S::Dim>| 1.0 + q.amax();
    for _ in 0..NEWTON_ITERATIONS {
        if !g.iter().all(|x| x.is_finite()) {
            return None;
        }
        sys.hess_potential(&q, &mut hessian);
        let rhs = DVector::from_iterator(n, g.iter().copied());
        // The pseudo-inverse: at a degenerate point the step is the least-squares one.
        let step = hessian.clone().svd(true, true).solve(&rhs, 1e-14).ok()?;
        let before = g.norm();
        let mut t = 1.0;
        let mut improved = false;
        for _ in 0..30 {
            for i in 0..n {
                trial[i] = q[i] - t * step[i];
            }
            sys.grad_potential(&trial, &mut g_trial);
            if g_trial.norm() < before {
                improved = true;
                break;
            }
            t *= 0.5;
        }
        if !improved {
            break;
        }
        q.copy_from(&trial);
        g.copy_from(&g_trial);
        if g.norm() <= 1e-13 * scale(&q) {
            break;
        }
    }
    // Converged to round-off of the gradient's own size.
    if !(g.norm() <= 1e-9 * scale(&q)) || !q.iter().all(|x| x.is_finite()) {
        return None;
    }
    sys.hess_potential(&q, &mut hessian);
    let mut eigenvalues: Vec<f64> = hessian.symmetric_eigenvalues().iter().copied().collect();
    eigenvalues.sort_by(f64::total_cmp);
    Some(CriticalPoint {
        energy: sys.potential(&q),
        q: q.iter().copied().collect(),
        hessian_eigenvalues: eigenvalues,
    })
}

fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
}
