//! Linear stability studies of the damped oscillator (paper 003 Ch. 3) as the service offers
//! them: maps of the spectral radius over a (γ, h) grid for several methods at once, and the
//! analysis of one method at one (ω, γ, h), with their result documents. The analysis itself is
//! [`crate::stability`].
//!
//! Maps are laid out as the core computes them, one row per h value and one column per γ value;
//! a spectral radius that is not finite (the method is undefined there, e.g. csv2 at γh = 2, or
//! overflows) is `null`, since JSON has no NaN.

use serde::Serialize;

use crate::error::{CoreError, Field, Range};
use crate::methods::{Method, MethodId};
use crate::run::Budget;
use crate::simulation::MethodAt;
use crate::stability::{
    self, Eigenvalue, PointAnalysis, Relation, Spectrum, StabilityAxis, StabilityMap,
    MAX_AXIS_POINTS,
};
use crate::studies::engine::{self, Executor, Finished, Study};
use crate::studies::parts::{Part, ShardAt, Travelling};
use crate::studies::{StudyCompletion, StudySpec};
use crate::system::MechanicalSystem;
use crate::systems::HarmonicOscillator;

/// Most methods in one map request.
pub const MAX_MAP_METHODS: usize = 16;

/// Most cells (methods × γ points × h points) in one map request.
pub const MAX_MAP_CELLS: usize = 1_000_000;

/// Stability maps as asked for: methods, ω and the two axes.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StabilitySpec {
    /// The methods, with their fields (`methods[i]`).
    pub methods: Vec<MethodAt>,
    /// ω.
    pub omega: f64,
    /// The γ axis (columns).
    pub gamma: StabilityAxis,
    /// The h axis (rows).
    pub h: StabilityAxis,
}

/// The analysis at one point as asked for.
#[derive(Clone, Debug, PartialEq)]
pub struct PointSpec {
    /// The method, with its field (`method`).
    pub method: MethodAt,
    /// ω.
    pub omega: f64,
    /// γ.
    pub gamma: f64,
    /// h.
    pub h: f64,
}

/// Validated stability maps, ready to compute.
#[derive(Clone, Debug, PartialEq)]
pub struct StabilityJob {
    /// The spec it was prepared from (what workers and parts carry).
    pub spec: StabilitySpec,
    /// The methods, in the order asked.
    pub methods: Vec<Method>,
    /// ω.
    pub omega: f64,
    /// The γ axis (columns).
    pub gamma: StabilityAxis,
    /// The h axis (rows).
    pub h: StabilityAxis,
}

impl StabilityJob {
    /// Grid points over all maps.
    pub fn points(&self) -> usize {
        self.methods.len() * self.gamma.n * self.h.n
    }
}

/// Why the adaptive reference has no stability map.
pub const NO_PROPAGATION_MATRIX: &str = "the adaptive `reference` integrator has no fixed step \
    and so no propagation matrix; choose a fixed-step method (see GET /api/v1/methods)";

/// Refuses the adaptive reference, which has no fixed step and so no propagation matrix.
fn fixed_step(method: &MethodAt) -> Result<Method, CoreError> {
    if method.method.id() == MethodId::Reference {
        return Err(CoreError::Unsupported {
            field: method.field.clone(),
            reason: NO_PROPAGATION_MATRIX,
        });
    }
    Ok(method.method)
}

/// Refuses `method` on the oscillator damped at rate γ (rowlands needs γ = 0), naming `field`.
fn check_damping(method: &Method, gamma: f64, field: &Field) -> Result<(), CoreError> {
    let sys = HarmonicOscillator { omega: 1.0, gamma };
    method.check(
        field,
        "harmonic_oscillator",
        sys.structure(),
        sys.damping_rate(),
    )
}

impl StabilitySpec {
    /// Validates the maps (cheap: nothing is computed): the methods, ω, the axes and the size
    /// of the work.
    pub fn prepare(&self) -> Result<StabilityJob, CoreError> {
        let field = Field::new("methods");
        if self.methods.is_empty() {
            return Err(CoreError::Empty {
                field,
                what: "method",
            });
        }
        if self.methods.len() > MAX_MAP_METHODS {
            return Err(CoreError::TooMany {
                field,
                what: "methods per request",
                limit: MAX_MAP_METHODS,
                got: Some(self.methods.len()),
            });
        }
        let methods = self
            .methods
            .iter()
            .map(fixed_step)
            .collect::<Result<Vec<_>, _>>()?;
        Range::POSITIVE.check(self.omega, &Field::new("omega"))?;
        self.gamma.check(&Field::new("gamma"), MAX_AXIS_POINTS)?;
        self.h.check(&Field::new("h"), MAX_AXIS_POINTS)?;
        for (method, at) in methods.iter().zip(&self.methods) {
            check_damping(method, self.gamma.max, &at.field)?;
        }
        let job = StabilityJob {
            spec: self.clone(),
            methods,
            omega: self.omega,
            gamma: self.gamma,
            h: self.h,
        };
        let cells = job.points();
        if cells > MAX_MAP_CELLS {
            return Err(CoreError::TooManyCells {
                field,
                methods: job.methods.len(),
                gammas: job.gamma.n,
                hs: job.h.n,
                cells,
                limit: MAX_MAP_CELLS,
            });
        }
        Ok(job)
    }
}

impl PointSpec {
    /// Validates the point (cheap: nothing is computed).
    pub fn prepare(&self) -> Result<PointSpec, CoreError> {
        let method = fixed_step(&self.method)?;
        Range::POSITIVE.check(self.omega, &Field::new("omega"))?;
        Range::NON_NEGATIVE.check(self.gamma, &Field::new("gamma"))?;
        Range::POSITIVE.check(self.h, &Field::new("h"))?;
        check_damping(&method, self.gamma, &self.method.field)?;
        Ok(self.clone())
    }
}

/// The answer to a map request.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct StabilityDocument {
    /// ω.
    pub omega: f64,
    /// The γ axis: the columns of every map.
    pub gamma: StabilityAxis,
    /// The h axis: the rows of every map.
    pub h: StabilityAxis,
    /// One map per method, in the order asked: all of them, or those finished before the time
    /// limit.
    pub maps: Vec<MapDocument>,
    /// `time_limit` when the time limit passed before every method's map was made.
    pub stop: StudyCompletion,
}

/// The stability map of one method: every grid is h.n rows (h values) × gamma.n columns
/// (γ values).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct MapDocument {
    /// The method's label, e.g. `triple_jump(csv1)`.
    #[cfg_attr(feature = "openapi", schema(example = "csv1"))]
    pub method: String,
    /// Largest eigenvalue modulus of the one-step matrix; `null` where it is not finite (the
    /// method is undefined there, e.g. csv2 at γh = 2, or overflows). At h = 0 it is 1.
    pub spectral_radius: Vec<Vec<Option<f64>>>,
    /// Whether both eigenvalues lie in the closed unit disk (spectral radius ≤ 1 + 1e-12).
    pub stable: Vec<Vec<bool>>,
    /// The corrected analytic relation's verdict (cimp, csv1, csv2; `null` for the others).
    pub analytic: Option<Vec<Vec<bool>>>,
    /// The verdict of the relation as printed in the thesis, eqs. (3.12), (3.17), (3.22)
    /// (cimp, csv1, csv2; `null` for the others).
    pub printed: Option<Vec<Vec<bool>>>,
    /// Cells where `stable` and `analytic` disagree, not counting cells next to the numerical
    /// boundary; `null` without an analytic relation.
    pub disagreements: Option<usize>,
    /// The same count for `printed`.
    pub printed_disagreements: Option<usize>,
}

/// A complex eigenvalue.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct EigenvalueDocument {
    /// Real part (`null` when not finite).
    pub re: Option<f64>,
    /// Imaginary part (`null` when not finite).
    pub im: Option<f64>,
}

/// A 2×2 one-step matrix and its spectral data; numbers that are not finite (overflow at
/// extreme ω, γ, h) are `null`.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct SpectrumDocument {
    /// The matrix, row-major: [[∂q⁺/∂q, ∂q⁺/∂p], [∂p⁺/∂q, ∂p⁺/∂p]].
    pub matrix: [[Option<f64>; 2]; 2],
    /// Trace.
    pub trace: Option<f64>,
    /// Determinant.
    pub det: Option<f64>,
    /// The two eigenvalues ½tr ± √((½tr)² − det).
    pub eigenvalues: [EigenvalueDocument; 2],
    /// Largest eigenvalue modulus.
    pub spectral_radius: Option<f64>,
}

/// The core's analysis at one point: the method's one-step matrix and the exact flow's.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct PointAnalysisDocument {
    /// The method's one-step matrix.
    pub method: SpectrumDocument,
    /// The exact flow's matrix over one step (det = e^{−2γh}, ½tr = e^{−γh} cos βh).
    pub exact: SpectrumDocument,
    /// |½ tr M_exact − ½ tr M_method|.
    pub half_trace_error: Option<f64>,
    /// Whether the method is stable here (spectral radius ≤ 1 + 1e-12).
    pub stable: bool,
}

/// The analytic stability verdicts of cimp, csv1 and csv2.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct AnalyticVerdicts {
    /// The relation derived with the Jury condition |½ tr M| ≤ e^{−γh} cosh γh.
    pub corrected: bool,
    /// The relation as printed in the thesis, eqs. (3.12), (3.17), (3.22).
    pub printed: bool,
}

/// The answer to a point request.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct PointDocument {
    /// The method's label.
    #[cfg_attr(feature = "openapi", schema(example = "csv1"))]
    pub method: String,
    /// ω.
    pub omega: f64,
    /// γ.
    pub gamma: f64,
    /// h.
    pub h: f64,
    /// The method's and the exact one-step matrices, the ½-trace error and the verdict.
    pub analysis: PointAnalysisDocument,
    /// The analytic verdicts (cimp, csv1, csv2; `null` for the others).
    pub analytic: Option<AnalyticVerdicts>,
}

/// `x` when finite.
fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

impl From<&Spectrum> for SpectrumDocument {
    fn from(s: &Spectrum) -> Self {
        let eigen = |e: &Eigenvalue| EigenvalueDocument {
            re: finite(e.re),
            im: finite(e.im),
        };
        SpectrumDocument {
            matrix: s.matrix.map(|row| row.map(finite)),
            trace: finite(s.trace),
            det: finite(s.det),
            eigenvalues: [eigen(&s.eigenvalues[0]), eigen(&s.eigenvalues[1])],
            spectral_radius: finite(s.spectral_radius),
        }
    }
}

impl From<&PointAnalysis> for PointAnalysisDocument {
    fn from(a: &PointAnalysis) -> Self {
        PointAnalysisDocument {
            method: (&a.method).into(),
            exact: (&a.exact).into(),
            half_trace_error: finite(a.half_trace_error),
            stable: a.stable,
        }
    }
}

/// `cells` (row-major, `cols` per row) as rows.
fn rows<T: Copy, U>(cells: &[T], cols: usize, f: impl Fn(T) -> U) -> Vec<Vec<U>> {
    cells
        .chunks(cols)
        .map(|row| row.iter().map(|&x| f(x)).collect())
        .collect()
}

impl From<&StabilityMap> for MapDocument {
    fn from(m: &StabilityMap) -> Self {
        let cols = m.gamma.n;
        MapDocument {
            method: m.method.clone(),
            spectral_radius: rows(&m.spectral_radius, cols, finite),
            stable: rows(&m.stable, cols, |s| s),
            analytic: m.analytic.as_deref().map(|a| rows(a, cols, |s| s)),
            printed: m.printed.as_deref().map(|p| rows(p, cols, |s| s)),
            disagreements: m.analytic.as_ref().map(|_| m.disagreements),
            printed_disagreements: m.printed.as_ref().map(|_| m.printed_disagreements),
        }
    }
}

impl Study for StabilityJob {
    /// One row of one method's map: the spectral radius per γ (`None` where it is not finite).
    type Cell = Vec<Option<f64>>;

    fn name(&self) -> &'static str {
        "stability maps"
    }

    /// Method-major: the rows of the first method, then of the second…
    fn cells(&self) -> usize {
        self.methods.len() * self.h.n
    }

    fn run_cells(
        &self,
        cells: std::ops::Range<usize>,
        budget: Budget<'_>,
    ) -> Result<Vec<Option<Self::Cell>>, CoreError> {
        Ok(cells
            .map(|cell| {
                // A row is quick: the budget is looked at between rows.
                (!budget.expired() && !budget.cancelled()).then(|| {
                    let method = &self.methods[cell / self.h.n];
                    stability::map_row(method, self.omega, self.gamma, self.h.at(cell % self.h.n))
                        .into_iter()
                        .map(|r| r.is_finite().then_some(r))
                        .collect()
                })
            })
            .collect())
    }

    fn fits(&self, row: &Self::Cell) -> bool {
        row.len() == self.gamma.n
    }

    fn spec(&self) -> Option<StudySpec> {
        Some(StudySpec::Stability(self.spec.clone()))
    }

    /// A row costs about as much as a few steps per γ: propagation matrices of one step.
    fn steps(&self) -> u64 {
        (self.cells() * self.gamma.n) as u64 * 8
    }
}

impl StabilityJob {
    /// The document from what the rows came to: the maps of the methods whose rows all
    /// finished, in order up to the first that did not (the maps made before the time limit).
    pub fn document_of(&self, finished: Finished<Vec<Option<f64>>>) -> StabilityDocument {
        let mut maps = Vec::with_capacity(self.methods.len());
        for (method, rows) in self.methods.iter().zip(finished.cells.chunks(self.h.n)) {
            let Some(rows) = rows.iter().cloned().collect::<Option<Vec<_>>>() else {
                break;
            };
            let radius = rows
                .into_iter()
                .flatten()
                .map(|r| r.unwrap_or(f64::NAN))
                .collect();
            let map = stability::map_of_rows(method, self.omega, self.gamma, self.h, radius);
            maps.push(MapDocument::from(&map));
        }
        StabilityDocument {
            omega: self.omega,
            gamma: self.gamma,
            h: self.h,
            maps,
            stop: finished.stop,
        }
    }
}

/// Computes the maps of `job` on `executor`. Past the deadline it answers with the maps made so
/// far; it gives up when its flag is set (the server is shutting down or the client went away).
pub fn maps<E: Executor>(
    job: &StabilityJob,
    executor: &E,
    budget: Budget,
) -> Result<StabilityDocument, CoreError> {
    let finished = engine::run(job, executor, budget, &|_, _| {})?;
    Ok(job.document_of(finished))
}

/// The analysis at one point: the core's [`PointAnalysis`] and, for cimp, csv1 and csv2, the
/// analytic verdicts.
pub fn point(spec: &PointSpec) -> Result<PointDocument, CoreError> {
    let PointSpec {
        method,
        omega,
        gamma,
        h,
    } = spec;
    let analysis = stability::analyse(&method.method, *omega, *gamma, *h).map_err(|e| {
        match e.field().map(Field::as_str) {
            Some("method") => e.at(method.field.clone()),
            _ => e,
        }
    })?;
    let verdict =
        |relation| stability::analytic_stable(method.method.id(), relation, *omega, *gamma, *h);
    let analytic = match (verdict(Relation::Corrected), verdict(Relation::Printed)) {
        (Some(corrected), Some(printed)) => Some(AnalyticVerdicts { corrected, printed }),
        _ => None,
    };
    Ok(PointDocument {
        method: method.method.label(),
        omega: *omega,
        gamma: *gamma,
        h: *h,
        analysis: (&analysis).into(),
        analytic,
    })
}

/// A shard of it, as a worker or an array task runs it.
impl Travelling for StabilitySpec {
    type Cell = Vec<Option<f64>>;

    // The maps are bounded by their own cell limit, not a simulation's.
    fn run_shard(
        &self,
        at: &ShardAt<'_>,
        _limits: &crate::simulation::Limits,
    ) -> Result<Part<Self::Cell>, CoreError> {
        at.run(&self.prepare()?)
    }
}
