"""The client against the OpenAPI document the server serves: every route it calls exists with
that method, query value and media type, and every member it sends or reads exists with a
compatible type (see schema_check.py for the rules)."""

from __future__ import annotations

import re
import typing
from pathlib import Path
from typing import Any, Dict, List, Literal, Optional, TypedDict

import httpx
import pytest

import geomint
from geomint import _wire
from geomint._wire import JSON, ROUTES, Route
from schema_check import Document, check


@pytest.fixture(scope="module")
def doc(raw: httpx.Client) -> Document:
    response = raw.get("/api/v1/openapi.json")
    assert response.status_code == 200
    return Document(response.json())


def operation(doc: Document, route: Route) -> Dict[str, Any]:
    paths = doc.raw["paths"]
    assert route.path in paths, f"{route.path} is not in the document's paths"
    ops = paths[route.path]
    assert route.method.lower() in ops, f"{route.method} {route.path} is not in the document"
    return ops[route.method.lower()]


@pytest.mark.parametrize("name", sorted(ROUTES))
def test_route_exists_with_method_query_and_media(doc: Document, name: str) -> None:
    route = ROUTES[name]
    op = operation(doc, route)
    params = {(p["in"], p["name"]): p for p in op.get("parameters", [])}
    for segment in re.findall(r"\{(\w+)\}", route.path):
        assert ("path", segment) in params, f"{name}: path parameter {segment} is not declared"
    for key, values in route.query.items():
        assert ("query", key) in params, f"{name}: query parameter {key} is not declared"
        schema = doc.deref(params[("query", key)]["schema"])
        for value in values:
            assert value in schema["enum"], f"{name}: {key}={value} is not among {schema['enum']}"
    answer = op["responses"].get(str(route.status))
    assert answer is not None, f"{name}: no {route.status} answer (has {sorted(op['responses'])})"
    for media in route.answers:
        assert media in answer.get("content", {}), f"{name}: {media} is not an answer's media type"
    if route.request is not None:
        assert route.request_media in op["requestBody"]["content"], f"{name}: the body's media type"
    else:
        assert "requestBody" not in op, f"{name}: the document expects a body the client does not send"


@pytest.mark.parametrize("name", sorted(ROUTES))
def test_request_and_answer_types_match_the_schemas(doc: Document, name: str) -> None:
    route = ROUTES[name]
    op = operation(doc, route)
    problems: List[str] = []
    if route.request is not None and route.request is not bytes:
        schema = op["requestBody"]["content"][route.request_media]["schema"]
        problems += check(doc, route.request, schema, "request", name + ".request")
    for media, kind in route.answers.items():
        schema = op["responses"][str(route.status)]["content"][media].get("schema", {})
        problems += check(doc, kind, schema, "answer", f"{name}.answer[{media}]")
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("name", sorted(ROUTES))
def test_error_answers_read_as_the_error_shape(doc: Document, name: str) -> None:
    op = operation(doc, ROUTES[name])
    problems: List[str] = []
    for status, answer in op["responses"].items():
        if status.startswith(("4", "5")) and JSON in answer.get("content", {}):
            schema = answer["content"][JSON]["schema"]
            problems += check(doc, _wire.ErrorBody, schema, "answer", f"{name}.{status}")
    assert not problems, "\n".join(problems)


def test_every_route_the_document_has_for_the_client_is_called_through_the_table() -> None:
    """No module but _wire's route table names an API path, so every call goes through ROUTES."""
    package = Path(geomint.__file__).parent
    for source in package.rglob("*.py"):
        if source.relative_to(package).as_posix() == "_wire/routes.py":
            continue
        text = source.read_text(encoding="utf-8")
        assert not re.search(r"[\"'](/api/|/healthz)", text), f"{source.name} names a path"


def test_the_client_uses_every_route_in_the_table() -> None:
    package = Path(geomint.__file__).parent
    text = (package / "client.py").read_text(encoding="utf-8")
    jobs = (package / "jobs.py").read_text(encoding="utf-8")
    library = (package / "library.py").read_text(encoding="utf-8")
    used = set(re.findall(r'(?:_send|_json|_stream|_study|_rrd)\("(\w+)"', text + jobs + library))
    used |= set(re.findall(r'ROUTES\["(\w+)"\]', jobs))
    used |= set(re.findall(r'"(\w+)"', text[text.index("routes = {"):text.index("}", text.index("routes = {"))]))
    assert set(ROUTES) - used == set(), f"routes declared but never called: {set(ROUTES) - used}"


# The checker must see drift, or the tests above would pass whatever the client declares.


class _Drifted(TypedDict):
    coordinates: List[str]
    potentials: str


class _WrongType(TypedDict):
    h: str


class _NullableClient(TypedDict):
    id: Optional[str]


class _Answer(TypedDict):
    method: str
    energy: List[float]
    energy_error: List[float]
    stop: Literal["finished"]


class _StopWhenAnything(TypedDict, total=False):
    where: str
    megno_mean: float


class _DirectionWithoutWhere(TypedDict):
    megno: float
    direction: Literal["up"]


class _NullWhere(TypedDict):
    where: Optional[str]


def test_the_checker_reads_member_constraints(doc: Document) -> None:
    """StopWhenRequest's allOf of anyOf clauses: at least one of `where` and the thresholds,
    non-null; `direction` and `count` only beside `where`."""
    ref = {"$ref": "#/components/schemas/StopWhenRequest"}
    empty = check(doc, _StopWhenAnything, ref, "request", "StopWhen")
    assert any("the schema requires it, the client may leave it out" in p for p in empty), empty
    lonely = check(doc, _DirectionWithoutWhere, ref, "request", "StopWhen")
    # Fits no alternative: with `where` it lacks `where`, without it `direction` must be null.
    assert lonely == ["StopWhen.where: the schema requires it, the client may leave it out"], lonely
    alternatives = doc.shapes(ref)
    without_where = [a for a in alternatives if "where" not in a.required]
    assert without_where and len(without_where) < len(alternatives)
    for a in without_where:
        for member in ("direction", "count"):
            assert {t for s in doc.shapes(a.properties[member]) for t in s.types} == {"null"}, (member, a)
    null = check(doc, _NullWhere, ref, "request", "StopWhen")
    assert any("StopWhen.where: the client may send null" in p for p in null), null
    assert check(doc, _wire.StopWhenEvent, ref, "request", "StopWhen") == []
    assert check(doc, _wire.StopWhenRequest, ref, "request", "StopWhen") == []
    # A shape the checker cannot read is an error, not a pass.
    with pytest.raises(ValueError, match="does not understand"):
        doc.shapes({"not": {"enum": ["up"]}})


def test_the_checker_reports_drift(doc: Document) -> None:
    ref = lambda name: {"$ref": f"#/components/schemas/{name}"}  # noqa: E731
    drift = check(doc, _Drifted, ref("SystemDefinition"), "request", "SystemDefinition")
    assert any("potentials: not in the schema" in p for p in drift), drift
    wrong = check(doc, _WrongType, ref("SimulateRequest"), "request", "SimulateRequest")
    assert any(".h: the client has string" in p for p in wrong), wrong
    assert any(".system: the schema requires it" in p for p in wrong), wrong
    nullable = check(doc, _NullableClient, ref("SystemEntry"), "request", "SystemEntry")
    assert any("may send null" in p for p in nullable), nullable
    answer = check(doc, _Answer, ref("RunDocument"), "answer", "RunDocument")
    # energy_error may be absent or null, and stop is an object, not a string.
    assert any("energy_error: the server may send null" in p for p in answer), answer
    assert any("energy_error: the client relies on it" in p for p in answer), answer
    assert any(p.startswith("RunDocument.stop: the client has ['finished']") for p in answer), answer
    # A union the client reads must cover every branch: one stop reason is not enough.
    narrow = check(doc, _wire.StopFinished, ref("Stop"), "answer", "Stop")
    assert any("'diverged'" in p for p in narrow), narrow
    assert check(doc, _wire.Stop, ref("Stop"), "answer", "Stop") == []


def test_wire_types_resolve() -> None:
    """Every annotation in _wire names a type the checker knows (a typo would hide a member)."""
    for name in dir(_wire):
        value = getattr(_wire, name)
        if isinstance(value, type) and issubclass(value, dict) and hasattr(value, "__required_keys__"):
            typing.get_type_hints(value)
