"""Looking up one of a result's parts by position or by name."""

from __future__ import annotations

from typing import Callable, List, Sequence, Tuple, TypeVar, Union

T = TypeVar("T")
Key = Union[int, str, Tuple[str, str]]


def asked_name(label: object) -> object:
    """The name a run was asked for, from its label: ``yoshida_6(modin_3s)`` → ``yoshida_6``,
    ``csv1 [polar]`` → ``csv1`` (other labels and keys unchanged)."""
    if not isinstance(label, str):
        return label
    for mark in ("(", " ["):
        if mark in label:
            label = label[: label.index(mark)]
    return label.strip()


def pick(items: Sequence[T], key: Key, names: Callable[[T], Tuple[object, ...]], what: str) -> T:
    """``items[key]`` for a position, else the first item that ``names`` gives ``key`` for, else
    the one item whose name as asked for (:func:`asked_name`: a method ``yoshida_6`` is labelled
    ``yoshida_6(modin_3s)``) is ``key``; the KeyError lists each item's first name."""
    if isinstance(key, int):
        return items[key]
    for item in items:
        if key in names(item):
            return item
    asked: List[T] = [item for item in items if any(asked_name(n) == key for n in names(item))]
    if len(asked) == 1:
        return asked[0]
    labels = [names(item)[0] for item in (asked or items)]
    if asked:
        raise KeyError(f"{key!r} names several {what}s: {labels}; give one of these labels")
    raise KeyError(f"no {what} {key!r}; there are {labels}")
