"""Keyword arguments checked by name: a misspelt keyword (``param=`` for ``params=``) raises a
TypeError that names it and the nearest keyword the function takes, instead of being ignored."""

from __future__ import annotations

import difflib
import functools
import inspect
from typing import Any, Callable, Sequence, TypeVar, cast

F = TypeVar("F", bound=Callable[..., Any])


def unknown_keyword(function: str, given: str, known: Sequence[str]) -> TypeError:
    """The TypeError for keyword ``given``, which ``function`` does not take: the nearest of
    ``known`` (by difflib's similarity), or every one of them when none is near."""
    near = difflib.get_close_matches(given, known, n=1, cutoff=0.6)
    if near:
        hint = f"did you mean {near[0]!r}?"
    else:
        hint = "it takes " + ", ".join(known)
    return TypeError(f"{function}() got an unexpected keyword argument {given!r}; {hint}")


def checked(function: F) -> F:
    """``function`` refusing keywords it does not take with :func:`unknown_keyword`'s error.

    ``function`` keeps its own signature for ``help()``, IDEs and type checkers (the wrapper is
    ``functools.wraps``'d); a function that itself takes ``**kwargs`` is returned unchanged."""
    parameters = inspect.signature(function).parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters.values()):
        return function
    keywords = [name for name, p in parameters.items()
                if name != "self" and p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD,
                                                 inspect.Parameter.KEYWORD_ONLY)]
    accepted = frozenset(keywords)
    name = function.__qualname__

    @functools.wraps(function)
    def call(*args: Any, **kwargs: Any) -> Any:
        for key in kwargs:
            if key not in accepted:
                raise unknown_keyword(name, key, keywords)
        return function(*args, **kwargs)

    return cast(F, call)
