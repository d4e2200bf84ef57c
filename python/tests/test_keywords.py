"""The client never ignores what it was told: a misspelt keyword raises TypeError naming the
nearest one, the real keywords are in the signatures ``help()`` shows, and a client without a
server says where it looked and what to do. These checks need no server but the last."""

from __future__ import annotations

import inspect
import socket
from typing import Any, Callable, Dict

import pytest

import geomint
from geomint import local

# Misspellings a new user made, and the keyword each one meant.
MISSPELT = {"param": "params", "tend": "t_end", "q_0": "q0", "indicator": "indicators", "sections": "section"}


def unused_url() -> str:
    """A loopback URL where nothing listens (a port just freed)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    return f"http://127.0.0.1:{port}"


@pytest.fixture()
def nowhere() -> geomint.Client:
    return geomint.Client(unused_url(), timeout=5)


@pytest.mark.parametrize("wrong,meant", sorted(MISSPELT.items()))
@pytest.mark.parametrize("call", ["simulate", "stream", "local"])
def test_a_misspelt_keyword_of_a_simulation_raises_and_names_the_nearest(
    nowhere: geomint.Client, call: str, wrong: str, meant: str
) -> None:
    functions: Dict[str, Callable[..., Any]] = {"simulate": nowhere.simulate, "stream": nowhere.stream,
                                                "local": local.simulate}
    kwargs: Dict[str, Any] = {"h": 0.1, "t_end": 10, wrong: 1}
    if wrong == "tend":
        del kwargs["t_end"]
    # Raised before anything is sent: the client has no server to send to.
    with pytest.raises(TypeError) as refused:
        functions[call]("pendulum", "rk4", **kwargs)
    message = str(refused.value)
    assert repr(wrong) in message and f"did you mean {meant!r}" in message, message


def test_every_client_method_refuses_unknown_keywords(nowhere: geomint.Client) -> None:
    calls: Dict[str, Callable[[], Any]] = {
        "sweep": lambda: nowhere.sweep("pendulum", "rk4", [("h", 0.1, 0.2, 2)], 1, energy_surfaces=(1, "p_x")),
        "define": lambda: nowhere.define(coordinates=["x"], potentail="x^2"),
        "store_system": lambda: nowhere.store_system(coordinates=["x"], potentail="x^2"),
        "stability": lambda: nowhere.stability("csv1", omega=1, gamma=(0, 1, 2), h=(0.1, 1, 2), gama=1),
        "stability_point": lambda: nowhere.stability_point("csv1", omega=1, gamma=0, h=0.1, hh=1),
        "energy_map": lambda: nowhere.energy_map(n_x=5),
        "convergence": lambda: nowhere.convergence("pendulum", "rk4", [0.1], 1, sample=3),
        "work_precision": lambda: nowhere.work_precision("pendulum", [("rk4", [0.1])], 1, sample=3),
    }
    nearest = {"sweep": "energy_surface", "define": "potential", "store_system": "potential",
               "stability": "gamma", "stability_point": "h", "energy_map": "nx", "convergence": "samples",
               "work_precision": "samples"}
    for name, call in calls.items():
        with pytest.raises(TypeError) as refused:
            call()
        assert f"did you mean {nearest[name]!r}" in str(refused.value), (name, str(refused.value))


def test_an_unknown_keyword_far_from_every_name_lists_them_all(nowhere: geomint.Client) -> None:
    with pytest.raises(TypeError) as refused:
        nowhere.simulate("pendulum", "rk4", h=0.1, t_end=1, zzzzzz=1)
    message = str(refused.value)
    assert "'zzzzzz'" in message and "params" in message and "qr_every" in message and "on_line" in message


@pytest.mark.parametrize("function", [geomint.Client.simulate, geomint.Client.stream, local.simulate],
                         ids=["simulate", "stream", "local"])
def test_help_shows_the_real_keywords(function: Callable[..., Any]) -> None:
    parameters = inspect.signature(function).parameters
    for name in ("h", "t_end", "params", "q0", "p0", "chart", "every", "section", "stop_when", "energy",
                 "indicators", "deviations", "qr_every", "compare_to_reference"):
        assert parameters[name].kind is inspect.Parameter.KEYWORD_ONLY, name
    assert not any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters.values())
    assert "params" in inspect.getdoc(function) or function is not geomint.Client.simulate


def test_no_server_raises_an_error_that_says_where_and_what_to_do(nowhere: geomint.Client) -> None:
    for call in (nowhere.health, lambda: nowhere.stream("pendulum", "rk4", h=0.1, t_end=1, progress=False),
                 lambda: nowhere.sweep("pendulum", "rk4", [("h", 0.1, 0.2, 2)], 1, progress=False)):
        with pytest.raises(geomint.UnreachableError) as refused:
            call()
        message = str(refused.value)
        assert nowhere.url in message and "scripts/serve" in message and "GEOMINT_URL" in message
        assert "geomint.local" in message and refused.value.code == "unreachable"
    assert isinstance(refused.value, geomint.GeomintError)
