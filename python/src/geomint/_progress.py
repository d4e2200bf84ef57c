"""A progress bar for streams: tqdm's, when it is installed, wanted and someone is watching (a
notebook, or a terminal on stderr); nothing in a plain script whose output goes to a file."""

from __future__ import annotations

import sys
from typing import Any, Optional

from . import _optional


def in_notebook() -> bool:
    """Whether this process is a Jupyter kernel: an IPython shell with a kernel (Jupyter's,
    VS Code's, Colab's), not IPython in a terminal."""
    ipython = sys.modules.get("IPython")
    get = getattr(ipython, "get_ipython", None) if ipython is not None else None
    shell = get() if callable(get) else None
    return getattr(shell, "kernel", None) is not None


def interactive() -> bool:
    """Whether a progress bar would be seen: in a notebook, or with stderr on a terminal."""
    if in_notebook():
        return True
    isatty = getattr(sys.stderr, "isatty", None)
    return bool(isatty()) if callable(isatty) else False


class Progress:
    """Counts a stream's work; draws it with ``tqdm.auto`` when enabled, installed and
    :func:`interactive`."""

    def __init__(self, enabled: bool, unit: str) -> None:
        self._bar: Optional[Any] = None
        self.done = 0
        if enabled and interactive() and _optional.available("tqdm"):
            from tqdm.auto import tqdm

            self._bar = tqdm(total=None, unit=f" {unit}", leave=True)

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.close()

    def total(self, total: int) -> None:
        """Sets the amount of work the stream announced."""
        if self._bar is not None and self._bar.total != total:
            self._bar.total = total
            self._bar.refresh()

    def advance(self, n: int) -> None:
        """Counts ``n`` more units done."""
        self.to(self.done + n)

    def to(self, done: int) -> None:
        """Sets the units done."""
        if self._bar is not None and done > self.done:
            self._bar.update(done - self.done)
        self.done = max(self.done, done)
