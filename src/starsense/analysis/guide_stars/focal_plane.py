"""Focal-plane geometry of the paper's simulation: the four areas, the lattice, the placements.

Coordinates ``(x, y)`` are in units of the science field V, origin on the boresight (see
:mod:`starsense.analysis.guide_stars`). Lin et al. 2024, sec. 2.2 and sec. 4.
"""

from __future__ import annotations

import math
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from starsense._validate import as_generator, check_int, check_scalar
from starsense.errors import InputError
from starsense.geometry.projection import tangent_to_vectors, xy_points
from starsense.references import lin2024

__all__ = [
    "AREA_OF_SEGMENT",
    "CONFIGURATIONS",
    "LENS_RADIUS",
    "PAPER_STEP",
    "SQUARE_HALF",
    "area_index",
    "attitude_area",
    "configuration_areas",
    "focal_to_vectors",
    "in_configuration",
    "lattice_points",
    "sample_placements",
    "triangle_fov_ratio",
]

SQUARE_HALF = 0.5
"""Half side of the science square, units of V."""
LENS_RADIUS = math.sqrt(2.0) / 2.0
"""Radius of the lens circle (diameter sqrt(2) V), units of V."""
AREA_OF_SEGMENT = math.pi / 8.0 - 0.25
"""Area of one circular segment outside the square: (pi/8 - 1/4) V^2 = 0.1427 V^2."""
CONFIGURATIONS: dict[str, tuple[int, ...]] = {
    "one": (1,),
    "two_adjacent": (1, 2),
    "two_symmetric": (1, 3),
    "three": (1, 2, 3),
    "four": (1, 2, 3, 4),
}
"""The layouts of Lin et al. 2024, Table 1 (area numbers, counter-clockwise from +x)."""
PAPER_STEP = lin2024.LATTICE_STEP
"""Default lattice step, fraction of V (sec. 4)."""


def configuration_areas(configuration: str) -> tuple[int, ...]:
    """Return the area numbers (1-4) of a named configuration; InputError for an unknown name."""
    try:
        return CONFIGURATIONS[configuration]
    except (KeyError, TypeError):
        raise InputError(
            f"configuration = {configuration!r} is not known; choose one of "
            f"{', '.join(CONFIGURATIONS)}"
        ) from None


def attitude_area(configuration: str = "four") -> float:
    """Return the total area of a configuration's attitude-determination areas, units of V^2.

    ``attitude_area("four")`` = pi/2 - 1 = 0.5708 (Lin et al. 2024, sec. 2.2: 0.57 V^2).
    """
    return len(configuration_areas(configuration)) * AREA_OF_SEGMENT


def area_index(xy: ArrayLike) -> NDArray[np.int_]:
    """Return which attitude-determination area each focal-plane point is in.

    Parameters
    ----------
    xy : array_like, shape (..., 2)
        Focal-plane points, units of V.

    Returns
    -------
    ndarray of int, shape (...)
        1-4 for the segments (1: x > 1/2, 2: y > 1/2, 3: x < -1/2, 4: y < -1/2), 0 inside
        the science square or outside the lens circle. Boundaries belong to the areas: the
        square's edges are excluded from the segments (strict), the lens circle included.
    """
    p = xy_points(xy)
    x, y = p[..., 0], p[..., 1]
    in_lens = x * x + y * y <= LENS_RADIUS**2 * (1.0 + 1e-12)
    out = np.zeros(x.shape, dtype=int)
    out[in_lens & (x > SQUARE_HALF)] = 1
    out[in_lens & (y > SQUARE_HALF)] = 2
    out[in_lens & (x < -SQUARE_HALF)] = 3
    out[in_lens & (y < -SQUARE_HALF)] = 4
    return out


def in_configuration(xy: ArrayLike, configuration: str) -> NDArray[np.bool_]:
    """Return True where a point (..., 2), units of V, lies in one of the configuration's areas.

    Parameters
    ----------
    xy : array_like, shape (..., 2)
        Focal-plane points, units of V.
    configuration : str
        One of :data:`CONFIGURATIONS`.

    Returns
    -------
    ndarray of bool, shape (...)
    """
    areas = configuration_areas(configuration)
    return np.isin(area_index(xy), areas)


def lattice_points(step: float = PAPER_STEP) -> tuple[NDArray[np.float64], NDArray[np.int_]]:
    """Return the candidate guide-star positions: the lattice ``step * (i, j)`` in the areas.

    Parameters
    ----------
    step : float
        Lattice step, fraction of V, in (0, 0.2].

    Returns
    -------
    xy : ndarray, shape (M, 2)
        Points, units of V.
    area : ndarray of int, shape (M,)
        Area number (1-4) of each point.
    """
    check_scalar(step, "step", 0.0, 0.2, lo_open=True)
    n = math.ceil(LENS_RADIUS / step) + 1
    i = np.arange(-n, n + 1)
    gx, gy = np.meshgrid(i * step, i * step, indexing="ij")
    xy = np.stack([gx.ravel(), gy.ravel()], axis=-1)
    area = area_index(xy)
    keep = area > 0
    return xy[keep], area[keep]


def sample_placements(
    configuration: str,
    *,
    n_trials: int,
    n_stars: int = lin2024.N_GUIDE_STARS,
    step: float = PAPER_STEP,
    rng: np.random.Generator | int | None = None,
) -> NDArray[np.float64]:
    """Draw random guide-star placements on the lattice (Lin et al. 2024, sec. 4).

    Each placement is ``n_stars`` distinct lattice points of the configuration's areas, drawn
    uniformly among the combinations that put at least one star in every area of the
    configuration.

    Parameters
    ----------
    configuration : str
        One of :data:`CONFIGURATIONS`.
    n_trials : int
        Number of placements, >= 1.
    n_stars : int
        Guide stars per placement, >= 3 and >= the number of areas.
    step : float
        Lattice step, fraction of V.
    rng : Generator, int or None
        Random generator or seed.

    Returns
    -------
    ndarray, shape (n_trials, n_stars, 2)
        Focal-plane positions, units of V.
    """
    areas = configuration_areas(configuration)
    n_trials = check_int(n_trials, "n_trials", 1)
    n_stars = check_int(n_stars, "n_stars")
    if n_stars < 3:
        raise InputError(f"n_stars = {n_stars} must be >= 3 (triangles need three stars)")
    if n_stars < len(areas):
        raise InputError(
            f"n_stars = {n_stars} cannot cover the {len(areas)} areas of {configuration!r}"
        )
    xy, area = lattice_points(step)
    keep = np.isin(area, areas)
    xy, area = xy[keep], area[keep]
    if n_stars > len(xy):
        raise InputError(f"n_stars = {n_stars} exceeds the {len(xy)} lattice points available")
    gen, _ = as_generator(rng)
    chosen: list[NDArray[np.int_]] = []
    have = 0
    while have < n_trials:
        m = max(2 * (n_trials - have), 64)
        idx = np.argpartition(gen.random((m, len(xy))), n_stars - 1, axis=1)[:, :n_stars]
        a = area[idx]
        ok = np.all([(a == k).any(axis=1) for k in areas], axis=0)
        chosen.append(idx[ok])
        have += int(ok.sum())
    idx = np.concatenate(chosen)[:n_trials]
    return xy[idx]


def focal_to_vectors(xy: ArrayLike, fov_rad: float) -> NDArray[np.float64]:
    """Return the camera-frame unit vectors of focal-plane points (gnomonic).

    A point ``(x, y)`` (units of V) has tangent-plane coordinates ``(x, y) * 2 tan(V/2)``, so
    the science square's edges subtend V through the boresight
    (:func:`starsense.geometry.projection.tangent_to_vectors`).

    Parameters
    ----------
    xy : array_like, shape (..., 2)
        Focal-plane points, units of V.
    fov_rad : float
        Side V of the science square, rad, in (0, pi/2).

    Returns
    -------
    ndarray, shape (..., 3)
        Unit vectors, camera frame.
    """
    check_scalar(fov_rad, "fov_rad", 0.0, math.pi / 2, lo_open=True, hi_open=True)
    return tangent_to_vectors(xy_points(xy) * (2.0 * math.tan(fov_rad / 2.0)))


def triangle_fov_ratio(xy: ArrayLike, configuration: str | None = None) -> NDArray[np.float64]:
    """Return the "average FOV ratio of the triangles formed by the guide stars" (Figs. 5-6).

    Mean area of the C(n, 3) triangles formed by the guide stars, over the total area of the
    attitude-determination areas of ``configuration`` (``None``: all four, 0.5708 V^2).

    Parameters
    ----------
    xy : array_like, shape (..., n, 2)
        Guide-star positions, units of V, n >= 3.
    configuration : str or None
        Whose areas make the denominator.

    Returns
    -------
    ndarray, shape (...)
    """
    p = xy_points(xy)
    if p.ndim < 2 or p.shape[-2] < 3:
        raise InputError(f"need at least 3 guide stars for triangles, got shape {p.shape}")
    denom = attitude_area("four" if configuration is None else configuration)
    tri = np.array(list(combinations(range(p.shape[-2]), 3)))
    a, b, c = p[..., tri[:, 0], :], p[..., tri[:, 1], :], p[..., tri[:, 2], :]
    u, v = b - a, c - a
    area = 0.5 * np.abs(u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0])
    return area.mean(axis=-1) / denom
