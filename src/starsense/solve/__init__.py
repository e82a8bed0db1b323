"""Solving frames: load any image, detect, identify and estimate the attitude."""

from starsense.solve.frames import load_image
from starsense.solve.solver import Solution, Solver

__all__ = ["Solution", "Solver", "load_image"]
