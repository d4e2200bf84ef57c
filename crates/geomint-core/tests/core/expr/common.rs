//! Shared test fixtures: a small deterministic random generator and the example systems.

use geomint_core::expr::{Graph, NameScope, NodeId, Var};

/// SplitMix64: deterministic, dependency-free, good enough for sampling test points.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        let unit = (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        lo + (hi - lo) * unit
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}

/// An example system: its expression, its names, and a sampler of points where it is
/// smooth (away from singularities and kinks).
pub struct Example {
    pub name: &'static str,
    pub text: &'static str,
    pub names: &'static [&'static str],
    pub sample: fn(&mut Rng) -> Vec<f64>,
}

fn box_sample(rng: &mut Rng, n: usize, lo: f64, hi: f64) -> Vec<f64> {
    (0..n).map(|_| rng.uniform(lo, hi)).collect()
}

pub const EXAMPLES: &[Example] = &[
    Example {
        name: "pendulum",
        text: "1 - cos(q)",
        names: &["q"],
        sample: |rng| box_sample(rng, 1, -4.0, 4.0),
    },
    Example {
        name: "elastic pendulum",
        text: "k/2*(sqrt(x^2+y^2+z^2) - l)^2 + m*g*z",
        names: &["x", "y", "z", "k", "l", "m", "g"],
        sample: |rng| {
            let mut v = box_sample(rng, 3, -2.0, 2.0);
            v[0] = v[0].signum() * (0.3 + v[0].abs()); // keep away from the origin
            v.extend([rng.uniform(1.0, 50.0), rng.uniform(0.5, 2.0)]);
            v.extend([rng.uniform(0.1, 3.0), 9.81]);
            v
        },
    },
    Example {
        name: "Henon-Heiles",
        text: "(x^2+y^2)/2 + x^2*y - y^3/3",
        names: &["x", "y"],
        sample: |rng| box_sample(rng, 2, -1.0, 1.0),
    },
    Example {
        name: "double pendulum",
        text: "(p1^2 + 2*p2^2 - 2*p1*p2*cos(t1-t2)) / (2*(1 + sin(t1-t2)^2)) - 2*cos(t1) - cos(t2)",
        names: &["t1", "t2", "p1", "p2"],
        sample: |rng| box_sample(rng, 4, -3.0, 3.0),
    },
    Example {
        name: "Kepler",
        text: "-1/sqrt(x^2+y^2)",
        names: &["x", "y"],
        sample: |rng| {
            let (r, phi) = (rng.uniform(0.3, 3.0), rng.uniform(-3.1, 3.1));
            vec![r * phi.cos(), r * phi.sin()]
        },
    },
    Example {
        name: "Duffing",
        text: "a*x^2/2 + b*x^4/4",
        names: &["x", "a", "b"],
        sample: |rng| box_sample(rng, 3, -2.0, 2.0),
    },
    Example {
        name: "mixed functions",
        text: "atan2(y, x) * abs(x - y) + exp(-x^2) * log(1 + y^2) + tanh(x*y)",
        names: &["x", "y"],
        sample: |rng| loop {
            let v = box_sample(rng, 2, -2.0, 2.0);
            // atan2 is smooth off the negative x axis, abs off the diagonal.
            if (v[0] - v[1]).abs() > 0.05 && !(v[0] < 0.0 && v[1].abs() < 0.05) {
                return v;
            }
        },
    },
    Example {
        name: "all functions",
        text: "sin(x)*cos(y) + tan(x/3) + asin(x/3) + acos(y/3) + atan(x*y) + sinh(x/2) \
               + cosh(y/2) + sqrt(2 + x) - x^-2 + y^0.5 + x^y",
        names: &["x", "y"],
        sample: |rng| vec![rng.uniform(0.3, 1.5), rng.uniform(0.3, 1.5)],
    },
];

/// Parses an example into a fresh graph.
pub fn build(example: &Example) -> (Graph, NameScope, NodeId) {
    let scope = NameScope::with_names(example.names).unwrap();
    let mut graph = Graph::new();
    let root = graph.parse(example.text, &scope).unwrap();
    (graph, scope, root)
}

pub fn vars(scope: &NameScope) -> Vec<Var> {
    scope.vars().collect()
}

/// `|a - b|` within `rel` of the larger magnitude, with a small absolute floor.
pub fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()) + 1e-8
}

/// Bitwise equality, with all NaNs equal and +0 equal to -0.
pub fn same_value(a: f64, b: f64) -> bool {
    a == b || (a.is_nan() && b.is_nan())
}
