"""What tracking predicts before it looks: the frame's stars and streaks from the prior.

:func:`predicted_field` projects the database stars near the predicted boresight onto the
detector (mid-exposure position and the streak the body rate draws over the exposure, from the
rotation over half the exposure, :func:`half_turn`); :func:`unblended` tells which matched
stars have no catalogue neighbour close enough to blend with; :func:`tracking_setup` keeps
what does not change between the frames of one Solver (database, identifier, window detector,
CoG margin, field corners).
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np

from starsense.detect.streak import columns
from starsense.detect.windows import WindowDetector
from starsense.identify.track_kernels import unblended_compiled, unblended_numpy
from starsense.identify.tracking import TrackingIdentifier

__all__ = ["TrackingSetup", "half_turn", "predicted_field", "tracking_setup", "unblended"]


@dataclass(frozen=True)
class TrackingSetup:
    """What tracking needs from a Solver that does not change between frames (cached).

    Attributes
    ----------
    sensor : Sensor
        The Solver's sensor.
    background : str
        The Solver's background mode ("auto" or "known").
    db : IdentificationDatabase
        The database of the sensor's field.
    identifier : TrackingIdentifier
        Matches detections to the predicted stars.
    windows : WindowDetector
        Detects stars in windows around the predicted ones.
    field_r : float
        Half-diagonal of the field, rad.
    margin_px : int
        The CoG window's margin, px.
    corners : ndarray, shape (4, 3)
        Unit vectors of the field's corners, camera frame.
    fov_rad : float
        Full width of the field across the columns, rad (``2 half_fov_rad[0]``).
    """

    sensor: object
    background: str
    db: object
    identifier: object
    windows: WindowDetector
    field_r: float
    margin_px: int
    corners: np.ndarray
    fov_rad: float


_SETUPS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def tracking_setup(solver) -> TrackingSetup:
    """Return the solver's tracking set-up, built on first use and when its sensor changes.

    Parameters
    ----------
    solver : Solver
        With a sensor.

    Returns
    -------
    TrackingSetup
    """
    sensor = solver.sensor
    settings = solver.settings
    db = solver.identifier(2.0 * sensor.half_fov_rad[0]).database
    got = _SETUPS.get(solver)
    if (
        got is None
        or got.sensor is not sensor
        or got.db is not db
        or got.background != settings.background
    ):
        field_r = math.atan(math.hypot(*(math.tan(h) for h in sensor.half_fov_rad)))
        known = settings.background == "known"
        margin = solver.detector.margin_px if known else 2
        ident = TrackingIdentifier(db, min_match_radius_rad=2.0 / sensor.focal_length_px)
        windows = WindowDetector(solver.detector, sensor.detector, known, settings.threshold_sigma)
        tx, ty = (math.tan(h) for h in sensor.half_fov_rad)
        corners = np.array([[-tx, -ty, 1.0], [-tx, ty, 1.0], [tx, -ty, 1.0], [tx, ty, 1.0]])
        corners /= math.sqrt(tx * tx + ty * ty + 1.0)
        fov = 2.0 * sensor.half_fov_rad[0]
        got = TrackingSetup(
            sensor, settings.background, db, ident, windows, field_r, margin, corners, fov
        )
        _SETUPS[solver] = got
    return got


def half_turn(sensor, rate_rad_s) -> np.ndarray | None:
    """Return the rotation over half the exposure at the body rate, (3, 3); None at rest.

    Rodrigues' formula for the rotation vector ``v = w t_e / 2`` (angle ``|v|``, axis ``k``):
    ``R = I + sin|v| K + 2 sin^2(|v| / 2) K^2``, ``K`` the cross-product matrix of ``k``
    (the matrix of ``Rotation.from_rotvec(v)`` to rounding, without building a Rotation).

    Parameters
    ----------
    sensor : Sensor
        Its exposure time is used.
    rate_rad_s : array_like, shape (3,) or None
        Body rate, camera frame, rad/s.

    Returns
    -------
    ndarray, shape (3, 3) or None
    """
    if rate_rad_s is None:
        return None
    half = sensor.exposure_s / 2.0
    v1, v2, v3 = (float(r) * half for r in np.asarray(rate_rad_s, dtype=float).reshape(3))
    angle = math.sqrt(v1 * v1 + v2 * v2 + v3 * v3)
    if angle == 0.0:
        return None
    k1, k2, k3 = v1 / angle, v2 / angle, v3 / angle
    s, c = math.sin(angle), 2.0 * math.sin(angle / 2) ** 2  # c = 1 - cos(angle)
    return np.array(
        [
            [1.0 - c * (k2 * k2 + k3 * k3), c * k1 * k2 - s * k3, c * k1 * k3 + s * k2],
            [c * k1 * k2 + s * k3, 1.0 - c * (k1 * k1 + k3 * k3), c * k2 * k3 - s * k1],
            [c * k1 * k3 - s * k2, c * k2 * k3 + s * k1, 1.0 - c * (k1 * k1 + k2 * k2)],
        ]
    )


def predicted_field(sensor, db, rot, *, r_s, field_r, half_turn_matrix):
    """Database stars near the field, brightest first: their predicted pixel positions.

    Parameters
    ----------
    sensor : Sensor
        Projects camera-frame vectors to pixels.
    db : IdentificationDatabase
        The stars (unit vectors, KD-tree), brightest first.
    rot : ndarray, shape (3, 3)
        The predicted attitude's matrix (ICRS -> camera).
    r_s : float
        Search radius, rad.
    field_r : float
        Half-diagonal of the field, rad.
    half_turn_matrix : ndarray, shape (3, 3) or None
        The rotation over half the exposure (:func:`half_turn`); None without a rate.

    Returns
    -------
    near : ndarray of int, shape (N,)
        Database indices.
    x, y : ndarray, shape (N,)
        Predicted mid-exposure positions, px.
    margin_on : ndarray of bool, shape (N,)
        Whether each lies on the detector or within the search radius of it.
    streaks : ndarray, shape (N, 2) or None
        The streak (start to end, px) of each over the exposure; None without a rate.
    """
    r = rot
    centre = r[2]  # the boresight in ICRS: R^T z
    near = db.tree.query_ball_point(centre, 2 * math.sin((field_r + r_s) / 2), return_sorted=True)
    near = np.asarray(near, dtype=np.intp)
    cam = db.vectors[near] @ r.T
    n = len(near)
    if half_turn_matrix is None:
        x, y = sensor.project(cam)
    else:  # mid-exposure, start b(0) = R(w t_e / 2) b_mid and end R(w t_e / 2)^T b_mid at once
        px, py = sensor.project(
            np.concatenate([cam, cam @ half_turn_matrix.T, cam @ half_turn_matrix])
        )
        x, y = px[:n], py[:n]
    m = r_s * sensor.focal_length_px
    det = sensor.detector
    margin_on = (x >= -m) & (x <= det.columns - 1 + m) & (y >= -m) & (y <= det.rows - 1 + m)
    if half_turn_matrix is None:
        return near, x, y, margin_on, None
    streaks = columns(px[2 * n :] - px[n : 2 * n], py[2 * n :] - py[n : 2 * n])
    return near, x, y, margin_on, streaks


def unblended(cat_index, near, *, x, y, blend_px: float) -> np.ndarray:
    """Return whether each matched star has no other database star within ``blend_px``.

    A double star (two catalogue stars a few pixels apart) is detected as one blended spot
    whose centroid lies between them: it is left out of the fit when others remain. The
    nearest other predicted star of each, by direct comparison (a few dozen stars;
    :func:`~starsense.identify.track_kernels.unblended_numpy`, compiled where built).

    Parameters
    ----------
    cat_index : ndarray of int, shape (M,)
        Database indices of the matched stars (all in ``near``).
    near, x, y : ndarray, shape (N,)
        The predicted field (:func:`predicted_field`): database indices (ascending), px.
    blend_px : float
        Distance below which two stars blend, px.

    Returns
    -------
    ndarray of bool, shape (M,)
    """
    got = unblended_compiled(cat_index, near, x=x, y=y, blend_px=blend_px)
    return unblended_numpy(cat_index, near, x=x, y=y, blend_px=blend_px) if got is None else got
