//! Typed errors of the integrator core. An error about an input carries the path of the field at
//! fault ([`Field`], e.g. `methods[1].inner`) as the caller named it, and the numbers that explain
//! it (the value, the valid range, the limit); its error code ([`ErrorCode`]) is chosen by its
//! variant, and the message [`Display`](std::fmt::Display) writes.
//!
//! - [`field`]: field paths and valid ranges.
//! - [`detail`]: error codes and the error shape every interface reports.
//! - [`StepError`]: a failure inside one step.

pub mod detail;
pub mod field;
mod message;
mod step;

use thiserror::Error;

use super::expr::ExprError;
use super::system::Requirement;
pub use detail::{ErrorCode, ErrorDetail};
use field::out_of_range;
pub use field::{show, Field, Range};
pub use message::StepScope;
use message::{at_point, divisor_detail, list, too_many_steps};
pub use step::StepError;

/// Why a request to the core cannot be carried out. Every variant about an input names its
/// field; the interfaces map variants to error codes.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum CoreError {
    /// No system has this id.
    #[error("unknown system `{id}`; known: {}", list(known))]
    UnknownSystem {
        /// The field (`system`).
        field: Field,
        /// The id asked for.
        id: String,
        /// The ids on offer.
        known: Vec<String>,
    },
    /// No method has this id.
    #[error("{field}: unknown method `{id}`; known: {}", list(known))]
    UnknownMethod {
        /// The field, e.g. `methods[1]` or `methods[1].inner`.
        field: Field,
        /// The id asked for.
        id: String,
        /// The ids on offer.
        known: Vec<String>,
    },
    /// The system has no chart of this id.
    #[error("{field}: `{system}` has no chart `{id}`; charts: {}", list(known))]
    UnknownChart {
        /// The field, e.g. `chart` or `charts[1]`.
        field: Field,
        /// The system.
        system: String,
        /// The chart asked for.
        id: String,
        /// The system's charts.
        known: Vec<String>,
    },
    /// A parameter the system does not have.
    #[error("{field}: unknown parameter for `{system}`; known: {}", list(known))]
    UnknownParameter {
        /// The field, e.g. `params.omega`.
        field: Field,
        /// The system.
        system: String,
        /// Its parameters.
        known: Vec<String>,
    },
    /// A name that is not one of a fixed set (a processor, a pair potential).
    #[error("{field}: unknown {what} `{value}`; known: {}", list(known))]
    UnknownName {
        /// The field.
        field: Field,
        /// What kind of name (`processor`, `potential`).
        what: String,
        /// The name given.
        value: String,
        /// The names on offer.
        known: Vec<String>,
    },
    /// An option the method does not take.
    #[error("{field}: `{method}` takes no option `{option}`")]
    UnknownOption {
        /// The field, e.g. `methods[0].inner`.
        field: Field,
        /// The method's id.
        method: &'static str,
        /// The option given.
        option: &'static str,
    },
    /// A known method where only some are allowed (the inner method of modin_rks, the base of a
    /// composition).
    #[error("{field}: {rule}: one of {}", list(allowed))]
    NotAllowed {
        /// The field.
        field: Field,
        /// The id of the method given.
        method: &'static str,
        /// What is required, in words.
        rule: &'static str,
        /// The methods allowed.
        allowed: Vec<String>,
    },
    /// A number outside its valid range (or not finite).
    #[error("{}", out_of_range(field, *value, range))]
    OutOfRange {
        /// The field.
        field: Field,
        /// The value given.
        value: f64,
        /// The valid range.
        range: Range,
    },
    /// A value that must be finite is not.
    #[error("{field}: must be finite")]
    NotFinite {
        /// The field, e.g. `q0[2]`.
        field: Field,
    },
    /// A value of the wrong kind (a parameter given as text where a number is needed).
    #[error("{field}: must be {expected}")]
    WrongKind {
        /// The field.
        field: Field,
        /// What it must be, e.g. `a number`.
        expected: &'static str,
    },
    /// A list of the wrong length for the system.
    #[error("{field}: needs {expected} entries for this system, got {got}")]
    WrongLength {
        /// The field.
        field: Field,
        /// The length needed.
        expected: usize,
        /// The length given.
        got: usize,
    },
    /// A count outside its bounds (grid points, list entries).
    #[error("{field}: needs {min} to {max} {what}, got {got}")]
    Count {
        /// The field.
        field: Field,
        /// The count given.
        got: u64,
        /// Fewest allowed.
        min: u64,
        /// Most allowed.
        max: u64,
        /// What is counted (`entries`, `grid points`, `points`).
        what: &'static str,
    },
    /// An input the request must give and did not.
    #[error("missing field `{field}`: {what}")]
    Missing {
        /// The field.
        field: Field,
        /// What it is, e.g. `the step sizes, e.g. [0.1, 0.05]`.
        what: &'static str,
    },
    /// A list that must not be empty.
    #[error("{field}: give at least one {what}")]
    Empty {
        /// The field.
        field: Field,
        /// One of its entries, e.g. `method`.
        what: &'static str,
    },
    /// More entries than a request may have.
    #[error("{field}: at most {limit} {what}{}", got.map(|n| format!(", got {n}")).unwrap_or_default())]
    TooMany {
        /// The field.
        field: Field,
        /// What, per what (`methods per request`).
        what: &'static str,
        /// The limit.
        limit: usize,
        /// The count given, when the message shows it.
        got: Option<usize>,
    },
    /// An entry listed twice.
    #[error("{field}: `{value}` is listed twice")]
    Duplicate {
        /// The field of the second entry.
        field: Field,
        /// The entry.
        value: String,
    },
    /// Two inputs that exclude each other were both given.
    #[error("{field}: give either {first} or {second}, not both")]
    Either {
        /// The field blamed.
        field: Field,
        /// The first choice, in words.
        first: &'static str,
        /// The second choice, in words.
        second: &'static str,
    },
    /// An interval given as [min, max] that is not finite or has min > max.
    #[error("{field}: must be a finite range [min, max] with min ≤ max, got [{}, {}]", show(*min), show(*max))]
    BadInterval {
        /// The field.
        field: Field,
        /// Its first number.
        min: f64,
        /// Its second number.
        max: f64,
    },
    /// A run (or a study's runs together) would take more steps than allowed.
    #[error("{}", too_many_steps(field, *steps, *limit, *scope))]
    TooManySteps {
        /// The field blamed (t_end for a simulation, the step size of a study's setting, the
        /// study's list of settings for a study).
        field: Field,
        /// The steps asked for.
        steps: u64,
        /// The limit.
        limit: u64,
        /// What the limit counts.
        scope: StepScope,
    },
    /// A request would produce more samples than allowed.
    #[error("{field}: {samples} samples in all exceeds the limit of {limit}; sample less often")]
    TooManySamples {
        /// The field (`output.every`).
        field: Field,
        /// The samples asked for.
        samples: u64,
        /// The limit.
        limit: u64,
    },
    /// A stability request would compute more map cells than allowed.
    #[error("{field}: {methods} methods × {gammas} γ values × {hs} h values = {cells} cells exceeds the limit of {limit} per request; ask for fewer methods or coarser axes")]
    TooManyCells {
        /// The field (`methods`).
        field: Field,
        /// Methods.
        methods: usize,
        /// Points of the γ axis.
        gammas: usize,
        /// Points of the h axis.
        hs: usize,
        /// Their product.
        cells: usize,
        /// The limit.
        limit: usize,
    },
    /// An energy-error map would take more steps than allowed.
    #[error("{field}: {cells} cells × 2 charts × {steps} steps = {total} steps exceeds the limit of {limit}")]
    MapTooLarge {
        /// The field (`t_max`).
        field: Field,
        /// Cells of the grid.
        cells: u64,
        /// Steps per cell and chart.
        steps: u64,
        /// Steps in all.
        total: u64,
        /// The limit.
        limit: u64,
    },
    /// A method whose structural requirements the system does not meet.
    #[error("method `{method}` cannot run on `{system}`: it requires {}", requirement.describe())]
    Unmet {
        /// The method's field.
        field: Field,
        /// The method's label.
        method: String,
        /// The system (and chart).
        system: String,
        /// The first unmet requirement.
        requirement: Requirement,
    },
    /// A method that cannot take a system depending on the time t.
    #[error("method `{method}` cannot run on `{system}`, whose energy or damping depends on the time t: {why}")]
    TimeDependent {
        /// The method's field.
        field: Field,
        /// The method's label.
        method: String,
        /// The system.
        system: String,
        /// Why not.
        why: &'static str,
    },
    /// A method without a step Jacobian where one is needed.
    #[error("{field}: {why} no step Jacobian; drop it or jacobian_defect")]
    NoStepJacobian {
        /// The method's field.
        field: Field,
        /// The method's id.
        method: &'static str,
        /// Why it has none, as the method's catalogue entry says.
        why: &'static str,
    },
    /// A method with no tangent map on this system, where chaos indicators need one.
    #[error(
        "{field}: `{method}` has no tangent map on `{system}`: {why}; drop it or the indicators"
    )]
    NoTangentMap {
        /// The method's field (`methods[1]`), or `indicators` when the system is the reason.
        field: Field,
        /// The method's label.
        method: String,
        /// The system (and chart).
        system: String,
        /// Why.
        why: String,
    },
    /// Too few deviation vectors for an indicator.
    #[error("{field}: `{indicator}` needs at least {needed} deviation vectors, got {got}")]
    NeedsDeviations {
        /// The field (`deviations`).
        field: Field,
        /// The indicator.
        indicator: &'static str,
        /// Vectors it needs.
        needed: usize,
        /// Vectors asked for.
        got: usize,
    },
    /// A threshold on a statistic whose indicator is not asked for.
    #[error(
        "{field}: a threshold on `{statistic}` needs the indicator `{indicator}` in `indicators`"
    )]
    ThresholdWithoutIndicator {
        /// The field (`stop_when.<statistic>`).
        field: Field,
        /// The statistic.
        statistic: &'static str,
        /// The indicator that reports it.
        indicator: &'static str,
    },
    /// An initial state whose solved momentum cannot bring H down to the energy surface.
    #[error("{field}: no state here has H = {energy}: whatever `{solve_for}` is, H ≥ {}", show(*lowest))]
    AboveEnergySurface {
        /// The field (`energy_surface.energy`).
        field: Field,
        /// E.
        energy: f64,
        /// The momentum solved for (`p0[0]`).
        solve_for: String,
        /// The least H over the solved momentum.
        lowest: f64,
    },
    /// An energy surface H = E that no cell of a sweep's grid reaches.
    #[error("{field}: no cell of the grid has a state with H = {energy}: at every cell H stays above it whatever `{solve_for}` is; its least value is {} (cell {cell})", show(*lowest))]
    NoEnergySolution {
        /// The field (`energy_surface.energy`).
        field: Field,
        /// E.
        energy: f64,
        /// The momentum solved for (`p0[0]`).
        solve_for: String,
        /// The least H over the solved momentum, at the best cell.
        lowest: f64,
        /// That cell.
        cell: usize,
    },
    /// A request the computation does not support, with the reason.
    #[error("{field}: {reason}")]
    Unsupported {
        /// The field.
        field: Field,
        /// Why, in words.
        reason: &'static str,
    },
    /// An initial state the chart does not cover.
    #[error("{field}: the initial state is outside the `{chart}` chart: {reason}")]
    OutsideChart {
        /// The field (`q0`, or `chart` when the state is the default one).
        field: Field,
        /// The chart.
        chart: String,
        /// Why (a singular point, outside the chart's range).
        reason: String,
    },
    /// A study's settings that would start from different physical states (a chart whose
    /// transformation depends on h, with the initial state given in the chart).
    #[error("{field}: the initial state in the `{chart}` chart at h = {h} is another physical state than at the first setting; give q0 and p0 in Cartesian coordinates")]
    StateDiffers {
        /// The field (`q0`).
        field: Field,
        /// The chart.
        chart: String,
        /// The step size of the setting.
        h: f64,
    },
    /// A system whose default initial state does not fit its parameters (N bodies with other
    /// masses).
    #[error(
        "{field}: give q0 and p0 ({dimension} entries each) for a non-default number of bodies"
    )]
    NeedsInitialState {
        /// The missing field (`q0` or `p0`).
        field: Field,
        /// Entries each needs.
        dimension: usize,
    },
    /// A step size at which a method's linear solve is singular.
    #[error("{field}: {method} needs to solve a singular linear system at this step size (γh = {gamma_h}): choose another h")]
    SingularStep {
        /// The field (`h`).
        field: Field,
        /// The method's id.
        method: &'static str,
        /// γh there.
        gamma_h: f64,
    },
    /// A step size that must divide a time span into whole steps and does not.
    #[error("{field}: must divide {span_name} = {} {purpose}; {}", show(*span), divisor_detail(*h, *span, *show_ratio))]
    NotADivisor {
        /// The field.
        field: Field,
        /// The step size.
        h: f64,
        /// The span.
        span: f64,
        /// The span's name, e.g. `t_end/samples`.
        span_name: &'static str,
        /// Why it must divide, e.g. `so that the samples are step endpoints`.
        purpose: &'static str,
        /// Whether the message shows span/h (else it shows h).
        show_ratio: bool,
    },
    /// The reference run of a simulation did not finish.
    #[error("{field}: the reference run did not finish ({stop})")]
    ReferenceUnfinished {
        /// The field (`compare_to_reference`).
        field: Field,
        /// How it stopped.
        stop: String,
    },
    /// An expression of a user-defined system that does not parse, uses a name it may not, or
    /// whose derivatives or code grow past the limits.
    #[error("{field}: {error}")]
    Expression {
        /// The field holding the expression, e.g. `system.damping.matrix[1][0]`.
        field: Field,
        /// What is wrong, with the character position for an error in the text.
        error: ExprError,
    },
    /// A name declared twice in a user-defined system.
    #[error("{field}: `{name}` is already declared at {first}")]
    DuplicateName {
        /// The second declaration.
        field: Field,
        /// The name.
        name: String,
        /// The first declaration.
        first: Field,
    },
    /// A matrix that must be symmetric and is not.
    #[error(
        "{field}: the matrix must be symmetric, but this entry differs from {other}{}",
        at_point(at)
    )]
    NotSymmetric {
        /// The entry (i, j).
        field: Field,
        /// The entry (j, i).
        other: Field,
        /// The configuration where the entries differ (empty when they differ as expressions).
        at: Vec<f64>,
    },
    /// A matrix that must be positive (semi)definite and is not.
    #[error("{field}: {what} must be {property}; {detail}")]
    NotDefinite {
        /// The field of the matrix.
        field: Field,
        /// Which matrix, in words.
        what: &'static str,
        /// What it must be (`symmetric positive definite`).
        property: &'static str,
        /// Where and what it is.
        detail: String,
    },
    /// A step failed (Newton did not converge, …).
    #[error("{}step {step} (t = {t}): {source}", run.as_ref().map(|r| format!("{r}: ")).unwrap_or_default())]
    Step {
        /// The input that asked for the failing run, when it was not a method of the request
        /// (`compare_to_reference`).
        field: Option<Field>,
        /// Which run failed, when the message should say (`reference run`, a study's method).
        run: Option<String>,
        /// The step that failed, counted from 1.
        step: u64,
        /// The time at the start of that step.
        t: f64,
        /// What went wrong.
        source: StepError,
    },
    /// The executor that runs a study's shards elsewhere failed (its NATS server went away).
    #[error("{message}")]
    Executor {
        /// What failed, in words.
        message: String,
    },
    /// A computation stopped because it was cancelled (its client went away, or the server is
    /// shutting down).
    #[error("the {what} was cancelled{}", if *shutdown { " (the server is shutting down)" } else { "" })]
    Cancelled {
        /// What was cancelled (`study`, `map`).
        what: &'static str,
        /// Whether the message blames the shutdown.
        shutdown: bool,
    },
    /// A computation did not finish within its time limit.
    #[error("{message}")]
    TimeLimit {
        /// The input whose work did not finish, when one is to blame (`compare_to_reference`).
        field: Option<Field>,
        /// What did not finish and what to do, in words.
        message: String,
    },
}

/// Matches an error on where its field is: `$field` binds the field of the variants that always
/// have one, `$maybe` the optional field of those that may, and `$none` stands for the variants
/// without one. The variants are listed here once, for [`CoreError::field`] and [`CoreError::at`].
macro_rules! match_field {
    ($error:expr, $field:ident => $always:expr, $maybe:ident => $sometimes:expr, _ => $none:expr) => {
        match $error {
            CoreError::UnknownSystem { field: $field, .. }
            | CoreError::UnknownMethod { field: $field, .. }
            | CoreError::UnknownChart { field: $field, .. }
            | CoreError::UnknownParameter { field: $field, .. }
            | CoreError::UnknownName { field: $field, .. }
            | CoreError::UnknownOption { field: $field, .. }
            | CoreError::NotAllowed { field: $field, .. }
            | CoreError::OutOfRange { field: $field, .. }
            | CoreError::NotFinite { field: $field, .. }
            | CoreError::WrongKind { field: $field, .. }
            | CoreError::WrongLength { field: $field, .. }
            | CoreError::Count { field: $field, .. }
            | CoreError::Missing { field: $field, .. }
            | CoreError::Empty { field: $field, .. }
            | CoreError::TooMany { field: $field, .. }
            | CoreError::Duplicate { field: $field, .. }
            | CoreError::Either { field: $field, .. }
            | CoreError::BadInterval { field: $field, .. }
            | CoreError::TooManySteps { field: $field, .. }
            | CoreError::TooManySamples { field: $field, .. }
            | CoreError::TooManyCells { field: $field, .. }
            | CoreError::MapTooLarge { field: $field, .. }
            | CoreError::Unmet { field: $field, .. }
            | CoreError::TimeDependent { field: $field, .. }
            | CoreError::NoStepJacobian { field: $field, .. }
            | CoreError::NoTangentMap { field: $field, .. }
            | CoreError::NeedsDeviations { field: $field, .. }
            | CoreError::ThresholdWithoutIndicator { field: $field, .. }
            | CoreError::NoEnergySolution { field: $field, .. }
            | CoreError::AboveEnergySurface { field: $field, .. }
            | CoreError::Unsupported { field: $field, .. }
            | CoreError::OutsideChart { field: $field, .. }
            | CoreError::StateDiffers { field: $field, .. }
            | CoreError::NeedsInitialState { field: $field, .. }
            | CoreError::SingularStep { field: $field, .. }
            | CoreError::NotADivisor { field: $field, .. }
            | CoreError::ReferenceUnfinished { field: $field, .. }
            | CoreError::Expression { field: $field, .. }
            | CoreError::DuplicateName { field: $field, .. }
            | CoreError::NotSymmetric { field: $field, .. }
            | CoreError::NotDefinite { field: $field, .. } => $always,
            CoreError::Step { field: $maybe, .. } | CoreError::TimeLimit { field: $maybe, .. } => {
                $sometimes
            }
            CoreError::Cancelled { .. } | CoreError::Executor { .. } => $none,
        }
    };
}

impl CoreError {
    /// The input field the error concerns, if any.
    pub fn field(&self) -> Option<&Field> {
        match_field!(self, field => Some(field), field => field.as_ref(), _ => None)
    }

    /// The same error about another field: for an input that a caller passed on under another
    /// name (a study's setting checked as a simulation's `h`).
    pub fn at(mut self, to: Field) -> Self {
        match_field!(&mut self, field => *field = to, field => *field = Some(to), _ => {});
        self
    }
}
