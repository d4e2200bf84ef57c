"""The client's arguments as Python takes them — systems, methods, axes, sections, stop
conditions, energy levels — and their checked translation into the API's request bodies; shared
by the HTTP client and :mod:`geomint.local`."""

from __future__ import annotations

import math
from typing import (
    Any,
    Callable,
    Dict,
    List,
    Mapping,
    Optional,
    Sequence,
    Tuple,
    Union,
    cast,
)

import numpy as np

from ._wire import (
    JSON,
    AttractorRequest,
    AxisRequest,
    BasinsLine,
    BasinsRequest,
    BasinsResultLine,
    AxisSpec,
    ConvergenceLine,
    ConvergenceResultLine,
    EnergyRequest,
    MapLine,
    MapResultLine,
    MethodSpec,
    OutputOptions,
    ParamValue,
    RecognitionRequest,
    SectionRequest,
    SimulateRequest,
    EnergySurfaceRequest,
    ExitRequest,
    Indicator,
    StopWhenRequest,
    StopWhenThresholds,
    StudyLine,
    SweepLine,
    SweepResultLine,
    SystemDefinition,
    SystemRequest,
    WorkPrecisionResultLine,
)
from .catalog import Definition, System
from ._names import WIRE, StateNames, is_wire
from .errors import ValidationError
from .simulation import Simulation
from .maps import (
    EnergyMap,
    StabilityMaps,
)
from .studies import (
    Axis,
    Sweep,
    WorkPrecision,
)


SystemLike = Union[str, SystemDefinition, System, Definition]
"""A system: a built-in or stored id, a definition, or a catalogue entry."""
Methods = Union[MethodSpec, Sequence[MethodSpec]]
"""One method (an id, or an object with options such as ``{"id": "modin_rks", "inner": "rk4"}``),
or several."""
Vector = Union[Sequence[float], "np.ndarray[Any, Any]"]
AxisLike = Union[Axis, AxisRequest, Tuple[str, float, float, int], Tuple[str, float, float, int, str]]
"""An axis of a sweep: an :class:`Axis`, a dict as the API takes it, or ``(name, min, max, n)``
with an optional scale."""
GridAxis = Union[AxisSpec, Tuple[float, float, int]]
"""An axis of a stability map: ``{"min", "max", "n"}`` or ``(min, max, n)``."""
SectionLike = Union[str, SectionRequest]
"""A Poincaré section: the expression S of the surface S = 0 (crossed upwards), or
``{"where": S, "direction": "up" | "down" | "both", "max_points": N}``, or a stroboscopic
section ``{"period": T, "phase": φ}``."""
StopWhenLike = Union[str, StopWhenRequest]
"""What ends each run before ``t_end``: the expression S (its first crossing of S = 0 either
way), or ``{"where": S, "direction": "up" | "down" | "both", "count": n}``, or thresholds of
the indicators (``{"megno_mean": 8}``; ``lyapunov_max``, ``megno``, ``megno_mean`` and ``fli``
reached from below, ``sali`` and ``gali`` falling to theirs), or a surface and thresholds
together (whichever comes first)."""
Indicators = Union[Indicator, Sequence[Indicator]]
"""One chaos indicator (``lyapunov``, ``megno``, ``fli``, ``sali``, ``gali``) or several."""
EnergySurfaceLike = Union[EnergySurfaceRequest, Tuple[float, str]]
"""A sweep's energy surface: ``{"energy": E, "solve_for": "p_x"}`` or ``(E, "p_x")``, the
momentum by name or as ``p0[i]`` (a simulation's ``{"value", "momentum"}`` is taken too)."""

THRESHOLDS = ("lyapunov_max", "megno", "megno_mean", "fli", "sali", "gali")
INDICATOR_NAMES = ("lyapunov", "megno", "fli", "sali", "gali")
EnergyLike = Union[EnergyRequest, Tuple[float, str]]
"""An energy level: ``{"value": E, "momentum": name}`` or ``(E, name)``, the momentum by name
(``p_x``) or as ``p0[i]`` (a sweep's ``{"energy", "solve_for"}`` is taken too)."""
Result = Union[Simulation, Sweep, StabilityMaps, EnergyMap, WorkPrecision]
AnyStudyLine = Union[SweepLine, MapLine, ConvergenceLine, StudyLine, BasinsLine]
StudyResult = Union[SweepResultLine, MapResultLine, ConvergenceResultLine, WorkPrecisionResultLine,
                    BasinsResultLine]
ExitLike = Union[ExitRequest, Tuple[str, str], Tuple[str, str, str]]
"""An exit of a basin map: ``{"name", "where", "direction"}``, or ``(name, where)`` with an
optional direction (``up``, ``down``, ``both``)."""
AttractorLike = Union[AttractorRequest, Tuple[str, Any, float]]
"""An attractor known in advance: ``{"name", "points", "radius"}`` or ``(name, points, radius)``,
``points`` rows of q then p."""


def _plain(value: Any, where: str) -> Any:
    """``value`` as plain JSON data (numpy arrays and scalars, tuples become lists and numbers),
    refusing numbers that are not finite with the field named: JSON has none, and the server
    would refuse them anyway."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    elif isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, int):
        return value
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValidationError(where, f"must be a finite number, not {value!r}")
        return value
    if isinstance(value, Mapping):
        return {str(k): _plain(v, f"{where}.{k}" if where else str(k)) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v, f"{where}[{i}]") for i, v in enumerate(value)]
    raise ValidationError(where, f"cannot be sent as JSON: {type(value).__name__}")


def _positive(value: float, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValidationError(where, f"must be a number, not {type(value).__name__}", code="invalid_type")
    number = float(value)
    if not math.isfinite(number) or number <= 0:
        raise ValidationError(where, f"must be a finite number > 0, not {value!r}")
    return number


def _count(value: int, where: str, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValidationError(where, f"must be a whole number, not {value!r}", code="invalid_type")
    if value < minimum:
        raise ValidationError(where, f"must be at least {minimum}, not {value}")
    return int(value)


def _method_list(methods: Methods, where: str = "methods") -> List[MethodSpec]:
    items: List[Any] = [methods] if isinstance(methods, (str, Mapping)) else list(methods)
    if not items:
        raise ValidationError(where, "give at least one method")
    for i, m in enumerate(items):
        if not isinstance(m, (str, Mapping)):
            raise ValidationError(f"{where}[{i}]", "a method is an id or an object with `id`",
                                  code="invalid_type")
    return cast(List[MethodSpec], _plain(items, where))


def _system(system: SystemLike) -> SystemRequest:
    if isinstance(system, (System, Definition)):
        return system.id
    if isinstance(system, str):
        return system
    if isinstance(system, Mapping):
        return cast(SystemDefinition, _plain(system, "system"))
    raise ValidationError("system", "give a system id, a definition (a dict) or a catalogue entry",
                          code="invalid_type")


def _axis(axis: AxisLike, where: str, names: Optional[StateNames] = None) -> AxisRequest:
    """A sweep axis as the request has it; with ``names``, a coordinate or momentum given by
    name (``y``, ``p_y``) becomes ``q0[i]``/``p0[i]`` and a bare parameter ``params.<name>``."""
    if isinstance(axis, Axis):
        out: AxisRequest = {"name": axis.name, "min": axis.min, "max": axis.max, "n": axis.n,
                            "scale": axis.scale}
    elif isinstance(axis, Mapping):
        out = cast(AxisRequest, dict(axis))
    elif isinstance(axis, tuple) and len(axis) in (4, 5):
        out = {"name": axis[0], "min": axis[1], "max": axis[2], "n": axis[3]}
        if len(axis) == 5:
            out["scale"] = axis[4]
    else:
        raise ValidationError(where, "an axis is an Axis, a dict or (name, min, max, n[, scale])",
                              code="invalid_type")
    for key in ("name", "min", "max", "n"):
        if key not in out:
            raise ValidationError(f"{where}.{key}", "is missing", code="missing_field")
    _count(out["n"], f"{where}.n")
    if names is not None and isinstance(out["name"], str) and not is_wire(out["name"]):
        out["name"] = names.axis(out["name"], f"{where}.name")
    return cast(AxisRequest, _plain(out, where))


def _axes(axes: Union[AxisLike, Sequence[AxisLike]], names: Optional[StateNames], study: str) -> List[AxisRequest]:
    """The one or two axes of a sweep or a basin map (one axis may be given alone)."""
    if isinstance(axes, (Axis, Mapping)) or (isinstance(axes, tuple) and axes and isinstance(axes[0], str)):
        axes = [cast(AxisLike, axes)]
    items = list(cast(Sequence[AxisLike], axes))
    if not 1 <= len(items) <= 2:
        raise ValidationError("axes", f"{study} has one or two axes, not {len(items)}")
    return [_axis(a, f"axes[{i}]", names) for i, a in enumerate(items)]


def _grid_axis(axis: GridAxis, where: str) -> AxisSpec:
    if isinstance(axis, Mapping):
        out = cast(AxisSpec, dict(axis))
    elif isinstance(axis, tuple) and len(axis) == 3:
        out = {"min": axis[0], "max": axis[1], "n": axis[2]}
    else:
        raise ValidationError(where, "an axis is {'min', 'max', 'n'} or (min, max, n)", code="invalid_type")
    for key in ("min", "max", "n"):
        if key not in out:
            raise ValidationError(f"{where}.{key}", "is missing", code="missing_field")
    return cast(AxisSpec, _plain(out, where))


def _section(section: SectionLike) -> SectionRequest:
    if isinstance(section, str):
        return {"where": section}
    if not isinstance(section, Mapping):
        raise ValidationError("section", "a section is an expression, {'where', 'direction', 'max_points'} "
                              "or {'period', 'phase'}", code="invalid_type")
    if "where" in section and "period" in section:
        raise ValidationError("section", "give either `where` or `period`, not both")
    if "where" not in section and "period" not in section:
        raise ValidationError("section", "give the surface `where`, or a stroboscopic `period`",
                              code="missing_field")
    out = cast(SectionRequest, _plain(section, "section"))
    if "max_points" in out:
        _count(out["max_points"], "section.max_points")
    if "period" in out:
        _positive(out["period"], "section.period")
    return out


def _exits(exits: Union[ExitLike, Sequence[ExitLike]]) -> List[ExitRequest]:
    """A basin map's exits: each a surface S = 0 with its name and the direction it is left in."""
    if isinstance(exits, Mapping) or (isinstance(exits, tuple) and exits and isinstance(exits[0], str)):
        exits = [cast(ExitLike, exits)]
    out: List[ExitRequest] = []
    for i, exit in enumerate(cast(Sequence[ExitLike], exits)):
        where = f"exits[{i}]"
        if isinstance(exit, tuple) and len(exit) in (2, 3):
            members: Dict[str, Any] = {"name": exit[0], "where": exit[1]}
            if len(exit) == 3:
                members["direction"] = exit[2]
        elif isinstance(exit, Mapping):
            members = dict(exit)
        else:
            raise ValidationError(where, "an exit is {'name', 'where', 'direction'} or (name, where[, direction])",
                                  code="invalid_type")
        for key in ("name", "where"):
            if key not in members:
                raise ValidationError(f"{where}.{key}", "is missing", code="missing_field")
        for key in ("name", "where", "direction"):
            if key in members and not isinstance(members[key], str):
                raise ValidationError(f"{where}.{key}", f"must be a string, not {members[key]!r}",
                                      code="invalid_type")
        if members.get("direction", "both") not in ("up", "down", "both"):
            raise ValidationError(f"{where}.direction", f"is up, down or both, not {members['direction']!r}")
        out.append(cast(ExitRequest, _plain(members, where)))
    return out


def _recognition(recognition: RecognitionRequest) -> RecognitionRequest:
    """A basin map's ``recognition``: ``period``, ``max_period``, ``tolerance``, ``escape_radius``,
    ``angles``."""
    if not isinstance(recognition, Mapping):
        raise ValidationError("recognition", "give {'period', 'max_period', 'tolerance', 'escape_radius', "
                              "'angles'}", code="invalid_type")
    members = dict(cast(Mapping[str, Any], recognition))
    for key in ("period", "tolerance", "escape_radius"):
        if key in members:
            _positive(members[key], f"recognition.{key}")
    if "max_period" in members:
        _count(members["max_period"], "recognition.max_period")
    if "angles" in members:
        angles = members["angles"]
        if isinstance(angles, str):
            angles = [angles]
        if not isinstance(angles, (list, tuple)) or not all(isinstance(a, str) for a in angles):
            raise ValidationError("recognition.angles", f"is a list of coordinate names such as ['theta'], "
                                  f"not {angles!r}", code="invalid_type")
        members["angles"] = list(angles)
    return cast(RecognitionRequest, _plain(members, "recognition"))


def _attractors(attractors: Union[AttractorLike, Sequence[AttractorLike]]) -> List[AttractorRequest]:
    """A basin map's attractors known in advance: each a name, its points (rows of q then p) and a
    radius."""
    if isinstance(attractors, Mapping) or (isinstance(attractors, tuple) and attractors
                                           and isinstance(attractors[0], str)):
        attractors = [cast(AttractorLike, attractors)]
    out: List[AttractorRequest] = []
    for i, attractor in enumerate(cast(Sequence[AttractorLike], attractors)):
        where = f"attractors[{i}]"
        if isinstance(attractor, tuple) and len(attractor) == 3:
            members: Dict[str, Any] = dict(zip(("name", "points", "radius"), attractor))
        elif isinstance(attractor, Mapping):
            members = dict(attractor)
        else:
            raise ValidationError(where, "an attractor is {'name', 'points', 'radius'} or (name, points, radius)",
                                  code="invalid_type")
        for key in ("name", "points", "radius"):
            if key not in members:
                raise ValidationError(f"{where}.{key}", "is missing", code="missing_field")
        if not isinstance(members["name"], str):
            raise ValidationError(f"{where}.name", f"must be a string, not {members['name']!r}", code="invalid_type")
        try:
            points = np.asarray(members["points"], dtype=float)
        except (TypeError, ValueError):
            points = np.empty((0, 0))
        if points.ndim == 1:
            points = points[None, :]
        if points.ndim != 2 or points.shape[0] == 0:
            raise ValidationError(f"{where}.points", "is a list of points of equal length, each q then p, such as "
                                  "[[-1, 0]]", code="invalid_type")
        if not np.isfinite(points).all():
            raise ValidationError(f"{where}.points", "holds a number that is not finite")
        members["points"] = points.tolist()
        _positive(members["radius"], f"{where}.radius")
        out.append(cast(AttractorRequest, _plain(members, where)))
    return out


def _stop_when(stop_when: StopWhenLike) -> StopWhenRequest:
    if isinstance(stop_when, str):
        return {"where": stop_when}
    if not isinstance(stop_when, Mapping):
        raise ValidationError("stop_when", "give an expression, {'where', 'direction', 'count'} or thresholds "
                              "such as {'megno_mean': 8}", code="invalid_type")
    members = cast(Mapping[str, Any], stop_when)
    if "where" not in members:
        for key in ("direction", "count"):
            if key in members:
                raise ValidationError("stop_when.where", f"is missing: `{key}` goes with a surface `where`",
                                      code="missing_field")
        if not any(k in members for k in THRESHOLDS):
            raise ValidationError("stop_when", "give the surface `where`, or a threshold of "
                                  + ", ".join(f"`{k}`" for k in THRESHOLDS), code="missing_field")
    if "count" in members:
        _count(members["count"], "stop_when.count")
    for key in THRESHOLDS:
        value = members.get(key)
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float, np.number))):
            raise ValidationError(f"stop_when.{key}", f"a threshold is a number, not {value!r}", code="invalid_type")
    return cast(StopWhenRequest, _plain(members, "stop_when"))


def _thresholds(stop_when: Mapping[str, float]) -> StopWhenThresholds:
    """A sweep's ``stop_when``: thresholds only (a sweep's cells have no event surface)."""
    if not isinstance(stop_when, Mapping):
        raise ValidationError("stop_when", "a sweep's stop_when is thresholds, such as {'megno_mean': 8}",
                              code="invalid_type")
    for key in ("where", "direction", "count"):
        if key in stop_when:
            raise ValidationError(f"stop_when.{key}", "a sweep stops on thresholds only, not on an event")
    return cast(StopWhenThresholds, _stop_when(cast(StopWhenRequest, stop_when)))


def _indicators(indicators: Indicators) -> List[Indicator]:
    items: List[Any] = [indicators] if isinstance(indicators, str) else list(indicators)
    for i, name in enumerate(items):
        if name not in INDICATOR_NAMES:
            raise ValidationError(f"indicators[{i}]", f"{name!r} is not one of {', '.join(INDICATOR_NAMES)}")
    return cast(List[Indicator], items)


def _energy_members(energy: Union[EnergyLike, EnergySurfaceLike], where: str) -> Tuple[Any, Any]:
    """The energy and the momentum of an energy level in any of its spellings: ``(E, name)``,
    ``{"value": E, "momentum": name}`` (a simulation's) or ``{"energy": E, "solve_for": name}``
    (a sweep's)."""
    if isinstance(energy, tuple) and len(energy) == 2:
        return energy[0], energy[1]
    if not isinstance(energy, Mapping):
        raise ValidationError(where, "an energy level is (E, momentum), {'value': E, 'momentum': name} or "
                              "{'energy': E, 'solve_for': name}", code="invalid_type")
    members = cast(Mapping[str, Any], energy)
    for value_key, momentum_key in (("value", "momentum"), ("energy", "solve_for")):
        if value_key in members or momentum_key in members:
            for key in (value_key, momentum_key):
                if key not in members:
                    raise ValidationError(f"{where}.{key}", "is missing", code="missing_field")
            extra = sorted(set(members) - {value_key, momentum_key})
            if extra:
                raise ValidationError(f"{where}.{extra[0]}", f"is not a member of an energy level "
                                      f"(it has `{value_key}` and `{momentum_key}`)", code="unknown_field")
            return members[value_key], members[momentum_key]
    raise ValidationError(f"{where}.value", "is missing", code="missing_field")


def _energy_surface(surface: Union[EnergyLike, EnergySurfaceLike], names: Optional[StateNames],
                    where: str = "energy_surface") -> EnergySurfaceRequest:
    """A sweep's energy surface; the momentum by name (``p_x``, when ``names`` are known) or as
    ``p0[i]``."""
    energy, momentum = _energy_members(surface, where)
    if not isinstance(momentum, str):
        raise ValidationError(f"{where}.solve_for", "give the momentum to solve for by name ('p_x') or as `p0[i]`",
                              code="invalid_type")
    if names is not None:
        momentum = names.momentum_wire(momentum, f"{where}.solve_for")
    return cast(EnergySurfaceRequest, _plain({"energy": energy, "solve_for": momentum}, where))


def _energy(energy: Union[EnergyLike, EnergySurfaceLike],
            names: Optional[Callable[[], Optional[StateNames]]] = None) -> EnergyRequest:
    """A simulation's energy level; the momentum by name, or as ``p0[i]`` when ``names`` can
    name it (the server takes names)."""
    value, momentum = _energy_members(energy, "energy")
    if not isinstance(momentum, str):
        raise ValidationError("energy.momentum", "give the name of one of the system's momenta",
                              code="invalid_type")
    if WIRE.fullmatch(momentum):
        known = names() if names is not None else None
        if known is None:
            raise ValidationError("energy.momentum", f"give the momentum by its name, not as {momentum!r} "
                                  "(this system's names are not known here)")
        momentum = known.momentum_name(momentum, "energy.momentum")
    return cast(EnergyRequest, _plain({"value": value, "momentum": momentum}, "energy"))


def _is_error_body(body: object) -> bool:
    """Whether ``body`` has the service's error shape, ``{"error": {"code", "message", …}}``."""
    detail = body.get("error") if isinstance(body, dict) else None
    return isinstance(detail, dict) and isinstance(detail.get("code"), str) and isinstance(detail.get("message"), str)


def _put(body: Any, key: str, value: Any) -> None:
    """Sets ``body[key]`` to ``value`` as JSON data, unless ``value`` is None (left to the
    server's default)."""
    if value is not None:
        body[key] = _plain(value, key)


def _put_indicators(
    body: Any, indicators: Optional[Indicators], deviations: Optional[int], qr_every: Optional[int]
) -> None:
    """Sets the chaos indicators' members of a simulation's or a sweep's body, where given."""
    if indicators is not None:
        body["indicators"] = _indicators(indicators)
    if deviations is not None:
        body["deviations"] = _count(deviations, "deviations")
    if qr_every is not None:
        body["qr_every"] = _count(qr_every, "qr_every")


def simulate_request(
    system: SystemLike,
    methods: Methods,
    *,
    h: float,
    t_end: float,
    params: Optional[Mapping[str, ParamValue]] = None,
    q0: Optional[Vector] = None,
    p0: Optional[Vector] = None,
    chart: Optional[str] = None,
    initial_coordinates: Optional[str] = None,
    every: Optional[int] = None,
    compare_to_reference: Optional[bool] = None,
    jacobian_defect: Optional[bool] = None,
    section: Optional[SectionLike] = None,
    stop_when: Optional[StopWhenLike] = None,
    energy: Optional[EnergyLike] = None,
    indicators: Optional[Indicators] = None,
    deviations: Optional[int] = None,
    qr_every: Optional[int] = None,
    names: Optional[Callable[[], Optional[StateNames]]] = None,
) -> SimulateRequest:
    """The body of ``POST /api/v1/simulate`` for :meth:`Client.simulate`'s arguments (and
    :func:`geomint.local.simulate`'s), checked as far as the client can check it. ``names``
    gives the system's state names when an energy level's momentum is written ``p0[i]`` (the
    server takes momenta by name)."""
    body: SimulateRequest = {
        "system": _system(system),
        "methods": _method_list(methods),
        "h": _positive(h, "h"),
        "t_end": _positive(t_end, "t_end"),
    }
    if len(body["methods"]) > 16:
        raise ValidationError("methods", f"at most 16 methods, not {len(body['methods'])}")
    _put(body, "params", params)
    _put(body, "q0", q0)
    _put(body, "p0", p0)
    _put(body, "chart", chart)
    _put(body, "initial_coordinates", initial_coordinates)
    if every is not None:
        output: OutputOptions = {"every": _count(every, "output.every")}
        body["output"] = output
    _put(body, "compare_to_reference", compare_to_reference)
    _put(body, "jacobian_defect", jacobian_defect)
    if section is not None:
        body["section"] = _section(section)
    if stop_when is not None:
        body["stop_when"] = _stop_when(stop_when)
    if energy is not None:
        body["energy"] = _energy(energy, names)
    _put_indicators(body, indicators, deviations, qr_every)
    return body


def basins_request(
    system: SystemLike,
    methods: Methods,
    axes: Union[AxisLike, Sequence[AxisLike]],
    t_end: float,
    *,
    h: float,
    names: Optional[StateNames] = None,
    exits: Optional[Union[ExitLike, Sequence[ExitLike]]] = None,
    recognition: Optional[RecognitionRequest] = None,
    attractors: Optional[Union[AttractorLike, Sequence[AttractorLike]]] = None,
    params: Optional[Mapping[str, ParamValue]] = None,
    q0: Optional[Vector] = None,
    p0: Optional[Vector] = None,
    chart: Optional[str] = None,
    initial_coordinates: Optional[str] = None,
    energy: Optional[EnergyLike] = None,
    energy_surface: Optional[EnergySurfaceLike] = None,
) -> BasinsRequest:
    """The body of ``POST /api/v1/studies/basins`` for :meth:`Client.basins`'s arguments, checked
    as far as the client can check it; with ``names``, axes and the energy level's momentum may
    name state components (``y``, ``p_y``)."""
    body: BasinsRequest = {
        "system": _system(system),
        "methods": _method_list(methods),
        "h": _positive(h, "h"),
        "t_end": _positive(t_end, "t_end"),
        "axes": _axes(axes, names, "a basin map"),
    }
    _put(body, "params", params)
    _put(body, "chart", chart)
    _put(body, "initial_coordinates", initial_coordinates)
    _put(body, "q0", q0)
    _put(body, "p0", p0)
    if energy is not None and energy_surface is not None:
        raise ValidationError("energy", "give the energy level once: `energy` or `energy_surface`, not both")
    if energy is not None:
        body["energy_surface"] = _energy_surface(energy, names, "energy")
    elif energy_surface is not None:
        body["energy_surface"] = _energy_surface(energy_surface, names)
    if exits is not None:
        body["exits"] = _exits(exits)
    if recognition is not None:
        body["recognition"] = _recognition(recognition)
    if attractors is not None:
        body["attractors"] = _attractors(attractors)
    return body
