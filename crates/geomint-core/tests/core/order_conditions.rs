//! The order conditions of every method the catalogue gives as data — a splitting's sequence of
//! flows, a composition's weights, a Runge–Kutta tableau — checked by algebra rather than by
//! measuring errors (the observed orders are `orders.rs`'s and each family's own tests').
//!
//! **Splittings and compositions.** Each exact flow is the exponential of its Lie operator: a
//! drift over τ is exp(τA), a kick exp(τB), the damping decay exp(τC) and the exact
//! kick-and-damp exp(τ(B + C)). A step is the product of its flows' exponentials in the order
//! they are applied, and it has order p when that product agrees with the exact flow
//! exp(h(A + B + C)) in every word of A, B, C up to length p (Hairer–Lubich–Wanner, *Geometric
//! Numerical Integration*, III.5). The series are truncated at length p + 1, so the check also
//! shows that the order is not higher. Letters are free (no relation between A, B, C): order
//! p holds for every splitting into such parts. Blanes & Moan's SRKN₁₁ᵇ claims order 6 for
//! Runge–Kutta–Nyström problems only (a quadratic kinetic energy, where [B, [B, [B, A]]] = 0);
//! for it the difference must lie in the two-sided ideal that bracket generates.
//!
//! The θ-method kicks (symplectic Euler, Verlet with damping) and modin_rks's Runge–Kutta
//! momentum flow are exact only without damping: their damped orders are measured (`orders.rs`),
//! and here they are checked as the exact kick they are at γ = 0.
//!
//! **Runge–Kutta tableaux.** Order p holds when Φ(t) = 1/γ(t) for every rooted tree t with at
//! most p vertices (Butcher; Hairer–Nørsett–Wanner I, II.2), Φ the tableau's elementary weight
//! and γ the tree's density.

use geomint_core::methods::build::{sequence, tableau};
use geomint_core::methods::composition::{inverse, Scheme};
use geomint_core::methods::dop853::DOP853;
use geomint_core::methods::splitting::{self, Sequence, SubFlow};
use geomint_core::methods::{MethodId, Requirement};
use nalgebra::{DMatrix, DVector};

/// A coefficient of the difference this small is round-off (the tables are given to 15 to 30
/// digits, and the exact coefficients at length k are 1/k!, 2.5e-5 at k = 8: the largest
/// difference found where the conditions hold is 2.2e-15); at the first failing length some
/// coefficient must differ by more than `FAILS` (the optimized splittings are built to make
/// those small: SRKN₁₁ᵇ's is 5e-7).
const HOLDS: f64 = 1e-13;
const FAILS: f64 = 1e-8;

/// The methods given neither as a sequence, nor as a composition's weights, nor as a tableau,
/// and why: their orders are measured (`orders.rs`, `compositions.rs`, `charts.rs`).
const NOT_DATA: &[(MethodId, &str)] = &[
    (
        MethodId::Csv2,
        "conformal implicit midpoint on the kick, formulas of its own",
    ),
    (
        MethodId::Cimp,
        "a conformal implicit midpoint, solved by Newton's method",
    ),
    (MethodId::ImplicitMidpoint, "solved by Newton's method"),
    (
        MethodId::Rowlands,
        "a modified potential, not a sequence of exact flows",
    ),
];

#[test]
fn every_sequence_composition_and_tableau_meets_its_order_conditions() {
    let mut report = Vec::new();
    for &id in MethodId::ALL {
        let claimed = id.info().order as usize;
        let checked = if let Some(flows) = sequence(id) {
            check_sequence(id, flows, claimed)
        } else if let Some(scheme) = Scheme::of(id) {
            check_composition(scheme, claimed)
        } else if let Some(t) = tableau(id) {
            assert_eq!(t.order as usize, claimed, "{id}: the tableau's own order");
            for (i, (row, c)) in t.a.iter().zip(t.c).enumerate() {
                assert!((row.iter().sum::<f64>() - c).abs() < 1e-15, "{id}: c[{i}]");
            }
            let a: Vec<Vec<f64>> = t.a.iter().map(|row| row.to_vec()).collect();
            vec![("tableau", tree_order(&a, t.b, claimed))]
        } else if id == MethodId::Reference {
            let a: Vec<Vec<f64>> = DOP853.a.iter().map(|row| row.to_vec()).collect();
            vec![("DOP853 tableau", tree_order(&a, &DOP853.b, claimed))]
        } else {
            assert!(
                NOT_DATA.iter().any(|&(m, _)| m == id),
                "{id} is given as none of a sequence, a composition, a tableau: list it in NOT_DATA"
            );
            continue;
        };
        for (what, found) in checked {
            report.push(format!(
                "{:<26} {what:<34} claimed {claimed}, conditions hold to {} (largest difference \
                 there {:.1e}, at the next length {:.1e})",
                id.as_str(),
                found.order,
                found.held,
                found.next
            ));
            assert_eq!(found.order, claimed, "{id} ({what})\n{}", report.join("\n"));
            assert!(found.next > FAILS, "{id} ({what}): {:.1e}", found.next);
        }
    }
    println!("{}", report.join("\n"));
}

/// What the check found: the order (the longest length up to which every condition holds), the
/// largest difference up to it, and the largest at the next length.
struct Found {
    order: usize,
    held: f64,
    next: f64,
}

impl Found {
    /// From the largest difference at each length 1, 2, …, d.
    fn from(differences: &[f64]) -> Found {
        let order = differences.iter().take_while(|&&e| e <= HOLDS).count();
        Found {
            order,
            held: differences[..order].iter().fold(0.0, |m, &e| e.max(m)),
            next: differences.get(order).copied().unwrap_or(0.0),
        }
    }
}

// ---- Splittings and compositions: products of exponentials in free letters ----

/// Letters: the drift A, the kick B, the damping C.
const A: usize = 0;
const B: usize = 1;
const C: usize = 2;

/// A power series in non-commuting letters 0..n, words up to length d, stored by length and
/// then as base-n numbers (the first letter most significant).
#[derive(Clone)]
struct Series {
    n: usize,
    d: usize,
    c: Vec<f64>,
}

impl Series {
    fn offset(n: usize, k: usize) -> usize {
        (0..k).map(|j| n.pow(j as u32)).sum()
    }

    fn one(n: usize, d: usize) -> Series {
        let mut c = vec![0.0; Series::offset(n, d + 1)];
        c[0] = 1.0;
        Series { n, d, c }
    }

    /// The words of length k.
    fn length(&self, k: usize) -> &[f64] {
        &self.c[Series::offset(self.n, k)..Series::offset(self.n, k + 1)]
    }

    fn mul(&self, other: &Series) -> Series {
        let (n, d) = (self.n, self.d);
        let mut out = Series {
            n,
            d,
            c: vec![0.0; self.c.len()],
        };
        for i in 0..=d {
            for (u, &cu) in self.length(i).iter().enumerate() {
                if cu == 0.0 {
                    continue;
                }
                for j in 0..=d - i {
                    let at = Series::offset(n, i + j) + u * n.pow(j as u32);
                    for (v, &cv) in other.length(j).iter().enumerate() {
                        out.c[at + v] += cu * cv;
                    }
                }
            }
        }
        out
    }

    /// exp(τ X) with X = Σ_l x_l · letter l: Σ_k (τX)^k / k!, each term the last times τX/k.
    fn exp(n: usize, d: usize, x: &[f64], tau: f64) -> Series {
        let mut sum = Series::one(n, d);
        let mut term = sum.clone();
        for k in 1..=d {
            let mut next = vec![0.0; term.c.len()];
            let (from, to) = (Series::offset(n, k - 1), Series::offset(n, k));
            for (u, &cu) in term.c[from..to].iter().enumerate() {
                for (l, &xl) in x.iter().enumerate() {
                    next[to + u * n + l] = cu * xl * tau / k as f64;
                }
            }
            term.c = next;
            for (s, t) in sum.c.iter_mut().zip(&term.c) {
                *s += t;
            }
        }
        sum
    }

    /// The largest difference from `exact` at each length 1..=d.
    fn differences(&self, exact: &Series) -> Vec<f64> {
        (1..=self.d)
            .map(|k| {
                let (a, b) = (self.length(k), exact.length(k));
                a.iter().zip(b).fold(0.0, |m, (x, y)| (x - y).abs().max(m))
            })
            .collect()
    }
}

/// The letters of a flow: `None` for a flow that is not an exact exponential once `damped`
/// (a θ-kick, a Runge–Kutta momentum flow); without damping the decay is the identity.
fn letters(flow: SubFlow, damped: bool) -> Option<Vec<f64>> {
    let n = if damped { 3 } else { 2 };
    let mut x = vec![0.0; n];
    match flow {
        SubFlow::Drift => x[A] = 1.0,
        SubFlow::Kick => x[B] = 1.0,
        SubFlow::Damp if damped => x[C] = 1.0,
        SubFlow::Damp => {}
        SubFlow::KickDamp => {
            x[B] = 1.0;
            if damped {
                x[C] = 1.0;
            }
        }
        SubFlow::DampedKick(_) | SubFlow::MomentumRk if damped => return None,
        SubFlow::DampedKick(_) | SubFlow::MomentumRk => x[B] = 1.0,
    }
    Some(x)
}

/// One step over h of `flows`, as a product of exponentials, or `None` (see [`letters`]).
fn step(flows: Sequence, h: f64, damped: bool, d: usize) -> Option<Series> {
    let n = if damped { 3 } else { 2 };
    let mut product = Series::one(n, d);
    for &(flow, fraction) in flows {
        let x = letters(flow, damped)?;
        product = product.mul(&Series::exp(n, d, &x, fraction * h));
    }
    Some(product)
}

/// The exact flow over h = 1.
fn exact(damped: bool, d: usize) -> Series {
    let n = if damped { 3 } else { 2 };
    Series::exp(n, d, &vec![1.0; n], 1.0)
}

fn has_damping(flows: Sequence) -> bool {
    flows
        .iter()
        .any(|&(f, _)| matches!(f, SubFlow::Damp | SubFlow::KickDamp))
}

fn check_sequence(id: MethodId, flows: Sequence, claimed: usize) -> Vec<(&'static str, Found)> {
    let d = claimed + 1;
    let mut found = Vec::new();
    let undamped = step(flows, 1.0, false, d).expect("every flow is exact without damping");
    if id == MethodId::BlanesMoanSrkn11 {
        found.push((
            "undamped, modulo [B,[B,[B,A]]]",
            Found::from(&nystrom_differences(&undamped, &exact(false, d))),
        ));
        // Free letters (a kinetic energy that is not quadratic) allow less.
        let free = Found::from(&undamped.differences(&exact(false, d)));
        assert!(
            free.order < claimed,
            "{id}: order {} in free letters",
            free.order
        );
    } else {
        found.push((
            "undamped",
            Found::from(&undamped.differences(&exact(false, d))),
        ));
    }
    let conservative = id.info().requirements.contains(&Requirement::Conservative);
    if has_damping(flows) && !conservative {
        // Exact damping flows come with exact kicks: a sequence mixing them with θ-kicks would
        // need its damped order measured, and is not one of the catalogue's.
        let damped = step(flows, 1.0, true, d)
            .unwrap_or_else(|| panic!("{id}: exact damping flows beside inexact ones"));
        found.push(("damped", Found::from(&damped.differences(&exact(true, d)))));
    }
    found
}

/// A composition Ψ_h = Φ_{γ_s h} ∘ … ∘ Φ_{γ_1 h} of Störmer–Verlet, and with damping of
/// modin_3s (whose flows are all exact); a processed one conjugated by its processor,
/// π⁻¹ ∘ K_h ∘ π, and its kernel alone of lower order.
fn check_composition(scheme: Scheme, claimed: usize) -> Vec<(&'static str, Found)> {
    let d = claimed + 1;
    let composed = |base: Sequence, damped: bool, weights: &[f64]| {
        let n = if damped { 3 } else { 2 };
        weights.iter().fold(Series::one(n, d), |product, &w| {
            product.mul(&step(base, w, damped, d).expect("an exact base"))
        })
    };
    let mut found = Vec::new();
    for (what, base, damped) in [
        ("of position Verlet, undamped", STRANG, false),
        ("of modin_3s, damped", splitting::MODIN_3S, true),
    ] {
        let kernel = composed(base, damped, &scheme.weights());
        let psi = match scheme.processor() {
            None => kernel,
            Some(pi) => {
                let alone = Found::from(&kernel.differences(&exact(damped, d)));
                assert!(
                    alone.order < claimed,
                    "{scheme:?}'s kernel has order {}",
                    alone.order
                );
                composed(base, damped, &pi)
                    .mul(&kernel)
                    .mul(&composed(base, damped, &inverse(&pi)))
            }
        };
        found.push((what, Found::from(&psi.differences(&exact(damped, d)))));
    }
    found
}

/// Störmer–Verlet with exact flows (position Verlet's θ-kick is the kick at γ = 0).
const STRANG: Sequence = &[
    (SubFlow::Drift, 0.5),
    (SubFlow::Kick, 1.0),
    (SubFlow::Drift, 0.5),
];

/// The largest distance, at each length, of `psi − exact` from the two-sided ideal generated
/// by E = [B, [B, [B, A]]] (words u E v): the differences a Runge–Kutta–Nyström problem cannot
/// see. Lengths below 4 are plain differences.
fn nystrom_differences(psi: &Series, exact: &Series) -> Vec<f64> {
    let (n, d) = (psi.n, psi.d);
    // A word of one letter (the words of length 1 start at index 1).
    let letter = |l: usize| {
        let mut s = Series::one(n, d);
        s.c[0] = 0.0;
        s.c[1 + l] = 1.0;
        s
    };
    let bracket = |x: &Series, y: &Series| {
        let (xy, yx) = (x.mul(y), y.mul(x));
        Series {
            n,
            d,
            c: xy.c.iter().zip(&yx.c).map(|(p, q)| p - q).collect(),
        }
    };
    let (a, b) = (letter(A), letter(B));
    let e = bracket(&b, &bracket(&b, &bracket(&b, &a)));
    let e4 = e.length(4);
    (1..=d)
        .map(|k| {
            let diff: Vec<f64> = psi
                .length(k)
                .iter()
                .zip(exact.length(k))
                .map(|(x, y)| x - y)
                .collect();
            if k < 4 {
                return diff.iter().fold(0.0, |m, x| x.abs().max(m));
            }
            // The generators u E v, |u| + |v| = k − 4, as columns.
            let mut columns = Vec::new();
            for i in 0..=k - 4 {
                let j = k - 4 - i;
                for u in 0..n.pow(i as u32) {
                    for v in 0..n.pow(j as u32) {
                        let mut col = vec![0.0; n.pow(k as u32)];
                        for (w, &ew) in e4.iter().enumerate() {
                            col[(u * n.pow(4) + w) * n.pow(j as u32) + v] += ew;
                        }
                        columns.push(DVector::from_vec(col));
                    }
                }
            }
            let g = DMatrix::from_columns(&columns);
            let svd = g.svd(true, false);
            let u = svd.u.expect("left singular vectors");
            let largest = svd.singular_values.max();
            let mut rest = DVector::from_vec(diff);
            for (i, &s) in svd.singular_values.iter().enumerate() {
                if s > 1e-9 * largest {
                    let ui = u.column(i);
                    let along = ui.dot(&rest);
                    rest -= along * ui;
                }
            }
            rest.amax()
        })
        .collect()
}

// ---- Runge–Kutta tableaux: rooted trees ----

/// A rooted tree as the sorted list of its root's subtrees.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Tree(Vec<Tree>);

impl Tree {
    fn vertices(&self) -> usize {
        1 + self.0.iter().map(Tree::vertices).sum::<usize>()
    }

    /// γ(t) = |t| Π γ(subtrees).
    fn density(&self) -> f64 {
        self.vertices() as f64 * self.0.iter().map(Tree::density).product::<f64>()
    }

    /// Every tree with one more vertex, hung from one of this tree's.
    fn grown(&self) -> Vec<Tree> {
        let mut out = Vec::new();
        let mut at_root = self.0.clone();
        at_root.push(Tree(Vec::new()));
        at_root.sort();
        out.push(Tree(at_root));
        for (i, child) in self.0.iter().enumerate() {
            for bigger in child.grown() {
                let mut children = self.0.clone();
                children[i] = bigger;
                children.sort();
                out.push(Tree(children));
            }
        }
        out
    }

    /// The stage values of the elementary weight: g_i(t) = Π_subtrees u Σ_j a_ij g_j(u).
    fn stage_weights(&self, a: &[Vec<f64>]) -> Vec<f64> {
        let s = a.len();
        let mut g = vec![1.0; s];
        for child in &self.0 {
            let gc = child.stage_weights(a);
            for (i, row) in a.iter().enumerate() {
                g[i] *= row.iter().zip(&gc).map(|(aij, gj)| aij * gj).sum::<f64>();
            }
        }
        g
    }
}

/// Every rooted tree with 1..=d vertices, by number of vertices.
fn trees(d: usize) -> Vec<Vec<Tree>> {
    let mut by_size = vec![vec![Tree(Vec::new())]];
    while by_size.len() < d {
        let mut next: Vec<Tree> = by_size
            .last()
            .unwrap()
            .iter()
            .flat_map(Tree::grown)
            .collect();
        next.sort();
        next.dedup();
        by_size.push(next);
    }
    by_size
}

/// The order of the explicit tableau (rows of `a` as long as their stage, or padded with
/// zeros) by Butcher's conditions, over trees with up to claimed + 1 vertices.
fn tree_order(a: &[Vec<f64>], b: &[f64], claimed: usize) -> Found {
    let s = b.len();
    let a: Vec<Vec<f64>> = a
        .iter()
        .map(|row| (0..s).map(|j| row.get(j).copied().unwrap_or(0.0)).collect())
        .collect();
    let by_size = trees(claimed + 1);
    // The counts of rooted trees (OEIS A000081) confirm the enumeration.
    let counts: Vec<usize> = by_size.iter().map(Vec::len).collect();
    assert_eq!(
        counts[..],
        [1, 1, 2, 4, 9, 20, 48, 115, 286][..counts.len()]
    );
    let differences: Vec<f64> = by_size
        .iter()
        .map(|size| {
            size.iter()
                .map(|t| {
                    let phi: f64 = b
                        .iter()
                        .zip(t.stage_weights(&a))
                        .map(|(bi, gi)| bi * gi)
                        .sum();
                    (phi - 1.0 / t.density()).abs()
                })
                .fold(0.0, f64::max)
        })
        .collect();
    Found::from(&differences)
}
