"""Lazy imports of the optional ``starsense[scale]`` dependencies.

``import starsense`` (and ``import starsense.scale``) must not import lsdb, hats or dask: the
core stays light. Every entry point of :mod:`starsense.scale` calls :func:`require` first.
"""

from __future__ import annotations

import importlib
import warnings
from types import ModuleType

from starsense.scale.errors import ScaleNotInstalledError

#: distribution that provides each module (for the error message)
_DISTRIBUTIONS = {
    "lsdb": "lsdb",
    "hats": "hats",
    "hats_import": "hats-import",
    "dask": "dask",
    "distributed": "dask[distributed]",
}

# Deprecation warnings raised inside lsdb 0.11 / nested-pandas 0.7 when they run on pandas >= 3.1
# (an option and an ``inplace=`` argument that pandas 4 will remove). They are about those
# libraries' own code, say nothing a starsense user can act on, and would fill the terminal once
# per partition; they are silenced by exact message, nothing else.
_THIRD_PARTY_DEPRECATIONS = (
    r"The 'mode\.chained_assignment' option is deprecated",
    r"The inplace keyword in NestedFrame\.\w+ is deprecated",
)


# hats-import warns once per input chunk, from every worker, when RA/Dec are not float64. Integer
# degrees are exact, and the positions are read as float64 afterwards; the note is not worth a
# screenful of repeated warnings.
_THIRD_PARTY_USER_WARNINGS = (r"Column '.*' is not double-precision float",)


def quiet_third_party_warnings() -> None:
    """Ignore the known third-party warnings above (idempotent; cheap enough per task)."""
    for message in _THIRD_PARTY_DEPRECATIONS:
        warnings.filterwarnings("ignore", message=message, category=DeprecationWarning)
    for message in _THIRD_PARTY_USER_WARNINGS:
        warnings.filterwarnings("ignore", message=message, category=UserWarning)


def require(*modules: str) -> list[ModuleType]:
    """Import ``modules`` (default: all of the extra), or raise :class:`ScaleNotInstalledError`.

    Returns the imported modules in the order asked.
    """
    names = modules or ("lsdb", "hats", "dask", "distributed")
    out = []
    quiet_third_party_warnings()
    for name in names:
        try:
            with warnings.catch_warnings():
                quiet_third_party_warnings()
                out.append(importlib.import_module(name))
        except ImportError as exc:
            dist = _DISTRIBUTIONS.get(name.split(".")[0], name)
            raise ScaleNotInstalledError(
                f"deep catalogues need the optional dependency {dist!r} ({exc}); "
                "install starsense[scale]: pip install 'starsense[scale]'"
            ) from None
    return out
