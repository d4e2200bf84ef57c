"""A simulation's answer as numpy arrays: one :class:`Run` per method, with its section's points
and its event's crossings as :class:`Crossings`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _arrays, _optional
from ._lookup import pick
from ._arrays import FloatArray
from ._wire import (
    Columns,
    CrossingColumns,
    CrossingsLine,
    DivergedAt as DivergedAtDoc,
    DriftPoint,
    HeaderLine,
    IndicatorValues,
    ParamValue,
    RecordedDocument,
    RecordedRun,
    RunOutcome,
    SamplesLine,
    ScheduleSummary,
    SimulateRequest,
    SimulationDocument,
    Stats as StatsDoc,
    Stop as StopDoc,
    SummaryLine,
    SystemSummary,
)
from .errors import MissingError, ServerError
from .sections import Crossings, SectionSummary, Surface


@dataclass(frozen=True)
class Stop:
    """Why a run stopped: ``finished``, ``diverged``, ``cancelled``, ``time_limit``, ``failed``,
    ``event`` (the ``stop_when`` surface's ``count``-th crossing, at ``t``; the run's last
    sample is the step ``step`` past it) or ``indicator`` (a ``stop_when`` threshold: the
    statistic ``indicator``, e.g. ``megno_mean``, reached ``threshold`` with ``value`` at
    ``step``, ``t``, the run's last sample), with the step, the time and a message where the
    server gives them."""

    reason: str
    step: Optional[int] = None
    t: Optional[float] = None
    message: Optional[str] = None
    indicator: Optional[str] = None
    value: Optional[float] = None
    threshold: Optional[float] = None

    @classmethod
    def from_json(cls, doc: StopDoc) -> "Stop":
        if doc["reason"] == "finished":
            return cls("finished")
        if doc["reason"] == "diverged":
            return cls("diverged", doc["step"], doc["t"])
        if doc["reason"] == "failed":
            return cls("failed", doc["step"], doc["t"], doc["message"])
        if doc["reason"] == "event":
            return cls("event", doc["step"], doc["t"])
        if doc["reason"] == "indicator":
            return cls("indicator", doc["step"], doc["t"], indicator=doc["indicator"], value=doc["value"],
                       threshold=doc["threshold"])
        return cls(doc["reason"], doc["step"])


@dataclass(frozen=True)
class Stats:
    """Steps, force evaluations and wall time of a run (a recording holds no wall time)."""

    steps: int
    force_evaluations: Optional[int]
    wall_time_ms: Optional[float]

    @classmethod
    def from_json(cls, doc: StatsDoc) -> "Stats":
        return cls(doc["steps"], doc["force_evaluations"], doc["wall_time_ms"])


@dataclass(frozen=True)
class DivergedAt:
    """The first step whose state was not finite, and its time."""

    step: int
    t: float

    @classmethod
    def from_json(cls, doc: Optional[DivergedAtDoc]) -> Optional["DivergedAt"]:
        return None if doc is None else cls(doc["step"], doc["t"])


@dataclass(frozen=True, eq=False)
class Schedule:
    """The sampling: step size, steps, a sample every ``every`` steps, samples per method."""

    h: float
    steps: int
    every: int
    t_end: float
    samples_per_method: int

    @classmethod
    def from_json(cls, doc: ScheduleSummary) -> "Schedule":
        return cls(doc["h"], doc["steps"], doc["every"], doc["t_end"], doc["samples_per_method"])


@dataclass(frozen=True, eq=False)
class SystemState:
    """The system a run used: its id, chart, every parameter resolved, and the initial state."""

    id: str
    chart: str
    params: Mapping[str, ParamValue]
    q0: FloatArray
    p0: FloatArray

    @classmethod
    def from_json(cls, doc: SystemSummary) -> "SystemState":
        return cls(doc["id"], doc["chart"], dict(doc["params"]), _arrays.floats(doc["q0"]),
                   _arrays.floats(doc["p0"]))

    @property
    def dof(self) -> int:
        """Degrees of freedom: the length of ``q0``."""
        return int(self.q0.shape[0])


def _optional_floats(values: Optional[Sequence[Optional[float]]]) -> Optional[FloatArray]:
    return None if values is None else _arrays.floats(values)


ENERGY_ERROR_MISSING = (
    "the server measured no energy error for this run: there is one against the exact solution "
    "(a system that has it), against H at t = 0 (a system that nothing damps or drives, whose exact "
    "flow keeps H), or against an adaptive reference run when asked for (compare_to_reference=True); "
    "this system has neither of the first two (it is damped or driven, as the built-in pendulum is by "
    "default), so pass compare_to_reference=True, or look at run.energy itself"
)

INDICATORS = ("lyapunov", "megno", "fli", "sali", "gali")
"""The chaos indicators, in the order the server reports them."""

STATISTICS = ("megno", "megno_mean", "fli", "sali", "gali")
"""The indicators' per-sample columns of one number each (``lyapunov`` has k per sample)."""


@dataclass(frozen=True, eq=False)
class Indicators:
    """A run's chaos indicators at its last sample (``None``: not asked for): ``lyapunov``, the
    finite-time Lyapunov spectrum, largest first (k exponents); ``megno`` Y and its running
    mean ``megno_mean`` ⟨Y⟩ (≈ 2 on a torus, growing like λt/2 on a chaotic orbit); ``fli``;
    ``sali``; ``gali`` (GALI_k)."""

    lyapunov: Optional[FloatArray] = None
    megno: Optional[float] = None
    megno_mean: Optional[float] = None
    fli: Optional[float] = None
    sali: Optional[float] = None
    gali: Optional[float] = None

    @classmethod
    def from_json(cls, doc: Optional[IndicatorValues]) -> Optional["Indicators"]:
        if doc is None:
            return None
        spectrum = doc.get("lyapunov")
        return cls(None if spectrum is None else _arrays.floats(spectrum), doc.get("megno"),
                   doc.get("megno_mean"), doc.get("fli"), doc.get("sali"), doc.get("gali"))

    @property
    def lyapunov_max(self) -> Optional[float]:
        """The largest exponent of :attr:`lyapunov`."""
        return None if self.lyapunov is None or len(self.lyapunov) == 0 else float(self.lyapunov[0])

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Indicators):
            return NotImplemented
        same_spectrum = (self.lyapunov is None) == (other.lyapunov is None) and (
            self.lyapunov is None or other.lyapunov is None or self.lyapunov.tobytes() == other.lyapunov.tobytes())
        return same_spectrum and all(getattr(self, k) == getattr(other, k) for k in STATISTICS)

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, eq=False)
class Run:
    """One method's run: sample columns as numpy arrays (float64, the server's bits).

    ``t``, ``energy`` and ``energy_error`` have one entry per sample; ``q`` and ``p`` are
    (samples, degrees of freedom); ``invariants`` maps each invariant's name to its values.
    ``energy_error`` is there when the server measured it (against what:
    :attr:`Simulation.energy_reference`); asking for it otherwise raises
    :class:`~geomint.MissingError` (an AttributeError) saying why, and :attr:`has_energy_error`
    says which; ``cartesian_q``/``cartesian_p`` come with a
    non-Cartesian chart, ``bodies`` with a defined system (per sample, every body's position one
    after the other), ``jacobian_defect`` when asked for, ``dissipation_drift`` (``t``, ``d``)
    for 1-DOF conformally damped systems.

    With a ``section``, ``section`` holds the run's section points (:class:`Crossings`) and
    ``section_summary`` how the section went; with ``stop_when``, ``events`` holds the crossings
    of its surface, the last of which ended the run (``stop.reason == "event"``).

    With ``indicators``, the asked-for ones come per sample: ``lyapunov`` (samples, k), the
    finite-time Lyapunov spectrum, largest first; ``megno`` and ``megno_mean`` (Y and ⟨Y⟩),
    ``fli``, ``sali``, ``gali`` one value per sample; and :attr:`final` holds their values at
    the last sample (:class:`Indicators`).
    """

    method: str
    t: FloatArray
    q: FloatArray
    p: FloatArray
    energy: FloatArray
    invariants: Mapping[str, FloatArray]
    stop: Optional[Stop]
    stats: Optional[Stats]
    _energy_error: Optional[FloatArray] = field(default=None, repr=False)
    cartesian_q: Optional[FloatArray] = None
    cartesian_p: Optional[FloatArray] = None
    bodies: Optional[FloatArray] = None
    jacobian_defect: Optional[FloatArray] = None
    dissipation_drift: Optional[Tuple[FloatArray, FloatArray]] = None
    diverged_at: Optional[DivergedAt] = None
    section: Optional[Crossings] = None
    section_summary: Optional[SectionSummary] = None
    events: Optional[Crossings] = None
    lyapunov: Optional[FloatArray] = None
    megno: Optional[FloatArray] = None
    megno_mean: Optional[FloatArray] = None
    fli: Optional[FloatArray] = None
    sali: Optional[FloatArray] = None
    gali: Optional[FloatArray] = None
    final: Optional[Indicators] = None

    @property
    def samples(self) -> int:
        """The number of samples."""
        return int(self.t.shape[0])

    @property
    def energy_error(self) -> FloatArray:
        """H − H_ref per sample, H_ref as :attr:`Simulation.energy_reference` says; raises
        :class:`~geomint.MissingError` saying why when the server measured none."""
        if self._energy_error is None:
            raise MissingError("energy_error", ENERGY_ERROR_MISSING)
        return self._energy_error

    @property
    def has_energy_error(self) -> bool:
        """Whether the server measured :attr:`energy_error` for this run."""
        return self._energy_error is not None

    def __repr__(self) -> str:
        span = f"t={self.t[0]:g}…{self.t[-1]:g}" if self.samples else "no samples"
        parts = [repr(self.method), f"{self.samples} samples", span, f"dof={self.q.shape[1]}"]
        if self.stop is not None:
            parts.append(f"stop={self.stop.reason!r}")
        extras = ["energy_error"] if self.has_energy_error else []
        extras += [name for name in ("cartesian_q", "bodies", "jacobian_defect", "dissipation_drift", "section",
                                     "events") if getattr(self, name) is not None]
        extras += list(self.indicators)
        if extras:
            parts.append("with " + ", ".join(extras))
        return f"Run({', '.join(parts)})"

    @classmethod
    def _from_columns(
        cls,
        method: str,
        columns: Columns,
        dof: int,
        stop: Optional[Stop],
        stats: Optional[Stats],
        drift: Optional[List[DriftPoint]],
        diverged_at: Optional[DivergedAt],
        section: Optional[CrossingColumns] = None,
        section_summary: Optional[SectionSummary] = None,
        events: Optional[CrossingColumns] = None,
        final: Optional[Indicators] = None,
        deviations: Optional[int] = None,
    ) -> "Run":
        cartesian = columns.get("cartesian_q")
        spectrum = columns.get("lyapunov")
        if spectrum is not None and deviations is None:
            deviations = len(spectrum[0]) if spectrum else 0
        cartesian_width = len(cartesian[0]) if cartesian else 0
        bodies = columns.get("bodies")
        return cls(
            method=method,
            t=_arrays.floats(columns["t"]),
            q=_arrays.rows(columns["q"], dof),
            p=_arrays.rows(columns["p"], dof),
            energy=_arrays.floats(columns["energy"]),
            invariants={k: _arrays.floats(v) for k, v in columns["invariants"].items()},
            stop=stop,
            stats=stats,
            _energy_error=_optional_floats(columns.get("energy_error")),
            cartesian_q=_arrays.optional_rows(columns.get("cartesian_q"), cartesian_width),
            cartesian_p=_arrays.optional_rows(columns.get("cartesian_p"), cartesian_width),
            bodies=None if bodies is None else _arrays.rows(bodies, len(bodies[0]) if bodies else 0),
            jacobian_defect=_optional_floats(columns.get("jacobian_defect")),
            dissipation_drift=None if not drift else (
                _arrays.floats([d["t"] for d in drift]), _arrays.floats([d["d"] for d in drift])
            ),
            diverged_at=diverged_at,
            section=Crossings.optional(section, dof),
            section_summary=section_summary,
            events=Crossings.optional(events, dof),
            lyapunov=None if spectrum is None else _arrays.rows(spectrum, deviations or 0),
            megno=_optional_floats(columns.get("megno")),
            megno_mean=_optional_floats(columns.get("megno_mean")),
            fli=_optional_floats(columns.get("fli")),
            sali=_optional_floats(columns.get("sali")),
            gali=_optional_floats(columns.get("gali")),
            final=final,
        )

    @classmethod
    def from_outcome(
        cls,
        method: str,
        columns: Columns,
        outcome: RunOutcome,
        dof: int,
        section: Optional[CrossingColumns] = None,
        events: Optional[CrossingColumns] = None,
        deviations: Optional[int] = None,
    ) -> "Run":
        """A run from its samples and how it ended (a JSON answer's run, or a stream's chunks
        and summary), with its section's points and its event's crossings when it has them
        (``deviations``: the width of its ``lyapunov`` rows, when the stream's header gave it)."""
        return cls._from_columns(
            method, columns, dof, Stop.from_json(outcome["stop"]), Stats.from_json(outcome["stats"]),
            outcome.get("dissipation_drift"), DivergedAt.from_json(outcome.get("diverged_at")),
            section, SectionSummary.from_json(outcome.get("section_summary")), events,
            Indicators.from_json(outcome.get("indicators")), deviations,
        )

    @classmethod
    def from_recorded(cls, doc: RecordedRun, dof: int) -> "Run":
        """A run read back from a stored recording (no stop reason, no wall time)."""
        stats = Stats(doc["last_step"], doc.get("force_evaluations"), None)
        return cls._from_columns(doc["method"], doc, dof, None, stats, doc.get("dissipation_drift"), None)

    @property
    def indicators(self) -> Tuple[str, ...]:
        """The indicators this run reports per sample, in the server's order."""
        return tuple(name for name in INDICATORS if getattr(self, name) is not None)

    def columns(self) -> Dict[str, FloatArray]:
        """Every per-sample column, flat: ``t``, ``q0``…, ``p0``…, ``energy``, ``energy_error``,
        the invariants by name, ``cartesian_q0``…, ``cartesian_p0``…, and the indicators:
        ``lyapunov0``… (largest first), ``megno``, ``megno_mean``, ``fli``, ``sali``, ``gali``."""
        out: Dict[str, FloatArray] = {"t": self.t}
        for i in range(self.q.shape[1]):
            out[f"q{i}"] = self.q[:, i]
        for i in range(self.p.shape[1]):
            out[f"p{i}"] = self.p[:, i]
        out["energy"] = self.energy
        if self._energy_error is not None:
            out["energy_error"] = self._energy_error
        out.update(self.invariants)
        for name, values in (("cartesian_q", self.cartesian_q), ("cartesian_p", self.cartesian_p)):
            if values is not None:
                for i in range(values.shape[1]):
                    out[f"{name}{i}"] = values[:, i]
        if self.lyapunov is not None:
            for i in range(self.lyapunov.shape[1]):
                out[f"lyapunov{i}"] = self.lyapunov[:, i]
        for name in STATISTICS:
            column = getattr(self, name)
            if column is not None:
                out[name] = column
        return out

    def to_pandas(self) -> Any:
        """The samples as a pandas DataFrame, one row per sample (see :meth:`columns`)."""
        pd = _optional.pandas()
        return pd.DataFrame(self.columns())


@dataclass(frozen=True, eq=False)
class Simulation:
    """The answer to a simulation: the system as run, the schedule and one :class:`Run` per
    method in the order asked. Index it by position or by the method's label.

    ``energy_reference`` says what the runs' ``energy_error`` is measured against: ``exact``
    (the exact solution), ``initial`` (H₀: nothing damps or drives the system, so its exact
    flow keeps H) or ``reference`` (the adaptive reference run); ``None`` when there is none.
    ``section`` and ``stop_when`` are the request's section and event as the server resolved
    them (:class:`Surface`), ``None`` when not asked for (a ``stop_when`` of thresholds alone
    has no surface). ``indicators`` are the chaos indicators the runs report and ``deviations``
    the number of deviation vectors (the width of each run's ``lyapunov``): a stream's header
    gives it; from a one-document answer it is the width of ``lyapunov``, else the request's
    ``deviations``, else ``None`` (the server's default).
    """

    system: SystemState
    schedule: Schedule
    invariants: Tuple[str, ...]
    runs: Tuple[Run, ...]
    request: Optional[SimulateRequest] = field(default=None, repr=False)
    energy_reference: Optional[str] = None
    section: Optional[Surface] = None
    stop_when: Optional[Surface] = None
    indicators: Tuple[str, ...] = ()
    deviations: Optional[int] = None

    @classmethod
    def from_json(cls, doc: SimulationDocument, request: Optional[SimulateRequest] = None) -> "Simulation":
        """The simulation of a simulation's JSON answer."""
        system = SystemState.from_json(doc["system"])
        runs = tuple(Run.from_outcome(r["method"], r, r, system.dof, r.get("section"), r.get("events"))
                     for r in doc["runs"])
        # The document has no header: what the runs carry says which indicators and how many
        # deviation vectors (the stream's header says the same).
        indicators = runs[0].indicators if runs else ()
        deviations = None
        for r in doc["runs"]:
            final = r.get("indicators")
            spectrum = None if final is None else final.get("lyapunov")
            if spectrum is not None:
                deviations = len(spectrum)
                break
        if deviations is None and indicators and request is not None:
            deviations = request.get("deviations")
        return cls(system, Schedule.from_json(doc["schedule"]), tuple(doc["invariants"]), runs, request,
                   energy_reference=doc.get("energy_reference"), section=Surface.from_json(doc.get("section")),
                   stop_when=Surface.from_json(doc.get("stop_when")), indicators=indicators,
                   deviations=deviations)

    @classmethod
    def from_recorded(cls, doc: RecordedDocument) -> "Simulation":
        """The runs read back from a stored recording (``q``, ``p`` are single precision there)."""
        system = SystemState.from_json(doc["system"])
        runs = tuple(Run.from_recorded(r, system.dof) for r in doc["runs"])
        return cls(system, Schedule.from_json(doc["schedule"]), tuple(doc["invariants"]), runs)

    @property
    def methods(self) -> List[str]:
        """The runs' labels, in order."""
        return [r.method for r in self.runs]

    def __len__(self) -> int:
        return len(self.runs)

    def __iter__(self) -> Iterator[Run]:
        return iter(self.runs)

    def __getitem__(self, key: Union[int, str]) -> Run:
        """A run by position, by its label (``yoshida_6(modin_3s)``) or by the method as it was
        asked for (``yoshida_6``; a KeyError if several runs were asked for by that name)."""
        return pick(self.runs, key, lambda r: (r.method,), "run")

    def __repr__(self) -> str:
        lines = [f"Simulation({self.system.id} in {self.system.chart}, h={self.schedule.h:g}, "
                 f"t_end={self.schedule.t_end:g}, every={self.schedule.every}, "
                 f"energy_reference={self.energy_reference!r}, {len(self.runs)} runs:"]
        lines += [f"  {run!r}" for run in self.runs]
        return "\n".join(lines) + ")"

    def to_pandas(self) -> Any:
        """Every run's samples in one long DataFrame with a ``method`` column."""
        pd = _optional.pandas()
        frames = [r.to_pandas().assign(method=r.method) for r in self.runs]
        frame = pd.concat(frames, ignore_index=True)
        return frame[["method"] + [c for c in frame.columns if c != "method"]]

    def to_xarray(self) -> Any:
        """The runs as an xarray Dataset with dimensions ``run`` (the methods' labels), ``t`` and
        ``dof`` (and ``invariant``): ``q``, ``p``, ``energy``, ``energy_error``, ``invariants``,
        ``cartesian_q``, ``cartesian_p``, and the indicators asked for (``megno``,
        ``megno_mean``, ``fli``, ``sali``, ``gali``; ``lyapunov`` with an ``exponent``
        dimension, largest first); ``ds.sel(run="heun")`` picks a method. A run that
        stopped early is NaN past its last sample. Section points are not samples: they stay in
        each run's :attr:`Run.section` (``run.section.to_pandas()``).
        Runs whose sample times differ (which one request does not produce) are laid along a
        ``sample`` dimension with ``t`` as a variable instead."""
        xr = _optional.xarray()
        length = max((r.samples for r in self.runs), default=0)
        longest = max(self.runs, key=lambda r: r.samples).t if self.runs else _arrays.floats([])
        shared = all(np.array_equal(r.t, longest[: r.samples]) for r in self.runs)
        time = "t" if shared else "sample"
        dof = self.system.dof

        def pad(values: FloatArray) -> FloatArray:
            out = np.full((length,) + values.shape[1:], np.nan)
            out[: values.shape[0]] = values
            return out

        def stack(pick: Any) -> Optional[FloatArray]:
            arrays = [pick(r) for r in self.runs]
            if all(a is None for a in arrays):
                return None
            template = next(a for a in arrays if a is not None)
            return np.stack([pad(a if a is not None else np.full((0,) + template.shape[1:], np.nan))
                             for a in arrays])

        data: Dict[str, Any] = {
            "q": (("run", time, "dof"), stack(lambda r: r.q)),
            "p": (("run", time, "dof"), stack(lambda r: r.p)),
            "energy": (("run", time), stack(lambda r: r.energy)),
        }
        energy_error = stack(lambda r: r._energy_error)
        if energy_error is not None:
            data["energy_error"] = (("run", time), energy_error)
        if self.invariants:
            values = np.stack(
                [np.stack([pad(r.invariants[name]) for name in self.invariants], axis=-1) for r in self.runs]
            )
            data["invariants"] = (("run", time, "invariant"), values)
        for name in ("cartesian_q", "cartesian_p"):
            stacked = stack(lambda r, name=name: getattr(r, name))
            if stacked is not None:
                data[name] = (("run", time, "cartesian_dof"), stacked)
        for name in STATISTICS:
            stacked = stack(lambda r, name=name: getattr(r, name))
            if stacked is not None:
                data[name] = (("run", time), stacked)
        spectrum = stack(lambda r: r.lyapunov)
        coords: Dict[str, Any] = {"run": self.methods, "dof": np.arange(dof)}
        if spectrum is not None:
            data["lyapunov"] = (("run", time, "exponent"), spectrum)
            coords["exponent"] = np.arange(spectrum.shape[-1])
        if shared:
            coords["t"] = pad(longest)
        else:
            data["t"] = (("run", time), stack(lambda r: r.t))
        if self.invariants:
            coords["invariant"] = list(self.invariants)
        attrs = {"system": self.system.id, "chart": self.system.chart, "h": self.schedule.h,
                 "t_end": self.schedule.t_end, "every": self.schedule.every}
        if self.energy_reference is not None:
            attrs["energy_reference"] = self.energy_reference
        if self.indicators:
            attrs["indicators"] = list(self.indicators)
        return xr.Dataset(data, coords=coords, attrs=attrs)


class StreamAssembler:
    """Builds a :class:`Simulation` from the lines of a simulation's NDJSON stream, in order."""

    def __init__(self, request: Optional[SimulateRequest] = None) -> None:
        self.request = request
        self.header: Optional[HeaderLine] = None
        self._columns: List[Dict[str, Any]] = []
        # Per method, the crossings of each surface the header announced ("section", "stop_when").
        self._crossings: List[Dict[str, Dict[str, Any]]] = []
        self._summaries: Dict[int, SummaryLine] = {}

    @property
    def total_samples(self) -> int:
        """Samples the header announces over all methods (0 before the header)."""
        if self.header is None:
            return 0
        return self.header["schedule"]["samples_per_method"] * len(self.header["methods"])

    def header_line(self, line: HeaderLine) -> None:
        self.header = line
        self._columns = [
            {"t": [], "q": [], "p": [], "energy": [], "invariants": {k: [] for k in line["invariants"]}}
            for _ in line["methods"]
        ]
        surfaces = [name for name in ("section", "stop_when") if line.get(name) is not None]
        self._crossings = [
            {name: {"t": [], "q": [], "p": [], "energy": []} for name in surfaces} for _ in line["methods"]
        ]

    def samples_line(self, line: SamplesLine) -> int:
        """Adds a chunk; returns its number of samples."""
        columns = self._columns[line["method"]]
        have = len(columns["t"])
        if line["offset"] != have:
            raise ServerError("stream_order", f"method {line['method']}: a chunk at sample "
                              f"{line['offset']} after {have} samples")
        for key in ("t", "q", "p", "energy", "energy_error", "cartesian_q", "cartesian_p",
                    "bodies", "jacobian_defect", "lyapunov", "megno", "megno_mean", "fli", "sali", "gali"):
            values = line.get(key)
            if values is not None:
                columns.setdefault(key, []).extend(values)
        for name, values in line["invariants"].items():
            columns["invariants"].setdefault(name, []).extend(values)
        return len(line["t"])

    def crossings_line(self, line: CrossingsLine) -> None:
        """Adds a chunk of crossings of the section or the event's surface."""
        surface = line["surface"]
        columns = self._crossings[line["method"]].get(surface)
        if columns is None:
            raise ServerError("stream_order", f"method {line['method']}: crossings of {surface}, "
                              "which the header did not announce")
        have = len(columns["t"])
        if line["offset"] != have:
            raise ServerError("stream_order", f"method {line['method']}: {surface} crossings from point "
                              f"{line['offset']} after {have} points")
        for key in ("t", "q", "p", "energy", "cartesian_q"):
            values = line.get(key)
            if values is not None:
                columns.setdefault(key, []).extend(values)

    def summary_line(self, line: SummaryLine) -> None:
        self._summaries[line["method"]] = line

    def simulation(self) -> Simulation:
        """The simulation once the ``end`` line came."""
        if self.header is None:
            raise ServerError("stream_cut", "the stream had no header line")
        system = SystemState.from_json(self.header["system"])
        runs = []
        for i, label in enumerate(self.header["methods"]):
            summary = self._summaries.get(i)
            if summary is None:
                raise ServerError("stream_cut", f"the stream had no summary for {label}")
            columns: Columns = self._columns[i]  # type: ignore[assignment]
            crossings: Dict[str, CrossingColumns] = self._crossings[i]  # type: ignore[assignment]
            runs.append(Run.from_outcome(summary["label"], columns, summary, system.dof,
                                         crossings.get("section"), crossings.get("stop_when"),
                                         self.header.get("deviations")))
        return Simulation(system, Schedule.from_json(self.header["schedule"]),
                          tuple(self.header["invariants"]), tuple(runs), self.request,
                          energy_reference=self.header.get("energy_reference"),
                          section=Surface.from_json(self.header.get("section")),
                          stop_when=Surface.from_json(self.header.get("stop_when")),
                          indicators=tuple(self.header.get("indicators") or ()),
                          deviations=self.header.get("deviations"))
