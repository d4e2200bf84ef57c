"""geomint in the Python process (``geomint.local``, the compiled module from crates/geomint-py):
the same arguments and result types as the client, the server's numbers bit for bit, the
server's refusals with their field and position, and the interpreter free while a run computes."""

from __future__ import annotations

import threading
import time
from typing import Any, Dict

import numpy as np
import pytest

import geomint
from geomint import local
from test_sections import HENON_HEILES

ARRAYS = ("t", "q", "p", "energy", "energy_error", "cartesian_q", "cartesian_p", "invariants",
          "lyapunov", "megno", "megno_mean")


def same_runs(a: geomint.Simulation, b: geomint.Simulation) -> int:
    """Every array of every run of ``a`` has the bits of ``b``'s; the number of values compared."""
    compared = 0
    assert [r.method for r in a.runs] == [r.method for r in b.runs]
    for x, y in zip(a.runs, b.runs, strict=True):
        assert (x.stop, x.stats.steps, x.stats.force_evaluations) == (
            y.stop, y.stats.steps, y.stats.force_evaluations)
        for name in ARRAYS:
            u, v = getattr(x, name, None), getattr(y, name, None)
            if isinstance(u, dict):
                assert u.keys() == v.keys(), name
                pairs = [(u[k], v[k]) for k in u]
            else:
                pairs = [(u, v)]
            for s, w in pairs:
                assert (s is None) == (w is None), name
                if s is not None:
                    assert s.shape == w.shape and s.tobytes() == w.tobytes(), name
                    compared += s.size
    return compared


CASES: Dict[str, Dict[str, Any]] = {
    "pendulum": dict(system="pendulum", methods=["modin_3s", "heun", "rk4"], h=0.05, t_end=50,
                     params={"gamma": 0.1}),
    "elastic pendulum, polar": dict(system="elastic_pendulum_2d", methods=["symplectic_euler"],
                                    h=0.01, t_end=20, chart="polar", q0=[1.2, 0.3], every=7),
    "typed in, section and indicators": dict(
        system=HENON_HEILES, methods=["velocity_verlet", {"id": "triple_jump", "base": "velocity_verlet"}],
        h=0.05, t_end=200, q0=[0.1, 0.0], p0=[0.0, 0.0], energy={"value": 0.125, "momentum": "py"},
        section={"where": "y", "direction": "up"}, indicators=["megno", "lyapunov"], every=50),
}


@pytest.mark.parametrize("case", CASES)
def test_a_local_run_gives_the_servers_numbers_bit_for_bit(client: geomint.Client, case: str) -> None:
    arguments = CASES[case]
    here = local.simulate(**arguments)
    there = client.simulate(**arguments)
    assert isinstance(here, geomint.Simulation)
    assert here.system.id == there.system.id and here.energy_reference == there.energy_reference
    assert here.system.p0.tobytes() == there.system.p0.tobytes()
    assert same_runs(here, there) > 100
    if "section" in arguments:
        for x, y in zip(here.runs, there.runs, strict=True):
            assert x.section is not None and y.section is not None and len(x.section) > 5
            assert x.section.q.tobytes() == y.section.q.tobytes()


def test_a_local_refusal_is_the_servers(client: geomint.Client) -> None:
    bad = {"coordinates": ["x"], "potential": "x^2 +* 1"}
    with pytest.raises(geomint.RefusedError) as here:
        local.simulate(bad, ["rk4"], h=0.1, t_end=1)
    with pytest.raises(geomint.RefusedError) as there:
        client.simulate(bad, ["rk4"], h=0.1, t_end=1)
    assert (here.value.code, here.value.field, here.value.position) == (
        there.value.code, there.value.field, there.value.position)
    assert here.value.field == "system.potential" and here.value.position is not None
    assert here.value.status is None
    with pytest.raises(geomint.RefusedError) as unknown:
        local.simulate("pendulum", ["modin_3s"], h=0.1, t_end=1e12)
    assert unknown.value.field is not None


def test_other_threads_run_while_a_local_simulation_computes() -> None:
    # 10⁷ steps (the per-method limit), a fraction of a second; the main thread counts meanwhile.
    result: Dict[str, Any] = {}

    def run() -> None:
        result["sim"] = local.simulate("pendulum", ["rk4"], h=1e-4, t_end=1000, every=10**7)

    worker = threading.Thread(target=run)
    began = time.perf_counter()
    worker.start()
    counted = 0
    while worker.is_alive():
        counted += 1
        time.sleep(0.001)
    elapsed = time.perf_counter() - began
    worker.join()
    assert result["sim"].runs[0].stats.steps == 10_000_000
    # With the interpreter held, the loop would not have run until the simulation ended.
    assert elapsed > 0.05 and counted > 0.2 * elapsed / 0.001, (counted, elapsed)
    assert np.isfinite(result["sim"].runs[0].energy).all()
