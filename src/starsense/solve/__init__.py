"""Solving frames: load any image, detect, identify and estimate the attitude; track sequences."""

import importlib
from typing import Any

from starsense.solve.frames import load_image
from starsense.solve.settings import SolverSettings
from starsense.solve.solution import Solution, SolveStatus
from starsense.solve.solver import Solver

__all__ = [
    "Prior",
    "Solution",
    "SolveStatus",
    "Solver",
    "SolverSettings",
    "TrackSolution",
    "Tracker",
    "load_image",
    "track_frame",
]

#: tracking's names, imported on first use: solving one frame does not need the tracker (nor
#: the scipy.optimize fit of its streak rate)
_TRACKING = ("Prior", "Tracker", "TrackSolution", "track_frame")


def __getattr__(name: str) -> Any:
    """Return a tracking name (``Prior``, ``Tracker``, ...) from :mod:`.tracking`."""
    if name in _TRACKING:
        return getattr(importlib.import_module("starsense.solve.tracking"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
