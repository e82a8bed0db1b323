"""Pixel positions to camera-frame unit vectors through a pinhole (no sensor model)."""

from __future__ import annotations

import math

import numpy as np

from starsense.geometry.projection import tangent_to_vectors

__all__ = ["pinhole_vectors"]


def pinhole_vectors(x, y, *, shape, fov_rad: float) -> np.ndarray:
    """Return camera-frame unit vectors of pixel positions seen through a pinhole.

    The horizontal field across the image width is ``fov_rad``, the principal point at the image
    centre (pixel-centre convention); the gnomonic inverse is
    :func:`starsense.geometry.projection.tangent_to_vectors`.

    Parameters
    ----------
    x, y : array_like, shape (N,)
        Column and row of each position, pixels.
    shape : (int, int)
        Rows, columns of the image.
    fov_rad : float
        Horizontal field, rad.

    Returns
    -------
    ndarray, shape (N, 3)
    """
    rows, cols = shape
    f_px = cols / 2.0 / math.tan(fov_rad / 2.0)
    u = (np.asarray(x, dtype=float) - (cols - 1) / 2.0) / f_px
    w = (np.asarray(y, dtype=float) - (rows - 1) / 2.0) / f_px
    return tangent_to_vectors(np.column_stack([u, w]))
