"""What the server answers outside the studies: errors, the catalogues, simulations (their
documents and stream lines) and recordings.
"""

from __future__ import annotations

from typing import Dict, List, Literal, Optional, TypedDict, Union

from .requests import CrossingDirection, Indicator, ParamValue, Statistic


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


class JobOrigin(TypedDict):
    """The job a recording is the result of."""

    id: str
    study: str


class RecordingEntry(_RecordingEntryRequired, total=False):
    """One stored recording."""

    created_unix_ms: Optional[int]
    origin: Optional[str]
    application_id: Optional[str]
    spec: Optional[SpecSummary]
    job: Optional[JobOrigin]
