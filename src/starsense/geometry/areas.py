"""Attitude-determination areas in the focal plane (Lin et al. 2024).

A camera that reuses its optics for attitude determination reads stars only in some regions of
its focal plane: the four circular segments between a square science detector and the lens's
good-image circle (Lin et al. 2024, sec. 2.2), or any rectangles and polygons a design defines.

Coordinates
    Gnomonic tangent-plane coordinates ``(x, y) = (v_x / v_z, v_y / v_z)`` of camera-frame
    directions (:mod:`starsense.geometry.attitude`): dimensionless, the tangent of the field
    angle along each axis. A focal-plane position in millimetres divided by the focal length in
    millimetres is this coordinate (pinhole).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from starsense.errors import InputError
from starsense.geometry.projection import _points, tangent_to_vectors, vectors_to_tangent

__all__ = ["AreaLayout", "FocalArea", "tangent_to_vectors", "vectors_to_tangent"]


@dataclass(frozen=True, eq=False)
class FocalArea:
    """One attitude-determination area: a simple polygon in tangent-plane coordinates.

    Attributes
    ----------
    name : str
    vertices : ndarray, shape (K, 2)
        Vertices in order (either sense), K >= 3; the polygon closes itself.
    """

    name: str
    vertices: NDArray[np.float64]

    def __post_init__(self) -> None:
        v = _points(self.vertices, f"area {self.name!r} vertices")
        if v.ndim != 2 or len(v) < 3:
            raise InputError(f"area {self.name!r} needs at least 3 vertices, got {len(v)}")
        v = v.copy()
        v.flags.writeable = False
        object.__setattr__(self, "vertices", v)
        if not self.area > 0:
            raise InputError(f"area {self.name!r} has zero area (collinear vertices)")

    @property
    def area(self) -> float:
        """Area in tangent-plane units (shoelace formula)."""
        x, y = self.vertices[:, 0], self.vertices[:, 1]
        return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))

    def contains(self, xy: ArrayLike) -> NDArray[np.bool_]:
        """Points inside the polygon (even-odd rule), shape (...)."""
        p = _points(xy)
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
        """:meth:`contains` for every point of the grid ``xs`` x ``ys``, shape (len(ys), len(xs)).

        Scanline form of the same even-odd rule: the edge crossings of each row are found
        once, so the cost is O(rows x vertices + points) instead of O(points x vertices).
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
            r = self.lens_radius
            if not (math.isfinite(r) and r > 0):
                raise InputError(f"lens radius = {r!r} must be finite and > 0")
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
        """The four circular segments around a square science field (Lin et al. 2024, Fig. 1).

        Parameters
        ----------
        science_half : float
            Half side of the science square, tangent-plane units (``tan(V / 2)``).
        n_arc : int
            Vertices along each arc (the polygon's area is short by ~2e-5 relative at 256).
        """
        h = float(science_half)
        if not (math.isfinite(h) and 0 < h < 1):
            raise InputError(f"science_half = {science_half!r} must be in (0, 1)")
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
        return tuple(a.name for a in self.areas)

    @property
    def total_area(self) -> float:
        return float(sum(a.area for a in self.areas))

    def index(self, xy: ArrayLike) -> NDArray[np.int_]:
        """Area number (1-based) of each point, 0 outside every area, shape (...)."""
        p = _points(xy)
        out = np.zeros(p.shape[:-1], dtype=int)
        for k, a in enumerate(self.areas, start=1):
            out[(out == 0) & a.contains(p)] = k
        return out

    def index_grid(self, xs: ArrayLike, ys: ArrayLike) -> NDArray[np.int_]:
        """:meth:`index` on the grid ``xs`` x ``ys``, shape (len(ys), len(xs)) (scanline)."""
        xs = np.asarray(xs, dtype=np.float64)
        ys = np.asarray(ys, dtype=np.float64)
        out = np.zeros((len(ys), len(xs)), dtype=int)
        for k, a in enumerate(self.areas, start=1):
            out[(out == 0) & a.contains_grid(xs, ys)] = k
        return out

    def subset_area(self, numbers: tuple[int, ...]) -> float:
        """Total area of the areas with these 1-based numbers."""
        return float(sum(self.areas[k - 1].area for k in numbers))
