//! Symbolic derivatives against central differences, for first and second derivatives
//! of every example system, at random points.

use super::common::{build, close, vars, Example, Rng, EXAMPLES};
use geomint_core::expr::{CompileOptions, CompiledFunction};

/// Everything about one example compiled into one function:
/// `[f, gradient (reverse mode)..., derivatives (forward mode)..., Hessian row-major...]`.
struct Compiled {
    function: CompiledFunction,
    n: usize,
}

impl Compiled {
    fn new(example: &Example) -> Self {
        let (mut graph, scope, f) = build(example);
        let vars = vars(&scope);
        let n = vars.len();
        let gradient = graph.gradient(f, &vars).unwrap();
        let forward: Vec<_> = vars
            .iter()
            .map(|&v| graph.derivative(f, v).unwrap())
            .collect();
        let hessian = graph.hessian(f, &vars).unwrap();
        let mut outputs = vec![f];
        outputs.extend(&gradient);
        outputs.extend(&forward);
        outputs.extend(hessian.iter().flatten());
        let options = CompileOptions::with_layout(vars);
        let function = CompiledFunction::new(&graph, &outputs, &options).unwrap();
        Compiled { function, n }
    }

    fn eval(&self, point: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; 1 + 2 * self.n + self.n * self.n];
        self.function.eval(point, &mut out);
        out
    }

    /// Central difference of output `k` along coordinate `i`, with a step scaled to
    /// the coordinate.
    fn central(&self, point: &[f64], k: usize, i: usize) -> f64 {
        let h = 1e-5 * point[i].abs().max(1.0);
        let (mut plus, mut minus) = (point.to_vec(), point.to_vec());
        plus[i] += h;
        minus[i] -= h;
        // The actual step, after rounding of the shifted coordinates.
        let step = plus[i] - minus[i];
        (self.eval(&plus)[k] - self.eval(&minus)[k]) / step
    }
}

const POINTS: usize = 40;

#[test]
fn first_derivatives_match_central_differences() {
    let mut rng = Rng(1);
    for example in EXAMPLES {
        let compiled = Compiled::new(example);
        let n = compiled.n;
        for _ in 0..POINTS {
            let point = (example.sample)(&mut rng);
            let out = compiled.eval(&point);
            for i in 0..n {
                let numeric = compiled.central(&point, 0, i);
                let (reverse, forward) = (out[1 + i], out[1 + n + i]);
                let context = format!("{} d/d{} at {point:?}", example.name, example.names[i]);
                assert!(
                    close(reverse, numeric, 1e-6),
                    "{context}: {reverse} vs {numeric}"
                );
                assert!(
                    close(forward, numeric, 1e-6),
                    "{context}: {forward} vs {numeric}"
                );
                assert!(
                    close(forward, reverse, 1e-12),
                    "{context}: {forward} vs {reverse}"
                );
            }
        }
    }
}

#[test]
fn second_derivatives_match_central_differences() {
    let mut rng = Rng(2);
    for example in EXAMPLES {
        let compiled = Compiled::new(example);
        let n = compiled.n;
        for _ in 0..POINTS {
            let point = (example.sample)(&mut rng);
            let out = compiled.eval(&point);
            let hessian = &out[1 + 2 * n..];
            for i in 0..n {
                for j in 0..n {
                    // d/dx_i of the (exact) gradient component j.
                    let numeric = compiled.central(&point, 1 + j, i);
                    let symbolic = hessian[i * n + j];
                    let context = format!(
                        "{} d2/d{}d{} at {point:?}",
                        example.name, example.names[i], example.names[j]
                    );
                    assert!(
                        close(symbolic, numeric, 1e-6),
                        "{context}: {symbolic} vs {numeric}"
                    );
                    assert_eq!(
                        symbolic.to_bits(),
                        hessian[j * n + i].to_bits(),
                        "{context}"
                    );
                }
            }
        }
    }
}

#[test]
fn known_closed_forms() {
    // d/dq (1 - cos q) = sin q exactly, d2 = cos q exactly.
    let (mut graph, scope, f) = build(&EXAMPLES[0]);
    let q = scope.lookup("q").unwrap();
    let d = graph.derivative(f, q).unwrap();
    let d2 = graph.derivative(d, q).unwrap();
    for x in [-2.0, 0.1, 1.3, 3.0] {
        let values = graph.eval(&[d, d2], &[x]);
        assert_eq!(values, vec![f64::sin(x), f64::cos(x)]);
    }
    // The Kepler force: d/dx (-1/r) = x / r^3.
    let (mut graph, scope, f) = build(&EXAMPLES[4]);
    let gradient = graph.gradient(f, &vars(&scope)).unwrap();
    let (x, y) = (0.6, -0.8);
    let values = graph.eval(&gradient, &[x, y]);
    assert!(
        close(values[0], x, 1e-15) && close(values[1], y, 1e-15),
        "{values:?}"
    );
}

#[test]
fn derivative_of_each_function_at_a_point() {
    // Each operation alone, against its textbook derivative.
    type Derivative = fn(f64) -> f64;
    let cases: &[(&str, Derivative)] = &[
        ("sin(x)", f64::cos),
        ("cos(x)", |x| -x.sin()),
        ("tan(x)", |x| 1.0 / (x.cos() * x.cos())),
        ("asin(x)", |x| 1.0 / (1.0 - x * x).sqrt()),
        ("acos(x)", |x| -1.0 / (1.0 - x * x).sqrt()),
        ("atan(x)", |x| 1.0 / (1.0 + x * x)),
        ("sinh(x)", f64::cosh),
        ("cosh(x)", f64::sinh),
        ("tanh(x)", |x| 1.0 - x.tanh() * x.tanh()),
        ("exp(x)", f64::exp),
        ("log(x)", |x| 1.0 / x),
        ("sqrt(x)", |x| 0.5 / x.sqrt()),
        ("abs(x)", f64::signum),
        ("abs(-x)", f64::signum),
        ("x^3", |x| 3.0 * x * x),
        ("x^-2", |x| -2.0 / (x * x * x)),
        ("x^20", |x| 20.0 * x.powi(19)),
        ("x^0.5", |x| 0.5 / x.sqrt()),
        ("2^x", |x| 2f64.powf(x) * 2f64.ln()),
        ("x^x", |x| x.powf(x) * (x.ln() + 1.0)),
        ("atan2(x, 2)", |x| 2.0 / (4.0 + x * x)),
        ("atan2(2, x)", |x| -2.0 / (4.0 + x * x)),
        ("1/x", |x| -1.0 / (x * x)),
        ("-x", |_| -1.0),
        ("x - 3*x", |_| -2.0),
    ];
    let scope = geomint_core::expr::NameScope::with_names(&["x"]).unwrap();
    let x_var = scope.lookup("x").unwrap();
    for (text, expected) in cases {
        let mut graph = geomint_core::expr::Graph::new();
        let f = graph.parse(text, &scope).unwrap();
        let d = graph.derivative(f, x_var).unwrap();
        for x in [0.3, 0.7, 0.9] {
            let got = graph.eval(&[d], &[x])[0];
            assert!(
                close(got, expected(x), 1e-13),
                "d/dx {text} at {x}: {got} vs {}",
                expected(x)
            );
        }
    }
}
