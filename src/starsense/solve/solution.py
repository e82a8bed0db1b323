"""The answer of a solve: :class:`Solution` (attitude, matches, residuals, WCS).

A solver that holds its attitude as a matrix may give the fields derived from it (the
Rotation, RA/Dec/roll, the 1-sigma errors, the match and centroid tables) as :class:`Deferred`
values: each is computed when
first read, by the same code and with the same result as computing it at once, so a caller
that never reads it (a tracking loop that keeps the matrix) does not pay for it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import Literal, TypeAlias, get_args

import numpy as np
from scipy.spatial.transform import Rotation

from starsense.errors import InputError
from starsense.solve.wcs import solution_wcs, write_solution_wcs
from starsense.units import RAD_TO_ARCSEC

__all__ = ["Deferred", "Solution", "SolveStatus", "allow_deferred"]

#: The values of :attr:`Solution.status`: "solved", or why not (the identification's own
#: reasons, :data:`starsense.identify.result.IdentificationStatus`, among them); tracking adds
#: "unverified" (an attitude nothing was left to test) and "unreadable" (a frame's file).
SolveStatus: TypeAlias = Literal[
    "solved",
    "no_stars",
    "too_few_stars",
    "no_match",
    "ambiguous",
    "timeout",
    "too_many_candidates",
    "mirrored",
    "unverified",
    "unreadable",
]
_STATUSES = get_args(SolveStatus)


class Deferred:
    """A field value computed on first read: ``Deferred(compute)``, ``compute()`` the value.

    Several fields computed together share one call: ``Deferred(compute, index=i)`` is item
    ``i`` of ``compute()``; wrap ``compute`` in :func:`functools.cache` so it runs once.

    Parameters
    ----------
    compute : callable
        Takes no argument, returns the value (or a sequence of values with ``index``).
    index : int, optional
        The item of ``compute()`` this field takes.
    """

    __slots__ = ("compute", "index")

    def __init__(self, compute: Callable[[], object], *, index: int | None = None) -> None:
        self.compute = compute
        self.index = index

    def value(self) -> object:
        """Return the value (calls ``compute``)."""
        got = self.compute()
        return got if self.index is None else got[self.index]


class _DeferredField:
    """A dataclass field whose stored value may be :class:`Deferred`: computed when read.

    Installed on the class after the dataclass is made (its ``__init__`` stores through it).
    """

    def __init__(self, name: str) -> None:
        self.slot = "_" + name  # where an instance keeps the value

    def __get__(self, obj: object, objtype: type | None = None) -> object:
        if obj is None:
            return self
        value = obj.__dict__[self.slot]
        if isinstance(value, Deferred):
            value = value.value()
            obj.__dict__[self.slot] = value
        return value

    def __set__(self, obj: object, value: object) -> None:
        obj.__dict__[self.slot] = value


def _resolved_state(self) -> dict:
    """Return the instance's fields with every deferred one computed (for pickle and copy)."""
    for name in type(self).deferred_fields:
        getattr(self, name)
    return dict(self.__dict__)


def allow_deferred(cls: type, *names: str) -> type:
    """Let the fields ``names`` of the dataclass ``cls`` be given as :class:`Deferred`.

    Installs a descriptor per field (the dataclass's ``__init__`` stores through it; a read
    computes a :class:`Deferred` once and keeps the value) and a ``__getstate__`` that computes
    them all, so that pickle and copy keep values, not the calls.

    Parameters
    ----------
    cls : type
        A dataclass (frozen or not, without ``__slots__``).
    *names : str
        Its fields that may be deferred.

    Returns
    -------
    type
        ``cls``, changed in place.
    """
    for name in names:
        setattr(cls, name, _DeferredField(name))
    cls.deferred_fields = (*getattr(cls, "deferred_fields", ()), *names)
    cls.__getstate__ = _resolved_state
    return cls


def _deg(angle_rad: float | None) -> float | None:
    return None if angle_rad is None else float(np.degrees(angle_rad))


@dataclass(frozen=True)
class Solution:
    """The answer for one frame, with what is needed to judge it.

    ``status`` is "solved" or says why not ("no_stars", "too_few_stars", "no_match",
    "too_many_candidates" when a frame that did not solve gave more detections than
    :func:`~starsense.solve.solver.max_candidates`, "mirrored" when only the frame's
    left-right mirror image solves: a camera read out flipped; the attitude is then that of the
    flipped frame, see :mod:`starsense.solve.parity`, ...);
    angles follow :mod:`starsense.geometry.attitude` (roll as in the ESA reference.json). The
    angles are stored in radians; ``ra_deg``, ``rmse_arcsec`` ... give them in the units of the
    command line and of :meth:`to_dict`.

    Parameters
    ----------
    status : SolveStatus
        Outcome.
    message : str
        A sentence about the outcome.
    ra_rad, dec_rad, roll_rad : float or None
        Boresight and roll of the attitude, rad. These, ``sigma_rad``, ``rotation``,
        ``matches`` and ``centroids_px`` may be given as :class:`Deferred` (module docstring).
    fov_rad : float or None
        Horizontal field across the image width, rad (given, or found by the scale search).
    n_detections, n_matched : int
        Stars detected, and identified.
    rmse_rad : float or None
        Rms residual of the matched stars after the fit, rad.
    false_match_probability : float or None
        Probability that the identification is a chance match.
    sigma_rad : tuple of 3 float or None
        1-sigma attitude error about the camera x, y (cross-boresight) and z (roll) axes, rad.
    time_ms : float
        Wall time of the whole solve, ms.
    stage_ms : dict of str to float
        Wall time per stage (detection, identification, attitude...), ms.
    rotation : Rotation or None
        The attitude, ICRS -> camera.
    matches : tuple of (int, int)
        (detection index, catalogue id) of every matched star.
    centroids_px : ndarray, shape (N, 2) or None
        Detected centroids (x = column, y = row), pixels.
    image_shape : (int, int) or None
        Rows, columns of the frame.
    focal_px : float or None
        Focal length, pixels.
    apparent : dict or None
        The apparent-place correction applied to the matched stars
        (:meth:`starsense.catalog.apparent.ApparentPlaces.to_dict`), or why none was.
    sensor : Sensor or None
        The sensor model the centroids were unprojected with (principal point, distortion).
    distortion : dict or None
        For a frame solved with no sensor: the lens found with it
        (:meth:`starsense.solve.radial.RadialFit.to_dict`: radial k1, k2 with their sigmas, the
        focal length in pixels, the displacement at the image corner in per cent, the residual
        rms with and without it); None otherwise.
    notes : tuple of str
        What the user should know about the frame (e.g. that it looks like a raw Bayer mosaic).
    counts : dict
        How far each stage got (:func:`starsense.solve.counts.stage_counts`): pixels above the
        threshold, candidates and the rejected ones by reason, detections, patterns tried, the
        best false-match probability seen.
    """

    status: SolveStatus
    message: str = ""
    ra_rad: float | None = None
    dec_rad: float | None = None
    roll_rad: float | None = None
    fov_rad: float | None = None
    n_detections: int = 0
    n_matched: int = 0
    rmse_rad: float | None = None
    false_match_probability: float | None = None
    sigma_rad: tuple[float, float, float] | None = None
    time_ms: float = 0.0
    stage_ms: dict = field(default_factory=dict)
    rotation: Rotation | None = field(default=None, repr=False)
    matches: tuple[tuple[int, int], ...] = field(default=(), repr=False)
    centroids_px: np.ndarray | None = field(default=None, repr=False)
    image_shape: tuple[int, int] | None = None
    focal_px: float | None = None
    apparent: dict | None = None
    sensor: object = field(default=None, repr=False)
    distortion: dict | None = None
    notes: tuple[str, ...] = ()
    counts: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        """Refuse a status that is not one of :data:`SolveStatus` (a typo would read as failed)."""
        _check_status(self.status)

    @classmethod
    def of(cls, status: SolveStatus, message: str = "", **values) -> Solution:
        """Return ``Solution(status, message, **values)``, stored without the dataclass's __init__.

        The frozen dataclass's ``__init__`` sets its 23 fields one ``object.__setattr__`` at a
        time (a tenth of a centroid list's solve); this stores the same values (the defaults,
        fresh dicts for ``stage_ms`` and ``counts``, the deferred fields in their slots) at
        once, after the same check of ``status``.
        """
        _check_status(status)
        if not _FIELD_NAMES.issuperset(values):
            raise TypeError(f"Solution has no field {sorted(set(values) - _FIELD_NAMES)}")
        out = object.__new__(cls)
        stored = out.__dict__
        stored.update(_DEFAULT_VALUES, stage_ms={}, counts={})
        for name, value in values.items():
            stored[_SLOTS.get(name, name)] = value
        stored["status"], stored["message"] = status, message
        return out

    @property
    def ra_deg(self) -> float | None:
        """Right ascension of the boresight, deg."""
        return _deg(self.ra_rad)

    @property
    def dec_deg(self) -> float | None:
        """Declination of the boresight, deg."""
        return _deg(self.dec_rad)

    @property
    def roll_deg(self) -> float | None:
        """Roll about the boresight, deg."""
        return _deg(self.roll_rad)

    @property
    def fov_deg(self) -> float | None:
        """Horizontal field across the image width, deg."""
        return _deg(self.fov_rad)

    @property
    def rmse_arcsec(self) -> float | None:
        """Rms residual of the matched stars, arcsec."""
        return None if self.rmse_rad is None else float(self.rmse_rad * RAD_TO_ARCSEC)

    @property
    def sigma_arcsec(self) -> tuple[float, float, float] | None:
        """1-sigma attitude error about the camera x, y and z axes, arcsec."""
        if self.sigma_rad is None:
            return None
        return tuple(float(s * RAD_TO_ARCSEC) for s in self.sigma_rad)

    def wcs(self, sip_order: int | None = None):
        """Return an astropy WCS of the solved frame: TAN, or TAN-SIP when the sensor distorts.

        See :func:`starsense.solve.wcs.solution_wcs`.
        """
        return solution_wcs(self, sip_order)

    def write_wcs(self, path: str | Path, sip_order: int | None = None) -> Path:
        """Write the WCS as a FITS header (:func:`~starsense.solve.wcs.write_solution_wcs`)."""
        return write_solution_wcs(self, path, sip_order)

    @property
    def solved(self) -> bool:
        """Whether the frame solved."""
        return self.status == "solved"

    def to_dict(self) -> dict:
        """Return the solution as JSON-ready values (degrees and arcseconds, as the CLI prints)."""
        sigma = self.sigma_arcsec
        return {
            "status": self.status,
            "message": self.message,
            "ra_deg": self.ra_deg,
            "dec_deg": self.dec_deg,
            "roll_deg": self.roll_deg,
            "fov_deg": self.fov_deg,
            "n_detections": self.n_detections,
            "n_matched": self.n_matched,
            "rmse_arcsec": self.rmse_arcsec,
            "false_match_probability": self.false_match_probability,
            "sigma_arcsec": None if sigma is None else list(sigma),
            "time_ms": self.time_ms,
            "stage_ms": self.stage_ms,
            "apparent_places": self.apparent,
            "distortion": self.distortion,
            "counts": self.counts,
            "notes": list(self.notes),
        }


allow_deferred(
    Solution, "ra_rad", "dec_rad", "roll_rad", "sigma_rad", "rotation", "matches", "centroids_px"
)


def _check_status(status: object) -> None:
    if not isinstance(status, str) or status not in _STATUSES:
        raise InputError(f"status must be one of {', '.join(_STATUSES)}; got {status!r:.80}")


#: Solution's fields; where :meth:`Solution.of` stores each (a deferred field in its slot) and
#: the defaults it stores (the dict fields' factories are called per solution)
_FIELD_NAMES = frozenset(f.name for f in fields(Solution))
_SLOTS = {name: "_" + name for name in Solution.deferred_fields}
_DEFAULT_VALUES = {
    _SLOTS.get(f.name, f.name): f.default for f in fields(Solution) if f.default is not MISSING
}
