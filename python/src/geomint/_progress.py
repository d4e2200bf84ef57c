"""A progress bar for streams (tqdm's, when it is installed and wanted; else nothing)."""

from __future__ import annotations

from typing import Any, Optional

from . import _optional


class Progress:
    """Counts a stream's work; draws it with ``tqdm.auto`` when enabled and installed."""

    def __init__(self, enabled: bool, unit: str) -> None:
        self._bar: Optional[Any] = None
        self.done = 0
        if enabled and _optional.available("tqdm"):
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
