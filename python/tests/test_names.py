"""One spelling everywhere: coordinates and momenta by their names (``y``, ``p_y``) in a
simulation's energy level, a sweep's axes and its energy surface, and the Dataset's dimensions,
the request's own forms (``q0[1]``, ``p0[0]``) still taken; runs found by the name they were
asked for; a missing quantity that says why."""

from __future__ import annotations

import json
from typing import List

import httpx
import numpy as np
import pytest

import geomint

ENERGY = 0.125


def test_names_become_the_requests_forms_with_the_catalogue_read_once() -> None:
    entry = {"id": "hh", "name": "HH", "description": "", "degrees_of_freedom": 2, "params": [],
             "charts": [{"id": "cartesian", "coordinates": ["x", "y"], "separable": True, "description": ""}],
             "q0": [0, 0], "p0": [0, 0], "invariants": [], "exact_solution": False, "conformal_damping": False}
    sent: List[httpx.Request] = []

    def answer(request: httpx.Request) -> httpx.Response:
        sent.append(request)
        if request.method == "GET":
            return httpx.Response(200, json=entry)
        return httpx.Response(422, json={"error": {"code": "invalid_value", "message": "enough"}})

    with geomint.Client("http://geomint.invalid", transport=httpx.MockTransport(answer)) as c:
        with pytest.raises(geomint.RefusedError):
            c.sweep("hh", "velocity_verlet", [("y", 0, 1, 2), ("p_y", 0, 1, 2)], 1, h=0.1, energy=(ENERGY, "p_x"))
        body = json.loads(sent[-1].content)
        assert [a["name"] for a in body["axes"]] == ["q0[1]", "p0[1]"]
        assert body["energy_surface"] == {"energy": ENERGY, "solve_for": "p0[0]"}
        with pytest.raises(geomint.RefusedError):
            c.simulate("hh", "velocity_verlet", h=0.1, t_end=1, energy=(ENERGY, "p0[1]"))
        assert json.loads(sent[-1].content)["energy"] == {"value": ENERGY, "momentum": "p_y"}
        with pytest.raises(geomint.ValidationError) as refused:
            c.sweep("hh", "velocity_verlet", [("yy", 0, 1, 2)], 1, h=0.1)
        assert refused.value.field == "axes[0].name" and "did you mean 'y'" in str(refused.value)
    assert [r.method for r in sent] == ["GET", "POST", "POST"]


def test_an_energy_level_names_its_momentum_either_way(client: geomint.Client) -> None:
    kwargs = dict(h=0.05, t_end=5, q0=[0.1, 0.0], p0=[0.0, 0.0], progress=False)
    by_name = client.simulate("henon_heiles", "velocity_verlet", energy=(ENERGY, "p_y"), **kwargs)
    as_wire = client.simulate("henon_heiles", "velocity_verlet", energy=(ENERGY, "p0[1]"), **kwargs)
    as_sweep = client.simulate("henon_heiles", "velocity_verlet", energy={"energy": ENERGY, "solve_for": "p_y"},
                               **kwargs)
    assert as_wire.request is not None and as_wire.request["energy"] == {"value": ENERGY, "momentum": "p_y"}
    assert by_name.system.p0[1] > 0
    for other in (as_wire, as_sweep):
        assert other.system.p0.tobytes() == by_name.system.p0.tobytes()
        assert other["velocity_verlet"].q.tobytes() == by_name["velocity_verlet"].q.tobytes()
    with pytest.raises(geomint.ValidationError) as refused:
        client.simulate("henon_heiles", "velocity_verlet", energy=(ENERGY, "p0[2]"), **kwargs)
    assert refused.value.field == "energy.momentum" and "p_x, p_y" in str(refused.value)


def test_a_sweep_takes_the_names_and_names_its_dimensions_after_them(client: geomint.Client) -> None:
    common = dict(h=0.05, indicators="megno", progress=False)
    by_name = client.sweep("henon_heiles", "velocity_verlet", [("y", -0.2, 0.2, 3), ("p_y", -0.1, 0.1, 2)], 5,
                           energy=(ENERGY, "p_x"), **common)
    as_wire = client.sweep("henon_heiles", "velocity_verlet", [("q0[1]", -0.2, 0.2, 3), ("p0[1]", -0.1, 0.1, 2)], 5,
                           energy_surface={"energy": ENERGY, "solve_for": "p0[0]"}, **common)
    assert by_name.request is not None and as_wire.request is not None
    assert [a["name"] for a in by_name.request["axes"]] == ["q0[1]", "p0[1]"]
    assert by_name.request["energy_surface"] == {"energy": ENERGY, "solve_for": "p0[0]"}
    assert by_name.digest == as_wire.digest
    run, wire_run = by_name["velocity_verlet"], as_wire["velocity_verlet"]
    assert run.megno_mean is not None and wire_run.megno_mean is not None
    assert run.megno_mean.tobytes() == wire_run.megno_mean.tobytes()
    assert [a.dim for a in by_name.axes] == ["y", "p_y"] == [a.dim for a in as_wire.axes]
    ds = by_name.to_xarray()
    assert ds["megno_mean"].dims == ("run", "y", "p_y")
    # The request's spelling stays a coordinate along the same dimension.
    assert np.array_equal(ds["q0_1"].values, ds["y"].values) and ds["p0_1"].dims == ("p_y",)
    assert list(ds["coordinate"].values) == ["x", "y"] and list(ds["momentum"].values) == ["p_x", "p_y"]
    assert ds.sel(y=0.0, p_y=0.1, method="nearest")["megno_mean"].shape == (1,)


def test_a_typed_in_system_names_its_own_momenta(client: geomint.Client) -> None:
    definition = {"coordinates": ["u", "v"], "momenta": ["pu", "pv"], "potential": "(u^2+v^2)/2 + u^2*v"}
    sweep = client.sweep(definition, "velocity_verlet", [("v", -0.1, 0.1, 2), ("pv", -0.1, 0.1, 2)], 1, h=0.1,
                         energy=(0.1, "pu"), progress=False)
    assert sweep.request is not None and sweep.request["energy_surface"]["solve_for"] == "p0[0]"
    assert sweep.to_xarray()["energy_error_max"].dims == ("run", "v", "pv")
    with pytest.raises(geomint.ValidationError) as refused:
        client.sweep(definition, "velocity_verlet", [("vv", 0, 1, 2)], 1, h=0.1, progress=False)
    assert refused.value.field == "axes[0].name" and "did you mean 'v'" in str(refused.value)


def test_energy_and_energy_surface_are_one_keyword_given_once(client: geomint.Client) -> None:
    with pytest.raises(geomint.ValidationError) as refused:
        client.sweep("henon_heiles", "velocity_verlet", [("y", 0, 0.1, 2)], 1, h=0.05,
                     energy=(ENERGY, "p_x"), energy_surface=(ENERGY, "p_x"), progress=False)
    assert refused.value.field == "energy"


def test_a_run_is_found_by_the_name_it_was_asked_for(client: geomint.Client) -> None:
    sim = client.simulate("harmonic_oscillator", ["yoshida_6", "csv1"], h=0.1, t_end=1)
    label = sim.methods[0]
    assert label != "yoshida_6" and label.startswith("yoshida_6")
    assert sim["yoshida_6"] is sim[label] is sim.runs[0] and sim["csv1"] is sim.runs[1]
    with pytest.raises(KeyError) as missing:
        sim["yoshida_8"]
    assert label in str(missing.value)


def test_a_missing_energy_error_says_why(client: geomint.Client) -> None:
    sim = client.simulate("pendulum", ["modin_3s", "heun"], h=0.1, t_end=20)
    assert sim.energy_reference is None and not sim["heun"].has_energy_error
    with pytest.raises(geomint.MissingError) as missing:
        sim["heun"].energy_error.shape
    assert "compare_to_reference=True" in str(missing.value) and isinstance(missing.value, AttributeError)
    assert getattr(sim["heun"], "energy_error", None) is None
    compared = client.simulate("pendulum", ["modin_3s", "heun"], h=0.1, t_end=20, compare_to_reference=True)
    assert compared.energy_reference == "reference" and compared["heun"].energy_error.shape == compared["heun"].t.shape
