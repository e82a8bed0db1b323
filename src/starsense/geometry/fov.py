"""Fields of view: which sky directions a camera sees at a given attitude, and how many.

Frame conventions (camera +z along the boresight, +x towards increasing column, +y towards
increasing row; attitudes are ICRS -> camera rotations) are those of
:mod:`starsense.geometry.attitude`.

Two shapes are provided, both immutable and validated on construction:

* :class:`CircularFov` — a cone of half-angle ``a`` about the boresight.
* :class:`RectangularFov` — the field of a flat rectangular detector behind a pinhole
  (gnomonic / tangent-plane projection): a direction ``(x, y, z)`` in the camera frame is
  inside when ``z > 0``, ``|x / z| <= tan(half_width)`` and ``|y / z| <= tan(half_height)``.
  The half-width spans the columns (camera x), the half-height the rows (camera y).

:func:`count_in_fov` counts the stars inside the field for many attitudes at once, using a
:class:`scipy.spatial.cKDTree` over the star vectors as a prefilter (a cone query with the
field's enclosing radius around every boresight), followed by the exact test on the candidates.
"""

from __future__ import annotations

import itertools
import math
import operator
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from starsense._validate import check_rotation, check_scalar
from starsense.errors import InputError

__all__ = ["CircularFov", "RectangularFov", "count_in_fov"]

# Relative and absolute margins on the prefilter chord so that rounding never drops a star
# that the exact test would accept (the exact tests are accurate to ~1e-16).
_CHORD_REL_MARGIN = 1e-9
_CHORD_ABS_MARGIN = 1e-12

# Upper bound on the number of (pointing, star) candidate pairs held in memory at once.
_CANDIDATE_BUDGET = 2_000_000


def _half_angle(value: object, name: str, upper: float, upper_inclusive: bool) -> float:
    bound = f"0 < {name} {'<=' if upper_inclusive else '<'} {upper}"
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a real number (rad), got {value!r}") from exc
    ok = x > 0.0 and (x <= upper if upper_inclusive else x < upper)
    if not ok:  # also catches NaN
        raise InputError(f"{name} = {x} rad is out of range; must satisfy {bound} rad")
    return x


def _check_vectors(vectors: ArrayLike, name: str = "vectors") -> NDArray[np.float64]:
    try:
        v = np.asarray(vectors, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be an array of shape (N, 3), got {vectors!r}") from exc
    if v.ndim not in (1, 2) or v.shape[-1] != 3:
        raise InputError(f"{name} must have shape (N, 3) or (3,), got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise InputError(f"{name} contains non-finite values (NaN or inf); all must be finite")
    return v


class _Fov:
    """Shared behaviour of the field shapes; subclasses define the geometry."""

    @property
    def enclosing_radius_rad(self) -> float:  # pragma: no cover - overridden
        raise NotImplementedError

    @property
    def solid_angle_sr(self) -> float:  # pragma: no cover - overridden
        raise NotImplementedError

    def _inside(self, v_cam: NDArray[np.float64]) -> NDArray[np.bool_]:  # pragma: no cover
        raise NotImplementedError

    def contains(self, attitude: Rotation, vectors: ArrayLike) -> NDArray[np.bool_]:
        """Whether directions fall inside the field at the given attitude(s).

        This is the exact test, evaluated for every (attitude, vector) pair; use
        :func:`count_in_fov` for counts over many attitudes.

        Parameters
        ----------
        attitude : Rotation, single or batch of M
            Attitude(s), ICRS -> camera.
        vectors : array_like, shape (N, 3) or (3,)
            ICRS unit vectors.

        Returns
        -------
        ndarray of bool, shape (N,) for a single attitude or (M, N) for a batch
            (the N axis is dropped when `vectors` has shape (3,)).
        """
        rot = check_rotation(attitude, "attitude")
        v = _check_vectors(vectors)
        matrix = rot.as_matrix()  # (3, 3) or (M, 3, 3)
        v2 = np.atleast_2d(v)
        if rot.single:
            v_cam = v2 @ matrix.T  # (N, 3)
        else:
            v_cam = np.einsum("mij,nj->mni", matrix, v2)  # (M, N, 3)
        inside = self._inside(v_cam)
        return inside[..., 0] if v.ndim == 1 else inside


@dataclass(frozen=True)
class CircularFov(_Fov):
    """A circular field: the cone of half-angle `half_angle_rad` about the boresight.

    Parameters
    ----------
    half_angle_rad : float
        Cone half-angle, rad, with ``0 < half_angle_rad <= pi``.

    Raises
    ------
    InputError
        If the half-angle is out of range or NaN.
    """

    half_angle_rad: float

    def __post_init__(self) -> None:
        value = _half_angle(
            self.half_angle_rad, "CircularFov.half_angle_rad", math.pi, upper_inclusive=True
        )
        object.__setattr__(self, "half_angle_rad", value)

    @property
    def enclosing_radius_rad(self) -> float:
        """Radius of the smallest cone about the boresight enclosing the field, rad."""
        return self.half_angle_rad

    @property
    def solid_angle_sr(self) -> float:
        """Solid angle of the cone, ``2 pi (1 - cos a) = 4 pi sin^2(a / 2)``, sr."""
        return 4.0 * math.pi * math.sin(0.5 * self.half_angle_rad) ** 2

    def _inside(self, v_cam: NDArray[np.float64]) -> NDArray[np.bool_]:
        return v_cam[..., 2] >= math.cos(self.half_angle_rad)


@dataclass(frozen=True)
class RectangularFov(_Fov):
    """A rectangular field seen through a pinhole (gnomonic projection).

    Parameters
    ----------
    half_width_rad : float
        Half of the field across the columns (camera x), rad, ``0 < a < pi/2``.
    half_height_rad : float
        Half of the field across the rows (camera y), rad, ``0 < b < pi/2``.

    Raises
    ------
    InputError
        If a half-angle is out of range or NaN.
    """

    half_width_rad: float
    half_height_rad: float

    def __post_init__(self) -> None:
        for name in ("half_width_rad", "half_height_rad"):
            value = _half_angle(
                getattr(self, name), f"RectangularFov.{name}", math.pi / 2, upper_inclusive=False
            )
            object.__setattr__(self, name, value)

    @classmethod
    def from_detector(
        cls, columns: int, rows: int, *, pixel_pitch_m: float, focal_length_m: float
    ) -> RectangularFov:
        """Return the field of a pinhole camera with a detector of ``columns x rows`` square pixels.

        ``half_width = atan(columns * pixel_pitch_m / (2 focal_length_m))``, likewise for rows
        (measured to the outer edges of the detector).

        Parameters
        ----------
        columns, rows : int
            Detector size in pixels, >= 1.
        pixel_pitch_m : float
            Pixel pitch, m, > 0.
        focal_length_m : float
            Focal length, m, > 0.

        Returns
        -------
        RectangularFov

        Raises
        ------
        InputError
            If a size is not a positive integer or a length not a positive finite number.
        """
        sizes = []
        for name, value in (("columns", columns), ("rows", rows)):
            try:
                if isinstance(value, bool | np.bool_):
                    raise TypeError
                n = operator.index(value)
            except TypeError as exc:
                raise InputError(f"{name} must be an integer >= 1, got {value!r}") from exc
            if n < 1:
                raise InputError(f"{name} = {n} is out of range; must be an integer >= 1")
            sizes.append(n)
        pitch = check_scalar(pixel_pitch_m, "pixel_pitch_m", 0.0, None, lo_open=True)
        focal = check_scalar(focal_length_m, "focal_length_m", 0.0, None, lo_open=True)
        return cls(
            half_width_rad=math.atan(0.5 * sizes[0] * pitch / focal),
            half_height_rad=math.atan(0.5 * sizes[1] * pitch / focal),
        )

    @property
    def enclosing_radius_rad(self) -> float:
        """Angle from the boresight to a corner, ``atan(hypot(tan a, tan b))``, rad."""
        return math.atan(math.hypot(math.tan(self.half_width_rad), math.tan(self.half_height_rad)))

    @property
    def solid_angle_sr(self) -> float:
        """Exact solid angle of the gnomonic rectangle, ``4 asin(sin a sin b)``, sr."""
        return 4.0 * math.asin(math.sin(self.half_width_rad) * math.sin(self.half_height_rad))

    def _inside(self, v_cam: NDArray[np.float64]) -> NDArray[np.bool_]:
        x, y, z = v_cam[..., 0], v_cam[..., 1], v_cam[..., 2]
        return (
            (z > 0.0)
            & (np.abs(x) <= z * math.tan(self.half_width_rad))
            & (np.abs(y) <= z * math.tan(self.half_height_rad))
        )


def count_in_fov(
    fov: CircularFov | RectangularFov,
    attitudes: Rotation,
    vectors: ArrayLike,
    *,
    tree: cKDTree | None = None,
) -> NDArray[np.intp]:
    """Count the directions inside the field for each attitude.

    A :class:`scipy.spatial.cKDTree` over `vectors` returns, for all boresights at once, the
    candidates within the chord ``2 sin(r / 2)`` of the field's enclosing radius ``r``; the
    exact :meth:`contains` test is then applied to the flattened candidate pairs in NumPy.
    Pointings are processed in blocks so that at most a few million candidate pairs are held
    in memory. The result equals ``fov.contains(attitudes, vectors).sum(axis=-1)``.

    Parameters
    ----------
    fov : CircularFov or RectangularFov
        The field.
    attitudes : Rotation, batch of M (or single)
        Attitudes, ICRS -> camera.
    vectors : array_like, shape (N, 3)
        ICRS unit vectors (e.g. catalogue stars).
    tree : scipy.spatial.cKDTree, optional
        A tree built on exactly `vectors` (``cKDTree(vectors)``), to reuse across calls.

    Returns
    -------
    ndarray of int, shape (M,), or a scalar for a single attitude
        Counts per attitude.

    Raises
    ------
    InputError
        On a bad field, attitude, vectors array, or a tree of the wrong size.
    """
    if not isinstance(fov, _Fov):
        raise InputError(f"fov must be a CircularFov or RectangularFov, got {type(fov).__name__}")
    rot = check_rotation(attitudes, "attitudes")
    v = _check_vectors(vectors)
    if v.ndim != 2:
        raise InputError(f"vectors must have shape (N, 3), got shape {v.shape}")
    if tree is None:
        tree = cKDTree(v)
    elif not isinstance(tree, cKDTree) or tree.n != v.shape[0] or tree.m != 3:
        raise InputError(
            f"tree must be a cKDTree built on vectors ({v.shape[0]} points in 3-D), got "
            f"{type(tree).__name__}"
            + (f" with {tree.n} points in {tree.m}-D" if isinstance(tree, cKDTree) else "")
        )

    matrices = rot.as_matrix().reshape(-1, 3, 3)
    n_att = matrices.shape[0]
    counts = np.zeros(n_att, dtype=np.intp)
    if n_att == 0 or v.shape[0] == 0:
        return counts[0] if rot.single else counts

    radius = min(fov.enclosing_radius_rad, math.pi)
    chord = 2.0 * math.sin(0.5 * radius) * (1.0 + _CHORD_REL_MARGIN) + _CHORD_ABS_MARGIN
    if isinstance(fov, CircularFov):
        # A cone is a chord ball: the tree counts in C without listing pairs (3-4x faster).
        # Stars inside a slightly smaller ball are surely in the field; only the pointings with
        # a star in the thin shell between the two balls get the exact test below.
        inner = 2.0 * math.sin(0.5 * radius) * (1.0 - 1e-7)
        boresights = matrices[:, 2, :]
        n_out = np.asarray(tree.query_ball_point(boresights, chord, return_length=True))
        n_in = (
            np.asarray(tree.query_ball_point(boresights, inner, return_length=True))
            if inner > 0
            else np.zeros_like(n_out)
        )
        counts = n_in.astype(np.intp)
        shell = np.flatnonzero(n_out != n_in)
        if shell.size == 0:
            return counts[0] if rot.single else counts
        matrices, todo = matrices[shell], shell
    else:
        todo = None
    # Expected candidates per pointing (uniform sky, with headroom) sets the block size.
    expected = max(1.0, 1.5 * v.shape[0] * math.sin(0.5 * radius) ** 2)
    block = max(1, int(_CANDIDATE_BUDGET // expected))

    for start in range(0, len(matrices), block):
        mats = matrices[start : start + block]
        lists = tree.query_ball_point(mats[:, 2, :], chord, return_sorted=False)
        lengths = np.fromiter(map(len, lists), dtype=np.intp, count=len(lists))
        total = int(lengths.sum())
        if total == 0:
            continue
        star_idx = np.fromiter(itertools.chain.from_iterable(lists), dtype=np.intp, count=total)
        point_idx = np.repeat(np.arange(len(mats)), lengths)
        v_cam = np.einsum("kij,kj->ki", mats[point_idx], v[star_idx])
        inside = fov._inside(v_cam)
        found = np.bincount(point_idx[inside], minlength=len(mats))
        if todo is None:
            counts[start : start + len(mats)] = found
        else:
            counts[todo[start : start + len(mats)]] = found
    return counts[0] if rot.single else counts
