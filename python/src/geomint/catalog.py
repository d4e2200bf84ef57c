"""The system and method catalogues, and stored definitions, as typed objects."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Optional, Tuple, Union

from . import _arrays
from ._arrays import FloatArray
from ._wire import MethodEntry, ParamEntry, StoredSystem, SystemEntry


@dataclass(frozen=True)
class Parameter:
    """One parameter of a system: its kind (``number``, ``choice``, ``number_list``), default and
    range or options."""

    name: str
    description: str
    kind: str
    default: Union[float, str, Tuple[float, ...]]
    min: Optional[float] = None
    max: Optional[float] = None
    min_exclusive: bool = False
    options: Tuple[str, ...] = ()
    max_len: Optional[int] = None

    @classmethod
    def from_json(cls, doc: ParamEntry) -> "Parameter":
        if doc["kind"] == "number":
            return cls(doc["name"], doc["description"], "number", doc["default"],
                       min=doc["min"], max=doc["max"], min_exclusive=doc["min_exclusive"])
        if doc["kind"] == "choice":
            return cls(doc["name"], doc["description"], "choice", doc["default"],
                       options=tuple(doc["options"]))
        return cls(doc["name"], doc["description"], "number_list", tuple(doc["default"]),
                   min=doc["min"], max=doc["max"], max_len=doc["max_len"])


@dataclass(frozen=True)
class Chart:
    """A coordinate chart a system is offered in."""

    id: str
    coordinates: Tuple[str, ...]
    separable: bool
    description: str


@dataclass(frozen=True, eq=False)
class System:
    """A catalogue entry: a built-in system or a stored definition."""

    id: str
    name: str
    description: str
    degrees_of_freedom: int
    charts: Tuple[Chart, ...]
    params: Tuple[Parameter, ...]
    q0: FloatArray
    p0: FloatArray
    invariants: Tuple[str, ...]
    exact_solution: bool
    conformal_damping: bool

    @classmethod
    def from_json(cls, doc: SystemEntry) -> "System":
        return cls(
            id=doc["id"],
            name=doc["name"],
            description=doc["description"],
            degrees_of_freedom=doc["degrees_of_freedom"],
            charts=tuple(
                Chart(c["id"], tuple(c["coordinates"]), c["separable"], c["description"])
                for c in doc["charts"]
            ),
            params=tuple(Parameter.from_json(p) for p in doc["params"]),
            q0=_arrays.floats(doc["q0"]),
            p0=_arrays.floats(doc["p0"]),
            invariants=tuple(doc["invariants"]),
            exact_solution=doc["exact_solution"],
            conformal_damping=doc["conformal_damping"],
        )

    def param(self, name: str) -> Parameter:
        """The parameter called ``name``."""
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(f"{self.id} has no parameter {name!r}; it has {[p.name for p in self.params]}")


@dataclass(frozen=True)
class Facts:
    """What the server derived from a definition."""

    dimension: int
    separable: bool
    damping: str
    methods: Tuple[str, ...]


@dataclass(frozen=True, eq=False)
class Definition:
    """A stored definition: its catalogue entry, the definition as stored and its facts."""

    system: System
    definition: Mapping[str, object]
    facts: Facts
    created_unix_ms: int

    @property
    def id(self) -> str:
        """The stored system's id (``sys-`` and 16 hex digits of the definition's digest)."""
        return self.system.id

    @classmethod
    def from_json(cls, doc: StoredSystem) -> "Definition":
        facts = doc["facts"]
        return cls(
            system=System.from_json(doc),
            definition=doc["definition"],
            facts=Facts(facts["dimension"], facts["separable"], facts["damping"], tuple(facts["methods"])),
            created_unix_ms=doc["created_unix_ms"],
        )


@dataclass(frozen=True)
class Method:
    """A method's catalogue entry."""

    id: str
    name: str
    order: int
    kind: str
    symplectic: bool
    conformal_symplectic: bool
    symmetric: bool
    group: str
    requirements: Tuple[str, ...]
    options: Tuple[str, ...]
    paper: str
    equation: str

    @classmethod
    def from_json(cls, doc: MethodEntry) -> "Method":
        return cls(
            id=doc["id"],
            name=doc["name"],
            order=doc["order"],
            kind=doc["kind"],
            symplectic=doc["symplectic"],
            conformal_symplectic=doc["conformal_symplectic"],
            symmetric=doc["symmetric"],
            group=doc["group"],
            requirements=tuple(doc["requirements"]),
            options=tuple(doc["options"]),
            paper=doc["reference"]["paper"],
            equation=doc["reference"]["equation"],
        )

