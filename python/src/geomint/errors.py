"""Errors the client raises: the server's refusals and the client's own checks, in one shape."""

from __future__ import annotations

from typing import Optional

from ._wire import ErrorDetail


class GeomintError(Exception):
    """A request geomint refused, or one the client refused before sending it.

    Carries the server's error shape: ``code`` (machine-readable, e.g. ``invalid_expression``),
    ``field`` (where, e.g. ``system.potential`` or ``axes[0].min``), ``position`` (for an
    expression, the 0-based character where it goes wrong) and ``message``. ``status`` is the HTTP
    status (``None`` for the client's own checks and for errors reported inside a stream), and
    ``method`` the index of the method an error inside a simulation's stream concerns.
    """

    def __init__(
        self,
        code: str,
        message: str,
        *,
        field: Optional[str] = None,
        position: Optional[int] = None,
        status: Optional[int] = None,
        method: Optional[int] = None,
        retry_after: Optional[float] = None,
    ) -> None:
        super().__init__(message)
        self.code = code
        self.message = message
        self.field = field
        self.position = position
        self.status = status
        self.method = method
        self.retry_after = retry_after

    @classmethod
    def from_detail(
        cls,
        detail: ErrorDetail,
        *,
        status: Optional[int] = None,
        method: Optional[int] = None,
        retry_after: Optional[float] = None,
    ) -> "GeomintError":
        """The error for the server's ``{"code", "field", "position", "message"}``."""
        kind: type[GeomintError] = RefusedError if status is None or status < 500 else ServerError
        if status == 503:
            kind = OverloadedError
        return kind(
            detail["code"],
            detail["message"],
            field=detail.get("field"),
            position=detail.get("position"),
            status=status,
            method=method,
            retry_after=retry_after,
        )

    def __repr__(self) -> str:
        parts = [f"code={self.code!r}"]
        if self.field is not None:
            parts.append(f"field={self.field!r}")
        if self.position is not None:
            parts.append(f"position={self.position}")
        if self.status is not None:
            parts.append(f"status={self.status}")
        parts.append(f"message={self.message!r}")
        return f"{type(self).__name__}({', '.join(parts)})"


class RefusedError(GeomintError):
    """The request is wrong (a 4xx answer, or an error line in a stream)."""


class ValidationError(RefusedError):
    """The client found the request wrong before sending it (``status`` is ``None``)."""

    def __init__(self, field: str, message: str, *, code: str = "invalid_value") -> None:
        super().__init__(code, f"{field}: {message}", field=field)


class OverloadedError(GeomintError):
    """Every simulation slot was busy (503); ``retry_after`` says when to try again, in seconds."""


class UnreachableError(GeomintError):
    """No geomint server answered at the client's URL (the connection was refused, the name did
    not resolve, or connecting timed out): the message names the URL and how to start a server."""


class ServerError(GeomintError):
    """The server failed (5xx other than 503), or answered in a way the client cannot read."""


class MissingError(AttributeError):
    """A quantity the answer does not hold, asked for by its attribute: the message says why it is
    missing and how to ask for it (an AttributeError, so ``hasattr`` and ``getattr(…, default)``
    treat it as absent)."""

    def __init__(self, name: str, reason: str) -> None:
        super().__init__(f"{name}: {reason}")
        self.name = name
        self.reason = reason
