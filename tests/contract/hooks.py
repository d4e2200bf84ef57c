"""Hooks of the contract test (scripts/test-contract): schemathesis, driven by geomint's OpenAPI
document, checks every answer against the document. These hooks let it read the two media
types JSON does not cover, and replace its "valid data is accepted" check by the promise the
document can keep.

- NDJSON answers: every line is checked against the media type's schema (the line schema).
- Rerun recordings (application/octet-stream): a whole file starts with Rerun's magic `RRF2`.
- A request valid by the document is never refused for its form: no 400 and no 422 saying a
  member is missing, unknown or of the wrong type. A 422 for a value the document cannot
  constrain (an expression that does not parse, more steps than the limit, an option the chosen
  method lacks, an unknown stored system, a parameter the chosen system does not have) is the
  documented answer and passes.
"""

import json

import schemathesis
from jsonschema import Draft202012Validator

# Error codes that say the request's form is wrong: the document must have refused it first.
FORM_ERRORS = {"malformed_json", "unknown_field", "missing_field", "invalid_type", "unsupported_media_type"}

RRD_MAGIC = b"RRF2"


def _media_schema(ctx, response, media_type):
    operation = ctx.operation.definition.raw
    answer = operation.get("responses", {}).get(str(response.status_code), {})
    schema = answer.get("content", {}).get(media_type, {}).get("schema")
    if schema is None:
        return None
    # The document's components beside the schema, so that its `#/components/...` refs resolve.
    return {**schema, "components": ctx.operation.schema.raw_schema.get("components", {})}


@schemathesis.deserializer("application/x-ndjson")
def ndjson_lines(ctx, response):
    lines = [line for line in response.content.decode("utf-8").split("\n") if line]
    if not lines:
        raise ValueError("an NDJSON answer without a line")
    schema = _media_schema(ctx, response, "application/x-ndjson")
    documents = []
    for number, line in enumerate(lines, start=1):
        document = json.loads(line)
        if schema is not None:
            error = next(Draft202012Validator(schema).iter_errors(document), None)
            if error is not None:
                path = "/".join(str(p) for p in error.absolute_path)
                raise ValueError(f"NDJSON line {number} violates the line schema at /{path}: {error.message}")
        documents.append(document)
    # Schemathesis validates what is returned against the line schema once more.
    return documents[-1]


@schemathesis.deserializer("application/octet-stream")
def rerun_recording(ctx, response):
    if response.status_code == 200 and not response.content.startswith(RRD_MAGIC):
        raise ValueError(f"a recording that does not start with {RRD_MAGIC!r}: {response.content[:16]!r}")
    return response.content.decode("latin-1")


@schemathesis.check
def valid_requests_are_refused_only_for_their_values(ctx, response, case):
    meta = case.meta
    if meta is None or not meta.generation.mode.is_positive:
        return None
    if response.status_code in (400, 415):
        raise AssertionError(f"a request valid by the document was refused with {response.status_code}: {response.text[:300]}")
    if response.status_code == 422:
        error = json.loads(response.text).get("error", {})
        # A system's parameters are its own: their names and kinds are checked against the system.
        # (A job's request is checked as its route checks it, under `request.`.)
        per_system = (error.get("field") or "").removeprefix("request.").startswith("params.")
        if error.get("code") in FORM_ERRORS and not per_system:
            raise AssertionError(
                f"a request valid by the document was refused for its form ({error['code']}): {response.text[:300]}"
            )
    return None
