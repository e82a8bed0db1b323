"""Attitude-determination areas in the focal plane (Lin et al. 2024).

A camera that reuses its optics for attitude determination reads stars only in some regions of
its focal plane: the four circular segments between a square science detector and the lens's
good-image circle (Lin et al. 2024, sec. 2.2), or any rectangles and polygons a design defines.

Coordinates
    Gnomonic tangent-plane coordinates ``(x, y) = (v_x / v_z, v_y / v_z)`` of camera-frame
    directions (:mod:`starsense.geometry.attitude`; the projection itself is
    :func:`starsense.geometry.projection.vectors_to_tangent` and its inverse
    :func:`~starsense.geometry.projection.tangent_to_vectors`): dimensionless, the tangent of
    the field angle along each axis. A focal-plane position in metres divided by the focal
    length in metres is this coordinate (pinhole). Areas are in the square of these units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from starsense._validate import check_scalar, positive_float
from starsense.errors import InputError
from starsense.geometry.projection import xy_points

__all__ = ["AreaLayout", "FocalArea", "polygon_area", "polygon_centroid"]


def polygon_area(vertices: ArrayLike) -> float:
    """Return the area of a simple polygon (shoelace formula).

    Parameters
    ----------
    vertices : array_like, shape (K, 2)
        Vertices in order (either sense); the polygon closes itself.

    Returns
    -------
    float
        Area, in the square of the vertices' units.
    """
    v = np.asarray(vertices, dtype=np.float64)
    x, y = v[:, 0], v[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def polygon_centroid(vertices: ArrayLike) -> NDArray[np.float64]:
    """Return the centroid of a simple polygon (area-weighted, not the vertices' mean).

    Parameters
    ----------
    vertices : array_like, shape (K, 2)
        Vertices in order (either sense).

    Returns
    -------
    ndarray, shape (2,)
        Centroid, in the vertices' units (the vertices' mean for a degenerate polygon).
    """
    v = np.asarray(vertices, dtype=np.float64)
    x, y = v[:, 0], v[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    a = 0.5 * cross.sum()
    if a == 0:
        return v.mean(axis=0)
    return np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6.0 * a)


@dataclass(frozen=True, eq=False)
class FocalArea:
    """One attitude-determination area: a simple polygon in tangent-plane coordinates.

    Attributes
    ----------
    name : str
        The area's name (the report and the CLI print it).
    vertices : ndarray, shape (K, 2)
        Vertices in order (either sense), K >= 3, tangent-plane units; the polygon closes
        itself.
    """

    name: str
    vertices: NDArray[np.float64]

    def __post_init__(self) -> None:
        v = xy_points(self.vertices, f"area {self.name!r} vertices")
        if v.ndim != 2 or len(v) < 3:
            raise InputError(f"area {self.name!r} needs at least 3 vertices, got {len(v)}")
        v = v.copy()
        v.flags.writeable = False
        object.__setattr__(self, "vertices", v)
        if not self.area > 0:
            raise InputError(f"area {self.name!r} has zero area (collinear vertices)")

    @property
    def area(self) -> float:
        """Area, square tangent-plane units (shoelace formula)."""
        return polygon_area(self.vertices)

    def contains(self, xy: ArrayLike) -> NDArray[np.bool_]:
        """Return which points lie inside the polygon (even-odd rule).

        Parameters
        ----------
        xy : array_like, shape (..., 2)
            Tangent-plane points.

        Returns
        -------
        ndarray of bool, shape (...)
        """
        p = xy_points(xy)
        x, y = p[..., 0], p[..., 1]
        inside = np.zeros(x.shape, dtype=bool)
        v = self.vertices
        for (x0, y0), (x1, y1) in zip(v, np.roll(v, -1, axis=0), strict=True):
            crosses = (y0 > y) != (y1 > y)
            with np.errstate(divide="ignore", invalid="ignore"):
                x_cross = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
            inside ^= crosses & (x < x_cross)
        return inside

    def contains_grid(self, xs: ArrayLike, ys: ArrayLike) -> NDArray[np.bool_]:
        """Return :meth:`contains` for every point of the grid ``xs`` x ``ys``.

        Scanline form of the same even-odd rule: the edge crossings of each row are found
        once, so the cost is O(rows x vertices + points) instead of O(points x vertices).

        Parameters
        ----------
        xs : array_like, shape (nx,)
            Tangent-plane x of the grid's columns.
        ys : array_like, shape (ny,)
            Tangent-plane y of the grid's rows.

        Returns
        -------
        ndarray of bool, shape (ny, nx)
        """
        xs = np.asarray(xs, dtype=np.float64)
        ys = np.asarray(ys, dtype=np.float64)
        v = self.vertices
        x0, y0 = v[:, 0], v[:, 1]
        x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
        out = np.zeros((len(ys), len(xs)), dtype=bool)
        lo, hi = min(y0.min(), y1.min()), max(y0.max(), y1.max())
        for i in np.flatnonzero((ys >= lo) & (ys <= hi)):
            y = ys[i]
            crosses = (y0 > y) != (y1 > y)
            if not crosses.any():
                continue
            a, b, c, d = x0[crosses], y0[crosses], x1[crosses], y1[crosses]
            xc = np.sort(a + (y - b) * (c - a) / (d - b))
            # crossings strictly right of x, as in contains(): odd -> inside
            right = len(xc) - np.searchsorted(xc, xs, side="right")
            out[i] = (right % 2) == 1
        return out


@dataclass(frozen=True, eq=False)
class AreaLayout:
    """The attitude-determination areas of a camera.

    Attributes
    ----------
    areas : tuple of FocalArea
        Numbered 1, 2, ... in this order.
    lens_radius : float or None
        Radius of the good-image circle, tangent-plane units; every vertex must lie inside it.
    science_half : float or None
        Half side of the square science field, when the layout is built around one.
    """

    areas: tuple[FocalArea, ...]
    lens_radius: float | None = None
    science_half: float | None = None

    def __post_init__(self) -> None:
        if not self.areas:
            raise InputError("an area layout needs at least one attitude-determination area")
        names = [a.name for a in self.areas]
        if len(set(names)) != len(names):
            raise InputError(f"attitude-determination area names must be unique, got {names}")
        if self.lens_radius is not None:
            r = positive_float(self.lens_radius, "lens_radius")
            for a in self.areas:
                d = np.hypot(a.vertices[:, 0], a.vertices[:, 1])
                k = int(np.argmax(d))
                if d[k] > r * (1.0 + 1e-9):
                    x, y = a.vertices[k]
                    raise InputError(
                        f"area {a.name!r}: vertex ({x:.6g}, {y:.6g}) lies outside the lens "
                        f"circle (radius {r:.6g}, tangent-plane units)"
                    )

    @classmethod
    def lin2024(cls, science_half: float, n_arc: int = 256) -> AreaLayout:
        """Return the four circular segments around a square science field.

        Lin et al. 2024, Fig. 1: the lens circle of radius ``sqrt(2) science_half`` around the
        square, areas numbered counter-clockwise from +x.

        Parameters
        ----------
        science_half : float
            Half side of the science square, tangent-plane units (``tan(V / 2)``), in (0, 1).
        n_arc : int
            Vertices along each arc (the polygon's area is short by ~2e-5 relative at 256).

        Returns
        -------
        AreaLayout
        """
        h = check_scalar(science_half, "science_half", 0, 1, lo_open=True, hi_open=True)
        r = h * math.sqrt(2.0)
        t = np.linspace(-math.pi / 4, math.pi / 4, n_arc)
        arc = np.stack([r * np.cos(t), r * np.sin(t)], axis=-1)  # the x > h segment, area 1
        areas = []
        for k in range(4):
            c, s = math.cos(k * math.pi / 2), math.sin(k * math.pi / 2)
            rot = np.array([[c, -s], [s, c]])
            areas.append(FocalArea(str(k + 1), arc @ rot.T))
        return cls(tuple(areas), lens_radius=r, science_half=h)

    @property
    def names(self) -> tuple[str, ...]:
        """The areas' names, in number order."""
        return tuple(a.name for a in self.areas)

    @property
    def total_area(self) -> float:
        """Total area of all the areas, square tangent-plane units."""
        return float(sum(a.area for a in self.areas))

    def index(self, xy: ArrayLike) -> NDArray[np.int_]:
        """Return the area number (1-based) of each point, 0 outside every area.

        Parameters
        ----------
        xy : array_like, shape (..., 2)
            Tangent-plane points.

        Returns
        -------
        ndarray of int, shape (...)
        """
        p = xy_points(xy)
        out = np.zeros(p.shape[:-1], dtype=int)
        for k, a in enumerate(self.areas, start=1):
            out[(out == 0) & a.contains(p)] = k
        return out

    def index_grid(self, xs: ArrayLike, ys: ArrayLike) -> NDArray[np.int_]:
        """Return :meth:`index` on the grid ``xs`` x ``ys`` (scanline form).

        Parameters
        ----------
        xs : array_like, shape (nx,)
            Tangent-plane x of the grid's columns.
        ys : array_like, shape (ny,)
            Tangent-plane y of the grid's rows.

        Returns
        -------
        ndarray of int, shape (ny, nx)
        """
        xs = np.asarray(xs, dtype=np.float64)
        ys = np.asarray(ys, dtype=np.float64)
        out = np.zeros((len(ys), len(xs)), dtype=int)
        for k, a in enumerate(self.areas, start=1):
            out[(out == 0) & a.contains_grid(xs, ys)] = k
        return out

    def subset_area(self, numbers: tuple[int, ...]) -> float:
        """Return the total area of the areas numbered ``numbers`` (1-based), square units."""
        return float(sum(self.areas[k - 1].area for k in numbers))
