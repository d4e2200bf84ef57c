"""Poincaré sections, events and energy levels: the points lie on their surface to round-off at
the run's energy, an event ends a run at its crossing, the stream gives the document's bits, the
client's arrays are the server's numbers, and wrong surfaces are refused with their field."""

from __future__ import annotations

import json
from typing import Any, Dict, List

import httpx
import numpy as np
import pytest

import geomint
from conftest import post_text
from test_simulate import Recorder, assert_same_bits, literal_floats

# Hénon–Heiles, typed in: its exact flow keeps H, so energy errors are measured against H₀.
HENON_HEILES: Dict[str, Any] = {
    "coordinates": ["x", "y"], "momenta": ["px", "py"], "potential": "(x^2+y^2)/2 + x^2*y - y^3/3",
}
ENERGY = 0.125
START: Dict[str, Any] = {"h": 0.05, "t_end": 500, "q0": [0.1, 0.0], "p0": [0.0, 0.0],
                         "energy": {"value": ENERGY, "momentum": "py"}, "every": 100}


def hamiltonian(q: np.ndarray, p: np.ndarray) -> np.ndarray:
    x, y = q[:, 0], q[:, 1]
    return (p[:, 0] ** 2 + p[:, 1] ** 2) / 2 + (x**2 + y**2) / 2 + x**2 * y - y**3 / 3


def request(**members: Any) -> Dict[str, Any]:
    """The JSON body of a Hénon–Heiles simulation, as the client sends it."""
    body = {"system": HENON_HEILES, "methods": ["modin_3s", "velocity_verlet"], **START, **members}
    body["output"] = {"every": body.pop("every")}
    return body


def same_crossings(a: geomint.Crossings | None, b: geomint.Crossings | None) -> None:
    assert (a is None) == (b is None)
    if a is not None and b is not None:
        for name in ("t", "q", "p", "energy", "cartesian_q"):
            u, v = getattr(a, name), getattr(b, name)
            assert (u is None) == (v is None), name
            if u is not None:
                assert u.shape == v.shape and u.tobytes() == v.tobytes(), name


def test_a_henon_heiles_section_lies_on_the_surface_at_the_initial_energy(
    client: geomint.Client, raw: httpx.Client
) -> None:
    section = {"where": "y", "direction": "up"}
    sim = client.simulate(HENON_HEILES, ["modin_3s", "velocity_verlet"], section=section, **START)
    # The energy level: p_y solved, non-negative, so that H(q0, p0) = 1/8.
    assert sim.system.p0[0] == 0 and sim.system.p0[1] == pytest.approx(np.sqrt(2 * ENERGY - 0.1**2), rel=1e-15)
    assert hamiltonian(sim.system.q0[None], sim.system.p0[None])[0] == pytest.approx(ENERGY, rel=1e-15)
    # Nothing damps or drives the system: energy errors are measured against H₀.
    assert sim.energy_reference == "initial"
    assert sim.section == geomint.Surface(("x", "y"), ("px", "py"), where="y", direction="up", max_points=10_000)
    assert sim.stop_when is None
    for run in sim:
        points = run.section
        assert points is not None and run.events is None
        assert len(points) > 50 and points.q.shape == points.p.shape == (len(points), 2)
        assert run.stop == geomint.Stop("finished")
        # On the surface y = 0 to round-off, crossed upwards (y' = p_y > 0), in time order.
        assert np.max(np.abs(points.q[:, 1])) < 1e-15
        assert np.all(points.p[:, 1] > 0)
        assert np.all(np.diff(points.t) > 0) and 0 < points.t[0] and points.t[-1] <= 500
        # H at each point, near the initial energy (a symplectic method's bounded error).
        assert np.allclose(points.energy, hamiltonian(points.q, points.p), rtol=0, atol=1e-15)
        assert np.max(np.abs(points.energy - ENERGY)) < 1e-4
        summary = run.section_summary
        assert summary is not None and summary.points == len(points) and not summary.truncated
        assert summary.note is None and summary.surface_range is not None
        assert summary.surface_range[0] < 0 < summary.surface_range[1]
        assert run.energy_error is not None
        assert np.array_equal(run.energy_error, run.energy - run.energy[0])
    # The client's arrays are the server's numbers, bit for bit.
    literal = literal_floats(post_text(raw, "/api/v1/simulate", request(section=section)))
    assert literal["energy_reference"] == "initial"
    compared = 0
    for run, doc in zip(sim, literal["runs"], strict=True):
        assert run.section is not None
        for name in ("t", "q", "p", "energy"):
            compared += assert_same_bits(getattr(run.section, name), doc["section"][name])
    assert compared == sum(6 * len(run.section) for run in sim if run.section is not None)


def test_stop_when_ends_the_run_at_its_third_crossing(client: geomint.Client) -> None:
    every = dict(START, every=10)
    full = client.simulate(HENON_HEILES, "modin_3s", section={"where": "y", "direction": "up"}, **every)
    stopped = client.simulate(HENON_HEILES, "modin_3s", stop_when={"where": "y", "direction": "up", "count": 3},
                              **every)
    assert stopped.stop_when == geomint.Surface(("x", "y"), ("px", "py"), where="y", direction="up", count=3)
    assert stopped.section is None
    run = stopped["modin_3s"]
    assert run.stop is not None and run.stop.reason == "event"
    assert run.events is not None and len(run.events) == 3 and run.section is None
    assert run.stats is not None and run.stop.step == run.stats.steps
    # The event is the third upward crossing of y = 0: the unstopped run's third section point.
    assert run.stop.t == run.events.t[-1]
    reference = full["modin_3s"].section
    assert reference is not None
    same_crossings(run.events, geomint.Crossings(reference.t[:3], reference.q[:3], reference.p[:3],
                                                 reference.energy[:3]))
    # The last sample is the step past the crossing; the samples before it are the full run's.
    assert run.t[-2] < run.stop.t <= run.t[-1]
    assert run.t[-1] == pytest.approx(run.stop.step * 0.05, rel=1e-14)
    assert np.array_equal(run.q[:-1], full["modin_3s"].q[: run.samples - 1])
    # A string is the surface's first crossing either way.
    first = client.simulate(HENON_HEILES, "modin_3s", stop_when="y", **every)["modin_3s"]
    assert first.stop is not None and first.stop.reason == "event" and first.events is not None
    assert len(first.events) == 1 and first.stop.t == first.events.t[0] < run.events.t[0]


def test_the_stream_gives_the_documents_sections_and_events(client: geomint.Client) -> None:
    options: Dict[str, Any] = dict(START, section={"where": "y", "direction": "both", "max_points": 5},
                                   stop_when={"where": "x", "direction": "down", "count": 4})
    lines: List[Any] = []
    streamed = client.stream(HENON_HEILES, ["modin_3s", "velocity_verlet"], progress=False,
                             on_line=lines.append, **options)
    document = client.simulate(HENON_HEILES, ["modin_3s", "velocity_verlet"], **options)
    assert (streamed.energy_reference, streamed.section, streamed.stop_when) == (
        document.energy_reference, document.section, document.stop_when)
    assert document.section is not None and document.section.max_points == 5
    for a, b in zip(streamed, document, strict=True):
        same_crossings(a.section, b.section)
        same_crossings(a.events, b.events)
        assert a.section_summary == b.section_summary and a.stop == b.stop
        assert a.t.tobytes() == b.t.tobytes() and a.q.tobytes() == b.q.tobytes()
        assert b.stop is not None and b.stop.reason == "event" and b.events is not None and len(b.events) == 4
        assert b.section is not None and b.section_summary is not None
        assert b.section_summary.points == len(b.section) <= 5
    # Crossings come in chunks per surface, in order, from point 0 on.
    crossings = [line for line in lines if line["type"] == "crossings"]
    assert {line["surface"] for line in crossings} == {"section", "stop_when"}
    for method in range(2):
        for surface in ("section", "stop_when"):
            chunks = [c for c in crossings if c["method"] == method and c["surface"] == surface]
            assert [c["offset"] for c in chunks] == list(np.cumsum([0] + [len(c["t"]) for c in chunks[:-1]]))


def test_a_section_never_crossed_has_no_points_and_says_why(client: geomint.Client) -> None:
    options: Dict[str, Any] = {"h": 0.1, "t_end": 2, "section": "q - 5", "stop_when": "q - 5"}
    document = client.simulate("harmonic_oscillator", "modin_3s", **options)
    streamed = client.stream("harmonic_oscillator", "modin_3s", progress=False, **options)
    for sim in (document, streamed):
        run = sim[0]
        assert run.section is not None and run.events is not None
        assert len(run.section) == len(run.events) == 0 and run.section.q.shape == (0, 1)
        assert run.section_summary is not None and run.section_summary.points == 0
        assert run.section_summary.note and run.stop == geomint.Stop("finished")
    same_crossings(document[0].section, streamed[0].section)
    assert document[0].section_summary == streamed[0].section_summary


def test_a_stroboscopic_section_of_the_damped_oscillator(client: geomint.Client) -> None:
    sim = client.simulate("harmonic_oscillator", "modin_3s", h=0.1, t_end=20, section={"period": 2.0, "phase": 0.5})
    assert sim.energy_reference == "exact"
    assert sim.section is not None and (sim.section.period, sim.section.phase) == (2.0, 0.5)
    assert sim.section.where is None and sim.section.direction is None
    points = sim[0].section
    assert points is not None and len(points) == 10
    assert np.allclose(points.t, 0.5 + 2.0 * np.arange(10), rtol=0, atol=1e-12)
    # The damped energy decays between strobes; the points are near the samples at those times.
    assert np.all(np.diff(points.energy) < 0)
    steps = np.rint(points.t / 0.1).astype(int)
    assert np.allclose(points.q, sim[0].q[steps], rtol=0, atol=1e-3)


def test_a_section_in_polar_coordinates_reports_cartesian_points(client: geomint.Client) -> None:
    sim = client.simulate("elastic_pendulum_2d", "symplectic_euler", chart="polar", h=0.02, t_end=20,
                          section={"where": "r - 1.3", "direction": "both"})
    assert sim.section is not None and sim.section.coordinates[0] == "r"
    points = sim[0].section
    assert points is not None and points.cartesian_q is not None and len(points) > 2
    assert points.cartesian_q.shape == (len(points), 2)
    assert np.allclose(points.q[:, 0], 1.3, rtol=0, atol=1e-14)
    assert np.allclose(np.hypot(points.cartesian_q[:, 0], points.cartesian_q[:, 1]), 1.3, rtol=0, atol=1e-14)
    frame = points.to_pandas()
    assert list(frame.columns) == ["t", "q0", "q1", "p0", "p1", "energy", "cartesian_q0", "cartesian_q1"]
    assert np.array_equal(frame["q1"].to_numpy(), points.q[:, 1])


def test_max_points_truncates_the_section(client: geomint.Client) -> None:
    sim = client.simulate(HENON_HEILES, "modin_3s", section={"where": "y", "max_points": 2}, **START)
    run = sim[0]
    assert run.section is not None and len(run.section) == 2
    assert run.section_summary is not None
    assert (run.section_summary.points, run.section_summary.truncated) == (2, True)


def test_wrong_surfaces_are_refused_with_their_field(client: geomint.Client) -> None:
    with pytest.raises(geomint.GeomintError) as caught:
        client.simulate(HENON_HEILES, "modin_3s", section="z + 1", **START)
    assert (caught.value.code, caught.value.field, caught.value.position) == ("invalid_expression", "section.where", 0)
    with pytest.raises(geomint.GeomintError) as caught:
        client.simulate(HENON_HEILES, "modin_3s", **dict(START, energy={"value": -1, "momentum": "py"}))
    assert (caught.value.code, caught.value.field) == ("invalid_value", "energy.value")


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"section": 3}, "section"),
        ({"section": {}}, "section"),
        ({"section": {"where": "q", "period": 1.0}}, "section"),
        ({"section": {"where": "q", "max_points": 0}}, "section.max_points"),
        ({"section": {"period": -1.0}}, "section.period"),
        ({"stop_when": {"direction": "up"}}, "stop_when.where"),
        ({"stop_when": {"where": "q", "count": 0}}, "stop_when.count"),
        ({"energy": 0.5}, "energy"),
        ({"energy": {"value": 0.5}}, "energy.momentum"),
        ({"energy": (0.5, 1)}, "energy.momentum"),
        ({"energy": (float("nan"), "p_q")}, "energy.value"),
    ],
)
def test_bad_surfaces_are_refused_before_sending(kwargs: Dict[str, Any], field: str) -> None:
    transport = Recorder()
    with geomint.Client("http://geomint.invalid", transport=transport) as c:
        with pytest.raises(geomint.ValidationError) as caught:
            c.simulate("harmonic_oscillator", "modin_3s", h=0.1, t_end=1, **kwargs)
    assert caught.value.field == field
    assert transport.requests == []


def test_shorthands_are_sent_as_the_api_takes_them() -> None:
    transport = Recorder(status=422, body=b'{"error": {"code": "invalid_value", "message": "x", "field": "h"}}')
    with geomint.Client("http://geomint.invalid", transport=transport) as c:
        with pytest.raises(geomint.GeomintError):
            c.simulate("harmonic_oscillator", "modin_3s", h=0.1, t_end=1, section="q", stop_when="p_q",
                       energy=(np.float64(0.5), "p_q"))
    sent = json.loads(transport.requests[0].content)
    assert sent["section"] == {"where": "q"} and sent["stop_when"] == {"where": "p_q"}
    assert sent["energy"] == {"value": 0.5, "momentum": "p_q"}


def test_a_sweep_collects_each_cells_section_as_its_simulation_does(client: geomint.Client) -> None:
    section = {"where": "y", "direction": "up", "max_points": 4}
    sweep = client.sweep(HENON_HEILES, ["velocity_verlet"], [("q0[0]", -0.1, 0.1, 3)], 40, h=0.05,
                         q0=[0.0, 0.0], p0=[0.3, 0.2], every=100, section=section, progress=False)
    run = sweep.runs[0]
    assert run.sections is not None and run.section_truncated is not None
    assert len(run.sections) == 3 and run.section_truncated.shape == (3,)
    for cell, x in enumerate(sweep.axes[0].values):
        alone = client.simulate(HENON_HEILES, ["velocity_verlet"], h=0.05, t_end=40, q0=[x, 0.0],
                                p0=[0.3, 0.2], every=100, section=section)
        points = run.sections[cell]
        assert points is not None and 0 < len(points) <= 4
        same_crossings(points, alone.runs[0].section)
        assert bool(run.section_truncated[cell]) == alone.runs[0].section_summary.truncated
    assert client.sweep(HENON_HEILES, ["velocity_verlet"], [("q0[0]", -0.1, 0.1, 3)], 40, h=0.05,
                        progress=False).runs[0].sections is None
