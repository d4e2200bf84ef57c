"""The studies' answers as numpy arrays on their axes: sweeps, convergence and work–precision
studies (the maps are :mod:`geomint.maps`'s).

Per-cell columns of a sweep and of an energy map come from the server in cell order, the first
axis running fastest; here they are arrays indexed by the axes in their order
(``run.energy_error_max[i, j]`` is the cell at ``axes[0].values[i]``, ``axes[1].values[j]``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _arrays, _optional
from ._lookup import pick
from ._arrays import BoolArray, FloatArray, IntArray, ObjectArray
from ._wire import (
    AxisDocument,
    CellSection,
    ConvergenceDocument,
    ConvergenceRequest,
    SweepDocument,
    SweepRequest,
    WorkPrecisionDocument,
    WorkPrecisionRequest,
)
from ._names import StateNames
from .sections import Crossings
from .simulation import SystemState

# --------------------------------------------------------------------------------------------
# Sweeps


def dimension_name(axis: str) -> str:
    """The name of a sweep axis as a dimension: ``params.gamma`` → ``gamma``, ``q0[1]`` →
    ``q0_1``, ``h`` → ``h``."""
    if axis.startswith("params."):
        return axis[len("params."):]
    match = re.fullmatch(r"([qp]0)\[(\d+)\]", axis)
    return f"{match.group(1)}_{match.group(2)}" if match else axis


@dataclass(frozen=True, eq=False)
class Axis:
    """An axis of a sweep: ``name`` as in the request (``params.gamma``, ``h``, ``q0[0]``),
    ``n`` points from ``min`` to ``max`` on a ``linear`` or ``log`` scale. In an answer,
    ``values`` holds the points the server ran and ``dim`` the axis's dimension name."""

    name: str
    min: float
    max: float
    n: int
    scale: str = "linear"
    values: Optional[FloatArray] = field(default=None, compare=False)
    component: Optional[str] = field(default=None, compare=False)

    @property
    def dim(self) -> str:
        """The dimension name: the state component's name when the client knows it
        (``component``: ``q0[1]`` of Hénon–Heiles is ``y``, ``p0[1]`` is ``p_y``), else
        :func:`dimension_name`'s."""
        return self.component or dimension_name(self.name)


def axes_of(docs: Sequence[AxisDocument], names: Optional[StateNames] = None) -> Tuple[Axis, ...]:
    """A study's axes from its document, each named after the state component it varies when
    ``names`` (the system's state names) are known."""
    return tuple(
        Axis(a["name"], a["min"], a["max"], a["n"], a["scale"], _arrays.floats(a["values"]),
             None if names is None else names.component(a["name"]))
        for a in docs
    )


def axis_columns(axes: Sequence[Axis]) -> Dict[str, Any]:
    """Each axis's point at every cell, in cell order (the first axis fastest), by dimension
    name: the axis columns of a study's ``to_pandas()``."""
    grids = np.meshgrid(*[a.values if a.values is not None else np.arange(a.n) for a in axes], indexing="ij")
    return {axis.dim: grid.ravel(order="F") for axis, grid in zip(axes, grids, strict=True)}


def axis_coordinates(axes: Sequence[Axis]) -> Tuple[Tuple[str, ...], Dict[str, Any]]:
    """The dimensions of a study's grid and their coordinates for xarray: one dimension per axis,
    named :attr:`Axis.dim` (the request's names where two would clash), with the axis's points
    (the request's axis name and scale in attributes); where the dimension is a component's name
    (``y``), the request's form (``q0_1``) is a second coordinate along it."""
    xr = _optional.xarray()
    dims = tuple(a.dim for a in axes)
    if len(set(dims)) != len(dims):
        dims = tuple(a.name for a in axes)
    coords: Dict[str, Any] = {}
    for dim, axis in zip(dims, axes, strict=True):
        coords[dim] = xr.Variable(dim, axis.values, attrs={"axis": axis.name, "scale": axis.scale})
        wire = dimension_name(axis.name)
        if wire != dim and wire not in dims:
            coords[wire] = xr.Variable(dim, axis.values, attrs={"axis": axis.name, "scale": axis.scale})
    return dims, coords


CHAOS_COLUMNS = ("lyapunov_max", "megno", "megno_mean", "fli", "sali", "gali", "stopped_at")
"""A sweep run's chaos maps (with ``indicators``)."""


@dataclass(frozen=True, eq=False)
class SweepRun:
    """One method in one chart over a sweep's grid (arrays shaped like :attr:`Sweep.shape`).

    With ``indicators``, the chaos maps: each indicator's last value per cell
    (``lyapunov_max``, ``megno``, ``megno_mean``, ``fli``, ``sali``, ``gali``; NaN where not
    asked for or the run did not start) and ``stopped_at``, the time a ``stop_when`` threshold
    stopped the cell's run (NaN: it ran to the end); all ``None`` without indicators.

    With a ``section``, ``sections`` holds each cell's points in cell order (the first axis
    running fastest; ``None`` where the run did not start) and ``section_truncated`` on the grid
    whether a cell's crossings went past ``max_points``; both ``None`` without a section."""

    method: str
    chart: str
    energy_error_final: FloatArray
    energy_error_max: FloatArray
    energy_error_l2: FloatArray
    diverged_at: FloatArray
    steps: IntArray
    force_evaluations: IntArray
    errors: ObjectArray
    final_q: FloatArray
    final_p: FloatArray
    invariant_drift: Mapping[str, FloatArray]
    lyapunov_max: Optional[FloatArray] = None
    megno: Optional[FloatArray] = None
    megno_mean: Optional[FloatArray] = None
    fli: Optional[FloatArray] = None
    sali: Optional[FloatArray] = None
    gali: Optional[FloatArray] = None
    stopped_at: Optional[FloatArray] = None
    sections: Optional[Tuple[Optional[Crossings], ...]] = None
    section_truncated: Optional[BoolArray] = None

    @property
    def label(self) -> str:
        """``method [chart]``."""
        return f"{self.method} [{self.chart}]"


def _sections(
    cells: Optional[Sequence[Optional[CellSection]]], shape: Tuple[int, ...], dof: int
) -> Dict[str, Any]:
    """A run's ``sections`` and ``section_truncated``, if the sweep has a section."""
    if cells is None:
        return {}
    points = tuple(None if c is None else Crossings.from_json(c["points"], dof) for c in cells)
    truncated = _arrays.bools([c is not None and c["truncated"] for c in cells])
    return {"sections": points, "section_truncated": _arrays.grid_of(truncated, shape)}


def _ragged(values: Sequence[Sequence[float]]) -> FloatArray:
    """Rows of a common width, NaN where a row is empty (a run that could not start)."""
    width = max((len(v) for v in values), default=0)
    out = np.full((len(values), width), np.nan)
    for i, v in enumerate(values):
        if len(v):
            out[i] = v
    return out


@dataclass(frozen=True, eq=False)
class Sweep:
    """A sweep's answer: its axes and one :class:`SweepRun` per method and chart.

    ``unfinished_cells`` lists the cells (in the server's cell order) that a time limit left
    unrun; their values are NaN.
    """

    system: str
    axes: Tuple[Axis, ...]
    runs: Tuple[SweepRun, ...]
    invariants: Tuple[str, ...]
    energy_reference: str
    cells: int
    steps: int
    force_evaluations: int
    digest: str
    wall_ms: float
    stop: str
    unfinished_cells: IntArray
    request: Optional[SweepRequest] = field(default=None, repr=False)
    names: Optional[StateNames] = field(default=None, repr=False)

    def __repr__(self) -> str:
        axes = " × ".join(f"{a.dim} {a.n} ({a.min:g}…{a.max:g})" for a in self.axes)
        runs = ", ".join(r.label for r in self.runs)
        return (f"Sweep({self.system}: {axes}; {len(self.runs)} runs: {runs}; {self.cells} cells, "
                f"stop {self.stop!r})")

    @property
    def shape(self) -> Tuple[int, ...]:
        """The grid's shape: one entry per axis, in the axes' order."""
        return tuple(a.n for a in self.axes)

    def __iter__(self) -> Iterator[SweepRun]:
        return iter(self.runs)

    def __getitem__(self, key: Union[int, str, Tuple[str, str]]) -> SweepRun:
        """A run by position, by label, by method (the first chart), or by ``(method, chart)``."""
        return pick(self.runs, key, lambda r: (r.label, r.method, (r.method, r.chart)), "run")

    @classmethod
    def from_json(
        cls, doc: SweepDocument, request: Optional[SweepRequest] = None, names: Optional[StateNames] = None
    ) -> "Sweep":
        """The sweep of its result line; ``names`` (the system's state names, when the client
        knows them) name the axes' dimensions after the state components."""
        axes = axes_of(doc["axes"], names)
        shape = tuple(a.n for a in axes)

        def on_grid(values: Sequence[Optional[float]]) -> FloatArray:
            return _arrays.grid(values, shape)

        def maybe_on_grid(values: Optional[Sequence[Optional[float]]]) -> Optional[FloatArray]:
            return None if values is None else on_grid(values)

        def rows_on_grid(values: Sequence[Sequence[float]]) -> FloatArray:
            flat = _ragged(values)
            return np.reshape(flat, shape + (flat.shape[1],), order="F")

        runs = tuple(
            SweepRun(
                method=r["method"],
                chart=r["chart"],
                energy_error_final=on_grid(r["energy_error_final"]),
                energy_error_max=on_grid(r["energy_error_max"]),
                energy_error_l2=on_grid(r["energy_error_l2"]),
                diverged_at=on_grid(r["diverged_at"]),
                steps=_arrays.grid_of(_arrays.ints(r["steps"]), shape),
                force_evaluations=_arrays.grid_of(_arrays.ints(r["force_evaluations"]), shape),
                errors=_arrays.grid_of(_arrays.objects(r["errors"]), shape),
                final_q=rows_on_grid(r["final_q"]),
                final_p=rows_on_grid(r["final_p"]),
                invariant_drift={k: on_grid(v) for k, v in r["invariant_drift"].items()},
                lyapunov_max=maybe_on_grid(r.get("lyapunov_max")),
                megno=maybe_on_grid(r.get("megno")),
                megno_mean=maybe_on_grid(r.get("megno_mean")),
                fli=maybe_on_grid(r.get("fli")),
                sali=maybe_on_grid(r.get("sali")),
                gali=maybe_on_grid(r.get("gali")),
                stopped_at=maybe_on_grid(r.get("stopped_at")),
                **_sections(r.get("sections"), shape, max(map(len, r["final_q"]), default=0)),
            )
            for r in doc["runs"]
        )
        return cls(
            system=doc["system"],
            axes=axes,
            runs=runs,
            invariants=tuple(doc["invariants"]),
            energy_reference=doc["energy_reference"],
            cells=doc["cells"],
            steps=doc["steps"],
            force_evaluations=doc["force_evaluations"],
            digest=doc["digest"],
            wall_ms=doc["wall_ms"],
            stop=doc["stop"],
            unfinished_cells=_arrays.ints(doc["unfinished_cells"]),
            request=request,
            names=names,
        )

    def to_pandas(self) -> Any:
        """One row per run and cell: ``method``, ``chart``, one column per axis (named as its
        dimension, :attr:`Axis.dim`), then the per-cell numbers: the energy errors,
        ``diverged_at``, ``steps``, ``force_evaluations``, ``errors``, each invariant's drift
        (``drift_<name>``) and, with indicators, the chaos maps. Cells run in the server's order
        (the first axis fastest)."""
        pd = _optional.pandas()
        frames = []
        points = axis_columns(self.axes)
        for run in self.runs:
            columns: Dict[str, Any] = {"method": run.method, "chart": run.chart, **points}
            for name in ("energy_error_final", "energy_error_max", "energy_error_l2", "diverged_at",
                         "steps", "force_evaluations", "errors") + CHAOS_COLUMNS:
                values = getattr(run, name)
                if values is not None:
                    columns[name] = values.ravel(order="F")
            for name, drift in run.invariant_drift.items():
                columns[f"drift_{name}"] = drift.ravel(order="F")
            frames.append(pd.DataFrame(columns))
        return pd.concat(frames, ignore_index=True)

    def to_xarray(self) -> Any:
        """The sweep as an xarray Dataset: dimensions ``run`` and one per axis, named after the
        state component when the client knows the system's names (``y``, ``p_y``; the request's
        ``q0_1``, ``p0_1`` stay as coordinates along them), else as :func:`dimension_name` says,
        with the axes' points as coordinates (the request's axis name in each coordinate's
        ``axis`` attribute). ``run`` has the coordinates ``method``
        and ``chart``. Variables: ``energy_error_final``, ``energy_error_max``,
        ``energy_error_l2``, ``diverged_at``, ``steps``, ``force_evaluations``, ``errors``,
        ``final_q`` and ``final_p`` (with a ``dof`` dimension) and ``invariant_drift`` (with an
        ``invariant`` dimension) where the system has invariants; with indicators, the chaos
        maps ``lyapunov_max``, ``megno``, ``megno_mean``, ``fli``, ``sali``, ``gali`` (NaN where
        not asked for) and ``stopped_at``. ``run`` is indexed by the
        method's label, followed by `` [chart]`` when the sweep has several charts:
        ``ds.sel(run="csv1")``."""
        xr = _optional.xarray()
        dims, axis_coords = axis_coordinates(self.axes)
        cell = ("run",) + dims

        def stacked(name: str) -> np.ndarray[Any, Any]:
            return np.stack([getattr(r, name) for r in self.runs])

        data: Dict[str, Any] = {
            name: (cell, stacked(name))
            for name in ("energy_error_final", "energy_error_max", "energy_error_l2", "diverged_at",
                         "steps", "force_evaluations", "errors")
        }
        for name in CHAOS_COLUMNS:
            if any(getattr(r, name) is not None for r in self.runs):
                data[name] = (cell, np.stack([getattr(r, name) if getattr(r, name) is not None
                                              else np.full(self.shape, np.nan) for r in self.runs]))
        width = max((r.final_q.shape[-1] for r in self.runs), default=0)
        if all(r.final_q.shape[-1] == width for r in self.runs):
            data["final_q"] = (cell + ("dof",), stacked("final_q"))
            data["final_p"] = (cell + ("dof",), stacked("final_p"))
        if self.invariants:
            drift = np.stack(
                [np.stack([r.invariant_drift[name] for name in self.invariants], axis=-1) for r in self.runs]
            )
            data["invariant_drift"] = (cell + ("invariant",), drift)
        several = len({r.chart for r in self.runs}) > 1
        coords: Dict[str, Any] = {
            "run": [r.label if several else r.method for r in self.runs],
            "method": ("run", [r.method for r in self.runs]),
            "chart": ("run", [r.chart for r in self.runs]),
        }
        coords.update(axis_coords)
        if "final_q" in data and self.names is not None and len(self.names.coordinates) == width:
            coords["coordinate"] = ("dof", list(self.names.coordinates))
            coords["momentum"] = ("dof", list(self.names.momenta))
        if self.invariants:
            coords["invariant"] = list(self.invariants)
        attrs = {"system": self.system, "energy_reference": self.energy_reference, "digest": self.digest,
                 "stop": self.stop, "steps": self.steps, "wall_ms": self.wall_ms}
        return xr.Dataset(data, coords=coords, attrs=attrs)


# --------------------------------------------------------------------------------------------
# Convergence and work–precision


@dataclass(frozen=True)
class OrderFit:
    """log₁₀ error ≈ intercept + order·log₁₀ h over ``points`` settings (``None``: too few)."""

    order: Optional[float]
    intercept: Optional[float]
    points: int


@dataclass(frozen=True, eq=False)
class ConvergenceSeries:
    """One method in one chart over the study's step sizes, with its fitted orders."""

    method: str
    chart: str
    label: str
    h: FloatArray
    steps: IntArray
    state_error: FloatArray
    energy_error: FloatArray
    max_energy_error: FloatArray
    stop: Tuple[str, ...]
    state: OrderFit
    energy: OrderFit
    max_energy: OrderFit


@dataclass(frozen=True, eq=False)
class Convergence:
    """A convergence study: errors at t_end per method, chart and step size (NaN: not measured,
    or the run did not finish), against ``reference`` (the exact solution or an adaptive run)."""

    system: SystemState
    charts: Tuple[str, ...]
    t_end: float
    samples: int
    reference: str
    reference_ms: float
    series: Tuple[ConvergenceSeries, ...]
    request: Optional[ConvergenceRequest] = field(default=None, repr=False)

    @classmethod
    def from_json(cls, doc: ConvergenceDocument, request: Optional[ConvergenceRequest] = None) -> "Convergence":
        def fit(f: Any) -> OrderFit:
            return OrderFit(f.get("order"), f.get("intercept"), f["points"])

        series = []
        for index, s in enumerate(doc["series"]):
            points = [p for p in doc["points"] if p["series"] == index]
            series.append(ConvergenceSeries(
                method=s["method"],
                chart=s["chart"],
                label=s["label"],
                h=_arrays.floats([p["h"] for p in points]),
                steps=_arrays.ints([p["steps"] for p in points]),
                state_error=_arrays.floats([p.get("state_error") for p in points]),
                energy_error=_arrays.floats([p.get("energy_error") for p in points]),
                max_energy_error=_arrays.floats([p.get("max_energy_error") for p in points]),
                stop=tuple(p["stop"] for p in points),
                state=fit(s["state"]),
                energy=fit(s["energy"]),
                max_energy=fit(s["max_energy"]),
            ))
        return cls(SystemState.from_json(doc["system"]), tuple(doc["charts"]), doc["t_end"], doc["samples"],
                   doc["reference"], doc["reference_ms"], tuple(series), request)

    def __iter__(self) -> Iterator[ConvergenceSeries]:
        return iter(self.series)

    def __getitem__(self, key: Union[int, str]) -> ConvergenceSeries:
        """A series by position, or by label (``method [chart]``) or method."""
        return pick(self.series, key, lambda s: (s.label, s.method), "series")

    def to_pandas(self) -> Any:
        """One row per setting: method, chart, h, steps, the three errors and the stop reason."""
        pd = _optional.pandas()
        rows: List[Dict[str, Any]] = []
        for s in self.series:
            for i in range(len(s.h)):
                rows.append({"method": s.method, "chart": s.chart, "h": s.h[i], "steps": s.steps[i],
                             "state_error": s.state_error[i], "energy_error": s.energy_error[i],
                             "max_energy_error": s.max_energy_error[i], "stop": s.stop[i]})
        return pd.DataFrame(rows)

    def to_xarray(self) -> Any:
        """A Dataset with dimensions ``series`` (coordinates ``method``, ``chart``) and ``h``:
        the three errors and the steps, and the fitted orders along ``series``."""
        xr = _optional.xarray()
        h = self.series[0].h if self.series else _arrays.floats([])
        same = all(np.array_equal(s.h, h) for s in self.series)
        if not same:
            raise ValueError("the series have different step sizes; use to_pandas()")
        dims = ("series", "h")
        data: Dict[str, Any] = {name: (dims, np.stack([getattr(s, name) for s in self.series]))
                for name in ("state_error", "energy_error", "max_energy_error", "steps")}
        for name in ("state", "energy", "max_energy"):
            data[f"{name}_order"] = (("series",), _arrays.floats([getattr(s, name).order for s in self.series]))
        coords = {"h": h, "method": ("series", [s.method for s in self.series]),
                  "chart": ("series", [s.chart for s in self.series]),
                  "label": ("series", [s.label for s in self.series])}
        return xr.Dataset(data, coords=coords, attrs={"reference": self.reference, "t_end": self.t_end})


@dataclass(frozen=True, eq=False)
class WorkPrecisionRun:
    """One method's settings in a work–precision study (``h`` or ``tolerance``, NaN for the
    other) and its fitted cost line log₁₀(ms) ≈ intercept + slope·log₁₀(max energy error)."""

    method: str
    run: int
    h: FloatArray
    tolerance: FloatArray
    wall_ms: FloatArray
    steps: IntArray
    force_evaluations: IntArray
    max_energy_error: FloatArray
    final_state_error: FloatArray
    invariant_drift: Mapping[str, FloatArray]
    stop: Tuple[str, ...]
    slope: Optional[float]
    intercept: Optional[float]


@dataclass(frozen=True, eq=False)
class WorkPrecision:
    """A work–precision study: wall time against error for every setting of every method."""

    system: SystemState
    t_end: float
    samples: int
    reference: str
    reference_ms: float
    runs: Tuple[WorkPrecisionRun, ...]
    request: Optional[WorkPrecisionRequest] = field(default=None, repr=False)

    @classmethod
    def from_json(cls, doc: WorkPrecisionDocument, request: Optional[WorkPrecisionRequest] = None) -> "WorkPrecision":
        runs = []
        for fit in doc["fits"]:
            points = [p for p in doc["points"] if p["run"] == fit["run"]]
            names = sorted({k for p in points for k in p["invariant_drift"]})
            runs.append(WorkPrecisionRun(
                method=fit["method"],
                run=fit["run"],
                h=_arrays.floats([p.get("h") for p in points]),
                tolerance=_arrays.floats([p.get("tolerance") for p in points]),
                wall_ms=_arrays.floats([p["wall_ms"] for p in points]),
                steps=_arrays.ints([p["steps"] for p in points]),
                force_evaluations=_arrays.ints([p["force_evaluations"] for p in points]),
                max_energy_error=_arrays.floats([p.get("max_energy_error") for p in points]),
                final_state_error=_arrays.floats([p.get("final_state_error") for p in points]),
                invariant_drift={n: _arrays.floats([p["invariant_drift"].get(n) for p in points]) for n in names},
                stop=tuple(p["stop"] for p in points),
                slope=fit.get("slope"),
                intercept=fit.get("intercept"),
            ))
        return cls(SystemState.from_json(doc["system"]), doc["t_end"], doc["samples"], doc["reference"],
                   doc["reference_ms"], tuple(runs), request)

    def __iter__(self) -> Iterator[WorkPrecisionRun]:
        return iter(self.runs)

    def __getitem__(self, key: Union[int, str]) -> WorkPrecisionRun:
        return pick(self.runs, key, lambda r: (r.method,), "run")

    def to_pandas(self) -> Any:
        """One row per setting: method, h, tolerance, wall_ms, steps, force evaluations, the
        errors, each invariant's drift and the stop reason."""
        pd = _optional.pandas()
        rows: List[Dict[str, Any]] = []
        for r in self.runs:
            for i in range(len(r.h)):
                row = {"method": r.method, "run": r.run, "h": r.h[i], "tolerance": r.tolerance[i],
                       "wall_ms": r.wall_ms[i], "steps": r.steps[i], "force_evaluations": r.force_evaluations[i],
                       "max_energy_error": r.max_energy_error[i], "final_state_error": r.final_state_error[i],
                       "stop": r.stop[i]}
                row.update({f"drift_{n}": v[i] for n, v in r.invariant_drift.items()})
                rows.append(row)
        return pd.DataFrame(rows)
