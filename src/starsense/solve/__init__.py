"""Solving frames: load any image, detect, identify and estimate the attitude; track sequences."""

from starsense.solve.frames import load_image
from starsense.solve.settings import SolverSettings
from starsense.solve.solution import Solution, SolveStatus
from starsense.solve.solver import Solver
from starsense.solve.tracking import Prior, Tracker, TrackSolution, track_frame

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
