"""The HTTP client of a geomint server."""

from __future__ import annotations

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

from ._arguments import (
    AttractorLike,
    AxisLike,
    EnergyLike,
    EnergySurfaceLike,
    ExitLike,
    GridAxis,
    Indicators,
    Methods,
    Result,
    SectionLike,
    StopWhenLike,
    SystemLike,
    Vector,
    _axes,
    _count,
    _energy_surface,
    _grid_axis,
    _method_list,
    _plain,
    _positive,
    _put,
    _put_indicators,
    _section,
    _system,
    _thresholds,
    basins_request,
    simulate_request,
)
from ._keywords import checked
from ._names import StateNames
from ._transport import DEFAULT_URL
from .jobs import JobCalls
from .library import RecordingCalls
from ._progress import Progress
from ._wire import (
    NDJSON,
    BasinsResultLine,
    RRD,
    ConvergenceRequest,
    ConvergenceResultLine,
    DampingEntry,
    EnergyMapRequest,
    Health,
    MapResultLine,
    MassEntry,
    MethodSpec,
    ParamValue,
    PointRequest,
    Preset,
    RecognitionRequest,
    ReferenceRun,
    RunSpec,
    StabilityRequest,
    StoredSystem,
    StreamLine,
    SweepRequest,
    SweepResultLine,
    SystemDefinition,
    WorkPrecisionRequest,
    WorkPrecisionResultLine,
)
from .catalog import Definition, Method, System
from .errors import GeomintError, RefusedError, ValidationError
from .recording import Recording
from .simulation import Simulation, StreamAssembler
from .maps import (
    EnergyMap,
    StabilityMaps,
    StabilityPoint,
)
from .basins import BasinMap
from .studies import (
    Convergence,
    Sweep,
    WorkPrecision,
)


class Client(JobCalls, RecordingCalls):
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

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Client({self.url!r})"

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

    @checked
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

    @checked
    def store_system(
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
    ) -> Definition:
        """As :meth:`define`, returning the stored entry with the facts the server derived
        (dimension, separable or not, the damping's form, the methods that apply)."""
        body: Dict[str, Any] = dict(definition or {})
        members = {"coordinates": coordinates, "potential": potential, "mass": mass, "hamiltonian": hamiltonian,
                   "momenta": momenta, "damping": damping, "parameters": parameters, "invariants": invariants,
                   "positions": positions, "q0": q0, "p0": p0, "name": name}
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

    @checked
    def simulate(
        self,
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
        stream: bool = False,
        progress: bool = True,
        on_line: Optional[Callable[[StreamLine], None]] = None,
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
        :attr:`Run.events`. ``energy`` starts on an energy level: ``(E, "p_y")`` (or
        ``{"value": E, "momentum": "p_y"}``, or a sweep's ``{"energy": E, "solve_for": "p_y"}``)
        replaces that initial momentum with the non-negative one for which H(q0, p0) = E (the
        state used is :attr:`Simulation.system`); the momentum by name (``p_<coordinate>``
        unless a definition names its momenta) or as ``p0[i]``.

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
        ways give the same numbers, bit for bit. A keyword this method does not take raises
        TypeError naming the nearest one (``param=`` → ``params``).
        """
        body = simulate_request(
            system, methods, h=h, t_end=t_end, params=params, q0=q0, p0=p0, chart=chart,
            initial_coordinates=initial_coordinates, every=every, compare_to_reference=compare_to_reference,
            jacobian_defect=jacobian_defect, section=section, stop_when=stop_when, energy=energy,
            indicators=indicators, deviations=deviations, qr_every=qr_every,
            names=lambda: self._state_names(system, chart=chart),
        )
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

    @checked
    def stream(
        self,
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
        progress: bool = True,
        on_line: Optional[Callable[[StreamLine], None]] = None,
    ) -> Simulation:
        """:meth:`simulate` over the NDJSON stream, with a progress bar, ``Ctrl-C`` cancelling the
        server's run; it takes :meth:`simulate`'s keyword arguments."""
        return self.simulate(
            system, methods, h=h, t_end=t_end, params=params, q0=q0, p0=p0, chart=chart,
            initial_coordinates=initial_coordinates, every=every, compare_to_reference=compare_to_reference,
            jacobian_defect=jacobian_defect, section=section, stop_when=stop_when, energy=energy,
            indicators=indicators, deviations=deviations, qr_every=qr_every, stream=True, progress=progress,
            on_line=on_line,
        )

    def _state_names(
        self,
        system: SystemLike,
        *,
        chart: Optional[str] = None,
        charts: Optional[Sequence[str]] = None,
        initial_coordinates: Optional[str] = None,
    ) -> Optional[StateNames]:
        """The names of ``system``'s coordinates and momenta in the chart a request runs in
        (``None`` when they are not known: an unknown id, or charts that name them differently):
        from a definition, or from the catalogue entry (fetched once per id)."""
        if isinstance(system, Mapping):
            return StateNames.of_definition(system)
        if isinstance(system, Definition):
            return StateNames.of_definition(system.definition)
        if isinstance(system, System):
            entry = system
        else:
            if system not in self._entries:
                try:
                    self._entries[system] = self._json("get_system", ids={"id": system})
                except RefusedError:
                    return None  # the request itself will say what is wrong with the id
            doc = self._entries[system]
            if isinstance(doc.get("definition"), Mapping):
                return StateNames.of_definition(doc["definition"])
            entry = System.from_json(doc)
        asked: List[Optional[str]] = [None]
        if initial_coordinates == "cartesian":
            asked = ["cartesian"]
        elif chart:
            asked = [chart]
        elif charts:
            asked = list(charts)
        found = {StateNames.of_entry(entry, c) for c in asked}
        return found.pop() if len(found) == 1 else None

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

    # ----------------------------------------------------------------------------------------
    # Studies

    def sweep_presets(self) -> Dict[str, Preset]:
        """The server's ready-made sweeps by id; ``client.sweep(**preset["request"])`` runs one."""
        presets: List[Preset] = self._json("sweep_presets")
        return {p["id"]: p for p in presets}

    @checked
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
        energy: Optional[EnergyLike] = None,
        progress: bool = True,
    ) -> Sweep:
        """Runs ``methods`` (in each of ``charts``) over a grid of one or two axes and returns
        per-cell metrics as arrays on the grid (:meth:`Sweep.to_xarray` gives a Dataset with the
        axes as named coordinates).

        An axis is a parameter (``params.<name>``, or its bare name), ``h``, or a component of
        the initial state by name (``"y"``, ``"p_y"``; momenta are ``p_<coordinate>`` unless a
        definition names them) or as ``q0[i]``/``p0[i]``, with ``min``, ``max``, ``n`` and an
        optional ``scale`` (``linear`` or ``log``): ``("params.gamma", 0, 2, 21)``,
        ``("y", -0.3, 0.6, 50)``. :meth:`Sweep.to_xarray` names each axis's dimension after the
        component (``y``, ``p_y``).
        ``h`` is the step size unless an axis varies it; ``every`` the sampling; ``energy_reference``
        ``exact``, ``initial`` or ``reference``. Interrupting it stops the server's sweep.

        Chaos maps: ``indicators`` (with ``deviations`` and ``qr_every``, as in
        :meth:`simulate`) gives every run's last values per cell (:attr:`SweepRun.megno_mean`,
        …; variables of :meth:`Sweep.to_xarray`), ``stop_when`` thresholds (``{"megno_mean":
        8}``) stop a cell's run early (:attr:`SweepRun.stopped_at`), and ``energy``, as in
        :meth:`simulate` (``(E, "p_x")``, ``{"value": E, "momentum": "p_x"}``; or
        ``energy_surface``, ``{"energy": E, "solve_for": "p0[0]"}``: the same, either spelling
        in either keyword), solves that momentum per cell so that H = E while the axes vary the
        rest of the state (cells where no momentum reaches E have an entry in ``errors``).

        ``section`` (as in :meth:`simulate`) collects each cell's section points, up to its
        ``max_points`` per run (:attr:`SweepRun.sections`): a grid of orbits as one result.
        """
        names = self._state_names(system, charts=charts, initial_coordinates=initial_coordinates)
        body: SweepRequest = {
            "system": _system(system),
            "methods": _method_list(methods),
            "t_end": _positive(t_end, "t_end"),
            "axes": _axes(axes, names, "a sweep"),
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
        if energy is not None and energy_surface is not None:
            raise ValidationError("energy", "give the energy level once: `energy` or `energy_surface`, not both")
        if energy is not None:
            body["energy_surface"] = _energy_surface(energy, names, "energy")
        elif energy_surface is not None:
            body["energy_surface"] = _energy_surface(energy_surface, names)
        if section is not None:
            body["section"] = _section(section)
        line = cast(SweepResultLine, self._study("sweep", body, progress, "cells"))
        return Sweep.from_json(line, body, names)

    def basin_presets(self) -> Dict[str, Preset]:
        """The server's ready-made basin maps by id; ``client.basins(**preset["request"])`` runs
        one."""
        presets: List[Preset] = self._json("basins_presets")
        return {p["id"]: p for p in presets}

    @checked
    def basins(
        self,
        system: SystemLike,
        methods: Methods,
        axes: Union[AxisLike, Sequence[AxisLike]],
        t_end: float,
        *,
        h: float,
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
        progress: bool = True,
    ) -> BasinMap:
        """A basin map: where each orbit of a grid of initial states ends up (a damped orbit's
        well, a driven one's periodic orbit, an open system's exit), each cell run until decided
        (``t_end`` at most). Returns a :class:`~geomint.BasinMap`: per method the labels and
        decision times on the grid, the attractors' table, the shares and the metrics (basin
        entropy, boundary basin entropy, uncertainty exponent).

        The one or two axes vary the initial state, by name (``("y", -0.6, 1, 101)``, ``"p_y"``)
        or as ``q0[i]``/``p0[i]``; ``energy``/``energy_surface`` are :meth:`sweep`'s. ``exits``:
        ``{"name": "up", "where": "y - 2", "direction": "up"}`` or ``("up", "y - 2", "up")``;
        ``recognition``: ``period`` (a driven system's, a whole number of steps),
        ``max_period``, ``tolerance``, ``escape_radius``, ``angles`` (coordinates compared modulo
        2π, ``["theta"]``); ``attractors``: ones known in advance, ``{"name": "left", "points":
        [[-1, 0]], "radius": 0.05}`` or ``("left", [[-1, 0]], 0.05)``, which take the first
        labels. The rest are :meth:`simulate`'s (one ``chart``). A progress bar counts the cells; interrupting it stops the server's map."""
        names = self._state_names(system, chart=chart, initial_coordinates=initial_coordinates)
        body = basins_request(
            system, methods, axes, t_end, h=h, names=names, exits=exits, recognition=recognition,
            attractors=attractors, params=params,
            q0=q0, p0=p0, chart=chart, initial_coordinates=initial_coordinates, energy=energy,
            energy_surface=energy_surface,
        )
        line = cast(BasinsResultLine, self._study("basins", body, progress, "cells"))
        return BasinMap.from_json(line, body, names)

    @checked
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

    @checked
    def stability_point(self, method: MethodSpec, *, omega: float, gamma: float, h: float) -> StabilityPoint:
        """The stability analysis of one method at one (ω, γ, h): its one-step matrix, spectrum
        and the exact flow's."""
        body: PointRequest = {"omega": _plain(omega, "omega"), "gamma": _plain(gamma, "gamma"),
                              "h": _plain(h, "h"), "method": _method_list(method, "method")[0]}
        return StabilityPoint.from_json(self._json("stability_point", body=body))

    @checked
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

    @checked
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

    @checked
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
