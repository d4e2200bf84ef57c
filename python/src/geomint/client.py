"""The HTTP client of a geomint server."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import (
    TYPE_CHECKING,
    Any,
    Callable,
    Dict,
    List,
    Mapping,
    Optional,
    Sequence,
    Tuple,
    TypedDict,
    Union,
    cast,
)
from urllib.parse import quote

if TYPE_CHECKING:  # the keyword arguments' types (typing.Unpack from Python 3.11 on)
    from typing_extensions import Unpack

import httpx
import numpy as np

from ._version import __version__
from ._progress import Progress
from ._wire import (
    JSON,
    NDJSON,
    ROUTES,
    RRD,
    AxisRequest,
    AxisSpec,
    ConvergenceLine,
    ConvergenceRequest,
    ConvergenceResultLine,
    DampingEntry,
    EnergyMapRequest,
    EnergyRequest,
    ErrorBody,
    ErrorDetail,
    Health,
    MapLine,
    MapResultLine,
    MassEntry,
    MethodSpec,
    OutputOptions,
    ParamValue,
    PointRequest,
    Preset,
    RecordingCreated,
    ReferenceRun,
    Route,
    RunSpec,
    SectionRequest,
    SimulateRequest,
    StabilityRequest,
    EnergySurfaceRequest,
    Indicator,
    StopWhenRequest,
    StopWhenThresholds,
    StoredSystem,
    StreamLine,
    StudyLine,
    SweepLine,
    SweepRequest,
    SweepResultLine,
    SystemDefinition,
    SystemRequest,
    WorkPrecisionRequest,
    WorkPrecisionResultLine,
)
from .catalog import Definition, Method, System
from .errors import GeomintError, ServerError, ValidationError
from .recording import RRD_MAGIC, Recording, RecordingInfo
from .simulation import Simulation, StreamAssembler
from .studies import (
    Axis,
    Convergence,
    EnergyMap,
    StabilityMaps,
    StabilityPoint,
    Sweep,
    WorkPrecision,
)

DEFAULT_URL = "http://127.0.0.1:8080"

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
"""A sweep's energy surface: ``{"energy": E, "solve_for": "p0[i]"}`` or ``(E, "p0[i]")``."""

THRESHOLDS = ("lyapunov_max", "megno", "megno_mean", "fli", "sali", "gali")
INDICATOR_NAMES = ("lyapunov", "megno", "fli", "sali", "gali")
EnergyLike = Union[EnergyRequest, Tuple[float, str]]
"""An energy level: ``{"value": E, "momentum": name}`` or ``(E, name)``."""
Result = Union[Simulation, Sweep, StabilityMaps, EnergyMap, WorkPrecision]
AnyStudyLine = Union[SweepLine, MapLine, ConvergenceLine, StudyLine]
StudyResult = Union[SweepResultLine, MapResultLine, ConvergenceResultLine, WorkPrecisionResultLine]


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


def _axis(axis: AxisLike, where: str) -> AxisRequest:
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
    return cast(AxisRequest, _plain(out, where))


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


def _energy_surface(surface: EnergySurfaceLike) -> EnergySurfaceRequest:
    if isinstance(surface, tuple) and len(surface) == 2:
        out: Dict[str, Any] = {"energy": surface[0], "solve_for": surface[1]}
    elif isinstance(surface, Mapping):
        out = dict(surface)
    else:
        raise ValidationError("energy_surface", "an energy surface is {'energy', 'solve_for'} or (energy, 'p0[i]')",
                              code="invalid_type")
    for key in ("energy", "solve_for"):
        if key not in out:
            raise ValidationError(f"energy_surface.{key}", "is missing", code="missing_field")
    if not isinstance(out["solve_for"], str):
        raise ValidationError("energy_surface.solve_for", "give the momentum to solve for as `p0[i]`",
                              code="invalid_type")
    return cast(EnergySurfaceRequest, _plain(out, "energy_surface"))


def _energy(energy: EnergyLike) -> EnergyRequest:
    if isinstance(energy, tuple) and len(energy) == 2:
        out: Dict[str, Any] = {"value": energy[0], "momentum": energy[1]}
    elif isinstance(energy, Mapping):
        out = dict(energy)
    else:
        raise ValidationError("energy", "an energy level is {'value', 'momentum'} or (value, momentum)",
                              code="invalid_type")
    for key in ("value", "momentum"):
        if key not in out:
            raise ValidationError(f"energy.{key}", "is missing", code="missing_field")
    if not isinstance(out["momentum"], str):
        raise ValidationError("energy.momentum", "give the name of one of the system's momenta",
                              code="invalid_type")
    return cast(EnergyRequest, _plain(out, "energy"))


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


class SimulateOptions(TypedDict, total=False):
    """A simulation's options beside its system, methods, ``h`` and ``t_end``, as
    :meth:`Client.simulate` and :func:`geomint.local.simulate` take them (``None``: not given)."""

    params: Optional[Mapping[str, ParamValue]]
    q0: Optional[Vector]
    p0: Optional[Vector]
    chart: Optional[str]
    initial_coordinates: Optional[str]
    every: Optional[int]
    compare_to_reference: Optional[bool]
    jacobian_defect: Optional[bool]
    section: Optional[SectionLike]
    stop_when: Optional[StopWhenLike]
    energy: Optional[EnergyLike]
    indicators: Optional[Indicators]
    deviations: Optional[int]
    qr_every: Optional[int]


def simulate_request(
    system: SystemLike,
    methods: Methods,
    *,
    h: float,
    t_end: float,
    **options: Unpack[SimulateOptions],
) -> SimulateRequest:
    """The body of ``POST /api/v1/simulate`` for :meth:`Client.simulate`'s arguments (and
    :func:`geomint.local.simulate`'s), checked as far as the client can check it."""
    every, section = options.get("every"), options.get("section")
    stop_when, energy = options.get("stop_when"), options.get("energy")
    indicators, deviations = options.get("indicators"), options.get("deviations")
    qr_every = options.get("qr_every")
    body: SimulateRequest = {
        "system": _system(system),
        "methods": _method_list(methods),
        "h": _positive(h, "h"),
        "t_end": _positive(t_end, "t_end"),
    }
    if len(body["methods"]) > 16:
        raise ValidationError("methods", f"at most 16 methods, not {len(body['methods'])}")
    _put(body, "params", options.get("params"))
    _put(body, "q0", options.get("q0"))
    _put(body, "p0", options.get("p0"))
    _put(body, "chart", options.get("chart"))
    _put(body, "initial_coordinates", options.get("initial_coordinates"))
    if every is not None:
        output: OutputOptions = {"every": _count(every, "output.every")}
        body["output"] = output
    _put(body, "compare_to_reference", options.get("compare_to_reference"))
    _put(body, "jacobian_defect", options.get("jacobian_defect"))
    if section is not None:
        body["section"] = _section(section)
    if stop_when is not None:
        body["stop_when"] = _stop_when(stop_when)
    if energy is not None:
        body["energy"] = _energy(energy)
    _put_indicators(body, indicators, deviations, qr_every)
    return body


class Client:
    """A geomint server's API as Python calls.

    >>> client = Client("http://127.0.0.1:8080")          # doctest: +SKIP
    >>> run = client.simulate("pendulum", ["modin_3s", "heun"], h=0.1, t_end=200)  # doctest: +SKIP
    >>> run["heun"].energy[-1]                             # doctest: +SKIP

    ``url`` defaults to the environment's ``GEOMINT_URL``, else ``http://127.0.0.1:8080``.
    ``token``, when given, is sent as ``Authorization: Bearer <token>`` with every request.
    ``timeout`` bounds each wait for the server in seconds (``None``: no bound); studies with a
    progress bar stream, so the bound applies between two lines, not to the whole study.
    Refusals raise :class:`~geomint.GeomintError` with the server's ``code``, ``field`` and
    ``position``. Use it as a context manager, or call :meth:`close`, to release its connections.
    """

    def __init__(
        self,
        url: Optional[str] = None,
        token: Optional[str] = None,
        *,
        timeout: Optional[float] = 300.0,
        transport: Optional[httpx.BaseTransport] = None,
    ) -> None:
        self.url = (url or os.environ.get("GEOMINT_URL") or DEFAULT_URL).rstrip("/")
        headers = {"user-agent": f"geomint-python/{__version__}"}
        if token is not None:
            headers["authorization"] = f"Bearer {token}"
        self._http = httpx.Client(
            base_url=self.url,
            headers=headers,
            timeout=httpx.Timeout(timeout, connect=10.0 if timeout is None else min(timeout, 10.0)),
            transport=transport,
        )

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Closes the client's connections."""
        self._http.close()

    def __repr__(self) -> str:
        return f"Client({self.url!r})"

    # ----------------------------------------------------------------------------------------
    # Transport

    def _send(
        self,
        name: str,
        *,
        body: Any = None,
        content: Optional[bytes] = None,
        accept: str = JSON,
        query: Optional[Dict[str, str]] = None,
        ids: Optional[Dict[str, str]] = None,
    ) -> httpx.Response:
        route = ROUTES[name]
        request = self._request(route, body=body, content=content, accept=accept, query=query, ids=ids)
        response = self._http.send(request)
        if response.status_code >= 400:
            raise self._error(response)
        return response

    def _request(
        self,
        route: Route,
        *,
        body: Any = None,
        content: Optional[bytes] = None,
        accept: str = JSON,
        query: Optional[Dict[str, str]] = None,
        ids: Optional[Dict[str, str]] = None,
    ) -> httpx.Request:
        path = route.url(**{k: quote(v, safe="") for k, v in (ids or {}).items()})
        headers = {"accept": accept}
        if body is not None:
            content = json.dumps(body, allow_nan=False, ensure_ascii=False).encode("utf-8")
            headers["content-type"] = JSON
        elif content is not None:
            headers["content-type"] = route.request_media
        return self._http.build_request(route.method, path, content=content, headers=headers, params=query)

    @staticmethod
    def _error(response: httpx.Response) -> GeomintError:
        response.read()
        retry = response.headers.get("retry-after")
        retry_after = float(retry) if retry and retry.replace(".", "", 1).isdigit() else None
        try:
            body = response.json()
        except ValueError:
            body = None
        detail: ErrorDetail
        if _is_error_body(body):
            detail = cast(ErrorBody, body)["error"]
        else:
            # Not the service's error shape (a proxy in between, say): the status line and text.
            detail = {"code": f"http_{response.status_code}",
                      "message": f"HTTP {response.status_code} {response.reason_phrase}: {response.text[:200]}"}
        return GeomintError.from_detail(detail, status=response.status_code, retry_after=retry_after)

    def _json(self, name: str, **kwargs: Any) -> Any:
        """The JSON answer of route ``name``; callers give it the route's answer type."""
        return self._send(name, **kwargs).json()

    def _stream(self, name: str, body: Any, handle: Callable[[Any], None]) -> None:
        """POSTs ``body`` asking for NDJSON and calls ``handle`` with each line as it arrives.

        An ``error`` line raises; a stream that ends without its ``end`` line raises. When
        anything interrupts the reading (Ctrl-C in a notebook raises KeyboardInterrupt), the
        connection is closed before the exception goes on, and the server stops computing.
        """
        request = self._request(ROUTES[name], body=body, accept=NDJSON)
        response = self._http.send(request, stream=True)
        try:
            if response.status_code >= 400:
                raise self._error(response)
            ended = False
            for text in response.iter_lines():
                if not text.strip():
                    continue
                line = json.loads(text)
                kind = line.get("type")
                if kind == "error":
                    raise GeomintError.from_detail(line["error"], method=line.get("method"))
                if kind == "end":
                    ended = True
                    break
                handle(line)
            if not ended:
                raise ServerError("stream_cut", "the stream ended before its last line: the server stopped early")
        finally:
            response.close()

    def _rrd(self, name: str, body: Any) -> Recording:
        response = self._send(name, body=body, accept=RRD, query={"format": "rrd"})
        return Recording(response.content)

    # ----------------------------------------------------------------------------------------
    # Catalogues and definitions

    def health(self) -> Health:
        """The server's health: status, version, runs in progress and the most at once."""
        health: Health = self._json("health")
        return health

    def systems(self) -> List[System]:
        """Every system: the built-in ones, then the stored definitions."""
        return [System.from_json(s) for s in self._json("list_systems")]

    def system(self, id: str) -> System:
        """One system's catalogue entry: parameters with ranges, charts, default state."""
        return System.from_json(self._json("get_system", ids={"id": id}))

    def methods(self) -> List[Method]:
        """Every method: order, kind, properties, requirements, citation."""
        return [Method.from_json(m) for m in self._json("list_methods")]

    def define(
        self,
        definition: Optional[SystemDefinition] = None,
        *,
        coordinates: Optional[Sequence[str]] = None,
        potential: Optional[str] = None,
        mass: Optional[MassEntry] = None,
        hamiltonian: Optional[str] = None,
        momenta: Optional[Sequence[str]] = None,
        damping: Optional[DampingEntry] = None,
        parameters: Optional[Mapping[str, float]] = None,
        invariants: Optional[Mapping[str, str]] = None,
        positions: Optional[Sequence[Sequence[Union[float, str]]]] = None,
        q0: Optional[Vector] = None,
        p0: Optional[Vector] = None,
        name: Optional[str] = None,
    ) -> str:
        """Checks a system typed in as text, stores it on the server and returns its id
        (``sys-`` and 16 hex digits: the same definition always gets the same id).

        Give the definition as a dict, or its members as keywords: ``coordinates``, then either
        ``potential`` (with ``mass``, default 1) or ``hamiltonian``; optional ``damping``
        (``{"gamma": γ}`` or ``{"epsilon": ε, "matrix": D(q)}``), ``parameters`` (defaults),
        ``invariants``, ``positions``, ``q0``, ``p0``, ``momenta``, ``name``. A wrong definition
        raises :class:`~geomint.GeomintError` naming the field (``potential``) and, for an
        expression, the character (``position``).
        """
        return self.store_system(
            definition, coordinates=coordinates, potential=potential, mass=mass, hamiltonian=hamiltonian,
            momenta=momenta, damping=damping, parameters=parameters, invariants=invariants,
            positions=positions, q0=q0, p0=p0, name=name,
        ).id

    def store_system(self, definition: Optional[SystemDefinition] = None, **members: Any) -> Definition:
        """As :meth:`define`, returning the stored entry with the facts the server derived
        (dimension, separable or not, the damping's form, the methods that apply)."""
        body: Dict[str, Any] = dict(definition or {})
        for key, value in members.items():
            _put(body, key, value)
        coordinates = body.get("coordinates")
        if not isinstance(coordinates, list) or not all(isinstance(c, str) for c in coordinates):
            raise ValidationError("coordinates", "give the coordinates' names as a list of strings",
                                  code="missing_field" if coordinates is None else "invalid_type")
        stored: StoredSystem = self._json("create_system", body=_plain(body, ""))
        return Definition.from_json(stored)

    def delete_system(self, id: str) -> None:
        """Removes a stored definition (built-in systems cannot be removed)."""
        self._send("delete_system", ids={"id": id})

    # ----------------------------------------------------------------------------------------
    # Simulations

    def simulate(
        self,
        system: SystemLike,
        methods: Methods,
        *,
        h: float,
        t_end: float,
        stream: bool = False,
        progress: bool = True,
        on_line: Optional[Callable[[StreamLine], None]] = None,
        **options: Unpack[SimulateOptions],
    ) -> Simulation:
        """Runs ``methods`` on ``system`` with step ``h`` to ``t_end`` and returns every run's
        samples as numpy arrays.

        ``params`` override the system's defaults; ``q0``/``p0`` the initial state (in ``chart``'s
        coordinates, or Cartesian ones with ``initial_coordinates="cartesian"``); ``every``
        samples every so many steps; ``compare_to_reference`` measures energy errors against the
        adaptive reference (:attr:`Simulation.energy_reference` says what they are measured
        against); ``jacobian_defect`` reports |det ∂Φ/∂z − e^{−2γh}| per step.

        ``section`` collects a Poincaré section of each run: the crossings of a surface S = 0
        (an expression in the coordinates, momenta, parameters and ``t``, e.g. ``"y"``: crossed
        upwards; or ``{"where": "y", "direction": "up" | "down" | "both", "max_points": N}``),
        located to round-off, or the states of a stroboscopic section ``{"period": T,
        "phase": φ}``; each run's points are :attr:`Run.section` and how it went
        :attr:`Run.section_summary`. ``stop_when`` ends each run at an event, the ``count``-th
        crossing of a surface (``{"where": "y", "direction": "up", "count": 3}``; a string is its
        first crossing either way): its stop reason is then ``event`` and the crossings are
        :attr:`Run.events`. ``energy`` starts on an energy level: ``{"value": E, "momentum":
        "py"}`` (or ``(E, "py")``) replaces that initial momentum with the non-negative one for
        which H(q0, p0) = E (the state used is :attr:`Simulation.system`).

        ``indicators`` asks each run for chaos indicators, from ``deviations`` tangent vectors
        (k, 1 to 2n; the server's default is 2n with ``lyapunov`` or ``gali``, 2 with ``sali``,
        else 1) advanced by the method's own tangent map and re-orthonormalised every
        ``qr_every`` steps (default 10): ``lyapunov`` (the finite-time spectrum, a
        samples × k array :attr:`Run.lyapunov`), ``megno`` (:attr:`Run.megno` and
        :attr:`Run.megno_mean`), ``fli``, ``sali``, ``gali``; :attr:`Run.final` has their last
        values. ``stop_when`` may then hold thresholds, ``{"megno_mean": 8}``: a run that
        reaches one stops with the reason ``indicator`` (:class:`~geomint.Stop` names the
        statistic, its value and the threshold).

        With ``stream`` (or through :meth:`stream`) the samples come over the NDJSON stream as
        they are computed, with a progress bar (tqdm, when installed and ``progress`` is true);
        ``on_line`` is called with every line as it arrives. Interrupting a stream (Ctrl-C, or
        the notebook's stop button) closes the connection, which stops the server's run. Both
        ways give the same numbers, bit for bit.
        """
        body = simulate_request(system, methods, h=h, t_end=t_end, **options)
        if not stream:
            return Simulation.from_json(self._json("simulate", body=body), body)

        assembler = StreamAssembler(body)
        with Progress(progress, "samples") as bar:
            def handle(line: StreamLine) -> None:
                if on_line is not None:
                    on_line(line)
                if line["type"] == "header":
                    assembler.header_line(line)
                    bar.total(assembler.total_samples)
                elif line["type"] == "samples":
                    bar.advance(assembler.samples_line(line))
                elif line["type"] == "crossings":
                    assembler.crossings_line(line)
                elif line["type"] == "summary":
                    assembler.summary_line(line)

            self._stream("simulate", body, handle)
        return assembler.simulation()

    def stream(self, system: SystemLike, methods: Methods, **options: Any) -> Simulation:
        """:meth:`simulate` over the NDJSON stream, with a progress bar, ``Ctrl-C`` cancelling the
        server's run; it takes :meth:`simulate`'s keyword arguments (``h``, ``t_end``, …,
        ``progress``, ``on_line``)."""
        return self.simulate(system, methods, stream=True, **options)

    # ----------------------------------------------------------------------------------------
    # Recordings

    def recording(self, of: Result) -> Recording:
        """The Rerun recording of a result (a simulation, sweep, stability maps, energy map or
        work–precision study), computed afresh by the server from the same request (the same
        request gives the same numbers)."""
        if of.request is None:
            raise ValueError("this result carries no request (it was read back from a recording)")
        routes = {Simulation: "simulate", Sweep: "sweep", StabilityMaps: "stability_map",
                  EnergyMap: "energy_map", WorkPrecision: "work_precision"}
        return self._rrd(routes[type(of)], of.request)

    def store(self, of: Simulation) -> Recording:
        """Runs a simulation's request again as a stored recording on the server; returns the
        recording with its id (listed by :meth:`recordings`, read back by :meth:`samples`)."""
        if of.request is None:
            raise ValueError("this simulation carries no request (it was read back from a recording)")
        created: RecordingCreated = self._json("create_recording", body=of.request)
        return self.download(created["id"])

    def upload(self, recording: Union[Recording, bytes, str, "os.PathLike[str]"]) -> Recording:
        """Stores a .rrd file (a :class:`Recording`, bytes, or a path) on the server, which checks
        it first; returns it with its id."""
        if isinstance(recording, Recording):
            data = recording.data
        elif isinstance(recording, bytes):
            data = recording
        else:
            data = Path(recording).read_bytes()
        if not data.startswith(RRD_MAGIC):
            raise ValidationError("body", f"not a Rerun recording (.rrd): it starts with {data[:8]!r}",
                                  code="invalid_recording")
        created: RecordingCreated = self._json("upload_recording", content=data)
        return Recording(data, created["id"])

    def recordings(self) -> List[RecordingInfo]:
        """The stored recordings, newest first."""
        return [RecordingInfo.from_json(e) for e in self._json("list_recordings")]

    def download(self, id: str) -> Recording:
        """A stored recording's file."""
        response = self._send("get_recording", accept=RRD, ids={"id": f"{id}.rrd"})
        return Recording(response.content, id)

    def samples(self, id: str) -> Simulation:
        """A stored simulation recording's runs, read back from the file by the server: energies
        and invariants exact, ``q`` and ``p`` in single precision, no stop reasons or wall times."""
        return Simulation.from_recorded(self._json("recording_samples", ids={"id": id}))

    def delete_recording(self, id: str) -> None:
        """Deletes a stored recording."""
        self._send("delete_recording", ids={"id": id})

    # ----------------------------------------------------------------------------------------
    # Studies

    def _study(self, name: str, body: Any, progress: bool, label: str) -> StudyResult:
        """Runs a study over its NDJSON stream with a progress bar; returns its ``result`` line."""
        result: List[StudyResult] = []
        with Progress(progress, label) as bar:
            def handle(line: AnyStudyLine) -> None:
                if line["type"] == "progress" or line["type"] == "point":
                    bar.total(line["total"])
                    bar.to(line["done"])
                elif line["type"] == "reference":
                    bar.total(line["total"])
                elif line["type"] == "result":
                    result.append(line)

            self._stream(name, body, handle)
        if not result:
            raise ServerError("stream_cut", "the study's stream ended without its result")
        return result[0]

    def sweep_presets(self) -> Dict[str, Preset]:
        """The server's ready-made sweeps by id; ``client.sweep(**preset["request"])`` runs one."""
        presets: List[Preset] = self._json("sweep_presets")
        return {p["id"]: p for p in presets}

    def sweep(
        self,
        system: SystemLike,
        methods: Methods,
        axes: Sequence[AxisLike],
        t_end: float,
        *,
        h: Optional[float] = None,
        charts: Optional[Sequence[str]] = None,
        params: Optional[Mapping[str, ParamValue]] = None,
        q0: Optional[Vector] = None,
        p0: Optional[Vector] = None,
        every: Optional[int] = None,
        energy_reference: Optional[str] = None,
        initial_coordinates: Optional[str] = None,
        indicators: Optional[Indicators] = None,
        deviations: Optional[int] = None,
        qr_every: Optional[int] = None,
        stop_when: Optional[Mapping[str, float]] = None,
        energy_surface: Optional[EnergySurfaceLike] = None,
        section: Optional[SectionLike] = None,
        progress: bool = True,
    ) -> Sweep:
        """Runs ``methods`` (in each of ``charts``) over a grid of one or two axes and returns
        per-cell metrics as arrays on the grid (:meth:`Sweep.to_xarray` gives a Dataset with the
        axes as named coordinates).

        An axis is ``params.<name>``, ``h``, or ``q0[i]``/``p0[i]``, with ``min``, ``max``, ``n``
        and an optional ``scale`` (``linear`` or ``log``): ``("params.gamma", 0, 2, 21)``.
        ``h`` is the step size unless an axis varies it; ``every`` the sampling; ``energy_reference``
        ``exact``, ``initial`` or ``reference``. Interrupting it stops the server's sweep.

        Chaos maps: ``indicators`` (with ``deviations`` and ``qr_every``, as in
        :meth:`simulate`) gives every run's last values per cell (:attr:`SweepRun.megno_mean`,
        …; variables of :meth:`Sweep.to_xarray`), ``stop_when`` thresholds (``{"megno_mean":
        8}``) stop a cell's run early (:attr:`SweepRun.stopped_at`), and ``energy_surface``
        (``{"energy": E, "solve_for": "p0[0]"}`` or ``(E, "p0[0]")``) solves that momentum per
        cell so that H = E while the axes vary the rest of the state (cells where no momentum
        reaches E have an entry in ``errors``).

        ``section`` (as in :meth:`simulate`) collects each cell's section points, up to its
        ``max_points`` per run (:attr:`SweepRun.sections`): a grid of orbits as one result.
        """
        if isinstance(axes, (Axis, Mapping)) or (isinstance(axes, tuple) and axes and isinstance(axes[0], str)):
            axes = [cast(AxisLike, axes)]
        if not 1 <= len(axes) <= 2:
            raise ValidationError("axes", f"a sweep has one or two axes, not {len(axes)}")
        body: SweepRequest = {
            "system": _system(system),
            "methods": _method_list(methods),
            "t_end": _positive(t_end, "t_end"),
            "axes": [_axis(a, f"axes[{i}]") for i, a in enumerate(axes)],
        }
        if h is not None:
            body["h"] = _positive(h, "h")
        elif not any(a["name"] == "h" for a in body["axes"]):
            raise ValidationError("h", "give the step size h, or an axis named h", code="missing_field")
        _put(body, "charts", charts)
        _put(body, "params", params)
        _put(body, "q0", q0)
        _put(body, "p0", p0)
        if every is not None:
            body["every"] = _count(every, "every")
        _put(body, "energy_reference", energy_reference)
        _put(body, "initial_coordinates", initial_coordinates)
        _put_indicators(body, indicators, deviations, qr_every)
        if stop_when is not None:
            body["stop_when"] = _thresholds(stop_when)
        if energy_surface is not None:
            body["energy_surface"] = _energy_surface(energy_surface)
        if section is not None:
            body["section"] = _section(section)
        line = cast(SweepResultLine, self._study("sweep", body, progress, "cells"))
        return Sweep.from_json(line, body)

    def stability(
        self,
        methods: Methods,
        *,
        omega: float,
        gamma: GridAxis,
        h: GridAxis,
    ) -> StabilityMaps:
        """Linear stability maps of the damped oscillator q'' + 2γq' + ω²q = 0 over a (γ, h) grid:
        each method's spectral radius and verdicts, as (h points) × (γ points) arrays. Axes are
        ``(min, max, n)``."""
        body: StabilityRequest = {
            "omega": _positive(omega, "omega"),
            "gamma": _grid_axis(gamma, "gamma"),
            "h": _grid_axis(h, "h"),
            "methods": _method_list(methods),
        }
        return StabilityMaps.from_json(self._json("stability_map", body=body), body)

    def stability_point(self, method: MethodSpec, *, omega: float, gamma: float, h: float) -> StabilityPoint:
        """The stability analysis of one method at one (ω, γ, h): its one-step matrix, spectrum
        and the exact flow's."""
        body: PointRequest = {"omega": _plain(omega, "omega"), "gamma": _plain(gamma, "gamma"),
                              "h": _plain(h, "h"), "method": _method_list(method, "method")[0]}
        return StabilityPoint.from_json(self._json("stability_point", body=body))

    def energy_map(
        self,
        *,
        nx: Optional[int] = None,
        ny: Optional[int] = None,
        x: Optional[Tuple[float, float]] = None,
        y: Optional[Tuple[float, float]] = None,
        h: Optional[float] = None,
        t_max: Optional[float] = None,
        method: Optional[MethodSpec] = None,
        params: Optional[Mapping[str, float]] = None,
        progress: bool = True,
    ) -> EnergyMap:
        """The energy-error map of paper 001 Fig. 6 (symplectic Euler on the planar elastic
        pendulum, Cartesian against polar coordinates) over an ``nx`` × ``ny`` grid of release
        points in the ranges ``x`` and ``y``; every argument has the server's default."""
        body: EnergyMapRequest = {}
        if nx is not None:
            body["nx"] = _count(nx, "nx")
        if ny is not None:
            body["ny"] = _count(ny, "ny")
        _put(body, "x", x)
        _put(body, "y", y)
        if h is not None:
            body["h"] = _positive(h, "h")
        if t_max is not None:
            body["t_max"] = _positive(t_max, "t_max")
        if method is not None:
            body["method"] = _method_list(method, "method")[0]
        _put(body, "params", params)
        line = cast(MapResultLine, self._study("energy_map", body, progress, "cells"))
        return EnergyMap.from_json(line, body)

    def convergence(
        self,
        system: SystemLike,
        methods: Methods,
        h: Sequence[float],
        t_end: float,
        *,
        params: Optional[Mapping[str, ParamValue]] = None,
        chart: Optional[str] = None,
        charts: Optional[Sequence[str]] = None,
        q0: Optional[Vector] = None,
        p0: Optional[Vector] = None,
        initial_coordinates: Optional[str] = None,
        samples: Optional[int] = None,
        reference: Optional[ReferenceRun] = None,
        progress: bool = True,
    ) -> Convergence:
        """Errors at ``t_end`` of ``methods`` (in ``chart`` or each of ``charts``) at each step
        size in ``h`` (each must divide t_end), against the exact solution or a reference run,
        with each series' fitted order."""
        if not h:
            raise ValidationError("h", "give at least one step size")
        body: ConvergenceRequest = {
            "system": _system(system),
            "methods": _method_list(methods),
            "h": [_positive(v, f"h[{i}]") for i, v in enumerate(h)],
            "t_end": _positive(t_end, "t_end"),
        }
        _put(body, "params", params)
        _put(body, "chart", chart)
        _put(body, "charts", charts)
        _put(body, "q0", q0)
        _put(body, "p0", p0)
        _put(body, "initial_coordinates", initial_coordinates)
        if samples is not None:
            body["samples"] = _count(samples, "samples")
        _put(body, "reference", reference)
        line = cast(ConvergenceResultLine, self._study("convergence", body, progress, "settings"))
        return Convergence.from_json(line, body)

    def work_precision(
        self,
        system: SystemLike,
        runs: Sequence[Union[RunSpec, Tuple[MethodSpec, Sequence[float]]]],
        t_end: float,
        *,
        params: Optional[Mapping[str, ParamValue]] = None,
        q0: Optional[Vector] = None,
        p0: Optional[Vector] = None,
        samples: Optional[int] = None,
        reference: Optional[ReferenceRun] = None,
        progress: bool = True,
    ) -> WorkPrecision:
        """Wall time against energy error: each run is ``{"method", "h": [...]}`` (or
        ``{"method": "reference", "tolerance": [...]}``), or ``(method, [h, ...])``; each step
        size must divide t_end/samples. Returns every setting's cost and errors and each method's
        fitted line."""
        specs: List[RunSpec] = []
        for i, run in enumerate(runs):
            if isinstance(run, tuple):
                method, steps = run
                specs.append({"method": _method_list(method, f"runs[{i}].method")[0],
                              "h": [_positive(v, f"runs[{i}].h[{k}]") for k, v in enumerate(steps)]})
            else:
                specs.append(cast(RunSpec, _plain(run, f"runs[{i}]")))
        if not specs:
            raise ValidationError("runs", "give at least one run")
        body: WorkPrecisionRequest = {"system": _system(system), "runs": specs, "t_end": _positive(t_end, "t_end")}
        _put(body, "params", params)
        _put(body, "q0", q0)
        _put(body, "p0", p0)
        if samples is not None:
            body["samples"] = _count(samples, "samples")
        _put(body, "reference", reference)
        line = cast(WorkPrecisionResultLine, self._study("work_precision", body, progress, "settings"))
        return WorkPrecision.from_json(line, body)
