"""Looking up one of a result's parts by position or by name."""

from __future__ import annotations

from typing import Callable, Sequence, Tuple, TypeVar, Union

T = TypeVar("T")
Key = Union[int, str, Tuple[str, str]]


def pick(items: Sequence[T], key: Key, names: Callable[[T], Tuple[object, ...]], what: str) -> T:
    """``items[key]`` for a position, else the first item that ``names`` gives ``key`` for; the
    KeyError lists each item's first name."""
    if isinstance(key, int):
        return items[key]
    for item in items:
        if key in names(item):
            return item
    raise KeyError(f"no {what} {key!r}; there are {[names(item)[0] for item in items]}")
