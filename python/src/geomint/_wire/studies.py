"""The studies' documents and stream lines: stability maps, energy maps, sweeps, convergence and
work–precision.
"""

from __future__ import annotations

from typing import Dict, List, Literal, Optional, TypedDict, Union

from .requests import AxisSpec
from .answers import CrossingColumns, EndLine, StudyErrorLine, SystemSummary


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
    energy: List[Optional[float]]
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
