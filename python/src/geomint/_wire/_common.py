"""The JSON number types the other modules share."""

from __future__ import annotations

from typing import Union


# JSON numbers as the server writes them; a whole float may come as an integer literal.
Number = float
# A number, or an expression in the names a definition declares.
Entry = Union[float, str]
