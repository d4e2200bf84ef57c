"""Basin maps: the body of ``POST /api/v1/studies/basins`` and its document and stream lines."""

from __future__ import annotations

from typing import Dict, List, Literal, Optional, TypedDict, Union

from .requests import (
    AxisRequest,
    CrossingDirection,
    EnergySurfaceRequest,
    MethodSpec,
    ParamValue,
    SystemRequest,
)
from .answers import EndLine, StudyErrorLine
from .studies import AxisDocument, ProgressLine


class _ExitRequestRequired(TypedDict):
    name: str
    where: str


class ExitRequest(_ExitRequestRequired, total=False):
    """An exit of an open system: the surface S = 0 (``where``, in the section language),
    crossed in ``direction`` (default ``both``), and its ``name`` for the legend."""

    direction: CrossingDirection


class RecognitionRequest(TypedDict, total=False):
    """How a basin map recognises attractors: a driven system's driving ``period`` (its
    stroboscopic map), the longest period looked for (``max_period``, in driving periods), the
    ``tolerance`` of a recurrence, the ``escape_radius`` beyond which an orbit diverged and the
    coordinates that are ``angles`` (compared modulo 2π)."""

    period: float
    max_period: int
    tolerance: float
    escape_radius: float
    angles: List[str]


class AttractorRequest(TypedDict):
    """An attractor known in advance: an orbit (a driven system's stroboscopic point) within
    ``radius`` of one of its ``points`` (each q then p) in every component ends up there."""

    name: str
    points: List[List[float]]
    radius: float


class _BasinsRequestRequired(TypedDict):
    system: SystemRequest
    methods: List[MethodSpec]
    h: float
    t_end: float
    axes: List[AxisRequest]


class BasinsRequest(_BasinsRequestRequired, total=False):
    """``POST /api/v1/studies/basins``."""

    params: Dict[str, ParamValue]
    chart: str
    initial_coordinates: str
    q0: List[float]
    p0: List[float]
    energy_surface: EnergySurfaceRequest
    exits: List[ExitRequest]
    recognition: RecognitionRequest
    attractors: List[AttractorRequest]


class RunLabel(TypedDict):
    """A method in a chart."""

    method: str
    chart: str


AttractorKind = Literal["equilibrium", "well", "periodic", "exit", "diverged", "stayed", "given"]


class _AttractorEntryRequired(TypedDict):
    label: int
    kind: AttractorKind
    name: str
    cells: int


class AttractorEntry(_AttractorEntryRequired, total=False):
    """One label's entry (the schema ``Attractor``). ``equilibrium`` is the critical point of an
    equilibrium or a well (``q``, ``energy``, ``hessian_eigenvalues``; the schema declares only
    an object, so the client reads its members by hand); ``period`` and ``points`` (each
    stroboscopic point's q and p) those of a periodic orbit; ``points`` and ``radius`` those of
    an attractor the request gave."""

    equilibrium: Optional[Dict[str, object]]
    period: Optional[int]
    points: Optional[List[List[float]]]
    radius: Optional[float]


class DecidedBy(TypedDict):
    """How many cells each criterion decided."""

    energy: int
    exit: int
    recurrence: int
    proximity: int
    divergence: int
    t_end: int
    undecided: int


class UndecidedCell(TypedDict):
    """A cell without a label, and why."""

    cell: int
    reason: str


class UncertainFraction(TypedDict):
    """The fraction f(ε) of ε-uncertain cells at ε cells (the schema ``Uncertain``)."""

    epsilon_cells: int
    fraction: float


class WadaShare(TypedDict):
    """W_k of the Wada test by merging for label k (the schema ``WadaShare``)."""

    label: int
    share: float


class _BasinRunColumnsRequired(TypedDict):
    label: RunLabel
    labels: List[int]
    decided_at: List[Optional[float]]
    attractors: List[AttractorEntry]
    fractions: List[float]
    undecided_fraction: float
    undecided: List[UndecidedCell]
    decided_by: DecidedBy
    steps: int
    boundary_boxes: int
    boxes: int
    uncertain_fractions: List[UncertainFraction]
    wada: List[WadaShare]
    not_started: int


class BasinRunColumns(_BasinRunColumnsRequired, total=False):
    """One run's map (the schema ``BasinRun``), per-cell columns in cell order (the first axis
    runs fastest), with its metrics (``None`` where they are not defined)."""

    largest_energy_margin: Optional[float]
    basin_entropy: Optional[float]
    boundary_basin_entropy: Optional[float]
    uncertainty_exponent: Optional[float]


class _BasinsDocumentRequired(TypedDict):
    system: str
    axes: List[AxisDocument]
    cells: int
    exits: List[str]
    runs: List[BasinRunColumns]
    digest: str
    wall_ms: float
    stop: Literal["finished", "time_limit"]
    unfinished_cells: List[int]


class BasinsDocument(_BasinsDocumentRequired, total=False):
    """A basin map. ``equilibria`` (the critical points of V the search found, minima first;
    ``None`` for a driven system) are objects the schema does not describe further."""

    equilibria: Optional[List[Dict[str, object]]]
    lowest_saddle_energy: Optional[float]


class BasinsResultLine(BasinsDocument):
    type: Literal["result"]


BasinsLine = Union[ProgressLine, BasinsResultLine, StudyErrorLine, EndLine]
