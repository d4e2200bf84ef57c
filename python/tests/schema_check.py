"""Compares the client's wire types (``geomint._wire``) with an OpenAPI 3.1 document.

A Python type is checked against a JSON schema in one of two directions:

- ``request``: everything the client may send must be valid for the schema: each member it
  declares exists in the schema with a type the schema accepts, every member the schema requires
  is one the client always sends, ``None`` only where the schema takes ``null``, and each branch
  of a Python union is accepted by some branch of the schema.
- ``answer``: everything the server may send must be readable by the client: each member the
  client declares exists in the schema with a compatible type, every member the client relies on
  (a required key) is one the schema requires, ``null`` only where the client expects ``None``,
  and each branch of the schema's union is read by some branch of the client's type.

An ``allOf`` is the intersection of its parts: a member two parts declare takes both schemas
(``{"where": {"not": {"type": "null"}}}`` narrows a nullable ``where`` to a string), and an
``anyOf``/``oneOf`` part without a type or properties of its own splits the object into its
alternatives (which members must come, or must not come, together). ``not`` is understood in the
two forms such constraints use, ``{"not": {"type": T}}`` (any type but T) and ``{"not":
{"properties": {k: {"not": {"type": "null"}}}, "required": [k]}}`` (``k`` absent or null); any
other ``not`` is refused rather than skipped. A ``oneOf``/``anyOf`` beside the object's own type
or properties (``method`` or ``methods``), or a ``not`` there, is not expanded.

The functions return problems as strings naming the place (``SimulateRequest.methods[]``), so
a failing test lists every drift at once.
"""

from __future__ import annotations

import types
import typing
from dataclasses import dataclass, field
from typing import Any, Dict, List, Literal, Union, get_args, get_origin

Schema = Dict[str, Any]
NoneType = type(None)

JSON_TYPES = {bool: "boolean", int: "integer", float: "number", str: "string"}
ALL_TYPES = frozenset({"null", "boolean", "integer", "number", "string", "array", "object"})


@dataclass
class Shape:
    """One alternative of a schema with its ``allOf`` parts merged and ``$ref`` resolved."""

    types: set = field(default_factory=set)
    properties: Dict[str, Schema] = field(default_factory=dict)
    required: set = field(default_factory=set)
    closed: bool = False
    items: Schema | None = None
    additional: Schema | None = None
    enum: list | None = None
    # No value has this shape (the parts of an allOf disagree on the type).
    impossible: bool = False

    def merge(self, other: "Shape") -> "Shape":
        """The values of both shapes (an ``allOf`` of the two)."""
        mine = self.types - {"any"}
        theirs = other.types - {"any"}
        if mine and theirs:
            types_ = mine & theirs
            impossible = not types_
        else:
            types_ = mine | theirs or (self.types | other.types)
            impossible = False
        enum = self.enum if other.enum is None else other.enum if self.enum is None else [
            v for v in self.enum if v in other.enum
        ]
        properties = dict(self.properties)
        for key, schema in other.properties.items():
            properties[key] = {"allOf": [properties[key], schema]} if key in properties else schema
        return Shape(
            types=types_,
            properties=properties,
            required=self.required | other.required,
            closed=self.closed or other.closed,
            items=other.items or self.items,
            additional=other.additional or self.additional,
            enum=enum,
            impossible=impossible or self.impossible or other.impossible or enum == [],
        )


class Document:
    """An OpenAPI document whose component schemas can be resolved and flattened."""

    def __init__(self, raw: Schema) -> None:
        self.raw = raw
        self.components: Dict[str, Schema] = raw.get("components", {}).get("schemas", {})

    def deref(self, schema: Schema) -> Schema:
        seen = 0
        while "$ref" in schema:
            name = schema["$ref"].rsplit("/", 1)[-1]
            schema = self.components[name]
            seen += 1
            if seen > 50:
                raise ValueError("a $ref cycle")
        return schema

    def shapes(self, schema: Schema) -> List[Shape]:
        """The alternatives a value of ``schema`` can take (``null`` as the type ``"null"``)."""
        schema = self.deref(schema)
        if schema == {} or schema is True:
            return [Shape(types={"any"})]
        base = Shape()
        is_object_like = "type" in schema or "properties" in schema
        if "type" in schema:
            t = schema["type"]
            base.types = set(t) if isinstance(t, list) else {t}
        if "properties" in schema:
            base.properties = dict(schema["properties"])
            base.types = base.types or {"object"}
        base.required = set(schema.get("required", []))
        base.closed = schema.get("additionalProperties") is False
        if isinstance(schema.get("additionalProperties"), dict):
            base.additional = schema["additionalProperties"]
        if "items" in schema:
            base.items = schema["items"]
        if "enum" in schema:
            base.enum = list(schema["enum"])
            base.types = base.types or {_json_type(v) for v in schema["enum"]}
        if "const" in schema:
            base.enum = [schema["const"]]
            base.types = base.types or {_json_type(schema["const"])}
        alternatives = [base]
        # A "not" beside a type or properties, like a oneOf there, only constrains which members
        # come together; elsewhere (an allOf's part, an anyOf's branch) it is a shape's own.
        if "not" in schema and not is_object_like:
            alternatives = [base.merge(n) for n in self.negation(schema["not"])]
        for part in schema.get("allOf", []):
            alternatives = [a.merge(b) for a in alternatives for b in self.shapes(part)]
        # oneOf/anyOf beside a type or properties only constrain which members come together.
        union = schema.get("oneOf") or schema.get("anyOf")
        if union and not is_object_like:
            merged = []
            for branch in union:
                for b in self.shapes(branch):
                    for a in alternatives:
                        merged.append(a.merge(b) if (a.types or a.properties) else b)
            alternatives = merged
        return [a for a in alternatives if not a.impossible and not self._required_never(a)]

    def _required_never(self, shape: Shape) -> bool:
        """Whether a member ``shape`` requires can take no value (a contradiction in allOf)."""
        return any(key in shape.properties and not self.shapes(shape.properties[key])
                   for key in shape.required)

    def negation(self, schema: Schema) -> List[Shape]:
        """The alternatives ``{"not": schema}`` takes, in the forms the document's constraints
        use: not a type; not (``k`` present and not null), that is ``k`` absent or null; and not
        an allOf of those (one of them absent or null)."""
        schema = self.deref(schema)
        if set(schema) == {"type"}:
            t = schema["type"]
            excluded = set(t) if isinstance(t, list) else {t}
            return [Shape(types=set(ALL_TYPES - excluded))]
        if set(schema) == {"properties", "required"} and len(schema["required"]) == 1:
            (key,) = schema["required"]
            if schema["properties"] == {key: {"not": {"type": "null"}}}:
                return [Shape(properties={key: {"type": "null"}})]
        if set(schema) == {"allOf"}:
            return [n for part in schema["allOf"] for n in self.negation(part)]
        raise ValueError(f"the checker does not understand {{'not': {schema!r}}}")


def _json_type(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "number"
    if isinstance(value, str):
        return "string"
    return "object" if isinstance(value, dict) else "array"


def _is_typeddict(tp: Any) -> bool:
    return isinstance(tp, type) and issubclass(tp, dict) and hasattr(tp, "__required_keys__")


def _union_members(tp: Any) -> List[Any] | None:
    origin = get_origin(tp)
    if origin is Union or origin is types.UnionType:
        return list(get_args(tp))
    return None


def check(doc: Document, tp: Any, schema: Schema, direction: str, where: str) -> List[str]:
    """Problems of the Python type ``tp`` against ``schema`` in ``direction``."""
    shapes = doc.shapes(schema)
    if any("any" in s.types for s in shapes) or tp is object:
        return []
    members = _union_members(tp) or [tp]
    nullable_schema = any("null" in s.types for s in shapes)
    nullable_client = NoneType in members
    problems: List[str] = []
    if direction == "request" and nullable_client and not nullable_schema:
        problems.append(f"{where}: the client may send null, which the schema does not take")
    if direction == "answer" and nullable_schema and not nullable_client:
        problems.append(f"{where}: the server may send null, which the client does not expect")
    py_members = [m for m in members if m is not NoneType]
    schema_shapes = [_without_null(s) for s in shapes]
    schema_shapes = [s for s in schema_shapes if s.types or s.properties]
    if direction == "request":
        for m in py_members:
            problems += _best(doc, m, schema_shapes, direction, where)
    else:
        for s in schema_shapes:
            problems += _best_member(doc, py_members, s, direction, where)
    return problems


def _without_null(shape: Shape) -> Shape:
    return Shape(
        types=shape.types - {"null"},
        properties=shape.properties,
        required=shape.required,
        closed=shape.closed,
        items=shape.items,
        additional=shape.additional,
        enum=None if shape.enum is None else [v for v in shape.enum if v is not None],
        impossible=shape.impossible,
    )


def _best(doc: Document, tp: Any, shapes: List[Shape], direction: str, where: str) -> List[str]:
    """Problems of ``tp`` against the schema alternative it fits best ([] if one fits)."""
    if not shapes:
        return [f"{where}: the schema takes only null"]
    results = [_against_shape(doc, tp, s, direction, where) for s in shapes]
    return min(results, key=len)


def _best_member(doc: Document, members: List[Any], shape: Shape, direction: str, where: str) -> List[str]:
    if not members:
        return [f"{where}: the client reads only null here"]
    results = [_against_shape(doc, m, shape, direction, where) for m in members]
    return min(results, key=len)


def _against_shape(doc: Document, tp: Any, shape: Shape, direction: str, where: str) -> List[str]:
    types_ = shape.types
    if "any" in types_ or tp is object:
        return []
    origin = get_origin(tp)
    if origin is Literal:
        values = list(get_args(tp))
        if shape.enum is None:
            if not types_ & {_json_type(v) for v in values}:
                return [f"{where}: the client has {values}, the schema {sorted(types_)}"]
            return []
        if direction == "request":
            extra = [v for v in values if v not in shape.enum]
            return [f"{where}: {extra} not among the schema's {shape.enum}"] if extra else []
        missing = [v for v in shape.enum if v not in values]
        return [f"{where}: the schema's {missing} not among the client's {values}"] if missing else []
    if tp in JSON_TYPES:
        wanted = JSON_TYPES[tp]
        if wanted in types_:
            return []
        # A JSON integer is a number too: the client may send a float's member as an integer
        # only if the server takes numbers; it may read an integer member as a float.
        if tp is float and direction == "answer" and "integer" in types_:
            return []
        return [f"{where}: the client has {wanted}, the schema {sorted(types_)}"]
    if tp is bytes:
        return [] if "string" in types_ else [f"{where}: bytes against {sorted(types_)}"]
    if origin in (list, List):
        if "array" not in types_:
            return [f"{where}: the client has an array, the schema {sorted(types_)}"]
        (item,) = get_args(tp)
        return check(doc, item, shape.items or {}, direction, where + "[]")
    if origin in (dict, Dict):
        if "object" not in types_:
            return [f"{where}: the client has an object, the schema {sorted(types_)}"]
        _, value = get_args(tp)
        if value is object:
            return []
        if shape.properties and not shape.additional:
            return [f"{where}: the client has a map, the schema a record {sorted(shape.properties)}"]
        if shape.additional is not None:
            return check(doc, value, shape.additional, direction, where + "{}")
        return []
    if _is_typeddict(tp):
        if "object" not in types_:
            return [f"{where}: the client has {tp.__name__}, the schema {sorted(types_)}"]
        return _record(doc, tp, shape, direction, where)
    return [f"{where}: the checker does not know the type {tp!r}"]


def _record(doc: Document, tp: Any, shape: Shape, direction: str, where: str) -> List[str]:
    problems: List[str] = []
    hints = typing.get_type_hints(tp)
    required = set(tp.__required_keys__)
    for key, hint in hints.items():
        place = f"{where}.{key}"
        if key not in shape.properties:
            problems.append(f"{place}: not in the schema (members: {sorted(shape.properties)})")
            continue
        problems += check(doc, hint, shape.properties[key], direction, place)
        if direction == "answer" and key in required and key not in shape.required:
            problems.append(f"{place}: the client relies on it, the schema does not require it")
    if direction == "request":
        for key in sorted(shape.required - required):
            problems.append(f"{where}.{key}: the schema requires it, the client may leave it out")
    return problems
