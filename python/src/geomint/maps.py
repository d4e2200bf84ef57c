"""Maps as numpy arrays on their axes: the stability maps of the damped oscillator (with the
spectrum at one point) and the energy-error maps of paper 001.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Dict, Iterator, Mapping, Optional, Tuple, Union

import numpy as np

from . import _arrays, _optional
from ._lookup import pick
from ._arrays import BoolArray, FloatArray, IntArray
from ._wire import (
    AxisSpec,
    EnergyMapDocument,
    EnergyMapRequest,
    MapDocument,
    PointDocument,
    SpectrumDocument,
    StabilityDocument,
    StabilityRequest,
)

# --------------------------------------------------------------------------------------------
# Stability maps


def axis_points(axis: AxisSpec) -> FloatArray:
    """The points of a stability map's axis, computed as the server computes them:
    min + (max − min)·k/(n − 1), in that order of operations."""
    lo, hi, n = axis["min"], axis["max"], axis["n"]
    return _arrays.floats([lo + (hi - lo) * k / (n - 1) for k in range(n)])


@dataclass(frozen=True, eq=False)
class StabilityMap:
    """One method's map: arrays of (h points) × (γ points). ``analytic`` and ``printed`` are the
    corrected and the thesis's analytic verdicts (cimp, csv1 and csv2 only; else ``None``)."""

    method: str
    spectral_radius: FloatArray
    stable: BoolArray
    analytic: Optional[BoolArray]
    printed: Optional[BoolArray]
    disagreements: Optional[int]
    printed_disagreements: Optional[int]

    @classmethod
    def from_json(cls, doc: MapDocument) -> "StabilityMap":
        analytic, printed = doc.get("analytic"), doc.get("printed")
        return cls(
            method=doc["method"],
            spectral_radius=_arrays.floats(doc["spectral_radius"]),
            stable=_arrays.bools(doc["stable"]),
            analytic=None if analytic is None else _arrays.bools(analytic),
            printed=None if printed is None else _arrays.bools(printed),
            disagreements=doc.get("disagreements"),
            printed_disagreements=doc.get("printed_disagreements"),
        )


@dataclass(frozen=True, eq=False)
class StabilityMaps:
    """Stability maps of the damped oscillator q'' + 2γq' + ω²q = 0 over (γ, h), one per method.

    ``gamma`` and ``h`` are the grid's points (the document gives only min, max and n; they are
    computed here as the server computes them)."""

    omega: float
    gamma: FloatArray
    h: FloatArray
    maps: Tuple[StabilityMap, ...]
    stop: str
    request: Optional[StabilityRequest] = field(default=None, repr=False)

    @classmethod
    def from_json(cls, doc: StabilityDocument, request: Optional[StabilityRequest] = None) -> "StabilityMaps":
        return cls(doc["omega"], axis_points(doc["gamma"]), axis_points(doc["h"]),
                   tuple(StabilityMap.from_json(m) for m in doc["maps"]), doc["stop"], request)

    def __iter__(self) -> Iterator[StabilityMap]:
        return iter(self.maps)

    def __getitem__(self, key: Union[int, str]) -> StabilityMap:
        return pick(self.maps, key, lambda m: (m.method,), "map")

    def to_xarray(self) -> Any:
        """A Dataset with dimensions ``run`` (the methods), ``h`` and ``gamma``:
        ``spectral_radius`` (NaN where not finite or undefined), ``stable``, and
        ``analytic``/``printed`` (False for a method without them; ``has_analytic`` along ``run``
        says which have them). ``ds.sel(run="csv1")`` picks a method."""
        xr = _optional.xarray()
        shape = (len(self.h), len(self.gamma))

        def verdicts(pick: str) -> BoolArray:
            return np.stack([getattr(m, pick) if getattr(m, pick) is not None
                             else np.zeros(shape, dtype=bool) for m in self.maps])

        dims = ("run", "h", "gamma")
        data = {
            "spectral_radius": (dims, np.stack([m.spectral_radius for m in self.maps])),
            "stable": (dims, np.stack([m.stable for m in self.maps])),
            "analytic": (dims, verdicts("analytic")),
            "printed": (dims, verdicts("printed")),
        }
        coords = {
            "run": [m.method for m in self.maps],
            "h": self.h,
            "gamma": self.gamma,
            "has_analytic": ("run", [m.analytic is not None for m in self.maps]),
        }
        return xr.Dataset(data, coords=coords, attrs={"omega": self.omega, "stop": self.stop})

    def to_pandas(self) -> Any:
        """One row per method and grid point: ``method``, ``h``, ``gamma``, ``spectral_radius``,
        ``stable``, and ``analytic``/``printed`` where the method has them."""
        pd = _optional.pandas()
        h, gamma = np.meshgrid(self.h, self.gamma, indexing="ij")
        frames = []
        for m in self.maps:
            columns: Dict[str, Any] = {"method": m.method, "h": h.ravel(), "gamma": gamma.ravel(),
                                       "spectral_radius": m.spectral_radius.ravel(), "stable": m.stable.ravel()}
            for name in ("analytic", "printed"):
                verdict = getattr(m, name)
                if verdict is not None:
                    columns[name] = verdict.ravel()
            frames.append(pd.DataFrame(columns))
        return pd.concat(frames, ignore_index=True)


@dataclass(frozen=True, eq=False)
class Spectrum:
    """A 2×2 one-step matrix with its trace, determinant, eigenvalues and spectral radius
    (NaN where not finite)."""

    matrix: FloatArray
    eigenvalues: Tuple[complex, ...]
    trace: float
    det: float
    spectral_radius: float

    @classmethod
    def from_json(cls, doc: SpectrumDocument) -> "Spectrum":
        def number(value: Optional[float]) -> float:
            return float("nan") if value is None else value

        return cls(
            matrix=_arrays.floats(doc["matrix"]),
            eigenvalues=tuple(complex(number(e.get("re")), number(e.get("im"))) for e in doc["eigenvalues"]),
            trace=number(doc.get("trace")),
            det=number(doc.get("det")),
            spectral_radius=number(doc.get("spectral_radius")),
        )


@dataclass(frozen=True, eq=False)
class StabilityPoint:
    """The linear stability analysis of one method at one (ω, γ, h)."""

    method: str
    omega: float
    gamma: float
    h: float
    stable: bool
    spectrum: Spectrum
    exact: Spectrum
    half_trace_error: Optional[float]
    analytic: Optional[bool]
    printed: Optional[bool]

    @classmethod
    def from_json(cls, doc: PointDocument) -> "StabilityPoint":
        analysis, analytic = doc["analysis"], doc.get("analytic")
        return cls(
            method=doc["method"],
            omega=doc["omega"],
            gamma=doc["gamma"],
            h=doc["h"],
            stable=analysis["stable"],
            spectrum=Spectrum.from_json(analysis["method"]),
            exact=Spectrum.from_json(analysis["exact"]),
            half_trace_error=analysis.get("half_trace_error"),
            analytic=None if analytic is None else analytic["corrected"],
            printed=None if analytic is None else analytic["printed"],
        )


# --------------------------------------------------------------------------------------------
# Energy-error maps


@dataclass(frozen=True, eq=False)
class EnergyMap:
    """The energy-error map of paper 001 Fig. 6: symplectic Euler (or its adjoint) on the planar
    elastic pendulum released at rest from (x₀, y₀), in Cartesian and polar coordinates.

    Per-cell arrays are indexed ``[i, j]`` for (x[i], y[j]): ``energy`` (H₀),
    ``epsilon_cartesian`` and ``epsilon_polar`` (the ℓ² energy errors of eq. 50, NaN where the run
    diverged), ``difference`` (cartesian − polar), ``cartesian_diverged_at``,
    ``polar_diverged_at`` (NaN: never) and ``predicted_divergent`` (the region
    r₀ ≥ 2l + 2mg/k·cos θ₀). ``boundary`` is that region's edge as (x, y) points.
    """

    method: str
    params: Mapping[str, float]
    h: float
    t_max: float
    steps_per_run: int
    x: FloatArray
    y: FloatArray
    energy: FloatArray
    epsilon_cartesian: FloatArray
    epsilon_polar: FloatArray
    difference: FloatArray
    cartesian_diverged_at: FloatArray
    polar_diverged_at: FloatArray
    predicted_divergent: BoolArray
    boundary: FloatArray
    summary: Mapping[str, int]
    steps: int
    wall_ms: float
    stop: str
    unfinished_cells: IntArray
    request: Optional[EnergyMapRequest] = field(default=None, repr=False)

    @classmethod
    def from_json(cls, doc: EnergyMapDocument, request: Optional[EnergyMapRequest] = None) -> "EnergyMap":
        shape = (len(doc["xs"]), len(doc["ys"]))
        summary = doc["summary"]
        return cls(
            method=doc["method"],
            params={"m": doc["params"]["m"], "k": doc["params"]["k"], "l": doc["params"]["l"],
                    "g": doc["params"]["g"]},
            h=doc["h"],
            t_max=doc["t_max"],
            steps_per_run=doc["steps_per_run"],
            x=_arrays.floats(doc["xs"]),
            y=_arrays.floats(doc["ys"]),
            energy=_arrays.grid(doc["energy"], shape),
            epsilon_cartesian=_arrays.grid(doc["epsilon_cartesian"], shape),
            epsilon_polar=_arrays.grid(doc["epsilon_polar"], shape),
            difference=_arrays.grid(doc["difference"], shape),
            cartesian_diverged_at=_arrays.grid(doc["cartesian_diverged_at"], shape),
            polar_diverged_at=_arrays.grid(doc["polar_diverged_at"], shape),
            predicted_divergent=_arrays.grid_of(_arrays.bools(doc["predicted_divergent"]), shape),
            boundary=_arrays.rows(doc["boundary"], 2),
            summary={
                "cells": summary["cells"],
                "cartesian_better": summary["cartesian_better"],
                "polar_better": summary["polar_better"],
                "cartesian_diverged": summary["cartesian_diverged"],
                "polar_diverged": summary["polar_diverged"],
                "predicted_divergent": summary["predicted_divergent"],
                "diverged_outside_prediction": summary["diverged_outside_prediction"],
            },
            steps=doc["steps"],
            wall_ms=doc["wall_ms"],
            stop=doc["stop"],
            unfinished_cells=_arrays.ints(doc["unfinished_cells"]),
            request=request,
        )

    def to_xarray(self) -> Any:
        """A Dataset with dimensions ``x`` and ``y`` (the initial position) holding the per-cell
        arrays; the boundary along ``boundary_point``; the summary counts as attributes."""
        xr = _optional.xarray()
        names = ("energy", "epsilon_cartesian", "epsilon_polar", "difference", "cartesian_diverged_at",
                 "polar_diverged_at", "predicted_divergent")
        data: Dict[str, Any] = {name: (("x", "y"), getattr(self, name)) for name in names}
        data["boundary_x"] = (("boundary_point",), self.boundary[:, 0])
        data["boundary_y"] = (("boundary_point",), self.boundary[:, 1])
        attrs: Dict[str, Any] = {"method": self.method, "h": self.h, "t_max": self.t_max,
                                 "stop": self.stop, **{f"param_{k}": v for k, v in self.params.items()}}
        attrs.update(self.summary)
        return xr.Dataset(data, coords={"x": self.x, "y": self.y}, attrs=attrs)

    def to_pandas(self) -> Any:
        """One row per cell: ``x``, ``y`` and the per-cell arrays (the boundary and the summary
        are :attr:`boundary` and :attr:`summary`)."""
        pd = _optional.pandas()
        x, y = np.meshgrid(self.x, self.y, indexing="ij")
        columns: Dict[str, Any] = {"x": x.ravel(), "y": y.ravel()}
        for name in ("energy", "epsilon_cartesian", "epsilon_polar", "difference", "cartesian_diverged_at",
                     "polar_diverged_at", "predicted_divergent"):
            columns[name] = getattr(self, name).ravel()
        return pd.DataFrame(columns)
