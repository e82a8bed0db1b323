"""Command line: parse, load, call the API, print or write results. No physics here.

One module per command group (``limit``, ``slew``, ``frames`` for render/solve/montecarlo,
``report``, ``availability``, ``guide_stars``, ``catalog``); the shared options and output helpers
live in :mod:`starsense.cli.common`; :mod:`starsense.cli.app` assembles the app and turns user
errors into one line and exit status 2.
"""

from starsense.cli.app import _console_main, app, main

__all__ = ["_console_main", "app", "main"]
