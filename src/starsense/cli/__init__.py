"""Command line: parse, load, call the API, print or write results. No physics here.

One module per command group (``limit``, ``slew``, ``frames`` for render/montecarlo,
``report``, ``availability``, ``guide_stars``, ``catalog``); the shared options and output helpers
live in :mod:`starsense.cli.common`; :mod:`starsense.cli.app` assembles the app (only the
invoked command's module is imported) and turns user errors into one line and exit status 2.
"""

import importlib
from typing import Any

from starsense.cli.app import build_app, console_main, main

__all__ = ["app", "build_app", "console_main", "main"]

# ``starsense.cli.app`` is the app (``from starsense.cli import app``), as it always was, not the
# submodule that the import above bound here: the app is built on first use, by __getattr__
del globals()["app"]


def __getattr__(name: str) -> Any:
    """``app``: the app with every command registered, built on first use."""
    if name == "app":
        return importlib.import_module("starsense.cli.app").app
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
