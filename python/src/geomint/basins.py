"""Basin maps as numpy arrays on their axes: which attractor or exit each initial state of a grid
ends up at (``POST /api/v1/studies/basins``), with the attractors' table and the maps' metrics.

Per-cell columns come from the server in cell order, the first axis running fastest; here they
are arrays indexed by the axes in their order (``run.labels[i, j]`` is the cell at
``axes[0].values[i]``, ``axes[1].values[j]``), as a sweep's are.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _arrays, _optional
from ._arrays import FloatArray, IntArray
from ._lookup import pick
from ._names import StateNames
from ._wire import AttractorEntry, AttractorKind, BasinRunColumns, BasinsDocument, BasinsRequest
from .errors import ServerError
from .studies import Axis, axes_of, axis_columns, axis_coordinates

UNDECIDED = -1
"""The label of a cell nothing decided."""

METRICS = ("basin_entropy", "boundary_basin_entropy", "uncertainty_exponent", "boxes", "boundary_boxes",
           "undecided_fraction", "largest_energy_margin")
"""A run's metrics (:attr:`BasinRun.metrics`), as the document names them."""


@dataclass(frozen=True, eq=False)
class CriticalPoint:
    """A critical point of the potential V: position ``q``, ``energy`` V(q) and the eigenvalues
    of the Hessian of V there (all positive at a minimum, some negative at a saddle)."""

    q: FloatArray
    energy: float
    hessian_eigenvalues: FloatArray

    @classmethod
    def from_json(cls, doc: Mapping[str, object]) -> "CriticalPoint":
        """The point of the document's object, whose members the API's schema leaves untyped:
        they are checked here."""
        q, energy, eigenvalues = doc.get("q"), doc.get("energy"), doc.get("hessian_eigenvalues")
        numbers = (int, float)
        if not (isinstance(q, list) and all(isinstance(v, numbers) for v in q)
                and isinstance(energy, numbers) and not isinstance(energy, bool)
                and isinstance(eigenvalues, list) and all(isinstance(v, numbers) for v in eigenvalues)):
            raise ServerError("unreadable_answer", f"a critical point without numbers q, energy and "
                              f"hessian_eigenvalues: {dict(doc)!r}")
        return cls(_arrays.floats(q), float(energy), _arrays.floats(eigenvalues))


@dataclass(frozen=True, eq=False)
class Attractor:
    """One label of a basin map: ``kind`` is ``equilibrium`` (a damped system's minimum),
    ``well`` (an undamped system's, which the orbit never leaves), ``periodic`` (a driven
    system's periodic orbit), ``exit``, ``diverged`` or ``stayed`` (inside until t_end, in a map
    with exits); ``name`` says which in words (``equilibrium 2 (minimum)``, an exit's name,
    ``period-1 orbit 2``). ``cells`` counts its cells and ``fraction`` is their share of the
    cells that start an orbit.
    ``equilibrium`` is the critical point of an equilibrium or a well; ``period`` (in driving
    periods) and ``points`` (one row of q then p per stroboscopic point) those of a periodic
    orbit; ``points`` and ``radius`` those of an attractor the request gave (kind ``given``)."""

    label: int
    kind: AttractorKind
    name: str
    cells: int
    fraction: float
    equilibrium: Optional[CriticalPoint] = None
    period: Optional[int] = None
    points: Optional[FloatArray] = None
    radius: Optional[float] = None

    @classmethod
    def from_json(cls, doc: AttractorEntry, fraction: float) -> "Attractor":
        equilibrium, points = doc.get("equilibrium"), doc.get("points")
        return cls(
            label=doc["label"],
            kind=doc["kind"],
            name=doc["name"],
            cells=doc["cells"],
            fraction=fraction,
            equilibrium=None if equilibrium is None else CriticalPoint.from_json(equilibrium),
            period=doc.get("period"),
            points=None if points is None else _arrays.rows(points, len(points[0]) if points else 0),
            radius=doc.get("radius"),
        )


@dataclass(frozen=True)
class Undecided:
    """A cell nothing decided: its number in cell order, its index on the grid, and why."""

    cell: int
    index: Tuple[int, ...]
    reason: str


@dataclass(frozen=True, eq=False)
class BasinRun:
    """One method in one chart over a basin map's grid (arrays shaped like
    :attr:`BasinMap.shape`).

    ``labels`` holds each cell's attractor label (−1: undecided), ``decided_at`` the time its
    outcome was decided (NaN: undecided). ``attractors`` is the table of labels in label order
    (labels mean the same outcome in every run of a map), ``fractions`` each label's share;
    ``decided_by`` counts the cells each criterion decided (``energy``, ``exit``,
    ``recurrence``, ``proximity`` to a given attractor, ``divergence``, ``t_end``,
    ``undecided``).

    The metrics, over the undecided cells as one more outcome: ``basin_entropy`` S_b and
    ``boundary_basin_entropy`` S_bb over ``boxes`` boxes of 5 × 5 cells, ``boundary_boxes`` of
    them on a boundary (S_bb > ln 2 shows a fractal boundary; ``None`` without such boxes), the
    ``uncertainty_exponent`` α fitted to ``uncertain_fractions`` (f(ε) by ε in cells; ``None``
    with fewer than three ε), ``wada``, W_k of the Wada test by merging by label (the share of
    the boundary within a cell of label k's boundary against the rest merged; 1 for every k is
    a Wada boundary; empty with fewer than three labels), and ``largest_energy_margin``, the
    widest margin the energy argument used (``None`` where it decided nothing). Cells that
    start no orbit (``not_started`` of them) are left out of the shares and the metrics."""

    method: str
    chart: str
    labels: IntArray
    decided_at: FloatArray
    attractors: Tuple[Attractor, ...]
    fractions: FloatArray
    undecided_fraction: float
    undecided: Tuple[Undecided, ...]
    decided_by: Mapping[str, int]
    basin_entropy: Optional[float]
    boundary_basin_entropy: Optional[float]
    boundary_boxes: int
    boxes: int
    uncertainty_exponent: Optional[float]
    uncertain_fractions: Mapping[int, float]
    wada: Mapping[int, float]
    not_started: int
    largest_energy_margin: Optional[float]
    steps: int
    axes: Tuple[Axis, ...] = field(default=(), repr=False)

    @classmethod
    def from_json(cls, doc: BasinRunColumns, axes: Tuple[Axis, ...]) -> "BasinRun":
        shape = tuple(a.n for a in axes)
        fractions = _arrays.floats(doc["fractions"])
        decided_by = doc["decided_by"]
        return cls(
            method=doc["label"]["method"],
            chart=doc["label"]["chart"],
            labels=_arrays.grid_of(_arrays.ints(doc["labels"]), shape),
            decided_at=_arrays.grid(doc["decided_at"], shape),
            attractors=tuple(Attractor.from_json(a, float(fractions[i])) for i, a in enumerate(doc["attractors"])),
            fractions=fractions,
            undecided_fraction=doc["undecided_fraction"],
            undecided=tuple(Undecided(u["cell"], _grid_index(u["cell"], shape), u["reason"])
                            for u in doc["undecided"]),
            decided_by={"energy": decided_by["energy"], "exit": decided_by["exit"],
                        "recurrence": decided_by["recurrence"], "proximity": decided_by.get("proximity", 0),
                        "divergence": decided_by["divergence"],
                        "t_end": decided_by["t_end"], "undecided": decided_by["undecided"]},
            basin_entropy=doc.get("basin_entropy"),
            boundary_basin_entropy=doc.get("boundary_basin_entropy"),
            boundary_boxes=doc["boundary_boxes"],
            boxes=doc["boxes"],
            uncertainty_exponent=doc.get("uncertainty_exponent"),
            uncertain_fractions={u["epsilon_cells"]: u["fraction"] for u in doc["uncertain_fractions"]},
            wada={w["label"]: w["share"] for w in doc["wada"]},
            not_started=doc["not_started"],
            largest_energy_margin=doc.get("largest_energy_margin"),
            steps=doc["steps"],
            axes=axes,
        )

    @property
    def label(self) -> str:
        """``method [chart]``."""
        return f"{self.method} [{self.chart}]"

    @property
    def metrics(self) -> Dict[str, Optional[float]]:
        """The map's metrics by the document's names: ``basin_entropy``,
        ``boundary_basin_entropy``, ``uncertainty_exponent``, ``boxes``, ``boundary_boxes``,
        ``undecided_fraction`` and ``largest_energy_margin``."""
        return {name: getattr(self, name) for name in METRICS}

    @property
    def names(self) -> Dict[int, str]:
        """Each label's name, −1 (``undecided``) first: the legend of a map."""
        return {UNDECIDED: "undecided", **{a.label: a.name for a in self.attractors}}

    def attractor(self, key: Union[int, str]) -> Attractor:
        """An attractor by label, or by its name (``"up"``, ``"period-1 orbit 2"``): the server
        names each one uniquely."""
        if isinstance(key, int):
            for a in self.attractors:
                if a.label == key:
                    return a
            raise KeyError(f"no label {key}; there are {[a.label for a in self.attractors]}")
        for a in self.attractors:
            if a.name == key:
                return a
        raise KeyError(f"no attractor {key!r}; there are {[a.name for a in self.attractors]}")

    def to_xarray(self) -> Any:
        """The run as an xarray Dataset: ``labels`` and ``decided_at`` on the grid (dimensions
        named as a sweep's, after the state components: ``y``, ``p_y``), and the attractors'
        table along ``label`` (−1, undecided, first): ``attractor`` (the name), ``kind``,
        ``cells`` and ``fraction``, so ``ds["attractor"].sel(label=ds["labels"])`` names every
        cell. The metrics
        are attributes (NaN where not defined)."""
        xr = _optional.xarray()
        dims, coords = axis_coordinates(self.axes)
        table = _table([self])
        data: Dict[str, Any] = {
            "labels": (dims, self.labels),
            "decided_at": (dims, self.decided_at),
            "attractor": ("label", table["name"]),
            "kind": ("label", table["kind"]),
            "cells": ("label", table["cells"][0]),
            "fraction": ("label", table["fraction"][0]),
        }
        coords["label"] = table["label"]
        attrs = {"method": self.method, "chart": self.chart, "steps": self.steps,
                 **{k: _metric(v) for k, v in self.metrics.items()}}
        return xr.Dataset(data, coords=coords, attrs=attrs)


def _grid_index(cell: int, shape: Tuple[int, ...]) -> Tuple[int, ...]:
    """The grid index of a cell in cell order (the first axis fastest)."""
    return tuple(int(i) for i in np.unravel_index(cell, shape, order="F"))


def _number(value: Optional[float]) -> float:
    return float("nan") if value is None else float(value)


def _metric(value: Optional[float]) -> float:
    """A metric for xarray: counts stay whole numbers, ``None`` becomes NaN."""
    return value if isinstance(value, int) else _number(value)


def _table(runs: Sequence[BasinRun]) -> Dict[str, Any]:
    """The attractors' table of ``runs`` by label (−1, undecided, first): each label's name and
    kind, and per run its cells and fraction (0 where a run has no such cell)."""
    entries: Dict[int, Attractor] = {}
    for run in runs:
        for a in run.attractors:
            entries.setdefault(a.label, a)
    labels = [UNDECIDED] + sorted(entries)
    cells = np.zeros((len(runs), len(labels)), dtype=np.int64)
    fraction = np.zeros((len(runs), len(labels)))
    for r, run in enumerate(runs):
        cells[r, 0] = int((run.labels == UNDECIDED).sum())
        fraction[r, 0] = run.undecided_fraction
        for a in run.attractors:
            cells[r, labels.index(a.label)] = a.cells
            fraction[r, labels.index(a.label)] = a.fraction
    return {"label": labels, "name": ["undecided"] + [entries[k].name for k in labels[1:]],
            "kind": ["undecided"] + [entries[k].kind for k in labels[1:]], "cells": cells, "fraction": fraction}


@dataclass(frozen=True, eq=False)
class BasinMap:
    """A basin map's answer: its axes, one :class:`BasinRun` per method and chart, the exits'
    names, and for a system nothing drives the critical points of V the server found
    (``equilibria``, minima first) with ``lowest_saddle_energy``, below which the energy
    argument decides (``None`` for a driven system).

    ``unfinished_cells`` lists the cells (in cell order) that a time limit left unrun."""

    system: str
    axes: Tuple[Axis, ...]
    runs: Tuple[BasinRun, ...]
    exits: Tuple[str, ...]
    equilibria: Optional[Tuple[CriticalPoint, ...]]
    lowest_saddle_energy: Optional[float]
    cells: int
    digest: str
    wall_ms: float
    stop: str
    unfinished_cells: IntArray
    request: Optional[BasinsRequest] = field(default=None, repr=False)
    names: Optional[StateNames] = field(default=None, repr=False)

    def __repr__(self) -> str:
        axes = " × ".join(f"{a.dim} {a.n} ({a.min:g}…{a.max:g})" for a in self.axes)
        runs = "; ".join(f"{r.label}: " + ", ".join(f"{a.name} {a.fraction:.3f}" for a in r.attractors)
                         for r in self.runs)
        return f"BasinMap({self.system}: {axes}; {runs}; stop {self.stop!r})"

    @property
    def shape(self) -> Tuple[int, ...]:
        """The grid's shape: one entry per axis, in the axes' order."""
        return tuple(a.n for a in self.axes)

    def __iter__(self) -> Iterator[BasinRun]:
        return iter(self.runs)

    def __getitem__(self, key: Union[int, str, Tuple[str, str]]) -> BasinRun:
        """A run by position, by label, by method (the first chart), or by ``(method, chart)``."""
        return pick(self.runs, key, lambda r: (r.label, r.method, (r.method, r.chart)), "run")

    @classmethod
    def from_json(
        cls, doc: BasinsDocument, request: Optional[BasinsRequest] = None, names: Optional[StateNames] = None
    ) -> "BasinMap":
        """The map of its result line; ``names`` (the system's state names, when the client knows
        them) name the axes' dimensions after the state components."""
        axes = axes_of(doc["axes"], names)
        equilibria = doc.get("equilibria")
        return cls(
            system=doc["system"],
            axes=axes,
            runs=tuple(BasinRun.from_json(r, axes) for r in doc["runs"]),
            exits=tuple(doc["exits"]),
            equilibria=None if equilibria is None else tuple(CriticalPoint.from_json(e) for e in equilibria),
            lowest_saddle_energy=doc.get("lowest_saddle_energy"),
            cells=doc["cells"],
            digest=doc["digest"],
            wall_ms=doc["wall_ms"],
            stop=doc["stop"],
            unfinished_cells=_arrays.ints(doc["unfinished_cells"]),
            request=request,
            names=names,
        )

    def to_xarray(self) -> Any:
        """The map as an xarray Dataset: dimensions ``run`` and one per axis (named as a sweep's,
        after the state components), ``label`` for the attractors' table. Variables: ``labels``
        and ``decided_at`` on the grid; ``attractor`` (the name) and ``kind`` along ``label`` (−1, undecided,
        first), ``cells`` and ``fraction`` along ``run`` and ``label``; the metrics and
        ``steps`` along ``run`` (NaN where not defined). ``run`` is indexed by the method's
        label (with `` [chart]`` when the runs have several charts), with the coordinates
        ``method`` and ``chart``."""
        xr = _optional.xarray()
        dims, axis_coords = axis_coordinates(self.axes)
        cell = ("run",) + dims
        table = _table(self.runs)
        data: Dict[str, Any] = {
            "labels": (cell, np.stack([r.labels for r in self.runs])),
            "decided_at": (cell, np.stack([r.decided_at for r in self.runs])),
            "attractor": ("label", table["name"]),
            "kind": ("label", table["kind"]),
            "cells": (("run", "label"), table["cells"]),
            "fraction": (("run", "label"), table["fraction"]),
            "steps": ("run", [r.steps for r in self.runs]),
        }
        for metric in METRICS:
            data[metric] = ("run", [_metric(r.metrics[metric]) for r in self.runs])
        several = len({r.chart for r in self.runs}) > 1
        coords: Dict[str, Any] = {
            "run": [r.label if several else r.method for r in self.runs],
            "method": ("run", [r.method for r in self.runs]),
            "chart": ("run", [r.chart for r in self.runs]),
            "label": table["label"],
            **axis_coords,
        }
        attrs = {"system": self.system, "exits": list(self.exits), "digest": self.digest, "stop": self.stop,
                 "wall_ms": self.wall_ms, "lowest_saddle_energy": _number(self.lowest_saddle_energy)}
        return xr.Dataset(data, coords=coords, attrs=attrs)

    def to_pandas(self) -> Any:
        """One row per run and cell, in cell order (the first axis fastest): ``method``,
        ``chart``, one column per axis (named as its dimension), ``label``, ``attractor`` (its
        name) and ``decided_at``."""
        pd = _optional.pandas()
        points = axis_columns(self.axes)
        frames: List[Any] = []
        for run in self.runs:
            labels = run.labels.ravel(order="F")
            names = run.names
            frames.append(pd.DataFrame({
                "method": run.method, "chart": run.chart, **points, "label": labels,
                "attractor": [names[int(k)] for k in labels], "decided_at": run.decided_at.ravel(order="F"),
            }))
        return pd.concat(frames, ignore_index=True)
