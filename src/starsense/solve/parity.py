"""The parity check: a frame that does not solve is tried once more as its mirror image.

A star field seen in a mirror has the sky's edge ratios (pattern hashing finds candidates) but
the opposite handedness, so no proper rotation fits it and identification rightly fails. The
usual causes are a camera read out mirrored (a flipped row or column order) or a wrong sign
convention in the pixel axes. When the frame does not solve, its centroids are flipped left to
right (x -> width - 1 - x, the centroids of ``image[:, ::-1]``) and solved again; if that
solves, the answer is status "mirrored" (never "solved") with the attitude of the flipped frame,
which is the camera's attitude once its readout is flipped back.

The check runs only after a failure, so the normal path is unchanged; it costs one more
identification attempt on frames that do not solve.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from starsense.solve.counts import max_candidates, too_many_message
from starsense.solve.solution import Solution

__all__ = ["MIRRORED", "mirror_x", "solve_mirrored", "unsolved"]

#: status of a frame whose mirror image solves
MIRRORED = "mirrored"


def mirror_x(x, width: int) -> np.ndarray:
    """Return the columns of centroids in the left-right mirror image of a frame.

    Pixel convention of :mod:`starsense.detect`: (0, 0) is the centre of the top-left pixel, so
    column ``x`` of a frame ``width`` pixels wide is column ``width - 1 - x`` of
    ``image[:, ::-1]``.

    Parameters
    ----------
    x : array_like, shape (N,)
        Columns of the centroids, pixels.
    width : int
        Columns of the frame, pixels.

    Returns
    -------
    ndarray, shape (N,)
        Columns in the mirrored frame, pixels.
    """
    return (int(width) - 1) - np.asarray(x, dtype=float)


def solve_mirrored(x, y, flux, *, shape, solve_points):
    """Solve the mirror image of centroids that did not solve; return a "mirrored" Solution.

    Parameters
    ----------
    x, y : array_like, shape (N,)
        Columns and rows of the centroids as detected, pixels.
    flux : array_like, shape (N,)
        Their brightness (anything that grows with it).
    shape : (int, int)
        Rows, columns of the frame.
    solve_points : callable
        ``solve_points(x, y, flux)`` -> Solution: the solver's pipeline from centroids, without
        a further parity check.

    Returns
    -------
    Solution or None
        Status "mirrored" with the attitude of the left-right flipped frame, and its
        ``centroids_px`` those of the flipped frame; None when the mirror image does not solve
        either.
    """
    sol = solve_points(mirror_x(x, shape[1]), np.asarray(y, dtype=float), flux)
    if not sol.solved:
        return None
    message = (
        f"the image is mirrored: its left-right mirror image solves ({sol.message}); the "
        "camera is read out flipped (row or column order) or a pixel axis has the wrong "
        "sign; the attitude given is that of the flipped frame"
    )
    return dataclasses.replace(sol, status=MIRRORED, message=message)


def unsolved(points, ident, *, mirrored, stages, time_ms: float):
    """Return the answer for centroids that did not solve: their mirror image, or why not.

    Parameters
    ----------
    points : CentroidPoints
        The centroids.
    ident : identification result
        Why they did not identify (``status``, ``message``).
    mirrored : callable or None
        ``mirrored(x, y, flux) -> Solution``: the mirror image solved (None: not tried).
    stages : dict
        The solve's stage times, ms.
    time_ms : float
        The solve's time so far, ms.

    Returns
    -------
    Solution
        The mirror image's when it solves; else unsolved, "too_many_candidates" when the frame
        holds more detections than it can as stars (:func:`starsense.solve.counts.
        max_candidates`).
    """
    n, shape = len(points.x), points.shape
    status, message = ident.status, ident.message
    limit = max_candidates(shape)
    if mirrored is not None and n <= limit:  # a mirrored frame fails identification: flip
        got = solve_mirrored(points.x, points.y, points.flux, shape=shape, solve_points=mirrored)
        if got is not None:
            return got
    if n > limit:
        status, message = (
            "too_many_candidates",
            too_many_message(n, shape, limit=limit, then=message),
        )
    return Solution(status, message, n_detections=n, time_ms=time_ms, stage_ms=stages)
