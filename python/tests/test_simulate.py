"""Simulations: the client's arrays against the server's JSON text, bit for bit; the physics the
papers report; refusals with their field and position; the client's own checks."""

from __future__ import annotations

import json
import struct
from typing import Any, Dict, List

import httpx
import numpy as np
import pytest

import geomint
from conftest import post_text

PENDULUM: Dict[str, Any] = {
    "system": "pendulum", "params": {"epsilon": 0.01}, "methods": ["modin_3s", "modin_2s", "heun"],
    "h": 0.1, "t_end": 200, "output": {"every": 10}, "compare_to_reference": True,
}


def literal_floats(text: str) -> Any:
    """The server's JSON with every number kept as the text it was written as."""
    return json.loads(text, parse_float=str, parse_int=str)


def bits(value: float) -> bytes:
    return struct.pack("<d", value)


def assert_same_bits(array: np.ndarray, literals: List[Any]) -> int:
    """Every entry of ``array`` is the double nearest to the server's literal (NaN for null)."""
    flat = np.asarray(array, dtype=np.float64).ravel()
    expected = np.ravel(np.array(literals, dtype=object))
    assert flat.shape == expected.shape
    for got, text in zip(flat.tolist(), expected.tolist(), strict=True):
        if text is None:
            assert np.isnan(got)
        else:
            assert bits(got) == bits(float(text)), (got, text)
    return int(flat.size)


def simulate_kwargs(body: Dict[str, Any]) -> Dict[str, Any]:
    kwargs = {k: v for k, v in body.items() if k not in ("system", "methods", "output")}
    if "output" in body:
        kwargs["every"] = body["output"]["every"]
    return kwargs


def test_arrays_equal_the_servers_numbers_bit_for_bit(client: geomint.Client, raw: httpx.Client) -> None:
    literal = literal_floats(post_text(raw, "/api/v1/simulate", PENDULUM))
    sim = client.simulate(PENDULUM["system"], PENDULUM["methods"], **simulate_kwargs(PENDULUM))
    assert sim.methods == ["modin_3s", "modin_2s", "heun"]
    compared = 0
    for run, doc in zip(sim, literal["runs"], strict=True):
        for name in ("t", "energy", "energy_error", "q", "p"):
            compared += assert_same_bits(getattr(run, name), doc[name])
        assert run.stats is not None and run.stats.steps == int(doc["stats"]["steps"])
        assert run.stop == geomint.Stop("finished")
    assert compared == 3 * 201 * 5
    assert sim.schedule.samples_per_method == 201
    assert sim.system.params["gamma"] == 0.005


def test_the_same_request_gives_the_same_bits(client: geomint.Client) -> None:
    first = client.simulate("elastic_pendulum_3d", ["modin_3s", "rk4"], h=0.05, t_end=20, every=4)
    second = client.simulate("elastic_pendulum_3d", ["modin_3s", "rk4"], h=0.05, t_end=20, every=4)
    for a, b in zip(first, second, strict=True):
        for name in ("t", "q", "p", "energy"):
            assert getattr(a, name).tobytes() == getattr(b, name).tobytes()
        assert a.invariants["J3"].tobytes() == b.invariants["J3"].tobytes()


def test_paper_000_energy_at_t_200(client: geomint.Client) -> None:
    """Paper 000 Sec. 4.3: the damped pendulum from q0 = 0.9π, ε = 0.01, h = 0.1: the splittings
    follow the reference's energy decay, Heun drifts above it."""
    sim = client.simulate(PENDULUM["system"], PENDULUM["methods"], **simulate_kwargs(PENDULUM))
    final = {run.method: run.energy_error[-1] for run in sim if run.energy_error is not None}
    assert set(final) == {"modin_3s", "modin_2s", "heun"}
    assert abs(final["modin_3s"]) < 2e-4 and abs(final["modin_2s"]) < 2e-4
    assert final["heun"] > 5e-3
    assert final["heun"] > 50 * max(abs(final["modin_3s"]), abs(final["modin_2s"]))
    # The energy decays: H(200) is a sixth of H(0) for every method.
    for run in sim:
        assert run.energy[-1] < run.energy[0] / 5


def test_energy_decay_rate_of_the_damped_oscillator(client: geomint.Client) -> None:
    """csv1 is conformal symplectic: its energy of the damped oscillator decays at the exact rate
    e^{-2γt} on average (least squares of ln H over many periods)."""
    gamma = 0.05
    sim = client.simulate("harmonic_oscillator", "csv1", h=0.05, t_end=100, params={"gamma": gamma, "omega": 2})
    run = sim["csv1"]
    slope = np.polyfit(run.t, np.log(run.energy), 1)[0]
    assert slope == pytest.approx(-2 * gamma, rel=0.02)
    # The exact solution is known, so the energy error is measured at every sample.
    assert run.energy_error is not None and np.max(np.abs(run.energy_error)) < 0.01


def test_invariants_charts_and_cartesian_state(client: geomint.Client, raw: httpx.Client) -> None:
    body = {"system": "elastic_pendulum_2d", "chart": "polar", "methods": ["symplectic_euler", "rk4"],
            "h": 0.05, "t_end": 20}
    literal = literal_floats(post_text(raw, "/api/v1/simulate", body))
    sim = client.simulate("elastic_pendulum_2d", ["symplectic_euler", "rk4"], chart="polar", h=0.05, t_end=20)
    assert sim.system.chart == "polar"
    for run, doc in zip(sim, literal["runs"], strict=True):
        assert run.cartesian_q is not None and run.cartesian_p is not None
        assert run.cartesian_q.shape == (401, 2)
        assert_same_bits(run.cartesian_q, doc["cartesian_q"])
        assert_same_bits(run.cartesian_p, doc["cartesian_p"])
        # x = r sin θ, y = r cos θ (paper 001, θ from the downward vertical), to round-off.
        r, theta = run.q[:, 0], run.q[:, 1]
        assert np.allclose(run.cartesian_q[:, 0], r * np.sin(theta), rtol=0, atol=1e-14)
    pendulum = client.simulate("elastic_pendulum_3d", ["modin_3s", "heun"], h=0.1, t_end=200, every=10,
                               params={"epsilon": 0.01})
    drift = {run.method: np.max(np.abs(run.invariants["J3"] - run.invariants["J3"][0])) for run in pendulum}
    assert drift["modin_3s"] < 1e-13
    assert drift["heun"] > 1e-3


def test_a_defined_system_reports_bodies_and_invariants(client: geomint.Client, raw: httpx.Client) -> None:
    definition = {
        "coordinates": ["x", "y"], "momenta": ["px", "py"], "mass": 1,
        "potential": "k/2*(sqrt(x^2 + y^2) - l)^2 - m*g*y",
        "damping": {"epsilon": 0.1, "matrix": [["x^2/(x^2+y^2)", "x*y/(x^2+y^2)"],
                                               ["x*y/(x^2+y^2)", "y^2/(x^2+y^2)"]]},
        "parameters": {"k": 1, "l": 1, "m": 1, "g": 0.2}, "invariants": {"L": "x*py - y*px"},
        "positions": [["x", "-y"]], "q0": [1.2, 0.3], "p0": [0, 0],
    }
    body = {"system": definition, "params": {"g": 0.5}, "methods": ["modin_3s", "rk4"], "h": 0.05, "t_end": 10}
    literal = literal_floats(post_text(raw, "/api/v1/simulate", body))
    sim = client.simulate(definition, ["modin_3s", "rk4"], params={"g": 0.5}, h=0.05, t_end=10)
    assert sim.system.id.startswith("sys-")
    for run, doc in zip(sim, literal["runs"], strict=True):
        assert run.bodies is not None
        assert_same_bits(run.bodies, doc["bodies"])
        assert_same_bits(run.invariants["L"], doc["invariants"]["L"])
        # The body is drawn at (x, -y).
        assert np.array_equal(run.bodies[:, 1], -run.q[:, 1])
    # Radial damping leaves the angular momentum L alone under the splitting (to round-off).
    assert np.max(np.abs(sim["modin_3s"].invariants["L"])) > 0.1


def test_a_run_that_diverges_stops_and_pads_with_nan(client: geomint.Client) -> None:
    """Explicit Euler on the oscillator at h = 3 grows by |1 + 3i| per step and overflows;
    cimp is stable at every h (paper 003 Ch. 3)."""
    sim = client.simulate("harmonic_oscillator", ["explicit_euler", "cimp"], h=3, t_end=3000)
    euler = sim["explicit_euler"]
    assert euler.stop is not None and euler.stop.reason == "diverged"
    assert euler.diverged_at is not None and euler.diverged_at.step == euler.stop.step
    assert euler.samples < sim["cimp"].samples == 1001
    # The last energies overflowed: the server sends null, the client NaN.
    assert np.isnan(euler.energy[-1]) and np.isfinite(euler.q).all()
    growth = np.log(np.abs(euler.q[1:400, 0]) + np.abs(euler.p[1:400, 0]))
    assert np.polyfit(euler.t[1:400], growth, 1)[0] * 3 == pytest.approx(np.log(np.hypot(1, 3)), rel=0.05)
    ds = sim.to_xarray()
    energy = ds["energy"].sel(run="explicit_euler").values
    assert np.array_equal(energy[: euler.samples], euler.energy, equal_nan=True)
    assert np.isnan(energy[euler.samples:]).all()
    assert np.array_equal(ds["t"].values, sim["cimp"].t)


def test_xarray_and_pandas_hold_the_same_numbers(client: geomint.Client) -> None:
    sim = client.simulate("elastic_pendulum_3d", ["modin_3s", "rk4"], h=0.1, t_end=10)
    ds = sim.to_xarray()
    assert ds.sizes["run"] == 2 and ds.sizes["dof"] == 3 and ds.sizes["t"] == 101
    assert np.array_equal(ds["q"].sel(run="rk4").values, sim["rk4"].q)
    assert np.array_equal(ds["invariants"].sel(run="modin_3s", invariant="J3").values,
                          sim["modin_3s"].invariants["J3"])
    frame = sim.to_pandas()
    assert list(frame["method"].unique()) == ["modin_3s", "rk4"]
    rk4 = frame[frame["method"] == "rk4"]
    assert np.array_equal(rk4["q2"].to_numpy(), sim["rk4"].q[:, 2])
    assert np.array_equal(rk4["J3"].to_numpy(), sim["rk4"].invariants["J3"])


def test_refusals_carry_code_field_and_position(client: geomint.Client) -> None:
    with pytest.raises(geomint.GeomintError) as caught:
        client.simulate({"coordinates": ["x"], "potential": "sin(x) + (x^2"}, "rk4", h=0.1, t_end=1)
    err = caught.value
    assert (err.code, err.field, err.position, err.status) == ("invalid_expression", "system.potential", 13, 422)
    assert isinstance(err, geomint.RefusedError)
    with pytest.raises(geomint.GeomintError) as caught:
        client.simulate("pendulum", "csv1", h=0.1, t_end=1, params={"bogus": 1})
    assert (caught.value.code, caught.value.field) == ("unknown_field", "params.bogus")
    with pytest.raises(geomint.GeomintError) as caught:
        client.simulate("pendulum", "csv1", h=0.1, t_end=1, q0=[1, 2])
    assert (caught.value.code, caught.value.field) == ("invalid_value", "q0")
    with pytest.raises(geomint.GeomintError) as caught:
        client.simulate("elastic_pendulum_3d", "csv1", h=0.1, t_end=1)
    assert (caught.value.code, caught.value.field) == ("unmet_requirement", "methods[0]")


class Recorder(httpx.BaseTransport):
    """A transport that answers every request with one fixed answer and keeps the requests."""

    def __init__(self, status: int = 200, body: bytes = b"{}", headers: Dict[str, str] | None = None) -> None:
        self.requests: List[httpx.Request] = []
        self.status, self.body, self.headers = status, body, headers or {}

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        self.requests.append(request)
        return httpx.Response(self.status, content=self.body, headers=self.headers)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"h": -0.1, "t_end": 1}, "h"),
        ({"h": 0.1, "t_end": float("inf")}, "t_end"),
        ({"h": 0.1, "t_end": 1, "q0": [0.1, float("nan")]}, "q0[1]"),
        ({"h": 0.1, "t_end": 1, "params": {"gamma": float("nan")}}, "params.gamma"),
        ({"h": 0.1, "t_end": 1, "every": 0}, "output.every"),
    ],
)
def test_bad_input_is_refused_before_sending(kwargs: Dict[str, Any], field: str) -> None:
    transport = Recorder()
    with geomint.Client("http://geomint.invalid", transport=transport) as c:
        with pytest.raises(geomint.ValidationError) as caught:
            c.simulate("pendulum", "csv1", **kwargs)
    assert caught.value.field == field and caught.value.status is None
    assert transport.requests == []


def test_methods_are_checked_before_sending() -> None:
    transport = Recorder()
    with geomint.Client("http://geomint.invalid", transport=transport) as c:
        with pytest.raises(geomint.ValidationError) as caught:
            c.simulate("pendulum", [], h=0.1, t_end=1)
        assert caught.value.field == "methods"
        with pytest.raises(geomint.ValidationError) as caught:
            c.simulate("pendulum", ["csv1", 3], h=0.1, t_end=1)  # type: ignore[list-item]
        assert caught.value.field == "methods[1]"
    assert transport.requests == []


def test_token_is_sent_as_a_bearer_header() -> None:
    transport = Recorder(body=b'{"status": "ok", "version": "x", "runs_in_progress": 0, "max_concurrent": 1}')
    with geomint.Client("http://geomint.invalid", token="s3cret", transport=transport) as c:
        assert c.health()["status"] == "ok"
    with geomint.Client("http://geomint.invalid", transport=transport) as c:
        c.health()
    assert transport.requests[0].headers["authorization"] == "Bearer s3cret"
    assert "authorization" not in transport.requests[1].headers


def test_a_token_is_accepted_by_todays_server(url: str) -> None:
    with geomint.Client(url, token="unused") as c:
        assert c.simulate("pendulum", "csv1", h=0.1, t_end=1).runs[0].samples == 11


def test_an_overloaded_server_says_when_to_retry() -> None:
    body = b'{"error": {"code": "overloaded", "message": "every simulation slot is busy", "field": null}}'
    transport = Recorder(status=503, body=body, headers={"retry-after": "2"})
    with geomint.Client("http://geomint.invalid", transport=transport) as c:
        with pytest.raises(geomint.OverloadedError) as caught:
            c.simulate("pendulum", "csv1", h=0.1, t_end=1)
    assert (caught.value.code, caught.value.status, caught.value.retry_after) == ("overloaded", 503, 2.0)


def test_numpy_input_is_sent_exactly() -> None:
    transport = Recorder(status=422, body=b'{"error": {"code": "invalid_value", "message": "x", "field": "h"}}')
    q0 = np.array([np.pi * 0.9], dtype=np.float64)
    with geomint.Client("http://geomint.invalid", transport=transport) as c:
        with pytest.raises(geomint.GeomintError):
            c.simulate("pendulum", "csv1", h=np.float64(0.1), t_end=np.int64(2), q0=q0)
    sent = json.loads(transport.requests[0].content)
    assert sent["q0"] == [float(q0[0])] and sent["h"] == 0.1 and sent["t_end"] == 2.0
    assert bits(sent["q0"][0]) == q0.tobytes()


def test_an_answer_not_in_the_error_shape_still_raises_with_its_status() -> None:
    transport = Recorder(status=502, body=b"<html>Bad gateway</html>", headers={"content-type": "text/html"})
    with geomint.Client("http://geomint.invalid", transport=transport) as c:
        with pytest.raises(geomint.ServerError) as caught:
            c.simulate("pendulum", "csv1", h=0.1, t_end=1)
    assert (caught.value.code, caught.value.status) == ("http_502", 502)
    assert "Bad gateway" in caught.value.message


def test_a_stream_cut_short_raises() -> None:
    header = {"type": "header", "system": {"id": "pendulum", "chart": "cartesian", "params": {}, "q0": [1.0],
                                           "p0": [0.0]},
              "schedule": {"h": 0.1, "steps": 10, "every": 1, "t_end": 1.0, "samples_per_method": 11},
              "methods": ["csv1"], "invariants": [], "energy_error": False, "jacobian_defect": False}
    transport = Recorder(body=(json.dumps(header) + "\n").encode(), headers={"content-type": "application/x-ndjson"})
    with geomint.Client("http://geomint.invalid", transport=transport) as c:
        with pytest.raises(geomint.ServerError) as caught:
            c.stream("pendulum", "csv1", h=0.1, t_end=1, progress=False)
    assert caught.value.code == "stream_cut"
    assert transport.requests[0].headers["accept"] == "application/x-ndjson"
