"""What an identifier returns, and what every identifier does around its algorithm.

:class:`Identification` is the result shared by all algorithms (status, attitude, matches,
residual, probability of a false match, timing); :func:`validate_vectors` checks their input,
:func:`result_builder` stamps their results and :func:`identify_ranked` runs any of them on
detections given in any order.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Literal, TypeAlias, get_args

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from starsense.errors import InputError
from starsense.geometry.attitude import radec_roll_from_attitude
from starsense.identify.verify import exact_rotation
from starsense.units import RAD_TO_ARCSEC, RAD_TO_DEG

__all__ = [
    "STATUSES",
    "Identification",
    "IdentificationStatus",
    "identify_ranked",
    "result_builder",
    "validate_vectors",
]

#: The values of :attr:`Identification.status`.
IdentificationStatus: TypeAlias = Literal[
    "solved", "no_match", "ambiguous", "too_few_stars", "timeout"
]
STATUSES = get_args(IdentificationStatus)
"""Possible values of :attr:`Identification.status`."""

_EMPTY_INT = np.zeros(0, dtype=np.int64)


class _RotationField:
    """A dataclass field holding a Rotation, given as one or as its 3x3 matrix.

    A matrix (orthonormal to rounding: a fit's) is turned into the Rotation when the field is
    first read (:func:`~starsense.identify.verify.exact_rotation`), the same Rotation as
    building it at once: scipy's constructor (~10 us) is paid only by a caller that reads the
    attitude as a Rotation.
    """

    slot = "_rotation"  # where an instance keeps the value (result_builder stores it there)

    def __get__(self, obj: object, objtype: type | None = None) -> Rotation | None:
        if obj is None:
            return None  # the field's default
        value = obj.__dict__[self.slot]
        if isinstance(value, np.ndarray):
            value = exact_rotation(value)
            obj.__dict__[self.slot] = value
        return value

    def __set__(self, obj: object, value: object) -> None:
        obj.__dict__[self.slot] = value


@dataclass(frozen=True, eq=False)
class Identification:
    """The answer of a lost-in-space identifier.

    Attributes
    ----------
    status : IdentificationStatus
        ``"solved"``, ``"no_match"`` (no hypothesis passed verification),
        ``"too_few_stars"`` or ``"timeout"``. (``"ambiguous"``, two different attitudes
        passing, is reserved: the solvers accept the first hypothesis that passes.)
    algorithm : str
        ``"hashing"`` or ``"triangle"``.
    rotation : Rotation or None
        Attitude, ICRS -> camera (:mod:`starsense.geometry.attitude`), when solved. It may be
        given as its rotation matrix, shape (3, 3), orthonormal to rounding (a fit's): the
        Rotation is then built when first read.
    fov_rad : float or None
        Field of view (full width of the widest image axis), rad: the one given, or, when the
        field was unknown and the caller said at which field the vectors were computed, the
        one found.
    scale : float
        Factor applied to the tangent-plane coordinates ``(x/z, y/z)`` of the input vectors
        to get true camera directions: 1 for a known field, the estimate otherwise (the true
        focal length is the assumed one divided by `scale`).
    detection_index : ndarray of int, shape (M,)
        Matched detections (indices into the input vectors).
    catalog_index : ndarray of int, shape (M,)
        The database stars they match (indices into ``database.vectors``).
    catalog_id : ndarray of int64, shape (M,)
        Catalogue identifiers of those stars (HIP numbers for Hipparcos).
    residual_rms_rad : float
        RMS angle between matched detections and their catalogue stars after the fit, rad.
    false_match_probability : float
        Probability that a wrong attitude would match as many detections by chance.
    n_detections : int
        Detections given.
    n_patterns_tried : int
        Detection patterns (4-star or triangles) looked up.
    best_false_match_probability : float
        The least false-match probability of the hypotheses verified (1 when none got that
        far): how close a failed solve came.
    n_candidates : int
        Hypotheses verified.
    time_ms : float
        Wall time of the call, ms.
    message : str
        Why it failed, or a summary when solved.
    """

    status: IdentificationStatus
    algorithm: str
    rotation: Rotation | None = _RotationField()  # type: ignore[assignment]
    fov_rad: float | None = None
    scale: float = 1.0
    detection_index: NDArray[np.int64] = field(default_factory=lambda: _EMPTY_INT)
    catalog_index: NDArray[np.int64] = field(default_factory=lambda: _EMPTY_INT)
    catalog_id: NDArray[np.int64] = field(default_factory=lambda: _EMPTY_INT)
    residual_rms_rad: float = math.nan
    false_match_probability: float = 1.0
    n_detections: int = 0
    n_patterns_tried: int = 0
    n_candidates: int = 0
    best_false_match_probability: float = 1.0
    time_ms: float = 0.0
    message: str = ""

    @property
    def solved(self) -> bool:
        """True when :attr:`status` is ``"solved"``."""
        return self.status == "solved"

    @property
    def n_matches(self) -> int:
        """Number of matched detections."""
        return len(self.detection_index)

    def __repr__(self) -> str:
        if not self.solved:
            return f"Identification({self.status}: {self.message})"

        ra, dec, roll = (a * RAD_TO_DEG for a in radec_roll_from_attitude(self.rotation))
        return (
            f"Identification(solved, RA {ra:.4f} Dec {dec:.4f} roll {roll:.3f} deg, "
            f"{self.n_matches}/{self.n_detections} matched, rms "
            f"{self.residual_rms_rad * RAD_TO_ARCSEC:.1f} arcsec, P_false "
            f"{self.false_match_probability:.1e}, {self.time_ms:.1f} ms)"
        )


#: Identification's fields, and the defaults of those result_builder does not set
_FIELD_NAMES = frozenset(f.name for f in dataclasses.fields(Identification))
_DEFAULTS = {
    f.name: f.default if f.default_factory is dataclasses.MISSING else f.default_factory()
    for f in dataclasses.fields(Identification)
    if f.name != "rotation"
}


def validate_vectors(vectors_cam: object) -> NDArray[np.float64]:
    """Check and normalise detection directions ``(N, 3)``; raise :class:`InputError`."""
    try:
        v = np.asarray(vectors_cam, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"vectors_cam must be an (N, 3) array of numbers: {exc}") from None
    if v.ndim != 2 or v.shape[1] != 3:
        raise InputError(f"vectors_cam must have shape (N, 3), got {v.shape}")
    if not np.isfinite(v).all():
        row = int(np.flatnonzero(~np.isfinite(v).all(axis=1))[0])
        raise InputError(f"vectors_cam[{row}] = {v[row].tolist()} is not finite")
    norm = np.sqrt(np.add.reduce(v * v, axis=1))  # np.linalg.norm(v, axis=1)
    if (norm == 0).any():
        raise InputError(f"vectors_cam[{int(np.flatnonzero(norm == 0)[0])}] is a zero vector")
    v = v / norm[:, None]
    if (v[:, 2] <= 0).any():
        row = int(np.flatnonzero(v[:, 2] <= 0)[0])
        raise InputError(
            f"vectors_cam[{row}] = {v[row].tolist()} points behind the camera (z <= 0)"
        )
    return v


def result_builder(algorithm: str, n_detections: int, t0: float):
    """Return ``result(status, message, **fields) -> Identification`` for one identifier call.

    It stamps the algorithm, the number of detections and the time since ``t0``
    (perf_counter).
    """

    def result(status: str, message: str, **kw) -> Identification:
        if not _FIELD_NAMES.issuperset(kw):
            raise TypeError(f"Identification has no field {sorted(set(kw) - _FIELD_NAMES)}")
        # what the dataclass's __init__ stores, without its 17 object.__setattr__ calls (a
        # quarter of the Python time of a solve); the rotation goes through its field
        out = object.__new__(Identification)
        stored = out.__dict__
        stored.update(_DEFAULTS)
        stored[_RotationField.slot] = kw.pop("rotation", None)
        stored.update(kw)
        stored["status"] = status
        stored["algorithm"] = algorithm
        stored["n_detections"] = n_detections
        stored["time_ms"] = (time.perf_counter() - t0) * 1e3
        stored["message"] = message
        return out

    return result


def identify_ranked(identifier, vectors_cam, brightness, *args, **kwargs) -> Identification:
    """Run ``identifier`` on detections given in any order, ranked here by ``brightness``.

    The identifiers build their patterns from the first (brightest) detections; this makes the
    result independent of the order the caller lists them in. ``detection_index`` of the result
    refers to the caller's order.

    Parameters
    ----------
    identifier : HashIdentifier or TriangleIdentifier
    vectors_cam : array (N, 3)
    brightness : array (N,)
        Any measure that grows with brightness (integrated counts, electrons, flux).
    *args, **kwargs
        Passed on to the identifier (``fov_rad``, ``assumed_fov_rad``).
    """
    v = np.asarray(vectors_cam, dtype=float)
    b = np.asarray(brightness, dtype=float)
    if b.shape != (len(v),):
        raise InputError(f"brightness must have one value per detection ({len(v)}), got {b.shape}")
    if len(b) < 2 or (b[:-1] >= b[1:]).all():
        return identifier(v, *args, **kwargs)  # ranked already: the stable order is the same
    order = np.argsort(-b, kind="stable")
    result = identifier(v[order], *args, **kwargs)
    if len(result.detection_index) == 0:
        return result
    # dataclasses.replace without its __init__ (the fields are the same but one)
    out = object.__new__(Identification)
    out.__dict__.update(result.__dict__, detection_index=order[result.detection_index])
    return out
