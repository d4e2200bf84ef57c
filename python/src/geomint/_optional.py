"""The optional libraries (xarray, pandas, tqdm, Rerun's notebook viewer), imported when used."""

from __future__ import annotations

import importlib
from types import ModuleType


def require(module: str, extra: str, purpose: str) -> ModuleType:
    """Imports ``module``, or raises an ImportError that says which extra installs it."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise ImportError(
            f"{purpose} needs the package `{module.split('.')[0]}`: "
            f"pip install 'geomint[{extra}]'"
        ) from e


def xarray() -> ModuleType:
    """The xarray module (extra ``xarray``)."""
    return require("xarray", "xarray", "to_xarray()")


def pandas() -> ModuleType:
    """The pandas module (extra ``pandas``)."""
    return require("pandas", "pandas", "to_pandas()")


def available(module: str) -> bool:
    """Whether ``module`` can be imported."""
    try:
        importlib.import_module(module)
    except ImportError:
        return False
    return True
