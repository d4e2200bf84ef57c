"""geomint in this Python process: the integrator core without a server.

:func:`simulate` takes :meth:`Client.simulate`'s arguments (but for streaming, which a run in
the same process does not need) and returns the same :class:`~geomint.Simulation`. The request
is read by the service's own reader and run by the same core (the compiled module
``geomint_native``, from the wheel ``crates/geomint-py`` builds), so the numbers are the server's
bit for bit and a request the server would refuse raises the same
:class:`~geomint.RefusedError` (with its ``code``, ``field`` and ``position``; ``status`` is
``None``). The run computes with the interpreter released, so other Python threads go on
meanwhile. Stored systems (``sys-…`` ids) live on a server: give the definition itself here.

>>> from geomint import local                                        # doctest: +SKIP
>>> sim = local.simulate("pendulum", ["modin_3s"], h=0.01, t_end=10_000, every=1_000_000)  # doctest: +SKIP
"""

from __future__ import annotations

import json
from types import ModuleType
from collections.abc import Mapping as MappingABC
from typing import Mapping, Optional

from ._arguments import (
    EnergyLike,
    Indicators,
    Methods,
    SectionLike,
    StopWhenLike,
    SystemLike,
    Vector,
    simulate_request,
)
from ._keywords import checked
from ._names import StateNames
from ._wire import ParamValue
from .catalog import Definition
from .errors import GeomintError, ServerError
from .simulation import Simulation


def _native() -> ModuleType:
    try:
        import geomint_native
    except ImportError as e:  # pragma: no cover - the test command installs it
        raise ImportError(
            "geomint.local needs the compiled module geomint_native, which `pip install ./python` "
            "builds when a Rust toolchain (cargo) is on the PATH; or build its wheel with "
            "`maturin build --release -m crates/geomint-py/Cargo.toml` and pip install it"
        ) from e
    module: ModuleType = geomint_native
    return module


@checked
def simulate(
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
) -> Simulation:
    """Runs ``methods`` on ``system`` in this process: :meth:`Client.simulate`'s arguments and
    result, the same numbers (an energy level's momentum is given by name here, or as ``p0[i]``
    with a definition, whose names the client reads). A keyword this function does not take
    raises TypeError naming the nearest one."""

    def names() -> Optional[StateNames]:
        if isinstance(system, Definition):
            return StateNames.of_definition(system.definition)
        return StateNames.of_definition(system) if isinstance(system, MappingABC) else None

    body = simulate_request(
        system, methods, h=h, t_end=t_end, params=params, q0=q0, p0=p0, chart=chart,
        initial_coordinates=initial_coordinates, every=every, compare_to_reference=compare_to_reference,
        jacobian_defect=jacobian_defect, section=section, stop_when=stop_when, energy=energy,
        indicators=indicators, deviations=deviations, qr_every=qr_every, names=names,
    )
    ok, text = _native().simulate(json.dumps(body, allow_nan=False, ensure_ascii=False))
    answer = json.loads(text)
    if not ok:
        error = GeomintError.from_detail(answer)
        if error.code == "internal":
            raise ServerError(error.code, error.message)
        raise error
    return Simulation.from_json(answer, body)
