"""The client's connection to a geomint server: requests built from the route table, errors read
from answers, NDJSON streams, studies with a progress bar, recordings."""

from __future__ import annotations

import json
import os
from typing import Any, Callable, Dict, List, Optional, cast
from urllib.parse import quote

import httpx

from ._arguments import AnyStudyLine, StudyResult, _is_error_body
from ._progress import Progress
from ._version import __version__
from ._wire import JSON, NDJSON, ROUTES, RRD, ErrorBody, ErrorDetail, Route
from .errors import GeomintError, ServerError, UnreachableError
from .recording import Recording

DEFAULT_URL = "http://127.0.0.1:8080"


class Transport:
    """A connection to a geomint server and the ways the client talks over it: a route's request
    with its JSON body, the error an answer of 400 or more raises, NDJSON streams read line by
    line, studies streamed with a progress bar, and recordings."""

    def __init__(
        self,
        url: Optional[str] = None,
        token: Optional[str] = None,
        *,
        timeout: Optional[float] = 300.0,
        transport: Optional[httpx.BaseTransport] = None,
    ) -> None:
        self.url = (url or os.environ.get("GEOMINT_URL") or DEFAULT_URL).rstrip("/")
        headers = {"user-agent": f"geomint-python/{__version__}"}
        if token is not None:
            headers["authorization"] = f"Bearer {token}"
        # Catalogue entries by system id, fetched when a request names state components.
        self._entries: Dict[str, Any] = {}
        self._http = httpx.Client(
            base_url=self.url,
            headers=headers,
            timeout=httpx.Timeout(timeout, connect=10.0 if timeout is None else min(timeout, 10.0)),
            transport=transport,
        )

    def close(self) -> None:
        """Closes the client's connections."""
        self._http.close()


    def _send(
        self,
        name: str,
        *,
        body: Any = None,
        content: Optional[bytes] = None,
        accept: str = JSON,
        query: Optional[Dict[str, str]] = None,
        ids: Optional[Dict[str, str]] = None,
    ) -> httpx.Response:
        route = ROUTES[name]
        request = self._request(route, body=body, content=content, accept=accept, query=query, ids=ids)
        try:
            response = self._http.send(request)
        except (httpx.ConnectError, httpx.ConnectTimeout) as e:
            raise self._unreachable(e) from e
        if response.status_code >= 400:
            raise self._error(response)
        return response

    def _request(
        self,
        route: Route,
        *,
        body: Any = None,
        content: Optional[bytes] = None,
        accept: str = JSON,
        query: Optional[Dict[str, str]] = None,
        ids: Optional[Dict[str, str]] = None,
    ) -> httpx.Request:
        path = route.url(**{k: quote(v, safe="") for k, v in (ids or {}).items()})
        headers = {"accept": accept}
        if body is not None:
            content = json.dumps(body, allow_nan=False, ensure_ascii=False).encode("utf-8")
            headers["content-type"] = JSON
        elif content is not None:
            headers["content-type"] = route.request_media
        return self._http.build_request(route.method, path, content=content, headers=headers, params=query)

    def _unreachable(self, cause: Exception) -> UnreachableError:
        """The error for a server that did not answer at :attr:`url`."""
        source = "the GEOMINT_URL environment variable" if os.environ.get("GEOMINT_URL") else "the default URL"
        return UnreachableError(
            "unreachable",
            f"no geomint server answered at {self.url} ({cause or type(cause).__name__}). Start one with "
            "`scripts/serve` in the repository (or `geomint serve`; GEOMINT_ADDR sets its address), then "
            f"give its URL as Client(url) or in the GEOMINT_URL environment variable (this client took {source}). "
            "Simulations can also run without a server, in this process: geomint.local.simulate(...) "
            "takes the same arguments.",
        )

    @staticmethod
    def _error(response: httpx.Response) -> GeomintError:
        response.read()
        retry = response.headers.get("retry-after")
        retry_after = float(retry) if retry and retry.replace(".", "", 1).isdigit() else None
        try:
            body = response.json()
        except ValueError:
            body = None
        detail: ErrorDetail
        if _is_error_body(body):
            detail = cast(ErrorBody, body)["error"]
        else:
            # Not the service's error shape (a proxy in between, say): the status line and text.
            detail = {"code": f"http_{response.status_code}",
                      "message": f"HTTP {response.status_code} {response.reason_phrase}: {response.text[:200]}"}
        return GeomintError.from_detail(detail, status=response.status_code, retry_after=retry_after)

    def _json(self, name: str, **kwargs: Any) -> Any:
        """The JSON answer of route ``name``; callers give it the route's answer type."""
        return self._send(name, **kwargs).json()

    def _stream(self, name: str, body: Any, handle: Callable[[Any], None]) -> None:
        """POSTs ``body`` asking for NDJSON and calls ``handle`` with each line as it arrives.

        An ``error`` line raises; a stream that ends without its ``end`` line raises. When
        anything interrupts the reading (Ctrl-C in a notebook raises KeyboardInterrupt), the
        connection is closed before the exception goes on, and the server stops computing.
        """
        request = self._request(ROUTES[name], body=body, accept=NDJSON)
        try:
            response = self._http.send(request, stream=True)
        except (httpx.ConnectError, httpx.ConnectTimeout) as e:
            raise self._unreachable(e) from e
        try:
            if response.status_code >= 400:
                raise self._error(response)
            ended = False
            for text in response.iter_lines():
                if not text.strip():
                    continue
                line = json.loads(text)
                kind = line.get("type")
                if kind == "error":
                    raise GeomintError.from_detail(line["error"], method=line.get("method"))
                if kind == "end":
                    ended = True
                    break
                handle(line)
            if not ended:
                raise ServerError("stream_cut", "the stream ended before its last line: the server stopped early")
        finally:
            response.close()

    def _rrd(self, name: str, body: Any) -> Recording:
        response = self._send(name, body=body, accept=RRD, query={"format": "rrd"})
        return Recording(response.content)

    def _study(self, name: str, body: Any, progress: bool, label: str) -> StudyResult:
        """Runs a study over its NDJSON stream with a progress bar; returns its ``result`` line."""
        result: List[StudyResult] = []
        with Progress(progress, label) as bar:
            def handle(line: AnyStudyLine) -> None:
                if line["type"] == "progress" or line["type"] == "point":
                    bar.total(line["total"])
                    bar.to(line["done"])
                elif line["type"] == "reference":
                    bar.total(line["total"])
                elif line["type"] == "result":
                    result.append(line)

            self._stream(name, body, handle)
        if not result:
            raise ServerError("stream_cut", "the study's stream ended without its result")
        return result[0]
