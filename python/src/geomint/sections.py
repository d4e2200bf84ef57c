"""A run's Poincaré section and event crossings as numpy arrays: the surface as the server
resolved it, the section's summary, and the crossings' columns.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, Optional, Tuple


from . import _arrays, _optional
from ._arrays import FloatArray
from ._wire import (
    CrossingColumns,
    SectionSummary as SectionSummaryDoc,
    SurfaceInfo,
)


@dataclass(frozen=True)
class Surface:
    """A section or an event as the server resolved it (every default filled in).

    A surface ``where`` = 0 has ``direction`` (``up``, ``down`` or ``both``); a section has
    ``max_points``, an event ``count``; a stroboscopic section has ``period`` and ``phase``
    instead of ``where`` and ``direction``. ``coordinates`` and ``momenta`` name the columns of
    the points' ``q`` and ``p``.
    """

    coordinates: Tuple[str, ...]
    momenta: Tuple[str, ...]
    where: Optional[str] = None
    direction: Optional[str] = None
    max_points: Optional[int] = None
    count: Optional[int] = None
    period: Optional[float] = None
    phase: Optional[float] = None

    @classmethod
    def from_json(cls, doc: Optional[SurfaceInfo]) -> Optional["Surface"]:
        if doc is None:
            return None
        return cls(tuple(doc["coordinates"]), tuple(doc["momenta"]), doc.get("where"), doc.get("direction"),
                   doc.get("max_points"), doc.get("count"), doc.get("period"), doc.get("phase"))


@dataclass(frozen=True)
class SectionSummary:
    """How a run's section went: ``points`` located; ``truncated`` when crossings after
    ``max_points`` went uncollected; ``surface_range``, the least and greatest value of S over
    the run's steps (surfaces given as expressions); ``unlocated``, crossings seen whose point
    could not be located (tangent to the surface within round-off); ``note``, why there are no
    points when there are none."""

    points: int
    truncated: bool
    surface_range: Optional[Tuple[float, float]] = None
    unlocated: Optional[int] = None
    note: Optional[str] = None

    @classmethod
    def from_json(cls, doc: Optional[SectionSummaryDoc]) -> Optional["SectionSummary"]:
        if doc is None:
            return None
        bounds = doc.get("surface_range")
        surface_range = None if bounds is None else (float(bounds[0]), float(bounds[1]))
        return cls(doc["points"], doc["truncated"], surface_range, doc.get("unlocated"), doc.get("note"))


@dataclass(frozen=True, eq=False)
class Crossings:
    """Located crossings of a surface, as numpy arrays (float64, the server's bits): a run's
    Poincaré section, or the crossings of its ``stop_when`` surface.

    ``t`` and ``energy`` (H at each point) have one entry per point; ``q`` and ``p`` are
    (points, degrees of freedom), located on the surface to round-off; ``cartesian_q`` comes
    with a non-Cartesian chart.
    """

    t: FloatArray
    q: FloatArray
    p: FloatArray
    energy: FloatArray
    cartesian_q: Optional[FloatArray] = None

    @classmethod
    def from_json(cls, doc: CrossingColumns, dof: int) -> "Crossings":
        cartesian = doc.get("cartesian_q")
        return cls(
            t=_arrays.floats(doc["t"]),
            q=_arrays.rows(doc["q"], dof),
            p=_arrays.rows(doc["p"], dof),
            energy=_arrays.floats(doc["energy"]),
            cartesian_q=_arrays.optional_rows(cartesian, len(cartesian[0]) if cartesian else 0),
        )

    @classmethod
    def optional(cls, doc: Optional[CrossingColumns], dof: int) -> Optional["Crossings"]:
        return None if doc is None else cls.from_json(doc, dof)

    @property
    def points(self) -> int:
        """The number of points."""
        return int(self.t.shape[0])

    def __len__(self) -> int:
        return self.points

    def columns(self) -> Dict[str, FloatArray]:
        """Every column, flat: ``t``, ``q0``…, ``p0``…, ``energy``, ``cartesian_q0``…."""
        out: Dict[str, FloatArray] = {"t": self.t}
        for i in range(self.q.shape[1]):
            out[f"q{i}"] = self.q[:, i]
        for i in range(self.p.shape[1]):
            out[f"p{i}"] = self.p[:, i]
        out["energy"] = self.energy
        if self.cartesian_q is not None:
            for i in range(self.cartesian_q.shape[1]):
                out[f"cartesian_q{i}"] = self.cartesian_q[:, i]
        return out

    def to_pandas(self) -> Any:
        """The points as a pandas DataFrame, one row per point (see :meth:`columns`)."""
        pd = _optional.pandas()
        return pd.DataFrame(self.columns())
