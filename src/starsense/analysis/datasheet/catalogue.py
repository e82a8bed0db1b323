"""The catalogue's share of the attitude error: star positions the database does not know exactly.

The solver fits the attitude to the database catalogue's positions of the matched stars: an
error in a star's catalogued direction enters the fit like a centroid error of the same size,
through the same weights (:func:`starsense.analysis.datasheet.field.propagated_sigmas`). Per
star and axis its variance is the position's stated variance at the catalogue's epoch plus
that of the proper motion over the years to the epoch the positions are used at,
``e_pos^2 + (dt e_pm)^2`` (Hipparcos' proper-motion errors of ~1 mas/yr grow past its
positions' ~0.5 mas within a year).

The datasheet's frames are rendered from one catalogue, completed with the database's stars it
lacks (:func:`starsense.analysis.inputs.completed_sky`), at the epoch of the solver's database
(:func:`starsense.analysis.inputs.at_epoch`). When the database is another catalogue (a narrow
field's Gaia DR3 database, a sky rendered from Hipparcos), the two disagree on every star they
share by the errors of both at that epoch: the attitude measured against the rendering carries
them, and the prediction includes them (:func:`rendered_against_database_rad`). A star the
database holds under the rendering's own identifier (the Hipparcos stars merged into the
bundled Gaia file above its bright limit) has the same position in both: no term. When the
rendering is the database itself the frames are exact and the term is zero.
"""

from __future__ import annotations

import numpy as np

from starsense.analysis.inputs import SAME_STAR_RAD, at_epoch, same_star_index
from starsense.identify.fields import plan_band
from starsense.solve.solver import Solver
from starsense.units import MAS

__all__ = [
    "GAIA_DR3_SIGMA_RAD",
    "MATCH_RAD",
    "catalogue_term_rad",
    "flux_ratio_error",
    "position_sigma_rad",
    "rendered_against_database_rad",
]

#: the stated errors of a Gaia DR3 five-parameter solution at G ~ 9-13 (Lindegren et al. 2021,
#: A&A 649, A2, table 4: 0.01-0.02 mas in position at J2016.0 and 0.02-0.03 mas/yr in proper
#: motion; the larger values): per axis, rad and rad/yr. The bundled file carries no errors.
GAIA_DR3_SIGMA_RAD = (0.02 * MAS, 0.03 * MAS)

#: the farthest a rendered star's database counterpart is sought, rad: the solver's match
#: radius is a few pixels, and no star moved by its catalogue errors lies 1" away
MATCH_RAD = SAME_STAR_RAD

#: the columns of a catalogue's stated astrometric errors (:func:`starsense.catalog.load_hip2`)
_ERROR_COLUMNS = ("e_ra_rad", "e_dec_rad", "e_pm_ra_rad_yr", "e_pm_dec_rad_yr")


def position_sigma_rad(catalog, epoch_yr: float) -> np.ndarray | None:
    """Return each star's stated position error at ``epoch_yr``, rad rms per axis.

    ``sqrt((e_ra^2 + e_dec^2 + dt^2 (e_pm_ra^2 + e_pm_dec^2)) / 2)`` with ``dt`` the years
    from the catalogue's epoch. A star whose errors are not stated takes the catalogue's median
    (not stating an error does not make a position exact). Gaia DR3 (``gaia_dr3``, whose
    bundled file states none) takes :data:`GAIA_DR3_SIGMA_RAD` for every star; without proper
    motions (the bundled file), NaN away from its epoch (each star is off by its own motion).

    Parameters
    ----------
    catalog : Catalog
        The catalogue (``extra`` holding ``e_ra_rad``, ``e_dec_rad``, ``e_pm_ra_rad_yr``,
        ``e_pm_dec_rad_yr``, as :func:`starsense.catalog.load_hip2` reads them).
    epoch_yr : float
        The Julian epoch the positions are used at, years.

    Returns
    -------
    ndarray (N,) or None
        rad; None for a catalogue that states no errors.
    """
    dt = float(epoch_yr) - float(catalog.epoch_yr)
    n = len(catalog.ids)
    if all(k in catalog.extra for k in _ERROR_COLUMNS):
        cols = []
        for k in _ERROR_COLUMNS:
            v = np.asarray(catalog.extra[k], dtype=float)
            ok = np.isfinite(v)
            cols.append(np.where(ok, v, np.median(v[ok]) if ok.any() else 0.0))
        e_ra, e_dec, e_pmra, e_pmdec = cols
        return np.sqrt(0.5 * (e_ra**2 + e_dec**2 + dt * dt * (e_pmra**2 + e_pmdec**2)))
    if catalog.name == "gaia_dr3":
        pos, pm = GAIA_DR3_SIGMA_RAD
        if catalog.pm_ra_rad_yr is None and dt != 0.0:  # positions without motions (the
            return np.full(n, np.nan)  # bundled file): off by each star's own motion
        return np.full(n, float(np.hypot(pos, dt * pm)))
    return None


def rendered_against_database_rad(rendered, database, *, max_mag: float, band: str = "V"):
    """Return how far each rendered star lies from its counterpart in the solver's database.

    The frames are rendered from ``rendered`` at the database's epoch
    (:func:`starsense.analysis.inputs.at_epoch`); the solver fits the attitude to the
    database's position of each star it matches. Both catalogues are at hand, so the
    disagreement is not modelled but taken star by star: the offset to the nearest database
    star within :data:`MATCH_RAD` (a star with no counterpart there is not matched by the
    solver: no term), a bias of that star in every frame. The catalogues' stated errors
    (:func:`position_sigma_rad`) give the median of these angles but not their tail: a few
    per cent of Hipparcos stars lie 0.1" or more from Gaia DR3 at J2016 (binaries whose
    short-term proper motion is not their long-term one), which the rms follows.

    Parameters
    ----------
    rendered : Catalog
        The catalogue the frames are rendered from.
    database : Catalog
        The solver's database catalogue.
    max_mag : float
        The stars kept, as :func:`starsense.analysis.availability.field.catalog_stars` keeps
        them (``band`` magnitude <= ``max_mag``), in the same order.
    band : str
        Magnitude band of the cut.

    Returns
    -------
    ndarray (K, 3) or None
        Database less rendered unit vector of each kept star, ICRS, rad; None when the
        frames are rendered from the database itself (the term is zero).
    """
    if rendered.name == database.name:
        return None
    keep = np.asarray(rendered.mags[band], dtype=float) <= max_mag
    sky = at_epoch(rendered.subset(keep), database.epoch_yr)
    idx = same_star_index(sky.vectors, database.vectors)  # within MATCH_RAD
    found = idx >= 0
    out = np.zeros((len(sky.ids), 3))
    out[found] = database.vectors[idx[found]] - sky.vectors[found]
    return out


def catalogue_term_rad(rendered, sensor, *, max_mag: float, band: str = "V"):
    """Return the datasheet's catalogue term against the database of the solver of ``sensor``.

    :func:`rendered_against_database_rad` for the catalogue :class:`starsense.solve.Solver`
    identifies against (the sensor's field chooses it).

    Parameters
    ----------
    rendered : Catalog
        The catalogue the datasheet renders its frames from.
    sensor : Sensor
        The sensor (its field chooses the solver's database).
    max_mag : float
        The stars kept (``band`` magnitude <= ``max_mag``).
    band : str
        Magnitude band of the cut.

    Returns
    -------
    ndarray (K, 3) or None
        ICRS offsets, rad, or None (the term is zero).
    """
    database = Solver(sensor=sensor).catalog
    return rendered_against_database_rad(rendered, database, max_mag=max_mag, band=band)


def flux_ratio_error(rendered, database, sensitivity, *, colour: str = "B-V") -> float:
    """Return the relative rms error of two stars' flux ratio as the solver's catalogue gives it.

    The solver models a smeared star's neighbours from its catalogue's magnitudes in the band
    it orders stars by (:func:`starsense.identify.fields.plan_band`: G for a Gaia database),
    and a neighbour pulls the capsule's centroid by its share of their light
    (:func:`starsense.solve.blends.streak_reference`); the frames hold each star's light as
    the sensor's response gives it (``sensitivity``, from V and, for the black body, the
    colour). Over the stars both catalogues hold, each star's flux less the catalogue's (about
    their common scale) scatters by the colour terms between the two bands; a ratio of two
    stars carries both: ``sqrt(2)`` times that scatter. Zero when the solver's magnitudes are
    the response's own (a V catalogue and a V-only model).

    Parameters
    ----------
    rendered : Catalog
        The frames' sky (V, and ``colour`` for the black body).
    database : Catalog
        The solver's catalogue.
    sensitivity : Sensitivity
        The frames' response (:class:`starsense.photometry.sensitivity.Sensitivity`).
    colour : str
        The colour index of the black-body model.

    Returns
    -------
    float
        Relative rms error (0.2: 20 %).
    """
    if "V" not in rendered.mags or len(rendered.ids) == 0 or len(database.ids) == 0:
        return 0.0
    sky = at_epoch(rendered, database.epoch_yr)
    idx = same_star_index(sky.vectors, database.vectors)
    found = np.flatnonzero(idx >= 0)
    v = np.asarray(rendered.mags["V"], dtype=float)[found]
    ci = None
    if sensitivity.model == "blackbody" and colour in rendered.colours:
        ci = np.asarray(rendered.colours[colour], dtype=float)[found]
    e = np.asarray(sensitivity.electrons(v, ci), dtype=float)
    m_db = np.asarray(database.mags[plan_band(database)], dtype=float)[idx[found]]
    ok = np.isfinite(e) & (e > 0) & np.isfinite(m_db)
    if ok.sum() < 2:
        return 0.0
    d = -2.5 * np.log10(e[ok]) - m_db[ok]  # the response's magnitude less the catalogue's
    flux = 10.0 ** (-0.4 * (d - np.median(d)))  # each star's flux over the catalogue's
    return float(np.sqrt(2.0) * np.std(flux) / np.mean(flux))
