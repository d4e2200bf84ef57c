"""The bodies the client sends: simulations, sweeps, stability maps, energy maps, convergence and
work–precision studies, and system definitions.
"""

from __future__ import annotations

from typing import Dict, List, Literal, TypedDict, Union

from ._common import Entry


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
