"""The HTTP API as the client uses it: every route it calls and the JSON it sends and reads.

Each ``TypedDict`` below mirrors a schema of the server's OpenAPI document
(``GET /api/v1/openapi.json``) and declares only the members this client sends or reads. A class
named like a component schema stands for it; the variants of a tagged union (a stream's lines, a
run's stop reasons, a parameter's kinds) are separate classes. ``python/tests/test_contract.py``
checks every route in :data:`ROUTES` against the served document (path, method, query values,
media types, request and answer schemas) and every member declared here against its schema
(present, of a compatible type, required where the client relies on it), so the client cannot
drift from the server. The client reaches JSON members only through these types, which the
type checker holds it to.

Members a request may omit, or an answer may leave out, are in the ``total=False`` half of a
pair (``_FooRequired`` holds the rest): the pattern works on every Python the package supports.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Literal, Optional, TypedDict, Union

# JSON numbers as the server writes them; a whole float may come as an integer literal.
Number = float
# A number, or an expression in the names a definition declares.
Entry = Union[float, str]

# --------------------------------------------------------------------------------------------
# Requests


class _MethodOptionsRequired(TypedDict):
    id: str


class MethodOptions(_MethodOptionsRequired, total=False):
    """A method with options, e.g. ``{"id": "modin_rks", "inner": "rk4"}``."""

    inner: str
    base: str
    processor: str
    tolerance: float


MethodSpec = Union[str, MethodOptions]


class GammaDamping(TypedDict):
    """Conformal damping p' = … − 2γp."""

    gamma: Entry


class RayleighDamping(TypedDict):
    """Rayleigh damping p' = … − ε D(q) q̇."""

    epsilon: Entry
    matrix: List[List[Entry]]


DampingEntry = Union[GammaDamping, RayleighDamping]
MassEntry = Union[Entry, List[Entry], List[List[Entry]]]


class _SystemDefinitionRequired(TypedDict):
    coordinates: List[str]


class SystemDefinition(_SystemDefinitionRequired, total=False):
    """A damped Hamiltonian system written as text (``POST /api/v1/systems``)."""

    momenta: List[str]
    mass: MassEntry
    potential: str
    hamiltonian: str
    damping: DampingEntry
    parameters: Dict[str, float]
    invariants: Dict[str, str]
    positions: List[List[Entry]]
    q0: List[float]
    p0: List[float]
    name: str


SystemRequest = Union[str, SystemDefinition]
ParamValue = Union[float, str, List[float]]


class OutputOptions(TypedDict, total=False):
    """Sampling of a simulation."""

    every: int


CrossingDirection = Literal["up", "down", "both"]
"""Which crossings of a surface S = 0 count: ``up`` (S from negative to non-negative), ``down``,
``both``."""


class SectionRequest(TypedDict, total=False):
    """A Poincaré section of each run: the crossings of the surface ``where`` = 0 in
    ``direction`` (default ``up``), or a stroboscopic section, the states at the times
    t ≡ ``phase`` (mod ``period``); at most ``max_points`` points per run (default 10⁴)."""

    where: str
    direction: CrossingDirection
    max_points: int
    period: float
    phase: float


Indicator = Literal["lyapunov", "megno", "fli", "sali", "gali"]
"""A chaos indicator a run can report: ``lyapunov`` (the finite-time Lyapunov spectrum),
``megno`` (MEGNO Y and its running mean ⟨Y⟩), ``fli``, ``sali``, ``gali``."""

Statistic = Literal["lyapunov_max", "megno", "megno_mean", "fli", "sali", "gali"]
"""A number the indicators report, by the name answers and thresholds give it."""


# ``stop_when`` is one object: an event surface (``where``, with ``direction`` and ``count``),
# thresholds of the indicators, or both, with at least one member, and ``direction``/``count``
# only beside ``where``. A TypedDict cannot say "at least one of", so the request is a union: an
# event (thresholds optional), or thresholds alone, each variant requiring one threshold and
# allowing the ones after it (any non-empty set of thresholds is the variant of its first).


class _AfterSali(TypedDict, total=False):
    gali: float


class _AfterFli(_AfterSali, total=False):
    sali: float


class _AfterMegnoMean(_AfterFli, total=False):
    fli: float


class _AfterMegno(_AfterMegnoMean, total=False):
    megno_mean: float


class _AfterLyapunovMax(_AfterMegno, total=False):
    megno: float


class Thresholds(_AfterLyapunovMax, total=False):
    """Every threshold, each optional: a rising indicator (``lyapunov_max``, ``megno``,
    ``megno_mean``, ``fli``) reaching its value from below, or a falling one (``sali``,
    ``gali``) falling to it, ends the run (its stop reason is then ``indicator``)."""

    lyapunov_max: float


class _StopWhenEventRequired(Thresholds):
    where: str


class StopWhenEvent(_StopWhenEventRequired, total=False):
    """An event that ends each run: the ``count``-th crossing (default 1) of ``where`` = 0 in
    ``direction`` (default ``both``), with thresholds besides (whichever comes first)."""

    direction: CrossingDirection
    count: int


class StopAtLyapunovMax(_AfterLyapunovMax):
    lyapunov_max: float


class StopAtMegno(_AfterMegno):
    megno: float


class StopAtMegnoMean(_AfterMegnoMean):
    megno_mean: float


class StopAtFli(_AfterFli):
    fli: float


class StopAtSali(_AfterSali):
    sali: float


class StopAtGali(TypedDict):
    gali: float


StopWhenThresholds = Union[StopAtLyapunovMax, StopAtMegno, StopAtMegnoMean, StopAtFli, StopAtSali, StopAtGali]
"""Thresholds alone (at least one): what a sweep's ``stop_when`` takes."""

StopWhenRequest = Union[StopWhenEvent, StopWhenThresholds]
"""What ends each run before ``t_end``: an event, thresholds, or both."""


class EnergySurfaceRequest(TypedDict):
    """A sweep's initial states on the energy surface H = ``energy``: per cell, the initial
    momentum ``solve_for`` (``p0[i]``) is solved for."""

    energy: float
    solve_for: str


class EnergyRequest(TypedDict):
    """An energy level: the initial ``momentum`` (one of the system's momenta) is solved for,
    non-negative, so that H(q0, p0) = ``value``."""

    value: float
    momentum: str


class _SimulateRequestRequired(TypedDict):
    system: SystemRequest
    h: float
    t_end: float


class SimulateRequest(_SimulateRequestRequired, total=False):
    """``POST /api/v1/simulate`` (and ``POST /api/v1/recordings``)."""

    methods: List[MethodSpec]
    params: Dict[str, ParamValue]
    chart: str
    initial_coordinates: str
    q0: List[float]
    p0: List[float]
    output: OutputOptions
    compare_to_reference: bool
    jacobian_defect: bool
    section: SectionRequest
    stop_when: StopWhenRequest
    energy: EnergyRequest
    indicators: List[Indicator]
    deviations: int
    qr_every: int


class _AxisRequestRequired(TypedDict):
    name: str
    min: float
    max: float
    n: int


class AxisRequest(_AxisRequestRequired, total=False):
    """One axis of a sweep."""

    scale: str


class _SweepRequestRequired(TypedDict):
    system: SystemRequest
    methods: List[MethodSpec]
    t_end: float
    axes: List[AxisRequest]


class SweepRequest(_SweepRequestRequired, total=False):
    """``POST /api/v1/studies/sweep``."""

    h: float
    charts: List[str]
    params: Dict[str, ParamValue]
    q0: List[float]
    p0: List[float]
    every: int
    energy_reference: str
    initial_coordinates: str
    indicators: List[Indicator]
    deviations: int
    qr_every: int
    stop_when: StopWhenThresholds
    energy_surface: EnergySurfaceRequest
    section: SectionRequest


class AxisSpec(TypedDict):
    """An evenly spaced axis: the k-th of ``n`` points is min + (max − min)·k/(n − 1)."""

    min: float
    max: float
    n: int


class StabilityRequest(TypedDict):
    """``POST /api/v1/stability``."""

    omega: float
    gamma: AxisSpec
    h: AxisSpec
    methods: List[MethodSpec]


class PointRequest(TypedDict):
    """``POST /api/v1/stability/point``."""

    omega: float
    gamma: float
    h: float
    method: MethodSpec


class EnergyMapRequest(TypedDict, total=False):
    """``POST /api/v1/studies/energy-map``: every member has a default."""

    nx: int
    ny: int
    x: List[float]
    y: List[float]
    h: float
    t_max: float
    method: MethodSpec
    params: Dict[str, float]


class _ReferenceRunRequired(TypedDict):
    method: MethodSpec


class ReferenceRun(_ReferenceRunRequired, total=False):
    """A study's reference: a method with one step size, or the adaptive one with a tolerance."""

    h: float
    tolerance: float


class _ConvergenceRequestRequired(TypedDict):
    system: SystemRequest
    methods: List[MethodSpec]
    h: List[float]
    t_end: float


class ConvergenceRequest(_ConvergenceRequestRequired, total=False):
    """``POST /api/v1/studies/convergence``."""

    params: Dict[str, ParamValue]
    chart: str
    charts: List[str]
    initial_coordinates: str
    q0: List[float]
    p0: List[float]
    samples: int
    reference: ReferenceRun


class _RunSpecRequired(TypedDict):
    method: MethodSpec


class RunSpec(_RunSpecRequired, total=False):
    """One method of a work–precision study, with its step sizes or tolerances."""

    h: List[float]
    tolerance: List[float]


class _WorkPrecisionRequestRequired(TypedDict):
    system: SystemRequest
    t_end: float
    runs: List[RunSpec]


class WorkPrecisionRequest(_WorkPrecisionRequestRequired, total=False):
    """``POST /api/v1/studies/work-precision``."""

    params: Dict[str, ParamValue]
    q0: List[float]
    p0: List[float]
    samples: int
    reference: ReferenceRun


# --------------------------------------------------------------------------------------------
# Errors


class _ErrorDetailRequired(TypedDict):
    code: str
    message: str


class ErrorDetail(_ErrorDetailRequired, total=False):
    """What went wrong: ``code`` and ``field`` for machines, ``message`` for people."""

    field: Optional[str]
    position: Optional[int]


class ErrorBody(TypedDict):
    """The body of every error answer."""

    error: ErrorDetail


# --------------------------------------------------------------------------------------------
# Catalogues


class Health(TypedDict):
    """``GET /healthz``."""

    status: str
    version: str
    runs_in_progress: int
    max_concurrent: int


class ChartEntry(TypedDict):
    """A coordinate chart a system is offered in."""

    id: str
    coordinates: List[str]
    separable: bool
    description: str


class NumberParam(TypedDict):
    """A number parameter with its range."""

    name: str
    description: str
    kind: Literal["number"]
    default: float
    min: float
    max: float
    min_exclusive: bool


class ChoiceParam(TypedDict):
    """A parameter that takes one of a few names."""

    name: str
    description: str
    kind: Literal["choice"]
    default: str
    options: List[str]


class NumberListParam(TypedDict):
    """A parameter that takes a list of numbers (the N bodies' masses)."""

    name: str
    description: str
    kind: Literal["number_list"]
    default: List[float]
    min: float
    max: float
    max_len: int


ParamEntry = Union[NumberParam, ChoiceParam, NumberListParam]


class SystemEntry(TypedDict):
    """A catalogue entry."""

    id: str
    name: str
    description: str
    degrees_of_freedom: int
    charts: List[ChartEntry]
    params: List[ParamEntry]
    q0: List[float]
    p0: List[float]
    invariants: List[str]
    exact_solution: bool
    conformal_damping: bool


class Facts(TypedDict):
    """What a definition is, derived from it."""

    dimension: int
    separable: bool
    damping: str
    methods: List[str]


class StoredSystem(SystemEntry):
    """A stored definition with what the service derived from it (the definition as stored is
    passed on to the caller unread)."""

    definition: Dict[str, object]
    facts: Facts
    created_unix_ms: int


class CitationEntry(TypedDict):
    """Where a method comes from."""

    paper: str
    equation: str


class MethodEntry(TypedDict):
    """A method's catalogue entry."""

    id: str
    name: str
    order: int
    kind: str
    symplectic: bool
    conformal_symplectic: bool
    symmetric: bool
    requirements: List[str]
    reference: CitationEntry
    group: str
    options: List[str]


# --------------------------------------------------------------------------------------------
# Simulations


class SystemSummary(TypedDict):
    """The system a run used, with every parameter resolved."""

    id: str
    chart: str
    params: Dict[str, ParamValue]
    q0: List[float]
    p0: List[float]


class ScheduleSummary(TypedDict):
    """The sampling of a simulation."""

    h: float
    steps: int
    every: int
    t_end: float
    samples_per_method: int


class DivergedAt(TypedDict):
    """The first step whose state is not finite."""

    step: int
    t: float


class DriftPoint(TypedDict):
    """One point of the dissipation drift (paper 003 eq. 4.4)."""

    t: float
    d: float


class Stats(TypedDict):
    """Run statistics."""

    steps: int
    force_evaluations: int
    wall_time_ms: float


class StopFinished(TypedDict):
    reason: Literal["finished"]


class StopDiverged(TypedDict):
    reason: Literal["diverged"]
    step: int
    t: float


class StopCancelled(TypedDict):
    reason: Literal["cancelled", "time_limit"]
    step: int


class StopFailed(TypedDict):
    reason: Literal["failed"]
    step: int
    t: float
    message: str


class StopEvent(TypedDict):
    """The ``stop_when`` surface's ``count``-th crossing, at ``t``, ended the run after ``step``."""

    reason: Literal["event"]
    step: int
    t: float


class StopIndicator(TypedDict):
    """A ``stop_when`` threshold: ``indicator`` reached ``threshold`` (its ``value`` there) at
    ``step``, ``t``, the run's last sample."""

    reason: Literal["indicator"]
    step: int
    t: float
    indicator: Statistic
    value: float
    threshold: float


Stop = Union[StopFinished, StopDiverged, StopCancelled, StopFailed, StopEvent, StopIndicator]

EnergyReference = Literal["exact", "initial", "reference"]
"""What ``energy_error`` is measured against: the exact solution, H₀ (nothing damps or drives the
system), or the adaptive reference run."""


class _ColumnsRequired(TypedDict):
    t: List[float]
    q: List[List[float]]
    p: List[List[float]]
    energy: List[Optional[float]]
    invariants: Dict[str, List[Optional[float]]]


class Columns(_ColumnsRequired, total=False):
    """Sample columns: one entry per sample in every column. An energy, energy error or
    invariant that is not finite (a run about to diverge) comes as ``null``."""

    energy_error: Optional[List[Optional[float]]]
    cartesian_q: Optional[List[List[float]]]
    cartesian_p: Optional[List[List[float]]]
    bodies: Optional[List[List[float]]]
    jacobian_defect: Optional[List[Optional[float]]]
    lyapunov: Optional[List[List[float]]]
    megno: Optional[List[float]]
    megno_mean: Optional[List[float]]
    fli: Optional[List[float]]
    sali: Optional[List[float]]
    gali: Optional[List[float]]


class _CrossingColumnsRequired(TypedDict):
    t: List[float]
    q: List[List[float]]
    p: List[List[float]]
    energy: List[Optional[float]]


class CrossingColumns(_CrossingColumnsRequired, total=False):
    """Located crossings of a surface (a section's points, or an event's crossings): one entry
    per point in every column; ``cartesian_q`` when the chart is not Cartesian."""

    cartesian_q: Optional[List[List[float]]]


class _SectionSummaryRequired(TypedDict):
    points: int
    truncated: bool


class SectionSummary(_SectionSummaryRequired, total=False):
    """How a run's section went: points located, whether ``max_points`` cut it short, the range
    of S over the run's steps (expressions only), crossings that could not be located, and why
    there are no points when there are none."""

    surface_range: Optional[List[float]]
    unlocated: Optional[int]
    note: Optional[str]


class _SurfaceInfoRequired(TypedDict):
    coordinates: List[str]
    momenta: List[str]


class SurfaceInfo(_SurfaceInfoRequired, total=False):
    """A section or an event as the server resolved it, with the names of its points' positions
    and momenta."""

    where: Optional[str]
    direction: Optional[CrossingDirection]
    max_points: Optional[int]
    count: Optional[int]
    period: Optional[float]
    phase: Optional[float]


class IndicatorValues(TypedDict, total=False):
    """The indicators at a run's last sample, under the names of the sample columns (``None``
    for those not asked for)."""

    lyapunov: Optional[List[float]]
    megno: Optional[float]
    megno_mean: Optional[float]
    fli: Optional[float]
    sali: Optional[float]
    gali: Optional[float]


class _RunOutcomeRequired(TypedDict):
    stats: Stats
    stop: Stop


class RunOutcome(_RunOutcomeRequired, total=False):
    """How one method's run ended: what the document and the stream's summary both report."""

    dissipation_drift: Optional[List[DriftPoint]]
    diverged_at: Optional[DivergedAt]
    section_summary: Optional[SectionSummary]
    indicators: Optional[IndicatorValues]


class _RunDocumentRequired(Columns, RunOutcome):
    method: str


class RunDocument(_RunDocumentRequired, total=False):
    """One method's run in a simulation's answer, with its section's points and the crossings
    of its ``stop_when`` surface when asked for."""

    section: Optional[CrossingColumns]
    events: Optional[CrossingColumns]


class _SimulationDocumentRequired(TypedDict):
    system: SystemSummary
    schedule: ScheduleSummary
    invariants: List[str]
    runs: List[RunDocument]


class SimulationDocument(_SimulationDocumentRequired, total=False):
    """The answer to ``POST /api/v1/simulate``."""

    energy_reference: Optional[EnergyReference]
    section: Optional[SurfaceInfo]
    stop_when: Optional[SurfaceInfo]


class _HeaderLineRequired(TypedDict):
    type: Literal["header"]
    system: SystemSummary
    schedule: ScheduleSummary
    methods: List[str]
    invariants: List[str]


class HeaderLine(_HeaderLineRequired, total=False):
    """The first line of a simulation's stream (``indicators`` the chunks carry, with
    ``deviations`` vectors: the length of each ``lyapunov`` entry)."""

    energy_reference: Optional[EnergyReference]
    section: Optional[SurfaceInfo]
    stop_when: Optional[SurfaceInfo]
    indicators: Optional[List[Indicator]]
    deviations: Optional[int]


class SamplesLine(Columns):
    """A chunk of one method's samples, from sample ``offset`` on."""

    type: Literal["samples"]
    method: int
    offset: int


SurfaceName = Literal["section", "stop_when"]
"""Whose crossings a ``crossings`` line carries: the section's or the ``stop_when`` event's."""


class CrossingsLine(CrossingColumns):
    """A chunk of one method's located crossings of ``surface``, from point ``offset`` on."""

    type: Literal["crossings"]
    method: int
    surface: SurfaceName
    offset: int


class SummaryLine(RunOutcome):
    """How one method's run ended, after its last chunk."""

    type: Literal["summary"]
    method: int
    label: str
    samples: int


class _ErrorLineRequired(TypedDict):
    type: Literal["error"]
    error: ErrorDetail


class ErrorLine(_ErrorLineRequired, total=False):
    """A failure inside a stream."""

    method: Optional[int]


class EndLine(TypedDict):
    """The last line of every stream."""

    type: Literal["end"]


StreamLine = Union[HeaderLine, SamplesLine, CrossingsLine, SummaryLine, ErrorLine, EndLine]


class StudyErrorLine(TypedDict):
    """A failure inside a study's stream."""

    type: Literal["error"]
    error: ErrorDetail


class _RecordedRunRequired(Columns):
    method: str
    last_step: int


class RecordedRun(_RecordedRunRequired, total=False):
    """One method's rows read back from a recording."""

    force_evaluations: Optional[int]
    dissipation_drift: Optional[List[DriftPoint]]


class RecordedDocument(TypedDict):
    """A stored recording's samples (``GET /api/v1/recordings/{id}/samples``)."""

    system: SystemSummary
    schedule: ScheduleSummary
    invariants: List[str]
    runs: List[RecordedRun]


# --------------------------------------------------------------------------------------------
# Recordings


class RecordingCreated(TypedDict):
    """The answer to a stored recording."""

    id: str
    url: str
    bytes: int


class SpecSummary(TypedDict):
    """What a recording holds, in brief."""

    system: str
    methods: List[str]
    h: float
    t_end: float
    steps: int
    every: int
    samples_per_method: int


class _RecordingEntryRequired(TypedDict):
    id: str
    bytes: int
    created: str


class RecordingEntry(_RecordingEntryRequired, total=False):
    """One stored recording."""

    created_unix_ms: Optional[int]
    origin: Optional[str]
    application_id: Optional[str]
    spec: Optional[SpecSummary]


# --------------------------------------------------------------------------------------------
# Studies


class StudyOutcome(TypedDict):
    """How much work a sweep or an energy map did, and whether a time limit cut it short."""

    steps: int
    wall_ms: float
    stop: Literal["finished", "time_limit"]
    unfinished_cells: List[int]


class ProgressLine(TypedDict):
    """Progress of a sweep or an energy map."""

    type: Literal["progress"]
    done: int
    total: int


class AxisDocument(TypedDict):
    """One axis of a sweep, with its points."""

    name: str
    min: float
    max: float
    n: int
    scale: str
    values: List[float]


class ChaosColumns(TypedDict, total=False):
    """A sweep's chaos maps: each indicator's last value per cell (``None`` where not asked for
    or the run did not start), and the time a threshold stopped a cell's run (``None``: it ran
    to the end)."""

    lyapunov_max: List[Optional[float]]
    megno: List[Optional[float]]
    megno_mean: List[Optional[float]]
    fli: List[Optional[float]]
    sali: List[Optional[float]]
    gali: List[Optional[float]]
    stopped_at: List[Optional[float]]


class CellSection(TypedDict):
    """One run's section in one cell of a sweep: its points (up to ``max_points``), whether
    later crossings went uncollected, and the crossings that could not be located."""

    points: CrossingColumns
    truncated: bool
    unlocated: int


class SectionColumns(TypedDict, total=False):
    """Per cell, a run's section (``None`` where the run did not start), with ``section``."""

    sections: Optional[List[Optional[CellSection]]]


class RunColumns(ChaosColumns, SectionColumns):
    """One run's metrics over a sweep's cells, in cell order (the first axis runs fastest)."""

    method: str
    chart: str
    energy_error_final: List[Optional[float]]
    energy_error_max: List[Optional[float]]
    energy_error_l2: List[Optional[float]]
    invariant_drift: Dict[str, List[Optional[float]]]
    diverged_at: List[Optional[float]]
    final_q: List[List[float]]
    final_p: List[List[float]]
    steps: List[int]
    force_evaluations: List[int]
    errors: List[Optional[str]]


class SweepDocument(StudyOutcome):
    """A sweep's result."""

    system: str
    axes: List[AxisDocument]
    cells: int
    energy_reference: str
    invariants: List[str]
    runs: List[RunColumns]
    force_evaluations: int
    digest: str


class SweepResultLine(SweepDocument):
    type: Literal["result"]


SweepLine = Union[ProgressLine, SweepResultLine, StudyErrorLine, EndLine]


class Preset(TypedDict):
    """A ready-made sweep."""

    id: str
    title: str
    request: Dict[str, object]


class _MapDocumentRequired(TypedDict):
    method: str
    spectral_radius: List[List[Optional[float]]]
    stable: List[List[bool]]


class MapDocument(_MapDocumentRequired, total=False):
    """The stability map of one method: h rows × γ columns."""

    analytic: Optional[List[List[bool]]]
    printed: Optional[List[List[bool]]]
    disagreements: Optional[int]
    printed_disagreements: Optional[int]


class StabilityDocument(TypedDict):
    """The answer to ``POST /api/v1/stability``."""

    omega: float
    gamma: AxisSpec
    h: AxisSpec
    maps: List[MapDocument]
    stop: Literal["finished", "time_limit"]


class EigenvalueDocument(TypedDict, total=False):
    """A complex eigenvalue (``null`` parts are not finite)."""

    re: Optional[float]
    im: Optional[float]


class _SpectrumDocumentRequired(TypedDict):
    matrix: List[List[Optional[float]]]
    eigenvalues: List[EigenvalueDocument]


class SpectrumDocument(_SpectrumDocumentRequired, total=False):
    """A 2×2 one-step matrix and its spectral data."""

    trace: Optional[float]
    det: Optional[float]
    spectral_radius: Optional[float]


class _PointAnalysisRequired(TypedDict):
    method: SpectrumDocument
    exact: SpectrumDocument
    stable: bool


class PointAnalysisDocument(_PointAnalysisRequired, total=False):
    """A method's one-step matrix and the exact flow's."""

    half_trace_error: Optional[float]


class AnalyticVerdicts(TypedDict):
    """The analytic stability verdicts of cimp, csv1 and csv2."""

    corrected: bool
    printed: bool


class _PointDocumentRequired(TypedDict):
    method: str
    omega: float
    gamma: float
    h: float
    analysis: PointAnalysisDocument


class PointDocument(_PointDocumentRequired, total=False):
    """The answer to ``POST /api/v1/stability/point``."""

    analytic: Optional[AnalyticVerdicts]


class MapParams(TypedDict):
    """The planar pendulum's parameters of an energy map."""

    m: float
    k: float
    l: float  # noqa: E741 (the spring's rest length, as the server names it)
    g: float


class MapSummary(TypedDict):
    """Counts over an energy map."""

    cells: int
    cartesian_better: int
    polar_better: int
    cartesian_diverged: int
    polar_diverged: int
    predicted_divergent: int
    diverged_outside_prediction: int


class EnergyMapDocument(StudyOutcome):
    """An energy-error map; per-cell arrays are row-major, entry j·nx + i at (xs[i], ys[j])."""

    method: str
    params: MapParams
    h: float
    t_max: float
    steps_per_run: int
    xs: List[float]
    ys: List[float]
    energy: List[float]
    epsilon_cartesian: List[Optional[float]]
    epsilon_polar: List[Optional[float]]
    difference: List[Optional[float]]
    polar_diverged_at: List[Optional[float]]
    cartesian_diverged_at: List[Optional[float]]
    predicted_divergent: List[bool]
    boundary: List[List[float]]
    summary: MapSummary


class MapResultLine(EnergyMapDocument):
    type: Literal["result"]


MapLine = Union[ProgressLine, MapResultLine, StudyErrorLine, EndLine]


class ReferenceLine(TypedDict):
    """A study's reference run is done."""

    type: Literal["reference"]
    reference: str
    reference_ms: float
    total: int


class _ConvergencePointRequired(TypedDict):
    series: int
    method: str
    chart: str
    h: float
    steps: int
    stop: str


class ConvergencePoint(_ConvergencePointRequired, total=False):
    """One setting of a convergence study and its errors at t_end."""

    state_error: Optional[float]
    energy_error: Optional[float]
    max_energy_error: Optional[float]


class _OrderFitRequired(TypedDict):
    points: int


class OrderFit(_OrderFitRequired, total=False):
    """log₁₀ error ≈ intercept + order·log₁₀ h."""

    order: Optional[float]
    intercept: Optional[float]


class ConvergenceSeries(TypedDict):
    """One method in one chart, with its fitted orders."""

    method: str
    chart: str
    label: str
    state: OrderFit
    energy: OrderFit
    max_energy: OrderFit


class ConvergenceDocument(TypedDict):
    """The answer to a convergence study."""

    system: SystemSummary
    charts: List[str]
    t_end: float
    samples: int
    reference: str
    reference_ms: float
    points: List[ConvergencePoint]
    series: List[ConvergenceSeries]


class ConvergencePointLine(TypedDict):
    type: Literal["point"]
    done: int
    total: int
    point: ConvergencePoint


class ConvergenceResultLine(ConvergenceDocument):
    type: Literal["result"]


ConvergenceLine = Union[ReferenceLine, ConvergencePointLine, ConvergenceResultLine, StudyErrorLine, EndLine]


class _WorkPrecisionPointRequired(TypedDict):
    run: int
    method: str
    wall_ms: float
    steps: int
    force_evaluations: int
    invariant_drift: Dict[str, float]
    stop: str


class WorkPrecisionPoint(_WorkPrecisionPointRequired, total=False):
    """One setting of a work–precision study."""

    h: Optional[float]
    tolerance: Optional[float]
    max_energy_error: Optional[float]
    final_state_error: Optional[float]


class _WorkPrecisionFitRequired(TypedDict):
    run: int
    method: str
    points: int


class WorkPrecisionFit(_WorkPrecisionFitRequired, total=False):
    """log₁₀(ms) ≈ intercept + slope·log₁₀(max energy error)."""

    slope: Optional[float]
    intercept: Optional[float]


class WorkPrecisionDocument(TypedDict):
    """The answer to a work–precision study."""

    system: SystemSummary
    t_end: float
    samples: int
    reference: str
    reference_ms: float
    points: List[WorkPrecisionPoint]
    fits: List[WorkPrecisionFit]


class WorkPrecisionPointLine(TypedDict):
    type: Literal["point"]
    done: int
    total: int
    point: WorkPrecisionPoint


class WorkPrecisionResultLine(WorkPrecisionDocument):
    type: Literal["result"]


StudyLine = Union[ReferenceLine, WorkPrecisionPointLine, WorkPrecisionResultLine, StudyErrorLine, EndLine]


# --------------------------------------------------------------------------------------------
# Routes

JSON = "application/json"
NDJSON = "application/x-ndjson"
RRD = "application/octet-stream"


@dataclass(frozen=True)
class Route:
    """One operation the client performs.

    ``answers`` maps each media type the client asks for to the type it reads (``bytes`` for a
    recording); ``query`` lists the query values it sends; ``request`` is the body's type.
    """

    method: Literal["GET", "POST", "DELETE"]
    path: str
    answers: Dict[str, object] = field(default_factory=dict)
    request: Optional[object] = None
    request_media: str = JSON
    query: Dict[str, List[str]] = field(default_factory=dict)
    status: int = 200

    def url(self, **params: str) -> str:
        """The path with its ``{name}`` segments filled in (the values quoted by the caller)."""
        return self.path.format(**params)


ROUTES: Dict[str, Route] = {
    "health": Route("GET", "/healthz", {JSON: Health}),
    "list_systems": Route("GET", "/api/v1/systems", {JSON: List[SystemEntry]}),
    "get_system": Route("GET", "/api/v1/systems/{id}", {JSON: SystemEntry}),
    "create_system": Route("POST", "/api/v1/systems", {JSON: StoredSystem}, SystemDefinition),
    "delete_system": Route("DELETE", "/api/v1/systems/{id}", status=204),
    "list_methods": Route("GET", "/api/v1/methods", {JSON: List[MethodEntry]}),
    "simulate": Route(
        "POST",
        "/api/v1/simulate",
        {JSON: SimulationDocument, NDJSON: StreamLine, RRD: bytes},
        SimulateRequest,
        query={"format": ["rrd"]},
    ),
    "create_recording": Route(
        "POST", "/api/v1/recordings", {JSON: RecordingCreated}, SimulateRequest, status=201
    ),
    "upload_recording": Route(
        "POST", "/api/v1/recordings", {JSON: RecordingCreated}, bytes, request_media=RRD, status=201
    ),
    "list_recordings": Route("GET", "/api/v1/recordings", {JSON: List[RecordingEntry]}),
    "get_recording": Route("GET", "/api/v1/recordings/{id}", {RRD: bytes}),
    "recording_samples": Route("GET", "/api/v1/recordings/{id}/samples", {JSON: RecordedDocument}),
    "delete_recording": Route("DELETE", "/api/v1/recordings/{id}", status=204),
    "stability_map": Route(
        "POST",
        "/api/v1/stability",
        {JSON: StabilityDocument, RRD: bytes},
        StabilityRequest,
        query={"format": ["rrd"]},
    ),
    "stability_point": Route("POST", "/api/v1/stability/point", {JSON: PointDocument}, PointRequest),
    "sweep": Route(
        "POST",
        "/api/v1/studies/sweep",
        {NDJSON: SweepLine, RRD: bytes},
        SweepRequest,
        query={"format": ["rrd"]},
    ),
    "sweep_presets": Route("GET", "/api/v1/studies/sweep/presets", {JSON: List[Preset]}),
    "energy_map": Route(
        "POST",
        "/api/v1/studies/energy-map",
        {NDJSON: MapLine, RRD: bytes},
        EnergyMapRequest,
        query={"format": ["rrd"]},
    ),
    "convergence": Route(
        "POST", "/api/v1/studies/convergence", {NDJSON: ConvergenceLine}, ConvergenceRequest
    ),
    "work_precision": Route(
        "POST",
        "/api/v1/studies/work-precision",
        {NDJSON: StudyLine, RRD: bytes},
        WorkPrecisionRequest,
        query={"format": ["rrd"]},
    ),
}
