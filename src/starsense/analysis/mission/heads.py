"""Star-tracker heads on the body: a sensor, its mounting and its bright-body exclusion.

The mounting is the rotation body -> head, ``v_head = M.apply(v_body)``; a head with the
identity mounting looks along the body +z axis. The head's attitude is ``M * A_body`` and its
boresight in the body frame ``M.inv().apply([0, 0, 1])``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from starsense._validate import finite_array
from starsense.analysis.availability.checks import Fov, check_fov
from starsense.analysis.availability.threshold import ThresholdCurve
from starsense.errors import InputError

__all__ = ["QUATERNION_NORM_TOLERANCE", "Head", "mounting_from_euler", "mounting_from_quaternion"]

#: |norm - 1| above which a mounting quaternion is refused as not a rotation (4 decimals
#: written by hand give ~1e-4)
QUATERNION_NORM_TOLERANCE = 1e-3


def mounting_from_quaternion(q: Any, name: str = "mounting") -> Rotation:
    """Return the mounting body -> head from a quaternion ``(qx, qy, qz, qw)`` (scalar last).

    Raises
    ------
    InputError
        Not 4 finite numbers, or a norm that differs from 1 by more than
        :data:`QUATERNION_NORM_TOLERANCE` (not a rotation).
    """
    a = finite_array(q, name)
    if a.shape != (4,):
        raise InputError(f"{name} must be 4 numbers qx,qy,qz,qw, got shape {a.shape}")
    norm = float(np.linalg.norm(a))
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise InputError(
            f"{name} quaternion {a.tolist()} has norm {norm:.6g}: not a rotation (a unit "
            f"quaternion has norm 1, within {QUATERNION_NORM_TOLERANCE:g})"
        )
    return Rotation.from_quat(a / norm)


def mounting_from_euler(seq: str, angles: Any, name: str = "mounting") -> Rotation:
    """Return the mounting body -> head from Euler angles, rad, in scipy's `seq` convention.

    ``seq`` is one to three of ``xyz`` (extrinsic) or ``XYZ`` (intrinsic), one angle each, as
    :meth:`scipy.spatial.transform.Rotation.from_euler`.
    """
    a = np.atleast_1d(finite_array(angles, name))
    if not (1 <= len(seq) <= 3 and (set(seq) <= set("xyz") or set(seq) <= set("XYZ"))):
        raise InputError(f"{name}: Euler sequence must be 1-3 of xyz or of XYZ, got {seq!r}")
    if a.shape != (len(seq),):
        raise InputError(f"{name}: {len(seq)} Euler angle(s) for {seq!r}, got {a.size}")
    return Rotation.from_euler(seq, a)


@dataclass(frozen=True)
class Head:
    """One star-tracker head on the body.

    Parameters
    ----------
    name : str
        Its name in the results.
    fov : CircularFov or RectangularFov
        The field counted for availability.
    curve : ThresholdCurve
        Detection threshold against the cross-boresight rate, ``m_t(w)`` (rad/s).
    mounting : Rotation
        Body -> head (identity: boresight along body +z).
    exclusion : Exclusion or None
        Sun / Moon / Earth-limb half-angles (:class:`starsense.sensor.exclusion.Exclusion`);
        None: no bright body is considered.
    """

    name: str
    fov: Fov
    curve: ThresholdCurve
    mounting: Rotation = field(default_factory=Rotation.identity)
    exclusion: Any = None

    def __post_init__(self) -> None:
        check_fov(self.fov)
        if not isinstance(self.curve, ThresholdCurve):
            raise InputError(f"head {self.name}: curve must be a ThresholdCurve")
        if not isinstance(self.mounting, Rotation) or not self.mounting.single:
            raise InputError(f"head {self.name}: mounting must be a single scipy Rotation")

    @property
    def boresight_body(self) -> np.ndarray:
        """The boresight in body axes, (3,)."""
        return self.mounting.inv().apply([0.0, 0.0, 1.0])

    def describe(self) -> dict:
        """Return the head as JSON-ready values (degrees at the edge)."""
        b = self.boresight_body
        return {
            "name": self.name,
            "boresight_body": [round(float(c), 6) + 0.0 for c in b],
            "mounting_quaternion": [float(c) for c in self.mounting.as_quat()],
            "exclusion": None if self.exclusion is None else self.exclusion.to_dict(),
            "zero_rate_threshold_mag": float(self.curve([0.0])[0]),
            "curve": self.curve.label,
        }
