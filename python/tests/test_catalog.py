"""Catalogues and stored definitions."""

from __future__ import annotations

import re
import uuid

import httpx
import numpy as np
import pytest

import geomint
from test_simulate import assert_same_bits, literal_floats


def test_systems_and_methods_read_as_the_server_lists_them(client: geomint.Client, raw: httpx.Client) -> None:
    listed = literal_floats(raw.get("/api/v1/systems").text)
    systems = client.systems()
    assert [s.id for s in systems] == [s["id"] for s in listed]
    for system, doc in zip(systems, listed, strict=True):
        assert system.degrees_of_freedom == int(doc["degrees_of_freedom"]) == system.q0.shape[0]
        assert_same_bits(system.q0, doc["q0"])
        assert [p.name for p in system.params] == [p["name"] for p in doc["params"]]
        for p, d in zip(system.params, doc["params"], strict=True):
            if d["kind"] == "number":
                assert (p.min, p.max) == (float(d["min"]), float(d["max"]))
    nbody = client.system("nbody")
    assert nbody.param("masses").kind == "number_list" and nbody.param("potential").kind == "choice"
    assert "gravity" in nbody.param("potential").options
    methods = client.methods()
    raw_methods = raw.get("/api/v1/methods").json()
    assert [(m.id, m.order, m.symplectic) for m in methods] == \
        [(m["id"], m["order"], m["symplectic"]) for m in raw_methods]


def test_a_definition_is_stored_under_its_digest(client: geomint.Client) -> None:
    # A parameter name no other test uses, so that this definition is new to the server.
    k = f"k_{uuid.uuid4().hex[:8]}"
    definition = {"coordinates": ["x"], "potential": f"{k}*x^4/4 - x^2/2", "damping": {"gamma": 0.05},
                  "parameters": {k: 1.0}, "q0": [1.5]}
    first = client.define(definition)
    assert re.fullmatch(r"sys-[0-9a-f]{16}", first)
    # The same definition given as keywords is the same system.
    assert client.define(coordinates=["x"], potential=f"{k}*x^4/4 - x^2/2", damping={"gamma": 0.05},
                         parameters={k: 1.0}, q0=[1.5]) == first
    stored = client.store_system(definition)
    assert stored.id == first
    assert stored.facts.dimension == 1 and stored.facts.damping == "conformal" and stored.facts.separable
    assert "csv1" in stored.facts.methods
    assert first in [s.id for s in client.systems()]
    entry = client.system(first)
    assert entry.param(k).default == 1.0 and np.array_equal(entry.q0, [1.5])
    # It runs by its id like a built-in system, with the same numbers as the definition itself.
    by_id = client.simulate(first, "csv1", h=0.1, t_end=10)
    inline = client.simulate(definition, "csv1", h=0.1, t_end=10)
    assert by_id["csv1"].energy.tobytes() == inline["csv1"].energy.tobytes()
    client.delete_system(first)
    with pytest.raises(geomint.GeomintError) as caught:
        client.system(first)
    assert (caught.value.code, caught.value.status) == ("not_found", 404)


def test_definition_refusals(client: geomint.Client) -> None:
    with pytest.raises(geomint.GeomintError) as caught:
        client.define(coordinates=["x"], potential="x^2/2 + (x")
    assert (caught.value.code, caught.value.field, caught.value.position) == ("invalid_expression", "potential", 10)
    with pytest.raises(geomint.GeomintError) as caught:
        client.define(coordinates=["x", "y"], potential="x^2 + y^2",
                      damping={"epsilon": 0.1, "matrix": [["1", "0"], ["z", "1"]]})
    assert caught.value.field == "damping.matrix[1][0]" and caught.value.position == 0
    with pytest.raises(geomint.ValidationError) as caught:
        client.define(potential="x^2")
    assert (caught.value.field, caught.value.code) == ("coordinates", "missing_field")
    with pytest.raises(geomint.GeomintError) as caught:
        client.delete_system("pendulum")
    assert (caught.value.code, caught.value.status) == ("built_in_system", 409)
