"""An unknown camera's identification refined: its focal length and radial distortion fitted.

A frame solved with nothing known about its optics is identified through a pinhole (or a guessed
radial distortion) of the field found; :func:`refine_identification` fits the camera's focal
length and radial distortion to the matches (:func:`starsense.solve.radial.fit_radial`) and
re-identifies through it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from starsense.geometry.distortion import undistort
from starsense.solve.pinhole import pinhole_vectors
from starsense.solve.radial import MIN_FIELD_RAD, fit_radial, radial_vectors

__all__ = ["refine_identification"]


def refine_identification(
    ident, database, xy, *, flux, shape, fov_rad: float, k1=0.0, catalog=None
):
    """Refine a solved identification of an unknown camera with a radial-distortion fit.

    A field narrower than :data:`~starsense.solve.radial.MIN_FIELD_RAD` identified as a pinhole
    is left as it is.

    Parameters
    ----------
    ident : Identification
        A solved identification (pinhole, field ``fov_rad``).
    database : IdentificationDatabase
        Its database.
    xy : ndarray, shape (N, 2)
        The centroids (x = column, y = row), pixels.
    flux : ndarray, shape (N,)
        Their brightness (larger is brighter).
    shape : (int, int)
        Rows, columns of the image.
    fov_rad : float
        The horizontal field the identification found (pinhole), rad.
    k1 : float
        The radial distortion the identification assumed, tangent-plane units of the focal
        length of ``fov_rad``.
    catalog : Catalog, optional
        The full catalogue behind the database (:func:`fit_radial`).

    Returns
    -------
    ident : Identification
        With the refined matches, attitude and false-match probability (unchanged when the fit
        does not pass the false-match test).
    fit : RadialFit or None
        The camera found, or None.
    vectors : ndarray, shape (N, 3)
        The centroids' camera-frame unit vectors through the camera found (or the pinhole).
    fov_rad : float
        The horizontal field across the image width, rad (through the distortion found).
    """
    cols = shape[1]
    focal = cols / 2.0 / math.tan(fov_rad / 2.0)
    x, y = np.asarray(xy, dtype=float).T
    if fov_rad < MIN_FIELD_RAD and not k1:
        return ident, None, pinhole_vectors(x, y, shape=shape, fov_rad=fov_rad), fov_rad
    order = np.argsort(-np.asarray(flux, dtype=float), kind="stable")  # brightest first
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    fit = fit_radial(
        np.column_stack([x, y])[order],
        shape,
        database,
        tentative=(ident.rotation, rank[np.asarray(ident.detection_index)], ident.catalog_index),
        focal_px=focal,
        k1=k1,
        catalog=catalog,
    )
    if fit is None:
        if k1:
            vectors = radial_vectors(x, y, shape=shape, focal_px=focal, k1=k1)
            return ident, None, vectors, fov_rad
        return ident, None, pinhole_vectors(x, y, shape=shape, fov_rad=fov_rad), fov_rad
    ident = dataclasses.replace(
        ident,
        rotation=fit.rotation,
        detection_index=order[fit.detection_index],
        catalog_index=fit.catalog_index,
        catalog_id=database.ids[fit.catalog_index],
        false_match_probability=fit.false_match_probability,
    )
    vectors = radial_vectors(x, y, shape=shape, focal_px=fit.focal_px, k1=fit.k1, k2=fit.k2)
    half, _ = undistort([cols / 2.0 / fit.focal_px], [0.0], (fit.k1, fit.k2, 0.0, 0.0))
    fov = 2.0 * math.atan(float(half[0])) if np.isfinite(half[0]) else fov_rad
    return ident, fit, vectors, fov
