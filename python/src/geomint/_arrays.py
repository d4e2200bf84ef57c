"""JSON values to numpy arrays, without losing a bit.

Python's JSON reader turns every number into the nearest double (``float()`` is correctly
rounded), and the server writes every double so that it reads back as itself; the arrays below
copy those doubles unchanged. ``null`` (the server's word for a number that is not finite, or
not measured) becomes NaN in float arrays. Integer columns stay integers (int64); a count that
int64 cannot hold raises instead of wrapping.
"""

from __future__ import annotations

from typing import Optional, Sequence, TypeVar, Union

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
ObjectArray = npt.NDArray[np.object_]

Nested = Union[
    Sequence[Optional[float]],
    Sequence[Sequence[Optional[float]]],
    Sequence[Sequence[Sequence[Optional[float]]]],
]


def floats(values: Nested) -> FloatArray:
    """A float64 array of JSON numbers (``None`` → NaN)."""
    return np.array(values, dtype=np.float64)


def rows(values: Sequence[Sequence[float]], width: int) -> FloatArray:
    """A (samples, width) float64 array, also when there are no samples."""
    if len(values) == 0:
        return np.empty((0, width), dtype=np.float64)
    return np.array(values, dtype=np.float64)


def ints(values: Sequence[int]) -> IntArray:
    """An int64 array of JSON integers."""
    return np.array(values, dtype=np.int64)


def bools(values: Union[Sequence[bool], Sequence[Sequence[bool]]]) -> BoolArray:
    """A boolean array."""
    return np.array(values, dtype=np.bool_)


def objects(values: Sequence[Optional[str]]) -> ObjectArray:
    """An object array of strings and ``None``."""
    out = np.empty(len(values), dtype=object)
    for i, v in enumerate(values):
        out[i] = v
    return out


def grid(values: Nested, shape: tuple[int, ...]) -> FloatArray:
    """A per-cell column in cell order (the first axis running fastest) on a grid of ``shape``.

    Cell ``i0 + n0·i1`` goes to ``[i0, i1]``: the array is indexed by the axes in their order.
    """
    return np.reshape(floats(values), shape, order="F")


Scalar = TypeVar("Scalar", bound=np.generic)


def grid_of(array: npt.NDArray[Scalar], shape: tuple[int, ...]) -> npt.NDArray[Scalar]:
    """``grid`` for an array that is already numpy (integers, booleans, objects)."""
    return np.reshape(array, shape, order="F")


def optional_rows(values: Optional[Sequence[Sequence[float]]], width: int) -> Optional[FloatArray]:
    """:func:`rows`, or ``None`` for a column the server left out."""
    return None if values is None else rows(values, width)
