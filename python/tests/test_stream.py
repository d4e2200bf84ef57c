"""The NDJSON stream: the same numbers as the one-document answer, progress as it arrives, and an
interrupt (Ctrl-C) that stops the server's computation."""

from __future__ import annotations

import signal
import threading
import time
from typing import Any, Dict, List

import numpy as np
import pytest

import geomint
from geomint import _progress


def same_runs(a: geomint.Simulation, b: geomint.Simulation) -> None:
    assert a.methods == b.methods
    for x, y in zip(a, b, strict=True):
        for name in ("t", "q", "p", "energy", "energy_error", "cartesian_q", "cartesian_p", "jacobian_defect"):
            u, v = getattr(x, name, None), getattr(y, name, None)  # None: not in the answer
            assert (u is None) == (v is None), name
            if u is not None:
                assert u.tobytes() == v.tobytes(), name
        assert set(x.invariants) == set(y.invariants)
        for k in x.invariants:
            assert x.invariants[k].tobytes() == y.invariants[k].tobytes()
        assert x.stop == y.stop
        assert x.stats is not None and y.stats is not None
        assert (x.stats.steps, x.stats.force_evaluations) == (y.stats.steps, y.stats.force_evaluations)


@pytest.mark.parametrize(
    "system, methods, kwargs",
    [
        ("pendulum", ["modin_3s", "heun"], {"h": 0.1, "t_end": 200, "compare_to_reference": True}),
        ("elastic_pendulum_2d", ["symplectic_euler", "rk4"], {"h": 0.02, "t_end": 40, "chart": "polar"}),
        ("harmonic_oscillator", ["csv1", "csv2"], {"h": 0.5, "t_end": 100, "jacobian_defect": True}),
        ("elastic_pendulum_3d", [{"id": "modin_rks", "inner": "rk4"}, "modin_3s"], {"h": 0.01, "t_end": 30}),
    ],
)
def test_the_stream_gives_the_documents_bits(
    client: geomint.Client, system: str, methods: List[Any], kwargs: Dict[str, Any]
) -> None:
    lines: List[Any] = []
    streamed = client.stream(system, methods, progress=False, on_line=lines.append, **kwargs)
    document = client.simulate(system, methods, **kwargs)
    same_runs(streamed, document)
    # Samples arrive in chunks (at most 256 each), in order, and add up to the schedule.
    chunks = [line for line in lines if line["type"] == "samples"]
    assert lines[0]["type"] == "header"
    # Methods run side by side; each one's summary follows its last chunk.
    for i in range(len(methods)):
        mine = [k for k, line in enumerate(lines) if line["type"] in ("samples", "summary") and line["method"] == i]
        assert lines[mine[-1]]["type"] == "summary" and sum(lines[k]["type"] == "summary" for k in mine) == 1
    assert max(len(c["t"]) for c in chunks) <= 256
    assert sum(len(c["t"]) for c in chunks) == document.schedule.samples_per_method * len(methods)
    assert len(chunks) >= document.schedule.samples_per_method // 256


def test_the_progress_bar_counts_every_sample(
    client: geomint.Client, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(_progress, "interactive", lambda: True)  # as on a terminal
    sim = client.stream("pendulum", ["modin_3s", "csv1"], h=0.01, t_end=100, progress=True)
    err = capsys.readouterr().err
    total = 2 * sim.schedule.samples_per_method
    assert f"{total}/{total}" in err


def runs_in_progress(client: geomint.Client) -> int:
    return client.health()["runs_in_progress"]


LONG = dict(system="nbody", methods=["implicit_midpoint"], h=1e-4, t_end=1000, every=10_000)


def test_an_interrupt_closes_the_stream_and_stops_the_servers_run(url: str) -> None:
    """Ctrl-C while samples arrive: the client closes the connection and the server's run stops
    (10⁷ implicit steps of three bodies, many seconds of work, stop within a few seconds)."""
    main = threading.get_ident()
    seen: Dict[str, Any] = {}
    with geomint.Client(url) as client, geomint.Client(url) as observer:
        def interrupt() -> None:
            time.sleep(0.2)
            seen["at"] = time.monotonic()
            # The signal a terminal's Ctrl-C sends, to the thread reading the stream.
            signal.pthread_kill(main, signal.SIGINT)

        def on_line(line: Any) -> None:
            if line["type"] == "samples" and "busy" not in seen:
                seen["busy"] = runs_in_progress(observer)
                threading.Thread(target=interrupt).start()

        with pytest.raises(KeyboardInterrupt):
            client.stream(LONG["system"], LONG["methods"], h=LONG["h"], t_end=LONG["t_end"],
                          every=LONG["every"], progress=False, on_line=on_line)
        interrupted = time.monotonic()
        assert seen["busy"] >= 1
        assert interrupted - seen["at"] < 1.0
        while runs_in_progress(observer) > 0 and time.monotonic() - interrupted < 10:
            time.sleep(0.05)
        stopped = time.monotonic() - interrupted
        assert runs_in_progress(observer) == 0, "the server's run went on after the client left"
        assert stopped < 5.0
        # The client still works after the interrupt.
        assert client.simulate("pendulum", "csv1", h=0.1, t_end=1).runs[0].samples == 11


def test_an_interrupt_stops_a_study(url: str) -> None:
    """The same for a sweep: closing its NDJSON stream stops the cells still to run."""
    main = threading.get_ident()
    with geomint.Client(url) as client, geomint.Client(url) as observer:
        def interrupt() -> None:
            deadline = time.monotonic() + 20
            while runs_in_progress(observer) == 0 and time.monotonic() < deadline:
                time.sleep(0.02)
            signal.pthread_kill(main, signal.SIGINT)

        thread = threading.Thread(target=interrupt)
        thread.start()
        started = time.monotonic()
        with pytest.raises(KeyboardInterrupt):
            client.sweep("nbody", ["implicit_midpoint"], [("params.gamma", 0, 0.1, 8)], t_end=1000, h=1e-3,
                         every=100_000, progress=False)
        thread.join()
        interrupted = time.monotonic()
        assert interrupted - started < 20
        while runs_in_progress(observer) > 0 and time.monotonic() - interrupted < 10:
            time.sleep(0.05)
        assert runs_in_progress(observer) == 0
        assert time.monotonic() - interrupted < 5.0


def test_a_stream_refusal_raises_before_any_line(client: geomint.Client) -> None:
    with pytest.raises(geomint.GeomintError) as caught:
        client.stream({"coordinates": ["x"], "potential": "x^^2"}, "rk4", h=0.1, t_end=1, progress=False)
    assert (caught.value.field, caught.value.position, caught.value.status) == ("system.potential", 2, 422)


def test_stream_and_document_agree_on_stopped_runs(client: geomint.Client) -> None:
    kwargs = dict(h=3.0, t_end=3000)
    streamed = client.stream("harmonic_oscillator", ["explicit_euler", "cimp"], progress=False, **kwargs)
    same_runs(streamed, client.simulate("harmonic_oscillator", ["explicit_euler", "cimp"], **kwargs))
    assert streamed["explicit_euler"].stop == geomint.Stop("diverged", 625, 1875.0)
    assert np.isnan(streamed["explicit_euler"].energy[-1])
