"""The stars the solver fits its attitude to, and the chance that each is in a frame's fit.

The forward model's fit (``refine="model"``) takes every catalogue star on the detector that
the model predicts above the noise of its footprint at the frame's rate
(:func:`starsense.model.selection.fitted_min_electrons`; the solver's
:func:`starsense.solve.in_view.stars_in_view`), detected or not: the same stars here, each
in the fit or not by its predicted electrons (:meth:`FittedStars.presence` is 1 or 0).

The centroids' attitude (``refine="cog"``) fits the identified stars alone: those of its
database (:func:`tracked_stars`), when detected, so its information counts by its chance of
detection: the fraction of the slew tolerance run's renders of its magnitude that the detector
found, at rest or at the frame's rate (:func:`detection_chance`). The sums of the prediction
are their expectations over the frames (:func:`starsense.analysis.datasheet.field.
propagated_sigmas`, ``presence``); stars past the run's faintest magnitude are never found.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from starsense.analysis.availability.field import catalog_stars
from starsense.analysis.datasheet.catalogue import catalogue_term_rad
from starsense.identify.database import build_database
from starsense.identify.patterns import thin_by_region
from starsense.model.selection import faintest_mag, fitted_min_electrons
from starsense.photometry.sensitivity import Sensitivity

__all__ = ["FittedStars", "detection_chance", "fitted_faint_mag", "fitted_stars", "tracked_stars"]

#: the database's thinning, as the solver builds it (its defaults: one copy, in build_database)
_DB_DEFAULTS = inspect.signature(build_database).parameters


def tracked_stars(vectors, magnitudes, fov_rad: float) -> NDArray[np.bool_]:
    """Return which stars the solver can identify: those of its database.

    The solver's identification database of a known field keeps, in every field-sized region
    of the sky, its brightest ``verification_stars_per_fov`` stars
    (:func:`starsense.identify.database.build_database`, thinned by
    :func:`starsense.identify.patterns.thin_by_region`). In a crowded field (hundreds of
    detectable stars) that is the brightest few tens.

    Parameters
    ----------
    vectors : ndarray (N, 3)
        ICRS unit vectors of the detectable stars.
    magnitudes : ndarray (N,)
        Their magnitudes (brightness order).
    fov_rad : float
        The field the solver's database is built for (full width of the widest axis), rad.

    Returns
    -------
    ndarray of bool (N,)
    """
    return thin_by_region(
        np.asarray(vectors, dtype=float),
        np.asarray(magnitudes, dtype=float),
        radius_rad=0.5 * float(fov_rad),
        n_per_region=int(_DB_DEFAULTS["verification_stars_per_fov"].default),
        oversampling=float(_DB_DEFAULTS["lattice_oversampling"].default),
    )


def detection_chance(slew, magnitudes, rate_rad_s: float = 0.0) -> NDArray[np.float64]:
    """Return the chance that a star of each magnitude is detected at ``rate_rad_s``.

    The slew tolerance run's detected fraction (:class:`starsense.analysis.slew.SlewResult`),
    linear between its magnitudes and between its rates; its brightest row for brighter stars,
    0 past its faintest magnitude (the grid ends past the limit) and past its top rate, and 0
    in the cells it did not simulate (a magnitude already lost at a slower rate).

    Parameters
    ----------
    slew : SlewResult
        The run: ``magnitudes`` (M,), ``rates_rad_s`` (R,), ``detected_fraction`` (M, R).
    magnitudes : array_like (N,)
        V magnitudes.
    rate_rad_s : float
        Body rate across the boresight, rad/s.

    Returns
    -------
    ndarray (N,)
        In [0, 1].
    """
    mags = np.asarray(slew.magnitudes, dtype=float)
    rates = np.asarray(slew.rates_rad_s, dtype=float)
    table = np.nan_to_num(np.asarray(slew.detected_fraction, dtype=float), nan=0.0)
    rate = abs(float(rate_rad_s))
    if rate > rates[-1] * (1.0 + 1e-12):
        return np.zeros(np.shape(magnitudes))
    j = int(np.clip(np.searchsorted(rates, rate, side="right") - 1, 0, len(rates) - 1))
    column = table[:, j]
    if j + 1 < len(rates):
        t = (rate - rates[j]) / (rates[j + 1] - rates[j])
        column = (1.0 - t) * column + t * table[:, j + 1]
    return np.interp(np.asarray(magnitudes, dtype=float), mags, column, left=column[0], right=0.0)


@dataclass(frozen=True)
class FittedStars:
    """The catalogue stars a solver may fit, and what decides whether a frame's fit holds one.

    Attributes
    ----------
    vectors : ndarray (N, 3)
        ICRS unit vectors (every star to the slew run's faintest magnitude).
    magnitudes : ndarray (N,)
        V magnitudes.
    held : ndarray of bool (N,)
        The stars the solver can fit when detected (all for the model fit; its database's for
        the centroids' attitude).
    slew : SlewResult
        The detector's slew tolerance run (the chance of detection per magnitude and rate).
    catalogue : ndarray (N, 3) or None
        Each star's database position less its rendered one, ICRS, rad (None: no such term).
    electrons : ndarray (N,) or None
        The model fit's stars: each one's predicted electrons (None: the centroids' attitude,
        whose stars are the detector's).
    sensor : Sensor or None
        With ``electrons``: the sensor whose noise sets the fit's floor.
    """

    vectors: np.ndarray
    magnitudes: np.ndarray
    held: np.ndarray
    slew: object
    catalogue: np.ndarray | None = None
    electrons: np.ndarray | None = None
    sensor: object = None

    def presence(self, rate_rad_s: float = 0.0) -> NDArray[np.float64]:
        """Return the chance each star is in a frame's fit at ``rate_rad_s`` (N,)."""
        if self.electrons is not None:  # the model's choice: 1 above the fit's floor, else 0
            floor = fitted_min_electrons(self.sensor, abs(float(rate_rad_s)))
            return np.where(self.held & (self.electrons >= floor), 1.0, 0.0)
        return np.where(self.held, detection_chance(self.slew, self.magnitudes, rate_rad_s), 0.0)

    def at(self, rate_rad_s: float = 0.0):
        """Return the stars a frame's fit may hold at ``rate_rad_s``, with their chances.

        Returns
        -------
        vectors (K, 3), magnitudes (K,), presence (K,), catalogue (K, 3) or None
            The stars whose chance is above 0.
        """
        p = self.presence(rate_rad_s)
        k = p > 0.0
        cat = None if self.catalogue is None else self.catalogue[k]
        return self.vectors[k], self.magnitudes[k], p[k], cat


def fitted_faint_mag(sensor, model: str = "reed") -> float:
    """Return the faintest V magnitude the model fit holds at rest (its floor, in magnitudes)."""
    zero = float(Sensitivity.for_sensor(sensor, model).electrons(0.0))
    return faintest_mag(zero, fitted_min_electrons(sensor, 0.0))


def fitted_stars(catalog, sensor, *, slew, limit_mag: float, refine: str = "model", model="reed"):
    """Return the :class:`FittedStars` of ``sensor`` on ``catalog`` (module docstring).

    Parameters
    ----------
    catalog : Catalog
        The frames' sky (V magnitudes).
    sensor : Sensor
    slew : SlewResult
        Its slew tolerance run.
    limit_mag : float
        Its limiting magnitude at rest, V (the database's stars are thinned among those).
    refine : {"model", "cog"}
        The solver's last step.
    model : str
        The sensitivity model (magnitude -> electrons) of the model fit's floor.

    Returns
    -------
    FittedStars
    """
    fit = refine == "model"  # the model's stars to its floor, or the detector's to its reach
    reach = fitted_faint_mag(sensor, model) if fit else float(np.max(slew.magnitudes))
    faint = max(reach, float(limit_mag))
    vectors, mags = catalog_stars(catalog, faint, band="V")
    catalogue = catalogue_term_rad(catalog, sensor, max_mag=faint)
    if fit:
        electrons = Sensitivity.for_sensor(sensor, model).electrons(mags)
        held = np.ones(len(mags), dtype=bool)
        return FittedStars(vectors, mags, held, slew, catalogue, electrons, sensor)
    held = mags <= limit_mag
    held[held] = tracked_stars(vectors[held], mags[held], 2.0 * sensor.half_fov_rad[0])
    return FittedStars(vectors, mags, held, slew, catalogue)
