"""A system's state components by name: the coordinates (``x``, ``y``, or a chart's ``r``,
``θ``) and momenta (``p_<coordinate>`` unless a definition names them), and their translation to
and from the request's wire forms ``q0[i]`` and ``p0[i]``, so that a sweep's axis, an energy
level and a Dataset's dimension are all spelt the same way."""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from typing import Any, Mapping, Optional, Sequence, Tuple

from .catalog import System
from .errors import ValidationError

WIRE = re.compile(r"([qp])0\[(\d+)\]")
"""A component in the request's form: ``q0[i]`` or ``p0[i]``."""


@dataclass(frozen=True)
class StateNames:
    """The names of a system's coordinates and momenta, in state order, and its parameters."""

    coordinates: Tuple[str, ...]
    momenta: Tuple[str, ...]
    parameters: Tuple[str, ...] = ()

    @classmethod
    def of_definition(cls, definition: Mapping[str, Any]) -> Optional["StateNames"]:
        """The names a typed-in definition gives (``momenta`` default to ``p_<coordinate>``)."""
        coordinates = definition.get("coordinates")
        if not isinstance(coordinates, Sequence) or not all(isinstance(c, str) for c in coordinates):
            return None
        momenta = definition.get("momenta")
        if not isinstance(momenta, Sequence) or len(momenta) != len(coordinates):
            momenta = [f"p_{c}" for c in coordinates]
        parameters = definition.get("parameters")
        return cls(tuple(coordinates), tuple(str(m) for m in momenta),
                   tuple(parameters) if isinstance(parameters, Mapping) else ())

    @classmethod
    def of_entry(cls, entry: System, chart: Optional[str] = None) -> Optional["StateNames"]:
        """The names in a catalogue entry's ``chart`` (default: its first), as the server names
        them: the chart's coordinates, or ``x1, y1, z1, x2, …`` for bodies; ``None`` if the entry
        has no such chart."""
        charts = [c for c in entry.charts if chart is None or c.id == chart]
        if not charts:
            return None
        dof = entry.degrees_of_freedom
        coordinates: Sequence[str] = charts[0].coordinates
        if len(coordinates) != dof or "…" in coordinates:
            coordinates = [f"{'xyz'[i % 3]}{i // 3 + 1}" for i in range(dof)]
        return cls(tuple(coordinates), tuple(f"p_{c}" for c in coordinates), tuple(p.name for p in entry.params))

    def find(self, name: str) -> Optional[Tuple[bool, int]]:
        """``(is a momentum, index)`` of a component given by name or as ``q0[i]``/``p0[i]``."""
        wire = WIRE.fullmatch(name)
        if wire is not None:
            index = int(wire.group(2))
            return (wire.group(1) == "p", index) if index < len(self.coordinates) else None
        if name in self.coordinates:
            return False, self.coordinates.index(name)
        if name in self.momenta:
            return True, self.momenta.index(name)
        return None

    def component(self, wire: str) -> Optional[str]:
        """The name of ``q0[i]``/``p0[i]`` (``None``: not a component of this system)."""
        found = self.find(wire) if WIRE.fullmatch(wire) else None
        if found is None:
            return None
        momentum, index = found
        return (self.momenta if momentum else self.coordinates)[index]

    def unknown(self, where: str, name: str, what: str, known: Sequence[str]) -> ValidationError:
        """The error for ``name``, which is none of ``known``: the nearest one, and all of them."""
        near = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        return ValidationError(where, f"{name!r} is not {what} of this system{hint}; it has "
                               + ", ".join(known), code="unknown_name")

    def momentum_name(self, name: str, where: str) -> str:
        """A momentum by its name, given by name or as ``p0[i]``."""
        found = self.find(name)
        if found is None or not found[0]:
            raise self.unknown(where, name, "a momentum", self.momenta)
        return self.momenta[found[1]]

    def momentum_wire(self, name: str, where: str) -> str:
        """A momentum as ``p0[i]``, given by name or as ``p0[i]``."""
        found = self.find(name)
        if found is None or not found[0]:
            raise self.unknown(where, name, "a momentum", self.momenta)
        return f"p0[{found[1]}]"

    def axis(self, name: str, where: str) -> str:
        """A sweep axis in the request's form: a coordinate or momentum by name becomes ``q0[i]``
        or ``p0[i]``, a bare parameter name ``params.<name>``; the request's own forms pass."""
        if name == "h" or name.startswith("params."):
            return name
        found = self.find(name)
        if found is not None:
            return f"{'p' if found[0] else 'q'}0[{found[1]}]"
        if name in self.parameters:
            return f"params.{name}"
        raise self.unknown(where, name, "an axis", ("h",) + self.coordinates + self.momenta + self.parameters)


def is_wire(name: str) -> bool:
    """Whether ``name`` is in the request's form (``q0[i]``, ``p0[i]``, ``params.<name>``, ``h``)."""
    return name == "h" or name.startswith("params.") or WIRE.fullmatch(name) is not None
