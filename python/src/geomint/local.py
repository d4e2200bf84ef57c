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
from typing import TYPE_CHECKING

from ._arguments import Methods, SimulateOptions, SystemLike, simulate_request
from .errors import GeomintError, ServerError
from .simulation import Simulation

if TYPE_CHECKING:
    from typing_extensions import Unpack


def _native() -> ModuleType:
    try:
        import geomint_native
    except ImportError as e:  # pragma: no cover - the test command installs it
        raise ImportError(
            "geomint.local needs the compiled module geomint_native: build its wheel with "
            "`maturin build --release -m crates/geomint-py/Cargo.toml` and pip install it"
        ) from e
    module: ModuleType = geomint_native
    return module


def simulate(
    system: SystemLike,
    methods: Methods,
    *,
    h: float,
    t_end: float,
    **options: Unpack[SimulateOptions],
) -> Simulation:
    """Runs ``methods`` on ``system`` in this process: :meth:`Client.simulate`'s arguments
    (:class:`~geomint._arguments.SimulateOptions`) and result, the same numbers."""
    body = simulate_request(system, methods, h=h, t_end=t_end, **options)
    ok, text = _native().simulate(json.dumps(body, allow_nan=False, ensure_ascii=False))
    answer = json.loads(text)
    if not ok:
        error = GeomintError.from_detail(answer)
        if error.code == "internal":
            raise ServerError(error.code, error.message)
        raise error
    return Simulation.from_json(answer, body)
