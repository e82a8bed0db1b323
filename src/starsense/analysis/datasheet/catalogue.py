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

import math

import numpy as np
from scipy.spatial import cKDTree

from starsense.analysis.inputs import SAME_STAR_RAD, at_epoch, held_by, same_star_index
from starsense.identify.fields import plan_band
from starsense.solve.refine import MERGED_PX
from starsense.solve.solver import Solver
from starsense.units import MAS

__all__ = [
    "GAIA_DR3_SIGMA_RAD",
    "MATCH_RAD",
    "catalogue_term_rad",
    "flux_ratio_error",
    "merged_pull_rad",
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
    off = rendered_against_database_rad(rendered, database, max_mag=max_mag, band=band)
    if off is None:
        return None
    return off - merged_pull_rad(rendered, database, sensor, max_mag=max_mag, band=band)


def merged_pull_rad(rendered, database, sensor, *, max_mag: float, band: str = "V"):
    """Return how far the stars the model fit merges into each kept star pull its light, rad.

    The solver's model fit draws the frame's other stars as the identified stars' neighbours,
    but one closer than :data:`starsense.solve.refine.MERGED_PX` to an identified star is part
    of its image (a double the PSF does not split: a binary's companion that Gaia resolves and
    Hipparcos lists as one star): the fitted position is their light's centre. For a star of
    PSF sigma ``s`` (pixel-integrated: ``sqrt(s^2 + 1/12)`` px) and a companion of flux ratio
    ``f`` at offset ``d``, the fit of one profile moves, to first order in ``f`` (the
    companion's light projected on the position's derivative over the position's Fisher
    information, for a Gaussian profile on a uniform background), by ``f w d`` with
    ``w = exp(-|d|^2 / (4 s^2))``, and to the light's centre ``f d / (1 + f)`` as ``d -> 0``:
    over companions, ``sum(f w d) / (1 + sum(f w))``. The same offset in every frame that holds
    the star, as its catalogue offset (:func:`rendered_against_database_rad`), whose order the
    result follows.

    Parameters
    ----------
    rendered, database : Catalog
        The frames' sky and the solver's catalogue.
    sensor : Sensor
        Its PSF width and plate scale.
    max_mag : float
        The stars kept (``band`` magnitude <= ``max_mag``), as the catalogue term keeps them.
    band : str
        Magnitude band of the cut and of the flux ratios.

    Returns
    -------
    ndarray (K, 3)
        Light centre less rendered direction of each kept star the database holds (0 for
        the others, as their catalogue offset), ICRS, rad.
    """
    mags = np.asarray(rendered.mags[band], dtype=float)
    keep = mags <= max_mag
    out = np.zeros((int(keep.sum()), 3))
    if not len(out):
        return out
    sky = at_epoch(rendered, database.epoch_yr).vectors
    held = held_by(rendered, database)[keep]
    pixel_rad = 1.0 / sensor.focal_length_px
    sigma_rad = float(np.hypot(sensor.detector.psf_sigma_px, math.sqrt(1.0 / 12.0))) * pixel_rad
    kept_v, kept_m = sky[keep], mags[keep]
    reach = 2.0 * np.sin(0.5 * MERGED_PX * pixel_rad)
    pairs = cKDTree(kept_v).sparse_distance_matrix(cKDTree(sky), reach, output_type="ndarray")
    i, j = pairs["i"], pairs["j"]
    mine = (pairs["v"] > 0.0) & held[i]  # not the star itself; a star the solver holds
    i, j = i[mine], j[mine]
    d = sky[j] - kept_v[i]
    fw = 10.0 ** (-0.4 * (mags[j] - kept_m[i]))
    fw = fw * np.exp(-np.einsum("ij,ij->i", d, d) / (4.0 * sigma_rad * sigma_rad))
    fw = np.where(np.isfinite(fw), fw, 0.0)
    np.add.at(out, i, fw[:, None] * d)
    total = np.zeros(len(out))
    np.add.at(total, i, fw)
    out /= (1.0 + total)[:, None]
    return out


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
