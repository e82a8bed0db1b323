"""``Solver.solve_centroids``: a centroid list checked, then solved in one pass where it can be.

:func:`solve_centroid_list` is the method's body. A set of known optics that identifies at its
field is solved by :func:`solve_known_field`: the steps of ``Solver._solve_points`` that such a
set goes through (unproject, identify at the known field, references, the robust attitude, the
Solution), in the same order with the same functions, without the steps it does not take
(the scale search, the distortion guesses and the mirror image of a set that does not
identify; the radial fit of a field of 20 deg or more without a sensor; the pixel steps of an
image), whose checks and bookkeeping were a third of a solve's time. A set that does not
identify at its field returns None here and goes the whole way; its first identification is
handed over (:meth:`~starsense.solve.identifiers.FieldIdentifiers.keep_first`), not repeated.
The answers are those of the whole way (tests/solve/test_centroid_path.py holds them equal).
"""

from __future__ import annotations

import time

import numpy as np

from starsense.attitude.robust import residual_scaled, robust_attitude
from starsense.solve.attitude_fit import kernel_fit
from starsense.solve.centroids import CentroidPoints, check_centroid_input
from starsense.solve.counts import ms, solved
from starsense.solve.pinhole import pinhole_vectors
from starsense.solve.radial import MIN_FIELD_RAD
from starsense.solve.references import matched_references
from starsense.solve.solution import Solution

__all__ = ["solve_centroid_list", "solve_known_field"]


def solve_centroid_list(solver, xy, image_size, *, identifiers, whole_way, **options) -> Solution:
    """Return ``solver.solve_centroids(xy, image_size, **options)`` (see there).

    Parameters
    ----------
    solver : Solver
    xy, image_size
        As :meth:`~starsense.solve.solver.Solver.solve_centroids`.
    identifiers : FieldIdentifiers
        The Solver's identifiers: the solve's work budget starts here.
    whole_way : callable
        The Solver's ``_solve_points``: the way of a set :func:`solve_known_field` leaves.
    **options
        ``fov_rad``, ``brightness``, ``obs_time``.
    """
    t0 = time.perf_counter()
    identifiers.start()  # the set's identifications share one work budget
    obs_time = options.get("obs_time")
    pts, shape, flux, fov_rad = check_centroid_input(
        xy,
        image_size,
        brightness=options.get("brightness"),
        fov_rad=options.get("fov_rad"),
        sensor=solver.sensor,
    )
    sigma = solver.settings.centroid_sigma_px
    sigma = sigma if sigma != "snr" else 0.3  # no pixels: no signal to weigh them by
    points = CentroidPoints(pts[:, 0], pts[:, 1], flux, shape, "centroids")
    sol = solve_known_field(
        solver,
        points,
        identifiers=identifiers,
        sigma_px=sigma,
        fov_given=fov_rad,
        obs_time=obs_time,
        t0=t0,
    )
    if sol is not None:
        return sol
    return whole_way(points, t0, {}, lambda _m, _x, v: (v, sigma, None), fov_rad, obs_time)


def solve_known_field(solver, points, *, identifiers, sigma_px: float, fov_given, obs_time, t0):
    """Return the Solution of centroids that identify at the Solver's known field, else None.

    Parameters
    ----------
    solver : Solver
        Its sensor, or its field (``fov_given`` for this call, else its settings').
    points : CentroidPoints
        The centroids (no pixels: ``sigma_px`` and ``windows`` None).
    identifiers : FieldIdentifiers
        The Solver's identifiers (its first identification is kept there when it fails).
    sigma_px : float
        The centroids' noise, px (the Solver's ``centroid_sigma_px``).
    fov_given : float or None
        The field given for this call, rad.
    obs_time : str, astropy.time.Time or None
        When the image was taken.
    t0 : float
        ``time.perf_counter()`` at the call's start.

    Returns
    -------
    Solution or None
        None where the whole way is needed: no known field, a field of 20 deg or more without
        a sensor (its radial fit), fewer than 4 centroids, or a set that does not identify at
        its field.
    """
    sensor, n = solver.sensor, len(points.x)
    if sensor is not None:
        fov = 2.0 * sensor.half_fov_rad[0]
    else:
        fov = fov_given if fov_given is not None else solver.settings.fov_rad
        if fov is None or fov >= MIN_FIELD_RAD:
            return None
    if n < 4:
        return None
    if sensor is not None:
        vectors = sensor.unproject(points.x, points.y)
    else:
        vectors = pinhole_vectors(points.x, points.y, shape=points.shape, fov_rad=fov)
    stages: dict[str, float] = {}
    t1 = time.perf_counter()
    identifier = solver.identifier(fov)  # database build or cache load, timed on its own
    stages["database_ms"] = ms(t1)
    t2 = time.perf_counter()
    ident = identifiers.keep_first(identifier, vectors, points.flux, fov_rad=fov)
    stages["identify_ms"] = ms(t2)
    if not ident.solved:
        return None
    t3, pixel_rad = time.perf_counter(), fov / points.shape[1]
    matched = np.asarray(ident.detection_index)
    ref, apparent, _places = matched_references(
        solver, identifier.database, ident, obs_time=obs_time
    )
    # a list: its sigma stated, not measured (raised to the stars' scatter where it drops one)
    att, _keep = robust_attitude(
        vectors[matched], ref, sigma_px * pixel_rad, fit=kernel_fit, scatter=True
    )
    att = residual_scaled(att)  # as sure as its residuals allow (the general path's rule)
    stages["attitude_ms"] = ms(t3)
    sol: Solution = solved(
        points,
        ident,
        att,
        fov=fov,
        apparent=apparent,
        time_ms=ms(t0),
        stages=stages,
        radial=None,
        sensor=sensor,
    )
    return sol
