"""The frames of a calibration: each solved, and reduced to its matched stars.

:class:`FrameSolver` solves a frame with the sensor being calibrated, else as a camera of
unknown optics; :func:`frame_stars` keeps a solved frame's matched stars (centroids and
catalogue or apparent places) and its attitude, what :func:`starsense.solve.calibration.
calibrate` fits.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from starsense._validate import show
from starsense.catalog.apparent import apparent_places
from starsense.catalog.table import Catalog
from starsense.errors import InputError
from starsense.sensor import Sensor
from starsense.solve.solution import Solution
from starsense.solve.solver import Solver

__all__ = ["FrameSolver", "FrameStars", "frame_list", "frame_stars", "matched_stars"]


@dataclass(frozen=True, eq=False)
class FrameStars:
    """The matched stars of one solved frame.

    Attributes
    ----------
    centroids_px : ndarray, shape (N, 2)
        Measured (x = column, y = row), px.
    vectors : ndarray, shape (N, 3)
        The stars' ICRS unit vectors (catalogue or apparent places).
    rotation : Rotation
        The frame's attitude from the solver (ICRS -> camera): the starting point.
    name : str
        The frame's name, for messages.
    """

    centroids_px: np.ndarray
    vectors: np.ndarray
    rotation: Rotation
    name: str = ""


def frame_stars(solution, catalog, name: str = "") -> FrameStars:
    """Return the matched stars of a solved frame (apparent places when the solve used them).

    Parameters
    ----------
    solution : Solution
        A solved frame (:class:`starsense.solve.solver.Solution`).
    catalog : Catalog
        The catalogue the frame was identified with.
    name : str
        The frame's name.

    Returns
    -------
    FrameStars
    """
    if not solution.solved:
        raise InputError(f"{name or 'frame'}: not solved ({solution.status}), nothing to fit")
    det = np.array([d for d, _ in solution.matches], dtype=np.intp)
    idx = catalog.index_of(np.array([c for _, c in solution.matches], dtype=np.int64))
    vectors = np.asarray(catalog.vectors[idx], dtype=float)
    ap = solution.apparent or {}
    if ap.get("applied"):
        vectors = apparent_places(catalog, idx, ap["time_utc"]).vectors
    return FrameStars(solution.centroids_px[det], vectors, solution.rotation, name)


class FrameSolver:
    """Solve frames for a calibration: with the sensor, else as a camera of unknown optics.

    A frame through a lens that bends it more than the sensor's model allows (the model being
    calibrated) may not identify with that model; it is then solved with nothing known
    (:class:`~starsense.solve.solver.Solver` without a sensor: the field searched, a radial
    distortion fitted) and its matched stars fitted all the same. Call it on a frame (array) or
    an image file.

    Parameters
    ----------
    sensor : Sensor
        The starting camera model.
    catalog : Catalog or str
        The catalogue (object or spec), shared by both solvers.
    """

    def __init__(self, sensor, *, catalog: Catalog | str = "hipparcos") -> None:
        self.solver = Solver(sensor, catalog=catalog)
        self._unknown: Solver | None = None

    @property
    def catalog(self) -> Catalog:
        """The catalogue the matches refer to."""
        return self.solver.catalog

    def __call__(self, frame, obs_time=None) -> Solution:
        """Return the frame's Solution (the sensor's, or the unknown camera's if that solves)."""
        path = isinstance(frame, str | Path)
        sol = self.solver.solve_file(frame, obs_time) if path else self.solver(frame, obs_time)
        if sol.solved:
            return sol
        if self._unknown is None:
            self._unknown = Solver(catalog=self.solver.catalog)
        unknown = self._unknown
        other = unknown.solve_file(frame, obs_time) if path else unknown(frame, obs_time)
        return other if other.solved else sol


def matched_stars(frames: Sequence, sensor: Sensor, catalog) -> list[FrameStars]:
    """Return every frame as its matched stars, solving the images among them."""
    solver = FrameSolver(sensor, catalog=catalog)
    out = []
    for k, frame in enumerate(frames):
        name = str(frame) if isinstance(frame, str | Path) else f"frame {k}"
        if isinstance(frame, FrameStars):
            out.append(frame)
            continue
        if isinstance(frame, Solution):
            sol = frame
        else:
            sol = solver(frame)
        if not sol.solved:
            raise InputError(f"calibrate: {name} is not solved ({sol.status}: {sol.message})")
        out.append(frame_stars(sol, solver.catalog, name))
    return out


def frame_list(frames) -> list:
    """Return the frames given to :func:`calibrate` as a list (one frame alone is one item)."""
    if isinstance(frames, str | Path | np.ndarray | Solution | FrameStars):
        return [frames]
    if not isinstance(frames, Iterable):
        raise InputError(
            "frames must be a list of solved frames (FrameStars, Solutions, images or image "
            f"files); got {type(frames).__name__} {show(frames)}"
        )
    return list(frames)
